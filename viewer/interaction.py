"""Mouse and keyboard on the image: orbit, pan, zoom, click to inspect, shortcuts, hover readout.

Input is read through ImGui (so scripted input injected into ImGui's IO takes the same path)
and ignored while ImGui wants it (a panel under the cursor, a text field with focus).
"""
from __future__ import annotations

import traceback

from imgui_bundle import imgui

from . import camera_control
from .picking import hover_values, inspect_pixel, outline_vertices, window_to_pixel
from .ui_camera import frame_scene, reset_view, restore_bookmark, save_bookmark

CLICK_SLOP = 3.0  # pixels the mouse may move between press and release and still be a click
BOOKMARK_KEYS = [getattr(imgui.Key, f"_{i}") for i in range(1, 10)]


class Interaction:
    def __init__(self, viewer):
        self.v = viewer
        self.left = None     # (x, y) where the left button went down on the image
        self.dragged = False
        self.middle = False
        self.hover = None
        self.new_inspection = False  # the panel switches to the Inspector tab once

    def _pixel(self, mx, my):
        return window_to_pixel(self.v.region, self.v.state.image_size, mx, my)

    def handle_input(self) -> None:
        st, io = self.v.state, imgui.get_io()
        self.hover = None
        if st.view is None:
            return
        mx, my = io.mouse_pos.x, io.mouse_pos.y
        over = not io.want_capture_mouse and self._pixel(mx, my) is not None
        if imgui.is_mouse_clicked(imgui.MouseButton_.left) and over:
            self.left, self.dragged = (mx, my), False
        if self.left is not None:
            if imgui.is_mouse_dragging(imgui.MouseButton_.left, CLICK_SLOP):
                self.dragged = True
                dx, dy = io.mouse_delta.x, io.mouse_delta.y
                if dx or dy:
                    if io.key_shift:
                        st.view = camera_control.pan(st.view, dx, dy, self.v.region[3])
                    else:
                        st.view = camera_control.orbit(st.view, dx, dy)
            if imgui.is_mouse_released(imgui.MouseButton_.left):
                if not self.dragged:
                    pixel = self._pixel(*self.left)
                    if pixel is not None:
                        self.inspect(*pixel)
                self.left = None
        if imgui.is_mouse_clicked(imgui.MouseButton_.middle) and over:
            self.middle = True
        if self.middle:
            dx, dy = io.mouse_delta.x, io.mouse_delta.y
            if dx or dy:
                st.view = camera_control.pan(st.view, dx, dy, self.v.region[3])
            if imgui.is_mouse_released(imgui.MouseButton_.middle):
                self.middle = False
        if over and io.mouse_wheel:
            st.view = camera_control.zoom(st.view, io.mouse_wheel)
        if over and self.left is None and not self.middle:
            self.hover = self._pixel(mx, my)
        if not io.want_capture_keyboard:
            self._keys(io)

    def _keys(self, io) -> None:
        st = self.v.state
        pressed = lambda key: imgui.is_key_pressed(key, False)  # noqa: E731
        if io.key_ctrl:
            if pressed(imgui.Key.s):
                from .ui_outputs import _next_name
                st.pending_screenshot = _next_name(st.output_dir or ".", "psrt-view", ".png")
            return
        if pressed(imgui.Key.f):
            frame_scene(st)
        if pressed(imgui.Key.r):
            reset_view(st)
        if pressed(imgui.Key.b):
            save_bookmark(st)
        for i, key in enumerate(BOOKMARK_KEYS):
            if pressed(key):
                restore_bookmark(st, i)
        if pressed(imgui.Key.h) or pressed(imgui.Key.f1):
            st.show_help = not st.show_help
        if pressed(imgui.Key.escape):
            st.inspector = None
            self.update_outlines()
        if pressed(imgui.Key.o):
            self.toggle_overlay()

    def toggle_overlay(self) -> None:
        from dataclasses import replace
        st = self.v.state
        if st.settings.overlay == "none":
            st.settings = replace(st.settings, overlay=st.last_overlay)
        else:
            st.last_overlay = st.settings.overlay
            st.settings = replace(st.settings, overlay="none")

    def inspect(self, px: int, py: int) -> bool:
        """Trace pixel (px, py) into the inspector; errors are shown, never raised."""
        st = self.v.state
        try:
            st.inspector = inspect_pixel(self.v.geometry, st.scene, st.opts, st.view, st.image_size, px, py)
        except Exception as e:
            st.log(f"inspecting pixel {px},{py} failed: {type(e).__name__}: {e}\n"
                   f"{traceback.format_exc(limit=3)}", "error")
            return False
        self.update_outlines()
        self.new_inspection = True
        t = st.inspector.trace
        st.log(f"pixel {px},{py}: " + (f"hit patch {t.patch} at t={t.t:.6g}" if t.hit else "miss") +
               f", {len(t.steps_f)} boxes")
        return True

    def refresh_inspection(self) -> None:
        """Re-trace the inspected pixel when the tracer options change (same view, same pixel)."""
        from .worker import trace_options
        st, ins = self.v.state, self.v.state.inspector
        if ins is None or ins.opts is None or ins.view != st.view or st.scene is None:
            return
        if trace_options(ins.opts) != trace_options(st.opts):
            step = ins.step
            ins.opts = st.opts  # a failing re-trace is reported once, not every frame
            if self.inspect(*ins.pixel) and 0 <= step < len(st.inspector.trace.steps_f) - 1:
                st.inspector.step = step
                self.update_outlines()
            self.new_inspection = False

    def update_outlines(self) -> None:
        ins = self.v.state.inspector
        self.v.display.set_boxes(outline_vertices(ins) if ins is not None else None)

    def outline_view(self):
        """Boxes are in world space: project them with the current view."""
        st = self.v.state
        return st.view if st.inspector is not None else None

    def view_changed(self) -> None:
        self.hover = None

    def hover_tooltip(self) -> None:
        if self.hover is None:
            return
        imgui.begin_tooltip()
        for label, text in hover_values(self.v.state, *self.hover):
            imgui.text(f"{label:9s} {text}")
        imgui.end_tooltip()
