"""The surface normal at a reported hit."""
from __future__ import annotations

import math

import numpy as np

from .jit import njit

from .bezier import _bernstein_row, normal_at, normal_from, tangents
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
        found = _bicubic_normal(ctrl, start, u, v, pts, scratch, work, out)
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
def _bicubic_normal(ctrl, start, u, v, pts, scratch, work, out):
    """normal_at for an integral bicubic leaf, bit for bit: the same tangents, with the degrees
    constants (the loops unrolled) and neither the point itself nor the weights computed."""
    three = np.int64(3)
    two = np.int64(2)
    for c in range(3):
        for k in range(16):
            pts[c, k] = ctrl[c, start + k]
    _bernstein_row(three, u, scratch[0])
    _bernstein_row(three, v, scratch[1])
    _bernstein_row(two, u, scratch[2])
    _bernstein_row(two, v, scratch[3])
    for c in range(3):
        tangents(pts[c], three, three, scratch[0], scratch[1], scratch[2], scratch[3], c, work)
    return normal_from(work, u, v, False, out)
