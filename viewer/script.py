"""Scripted runs of the real window (`psrt view --click/--set/--load/--screenshot ...`).

The script applies its actions in order (settings, mid-render changes, the click, a file to
load), waits for the render to finish, writes its outputs and stops. The click goes through
ImGui's input queue, the same path as a real mouse click.

Waiting is bounded by time, never by frames, so a slow or busy machine gives the same result:
a step that waits for a load, a compile or a render waits for it, up to `timeout` seconds of
wall clock (exit 3). `frames` bounds only the frames drawn while the script waits for nothing
(say, for a frame-numbered --at). A step that fails (a load, the render, the click, an output)
gives its own non-zero exit code and one line saying why (Script.failure).
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, fields

from imgui_bundle import imgui

from tracer.stats import json_safe
from tracer.variants import compile_report

from . import outputs
from .picking import pixel_to_window, shown_trace
from .state import assign

EXIT_OK, EXIT_BAD_ARGS, EXIT_TIMEOUT, EXIT_CLICK, EXIT_LOAD, EXIT_RENDER = 0, 2, 3, 4, 5, 6
EXIT_INTERRUPTED = 130
MID_RENDER = "mid-render"
AFTER_RENDER = "after-render"
WHENS = (MID_RENDER, AFTER_RENDER)


def parse_at(text: str):
    """'N:name=value' (at UI frame N), 'mid-render:name=value' (once full tiles are arriving) or
    'after-render:name=value' (once the frame is traced, however long that takes)."""
    when, sep, assignment = text.partition(":")
    if not sep or "=" not in assignment:
        raise ValueError(f"--at expects FRAME:option=value or {'/'.join(WHENS)}:option=value, got {text!r}")
    if when not in WHENS:
        try:
            when = int(when)
        except ValueError:
            raise ValueError(f"--at {text!r}: {when!r} is neither a frame number nor one of "
                             f"{', '.join(WHENS)}") from None
    return when, assignment


def _fps_summary(frame_times) -> dict | None:
    """UI frames per second while a render ran: mean and the slowest 5% of frames."""
    if not frame_times:
        return None
    t = sorted(frame_times)
    return {"frames": len(t), "mean_fps": len(t) / sum(t), "p95_frame_ms": 1000 * t[int(0.95 * (len(t) - 1))],
            "max_frame_ms": 1000 * t[-1]}


CLICK_SETTLE_FRAMES = 8


@dataclass
class Script:
    sets: list = field(default_factory=list)        # "name=value", before the first render
    at: list = field(default_factory=list)          # (frame, MID_RENDER or AFTER_RENDER, "name=value")
    click: tuple | None = None                      # image pixel (column, row)
    load: str | None = None                         # opened once the first render has finished
    screenshot: str | None = None                   # the view (image, overlay, outlines), PNG
    window_screenshot: str | None = None            # the whole window, PNG
    dump_inspector: str | None = None               # the clicked pixel's trace JSON
    aov: str | None = None                          # the final render's AOVs, npz
    status: str | None = None                       # what happened, JSON (for tests)
    wait_reference: bool | None = None              # None: when the overlay channel needs it
    frames: int | None = None                       # frames drawn while waiting for nothing
    timeout: float | None = None                    # wall-clock seconds for the whole run
    done: bool = False
    exit_code: int = EXIT_OK
    failure: str | None = None                      # one line: the first step that failed
    compiles: dict = field(default_factory=dict)    # what was shown while kernels compiled
    applied: list = field(default_factory=list)
    _pending_at: list = field(default_factory=list)
    _click_stage: int = 0
    _click_pos: tuple = (0.0, 0.0)
    _click_done: int = -1  # the frame the click reached the inspector
    _loaded_at: int | None = None
    _started: float = 0.0
    _free_frames: int = 0   # frames drawn while waiting for nothing
    _hold = None            # the worker's mid-render hold, set once mid-render changes are made
    _last_frame: float = 0.0

    def start(self, viewer) -> None:
        st = viewer.state
        self._started = self._last_frame = time.perf_counter()
        for text in self.sets:
            st.opts, st.settings = assign(st.opts, st.settings, text)
        self._pending_at = list(self.at)
        if any(when == MID_RENDER for when, _ in self.at):
            self._hold = viewer.worker.hold_mid_render()

    def fail(self, code: int, message: str) -> None:
        """Record a failed step; the first failure gives the exit code and the message."""
        if self.exit_code == EXIT_OK:
            self.exit_code, self.failure = code, message.splitlines()[0] if message else message

    # --- per frame ------------------------------------------------------------------------
    def _apply_due(self, viewer) -> None:
        st, r = viewer.state, viewer.state.render
        mid = r.phase == "full" and 0 < r.tiles_done < max(r.tiles_total, 1)
        # A render too quick to catch mid-way: apply anyway (the status records the phase).
        late = r.phase in ("reference", "done", "error")
        for item in list(self._pending_at):
            when, text = item
            if ((when == MID_RENDER and (mid or late)) or (when == AFTER_RENDER and late)
                    or (when not in WHENS and st.frame_count >= when)):
                self._pending_at.remove(item)
                try:
                    st.opts, st.settings = assign(st.opts, st.settings, text)
                except ValueError as e:
                    st.log(str(e), "error")
                    self.fail(EXIT_BAD_ARGS, f"--at {text}: {e}")
                self.applied.append({"frame": st.frame_count, "set": text, "phase": r.phase,
                                     "tiles_done": r.tiles_done, "tiles_total": r.tiles_total})
        if self._hold is not None and not any(when == MID_RENDER for when, _ in self._pending_at):
            self._hold.set()  # the render that was held after its first tile goes on

    def inject(self, viewer) -> None:
        """Called after the backends' new frame and before ImGui's: actions and mouse input."""
        st, io = viewer.state, imgui.get_io()
        self._apply_due(viewer)
        ready = not self._pending_at and self.render_ready(viewer)
        if self.click is not None and self._click_stage < 5:
            if self._click_stage == 0 and ready:
                x, y = self.click
                w, h = st.image_size
                if not (0 <= x < w and 0 <= y < h):
                    st.log(f"--click {x},{y} is outside the {w}x{h} image", "error")
                    self.fail(EXIT_CLICK, f"--click {x},{y} is outside the {w}x{h} image")
                    self._click_stage = 5
                    return
                self._click_pos = pixel_to_window(viewer.region, st.image_size, x, y)
                self._click_stage = 1
            elif self._click_stage >= 1:
                io.add_mouse_pos_event(*self._click_pos)  # the glfw backend overwrites it each frame
                if self._click_stage == 4 and (viewer.interaction.pending or viewer.interaction.tree_pending):
                    return  # the pixel, then its ray tree, is being traced (the first trace compiles kernels)
                if self._click_stage in (2, 3):
                    io.add_mouse_button_event(0, self._click_stage == 2)
                if self._click_stage == 4:
                    ins = st.inspector
                    if ins is None or tuple(ins.trace.pixel) != tuple(self.click):
                        st.log(f"scripted click at {self.click} did not reach the inspector", "error")
                        self.fail(EXIT_CLICK, f"the click at {self.click} did not reach the inspector")
                    self._click_done = st.frame_count
                self._click_stage += 1
            return
        if self.load is not None and self._loaded_at is None and ready:
            st.pending_open, self._loaded_at = self.load, st.frame_count

    def render_ready(self, viewer) -> bool:
        """The render of the current state has finished (and its reference, when needed)."""
        st, r = viewer.state, viewer.state.render
        if st.frame_count < 1 or st.loading is not None or st.pending_open:
            return False  # no layout yet, or a scene on its way
        key = viewer.events.desired_key()
        if key is None:
            return st.scene is None
        if r.phase == "error":
            return r.key == key
        if r.key != key or r.frame is None or r.phase not in ("reference", "done") \
                or r.tiles_done < r.tiles_total or viewer.events.shaded_mode != st.opts.mode:
            return False
        ch = viewer.overlay.channel if st.settings.overlay != "none" else None
        need = self.wait_reference if self.wait_reference is not None else bool(ch and ch.needs_reference)
        if need and (r.phase != "done" or r.reference is None):
            return False
        return ch is None or not viewer.overlay.dirty_range  # the legend's range is up to date

    def finished(self, viewer) -> bool:
        if self._pending_at or (self.click is not None and self._click_stage < 5):
            return False
        if self.click is not None and viewer.state.frame_count < self._click_done + CLICK_SETTLE_FRAMES:
            return False  # the inspector's auto-fitted columns take a few frames to settle
        if self.load is not None and (self._loaded_at is None or viewer.state.frame_count < self._loaded_at + 2):
            return False
        return self.render_ready(viewer)

    def waiting_for(self, viewer) -> str | None:
        """What the script waits on now (a load, a compile, the render, the click), or None."""
        st, r = viewer.state, viewer.state.render
        if st.loading is not None:
            name, since = st.loading
            return f"loading {name} ({time.perf_counter() - since:.0f} s)"
        if st.compiling is not None:
            variant, since = st.compiling
            return f"compiling the {variant} kernel ({time.perf_counter() - since:.0f} s)"
        if (self.load is not None and self._loaded_at is None) or not self.render_ready(viewer):
            return f"the render ({r.phase}, {r.tiles_done}/{r.tiles_total} tiles)"
        if self.click is not None and (self._click_stage < 5 or st.frame_count < self._click_done + CLICK_SETTLE_FRAMES):
            return "the click to reach the inspector"
        if self.load is not None and st.frame_count < self._loaded_at + 2:
            return f"loading {self.load}"
        return None

    def _observe(self, viewer) -> None:
        """While a kernel compiles: how many frames were drawn, the longest gap, what they showed."""
        now = time.perf_counter()
        gap, self._last_frame = now - self._last_frame, now
        st = viewer.state
        if st.compiling is None:
            return
        variant, since = st.compiling
        c = self.compiles.setdefault(variant, {"frames": 0, "max_gap_ms": 0.0, "notes": []})
        c["frames"] += 1
        c["seconds"] = now - since
        if c["frames"] > 1:
            c["max_gap_ms"] = max(c["max_gap_ms"], 1000 * gap)
        note = next((n for n in st.notes if n.startswith("compiling ")), None)
        if note and note not in c["notes"]:
            c["notes"].append(note)

    def after_draw(self, viewer, fb_size) -> None:
        """After the view and ImGui are drawn, before the swap: outputs when everything is done."""
        self._observe(viewer)
        if self.done:
            return
        if self.finished(viewer):
            self._check_steps(viewer)
            self.write_outputs(viewer, fb_size)
            self.done = True
        elif self.waiting_for(viewer) is None:
            self._free_frames += 1

    def _check_steps(self, viewer) -> None:
        """A load that failed (the scene or --load) or a failed render fails the script."""
        st = viewer.state
        if st.failed_loads:
            self.fail(EXIT_LOAD, st.failed_loads[0])
        if st.render.phase == "error":
            self.fail(EXIT_RENDER, st.error or "the render failed")

    def check_limits(self, viewer) -> None:
        """After each frame: give up past the wall-clock timeout, or past `frames` free frames."""
        elapsed = time.perf_counter() - self._started
        if self.timeout is not None and elapsed > self.timeout:
            what = self.waiting_for(viewer) or "frame-numbered --at changes"
            self.give_up(viewer, f"timed out after {elapsed:.1f} s (--timeout {self.timeout:g}) waiting for {what}")
        elif self.frames is not None and self._free_frames >= self.frames:
            self.give_up(viewer, f"stopped after {self.frames} frames (--frames) before the script finished")

    def give_up(self, viewer, message: str) -> None:
        viewer.state.log(message, "error")
        self._check_steps(viewer)  # a failed load explains a timeout better than the timeout
        self.fail(EXIT_TIMEOUT, message)
        self.write_outputs(viewer, None)
        self.done = True

    def interrupt(self, viewer) -> None:
        """Ctrl-C: the run ends as interrupted, whatever failed before; only the status is written."""
        self.exit_code, self.failure = EXIT_INTERRUPTED, "interrupted"
        self.screenshot = self.window_screenshot = self.dump_inspector = self.aov = None
        self.write_outputs(viewer, None)
        self.done = True

    # --- outputs --------------------------------------------------------------------------
    def write_outputs(self, viewer, fb_size) -> None:
        st = viewer.state
        jobs = [(self.screenshot, lambda p: outputs.write_png(viewer.display.read_view(), p)),
                (self.window_screenshot,
                 lambda p: outputs.write_png(viewer.display.read_window(fb_size), p) if fb_size else None),
                (self.dump_inspector, lambda p: outputs.write_trace(st.inspector, p)),
                (self.aov, lambda p: outputs.write_aovs(st.render.frame, p))]
        for path, write in jobs:
            if path:
                try:
                    write(path)
                except Exception as e:
                    st.log(f"cannot write {path}: {type(e).__name__}: {e}", "error")
                    self.fail(EXIT_BAD_ARGS, f"cannot write {path}: {type(e).__name__}: {e}")
        if self.status:
            with open(self.status, "w") as f:
                json.dump(json_safe(self.status_dict(viewer)), f, indent=1, default=str)

    def status_dict(self, viewer) -> dict:
        st, r = viewer.state, viewer.state.render
        ins = st.inspector
        return {
            "exit_code": self.exit_code, "failure": self.failure, "frames": st.frame_count,
            "seconds": time.perf_counter() - self._started, "fps": st.fps,
            "scene": st.scene_path, "n_patches": st.scene.n_patches if st.scene else None,
            "error": st.error, "messages": [{"level": lvl, "text": t} for _, lvl, t in st.messages],
            "image_size": list(st.image_size), "region": list(viewer.region),
            "options": {f.name: getattr(st.opts, f.name) for f in fields(st.opts)},
            "settings": {f.name: getattr(st.settings, f.name) for f in fields(st.settings)},
            "render": {"job": r.job, "phase": r.phase, "tiles_done": r.tiles_done, "tiles_total": r.tiles_total,
                       "seconds": r.seconds, "ref_seconds": r.ref_seconds, "stats": r.stats,
                       "error_stats": r.error_stats, "shaded_mode": viewer.events.shaded_mode,
                       "traced_options": ({f.name: getattr(r.key[1], f.name) for f in fields(r.key[1])}
                                          if r.key else None)},
            "renders": {"started": st.renders_started, "finished": st.renders_finished,
                        "cancelled": st.renders_cancelled, "start_latencies": st.latencies},
            "ui_while_rendering": _fps_summary(st.busy_frame_times),
            "applied": self.applied,
            "overlay": {k: v for k, v in st.overlay_info.items() if k != "lut"},
            "inspector": ({"pixel": list(ins.trace.pixel), "hit": bool(ins.trace.hit), "patch": int(ins.trace.patch),
                           "boxes": len(ins.trace.steps_f), "error": ins.error,
                           "ray_tree": {"rays": len(ins.tree.rays) if ins.tree else None, "error": ins.tree_error,
                                        "rows_drawn": ins.rows_drawn, "chosen": ins.ray,
                                        "shown_boxes": len(shown_trace(ins).steps_f)},
                           "outline_vertices": viewer.display.box_count} if ins else None),
            "shader_error": viewer.display.error,
            "failed_loads": st.failed_loads, "loading": st.loading[0] if st.loading else None,
            "compiles": self.compiles, "notes": st.notes, "kernels": compile_report(),
        }
