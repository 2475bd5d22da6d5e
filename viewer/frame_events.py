"""Between the worker and the screen: start jobs when what should be traced changes, and turn
the worker's events (coarse preview, tiles, frame, reference) into texture uploads and stats.

Only what is traced starts a job (desired_key: scene, trace options, view, size). The display
mode is not traced: a change while a job runs goes to the worker (set_mode), which re-shades
and carries on; after the frame it is re-shaded off the UI thread (shade_async)."""
from __future__ import annotations

import queue
import time

from tracer import colormap
from tracer.pixel_order import fills_rect
from tracer.stats import error_stats, frame_stats

from .state import RenderState
from .worker import Job, shade_async, trace_options, upscale

DRAIN_SECONDS = 0.012   # uploads per UI frame, so a burst of tiles cannot stall the UI
RANGE_INTERVAL = 0.25   # recompute the overlay's auto range at most this often while rendering
RUNNING = ("preparing", "coarse", "full")


class EventSink:
    def __init__(self, viewer):
        self.v = viewer
        self.job_id = 0
        self.job_mode = None      # display mode last asked of the running job
        self.shaded_mode = None   # display mode of the colours in the texture
        self.reshading = None
        self.range_time = 0.0
        self.pending = {}         # texture ("colour", "overlay") -> rect to upload when the drain ends

    # --- requests -------------------------------------------------------------------------
    def desired_key(self):
        st = self.v.state
        if st.scene is None or st.view is None or min(st.image_size) <= 0:
            return None
        return (id(st.scene), trace_options(st.opts), st.view, tuple(st.image_size))

    def request(self) -> None:
        """Start, restart or extend the render so it matches the current state."""
        st, r = self.v.state, self.v.state.render
        key = self.desired_key()
        if key is None:
            return
        if key != r.key:
            self._submit(key)
        elif r.phase in RUNNING:
            if st.opts.mode != self.job_mode:
                self.job_mode = st.opts.mode
                self.v.worker.set_mode(r.job, st.opts.mode)
        elif r.phase in ("reference", "done") and st.opts.mode != self.shaded_mode \
                and self.reshading != st.opts.mode:
            self.reshading = st.opts.mode
            shade_async(r.frame, st.scene, st.opts.mode, r.job, self.v.worker.events)
        elif st.settings.reference and r.phase == "done" and r.reference is None and r.frame is not None:
            r.phase = "reference"
            self.v.worker.submit(Job(r.job, st.scene, st.opts, st.view, st.image_size, True, frame=r.frame))

    def _submit(self, key) -> None:
        st = self.v.state
        self.job_id += 1
        st.render = RenderState(job=self.job_id, phase="preparing", submitted=time.perf_counter(), key=key)
        self.job_mode = st.opts.mode
        self.reshading = None
        st.renders_started += 1
        self.v.worker.submit(Job(self.job_id, st.scene, st.opts, st.view, tuple(st.image_size),
                                 st.settings.reference))

    # --- worker events --------------------------------------------------------------------
    def drain(self) -> None:
        deadline = time.perf_counter() + DRAIN_SECONDS
        try:
            while time.perf_counter() < deadline:
                try:
                    kind, job, payload = self.v.worker.events.get_nowait()
                except queue.Empty:
                    return
                if kind == "compiling":  # the worker's, whichever job waits on it
                    self.v.state.compiling = payload  # (variant label, since) or None when done
                    continue
                if job != self.v.state.render.job:
                    if kind == "cancelled":
                        self.v.state.renders_cancelled += 1
                    continue
                getattr(self, "_on_" + kind)(payload)
        finally:
            self._upload_pending()

    def _pend(self, texture: str, rect) -> None:
        """Upload `rect` of a texture when the drain ends: the units drained together (scattered
        ones' rects overlap) are uploaded once."""
        old = self.pending.get(texture)
        self.pending[texture] = rect if old is None else (min(old[0], rect[0]), max(old[1], rect[1]),
                                                          min(old[2], rect[2]), max(old[3], rect[3]))

    def _upload_pending(self) -> None:
        colour, overlay = self.pending.pop("colour", None), self.pending.pop("overlay", None)
        if colour is not None and self.v.state.render.colour is not None:
            self.v.display.upload(self.v.state.render.colour, None, colour)
        if overlay is not None:
            self.v.display.upload(None, self.v.overlay.data, overlay)

    def _fill_overlay(self, frame, ref, unit) -> None:
        """The overlay at a traced unit's pixels only (a scattered unit's rect holds others)."""
        pixels = None if fills_rect(unit.pixels, unit.rect) else unit.pixels
        if self.v.overlay.fill(frame, ref, unit.rect, pixels):
            self._pend("overlay", unit.rect)

    def _overlay_channel(self):
        return self.v.overlay.channel if self.v.state.settings.overlay != "none" else None

    def _on_phase(self, payload):
        r = self.v.state.render
        name, stamp = payload
        if name == "preparing" and r.started is None:
            r.started = stamp
            self.v.state.latencies.append(stamp - r.submitted)
            del self.v.state.latencies[:-50]
        if r.phase != "error":
            r.phase = name

    def _on_coarse(self, payload):
        coarse, rgb, factor, mode = payload
        w, h = self.v.state.image_size
        self.v.display.upload(upscale(rgb, factor, (w, h)), None)
        self.shaded_mode = mode
        ch = self._overlay_channel()
        if ch is not None:
            if not self.v.overlay.fill_coarse(coarse, (w, h), factor):
                self.v.overlay.reset(self.v.overlay.name, (w, h))
            self.v.display.upload(None, self.v.overlay.data)

    def _on_frame_start(self, payload):
        r = self.v.state.render
        r.frame, r.colour = payload
        r.tiles_total = r.frame.tiles_total

    def _on_recolour(self, mode):
        """The worker re-shaded the colours traced so far in another mode."""
        self.v.display.upload(self.v.state.render.colour, None)
        self.shaded_mode = mode

    def _on_tile(self, unit):
        """A work unit is traced and shaded into r.colour (its pixels only)."""
        r = self.v.state.render
        r.tiles_done += 1
        self._pend("colour", unit.rect)
        ch = self._overlay_channel()
        if ch is not None and not ch.needs_reference:
            self._fill_overlay(r.frame, None, unit)

    def _on_frame(self, frame):
        st, r = self.v.state, self.v.state.render
        r.frame, r.seconds = frame, frame.seconds
        r.tiles_done = r.tiles_total = frame.tiles_total
        r.stats = frame_stats(frame)
        st.renders_finished += 1
        ch = self._overlay_channel()
        if ch is not None and ch.needs_reference:
            self.v.overlay.reset(self.v.overlay.name, st.image_size)
            self.v.display.upload(None, self.v.overlay.data)

    def _on_ref_start(self, ref):
        r = self.v.state.render
        r.reference, r.ref_total, r.ref_done = ref, ref.tiles_total, 0

    def _on_ref_tile(self, unit):
        r = self.v.state.render
        r.ref_done += 1
        ch = self._overlay_channel()
        if ch is not None and ch.needs_reference:
            self._fill_overlay(r.frame, r.reference, unit)

    def _on_reference(self, ref):
        r = self.v.state.render
        r.reference, r.ref_seconds = ref, ref.seconds
        r.ref_done = r.ref_total = ref.tiles_total
        r.error_stats = error_stats(r.frame, ref)

    def _on_shaded(self, payload):
        mode, rgb = payload
        self.reshading = None
        self.v.state.render.colour = rgb
        self.v.display.upload(rgb, None)
        self.shaded_mode = mode

    def _on_error(self, message):
        self.v.state.render.phase = "error"
        self.v.state.log(message, "error")

    def _on_cancelled(self, _):
        self.v.state.renders_cancelled += 1

    # --- overlay --------------------------------------------------------------------------
    def refill_overlay(self) -> None:
        """Recompute the whole overlay (another channel chosen, or a new size)."""
        st, ov = self.v.state, self.v.overlay
        ov.reset(st.settings.overlay, st.image_size)
        if ov.channel is not None:
            r = st.render
            ref = r.reference if r.phase == "done" else None
            ov.fill(r.frame, ref)
        if ov.data.size:
            self.v.display.upload(None, ov.data)

    def update_overlay(self) -> None:
        """Keep the overlay channel, its range, colour map and legend in step with the settings."""
        st, ov = self.v.state, self.v.overlay
        if ov.name != st.settings.overlay or ov.data.shape[:2] != tuple(st.image_size)[::-1]:
            self.refill_overlay()
        ch = ov.channel
        if ch is None:
            st.overlay_info = {}
            return
        now = time.perf_counter()
        if ov.dirty_range and (now - self.range_time > RANGE_INTERVAL or st.render.phase not in RUNNING):
            self.range_time, ov.dirty_range = now, False
            st.overlay_info["range"] = ov.value_range(st.settings)
        cmap = ov.colormap(st.settings)
        self.v.display.set_colormap(cmap, colormap.table(cmap))
        lo, hi = ov.value_range(st.settings) if st.settings.range == "manual" else \
            st.overlay_info.get("range", (0.0, 1.0))
        note = None
        if ch.needs_reference and st.render.reference is None:
            note = ("waiting for the float64 reference" if st.settings.reference
                    else "turn on 'reference' to compute this channel")
        st.overlay_info.update(label=ch.label, units=ch.units, lo=lo, hi=hi, scale=ov.scale(st.settings),
                               specials=ov.specials, lut=self.v.display.lut.glo, note=note)

    def overlay_uniforms(self):
        st, info = self.v.state, self.v.state.overlay_info
        if st.settings.overlay == "none" or not info or "lo" not in info:
            return None
        return (info["lo"], info["hi"], info["scale"] == "log", [rgb for rgb, _ in info["specials"]])
