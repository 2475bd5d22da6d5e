"""The surface normal at a reported hit."""
from __future__ import annotations

import math

from .jit import njit

from .bezier import normal_at
from .ray import H_PATCH, H_U, H_V, R_D


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
