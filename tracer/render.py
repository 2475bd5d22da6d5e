"""Parallel rendering of primary rays into per-pixel channels.

Work units (tiles, or runs of pixels in another order: pixel_order.py) run on the calling thread
and its helpers (unit_loop.py); the numba tile kernel releases the GIL, so threads trace in parallel. Each finished unit is
reported to an optional callback (the viewer uploads it), and a cancel event stops the frame
between units.
"""
from __future__ import annotations

import os
import queue
import threading
import time
import weakref
from dataclasses import dataclass, field

import numpy as np

from .camera import View, primary_rays, view_of
from .accel import aggregate_for
from .geometry import Geometry, prepare
from .kernel_channels import CHANNEL_NAMES, Outputs, allocate, fill_miss
from .options import CRITERION_CODE, SPLIT_CODE, Options
from .pixel_order import order_units, unit_count as order_unit_count
from .records import Leaves, Query, Trims, no_trace
from .tile_kernel import tile_scratch
from .unit_loop import guided_groups, joined_pixels, run_units
from .variants import compiled, entry_point, label, variant_for

CONTRACT_NAMES = ("ray_origin", "ray_dir", "hit", "t", "position", "box_min", "box_max",
                  "normal", "uv", "patch", "effort")
# What shading with secondary rays adds (lighting.py): name -> (dtype, trailing shape, value where unset).
LIGHTING_CHANNELS = {"shadow": (np.float32, (), np.nan), "shadow_rays": (np.int32, (), 0),
                     "penumbra": (np.int8, (), -1), "radiance": (np.float32, (3,), np.nan)}
# Every per-pixel array of a Frame written to the .npz: the rays, the kernel channels, the lighting's
# channels of the contract (radiance is the display's, not the contract's).
AOV_NAMES = (CONTRACT_NAMES + tuple(n for n in CHANNEL_NAMES if n not in CONTRACT_NAMES)
             + ("shadow", "shadow_rays", "penumbra"))


@dataclass
class Frame:
    """Per-pixel channels of one render, indexed [row, column, ...], row 0 at the top: the rays
    and every kernel channel (kernel_channels.KERNEL_CHANNELS)."""

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
    nodes: np.ndarray | None = None
    patches_tested: np.ndarray | None = None
    surfaces_tested: np.ndarray | None = None
    box_tests: np.ndarray | None = None
    cache_hits: np.ndarray | None = None
    cache_misses: np.ndarray | None = None
    unresolved: np.ndarray | None = None
    shadow: np.ndarray | None = None
    shadow_rays: np.ndarray | None = None
    penumbra: np.ndarray | None = None
    radiance: np.ndarray | None = None
    seconds: float = 0.0
    tiles_done: int = 0
    tiles_total: int = 0
    extras: dict = field(default_factory=dict)

    @classmethod
    def empty(cls, origins: np.ndarray, dirs: np.ndarray, filled: bool = True) -> "Frame":
        """The frame of these rays, its channels at their miss values (filled) or not yet written."""
        h, w = origins.shape[:2]
        return cls(origins, dirs, **allocate(h, w, filled))

    @property
    def size(self):
        return self.hit.shape[1], self.hit.shape[0]

    def add_lighting(self, shadows: bool) -> None:
        """Allocate the lighting's channels (shadow and penumbra only where shadows are traced)."""
        h, w = self.hit.shape
        for name, (dtype, tail, unset) in LIGHTING_CHANNELS.items():
            if shadows or name not in ("shadow", "penumbra"):
                setattr(self, name, np.full((h, w) + tail, unset, dtype))

    def aovs(self) -> dict:
        """The contract's per-pixel arrays (dtypes as specified), with every kernel channel computed."""
        return {name: getattr(self, name) for name in AOV_NAMES if getattr(self, name) is not None}

    def outputs(self) -> Outputs:
        """The kernel's view of the channels."""
        return Outputs(*(getattr(self, name) for name in CHANNEL_NAMES))

    def save_npz(self, path) -> None:
        np.savez_compressed(path, **self.aovs())


