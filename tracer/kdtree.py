"""kd-tree over the kernel's patches (their boxes, geometry.leaf_box), flattened into node arrays.

Dammertz 2005 (3.2, table 3.1) set a kd-tree (BSP) of depth 10-30 against his BVH over patches:
axis-aligned planes rarely separate patches, so leaves hold several and the patch searches
dominate. This is that tree, for measuring it here. Nodes are numbered depth first, node 0 the
root; an inner node's below child is node + 1, its above child node_above[node]; a leaf lists its
patches as items[node_first:node_first + node_count]. A patch whose box straddles a plane is listed
on both sides, so a patch can sit in several leaves. A box goes below when it starts below the
plane or ends at it, above when it ends above it or starts at it (a box flat in the plane goes to
both): every patch point lies in the voxel of each leaf that lists the patch, closed faces included.

Split planes (`rule`):
  sah     the surface area heuristic over the sides of the node's boxes inside its voxel, with
          pbrt's costs (a node step 1, a patch 80) but Wald and Havran's (2006) bonus for an empty
          side, a fifth off instead of pbrt's half: with half off, cutting a sliver of empty space
          off a flat field of teapots cost as little as halving it, the tree peeled slivers until
          the depth limit and left leaves of 188 patches (800 teapots, depth 20: 1,011 nodes, frames
          1.6x the BVH's; now 48,257 nodes, 5.5 patches a non-empty leaf); a node stays a leaf
          when splitting costs 4x a leaf with under 16 patches, or costs more than a leaf for the
          third time on its path (pbrt's bad refines);
  middle  Dammertz's: the side of a patch box nearest the middle of the voxel, on the longest axis
          that has one inside (so at least one patch is split off).
Both stop at `max_depth` planes on a path, at a single patch, and when a plane separates nothing.

Built by a compiled kernel, top down with an explicit stack: a node sorts its boxes' sides along
each axis, O(k log k) for its k boxes, so a tree costs about O(n log^2 n) for n patches (plus the
copies of straddling patches). Costs are computed on boxes scaled by bvh.cost_scale (a power of
two) so areas neither overflow nor vanish at extreme coordinates; planes are unscaled exactly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bvh import cost_scale
from .jit import njit

RULES = ("sah", "middle")
C_STEP, C_PATCH, EMPTY_BONUS = 1.0, 80.0, 0.2
BAD_REFINES = 3


@dataclass(frozen=True)
class KdTree:
    bounds: np.ndarray      # (6,) float64 the root voxel (lo xyz, hi xyz): the union of the boxes
    node_axis: np.ndarray   # (N,) int32 split axis 0-2, -1 at a leaf
    node_split: np.ndarray  # (N,) float64 the plane's coordinate (inner nodes)
    node_above: np.ndarray  # (N,) int32 the above child (inner nodes); the below child is node + 1
    node_first: np.ndarray  # (N,) int32 a leaf's first item
    node_count: np.ndarray  # (N,) int32 a leaf's item count
    items: np.ndarray       # (I,) int32 patch indices, leaf by leaf
    depth: int              # most planes on a path from the root to a leaf

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.bounds, self.node_axis, self.node_split, self.node_above,
                                      self.node_first, self.node_count, self.items))

    def report(self) -> dict:
        """Figures of the tree: nodes, leaves (empty ones too), items, depth, items per leaf."""
        leaf = self.node_axis < 0
        counts = self.node_count[leaf]
        full = counts[counts > 0]
        return {"nodes": int(len(self.node_axis)), "leaves": int(leaf.sum()), "empty_leaves": int((counts == 0).sum()),
                "items": int(len(self.items)), "depth": int(self.depth),
                "mean_items_per_leaf": float(counts.mean()),
                "mean_items_per_full_leaf": float(full.mean()) if len(full) else 0.0,
                "max_items_per_leaf": int(counts.max()), "bytes": int(self.nbytes)}


def build_kdtree(boxes: np.ndarray, max_depth: int = 20, rule: str = "sah") -> KdTree:
    """kd-tree over patch boxes (n, 6) float64 (finite, lo <= hi), at most max_depth planes deep."""
    boxes = np.ascontiguousarray(boxes, np.float64)
    if len(boxes) == 0:
        raise ValueError("cannot build a kd-tree over an empty scene")
    if not np.all(np.isfinite(boxes)):
        raise ValueError("cannot build a kd-tree over boxes that are not finite")
    if rule not in RULES:
        raise ValueError(f"kd-tree split rule must be one of {', '.join(RULES)}, got {rule!r}")
    if not 0 <= int(max_depth) <= 64:
        raise ValueError(f"kd-tree depth must be in 0..64, got {max_depth}")
    scale = cost_scale(boxes)
    scaled = boxes * scale if scale != 1.0 else boxes
    root = np.concatenate([scaled[:, :3].min(axis=0), scaled[:, 3:].max(axis=0)])
    axis, split, above, first, count, items, n_nodes, n_items, depth = _build(scaled, root, int(max_depth),
                                                                             rule == "sah")
    bounds = np.concatenate([boxes[:, :3].min(axis=0), boxes[:, 3:].max(axis=0)])
    return KdTree(bounds, axis[:n_nodes].copy(), split[:n_nodes] / scale, above[:n_nodes].copy(),
                  first[:n_nodes].copy(), count[:n_nodes].copy(), items[:n_items].copy(), int(depth))


@njit(cache=True, nogil=True)
def _grown(a, need):
    """a, or a copy at least twice as long when `need` entries do not fit."""
    if need <= len(a):
        return a
    b = np.empty(max(need, 2 * len(a)), a.dtype)
    b[:len(a)] = a
    return b


@njit(cache=True, nogil=True)
def _area(ex, ey, ez):
    return 2.0 * (ex * ey + ey * ez + ez * ex)


@njit(cache=True, nogil=True)
def _sah_plane(boxes, pool, s, c, bounds, lo_s, hi_s):
    """The cheapest plane of a node (pool[s:s + c] in the voxel `bounds`): (cost, axis, plane),
    axis -1 when no box side lies strictly inside the voxel. Every distinct side is a candidate:
    below it lie the boxes starting before it, above it those ending after it."""
    ext = np.empty(3)
    for a in range(3):
        ext[a] = bounds[3 + a] - bounds[a]
    total = _area(ext[0], ext[1], ext[2])
    best_cost, best_axis, best_plane = np.inf, -1, 0.0
    for a in range(3):
        for i in range(c):
            lo_s[i] = boxes[pool[s + i], a]
            hi_s[i] = boxes[pool[s + i], 3 + a]
        lo_s[:c].sort()
        hi_s[:c].sort()
        b_lo, b_hi = bounds[a], bounds[3 + a]
        il = ih = 0
        p = lo_s[0]
        while True:
            while il < c and lo_s[il] < p:
                il += 1
            while ih < c and hi_s[ih] <= p:
                ih += 1
            if b_lo < p < b_hi:
                n_below, n_above = il, c - ih
                if total > 0.0:
                    e = ext[a]
                    ext[a] = p - b_lo
                    p_below = _area(ext[0], ext[1], ext[2]) / total
                    ext[a] = b_hi - p
                    p_above = _area(ext[0], ext[1], ext[2]) / total
                    ext[a] = e
                else:  # a voxel without area (patches on a line): every ray meets both sides
                    p_below = p_above = 1.0
                bonus = EMPTY_BONUS if n_below == 0 or n_above == 0 else 0.0
                cost = C_STEP + C_PATCH * (1.0 - bonus) * (p_below * n_below + p_above * n_above)
                if cost < best_cost:
                    best_cost, best_axis, best_plane = cost, a, p
            while il < c and lo_s[il] <= p:
                il += 1
            if il >= c and ih >= c:
                break
            p = np.inf
            if il < c:
                p = lo_s[il]
            if ih < c and hi_s[ih] < p:
                p = hi_s[ih]
    return best_cost, best_axis, best_plane


@njit(cache=True, nogil=True)
def _middle_plane(boxes, pool, s, c, bounds):
    """Dammertz's plane: (axis, plane), the patch-box side strictly inside the voxel nearest its
    middle, on the longest axis that has one (sides of boxes flat along the axis do not count:
    such a box would go to both sides). Axis -1: none."""
    order = np.argsort(-(bounds[3:] - bounds[:3]))
    for a in order:
        b_lo, b_hi = bounds[a], bounds[3 + a]
        mid = 0.5 * (b_lo + b_hi)
        best, plane = np.inf, 0.0
        for i in range(c):
            lo, hi = boxes[pool[s + i], a], boxes[pool[s + i], 3 + a]
            if lo == hi:
                continue
            for side in (lo, hi):
                if b_lo < side < b_hi and abs(side - mid) < best:
                    best, plane = abs(side - mid), side
        if best < np.inf:
            return a, plane
    return -1, 0.0


@njit(cache=True, nogil=True)
def _build(boxes, root, max_depth, sah):
    """The node arrays (each longer than needed: the counts follow), their counts and the depth.

    A node's patches are a slice of `pool`; its children's slices are written after the slices
    still in use (the above child's first, then the below child's, which is built next), so a
    slice is free again once the stack has returned below it."""
    n = len(boxes)
    cap = 64
    node_axis = np.empty(cap, np.int32)
    node_split = np.empty(cap, np.float64)
    node_above = np.empty(cap, np.int32)
    node_first = np.empty(cap, np.int32)
    node_count = np.empty(cap, np.int32)
    items = np.empty(max(n, 16), np.int32)
    pool = np.empty(2 * n + 16, np.int32)
    for i in range(n):
        pool[i] = i
    lo_s = np.empty(n)
    hi_s = np.empty(n)
    size = max_depth + 2
    st_int = np.empty((size, 5), np.int64)  # depth, start, count, bad refines, parent (-1: a below child)
    st_box = np.empty((size, 6))
    box = root.copy()
    depth, s, c, bad, parent = 0, 0, n, 0, -1
    top, n_nodes, n_items, deepest = 0, 0, 0, 0
    while True:
        node = n_nodes
        n_nodes += 1
        if n_nodes > len(node_axis):
            node_axis = _grown(node_axis, n_nodes)
            node_split = _grown(node_split, n_nodes)
            node_above = _grown(node_above, n_nodes)
            node_first = _grown(node_first, n_nodes)
            node_count = _grown(node_count, n_nodes)
        if parent >= 0:
            node_above[parent] = node
        node_above[node] = -1
        node_first[node] = 0
        node_count[node] = 0
        node_split[node] = 0.0
        deepest = max(deepest, depth)
        free = s + c  # the pool above this node's slice holds finished subtrees only
        axis, plane = -1, 0.0
        if c > 1 and depth < max_depth:
            if sah:
                cost, axis, plane = _sah_plane(boxes, pool, s, c, box, lo_s, hi_s)
                leaf_cost = C_PATCH * c
                if cost > leaf_cost:
                    bad += 1
                if (cost > 4.0 * leaf_cost and c < 16) or bad >= BAD_REFINES:
                    axis = -1
            else:
                axis, plane = _middle_plane(boxes, pool, s, c, box)
        n_below = n_above = 0
        if axis >= 0:
            for i in range(s, s + c):
                lo, hi = boxes[pool[i], axis], boxes[pool[i], 3 + axis]
                if lo < plane or hi <= plane:
                    n_below += 1
                if hi > plane or lo >= plane:
                    n_above += 1
            if n_below == c and n_above == c:  # the plane separates nothing
                axis = -1
        if axis < 0:
            node_axis[node] = -1
            node_first[node] = n_items
            node_count[node] = c
            items = _grown(items, n_items + c)
            for i in range(c):
                items[n_items + i] = pool[s + i]
            n_items += c
            if top == 0:
                break
            top -= 1
            depth, s, c, bad, parent = st_int[top, 0], st_int[top, 1], st_int[top, 2], st_int[top, 3], st_int[top, 4]
            box[:] = st_box[top]
            continue
        node_axis[node] = axis
        node_split[node] = plane
        pool = _grown(pool, free + n_above + n_below)
        wa, wb = free, free + n_above
        for i in range(s, s + c):
            b = pool[i]
            lo, hi = boxes[b, axis], boxes[b, 3 + axis]
            if hi > plane or lo >= plane:
                pool[wa] = b
                wa += 1
            if lo < plane or hi <= plane:
                pool[wb] = b
                wb += 1
        st_int[top, 0], st_int[top, 1], st_int[top, 2] = depth + 1, free, n_above
        st_int[top, 3], st_int[top, 4] = bad, node
        st_box[top] = box
        st_box[top, axis] = plane
        top += 1
        depth, s, c, parent = depth + 1, free + n_above, n_below, -1
        box[3 + axis] = plane
    return node_axis, node_split, node_above, node_first, node_count, items, n_nodes, n_items, deepest
