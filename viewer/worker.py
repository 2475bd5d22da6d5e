"""Background rendering: one worker thread runs the newest job, tile by tile, cancellable.

A job traces a coarse preview (1/8 resolution, same view), then the full frame, then
(optionally) the float64 reference of the same rays. The full frame's work units come in the
pixel order option's sequence (tracer/pixel_order.py: Peano squares, or item-buffer runs of
scattered pixels); `scanline` tiles are handed out from the centre out instead of row by row (the
same tiles, what the user looks at first). A unit's pixels, and only those, are shaded in the
worker (tracer.shade) and reported as events; the UI thread drains the events and uploads the
rects holding them. The numba kernels release the GIL, so the UI thread keeps running while
units are traced.

The display mode is not part of a job: set_mode changes it while the job runs, and the
worker re-shades what it has traced so far (the trace is never restarted for it). A tile
in flight cannot be interrupted; cancelling stops the job before its next tile.
"""
from __future__ import annotations

import math
import os
import queue
import threading
import time
import traceback
from dataclasses import dataclass, replace

import numpy as np

from tracer.camera import View, primary_rays
from tracer.geometry import prepare
from tracer.options import Options, option_fields
from tracer.pixel_order import fills_rect
from tracer.render import reference_frame, thread_count, trace_rays, work_units
from tracer.shade import shade

COARSE = 8


def trace_options(opts: Options) -> Options:
    """Options with the display-only fields at their defaults: equal records trace equal images."""
    defaults = Options()
    return replace(opts, **{f.name: getattr(defaults, f.name) for f in option_fields()
                            if f.metadata.get("group") == "Display"})


def worker_threads(opts: Options) -> int:
    """Render threads: as asked, or all cores but one (kept for the UI)."""
    return opts.threads if opts.threads > 0 else max(1, (os.cpu_count() or 2) - 1)


def centre_out(width: int, height: int, opts: Options) -> list:
    """Scanline tile order (indices into render.work_units) by distance of the tile centre from
    the image centre."""
    rects = [u.rect for u in work_units(width, height, opts.with_(order="scanline"))]
    d = [((y0 + y1 - height) ** 2 + (x0 + x1 - width) ** 2) for y0, y1, x0, x1 in rects]
    return sorted(range(len(rects)), key=d.__getitem__)


def unit_order(width: int, height: int, opts: Options):
    """trace_rays' `order` for the full frame: centre-out for scanline, the option's own sequence
    otherwise (None)."""
    return centre_out(width, height, opts) if opts.order == "scanline" else None


def paint(colour: np.ndarray, frame, scene, mode: str, unit) -> None:
    """Shade a traced unit's pixels into `colour` (H, W, 3), leaving every other pixel alone."""
    y0, y1, x0, x1 = unit.rect
    if fills_rect(unit.pixels, unit.rect):
        colour[y0:y1, x0:x1] = shade(frame, scene, mode, rect=unit.rect)
    else:
        colour[unit.pixels[:, 0], unit.pixels[:, 1]] = shade(frame, scene, mode, pixels=unit.pixels)


def _lower_priority(nice: int = 10) -> None:
    """Make this thread (and the tile threads it starts, which inherit it) yield to the UI.

    On Linux the nice value is per thread; with few cores this keeps the UI (and Mesa's
    software rasteriser) at frame rate while tiles are traced.
    """
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
    except (AttributeError, OSError):
        pass