def tiles(width: int, height: int, size: int):
    """Tile rectangles (y0, y1, x0, x1), row-major."""
    return [(y, min(y + size, height), x, min(x + size, width))
            for y in range(0, height, size) for x in range(0, width, size)]


@dataclass(frozen=True)
class Unit:
    """One call of the tile kernel: pixels (k, 2) int32 (row, column) in the order they are traced,
    grouped into ray bundles: bundle i is pixels[blocks[i]:blocks[i + 1]] (blocks (nb + 1,) int32;
    one pixel each for the 1x1 bundle); and the rectangle (y0, y1, x0, x1) that holds them (what a
    display refreshes)."""

    pixels: np.ndarray
    blocks: np.ndarray
    rect: tuple


def bundle_shape(opts: Options) -> tuple:
    """(columns, rows) of a ray bundle."""
    cols, rows = opts.bundle.split("x")
    return int(cols), int(rows)


def rect_blocks(rect, cols: int = 1, rows: int = 1):
    """The pixels of a rectangle in bundles of cols x rows (cut at its edges), bundle by bundle in
    rows, row by row within a bundle: (pixels (k, 2) int32, blocks (nb + 1,) int32)."""
    y0, y1, x0, x1 = rect
    pixels, blocks = [], [0]
    for by in range(y0, y1, rows):
        for bx in range(x0, x1, cols):
            ys, xs = np.mgrid[by:min(by + rows, y1), bx:min(bx + cols, x1)]
            pixels.append(np.stack([ys.ravel(), xs.ravel()], axis=1))
            blocks.append(blocks[-1] + ys.size)
    return (np.ascontiguousarray(np.concatenate(pixels), np.int32) if pixels else np.zeros((0, 2), np.int32),
            np.asarray(blocks, np.int32))


def work_units(width: int, height: int, opts: Options, geometry: Geometry | None = None,
               view: View | None = None) -> list:
    """The image's work units in the order they are handed out, after opts.order
    (tracer/pixel_order.py); the item buffer projects the geometry's patch boxes through the view."""
    boxes = geometry.patch_box if geometry is not None and opts.order == "itembuffer" else None
    return [Unit(*u) for u in order_units(width, height, opts.order, opts.tile_size, bundle_shape(opts), boxes, view)]


def _plain(p: np.ndarray, b: np.ndarray) -> bool:
    """Whether a unit's pixels and blocks have the one type its kernel's bound entry point takes
    (int32, C-contiguous, aligned and writeable, as rect_blocks, pixel_order and
    unit_loop.joined_pixels make them)."""
    return p.dtype == np.int32 and b.dtype == np.int32 and p.flags.carray and b.flags.carray


def unit_count(width: int, height: int, opts: Options) -> int:
    """len(work_units(...)), without the scene (a progress bar's length)."""
    return order_unit_count(width, height, opts.order, opts.tile_size, bundle_shape(opts))


@dataclass(frozen=True)
class KernelInputs:
    """What the kernels take for one frame: the scene records (Leaves, Trims, aggregate), the
    query, the scratch sizes (threshold-of-detail slope, points, walk stack, trim points, rays of a
    bundle), the leaf-to-scene-patch map and the aggregate's build report (accel.aggregate_for)."""

    scene: tuple
    query: Query
    sizes: tuple
    leaf_patch: np.ndarray
    accel: dict = field(default_factory=dict)


NO_BUDGET = np.zeros((1, 1), np.int32)


