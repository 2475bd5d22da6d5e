"""tracer.record: the tracer's Options and the viewer's ViewSettings share one validation and one
`name=value` parser; each message names the field with its record's noun."""
from dataclasses import fields

import pytest

from tracer.options import Options, parse_assignment
from viewer.state import ViewSettings, assign


def test_validation_names_the_field_with_the_records_noun():
    with pytest.raises(ValueError, match=r"^option criterion: 'exact' is not one of float, fixed, adaptive, "
                                         r"mantissa$"):
        Options(criterion="exact")
    with pytest.raises(ValueError, match=r"^option fixed_size: 50\.0 is outside \[1e-09, 10\.0\]$"):
        Options().with_(fixed_size=50.0)
    with pytest.raises(ValueError, match=r"^setting gamma: 9\.0 is outside \[0\.2, 5\.0\]$"):
        ViewSettings(gamma=9.0)
    with pytest.raises(ValueError, match=r"^setting tone: 'aces' is not one of clamp, reinhard$"):
        ViewSettings().with_(tone="aces")


def test_assignments_reach_the_record_that_has_the_field():
    opts, settings = assign(Options(), ViewSettings(), "mantissa_ulps = 4096")
    opts, settings = assign(opts, settings, "reference=off")
    opts, settings = assign(opts, settings, "exposure=-1.5")
    assert opts == Options(mantissa_ulps=4096)
    assert settings == ViewSettings(reference=False, exposure=-1.5)
    assert parse_assignment(Options(), "trims=no") == Options(trims=False)


@pytest.mark.parametrize("text, message", [
    ("criterion", "expected option=value, got 'criterion'"),
    ("fixed_size=big", "option fixed_size: cannot read 'big' as float"),
    ("exposure=bright", "setting exposure: cannot read 'bright' as float"),
    ("trims=maybe", "option trims: cannot read 'maybe' as bool"),
    ("reference=maybe", "setting reference: cannot read 'maybe' as bool"),
    ("overlay=rainbow", "setting overlay: 'rainbow' is not one of none, "),
])
def test_bad_assignments_say_what_was_expected(text, message):
    with pytest.raises(ValueError) as err:
        assign(Options(), ViewSettings(), text)
    assert str(err.value).startswith(message)


def test_unknown_names_list_every_known_field():
    with pytest.raises(ValueError) as err:
        assign(Options(), ViewSettings(), "nope=1")
    known = [f.name for f in fields(Options)] + [f.name for f in fields(ViewSettings)]
    assert str(err.value) == f"unknown option 'nope' (known: {', '.join(known)})"
    with pytest.raises(ValueError) as err:
        parse_assignment(Options(), "exposure=1")  # the tracer alone knows no view settings
    assert str(err.value) == f"unknown option 'exposure' (known: {', '.join(f.name for f in fields(Options))})"