class GeometryCache:
    """Prepared geometry per precision for the current scene (preparing is the slow part)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._scene = None
        self._geoms = {}

    def adopt(self, scene, precision: str, geom) -> None:
        """Make `scene` current with one geometry already prepared (by the loader)."""
        with self._lock:
            self._scene, self._geoms = scene, {precision: geom}

    def get(self, scene, precision: str):
        with self._lock:
            if scene is not self._scene:
                self._scene, self._geoms = scene, {}
            if precision not in self._geoms:
                self._geoms[precision] = prepare(scene, precision)
            return self._geoms[precision]


@dataclass(frozen=True)
class Job:
    id: int
    scene: object
    opts: Options
    view: View
    size: tuple            # (width, height)
    reference: bool = True
    frame: object = None    # a finished Frame: only trace its float64 reference


class TileCancel:
    """The cancel event as trace_rays sees it, asked before every tile. With a `hold` event, only
    the pass's first `allowed` tiles start until it is set (or the job is cancelled): a scripted
    mid-render change then always lands mid-render, however fast the machine."""

    def __init__(self, cancel: threading.Event, hold: threading.Event | None = None, allowed: int = 1):
        self.cancel, self.hold, self.allowed = cancel, hold, allowed
        self._lock = threading.Lock()

    def is_set(self) -> bool:
        if self.hold is not None:
            with self._lock:
                self.allowed -= 1
                held = self.allowed < 0
            while held and not (self.hold.is_set() or self.cancel.is_set()):
                self.hold.wait(0.02)
        return self.cancel.is_set()


def upscale(rgb: np.ndarray, factor: int, size) -> np.ndarray:
    """The coarse preview's colours at full resolution (nearest), (H, W, 3)."""
    w, h = size
    return np.repeat(np.repeat(rgb, factor, 0), factor, 1)[:h, :w]


def shade_async(frame, scene, mode: str, job_id: int, events: queue.Queue) -> threading.Thread:
    """Re-shade a finished frame in another mode off the UI thread; posts ("shaded", job_id, (mode, rgb))."""
    def run():
        try:
            h, w = frame.hit.shape
            events.put(("shaded", job_id, (mode, shade(frame, scene, mode, rect=(0, h, 0, w)))))
        except Exception as e:
            events.put(("error", job_id, f"shading failed: {type(e).__name__}: {e}"))

    thread = threading.Thread(target=run, name="psrt-shade", daemon=True)
    thread.start()
    return thread


