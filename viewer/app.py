"""The viewer's window and loop: glfw + moderngl + Dear ImGui, one frame at a time.

Frame: poll events -> backend new frames -> script inputs -> ImGui widgets -> apply worker
events -> draw the view (image, overlay, outlines) -> blit it -> ImGui on top -> swap.
Nothing raised inside a frame closes the window: it is logged and shown in the UI. Scene
files load off the UI thread (viewer.loader), so the window keeps drawing whatever a load does.
Ctrl-C (or SIGTERM) closes the window at the end of the frame; a tile still being traced
cannot be interrupted, so the command line (cli_view) ends the process without waiting for it.
"""
from __future__ import annotations

import ctypes
import signal
import sys
import threading
import time
import traceback

from imgui_bundle import imgui, implot  # before glfw: imgui_bundle points glfw at its own library

import glfw  # noqa: E402
import moderngl  # noqa: E402

from .display import Display  # noqa: E402
from .frame_events import EventSink  # noqa: E402
from .interaction import Interaction  # noqa: E402
from .loader import SceneLoader, adopt  # noqa: E402
from .overlay import Overlay  # noqa: E402
from .state import AppState, load_persistent, save_persistent  # noqa: E402
from .ui_camera import ui_camera  # noqa: E402
from .ui_display import ui_display  # noqa: E402
from .ui_help import ui_help  # noqa: E402
from .ui_inspector import ui_inspector  # noqa: E402
from .ui_log import ui_error, ui_log  # noqa: E402
from .ui_outputs import ui_outputs  # noqa: E402
from .ui_overlays import ui_overlays  # noqa: E402
from .ui_scene import ui_scene  # noqa: E402
from .ui_stats import ui_stats  # noqa: E402
from .ui_tracer import ui_tracer  # noqa: E402
from .ui_viewport import ui_viewport  # noqa: E402
from .worker import GeometryCache, RenderWorker  # noqa: E402

PANEL_WIDTH = 400
DEFAULT_WINDOW = (1240, 780)
MIN_WINDOW_HEIGHT = 720
TARGET_FPS = 60.0
BUSY_FPS = 36.0  # while tiles are traced: above the 30 frames/s promised, leaving CPU to the tracer
IDLE_WAIT = 0.1
AWAKE_AFTER_INPUT = 0.5
STOP_WAIT = 0.1  # seconds closing waits for a tile in flight before leaving it running
EXIT_INTERRUPTED = 130


