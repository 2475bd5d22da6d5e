"""Camera panel: frame, reset, field of view, bookmarks."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from imgui_bundle import imgui

from . import camera_control


def frame_scene(state) -> bool:
    if state.scene is None or state.view is None:
        return False
    state.view = camera_control.frame_scene(state.view, *state.scene.bounds())
    return True


def reset_view(state) -> bool:
    if state.home_view is None:
        return False
    state.view = state.home_view
    return True


def save_bookmark(state) -> None:
    if state.view is not None:
        state.bookmarks.append((f"view {len(state.bookmarks) + 1}", state.view))
        state.log(f"saved camera bookmark {len(state.bookmarks)}")


def restore_bookmark(state, index: int) -> bool:
    if 0 <= index < len(state.bookmarks):
        state.view = state.bookmarks[index][1]
        return True
    return False


def ui_camera(state) -> bool:
    """Returns True when the view changed."""
    if not imgui.collapsing_header("Camera") or state.view is None:
        return False
    changed = False
    if imgui.button("Frame scene (F)"):
        changed |= frame_scene(state)
    imgui.same_line()
    if imgui.button("Reset (R)"):
        changed |= reset_view(state)
    imgui.same_line()
    if imgui.button("Bookmark (B)"):
        save_bookmark(state)
    v = state.view
    imgui.text(f"eye     {np.array2string(np.asarray(v.eye), precision=3)}")
    imgui.text(f"look at {np.array2string(np.asarray(v.look_at), precision=3)}")
    moved, fov = imgui.slider_float("fov (deg)", float(v.fov_deg), 1.0, 150.0, "%.1f")
    if moved:
        state.view, changed = replace(v, fov_deg=fov), True
    remove = None
    for i, (name, _) in enumerate(state.bookmarks):
        imgui.push_id(i)
        if imgui.button(f"{name}" + (f"  ({i + 1})" if i < 9 else "")):
            changed |= restore_bookmark(state, i)
        imgui.same_line()
        if imgui.small_button("x"):
            remove = i
        imgui.pop_id()
    if remove is not None:
        del state.bookmarks[remove]
    return changed
