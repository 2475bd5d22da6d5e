"""Tracer panel: every non-display field of tracer.options.Options, generated from its metadata."""
from __future__ import annotations

from imgui_bundle import imgui

from .ui_fields import groups_of, record_widgets

DISPLAY_GROUP = "Display"


def ui_tracer(state) -> bool:
    """Returns True when a tracer option changed (the render restarts)."""
    if not imgui.collapsing_header("Tracer", imgui.TreeNodeFlags_.default_open):
        return False
    changed_any = False
    for group in groups_of(state.opts, exclude=(DISPLAY_GROUP,)):
        if group != "Tracer":
            imgui.separator_text(group)
        changed, state.opts, error = record_widgets(state.opts, groups=(group,))
        changed_any |= changed
        if error:
            state.log(error, "error")
    return changed_any
