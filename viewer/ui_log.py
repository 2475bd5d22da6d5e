"""Message area: the latest error (red, dismissable) and a log of recent messages."""
from __future__ import annotations

import time

from imgui_bundle import imgui

ERROR_RGBA = (1.0, 0.35, 0.3, 1.0)
LEVEL_RGBA = {"error": ERROR_RGBA, "warning": (1.0, 0.8, 0.3, 1.0), "info": (0.75, 0.75, 0.75, 1.0)}


def ui_error(state) -> bool:
    if not state.error:
        return False
    imgui.push_style_color(imgui.Col_.text, ERROR_RGBA)
    imgui.text_wrapped(state.error)
    imgui.pop_style_color()
    if imgui.small_button("dismiss"):
        state.error = None
    imgui.separator()
    return False


def ui_log(state) -> bool:
    if not imgui.collapsing_header(f"Messages ({len(state.messages)})"):
        return False
    for stamp, level, text in reversed(state.messages[-50:]):
        imgui.text_colored(LEVEL_RGBA.get(level, LEVEL_RGBA["info"]),
                           f"{time.strftime('%H:%M:%S', time.localtime(stamp))} {text}")
    return False
