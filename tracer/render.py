"""Tile-parallel rendering of primary rays into per-pixel channels.

Tiles run on a thread pool; the numba tile kernel releases the GIL, so threads
trace in parallel. Each finished tile is reported to an optional callback (the
viewer uploads it), and a cancel event stops the frame between tiles.
"""
from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field

import numpy as np

from .camera import View, primary_rays, view_of
from .geometry import Geometry, prepare
from .options import CRITERION_CODE, SPLIT_CODE, Options
from .tile_kernel import render_tile

AOV_NAMES = ("ray_origin", "ray_dir", "hit", "t", "position", "box_min", "box_max",
             "normal", "uv", "patch", "effort")


@dataclass
class Frame:
    """Per-pixel channels of one render, indexed [row, column, ...], row 0 at the top."""

    ray_origin: np.ndarray
    ray_dir: np.ndarray
    hit: np.ndarray
    t: np.ndarray
    position: np.ndarray
    box_min: np.ndarray
    box_max: np.ndarray
    normal: np.ndarray
    uv: np.ndarray
    patch: np.ndarray
    effort: np.ndarray
    seconds: float = 0.0
    tiles_done: int = 0
    tiles_total: int = 0
    extras: dict = field(default_factory=dict)

    @classmethod
    def empty(cls, origins: np.ndarray, dirs: np.ndarray) -> "Frame":
        h, w = origins.shape[:2]
        nan3 = np.full((h, w, 3), np.nan)
        return cls(origins, dirs, np.zeros((h, w), bool), np.full((h, w), np.inf), nan3.copy(), nan3.copy(),
                   nan3.copy(), np.zeros((h, w, 3)), np.full((h, w, 2), np.nan),
                   np.full((h, w), -1, np.int32), np.zeros((h, w), np.int32))

    @property
    def size(self):
        return self.hit.shape[1], self.hit.shape[0]

    def aovs(self) -> dict:
        """The contract's per-pixel arrays (dtypes as specified)."""
        return {name: getattr(self, name) for name in AOV_NAMES}

    def save_npz(self, path) -> None:
        np.savez_compressed(path, **self.aovs())


def tiles(width: int, height: int, size: int):
    """Tile rectangles (y0, y1, x0, x1), row-major."""
    return [(y, min(y + size, height), x, min(x + size, width))
            for y in range(0, height, size) for x in range(0, width, size)]


def kernel_args(geom: Geometry, opts: Options, pixel_angle: float):
    """The scalars and arrays a tile kernel needs, derived once per frame."""
    criterion = CRITERION_CODE[opts.criterion]
    param = {"float": 0.0, "fixed": opts.fixed_size, "adaptive": 0.0,
             "mantissa": float(opts.mantissa_ulps)}[opts.criterion]
    slope = opts.pixel_fraction * pixel_angle if opts.criterion == "adaptive" else 0.0
    bvh = geom.bvh
    patches = (geom.ctrl, geom.pstart, geom.deg_u, geom.deg_v, geom.rational, geom.frame, geom.grid, geom.eps,
               geom.ctrl64, geom.eps64)  # as traverse.trace_ray takes them
    return (patches, bvh.node_box, bvh.node_child, bvh.node_patch,
            criterion, param, SPLIT_CODE[opts.split], geom.max_depth, geom.bits, slope,
            max(geom.max_points, 16), bvh.depth + 2, geom.trims_for(opts.trims), geom.trim_points,
            geom.leaf_patch)


def thread_count(opts: Options) -> int:
    return opts.threads if opts.threads > 0 else (os.cpu_count() or 1)


def trace_rays(geom: Geometry, opts: Options, origins, dirs, pixel_angle: float, *,
               on_tile=None, cancel: threading.Event | None = None, progress=None,
               order=None) -> Frame:
    """Trace given primary rays (H, W, 3) tile by tile; returns the filled Frame.

    on_tile(frame, rect) is called from the calling thread as each tile finishes;
    progress(n) advances a progress bar; `order` optionally permutes the tiles.
    """
    frame = Frame.empty(origins, dirs)
    h, w = frame.hit.shape
    rects = tiles(w, h, opts.tile_size)
    if order is not None:
        rects = [rects[i] for i in order]
    frame.tiles_total = len(rects)
    args = kernel_args(geom, opts, pixel_angle)
    outs = (frame.hit, frame.t, frame.position, frame.box_min, frame.box_max, frame.normal,
            frame.uv, frame.patch, frame.effort)

    def work(rect):
        if cancel is not None and cancel.is_set():
            return None
        render_tile(*rect, origins, dirs, *args, *outs)
        return rect

    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=thread_count(opts)) as pool:
        futures = [pool.submit(work, r) for r in rects]
        for fut in as_completed(futures):
            rect = fut.result()
            if rect is None:
                continue
            frame.tiles_done += 1
            if progress is not None:
                progress(1)
            if on_tile is not None:
                on_tile(frame, rect)
    frame.seconds = time.perf_counter() - start
    return frame


def render(scene, opts: Options = Options(), *, size=None, view: View | None = None,
           geometry: Geometry | None = None, **kwargs) -> Frame:
    """Render a loaded scene's primary rays with the given options.

    size: (width, height), else the scene's image size, else 512x512.
    geometry: a prepared Geometry of the same precision, to skip preparation.
    """
    width, height = size or scene.image_size or (512, 512)
    view = view or view_of(scene)
    geom = geometry if geometry is not None else prepare(scene, opts.precision)
    if geom.precision != opts.precision:
        raise ValueError(f"geometry is {geom.precision}, options ask for {opts.precision}")
    origins, dirs = primary_rays(view, width, height, opts.precision)
    frame = trace_rays(geom, opts, origins, dirs, view.pixel_angle(height), **kwargs)
    frame.extras["view"] = view
    return frame


def reference_frame(scene, frame: Frame, geometry: Geometry | None = None, **kwargs) -> Frame:
    """The float64, float-criterion render of exactly the rays of `frame` (the error reference)."""
    geom = geometry if geometry is not None else prepare(scene, "f64")
    opts = Options(criterion="float", precision="f64")
    return trace_rays(geom, opts, frame.ray_origin, frame.ray_dir, 0.0, **kwargs)
