"""Outputs panel: screenshot, AOV export, trace export into one output directory."""
from __future__ import annotations

import os

from imgui_bundle import imgui

from . import outputs


def _next_name(directory: str, stem: str, ext: str) -> str:
    i = 1
    while os.path.exists(os.path.join(directory, f"{stem}-{i:03d}{ext}")):
        i += 1
    return os.path.join(directory, f"{stem}-{i:03d}{ext}")


def ui_outputs(state) -> bool:
    """Buttons write files at once, except the screenshot, which the loop takes after drawing."""
    if not imgui.collapsing_header("Outputs"):
        return False
    imgui.set_next_item_width(-90)
    _, state.output_dir = imgui.input_text("directory", state.output_dir)
    directory = os.path.expanduser(state.output_dir or ".")
    if imgui.button("Screenshot (Ctrl+S)"):
        state.pending_screenshot = _next_name(directory, "psrt-view", ".png")
    imgui.same_line()
    done = state.render.phase in ("reference", "done")
    imgui.begin_disabled(not done)
    if imgui.button("AOVs .npz"):
        try:
            state.log(f"wrote {outputs.write_aovs(state.render.frame, _next_name(directory, 'psrt-aov', '.npz'))}")
        except (OSError, ValueError) as e:
            state.log(f"AOV export failed: {e}", "error")
    imgui.end_disabled()
    imgui.same_line()
    imgui.begin_disabled(state.inspector is None)
    if imgui.button("Trace .json"):
        try:
            state.log(f"wrote {outputs.write_trace(state.inspector, _next_name(directory, 'psrt-trace', '.json'))}")
        except (OSError, ValueError) as e:
            state.log(f"trace export failed: {e}", "error")
    imgui.end_disabled()
    return False
