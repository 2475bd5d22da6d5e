"""Frozen records whose fields describe themselves, and `name=value` assignments to them.

A field declared with `described` carries its help text, choices or range, log scale, group,
flag name and `when` (the values of other fields it applies under) in its metadata. The CLI
builds its flags and the viewer its widgets from that metadata; `Record` validates every
new value against it, and `assign` parses `--set name=value`. tracer.options.Options and the
viewer's ViewSettings are such records: messages name the field with the record's NOUN
("option criterion: ...", "setting overlay: ...").
"""
from __future__ import annotations

from dataclasses import field, fields, replace
from typing import ClassVar


def described(default, help, *, group, choices=None, lo=None, hi=None, log=False, cli=None, when=None):
    """A dataclass field with its description: choices, or a range lo..hi (log: on a log scale);
    group: the CLI's argument group and the viewer's panel section; cli: the flag's name if not
    the field's; when: {field: value} under which the field applies."""
    meta = {"help": help, "choices": choices, "lo": lo, "hi": hi, "log": log, "group": group, "cli": cli,
            "when": when}
    return field(default=default, metadata=meta)


class Record:
    """Base of frozen dataclasses made of `described` fields: each instance is validated."""

    NOUN: ClassVar[str] = "field"  # how messages name a field: "option", "setting"

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            meta = f.metadata
            if meta["choices"] is not None and value not in meta["choices"]:
                raise ValueError(f"{self.NOUN} {f.name}: {value!r} is not one of {', '.join(meta['choices'])}")
            if meta["lo"] is not None and not (meta["lo"] <= value <= meta["hi"]):
                raise ValueError(f"{self.NOUN} {f.name}: {value!r} is outside [{meta['lo']}, {meta['hi']}]")

    def with_(self, **changes):
        """A copy with some fields changed, validated."""
        return replace(self, **changes)


def assign(records: tuple, text: str) -> tuple:
    """Apply one `name=value` (as given to `--set`) to whichever of the records has that field;
    returns the records, that one replaced. Unknown names list the fields of all of them."""
    noun = records[0].NOUN
    if "=" not in text:
        raise ValueError(f"expected {noun}=value, got {text!r}")
    name, raw = (s.strip() for s in text.split("=", 1))
    for k, record in enumerate(records):
        by_name = {f.name: f for f in fields(record)}
        if name in by_name:
            value = parse_value(by_name[name], raw, record.NOUN)
            return records[:k] + (replace(record, **{name: value}),) + records[k + 1:]
    known = [f.name for record in records for f in fields(record)]
    raise ValueError(f"unknown {noun} {name!r} (known: {', '.join(known)})")


def parse_value(f, raw: str, noun: str):
    """The text `raw` as a value of field f, of the type of its default."""
    kind = type(f.default)
    try:
        return parse_bool(raw) if kind is bool else kind(float(raw)) if kind in (int, float) else kind(raw)
    except ValueError:
        raise ValueError(f"{noun} {f.name}: cannot read {raw!r} as {kind.__name__}") from None


def parse_bool(raw: str) -> bool:
    """true/false, on/off, yes/no, 1/0."""
    word = raw.strip().lower()
    if word in ("true", "on", "yes", "1"):
        return True
    if word in ("false", "off", "no", "0"):
        return False
    raise ValueError(f"cannot read {raw!r} as a boolean (true/false)")
