"""The surface normal at a reported hit."""
from __future__ import annotations

import math

import numpy as np

from .jit import njit

from .bezier import _bernstein_row, normal_at, normal_from
from .simd import bicubic_tangents
from .ray import H_PATCH, H_U, H_V, R_D


@njit(cache=True, nogil=True, _nrt=False)
def hit_normal(hit, ctrl, pstart, deg_u, deg_v, rational, ray, pts, scratch, work, out):
    """Unit normal at the hit's (u, v), facing the ray; pts: (4, >= points) float64 scratch,
    scratch: (4, >= max degree + 1), work: (6, 4)."""
    p = int(hit[H_PATCH])
    m = deg_u[p]
    n = deg_v[p]
    start = pstart[p]
    u = hit[H_U]
    v = hit[H_V]
    if m == 3 and n == 3 and rational[p] == 0:
        found = _bicubic_normal(ctrl, start, u, v, scratch, work, out)
    elif m == 1 and n == 1 and rational[p] == 0:
        found = _bilinear_normal(ctrl, start, u, v, work, out)
    else:
        count = (m + 1) * (n + 1)
        for c in range(4):
            for k in range(count):
                pts[c, k] = ctrl[c, start + k]
        found = normal_at(pts, m, n, u, v, rational[p] != 0, scratch, work, out)
    if not found:
        # A fully collapsed patch: face the ray.
        length = math.sqrt(ray[3] ** 2 + ray[4] ** 2 + ray[5] ** 2)
        for c in range(3):
            out[c] = -ray[R_D + c] / length
        return
    if out[0] * ray[3] + out[1] * ray[4] + out[2] * ray[5] > 0.0:
        for c in range(3):
            out[c] = -out[c]


@njit(cache=True, nogil=True, inline='always')
def _bicubic_normal(ctrl, start, u, v, scratch, work, out):
    """normal_at for an integral bicubic leaf, bit for bit: evaluate's Bernstein rows, the tangents
    with the three coordinates side by side (simd.bicubic_tangents), neither the point itself nor
    its weight computed."""
    bu, bv, du, dv = scratch[0], scratch[1], scratch[2], scratch[3]
    _bernstein_row(np.int64(3), u, bu)
    _bernstein_row(np.int64(3), v, bv)
    _bernstein_row(np.int64(2), u, du)
    _bernstein_row(np.int64(2), v, dv)
    bicubic_tangents(ctrl, start, bu[0], bu[1], bu[2], bu[3], bv[0], bv[1], bv[2], bv[3], du[0], du[1], du[2], dv[0],
                     dv[1], dv[2], work)
    return normal_from(work, u, v, False, out)


@njit(cache=True, nogil=True, inline='always')
def _bilinear_normal(ctrl, start, u, v, work, out):
    """normal_at for an integral bilinear leaf (floors, planes), bit for bit: evaluate's Bernstein
    rows and tangents written out for degree 1, its sums in the same order from the same 0.0 (so
    a zero keeps its sign), the products by 1.0 left out (they are exact)."""
    bu0 = 0.0 + (1.0 - u)
    bv0 = 0.0 + (1.0 - v)
    for c in range(3):
        a0 = np.float64(ctrl[c, start])
        a1 = np.float64(ctrl[c, start + 1])
        a2 = np.float64(ctrl[c, start + 2])
        a3 = np.float64(ctrl[c, start + 3])
        work[1, c] = 0.0 + bv0 * (a1 - a0) + v * (a3 - a2)
        work[2, c] = 0.0 + bu0 * (a2 - a0) + u * (a3 - a1)
        work[3, c] = 0.0 + (a3 - a2 - a1 + a0)
    return normal_from(work, u, v, False, out)
