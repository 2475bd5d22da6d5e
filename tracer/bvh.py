"""Bounding volume hierarchy over patches, flattened into node arrays.

One patch per leaf (Dammertz 3.2); splits chosen by the surface area heuristic
over the sorted box centroids of each axis. Traversal lives in intersect.trace_ray.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Bvh:
    node_box: np.ndarray    # (N, 6) float64: lo xyz, hi xyz
    node_child: np.ndarray  # (N, 2) int32: children, -1 at a leaf
    node_patch: np.ndarray  # (N,) int32: the leaf's patch, -1 inside

    @property
    def depth(self) -> int:
        depth = np.zeros(len(self.node_patch), np.int32)
        for node in range(len(depth)):  # children always follow their parent
            for child in self.node_child[node]:
                if child >= 0:
                    depth[child] = depth[node] + 1
        return int(depth.max()) + 1


def _area(lo, hi):
    e = np.maximum(hi - lo, 0.0)
    return 2.0 * (e[..., 0] * e[..., 1] + e[..., 1] * e[..., 2] + e[..., 2] * e[..., 0])


def _best_split(boxes):
    """(axis, order, count) minimising the SAH cost of splitting boxes after `count` of `order`."""
    centre = 0.5 * (boxes[:, :3] + boxes[:, 3:])
    best = (np.inf, 0, None, 1)
    for axis in range(3):
        order = np.argsort(centre[:, axis], kind="stable")
        lo = boxes[order, :3]
        hi = boxes[order, 3:]
        left = _area(np.minimum.accumulate(lo), np.maximum.accumulate(hi))[:-1]
        right = _area(np.minimum.accumulate(lo[::-1]), np.maximum.accumulate(hi[::-1]))[::-1][1:]
        counts = np.arange(1, len(boxes))
        cost = left * counts + right * (len(boxes) - counts)
        k = int(np.argmin(cost))
        if cost[k] < best[0]:
            best = (cost[k], axis, order, k + 1)
    return best[2], best[3]


def build_bvh(boxes: np.ndarray) -> Bvh:
    """BVH over patch boxes (n, 6); node 0 is the root, children follow their parent."""
    n = len(boxes)
    if n == 0:
        raise ValueError("cannot build a BVH over an empty scene")
    node_box = np.zeros((2 * n - 1, 6))
    node_child = np.full((2 * n - 1, 2), -1, np.int32)
    node_patch = np.full(2 * n - 1, -1, np.int32)
    count = 1
    work = [(0, np.arange(n))]  # (node, patches) still to place
    while work:
        node, items = work.pop()
        sub = boxes[items]
        node_box[node, :3] = sub[:, :3].min(axis=0)
        node_box[node, 3:] = sub[:, 3:].max(axis=0)
        if len(items) == 1:
            node_patch[node] = items[0]
            continue
        order, k = _best_split(sub)
        left, right = count, count + 1
        count += 2
        node_child[node] = (left, right)
        work.append((left, items[order[:k]]))
        work.append((right, items[order[k:]]))
    return Bvh(node_box, node_child, node_patch)
