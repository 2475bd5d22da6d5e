"""A sub-patch's control hull against a ray (a slot of records.Slots, as subpatch.py): the hull's
extent across a plane through the ray, widened by the slot's error bounds. Tighter than the box:
the search drops a half whose hull misses one of two planes that meet in the ray (hull_hit), lies
beyond the plane along the seam a split just made (seam_plane), or lies behind a secondary ray's
side plane (hull_behind); a sub-patch that met the criterion is a hit only if its hull straddles
the planes through the ray along its edges (stop_hull_meets)."""
from __future__ import annotations

import math

import numpy as np

from .jit import njit
from .ray import R_D, R_N1, R_N2, R_O, R_SIDE
from .simd import dist_range_cubic
from .subpatch import M_E, M_MAG, M_OX, leaf_magnitude, point, restricted_leaf


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
def _across(buf, mf, s, count, rational, cubic, sub_scale, ray, n0, n1, n2):
    sub = mf[s, M_MAG] * sub_scale
    rel0 = mf[s, M_OX] - ray[R_O]
    rel1 = mf[s, M_OX + 1] - ray[R_O + 1]
    rel2 = mf[s, M_OX + 2] - ray[R_O + 2]
    offset = rel0 * n0 + rel1 * n1 + rel2 * n2
    lo, hi = hull_range(buf, s, count, rational, cubic, n0, n1, n2)
    slack = ((mf[s, M_E] + sub) * abs(n0) + (mf[s, M_E + 1] + sub) * abs(n1) + (mf[s, M_E + 2] + sub) * abs(n2)
             + 2.0 ** -51 * (abs(rel0) + abs(rel1) + abs(rel2) + max(abs(lo), abs(hi))))
    return offset + lo, offset + hi, slack


@njit(cache=True, nogil=True, inline='always')
def hull_across(sl, s, pa, ray, n0, n1, n2):
    """(least, greatest, slack): the signed distances of slot s's control points from the plane
    through the ray's origin with unit normal (n0, n1, n2), and what they may be off by (the
    points' error bounds, the rounding of the distances)."""
    return _across(sl.buf, sl.mf, s, pa.count, pa.rational, pa.cubic, pa.sub_scale, ray, n0, n1, n2)


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
    clipping a corner of a thin, tilted sub-patch's box does not keep it (the halves' test)."""
    for base in (R_N1, R_N2):
        if hull_off_plane(sl, s, pa, ray, ray[base], ray[base + 1], ray[base + 2]):
            return False
    return True


# _beside's verdicts: the hull lies wholly on one side of a plane, straddles every plane, or
# comes within a plane's error band of the ray (the slot's points cannot tell)
BESIDE_OFF, BESIDE_MEETS, BESIDE_BAND = 0, 1, 2


@njit(cache=True, nogil=True, inline='always')
def _edge_normal(dx, dy, dz, ex, ey, ez):
    """Unit normal d x e of the plane through the ray parallel to edge direction e ((0, 0, 0): e
    along the ray, or nil)."""
    n0 = dy * ez - dz * ey
    n1 = dz * ex - dx * ez
    n2 = dx * ey - dy * ex
    length = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not length > 0.0:
        return 0.0, 0.0, 0.0
    return n0 / length, n1 / length, n2 / length


@njit(cache=True, nogil=True, inline='always')
def _edge_directions(buf, s, count, m, n, rational):
    """The control net's mean u edge (P[m][j] - P[0][j], j = 0, n) and mean v edge."""
    x0, y0, z0 = point(buf, s, np.int64(0), rational)  # P[0][0]
    x1, y1, z1 = point(buf, s, m, rational)  # P[m][0]
    x2, y2, z2 = point(buf, s, n * (m + 1), rational)  # P[0][n]
    x3, y3, z3 = point(buf, s, count - 1, rational)  # P[m][n]
    return ((x1 - x0) + (x3 - x2), (y1 - y0) + (y3 - y2), (z1 - z0) + (z3 - z2),
            (x2 - x0) + (x3 - x1), (y2 - y0) + (y3 - y1), (z2 - z0) + (z3 - z1))


