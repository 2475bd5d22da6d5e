"""Bounding volume hierarchy over patches, flattened into node arrays.

One patch per leaf (Dammertz 3.2); each node splits where the surface area heuristic is lowest
over its boxes sorted by centroid along each axis (a full sweep: every split position of every
axis), the stable order of the node's boxes breaking ties. Traversal lives in aggregate.py.

Built in O(n log n) by a compiled kernel (`_build`): each axis's order is kept sorted from the
root down (children partition it stably), and a node's stable sort along an axis is a counting
sort of its boxes by their rank in that order, so no node sorts; the split is the one a stable
argsort per node and axis gives, bit for bit (tests/test_bvh.py holds it against that).

Extreme coordinates: the heuristic's areas are products of box extents, and n of them are
summed into costs, so they would overflow for extents past about 1e150 (and underflow to zero
for extents below about 1e-160, where every split would cost nothing). The costs are computed
on the boxes scaled by a power of two (exact) to coordinates near 1 whenever the scene's largest
coordinate lies outside 2^-400..2^400 (`cost_scale`); the split choice is invariant under such a
scale, node boxes are the unscaled boxes' unions, and ordinary scenes are built unscaled, as ever.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .jit import njit

COST_RANGE = 2.0 ** 400  # coordinates beyond it (or all below 1/COST_RANGE) are scaled for the costs


@dataclass(frozen=True)
class Bvh:
    node_box: np.ndarray    # (N, 6) float64: lo xyz, hi xyz
    node_child: np.ndarray  # (N, 2) int32: children, -1 at a leaf
    node_patch: np.ndarray  # (N,) int32: the leaf's patch, -1 inside
    depth: int              # nodes on the longest path from the root to a leaf (the walk's stack)


def cost_scale(boxes: np.ndarray) -> float:
    """The power of two the split costs are computed at: 1 unless the boxes' largest coordinate
    lies outside 1/COST_RANGE..COST_RANGE, then one that brings it to [0.5, 1)."""
    largest = float(np.max(np.abs(boxes))) if boxes.size else 0.0
    if largest == 0.0 or 1.0 / COST_RANGE <= largest <= COST_RANGE:
        return 1.0
    return float(np.ldexp(1.0, -int(np.frexp(largest)[1])))


def build_bvh(boxes: np.ndarray) -> Bvh:
    """BVH over patch boxes (n, 6) float64, finite, lo <= hi; node 0 is the root, children follow
    their parent."""
    boxes = np.ascontiguousarray(boxes, np.float64)
    n = len(boxes)
    if n == 0:
        raise ValueError("cannot build a BVH over an empty scene")
    if not np.all(np.isfinite(boxes)):
        raise ValueError("cannot build a BVH over boxes that are not finite")
    scale = cost_scale(boxes)
    scaled = boxes * scale if scale != 1.0 else boxes
    centre = np.ascontiguousarray(0.5 * (scaled[:, :3] + scaled[:, 3:]))
    axis_order = np.ascontiguousarray(np.argsort(centre, axis=0, kind="stable").T.astype(np.int32))
    node_box = np.zeros((2 * n - 1, 6))
    node_child = np.full((2 * n - 1, 2), -1, np.int32)
    node_patch = np.full(2 * n - 1, -1, np.int32)
    depth = _build(boxes, scaled, centre, axis_order, node_box, node_child, node_patch)
    return Bvh(node_box, node_child, node_patch, int(depth))


@njit(cache=True, nogil=True)
def _area(lx, ly, lz, hx, hy, hz):
    """Surface area of a box, in the reference's order of operations (bit for bit)."""
    ex = max(hx - lx, 0.0)
    ey = max(hy - ly, 0.0)
    ez = max(hz - lz, 0.0)
    return 2.0 * (ex * ey + ey * ez + ez * ex)


@njit(cache=True, nogil=True)
def _sweep(scaled, order, s, e, left_area, best_cost):
    """The lowest SAH cost of splitting order[s:e] after its first k boxes: (cost, k), with cost
    below best_cost, or (best_cost, 0) if none is. Ties go to the smallest k."""
    m = e - s
    lx = ly = lz = np.inf
    hx = hy = hz = -np.inf
    for i in range(m - 1):
        b = order[s + i]
        lx, ly, lz = min(lx, scaled[b, 0]), min(ly, scaled[b, 1]), min(lz, scaled[b, 2])
        hx, hy, hz = max(hx, scaled[b, 3]), max(hy, scaled[b, 4]), max(hz, scaled[b, 5])
        left_area[i] = _area(lx, ly, lz, hx, hy, hz)
    lx = ly = lz = np.inf
    hx = hy = hz = -np.inf
    axis_cost, axis_k = np.inf, 0
    for i in range(m - 1, 0, -1):  # the right part is order[s + i:e]
        b = order[s + i]
        lx, ly, lz = min(lx, scaled[b, 0]), min(ly, scaled[b, 1]), min(lz, scaled[b, 2])
        hx, hy, hz = max(hx, scaled[b, 3]), max(hy, scaled[b, 4]), max(hz, scaled[b, 5])
        cost = left_area[i - 1] * float(i) + _area(lx, ly, lz, hx, hy, hz) * float(m - i)
        if cost <= axis_cost:  # walking down, <= keeps the smallest k of equal costs
            axis_cost, axis_k = cost, i
    if axis_cost < best_cost:
        return axis_cost, axis_k
    return best_cost, 0


