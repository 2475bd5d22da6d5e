"""Widgets generated from a frozen dataclass's field metadata (help, choices, lo, hi, log, group).

The Tracer and Display panels are built from tracer.options.Options and
viewer.state.ViewSettings through this one function, so every option the CLI
knows appears in the viewer with the same name, range and help.
"""
from __future__ import annotations

from dataclasses import fields, replace

from imgui_bundle import imgui

WIDE_RANGE = 1e6  # beyond this span a slider is useless: type the number


def applies(record, f) -> bool:
    """Whether field f matters for the record's current values.

    Metadata `when={"field": value}` says so explicitly; otherwise a help text that starts
    with "<choice>:" where <choice> is a choice of another field (e.g. "fixed: ...") ties the
    field to that choice being selected.
    """
    when = f.metadata.get("when")
    if when:
        return all(getattr(record, k) == v for k, v in when.items())
    head = f.metadata.get("help", "").split(":", 1)[0].strip()
    for other in fields(record):
        choices = other.metadata.get("choices")
        if other is not f and choices and head in choices:
            return getattr(record, other.name) == head
    return True


def field_widget(record, f):
    """One widget for field f; returns (changed, value)."""
    meta, value, label = f.metadata, getattr(record, f.name), f.name.replace("_", " ")
    choices, lo, hi = meta.get("choices"), meta.get("lo"), meta.get("hi")
    log_flag = imgui.SliderFlags_.logarithmic if meta.get("log") else 0
    if choices:
        items = list(choices)
        changed, idx = imgui.combo(label, items.index(value) if value in items else 0, items)
        return changed, items[idx]
    if isinstance(value, bool):
        return imgui.checkbox(label, value)
    if isinstance(value, int):
        if lo is not None and hi - lo <= WIDE_RANGE * 2:
            return imgui.slider_int(label, value, int(lo), int(hi), "%d",
                                    log_flag | imgui.SliderFlags_.always_clamp)
        changed, v = imgui.input_int(label, value)
        return changed, v if lo is None else int(min(max(v, lo), hi))
    if isinstance(value, float):
        if lo is not None and (meta.get("log") or hi - lo <= WIDE_RANGE):
            return imgui.slider_float(label, value, float(lo), float(hi), "%.4g",
                                      log_flag | imgui.SliderFlags_.always_clamp)
        return imgui.input_double(label, value, 0.0, 0.0, "%.6g")
    imgui.text(f"{label}: {value}")
    return False, value


def record_widgets(record, groups=None, exclude=()):
    """Widgets for the fields of `record` in `groups` (None: all); returns (changed, record, error).

    Fields that do not apply to the current values are shown disabled. A value the record's
    validation rejects leaves the record unchanged and returns the message.
    """
    changed_any, error = False, None
    for f in fields(record):
        if (groups is not None and f.metadata.get("group") not in groups) or f.name in exclude:
            continue
        active = applies(record, f)
        imgui.begin_disabled(not active)
        changed, value = field_widget(record, f)
        imgui.end_disabled()
        help_text = f.metadata.get("help")
        if help_text:
            imgui.set_item_tooltip(f"{f.name}: {help_text}")
        if changed and value != getattr(record, f.name):
            try:
                record = replace(record, **{f.name: value})
                changed_any = True
            except ValueError as e:
                error = str(e)
    return changed_any, record, error


def groups_of(record, exclude=()) -> list:
    """The metadata groups of a record's fields, in declaration order."""
    seen = []
    for f in fields(record):
        g = f.metadata.get("group")
        if g not in seen and g not in exclude:
            seen.append(g)
    return seen
