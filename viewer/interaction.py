"""Mouse and keyboard on the image: orbit, pan, zoom, click to inspect, shortcuts, hover readout.

Input is read through ImGui (so scripted input injected into ImGui's IO takes the same path)
and ignored while ImGui wants it (a panel under the cursor, a text field with focus). A click's
pixel is traced on a thread of its own: its first trace compiles the step-recording kernels,
which must not stop the window drawing. The same thread then traces the pixel's ray tree, which
the inspector adopts when it is done (the pixel's own trace shows first).
"""
from __future__ import annotations

import threading
import time
import traceback

from imgui_bundle import imgui

from . import camera_control
import numpy as np

from .picking import hover_values, inspect_pixel, inspect_tree, outline_vertices, uncompiled_variants, window_to_pixel
from .ray_lines import ray_tree_vertices
from .ui_camera import frame_scene, reset_view, restore_bookmark, save_bookmark

CLICK_SLOP = 3.0  # pixels the mouse may move between press and release and still be a click
BOOKMARK_KEYS = [getattr(imgui.Key, f"_{i}") for i in range(1, 10)]


def _failure(e: Exception) -> str:
    return f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=3)}"


class PixelJob:
    """One pixel traced for the inspector on a daemon thread; `result` is an Inspection or an error,
    then `tree` its ray tree (tracer.ray_tree.RayTree) or an error."""

    def __init__(self, geometry, scene, opts, view, size, pixel, keep_step=None, select=True):
        self.pixel, self.keep_step, self.select, self.scene = pixel, keep_step, select, scene
        self.started = time.perf_counter()
        self.compiling = []  # variant labels its trace compiles first
        self.result = self.tree = None
        self.done, self.tree_done = threading.Event(), threading.Event()
        args = (geometry, scene, opts, view, size, *pixel)
        threading.Thread(target=self._run, args=args, name="psrt-inspect", daemon=True).start()

    def _run(self, geometry, scene, opts, *rest):
        try:
            self.compiling = uncompiled_variants(geometry, scene, opts)
            self.result = inspect_pixel(geometry, scene, opts, *rest)
        except Exception as e:
            self.result = _failure(e)
        self.done.set()
        if not isinstance(self.result, str):
            try:
                self.compiling = uncompiled_variants(geometry, scene, opts, tree=True)
                self.tree = inspect_tree(geometry, scene, opts, *rest)
            except Exception as e:
                self.tree = _failure(e)
        self.tree_done.set()


class Interaction:
    def __init__(self, viewer):
        self.v = viewer
        self.left = None     # (x, y) where the left button went down on the image
        self.dragged = False
        self.middle = False
        self.hover = None
        self.new_inspection = False  # the panel switches to the Inspector tab once
        self.pending: PixelJob | None = None  # the pixel being traced
        self.tree_pending: PixelJob | None = None  # the inspected pixel, its ray tree being traced

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
            st.inspector, self.pending, self.tree_pending = None, None, None
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

    def inspect(self, px: int, py: int, keep_step=None, select=True) -> PixelJob:
        """Start tracing pixel (px, py) for the inspector (a pixel still being traced is dropped)."""
        st = self.v.state
        self.pending = PixelJob(self.v.geometry, st.scene, st.opts, st.view, st.image_size, (px, py),
                                keep_step, select)
        return self.pending

    def _adopt_inspection(self, job: PixelJob) -> None:
        """The traced pixel into the inspector; errors are shown, never raised."""
        st = self.v.state
        px, py = job.pixel
        if job.scene is not st.scene:
            return  # another scene was opened meanwhile
        if isinstance(job.result, str):
            st.log(f"inspecting pixel {px},{py} failed: {job.result}", "error")
            return
        st.inspector = job.result
        if job.keep_step is not None and 0 <= job.keep_step < len(st.inspector.trace.steps_f) - 1:
            st.inspector.step = job.keep_step
        self.tree_pending = job
        self.update_outlines()
        self.new_inspection = job.select
        t = st.inspector.trace
        st.log(f"pixel {px},{py}: " + (f"hit patch {t.patch} at t={t.t:.6g}" if t.hit else "miss") +
               f", {len(t.steps_f)} boxes")

    def refresh_inspection(self) -> None:
        """Adopt a traced pixel; re-trace the inspected pixel when the tracer options change (same
        view, same pixel)."""
        from .worker import trace_options
        st, job = self.v.state, self.pending
        if job is not None:
            if not job.done.is_set():
                st.inspecting = (job.pixel, job.started, job.compiling)
                return
            self.pending = None
            self._adopt_inspection(job)
        st.inspecting = None
        tree = self.tree_pending
        if tree is not None:
            if tree.tree_done.is_set():
                self._adopt_tree(tree)
            else:  # the image says so while its first trace compiles the shadow rays' kernel
                st.inspecting = (tree.pixel, tree.started, tree.compiling)
        ins = st.inspector
        if ins is None or ins.opts is None or ins.view != st.view or st.scene is None:
            return
        if trace_options(ins.opts) != trace_options(st.opts):
            ins.opts = st.opts  # a failing re-trace is reported once, not every frame
            self.inspect(*ins.pixel, keep_step=ins.step, select=False)

    def _adopt_tree(self, job: PixelJob) -> None:
        """The ray tree into the inspection it belongs to (a newer click or Esc drops it)."""
        st, self.tree_pending = self.v.state, None
        ins = st.inspector
        if ins is None or ins is not job.result:
            return
        if isinstance(job.tree, str):
            ins.tree_error = job.tree
            st.log(f"ray tree of pixel {job.pixel[0]},{job.pixel[1]} failed: {job.tree}", "error")
            return
        ins.tree = job.tree
        self.update_outlines()

    def update_outlines(self) -> None:
        """The chosen trace's boxes, and the ray tree's rays while they are shown."""
        st = self.v.state
        ins = st.inspector
        if ins is None:
            return self.v.display.set_boxes(None)
        parts = [outline_vertices(ins)]
        if st.show_rays and ins.tree is not None and ins.view is not None:
            try:
                parts.append(ray_tree_vertices(ins.tree, ins.view, ins.ray))
            except Exception as e:  # the boxes are still worth drawing
                st.log(f"cannot draw the ray tree: {_failure(e)}", "error")
        self.v.display.set_boxes(np.concatenate(parts))

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
