"""Closest hit of a ray in the scene: BVH traversal over the patch searches, and the hit normal."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .bezier import normal_at
from .intersect import MF_LEN, search_patch
from .ray import H_PATCH, H_TIN, H_U, H_V, R_D, RAY_LEN, slab


@njit(cache=True, nogil=True, _nrt=False, inline='always')
def trace_ray(ray, hit, patches, node_box, node_child, node_patch,
              criterion, param, split_mode, max_depth, bits,
              buf, box, mf, mi, order, lray, w64, trims, trim_h, trim_m,
              node_stack, node_tin, trace):
    """Closest hit of one ray: BVH traversal, near child first, sharing the shrinking ray
    interval with the patch searches. Returns the total effort (patch boxes computed).

    patches: (ctrl, pstart, deg_u, deg_v, rational, frame, grid, eps, ctrl64, eps64) as
    search_patch takes them (one tuple keeps callers under the 30 arguments that numba can
    inline: the renderer inlines this walk, a call per ray cost a fifth of `adaptive`).
    node_box: (N, 6) float64 world boxes; node_child: (N, 2) int32 children (-1 at a leaf);
    node_patch: (N,) int32 patch of a leaf. hit[H_TIN] must hold the initial t_max (inf).
    """
    ctrl, pstart, deg_u, deg_v, rational, frame, grid, eps, ctrl64, eps64 = patches
    effort = 0
    ok, t_in, _ = slab(node_box[0], 0.0, 0.0, 0.0, ray)
    if not ok:
        return 0
    node_stack[0] = 0
    node_tin[0] = t_in
    top = 1
    while top > 0:
        top -= 1
        node = node_stack[top]
        if node_tin[top] >= hit[H_TIN]:
            continue
        left = node_child[node, 0]
        if left < 0:
            effort += search_patch(node_patch[node], ctrl, pstart, deg_u, deg_v, rational, frame, grid, eps,
                                   ctrl64, eps64, ray, hit, criterion, param, split_mode, max_depth, bits,
                                   buf, box, mf, mi, order, lray, w64, trims, trim_h, trim_m, trace)
            continue
        right = node_child[node, 1]
        ok_l, tl, _ = slab(node_box[left], 0.0, 0.0, 0.0, ray)
        ok_r, tr, _ = slab(node_box[right], 0.0, 0.0, 0.0, ray)
        ok_l = ok_l and tl < hit[H_TIN]
        ok_r = ok_r and tr < hit[H_TIN]
        if ok_l and ok_r:
            far_first = tl <= tr
            node_stack[top] = right if far_first else left
            node_tin[top] = tr if far_first else tl
            node_stack[top + 1] = left if far_first else right
            node_tin[top + 1] = tl if far_first else tr
            top += 2
        elif ok_l or ok_r:
            node_stack[top] = left if ok_l else right
            node_tin[top] = tl if ok_l else tr
            top += 1
    return effort


@njit(cache=True, nogil=True, _nrt=False)
def hit_normal(hit, ctrl, pstart, deg_u, deg_v, rational, ray, pts, scratch, work, out):
    """Unit normal at the hit's (u, v), facing the ray; pts: (4, >= points) float64 scratch,
    scratch: (4, >= max degree + 1), work: (6, 4)."""
    p = int(hit[H_PATCH])
    m = deg_u[p]
    n = deg_v[p]
    start = pstart[p]
    count = (m + 1) * (n + 1)
    for c in range(4):
        for k in range(count):
            pts[c, k] = ctrl[c, start + k]
    if not normal_at(pts, m, n, hit[H_U], hit[H_V], rational[p] != 0, scratch, work, out):
        # A fully collapsed patch: face the ray.
        length = math.sqrt(ray[3] ** 2 + ray[4] ** 2 + ray[5] ** 2)
        for c in range(3):
            out[c] = -ray[R_D + c] / length
        return
    if out[0] * ray[3] + out[1] * ray[4] + out[2] * ray[5] > 0.0:
        for c in range(3):
            out[c] = -out[c]


def scratch_for(n_points: int, max_depth: int, dtype):
    """Per-thread scratch for search_patch / trace_ray: buf, box, mf, mi, order, lray, w64."""
    slots = max_depth + 2
    return (np.zeros((slots, 4, n_points), dtype), np.zeros((slots, 6)), np.zeros((slots, MF_LEN)),
            np.zeros((slots, 5), np.int32), np.arange(slots, dtype=np.uint32), np.zeros(RAY_LEN),
            np.zeros((4, n_points)))
