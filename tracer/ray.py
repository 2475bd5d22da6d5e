"""Ray and hit records (flat float64 arrays) and the ray-box slab test."""
from __future__ import annotations

import math

import numpy as np

from .jit import njit

# Ray record: origin, direction, 1/direction, t_min, threshold of detail T(t) = T0 + dT*t,
# the unit normals of two orthogonal planes that meet in the ray (for hull tests), and the boxes
# its searches may still compute (inf: no budget; the float64 reference's bound), and the normal
# of a plane through the origin that the ray never goes behind (set_side; zero: none), and the t
# every box a search keeps must reach (a kd-tree or grid cell's entry: cell_walk; -inf: none).
R_O, R_D, R_INV, R_TMIN, R_T0, R_DT, R_N1, R_N2, R_BUDGET, R_SIDE, R_REACH = 0, 3, 6, 9, 10, 11, 12, 15, 18, 19, 22
RAY_LEN = 23
# Hit record: entry/exit t of the hit box, world box, (u, v), patch, depth, interval sizes, the
# interval's lower corner (u0, v0: the tie key within a leaf, before_best).
H_TIN, H_TOUT, H_LO, H_HI, H_U, H_V, H_PATCH, H_DEPTH, H_DU, H_DV, H_U0, H_V0 = 0, 1, 2, 5, 8, 9, 10, 11, 12, 13, 14, 15
HIT_LEN = 16

T_SLACK = 4.0 * 2.0 ** -52  # widen slab exits by a few float64 ulps: grazing rays keep their boxes
# slab's offset for a box in the ray's own coordinates: x + -0.0 is x for every x, so the
# additions fold away (x + 0.0 turns -0.0 into 0.0, which LLVM must keep; only the sign of a
# zero t could differ, and a walk only compares those)
NO_SHIFT = -0.0


@njit(cache=True, nogil=True, inline='always')
def set_limit(hit, t_max):
    """An empty hit record searched up to t_max: a limit, not a hit, so no box ties with it
    (search_limit)."""
    hit[H_TIN] = t_max
    hit[H_PATCH] = -1.0


@njit(cache=True, nogil=True, inline='always')
def search_limit(hit, p):
    """The tie rule: of hit boxes entered at the same t, the one of the lower leaf wins, whatever
    order the leaves are searched in. So a search of leaf p runs up to the next float past the
    best t where the best hit lies in a leaf above p (a box entered at the best t is a candidate),
    else up to the best t; the walks let a box entered at the best t through. Within a leaf, the
    box of the lower parameter corner wins (before_best).

    Entry ts never decrease down a search tree (a half's interval starts at its parent's entry:
    subpatch.open_box), so a box's key bounds those of every box below it, and a prune by the
    best hit's key removes only boxes that cannot win, whichever hit was found first."""
    best = hit[H_TIN]
    if hit[H_PATCH] > p and best < math.inf:
        return np.nextafter(best, math.inf)
    return best


@njit(cache=True, nogil=True, inline='always')
def before_best(t, u0, v0, hit, p):
    """Can a box of leaf p entered at t, its parameter interval's lower corner (u0, v0), hold a
    hit box whose key (entry t, leaf, corner u0, then v0) is below the best hit's? hit[H_TIN] is
    the search's limit (search_limit); at an equal t within the best hit's own leaf, the lower
    corner decides (the boxes below a box have corners at or above its own)."""
    limit = hit[H_TIN]
    if t != limit:
        return t < limit
    return hit[H_PATCH] == p and corner_before(u0, v0, hit[H_U0], hit[H_V0])


FIXED_ONE = 2.0 ** 60  # corners in [0, 1] as 60-bit fixed point (Z order)


@njit(cache=True, nogil=True, inline='always')
def corner_before(u0, v0, u1, v1):
    """Does the parameter corner (u0, v0) come before (u1, v1) in the Z order of their bits (u's
    bit before v's of the same weight), then, where the first 60 bits agree, by u and then v? A
    box's corner comes at or before every corner below it (the order is monotone in u and in v);
    and the search visits a half before the other where both are entered at the same t, the lower
    one first, which the Z order follows where a sub-patch is halved in u and v in turn: so a tie
    within a leaf is mostly settled by the first box found, not by a search of every box tied with
    it."""
    au = np.int64(u0 * FIXED_ONE)
    av = np.int64(v0 * FIXED_ONE)
    bu = np.int64(u1 * FIXED_ONE)
    bv = np.int64(v1 * FIXED_ONE)
    xu = au ^ bu
    xv = av ^ bv
    if xu == 0 and xv == 0:
        return u0 < u1 or (u0 == u1 and v0 < v1)
    if xu < xv and xu < (xu ^ xv):  # v's highest differing bit is above u's
        return av < bv
    return au < bu