class Viewer:
    """One window, its GL context, the state and the render worker."""

    def __init__(self, size=None, window_size=None, persist=True, title="psrt view"):
        self.state = AppState(fixed_size=tuple(size) if size else None)
        self.persist = persist
        if persist:
            load_persistent(self.state)
        if not glfw.init():
            raise RuntimeError("glfw.init failed: no display? (set DISPLAY, e.g. run under Xvfb)")
        for hint, value in ((glfw.CONTEXT_VERSION_MAJOR, 3), (glfw.CONTEXT_VERSION_MINOR, 3),
                            (glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE), (glfw.OPENGL_FORWARD_COMPAT, True)):
            glfw.window_hint(hint, value)
        if window_size is None:
            window_size = ((size[0] + PANEL_WIDTH, max(size[1], MIN_WINDOW_HEIGHT)) if size else DEFAULT_WINDOW)
        self.window = glfw.create_window(int(window_size[0]), int(window_size[1]), title, None, None)
        if not self.window:
            glfw.terminate()
            raise RuntimeError("glfw could not create an OpenGL 3.3 core window")
        glfw.set_window_pos(self.window, 0, 0)  # no window manager on Xvfb
        glfw.make_context_current(self.window)
        glfw.swap_interval(0)
        self.ctx = moderngl.create_context()
        imgui.create_context()
        implot.create_context()
        io = imgui.get_io()
        io.set_ini_filename("")
        # A panel that raises half-way leaves Begin/End unbalanced: ImGui closes them, not abort.
        io.config_error_recovery_enable_assert = False
        io.config_error_recovery_enable_debug_log = False  # we log the Python exception once
        self.window_address = ctypes.cast(self.window, ctypes.c_void_p).value
        imgui.backends.glfw_init_for_opengl(self.window_address, True)
        imgui.backends.opengl3_init("#version 330")
        glfw.set_drop_callback(self.window, self._on_drop)
        self.display = Display(self.ctx)
        if self.display.error:
            self.state.log(self.display.error, "error")
        self.geometry = GeometryCache()
        self.worker = RenderWorker(self.geometry)
        self.loader = SceneLoader()
        self.overlay = Overlay()
        self.events = EventSink(self)
        self.interaction = Interaction(self)
        self.region = (0, 0, 0, 0)
        self.last_frame_time = time.perf_counter()
        self.closed = False
        self.interrupted = False
        self._last_internal_error = None
        self.awake_until = 0.0

    # --- files ----------------------------------------------------------------------------
    def _on_drop(self, _window, paths):
        if paths:
            self.state.pending_open = paths[0]

    def open(self, path):
        """Start loading `path` off the UI thread (a load in flight is abandoned); returns the Load."""
        load = self.loader.start(path, self.state.opts.precision)
        self.state.loading = (load.name, load.started)
        return load

    def _poll_load(self) -> None:
        """Cancel, or adopt the finished load; either way the window never waits on it."""
        st = self.state
        if st.cancel_load:
            st.cancel_load = False
            load = self.loader.cancel()
            if load is not None:
                st.failed_loads.append(f"loading {load.path} cancelled")
                st.log(f"cancelled loading {load.path}" + ("; keeping the current scene" if st.scene else ""))
        load = self.loader.poll()
        if load is not None and adopt(st, self.geometry, load):
            self.overlay.reset(st.settings.overlay, st.image_size)
            self.display.set_boxes(None)
        st.loading = (self.loader.current.name, self.loader.current.started) if self.loader.current else None

    # --- layout ---------------------------------------------------------------------------
    def _layout(self) -> None:
        """Image region left of the panel; the image size follows it unless fixed."""
        win_w, win_h = glfw.get_window_size(self.window)
        avail_w, avail_h = max(win_w - PANEL_WIDTH, 1), max(win_h, 1)
        size = self.state.fixed_size or (avail_w, avail_h)
        if self.state.fixed_size:
            scale = min(1.0, avail_w / size[0], avail_h / size[1])  # shrink to fit, never enlarge
            self.region = (0, 0, size[0] * scale, size[1] * scale)
        else:
            self.region = (0, 0, avail_w, avail_h)
        if tuple(size) != tuple(self.state.image_size):
            self.state.image_size = tuple(size)
            self.display.resize(*size)
            self.overlay.reset(self.state.settings.overlay, size)
            self.state.render.key = None  # re-render at the new size

    # --- widgets --------------------------------------------------------------------------
    def _panels(self) -> None:
        st = self.state
        win_w, win_h = glfw.get_window_size(self.window)
        imgui.set_next_window_pos((win_w - PANEL_WIDTH, 0))
        imgui.set_next_window_size((PANEL_WIDTH, win_h))
        flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
        imgui.begin("psrt", None, flags)
        if self.display.error:
            imgui.text_colored((1.0, 0.35, 0.3, 1.0), "shader error (the image cannot be drawn):")
            imgui.text_wrapped(self.display.error)
            if imgui.button("Reload shaders"):
                if self.display.reload_shaders():
                    st.log("shaders reloaded")
        ui_error(st)
        if imgui.begin_tab_bar("tabs"):
            select = imgui.TabItemFlags_.set_selected if self.interaction.new_inspection else 0
            self.interaction.new_inspection = False
            for label, flags, panels in (("Controls", 0, (ui_scene, ui_camera, ui_tracer, ui_display, ui_overlays)),
                                         ("Inspector", select, (self._inspector,)),
                                         ("Stats & output", 0, (ui_stats, ui_outputs, ui_log))):
                if imgui.begin_tab_item(label, None, flags)[0]:
                    imgui.begin_child(label)  # tabs stay in view while the panels scroll
                    for panel in panels:
                        panel(st)
                    imgui.end_child()
                    imgui.end_tab_item()
            imgui.end_tab_bar()
        imgui.end()
        ui_help(st)
        self.interaction.hover_tooltip()
        ui_viewport(st, self.region)

    def _inspector(self, st) -> None:
        if ui_inspector(st):
            self.interaction.update_outlines()

    def _guard(self, step, *args):
        try:
            step(*args)
        except Exception as e:
            text = f"internal error in {step.__name__}: {type(e).__name__}: {e}"
            if text != self._last_internal_error:  # the same bug every frame is logged once
                self._last_internal_error = text
                self.state.log(f"{text}\n{traceback.format_exc(limit=5)}", "error")

    # --- one frame ------------------------------------------------------------------------
    def frame(self, script=None) -> None:
        st = self.state
        waiting = bool(st.loading or st.compiling or st.inspecting)  # their notes count seconds
        if script is None and st.render.phase in ("idle", "done", "error", "cancelled") and not waiting \
                and self.worker.events.empty() and time.perf_counter() > self.awake_until:
            start = time.perf_counter()
            glfw.wait_events_timeout(IDLE_WAIT)  # idle: sleep until input
            if time.perf_counter() - start < 0.9 * IDLE_WAIT:
                # Input arrived: ImGui needs a few frames in a row to act on it (press, release, redraw).
                self.awake_until = time.perf_counter() + AWAKE_AFTER_INPUT
        else:
            glfw.poll_events()
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        if script is not None:
            script.inject(self)
        imgui.new_frame()
        if st.pending_open:
            path, st.pending_open = st.pending_open, None
            self._guard(self.open, path)
        for step in (self._poll_load, self._layout, self.events.drain, self.interaction.handle_input, self._panels,
                     self.interaction.refresh_inspection, self.events.request, self.events.update_overlay):
            self._guard(step)  # one failing step must not stop the others, nor close the window
        imgui.render()
        fb_size = glfw.get_framebuffer_size(self.window)
        self.ctx.screen.use()
        self.ctx.viewport = (0, 0, *fb_size)
        self.ctx.clear(0.08, 0.08, 0.09)
        try:
            self.display.draw_view(st.settings, self.events.overlay_uniforms(), self.interaction.outline_view())
            win_w, _ = glfw.get_window_size(self.window)
            ratio = fb_size[0] / max(win_w, 1)
            self.display.blit(tuple(v * ratio for v in self.region), fb_size)
            if st.pending_screenshot:
                path, st.pending_screenshot = st.pending_screenshot, None
                from .outputs import write_png
                st.log(f"wrote {write_png(self.display.read_view(), path)}")
        except Exception as e:
            st.log(f"drawing failed: {type(e).__name__}: {e}", "error")
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
        if script is not None:
            script.after_draw(self, fb_size)
        glfw.swap_buffers(self.window)
        now = time.perf_counter()
        dt = now - self.last_frame_time
        busy = st.render.phase in ("coarse", "full", "reference") or waiting
        period = 1.0 / (BUSY_FPS if busy else TARGET_FPS)
        if dt < period:
            time.sleep(period - dt)
            now = time.perf_counter()
        st.fps = 0.9 * st.fps + 0.1 / max(now - self.last_frame_time, 1e-6) if st.fps else 1.0 / max(dt, 1e-6)
        if st.render.phase in ("coarse", "full", "reference"):
            st.busy_frame_times.append(now - self.last_frame_time)
            del st.busy_frame_times[:-2000]
        self.last_frame_time = now
        st.frame_count += 1

    def should_close(self) -> bool:
        return self.closed or glfw.window_should_close(self.window)

    def close(self) -> None:
        """Stop the worker (a tile in flight is left running) and close the window."""
        self.worker.stop(STOP_WAIT)
        if self.persist:
            save_persistent(self.state)
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        implot.destroy_context()
        imgui.destroy_context()
        glfw.destroy_window(self.window)
        glfw.terminate()