def kernel_inputs(geom: Geometry, opts: Options, pixel_angle: float, budget=None, on_build=None) -> KernelInputs:
    """The records a tile kernel needs, derived once per frame. budget: (factor, (H, W) int32 base)
    bounds each ray's boxes to factor * max(base, records.BUDGET_FLOOR); None: no bound. The
    aggregate is built on first use (on_build: see accel.aggregate_for)."""
    criterion = CRITERION_CODE[opts.criterion]
    param = {"float": 0.0, "fixed": opts.fixed_size, "adaptive": 0.0,
             "mantissa": float(opts.mantissa_ulps)}[opts.criterion]
    slope = opts.pixel_fraction * pixel_angle if opts.criterion == "adaptive" else 0.0
    leaves = Leaves(geom.ctrl, geom.pstart, geom.deg_u, geom.deg_v, geom.rational, geom.frame, geom.grid, geom.eps,
                    geom.ctrl64, geom.eps64)
    trims = Trims(*geom.trims_for(opts.trims))
    factor, base = (0.0, NO_BUDGET) if budget is None else (float(budget[0]), np.ascontiguousarray(budget[1], np.int32))
    query = Query(criterion, param, SPLIT_CODE[opts.split], geom.max_depth, geom.bits, factor, base)
    agg = aggregate_for(geom, opts, on_build)
    cols, rows = bundle_shape(opts)
    sizes = (float(slope), max(geom.max_points, 16), agg.stack, max(geom.trim_points, 2), cols * rows)
    return KernelInputs((leaves, trims, agg.record), query, sizes, geom.leaf_patch, agg.report)


def thread_count(opts: Options) -> int:
    return opts.threads if opts.threads > 0 else (os.cpu_count() or 1)


# Surface-tree caches (surface_cache.py), one per render thread, kept while the geometry and the
# options that shape the trees stay the same: id(geometry) -> (weak reference, key, caches).
_CACHES: dict = {}
_CACHES_LOCK = threading.Lock()


def thread_caches(geom: Geometry, opts: Options, inputs: KernelInputs, count: int) -> list:
    """`count` surface-tree caches for renders of `geom` with `opts`, each to be lent to one work
    unit at a time, the same ones from frame to frame."""
    from .surface_cache import ThreadCache
    from .tile_kernel import working_slots
    key = (opts.criterion, opts.fixed_size, opts.pixel_fraction, opts.mantissa_ulps, opts.split, opts.trims,
           opts.cache_mb, opts.cache_depth)
    with _CACHES_LOCK:
        for k in [k for k, (ref, _, _) in _CACHES.items() if ref() is None]:
            del _CACHES[k]
        ref, old_key, caches = _CACHES.get(id(geom), (None, None, []))
        if ref is None or ref() is not geom or old_key != key:
            caches = []
        while len(caches) < count:
            caches.append(ThreadCache(geom.n_patches, working_slots(inputs), inputs.sizes[1], geom.ctrl.dtype,
                                      bool(np.any(geom.rational)), opts.cache_mb, opts.cache_depth))
        _CACHES[id(geom)] = (weakref.ref(geom), key, caches)
    return caches[:count]


def _held_caches(geom: Geometry) -> list:
    ref, _, caches = _CACHES.get(id(geom), (None, None, []))
    return caches if ref is not None and ref() is geom else []


def cache_summary(geom: Geometry) -> dict | None:
    """The geometry's surface-tree caches: searches that found a tree, that made one, nodes held,
    bytes (summed over the render threads); None without the cache."""
    parts = [c.summary() for c in _held_caches(geom)]
    if not parts:
        return None
    return {k: sum(p[k] for p in parts) for k in parts[0]} | {"threads": len(parts)}


def frame_lighting(scene, geom: Geometry, opts: Options, inputs: KernelInputs, pixel_angle: float, eye,
                   on_compile=None):
    """The lighting.Lighting that shades a frame traced with `inputs` (kernel_inputs) seen from `eye`."""
    from .lighting import Lighting
    # secondary rays go through the BVH whatever opts.accel: one set of batch kernels per scene
    shared = inputs if opts.accel == "bvh" else kernel_inputs(geom, opts.with_(accel="bvh"), pixel_angle)
    return Lighting(scene, geom, opts.with_(accel="bvh"), shared, eye, on_compile)


def fresh_caches(geom: Geometry, opts: Options) -> None:
    """Replace the geometry's surface-tree caches by new, empty ones for renders with opts, made
    now, their memory mapped: the next frame starts cold without paying for the allocation
    (benchmarks)."""
    with _CACHES_LOCK:
        _CACHES.pop(id(geom), None)
    for c in thread_caches(geom, opts, kernel_inputs(geom, opts, 0.0), thread_count(opts)):
        c.map_pages()