@njit(cache=True, nogil=True, inline='always')
def _unit(x, y, z):
    """(x, y, z) scaled to length 1 (left as is when zero)."""
    length = math.sqrt(x * x + y * y + z * z)
    if length > 0.0:
        return x / length, y / length, z / length
    return x, y, z


@njit(cache=True, nogil=True, _nrt=False)
def make_ray(ray, ox, oy, oz, dx, dy, dz, t_min, t0, dt):
    """Fill a ray record; zero direction components get an infinite inverse (see `slab`)."""
    ray[0] = ox
    ray[1] = oy
    ray[2] = oz
    ray[3] = dx
    ray[4] = dy
    ray[5] = dz
    for c in range(3):
        d = ray[R_D + c]
        ray[R_INV + c] = 1.0 / d if d != 0.0 else math.inf
    ray[R_TMIN] = t_min
    ray[R_T0] = t0
    ray[R_DT] = dt
    ray[R_BUDGET] = math.inf
    ray[R_REACH] = -math.inf
    for c in range(3):
        ray[R_SIDE + c] = 0.0
    # n1 = d x (axis of d's smallest component), n2 = d x n1, both normalised.
    ax = 0
    if abs(dy) < abs(dx) and abs(dy) <= abs(dz):
        ax = 1
    elif abs(dz) < abs(dx) and abs(dz) < abs(dy):
        ax = 2
    ex = 1.0 if ax == 0 else 0.0
    ey = 1.0 if ax == 1 else 0.0
    ez = 1.0 if ax == 2 else 0.0
    ax_, ay_, az_ = _unit(dy * ez - dz * ey, dz * ex - dx * ez, dx * ey - dy * ex)
    bx_, by_, bz_ = _unit(dy * az_ - dz * ay_, dz * ax_ - dx * az_, dx * ay_ - dy * ax_)
    ray[R_N1] = ax_
    ray[R_N1 + 1] = ay_
    ray[R_N1 + 2] = az_
    ray[R_N2] = bx_
    ray[R_N2 + 1] = by_
    ray[R_N2 + 2] = bz_


@njit(cache=True, nogil=True, inline='always')
def slab(bx, fx, fy, fz, ray):
    """Ray against the box bx (lo xyz, hi xyz) shifted by (fx, fy, fz); float64 throughout.

    Returns (hit, t_in, t_out) with t_in clamped to the ray's t_min. A zero
    direction component is tested by containment instead of by division, so
    no inf * 0 = NaN can appear.
    """
    return slab_at(bx[0] + fx, bx[1] + fy, bx[2] + fz, bx[3] + fx, bx[4] + fy, bx[5] + fz, ray, ray[R_TMIN], math.inf)


@njit(cache=True, nogil=True, inline='always')
def slab_at(lo0, lo1, lo2, hi0, hi1, hi2, ray, t_start, t_stop):
    """slab for the box already shifted (lo xyz, hi xyz), its interval clipped to [t_start, t_stop]
    (t_start >= the ray's t_min): where several rays meet one box, the shifted corners are computed
    once (the same sums)."""
    t_in = t_start
    t_out = t_stop
    for c in range(3):
        lo = (lo0 if c == 0 else (lo1 if c == 1 else lo2)) - ray[R_O + c]
        hi = (hi0 if c == 0 else (hi1 if c == 1 else hi2)) - ray[R_O + c]
        if ray[R_D + c] == 0.0:
            if lo > 0.0 or hi < 0.0:
                return False, t_in, t_out
            continue
        inv = ray[R_INV + c]
        a = lo * inv
        b = hi * inv
        if a > b:
            a, b = b, a
        b += abs(b) * T_SLACK
        if a > t_in:
            t_in = a
        if b < t_out:
            t_out = b
    return t_in <= t_out, t_in, t_out


@njit(cache=True, nogil=True, inline='always')
def set_side(ray, nx, ny, nz):
    """Record the plane through the ray's origin with normal (nx, ny, nz), the side a secondary ray
    leaves its surface on, where the ray goes in front of it (n . d > 0, the products exact to
    within a few ulps: a margin of 2^-40 of |n| |d| leaves no doubt): sub-patches whose hulls lie
    wholly behind it cannot meet the ray (hull.hull_behind)."""
    dot = nx * ray[R_D] + ny * ray[R_D + 1] + nz * ray[R_D + 2]
    size = (abs(nx) + abs(ny) + abs(nz)) * (abs(ray[R_D]) + abs(ray[R_D + 1]) + abs(ray[R_D + 2]))
    keep = dot > 2.0 ** -40 * size and ray[R_TMIN] >= 0.0
    ray[R_SIDE] = nx if keep else 0.0
    ray[R_SIDE + 1] = ny if keep else 0.0
    ray[R_SIDE + 2] = nz if keep else 0.0