def _catch_interrupts(viewer) -> dict:
    """Ctrl-C and SIGTERM close the window at the end of the frame (a second Ctrl-C raises
    KeyboardInterrupt); returns the handlers to restore. Signals can be caught only on the
    main thread."""
    if threading.current_thread() is not threading.main_thread():
        return {}

    def close(signum, _frame):
        if viewer.interrupted and signum == signal.SIGINT:
            raise KeyboardInterrupt
        viewer.interrupted = viewer.closed = True

    return {sig: signal.signal(sig, close) for sig in (signal.SIGINT, signal.SIGTERM)}


def run(scene_path=None, max_frames=None, *, size=None, script=None, opts=None, settings=None,
        persist=None) -> int:
    """Open the viewer on a scene and run until the window closes (or the script is done).

    max_frames: an upper bound on frames (tests; with a script, its own limits apply: see
    viewer.script); script: a viewer.script.Script of actions and outputs; opts/settings: the
    starting Options and ViewSettings. Returns the exit code (130 after Ctrl-C); a failed
    script step is reported on stderr in one line. A tile, a load or a shading may still be
    running on its thread when it returns.
    """
    if persist is None:
        persist = script is None and max_frames is None
    viewer = Viewer(size=size, persist=persist)
    handlers = _catch_interrupts(viewer)
    code = 0
    try:
        if opts is not None:
            viewer.state.opts = opts
        if settings is not None:
            viewer.state.settings = settings
        if scene_path:
            viewer.open(scene_path)
        if script is not None:
            script.start(viewer)
        while not viewer.should_close():
            viewer.frame(script)
            if script is not None:
                if not script.done:
                    script.check_limits(viewer)
                if script.done:
                    break
            elif max_frames is not None and viewer.state.frame_count >= max_frames:
                break
        if viewer.interrupted:
            code = EXIT_INTERRUPTED
            if script is not None:
                script.interrupt(viewer)
        elif script is not None:
            code = script.exit_code
    finally:
        viewer.close()
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    if script is not None and script.failure:
        print(f"psrt view: error: {script.failure}", file=sys.stderr)
    return code
