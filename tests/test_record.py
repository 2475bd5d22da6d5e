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


@pytest.mark.parametrize("text, message", [
    ("tile_size=4.7", "option tile_size: 4.7 is not an integer (expected an integer in [4, 256])"),
    ("threads=inf", "option threads: cannot read 'inf' as int (expected an integer in [0, 256])"),
    ("mantissa_ulps=1e400", "option mantissa_ulps: 1e400 is outside [0, 1048576]"),
    ("fixed_size=-1e400", "option fixed_size: -1e400 is outside [1e-09, 10.0]"),
    ("fixed_size=nan", "option fixed_size: cannot read 'nan' as float (expected a number in [1e-09, 10.0])"),
    ("threads=1_0", "option threads: cannot read '1_0' as int"),
    ("threads=\u0661\u0662", "option threads: cannot read '\u0661\u0662' as int"),  # Arabic-Indic digits
    ("threads=0x10", "option threads: cannot read '0x10' as int"),
    ("threads=", "option threads: cannot read '' as int"),
    ("threads=257", "option threads: 257 is outside [0, 256]"),
    ("exposure=1e30", "setting exposure: 1e30 is outside [-8.0, 8.0]"),
    ("mantissa_ulps=" + "9" * 5000, "option mantissa_ulps: cannot read '99999"),
])
def test_numbers_are_checked_for_type_integrality_finiteness_and_range(text, message):
    with pytest.raises(ValueError) as err:
        assign(Options(), ViewSettings(), text)
    assert str(err.value).startswith(message) and len(str(err.value)) < 200


def test_integral_numbers_reach_int_fields_exactly():
    assert parse_assignment(Options(), "tile_size=8.0").tile_size == 8
    assert parse_assignment(Options(), "mantissa_ulps=1e3").mantissa_ulps == 1000
    assert type(parse_assignment(Options(), "pixel_fraction=2").pixel_fraction) is float
    assert Options(tile_size=8.0) == Options(tile_size=8) and type(Options(tile_size=8.0).tile_size) is int


@pytest.mark.parametrize("changes, message", [
    ({"tile_size": 4.7}, "option tile_size: 4.7 is not an integer"),
    ({"threads": float("inf")}, "option threads: inf is not finite"),
    ({"fixed_size": float("nan")}, "option fixed_size: nan is not finite"),
    ({"trims": 1}, "option trims: 1 is not a boolean"),
    ({"tile_size": True}, "option tile_size: True is not a number"),
    ({"fixed_size": "0.1"}, "option fixed_size: '0.1' is not a number"),
    ({"mantissa_ulps": 10 ** 5000}, "option mantissa_ulps: <an integer of 16610 bits> is outside"),
    ({"criterion": ["float"]}, "option criterion: ['float'] is not one of"),
])
def test_records_built_in_python_are_validated_too(changes, message):
    """The viewer's widgets and the Python API build records directly: the same checks apply."""
    with pytest.raises(ValueError) as err:
        Options().with_(**changes)
    assert str(err.value).startswith(message)