@njit(cache=True, nogil=True)
def _stable_sort_by_rank(items, s, e, rank, count, out):
    """out[s:e] = items[s:e] stably sorted by rank[item] (ranks 0..e-s-1): a counting sort."""
    for r in range(e - s + 1):
        count[r] = 0
    for i in range(s, e):
        count[rank[items[i]] + 1] += 1
    for r in range(1, e - s + 1):
        count[r] += count[r - 1]
    for i in range(s, e):
        b = items[i]
        out[s + count[rank[b]]] = b
        count[rank[b]] += 1


@njit(cache=True, nogil=True)
def _build(boxes, scaled, centre, axis_order, node_box, node_child, node_patch):
    """Fill the node arrays (2n - 1 nodes, depth-first as the reference numbers them: a node's
    children are numbered when it is split, the right one is built first); returns the depth.

    boxes, scaled: (n, 6) float64, the boxes and the boxes the costs are computed on;
    centre: (n, 3) float64 centroids of scaled; axis_order: (3, n) int32, the boxes sorted by
    centre along each axis (any order among equal centres). A node owns the slice [s, e) of
    `items` (its boxes in the reference's order: its parent's sort along the split axis) and of
    each axis_order row (its boxes in centroid order)."""
    n = len(boxes)
    items = np.arange(n).astype(np.int32)
    sorted_by = np.empty((3, n), np.int32)
    rank = np.empty(n, np.int64)
    count = np.empty(n + 1, np.int64)
    left_area = np.empty(n, np.float64)
    is_left = np.empty(n, np.bool_)
    spare = np.empty(n, np.int32)
    stack = np.empty((n + 1, 3), np.int64)  # node, s, e; at most one entry per level plus one
    node_depth = np.ones(2 * n - 1, np.int64)
    stack[0, 0], stack[0, 1], stack[0, 2] = 0, 0, n
    top, nodes, depth = 1, 1, 1
    while top > 0:
        top -= 1
        node, s, e = stack[top, 0], stack[top, 1], stack[top, 2]
        depth = max(depth, node_depth[node])
        for a in range(3):
            lo, hi = np.inf, -np.inf
            for i in range(s, e):
                lo = min(lo, boxes[items[i], a])
                hi = max(hi, boxes[items[i], 3 + a])
            node_box[node, a], node_box[node, 3 + a] = lo, hi
        if e - s == 1:
            node_patch[node] = items[s]
            continue
        best_cost, best_axis, best_k = np.inf, -1, 0
        for a in range(3):
            r = -1
            for i in range(s, e):  # rank by centre: boxes of equal centres share one
                b = axis_order[a, i]
                if i == s or centre[b, a] != centre[axis_order[a, i - 1], a]:
                    r += 1
                rank[b] = r
            _stable_sort_by_rank(items, s, e, rank, count, sorted_by[a])
            cost, k = _sweep(scaled, sorted_by[a], s, e, left_area, best_cost)
            if k > 0:
                best_cost, best_axis, best_k = cost, a, k
        if best_axis < 0:  # no finite cost (unreachable for finite boxes at cost_scale): halve
            best_axis, best_k = 0, (e - s) // 2
        for i in range(s, e):
            b = sorted_by[best_axis, i]
            items[i] = b
            is_left[b] = i < s + best_k
        for a in range(3):  # each axis's centroid order, partitioned stably between the children
            w = s
            for i in range(s, e):
                if is_left[axis_order[a, i]]:
                    spare[w] = axis_order[a, i]
                    w += 1
            for i in range(s, e):
                if not is_left[axis_order[a, i]]:
                    spare[w] = axis_order[a, i]
                    w += 1
            for i in range(s, e):
                axis_order[a, i] = spare[i]
        left, right = nodes, nodes + 1
        nodes += 2
        node_child[node, 0], node_child[node, 1] = left, right
        node_depth[left] = node_depth[right] = node_depth[node] + 1
        stack[top, 0], stack[top, 1], stack[top, 2] = left, s, s + best_k
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = right, s + best_k, e
        top += 2
    return depth
