"""Display panel: the display mode (an Options field) and the tone mapping (ViewSettings)."""
from __future__ import annotations

from imgui_bundle import imgui

from .ui_fields import record_widgets


def ui_display(state) -> bool:
    """Returns True when the display mode changed (the image is re-shaded, not re-traced)."""
    if not imgui.collapsing_header("Display", imgui.TreeNodeFlags_.default_open):
        return False
    mode_changed, state.opts, error = record_widgets(state.opts, groups=("Display",))
    _, state.settings, error2 = record_widgets(state.settings, groups=("Display",))
    for e in (error, error2):
        if e:
            state.log(e, "error")
    return mode_changed
