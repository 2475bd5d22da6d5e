"""The per-tile kernel: primary rays of one image rectangle, writing per-pixel channels.

Called from worker threads (it releases the GIL), one call per tile; all
scratch is allocated per call so threads share nothing but the output arrays,
of which each tile writes only its own rectangle.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .intersect import MF_LEN
from .ray import H_HI, H_LO, H_PATCH, H_TIN, H_TOUT, H_U, H_V, HIT_LEN, RAY_LEN, make_ray
from .traverse import hit_normal, trace_ray
from .trim_kernel import MAX_SPLIT_DEPTH


@njit(cache=True, nogil=True)
def render_tile(y0, y1, x0, x1, origins, dirs, patches, node_box, node_child, node_patch,
                criterion, param, split_mode, max_depth, bits, detail_slope, max_points, stack_nodes,
                trims, trim_points, leaf_patch,
                out_hit, out_t, out_pos, out_lo, out_hi, out_normal, out_uv, out_patch, out_effort):
    """Trace pixels [y0, y1) x [x0, x1). origins/dirs: (H, W, 3) float64 rays as traced.

    patches: the leaf arrays, as traverse.trace_ray takes them. detail_slope: threshold of detail
    per unit distance (adaptive criterion; 0 otherwise).
    trims: the trim tuple (geometry.Geometry.trims_for); the kernel's patches are leaves, and
    leaf_patch maps them to scene patches for the output. Outputs follow the per-pixel contract
    (see render.Frame); uv is in the parameters of the patch's surface (NURBS), else of the patch.
    """
    slots = max_depth + 2
    buf = np.zeros((slots, 4, max_points), patches[0].dtype)
    box = np.zeros((slots, 6))
    mf = np.zeros((slots, MF_LEN))
    mi = np.zeros((slots, 5), np.int32)
    order = np.arange(slots).astype(np.uint32)  # unsigned slot indices: no negative-index fix-ups
    lray = np.zeros(RAY_LEN)
    trim_h = np.zeros((MAX_SPLIT_DEPTH + 4, trim_points, 3))
    trim_m = np.zeros((MAX_SPLIT_DEPTH + 4, 6))
    node_stack = np.zeros(stack_nodes, np.int32)
    node_tin = np.zeros(stack_nodes)
    _render_pixels(y0, y1, x0, x1, origins, dirs, patches, node_box, node_child, node_patch,
                   criterion, param, split_mode, max_depth, bits, detail_slope,
                   trims, leaf_patch, buf, box, mf, mi, order, lray, np.zeros((4, max_points)),
                   trim_h, trim_m,
                   node_stack, node_tin, np.zeros(RAY_LEN), np.zeros(HIT_LEN), np.zeros((4, max_points)),
                   np.zeros((4, max_points)), np.zeros((6, 4)), np.zeros(3),
                   out_hit, out_t, out_pos, out_lo, out_hi, out_normal, out_uv, out_patch, out_effort)


@njit(cache=True, nogil=True, _nrt=False)  # allocates nothing: no reference counts (see intersect)
def _render_pixels(y0, y1, x0, x1, origins, dirs, patches, node_box, node_child, node_patch,
                   criterion, param, split_mode, max_depth, bits, detail_slope,
                   trims, leaf_patch, buf, box, mf, mi, order, lray, w64, trim_h, trim_m,
                   node_stack, node_tin, ray, hit, pts, scratch, work, normal,
                   out_hit, out_t, out_pos, out_lo, out_hi, out_normal, out_uv, out_patch, out_effort):
    """render_tile's pixel loop, on scratch it was given."""
    domain = trims[1]
    ctrl, pstart, deg_u, deg_v, rational = patches[:5]
    for y in range(y0, y1):
        for x in range(x0, x1):
            dx = dirs[y, x, 0]
            dy = dirs[y, x, 1]
            dz = dirs[y, x, 2]
            length = math.sqrt(dx * dx + dy * dy + dz * dz)
            make_ray(ray, origins[y, x, 0], origins[y, x, 1], origins[y, x, 2], dx, dy, dz,
                     0.0, 0.0, detail_slope * length)
            hit[H_TIN] = math.inf
            out_effort[y, x] = trace_ray(ray, hit, patches, node_box, node_child, node_patch,
                                         criterion, param, split_mode, max_depth, bits,
                                         buf, box, mf, mi, order, lray, w64, trims, trim_h, trim_m,
                                         node_stack, node_tin, None)
            if hit[H_TIN] == math.inf:
                out_hit[y, x] = False
                out_t[y, x] = math.inf
                out_patch[y, x] = -1
                for c in range(3):
                    out_pos[y, x, c] = math.nan
                    out_lo[y, x, c] = math.nan
                    out_hi[y, x, c] = math.nan
                    out_normal[y, x, c] = 0.0
                out_uv[y, x, 0] = math.nan
                out_uv[y, x, 1] = math.nan
                continue
            out_hit[y, x] = True
            out_patch[y, x] = leaf_patch[int(hit[H_PATCH])]
            along = 0.0
            for c in range(3):
                lo = hit[H_LO + c]
                hi = hit[H_HI + c]
                centre = 0.5 * (lo + hi)
                out_lo[y, x, c] = lo
                out_hi[y, x, c] = hi
                out_pos[y, x, c] = centre
                along += (centre - ray[c]) * ray[3 + c]
            # t of the ray point nearest the box centre, kept inside the box's slab interval.
            out_t[y, x] = min(max(along / (length * length), hit[H_TIN]), hit[H_TOUT])
            p = int(hit[H_PATCH])
            out_uv[y, x, 0] = domain[p, 0] + hit[H_U] * (domain[p, 1] - domain[p, 0])
            out_uv[y, x, 1] = domain[p, 2] + hit[H_V] * (domain[p, 3] - domain[p, 2])
            hit_normal(hit, ctrl, pstart, deg_u, deg_v, rational, ray, pts, scratch, work, normal)
            for c in range(3):
                out_normal[y, x, c] = normal[c]
