"""Fast penumbra (Lukaszewski 2001, ch. 3-4): points found fully lit by one ray trace no samples.

Lemma 3.1: let L be a light, star-convex about its centre c. If the segment from a point p to c
misses every obstacle box Q grown by the box of c - L, no segment from p to a point of L meets
an obstacle box. Our lights are centrally symmetric, so the growth is the box of L - c:
`half_extent` per axis, anisotropic for segments and rectangles (Example 4.1).

Lemma 4.2 (options.penumbra 'tmax'): on a segment from p to a light point l, a point x in Q
lies at s = |x - p| / (|x - p| + |l - x|) <= D / (D + d) along it, where D bounds the distance
from any shading point to Q and d is Q's distance from the light; the segment p -> c then
passes within s * (l - c) of x. So each box grows only by its own t_max = D / (D + d) < 1
times the light's half extent: per obstacle-light pair. D is taken over the scene's box, so a
point outside it (an origin moved off the scene) is not classified.

The obstacle boxes are the leaves' boxes (geometry.leaf_box): a shadow ray's patch search starts
only where the ray meets one (the BVH's leaf nodes, the kd-tree's and grid's patch_box), so a
sample ray can only find a hit in a leaf whose grown box the centre ray meets. The grown box of
the point's own leaf (and of its neighbours) always holds the ray's origin, so for those leaves
the samples' own patch searches decide, which mostly stop at the leaf's first box (the rays
leave the surface); any other grown box met means "not proven lit". A point proven lit has the
outcome of every sample known, and skipping them changes no bit. The grown boxes get a relative
margin of MARGIN over the float64 slab tests' rounding. The expanded data set is a BVH over the
grown boxes (aggregate interface, ray_batch's 'penumbra' kernel), built once per geometry, light
and method and kept while the geometry lives.
"""
from __future__ import annotations

import threading
import time
import weakref
from typing import NamedTuple

import numpy as np

from .aggregate import bvh_nodes, walk_stack
from .bvh import build_bvh
from .light_samples import half_extent

MARGIN = 2.0 ** -30  # relative growth beyond the lemma's (slab tests round at 2^-52)
LIT, PENUMBRA, UMBRA, UNCLASSIFIED = 0, 1, 2, -1

_BUILT: dict = {}
# Reentrant: a geometry collected while this thread holds the lock (a build allocates, and the
# collector may run there) has its finalizer, _forget, take the lock again on the same thread.
_LOCK = threading.RLock()


def scene_box(geom) -> np.ndarray:
    """(6,) the box of every leaf box, grown by MARGIN of its reach."""
    box = np.asarray(geom.leaf_box)
    lo, hi = box[:, :3].min(axis=0), box[:, 3:].max(axis=0)
    pad = MARGIN * np.maximum(np.abs(lo), np.abs(hi)).max()
    return np.concatenate([lo - pad, hi + pad])


def shrink_factors(boxes: np.ndarray, scene: np.ndarray, light_lo: np.ndarray, light_hi: np.ndarray) -> np.ndarray:
    """(n,) Lemma 4.2's t_max per box: D / (D + d), D the farthest distance from the scene box to
    the box, d the box's distance from the light's box (1 where they touch)."""
    far = np.maximum(np.abs(scene[3:] - boxes[:, :3]), np.abs(boxes[:, 3:] - scene[:3]))
    big = np.linalg.norm(far, axis=1)
    gap = np.maximum(0.0, np.maximum(boxes[:, :3] - light_hi, light_lo - boxes[:, 3:]))
    near = np.linalg.norm(gap, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = big / (big + near)
    return np.where(near > 0.0, np.minimum(t * (1.0 + 4 * MARGIN), 1.0), 1.0)


def grown_boxes(geom, light, method: str) -> np.ndarray:
    """(n_leaves, 6) the leaves' boxes grown by the light (method 'expanded' or 'tmax')."""
    boxes = np.asarray(geom.leaf_box, np.float64)
    half = half_extent(light)
    c = light.centre()
    if method == "tmax":
        grow = shrink_factors(boxes, scene_box(geom), c - half, c + half)[:, None] * half
    else:
        grow = np.broadcast_to(half, (len(boxes), 3))
    reach = np.maximum(np.abs(boxes[:, :3]), np.abs(boxes[:, 3:])).max(axis=1, keepdims=True)
    pad = MARGIN * (reach + half.max())
    return np.concatenate([boxes[:, :3] - grow - pad, boxes[:, 3:] + grow + pad], axis=1)


def _key(geom, light, method):
    shape = tuple(np.asarray(getattr(light, k), np.float64).tobytes() for k in ("center", "radius", "a", "b",
                                                                               "corner", "edge1", "edge2")
                  if getattr(light, k) is not None)
    return (id(geom), light.type, shape, method)


def _forget(key):
    with _LOCK:
        _BUILT.pop(key, None)


class ExpandedSet(NamedTuple):
    record: tuple       # aggregate.BvhNodes over the grown boxes (leaf indices as items)
    stack: int          # the walk's stack entries
    grown: np.ndarray   # (n_leaves, 6) grown_boxes
    report: dict        # build time and size


def expanded_set(geom, light, method: str) -> ExpandedSet:
    """The expanded data set of one light: built now, or kept from before for this geometry."""
    key = _key(geom, light, method)
    with _LOCK:
        entry = _BUILT.get(key)
        if entry is None or entry[0]() is not geom:
            start = time.perf_counter()
            grown = grown_boxes(geom, light, method)
            bvh = build_bvh(grown)
            report = {"method": method, "light": light.type, "build_seconds": time.perf_counter() - start,
                      "nodes": len(bvh.node_patch), "bytes": int(bvh.node_box.nbytes + bvh.node_child.nbytes)}
            entry = (weakref.ref(geom), ExpandedSet(bvh_nodes(bvh), walk_stack(bvh), grown, report))
            _BUILT[key] = entry
            weakref.finalize(geom, _forget, key)
        return entry[1]


def inside(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """(k,) bool: points (k, 3) within box (6,)."""
    return np.all((points >= box[:3]) & (points <= box[3:]), axis=1)
