"""Frozen records whose fields describe themselves, and `name=value` assignments to them.

A field declared with `described` carries its help text, choices or range, log scale, group,
flag name and `when` (the values of other fields it applies under) in its metadata. The CLI
builds its flags and the viewer its widgets from that metadata; `Record` validates every
new value against it (type, integrality, finiteness, range or choices), and `assign` parses
`--set name=value`. tracer.options.Options and the viewer's ViewSettings are such records:
messages name the field with the record's NOUN ("option criterion: ...", "setting overlay: ...").
Numbers in text are plain ASCII decimals (no `_` separators, other scripts' digits, inf or nan),
compared with the range exactly before they are converted, so `1e400` is out of range, not a
traceback.
"""
from __future__ import annotations

import math
import numbers
import re
from dataclasses import field, fields, replace
from decimal import Decimal
from typing import ClassVar

import numpy as np

# An ASCII decimal number: what a user means by a number on a command line.
NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)
MAX_QUOTE = 80  # messages quote at most this many characters of a bad value; longer numbers are refused


def described(default, help, *, group, choices=None, lo=None, hi=None, log=False, cli=None, when=None):
    """A dataclass field with its description: choices, or a range lo..hi (log: on a log scale);
    group: the CLI's argument group and the viewer's panel section; cli: the flag's name if not
    the field's; when: {field: value} under which the field applies."""
    meta = {"help": help, "choices": choices, "lo": lo, "hi": hi, "log": log, "group": group, "cli": cli,
            "when": when}
    return field(default=default, metadata=meta)


def quote(value) -> str:
    """repr(value), cut to MAX_QUOTE characters (a bad value may be a megabyte long)."""
    try:
        text = repr(value)
    except ValueError:  # an int too long for str()
        return f"<an integer of {value.bit_length()} bits>"
    return text if len(text) <= MAX_QUOTE else text[:MAX_QUOTE - 3] + "..."


def expected(f) -> str:
    """What field f takes, for messages: 'an integer in [4, 256]', 'one of float, fixed', ..."""
    meta, kind = f.metadata, type(f.default)
    if meta["choices"] is not None:
        return f"one of {', '.join(meta['choices'])}"
    if kind is bool:
        return "true or false"
    what = "an integer" if kind is int else "a number"
    return what if meta["lo"] is None else f"{what} in [{meta['lo']}, {meta['hi']}]"


def checked(f, value):
    """value as a valid value of field f (ints and floats normalised to the field's type);
    ValueError naming the value and what is expected, without the field's name."""
    meta, kind = f.metadata, type(f.default)
    if kind is bool:
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"{quote(value)} is not a boolean (expected {expected(f)})")
        return bool(value)
    if kind in (int, float):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ValueError(f"{quote(value)} is not a number (expected {expected(f)})")
        if not isinstance(value, numbers.Integral) and not math.isfinite(value):
            raise ValueError(f"{quote(value)} is not finite (expected {expected(f)})")
        if kind is int and not isinstance(value, numbers.Integral) and value != math.floor(value):
            raise ValueError(f"{quote(value)} is not an integer (expected {expected(f)})")
        if meta["lo"] is not None and not (meta["lo"] <= value <= meta["hi"]):
            raise ValueError(f"{quote(value)} is outside [{meta['lo']}, {meta['hi']}]")
        return int(value) if kind is int else float(value)
    if meta["choices"] is not None and (not isinstance(value, str) or value not in meta["choices"]):
        raise ValueError(f"{quote(value)} is not {expected(f)}")
    if not isinstance(value, kind):
        raise ValueError(f"{quote(value)} is not a {kind.__name__}")
    return value


class Record:
    """Base of frozen dataclasses made of `described` fields: each instance is validated."""

    NOUN: ClassVar[str] = "field"  # how messages name a field: "option", "setting"

    def __post_init__(self):
        for f in fields(self):
            try:
                value = checked(f, getattr(self, f.name))
            except ValueError as e:
                raise ValueError(f"{self.NOUN} {f.name}: {e}") from None
            object.__setattr__(self, f.name, value)  # 8.0 for an int field is stored as 8

    def with_(self, **changes):
        """A copy with some fields changed, validated."""
        return replace(self, **changes)


def assign(records: tuple, text: str) -> tuple:
    """Apply one `name=value` (as given to `--set`) to whichever of the records has that field;
    returns the records, that one replaced. Unknown names list the fields of all of them."""
    noun = records[0].NOUN
    if "=" not in text:
        raise ValueError(f"expected {noun}=value, got {quote(text)}")
    name, raw = (s.strip() for s in text.split("=", 1))
    for k, record in enumerate(records):
        by_name = {f.name: f for f in fields(record)}
        if name in by_name:
            value = parse_value(by_name[name], raw, record.NOUN)
            return records[:k] + (replace(record, **{name: value}),) + records[k + 1:]
    known = [f.name for record in records for f in fields(record)]
    raise ValueError(f"unknown {noun} {quote(name)} (known: {', '.join(known)})")


def parse_value(f, raw: str, noun: str):
    """The text `raw` as a valid value of field f, of the type of its default; ValueError
    "<noun> <field>: ..." naming the value and what is expected."""
    try:
        return read_value(f, raw)
    except ValueError as e:
        raise ValueError(f"{noun} {f.name}: {e}") from None


def read_value(f, raw: str):
    """The text `raw` as a valid value of field f; ValueError naming the value and what is
    expected, without the field's name (the CLI's flags prefix the flag instead)."""
    kind = type(f.default)
    if kind is bool:
        try:
            return parse_bool(raw)
        except ValueError:
            raise ValueError(f"cannot read {quote(raw)} as bool (expected {expected(f)})") from None
    if kind in (int, float):
        if len(raw) > MAX_QUOTE or not NUMBER.fullmatch(raw):
            raise ValueError(f"cannot read {quote(raw)} as {kind.__name__} (expected {expected(f)})")
        exact, meta = Decimal(raw), f.metadata
        if kind is int and exact != exact.to_integral_value():
            raise ValueError(f"{raw} is not an integer (expected {expected(f)})")
        if meta["lo"] is not None and not (Decimal(repr(meta["lo"])) <= exact <= Decimal(repr(meta["hi"]))):
            raise ValueError(f"{raw} is outside [{meta['lo']}, {meta['hi']}]")
        return checked(f, int(exact) if kind is int else float(exact))
    return checked(f, raw)


def parse_bool(raw: str) -> bool:
    """true/false, on/off, yes/no, 1/0."""
    word = raw.strip().lower()
    if word in ("true", "on", "yes", "1"):
        return True
    if word in ("false", "off", "no", "0"):
        return False
    raise ValueError(f"cannot read {quote(raw)} as a boolean (true/false)")