@njit(cache=True, nogil=True, inline='always')
def _beside(buf, mf, s, count, m, n, rational, cubic, sub_scale, ray, reach):
    """Slot s's hull against the planes through the ray parallel to its mean u and v edges: (a
    BESIDE_ verdict, the planes' unit normals a and b). BESIDE_BAND only where the ray comes within
    a plane's error band and the band, over the ray's angle to the sub-patch, spans `reach` or
    more along the ray."""
    dx = ray[R_D]
    dy = ray[R_D + 1]
    dz = ray[R_D + 2]
    ux, uy, uz, vx, vy, vz = _edge_directions(buf, s, count, m, n, rational)
    a0, a1, a2 = _edge_normal(dx, dy, dz, ux, uy, uz)
    b0, b1, b2 = _edge_normal(dx, dy, dz, vx, vy, vz)
    # |cos| of the ray's angle to the sub-patch's normal u x v, times |u x v| |d|
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    facing = abs(nx * dx + ny * dy + nz * dz)
    scale = math.sqrt((nx * nx + ny * ny + nz * nz) * (dx * dx + dy * dy + dz * dz))
    verdict = BESIDE_MEETS
    for k in range(2):
        n0, n1, n2 = (a0, a1, a2) if k == 0 else (b0, b1, b2)
        if n0 == 0.0 and n1 == 0.0 and n2 == 0.0:
            continue
        lo, hi, slack = _across(buf, mf, s, count, rational, cubic, sub_scale, ray, n0, n1, n2)
        if lo > slack or hi < -slack:
            return BESIDE_OFF, a0, a1, a2, b0, b1, b2
        # within the band: it matters where the band over the ray's angle spans `reach`
        if not (lo < -slack and hi > slack) and slack * scale >= facing * reach:
            verdict = BESIDE_BAND
    return verdict, a0, a1, a2, b0, b1, b2


@njit(cache=True, nogil=True, _nrt=False)  # rare: a call
def _beside_float64(w64, mf, s, pa, ctrl64, eps64, ray, a0, a1, a2, b0, b1, b2):
    """Is the sub-patch of slot s, re-derived from the float64 leaf over its parameter interval,
    wholly on one side of one of _beside's planes (unit normals a and b)? Arrays, not records
    (subpatch._CALLED)."""
    rel = restricted_leaf(w64, mf, s, pa, ctrl64, 3)
    count = pa.count
    err0 = leaf_magnitude(ctrl64, pa, 0) * rel + eps64[pa.p, 0]
    err1 = leaf_magnitude(ctrl64, pa, 1) * rel + eps64[pa.p, 1]
    err2 = leaf_magnitude(ctrl64, pa, 2) * rel + eps64[pa.p, 2]
    for j in range(2):
        n0, n1, n2 = (a0, a1, a2) if j == 0 else (b0, b1, b2)
        if n0 == 0.0 and n1 == 0.0 and n2 == 0.0:
            continue
        lo = math.inf
        hi = -math.inf
        far = 0.0
        for k in range(count):
            r0 = w64[0, k] - ray[R_O]
            r1 = w64[1, k] - ray[R_O + 1]
            r2 = w64[2, k] - ray[R_O + 2]
            dist = r0 * n0 + r1 * n1 + r2 * n2
            lo = min(lo, dist)
            hi = max(hi, dist)
            far = max(far, abs(r0) + abs(r1) + abs(r2))
        slack = err0 * abs(n0) + err1 * abs(n1) + err2 * abs(n2) + 2.0 ** -50 * far
        if lo > slack or hi < -slack:
            return True
    return False


@njit(cache=True, nogil=True, inline='always')
def stop_hull_meets(sl, s, pa, lv, ray):
    """Does the ray meet the hull of slot s, a sub-patch that met the criterion? Tested across the
    planes through the ray along the sub-patch's edges (_beside): seen along the ray, a small
    sub-patch is nearly the parallelogram of its edges, and the ray passes beside it exactly when
    it lies beyond one of them, beyond the line through it parallel to that edge. (hull_hit's two
    planes are fixed by the ray alone: a sub-patch seen nearly edge-on is a thin slanted sliver
    whose extent across both can hold the ray while it passes beside the sliver, and a ray
    skimming a surface took a sub-patch it passes just above for its hit, ahead of the true
    crossing by up to the sub-patch's width over the angle.) Where the ray comes within a float32
    slot's error band of an edge plane, and the band over the ray's angle to the sub-patch spans a
    grid cell (the reported box's resolution) along the ray, the test is made again on the
    sub-patch re-derived from the float64 leaf, whose band is the restriction's rounding (at 1e-5
    radians the float32 band spans 1e5 band widths along the ray)."""
    p = pa.p
    reach = min(lv.grid[p, 0], lv.grid[p, 1], lv.grid[p, 2])
    verdict, a0, a1, a2, b0, b1, b2 = _beside(sl.buf, sl.mf, s, pa.count, np.int64(pa.m), np.int64(pa.n),
                                              pa.rational, pa.cubic, pa.sub_scale, ray, reach)
    if verdict == BESIDE_BAND and pa.cumulative:
        return not _beside_float64(sl.w64, sl.mf, s, pa, lv.ctrl64, lv.eps64, ray, a0, a1, a2, b0, b1, b2)
    return verdict != BESIDE_OFF


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
    return _edge_normal(ray[R_D], ray[R_D + 1], ray[R_D + 2], x1 - x0, y1 - y0, z1 - z0)
