"""A sub-patch's control hull against a ray (a slot of records.Slots, as subpatch.py): the hull's
extent across a plane through the ray, widened by the slot's error bounds. Tighter than the box:
the search drops a half whose hull misses one of two planes that meet in the ray (hull_hit), lies
beyond the plane along the seam a split just made (seam_plane), or lies behind a secondary ray's
side plane (hull_behind)."""
from __future__ import annotations

import math

import numpy as np

from .jit import njit
from .ray import R_D, R_N1, R_N2, R_O, R_SIDE
from .simd import dist_range_cubic
from .subpatch import M_E, M_MAG, M_OX, point


@njit(cache=True, nogil=True, _nrt=False)  # a call (see _CALLED)
def hull_range(buf, s, count, rational, cubic, n0, n1, n2):
    """The least and greatest x n0 + y n1 + z n2 over slot s's control points (cubic: an integral
    bicubic slot, its 16 points in vectors: simd, the same values)."""
    if cubic:
        return dist_range_cubic(buf, s, n0, n1, n2)
    lo = math.inf
    hi = -math.inf
    for k in range(count):
        x, y, z = point(buf, s, k, rational)
        dist = x * n0 + y * n1 + z * n2
        lo = min(lo, dist)
        hi = max(hi, dist)
    return lo, hi


@njit(cache=True, nogil=True, inline='always')
def hull_across(sl, s, pa, ray, n0, n1, n2):
    """(least, greatest, slack): the signed distances of slot s's control points from the plane
    through the ray's origin with unit normal (n0, n1, n2), and what they may be off by (the
    points' error bounds, the rounding of the distances)."""
    buf = sl.buf
    mf = sl.mf
    sub = mf[s, M_MAG] * pa.sub_scale
    rel0 = mf[s, M_OX] - ray[R_O]
    rel1 = mf[s, M_OX + 1] - ray[R_O + 1]
    rel2 = mf[s, M_OX + 2] - ray[R_O + 2]
    offset = rel0 * n0 + rel1 * n1 + rel2 * n2
    lo, hi = hull_range(buf, s, pa.count, pa.rational, pa.cubic, n0, n1, n2)
    slack = ((mf[s, M_E] + sub) * abs(n0) + (mf[s, M_E + 1] + sub) * abs(n1) + (mf[s, M_E + 2] + sub) * abs(n2)
             + 2.0 ** -51 * (abs(rel0) + abs(rel1) + abs(rel2) + max(abs(lo), abs(hi))))
    return offset + lo, offset + hi, slack


@njit(cache=True, nogil=True, inline='always')
def hull_off_plane(sl, s, pa, ray, n0, n1, n2):
    """Is the convex hull of slot s's control points (widened by the error bounds) wholly on one
    side of the plane through the ray with unit normal (n0, n1, n2), normal to the ray?"""
    lo, hi, slack = hull_across(sl, s, pa, ray, n0, n1, n2)
    return lo > slack or hi < -slack


@njit(cache=True, nogil=True, inline='always')
def hull_behind(sl, s, pa, ray):
    """Is slot s's hull (widened by the error bounds) wholly behind the ray's side plane
    (ray.set_side), which the ray never goes behind? Then no part of it can meet the ray. A
    secondary ray's own surface is settled so near its origin, where the boxes still hold the
    origin and only a descent to the rounding's scale would part them from the ray."""
    n0 = ray[R_SIDE]
    n1 = ray[R_SIDE + 1]
    n2 = ray[R_SIDE + 2]
    if n0 == 0.0 and n1 == 0.0 and n2 == 0.0:
        return False
    _, hi, slack = hull_across(sl, s, pa, ray, n0, n1, n2)
    return hi < -slack


@njit(cache=True, nogil=True, inline='always')
def hull_hit(sl, s, pa, ray):
    """Does the ray meet the convex hull of slot s's control points (widened by the error
    bounds)? Tested as the hull's extent across two planes that meet in the ray, so a ray
    clipping a corner of a thin, tilted sub-patch's box is not taken for a hit."""
    for base in (R_N1, R_N2):
        if hull_off_plane(sl, s, pa, ray, ray[base], ray[base + 1], ray[base + 2]):
            return False
    return True


@njit(cache=True, nogil=True, inline='always')
def seam_plane(sl, s, pa, direction, ray):
    """Unit normal of the plane through the ray along the seam a split just made (slot s's
    u = 0 edge after a u split, its v = 0 edge after a v split): the two halves lie on either
    side of it up to their curvature, so it separates the ray from the half it does not cross.
    (0, 0, 0) if the seam is parallel to the ray or collapsed."""
    buf = sl.buf
    rational = pa.rational
    end = pa.n * (pa.m + 1) if direction == 0 else pa.m
    x0, y0, z0 = point(buf, s, np.int64(0), rational)
    x1, y1, z1 = point(buf, s, end, rational)
    ex = x1 - x0
    ey = y1 - y0
    ez = z1 - z0
    dx = ray[R_D]
    dy = ray[R_D + 1]
    dz = ray[R_D + 2]
    wx = dy * ez - dz * ey
    wy = dz * ex - dx * ez
    wz = dx * ey - dy * ex
    length = math.sqrt(wx * wx + wy * wy + wz * wz)
    if not length > 0.0:
        return 0.0, 0.0, 0.0
    return wx / length, wy / length, wz / length
