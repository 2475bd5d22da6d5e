"""The acceleration structure a render walks (options.accel), built once per geometry and parameters.

The BVH comes with the geometry (geometry.prepare). A kd-tree (kd_depth, kd_split) or a grid
(grid_scale) is built on first use and kept while its Geometry lives, keyed by the geometry's
identity, the kind and the parameters that shape it, so the viewer's re-renders and the pixel
inspector reuse it; `mailbox` only changes how the walk uses it. Each use reports the build:
its time, whether this call built it, and the structure's figures (nodes or cells, items, depth,
items per leaf or cell, bytes), which the renderer puts in frame.extras["accel"].
"""
from __future__ import annotations

import threading
import time
import weakref
from typing import NamedTuple

from .aggregate import bvh_nodes, grid_cells, kd_nodes, walk_stack
from .grid import build_grid
from .kdtree import build_kdtree

KIND_NAMES = {"bvh": "BVH", "kdtree": "kd-tree", "grid": "grid"}

_BUILT: dict = {}  # (id(geometry), kind, parameters) -> (weakref to the geometry, structure, report)
# Reentrant: a geometry collected while this thread holds the lock (a build allocates, and the
# collector may run there) has its finalizer, _forget, take the lock again on the same thread.
_LOCK = threading.RLock()


class Aggregate(NamedTuple):
    record: tuple   # the kernels' record (aggregate.BvhNodes, KdNodes or GridCells)
    stack: int      # entries of the walk's stack (aggregate.walk_scratch)
    report: dict    # the build's figures for frame.extras["accel"]


def parameters(opts) -> tuple:
    """The options that shape the structure of opts.accel (not `mailbox`: the walk's choice)."""
    if opts.accel == "kdtree":
        return (("kd_depth", int(opts.kd_depth)), ("kd_split", opts.kd_split))
    if opts.accel == "grid":
        return (("grid_scale", float(opts.grid_scale)), ("registration", registration(opts)))
    return ()


def registration(opts) -> str:
    """How the grid registers a leaf (grid.build_grid): 'quarters' (Lischinski's l_a, the box's
    quarters where it is large) under the float and mantissa criteria, whose hit boxes hug the
    surface; 'boxes' (the leaf's whole box in every voxel it overlaps) under fixed and adaptive,
    whose coarse hit boxes reach voxels the quarters miss: a walk that skipped those would report
    another hit than the BVH's."""
    return "quarters" if opts.criterion in ("float", "mantissa") else "boxes"


def describe(opts) -> str:
    """e.g. 'kd-tree (kd_depth 20, kd_split sah)', for progress notes."""
    params = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in parameters(opts))
    return KIND_NAMES[opts.accel] + (f" ({params})" if params else "")


def build_structure(geom, opts):
    """A new kd-tree (kdtree.KdTree) or grid (grid.Grid) over geom's leaves, as opts ask; no cache."""
    if opts.accel == "kdtree":
        return build_kdtree(geom.leaf_box, opts.kd_depth, opts.kd_split)
    return build_grid(geom, opts.grid_scale, registration(opts) == "quarters")


def _forget(key):
    with _LOCK:
        _BUILT.pop(key, None)


def aggregate_for(geom, opts, on_build=None) -> Aggregate:
    """The structure opts.accel asks for over geom's leaves, built now or taken from the cache.

    on_build(description) is called before a build and on_build(description, seconds) after it."""
    if opts.accel == "bvh":
        bvh = geom.bvh
        n = len(bvh.node_patch)
        report = {"kind": "bvh", "parameters": {}, "build_seconds": None, "built_now": False,
                  "nodes": n, "leaves": int((bvh.node_patch >= 0).sum()), "items": int((bvh.node_patch >= 0).sum()),
                  "depth": int(bvh.depth), "mean_items_per_leaf": 1.0,
                  "bytes": int(bvh.node_box.nbytes + bvh.node_child.nbytes + bvh.node_patch.nbytes)}
        return Aggregate(bvh_nodes(bvh), walk_stack(bvh), report)
    if opts.accel not in ("kdtree", "grid"):
        raise ValueError(f"option accel: unknown structure {opts.accel!r}")
    params = parameters(opts)
    key = (id(geom), opts.accel, params)
    with _LOCK:  # one build at a time: a second caller waits for it instead of building again
        entry = _BUILT.get(key)
        built_now = entry is None or entry[0]() is not geom
        if built_now:
            if on_build is not None:
                on_build(describe(opts))
            start = time.perf_counter()
            structure = build_structure(geom, opts)
            seconds = time.perf_counter() - start
            figures = {"kind": opts.accel, "parameters": dict(params), "build_seconds": seconds,
                       **structure.report()}
            _BUILT[key] = (weakref.ref(geom), structure, figures)
            weakref.finalize(geom, _forget, key)
            if on_build is not None:
                on_build(describe(opts), seconds)
        _, structure, figures = _BUILT[key]
    report = {**figures, "built_now": built_now, "mailbox": bool(opts.mailbox)}
    if opts.accel == "kdtree":
        return Aggregate(kd_nodes(structure, geom.leaf_box, opts.mailbox), structure.depth + 2, report)
    return Aggregate(grid_cells(structure, geom.leaf_box, opts.mailbox), 3, report)


def cached_count() -> int:
    """Structures held (tests: they go with their geometry)."""
    with _LOCK:
        return len(_BUILT)
