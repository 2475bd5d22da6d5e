"""Status drawn over the image: a load in flight (with Cancel), a kernel compiling, a pixel being
traced for the inspector, the latest error.

These are what a user waits on before the first image, so they sit on the image itself, not
only in a panel. The lines drawn each frame are kept in state.notes (scripted runs record them).
"""
from __future__ import annotations

import time

from imgui_bundle import imgui

WARN_RGBA = (1.0, 0.8, 0.3, 1.0)
ERROR_RGBA = (1.0, 0.35, 0.3, 1.0)
_PASSIVE = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav
            | imgui.WindowFlags_.always_auto_resize | imgui.WindowFlags_.no_saved_settings)


def viewport_notes(state, now: float | None = None) -> list:
    """The status lines for the image: loading NAME... N s, compiling VARIANT... N s, tracing pixel X,Y... N s."""
    now = time.perf_counter() if now is None else now
    notes = []
    if state.loading is not None:
        name, since = state.loading
        notes.append(f"loading {name}... {now - since:.0f} s")
    if state.compiling is not None:
        variant, since = state.compiling
        notes.append(f"compiling {variant}... {now - since:.0f} s")
    if state.inspecting is not None:
        (px, py), since, compiling = state.inspecting
        also = f" (compiling {', '.join(compiling)})" if compiling else ""
        notes.append(f"tracing pixel {px},{py}{also}... {now - since:.0f} s")
    return notes


def ui_viewport(state, region) -> bool:
    """Draw the notes in the image's top-left corner and the error along its bottom; True when
    Cancel was pressed (state.cancel_load is set)."""
    x, y, w, h = region
    state.notes = viewport_notes(state)
    pressed = False
    if state.notes:
        imgui.set_next_window_pos((x + 8, y + 8), imgui.Cond_.always)
        imgui.set_next_window_bg_alpha(0.75)
        # Clicks pass through to the image unless there is a Cancel button to press.
        imgui.begin("##viewport-notes", None, _PASSIVE | (0 if state.loading else imgui.WindowFlags_.no_inputs))
        for line in state.notes:
            imgui.text_colored(WARN_RGBA, line)
            if line.startswith("loading ") and state.loading is not None:
                imgui.same_line()
                if imgui.small_button("Cancel"):
                    state.cancel_load = pressed = True
        imgui.end()
    if state.error:
        imgui.set_next_window_pos((x + 8, y + h - 8), imgui.Cond_.always, (0.0, 1.0))
        imgui.set_next_window_size((max(w - 16, 50), 0))
        imgui.set_next_window_bg_alpha(0.8)
        imgui.begin("##error-banner", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.no_inputs |
                    imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav)
        imgui.push_style_color(imgui.Col_.text, ERROR_RGBA)
        imgui.text_wrapped(state.error.splitlines()[0][:300])
        imgui.pop_style_color()
        imgui.end()
    return pressed
