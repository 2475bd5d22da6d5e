"""`psrt bench --coherence`: the coherence options side by side on each scene, in three tables.

- bundles (Dammertz 2005, table 2.5): ray bundles 1x1 to 8x8 under the float, adaptive and fixed
  criteria, and the largest bundle with the surface-tree cache and the Peano order added; and a
  frame without subdivision (`fixed` with fixed_size as large as the scene's leaves), 1x1 and 8x8.
- accel (Dammertz, table 3.1): the BVH against kd-trees of depth 10, 20 and 30 (both split rules)
  and grids at three resolutions, with and without the mailbox; build time and memory.
- order (Lischinski and Gonczarowski 1990, section 5): scanline, item-buffer and Peano order,
  without the cache and with caches bounded to SMALL_CACHE_MB, BOUNDED_CACHE_MB and room for every
  tree ("unbounded"), with their counters (stats.coherence_stats).

Every row fixes the coherence options it is about (the others at their plain values: 1x1, BVH,
no mailbox, no cache, scanline); options given on the command line (cache depth, tile size, split)
apply to every row. Each distinct configuration renders once to warm up (compiles, builds), then
`runs` times, the configurations taking turns within each run, so drift of the machine's speed
hits them alike. A row's time is the median; its speed-up is the median over runs of the plain
row's time in the same run over its own. With one render thread (the default) a frame's time is
the CPU time of the process over the render call (rays, work units, tracing); with more threads,
the wall time. The surface-tree cache starts empty in every timed frame, as in Lischinski's
single frames (the viewer keeps the trees from frame to frame), allocated and its memory mapped
before the clock starts (as the viewer's is after its first frame).
"""
from __future__ import annotations

import statistics
import time
from dataclasses import dataclass

from . import accel
from .bvh import build_bvh
from .camera import primary_rays, view_of
from .geometry import prepare
from .options import BUNDLES, ORDERS, PLAIN as PLAIN_SETTING, Options
from .render import fresh_caches, thread_count, trace_rays
from .stats import frame_stats
from .surface_cache import mib_for_every_tree

PLAIN = {"criterion": "float", **PLAIN_SETTING}
BUNDLE_CRITERIA = ("float", "adaptive", "fixed")
KD_DEPTHS = (10, 20, 30)
GRID_SCALES = (0.25, 0.5, 1.0)
SMALL_CACHE_MB = 4.0
BOUNDED_CACHE_MB = 60.0
TABLES = ("bundles", "accel", "order")


@dataclass(frozen=True)
class Row:
    """One row of a table: its options, and the configuration its speed-up is measured against."""

    table: str
    label: str
    opts: Options
    plain: Options


def no_subdivision_size(geom) -> float:
    """A fixed_size at which every leaf's root box already stops the search (the largest leaf box's
    L1 diameter), within the option's range."""
    box = geom.leaf_box
    return float(min(max((box[:, 3:] - box[:, :3]).sum(axis=1).max(), 1e-9), 10.0))


def unbounded_cache_mb(geom, opts: Options) -> float:
    """A cache_mb with room for every leaf's tree (no tree is ever released), rounded up."""
    mib = mib_for_every_tree(geom.n_patches, max(geom.max_points, 16), geom.ctrl.dtype,
                             bool(geom.rational.any()), opts.cache_depth)
    return float(min(max(int(mib) + 1, 1), 65536))


def rows_for(geom, base: Options, tables=TABLES) -> list:
    """The rows of the tables (of TABLES) for a prepared geometry."""
    return [r for r in _all_rows(geom, base) if r.table in tables]


def _all_rows(geom, base: Options) -> list:
    plain = base.with_(**PLAIN)
    rows = []
    for criterion in BUNDLE_CRITERIA:
        c = plain.with_(criterion=criterion)
        rows += [Row("bundles", f"{criterion} {b}", c.with_(bundle=b), c) for b in BUNDLES]
        rows += [Row("bundles", f"{criterion} 8x8 + cache", c.with_(bundle="8x8", cache=True), c),
                 Row("bundles", f"{criterion} 8x8 + cache + peano", c.with_(bundle="8x8", cache=True, order="peano"),
                     c)]
    size = no_subdivision_size(geom)
    flat = plain.with_(criterion="fixed", fixed_size=size)
    rows += [Row("bundles", f"fixed {size:.3g} {b}: no subdivision", flat.with_(bundle=b), plain)
             for b in ("1x1", "8x8")]
    rows.append(Row("accel", "BVH", plain, plain))
    for split in ("sah", "middle"):
        for depth in KD_DEPTHS:
            kd = plain.with_(accel="kdtree", kd_split=split, kd_depth=depth)
            rows.append(Row("accel", f"kd-tree {split} {depth}", kd, plain))
            if depth == 20:
                rows.append(Row("accel", f"kd-tree {split} {depth}, mailbox", kd.with_(mailbox=True), plain))
    for scale in GRID_SCALES:
        grid = plain.with_(accel="grid", grid_scale=scale)
        rows += [Row("accel", f"grid {scale:g}", grid, plain),
                 Row("accel", f"grid {scale:g}, mailbox", grid.with_(mailbox=True), plain)]
    every = unbounded_cache_mb(geom, plain)
    for order in ORDERS:
        o = plain.with_(order=order)
        rows += [Row("order", f"{order}, no cache", o, plain),
                 Row("order", f"{order}, cache {SMALL_CACHE_MB:g} MB", o.with_(cache=True, cache_mb=SMALL_CACHE_MB),
                     plain),
                 Row("order", f"{order}, cache {BOUNDED_CACHE_MB:g} MB",
                     o.with_(cache=True, cache_mb=BOUNDED_CACHE_MB), plain),
                 Row("order", f"{order}, cache unbounded ({every:g} MB)", o.with_(cache=True, cache_mb=every), plain)]
    return rows