def _frame_cache(caches: list, before: list | None = None):
    """Before a frame (before None): clear each cache's surfaces searched and return its totals.
    After it: the frame's figures for frame.extras["cache"]: searches that found a tree (hits),
    that made one (misses), trees released, surfaces searched (summed over the threads' caches:
    a surface two threads searched counts twice, as each made its own tree), and the nodes held,
    their capacity and bytes at the end (surface_cache.ThreadCache.summary)."""
    if before is None:
        for c in caches:
            c.record.seen[:] = 0
        return [c.summary() for c in caches]
    after = [c.summary() for c in caches]
    total = {k: sum(a[k] for a in after) for k in after[0]}
    for k in ("hits", "misses", "released"):
        total[k] -= sum(b[k] for b in before)
    return total | {"threads": len(caches)}


def trace_rays(geom: Geometry, opts: Options, origins, dirs, pixel_angle: float, *,
               on_tile=None, cancel: threading.Event | None = None, progress=None,
               order=None, on_compile=None, on_build=None, driver: str = "closest", budget=None,
               view: View | None = None, scene=None) -> Frame:
    """Trace given primary rays (H, W, 3) unit by unit (work_units: opts.order; the item buffer
    needs the view the rays come from); returns the filled Frame.

    on_tile(frame, unit) is called from the calling thread as each work unit finishes (a Unit:
    its pixels, and the rectangle holding them); progress(n) advances a progress bar; `order`
    optionally permutes the work units (indices into work_units);
    on_compile(variant[, seconds]) is called before and after a kernel variant is compiled
    or loaded from the cache (variants.compiled); on_build(description[, seconds]) likewise around the
    build of a kd-tree or grid (accel.aggregate_for; its figures go to frame.extras["accel"]);
    driver: 'closest' hit, or 'any' (the first hit box found);
    budget: a box budget per ray (kernel_inputs), its exhaustion marked in the `unresolved` channel.
    scene: the loaded scene of geom, to shade each unit with its secondary rays as it finishes
    (lighting.py: the radiance, shadow, shadow_rays and penumbra channels); None: primary rays only.
    """
    # Nobody sees the frame before it is returned unless on_tile shows it as it is traced: only then
    # must untraced pixels read as misses from the start (the kernel writes each traced pixel whole;
    # pixels a cancel leaves untraced are given their miss values at the end).
    frame = Frame.empty(origins, dirs, filled=on_tile is not None)
    h, w = frame.hit.shape
    units = work_units(w, h, opts, geom, view)
    if order is not None:
        units = [units[i] for i in order]
    frame.tiles_total = len(units)
    inputs = kernel_inputs(geom, opts, pixel_angle, budget, on_build)
    frame.extras["accel"] = inputs.accel
    outs = frame.outputs()
    trace = no_trace()
    variant = variant_for(geom, opts, driver=driver)
    if budget is not None and variant.bundle:
        raise ValueError(f"a box budget bounds single rays: bundle {opts.bundle} asked for (1x1 needed)")
    args = (inputs.scene, inputs.query, inputs.sizes[0], inputs.leaf_patch, outs, trace)
    no_pixels = (np.zeros((0, 2), np.int32), np.zeros(1, np.int32))
    kernel = compiled("tile", variant, no_pixels + (origins, dirs) + args + (tile_scratch(inputs),), on_compile)
    frame.extras["variant"] = label(variant)
    # what the float64 reference needs to trace in the same order (reference_frame)
    frame.extras.update(order=opts.order, tile_size=opts.tile_size)
    if view is not None:
        frame.extras["view"] = view

    caches = thread_caches(geom, opts, inputs, thread_count(opts)) if variant.cache else []
    lent = queue.SimpleQueue()  # each cache serves one unit at a time
    for c in caches:
        lent.put(c)
    before = _frame_cache(caches) if caches else None
    lighting = None
    if scene is not None:
        eye = view.eye if view is not None else origins[0, 0]
        lighting = frame_lighting(scene, geom, opts, inputs, pixel_angle, eye, on_compile)
        frame.add_lighting(opts.shadows)

    local = threading.local()  # a thread's scratch for each cache it borrows, kept from unit to unit

    def scratch_for(cache):
        mine = getattr(local, "scratch", None)
        if mine is None:
            mine = local.scratch = {}
        if id(cache) not in mine:
            mine[id(cache)] = tile_scratch(inputs, cache)
        return mine[id(cache)]

    callers = {}  # id(scratch) -> the kernel's entry point for its argument types (variants.entry_point)

    def work(group):
        if cancel is not None and cancel.is_set():
            return None
        pixels, blocks = joined_pixels(group)
        cache = lent.get() if caches else None
        try:
            scratch = scratch_for(cache)
            call = callers.get(id(scratch)) if _plain(pixels, blocks) else kernel
            if call is None:  # the first call with this scratch
                call = entry_point(kernel, (pixels, blocks, origins, dirs) + args + (scratch,))
                if call is not kernel:  # (kernel: no overload takes these types yet; it compiles one)
                    callers[id(scratch)] = call
            call(pixels, blocks, origins, dirs, *args, scratch)
        finally:
            if cache is not None:
                lent.put(cache)
        if lighting is not None:
            for unit in group:
                lighting.shade_unit(frame, unit.pixels)
        return group

    traced = set()

    def finished(group):
        for unit in group or ():
            traced.add(id(unit))
            frame.tiles_done += 1
            if progress is not None:
                progress(1)
            if on_tile is not None:
                on_tile(frame, unit)

    start = time.perf_counter()
    threads = thread_count(opts)
    run_units(guided_groups(units, threads, watched=on_tile is not None or progress is not None),
              work, finished, threads)
    frame.seconds = time.perf_counter() - start
    for unit in units:
        if id(unit) not in traced:
            fill_miss(frame, unit.pixels[:, 0], unit.pixels[:, 1])
    if lighting is not None:
        frame.extras["lighting"] = lighting.report()
    if caches:
        frame.extras["cache"] = _frame_cache(caches, before)
    return frame