class RenderWorker:
    """Runs the newest submitted job on a daemon thread; `events` is read by the UI thread."""

    def __init__(self, geometry: GeometryCache):
        self.geometry = geometry
        self.events: queue.Queue = queue.Queue()
        self._cond = threading.Condition()
        self._job = None
        self._cancel = threading.Event()
        self._stop = False
        self._mode = (0, None)   # (job id, display mode) set while that job runs
        self._hold = None        # full-resolution passes wait after one tile until it is set
        self._thread = threading.Thread(target=self._run, name="psrt-render", daemon=True)
        self._thread.start()

    def submit(self, job: Job) -> None:
        """Cancel whatever runs and queue `job` (an older queued job is dropped)."""
        with self._cond:
            self._cancel.set()
            self._cancel = threading.Event()
            self._job = job
            self._cond.notify()

    def cancel(self) -> None:
        with self._cond:
            self._cancel.set()
            self._job = None

    def set_mode(self, job_id: int, mode: str) -> None:
        """Shade job `job_id`'s remaining tiles in `mode`, re-shading those already traced."""
        self._mode = (job_id, mode)

    def _mode_of(self, job) -> str:
        job_id, mode = self._mode
        return mode if job_id == job.id and mode is not None else job.opts.mode

    def hold_mid_render(self) -> threading.Event:
        """Hold full-resolution passes after their first tile until the returned event is set."""
        self._hold = threading.Event()
        return self._hold

    def stop(self, timeout: float = 2.0) -> bool:
        """Cancel and end the worker thread; False if it is still busy after `timeout` (a tile, a
        compile or a geometry preparation cannot be interrupted)."""
        with self._cond:
            self._stop = True
            self._cancel.set()
            self._cond.notify()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def _emit(self, kind, job, payload=None):
        self.events.put((kind, job.id, payload))

    def _phase(self, job, name):
        self.events.put(("phase", job.id, (name, time.perf_counter())))

    def _on_compile(self, job):
        """trace_rays' on_compile: which kernel variant is compiling, from when (None: done)."""
        def note(variant, seconds=None):
            from tracer.variants import label
            self._emit("compiling", job, None if seconds is not None else (label(variant), time.perf_counter()))
        return note

    def _run(self):
        _lower_priority()
        while True:
            with self._cond:
                while self._job is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                job, cancel = self._job, self._cancel
                self._job = None
            try:
                if job.frame is not None:
                    self._reference(job, job.frame, cancel)
                else:
                    self._render(job, cancel)
            except Exception as e:  # reported in the UI; the worker lives on
                detail = traceback.format_exc(limit=4)
                self._emit("error", job, f"render failed: {type(e).__name__}: {e}\n{detail}")

    def _render(self, job, cancel):
        scene, opts, view = job.scene, job.opts, job.view
        width, height = job.size
        opts = opts.with_(threads=worker_threads(opts))
        self._phase(job, "preparing")
        geom = self.geometry.get(scene, opts.precision)
        if cancel.is_set():
            return self._emit("cancelled", job)

        # Coarse preview: same view at 1/COARSE resolution, shaded whole.
        cw, ch = max(1, math.ceil(width / COARSE)), max(1, math.ceil(height / COARSE))
        o, d = primary_rays(view, cw, ch, opts.precision)
        self._phase(job, "coarse")
        coarse = trace_rays(geom, opts.with_(tile_size=max(8, opts.tile_size)), o, d, view.pixel_angle(ch),
                            cancel=cancel, on_compile=self._on_compile(job), view=view, scene=scene)
        if cancel.is_set():
            return self._emit("cancelled", job)
        mode = self._mode_of(job)
        rgb = shade(coarse, scene, mode, rect=(0, ch, 0, cw))
        self._emit("coarse", job, (coarse, rgb, COARSE, mode))

        # Full resolution in the order's sequence; untraced pixels keep the preview's colours.
        colour = upscale(rgb, COARSE, job.size).astype(np.float32)
        origins, dirs = primary_rays(view, width, height, opts.precision, threads=thread_count(opts))
        traced, shaded = np.zeros((height, width), bool), [mode]

        def on_tile(frame, unit):
            if cancel.is_set():
                return
            if frame_box[0] is None:
                frame_box[0] = frame
                self._emit("frame_start", job, (frame, colour))
            now = self._mode_of(job)
            if now != shaded[0]:  # the mode changed: re-shade what is there, keep tracing
                shaded[0] = now
                colour[:] = upscale(shade(coarse, scene, now, rect=(0, ch, 0, cw)), COARSE, job.size)
                # only the pixels traced: the others are being written by the tile threads
                done = np.argwhere(traced)
                colour[done[:, 0], done[:, 1]] = shade(frame, scene, now, pixels=done)
                self._emit("recolour", job, now)
            paint(colour, frame, scene, now, unit)
            traced[unit.pixels[:, 0], unit.pixels[:, 1]] = True
            self._emit("tile", job, unit)

        frame_box = [None]
        hold = self._hold if self._hold is not None and not self._hold.is_set() else None
        self._phase(job, "full")
        frame = trace_rays(geom, opts, origins, dirs, view.pixel_angle(height), on_tile=on_tile,
                           cancel=TileCancel(cancel, hold), order=unit_order(width, height, opts), view=view,
                           scene=scene)
        if cancel.is_set() or frame.tiles_done < frame.tiles_total:
            return self._emit("cancelled", job)
        self._emit("frame", job, frame)
        if not job.reference:
            return self._phase(job, "done")
        self._reference(job, frame, cancel)

    def _reference(self, job, frame, cancel):
        """The float64 reference of exactly the frame's rays, for the error channels."""
        scene = job.scene
        geom64 = self.geometry.get(scene, "f64")
        ref_box = [None]

        def on_ref_tile(ref, unit):
            if ref_box[0] is None:
                ref_box[0] = ref
                self._emit("ref_start", job, ref)
            self._emit("ref_tile", job, unit)

        self._phase(job, "reference")
        start = time.perf_counter()
        ref = reference_frame(scene, frame, geometry=geom64, cancel=cancel, on_tile=on_ref_tile,
                              on_compile=self._on_compile(job))
        if cancel.is_set() or ref.tiles_done < ref.tiles_total:
            return self._emit("cancelled", job)
        ref.seconds = time.perf_counter() - start
        self._emit("reference", job, ref)
        self._phase(job, "done")