def _build_seconds(geom, opts: Options, runs: int, clock) -> float:
    """The least time of `runs` builds of the structure opts.accel asks for (the BVH's over the same
    leaves), by `clock`."""
    best = float("inf")
    for _ in range(runs):
        start = clock()
        build_bvh(geom.leaf_box) if opts.accel == "bvh" else accel.build_structure(geom, opts)
        best = min(best, clock() - start)
    return best


def run_scene(scene, base: Options, *, size, runs: int, tables=TABLES, log=None, on_compile=None) -> dict:
    """Time every row's configuration on one scene; {'patches', 'leaves', 'prepare_seconds',
    'rows': [...]} with each row's times, speed-up, frame_stats and (accel rows) build time."""
    start = time.perf_counter()
    geom = prepare(scene, base.precision)
    prepared = time.perf_counter() - start
    rows = rows_for(geom, base, tables)
    configs = list(dict.fromkeys([r.opts for r in rows] + [r.plain for r in rows]))
    clock = time.process_time if base.threads == 1 else time.perf_counter
    say = log or (lambda text: None)
    say(f"{scene.n_patches:,} patches, {geom.n_patches:,} leaves, prepared in {prepared:.1f} s; "
        f"{len(configs)} configurations, {size[0]}x{size[1]}")

    view = view_of(scene)

    def frame(opts):
        if opts.cache:
            fresh_caches(geom, opts)  # empty, allocated and mapped before the clock starts
        t0 = clock()
        # primary rays alone, as render() traces them (without any shading's secondary rays)
        origins, dirs = primary_rays(view, size[0], size[1], opts.precision, threads=thread_count(opts))
        f = trace_rays(geom, opts, origins, dirs, view.pixel_angle(size[1]), view=view, on_compile=on_compile)
        return clock() - t0, f

    start = time.perf_counter()
    stats = {o: frame_stats(frame(o)[1]) for o in configs}  # warm-up: compiles and builds
    say(f"warm-up (compiles, builds) {time.perf_counter() - start:.1f} s")
    times = {o: [] for o in configs}
    for run in range(runs):
        start = time.perf_counter()
        for o in configs:
            seconds, f = frame(o)
            times[o].append(seconds)
            stats[o] = frame_stats(f)
        say(f"run {run + 1}/{runs}: {len(configs)} frames in {time.perf_counter() - start:.1f} s")
    builds = {o: _build_seconds(geom, o, runs, clock) for o in configs if not o.mailbox and
              any(r.table == "accel" and r.opts == o for r in rows)}
    out = []
    for r in rows:
        mine, theirs = times[r.opts], times[r.plain]
        out.append({"table": r.table, "label": r.label, "options": _changes(r.opts, base),
                    "time": statistics.median(mine), "times": mine,
                    "speedup": statistics.median(p / t if t > 0 else float("inf") for p, t in zip(theirs, mine)),
                    "plain_time": statistics.median(theirs), "stats": stats[r.opts],
                    "build_seconds": builds.get(r.opts)})
    return {"patches": scene.n_patches, "leaves": geom.n_patches, "prepare_seconds": prepared, "rows": out}


def _changes(opts: Options, base: Options) -> dict:
    """The options a row sets, against the run's base options."""
    return {k: v for k, v in vars(opts).items() if getattr(base, k) != v}


def run_coherence(scenes: dict, base: Options, *, size=(256, 256), runs: int = 3, tables=TABLES, log=None,
                  on_compile=None) -> dict:
    """Every scene of {label: loaded scene} through run_scene; the result `psrt bench --coherence`
    prints (bench_tables) and writes as JSON."""
    if runs < 1:
        raise ValueError(f"--runs: expected at least 1, got {runs}")
    result = {"size": list(size), "runs": runs, "threads": base.threads,
              "timing": "cpu" if base.threads == 1 else "wall", "tables": list(tables), "scenes": {}}
    for label, scene in scenes.items():
        say = None if log is None else (lambda text, label=label: log(f"{label}: {text}"))
        result["scenes"][label] = run_scene(scene, base, size=size, runs=runs, tables=tables, log=say,
                                            on_compile=on_compile)
    return result