def render(scene, opts: Options = Options(), *, size=None, view: View | None = None,
           geometry: Geometry | None = None, lighting: bool = True, **kwargs) -> Frame:
    """Render a loaded scene's primary rays with the given options.

    size: (width, height), else the scene's image size, else 512x512.
    geometry: a prepared Geometry of the same precision, to skip preparation.
    lighting: shade with secondary rays (trace_rays' scene); False: primary rays alone.
    """
    width, height = size or scene.image_size or (512, 512)
    view = view or view_of(scene)
    geom = geometry if geometry is not None else prepare(scene, opts.precision)
    if geom.precision != opts.precision:
        raise ValueError(f"geometry is {geom.precision}, options ask for {opts.precision}")
    origins, dirs = primary_rays(view, width, height, opts.precision, threads=thread_count(opts))
    return trace_rays(geom, opts, origins, dirs, view.pixel_angle(height), view=view,
                      scene=scene if lighting else None, **kwargs)


# The reference's box budget per ray: this many times the boxes the frame's own ray computed (at
# least records.BUDGET_FLOOR). On every scene of the digest catalogue the reference computes 1.6 to
# 2.7 times the float32 render's boxes, the most for one ray 7 times; the budget bounds the
# rest, and the pixels where it ran out are marked unresolved instead of costing minutes.
REFERENCE_BUDGET = 16.0


def reference_frame(scene, frame: Frame, geometry: Geometry | None = None, **kwargs) -> Frame:
    """The float64, float-criterion render of exactly the rays of `frame` (the error reference),
    each ray bounded to REFERENCE_BUDGET times the boxes it cost `frame` (see `unresolved`), in
    the frame's pixel order and tile size, ray by ray (a budget bounds single rays)."""
    geom = geometry if geometry is not None else prepare(scene, "f64")
    same_units = {k: frame.extras[k] for k in ("order", "tile_size") if k in frame.extras}
    opts = Options(criterion="float", precision="f64", bundle="1x1", **same_units)  # a budget bounds single rays
    return trace_rays(geom, opts, frame.ray_origin, frame.ray_dir, 0.0, budget=(REFERENCE_BUDGET, frame.effort),
                      view=frame.extras.get("view"), **kwargs)
