"""A ray bundle's interval bounds: one test that a box is missed by every ray of the bundle.

ray.slab computes, per axis, lo = (box_lo + f) - origin and a = lo * inv (likewise hi, b), swaps
so that a <= b, widens b, and meets the box where max(t_min, a's) <= min(b's). Each of those
roundings is monotone in each operand, so over a bundle whose origins lie in [olo, ohi] and
inverse directions in [ilo, ihi] per axis, every ray's a and b lie between the least and the
greatest of the same expressions at the corners of those intervals, computed the same way. If
the greatest entry bound exceeds the least exit bound, every ray's own slab test misses: the
bundle drops the box without testing its rays one by one, and no ray's verdict changes (a box
some ray meets is always tested ray by ray). Bundles with a zero direction component (slab tests
those axes by containment) are not bounded (F_OK 0).

The record is a float64 array: origins' bounds (F_OLO, F_OHI), inverse directions' (F_ILO,
F_IHI), the least t_min (F_TMIN) and F_OK. The BVH walk of a bundle uses it: counted on the
teapot at 512x512 (8x8 bundles, adaptive), 92,000 bound tests of nodes seen by four rays or more
drop 35,000 nodes and 1.76 million slab tests of single rays. Sub-patch halves lie mostly
inside the bundle (12 % dropped of those tested): there the slabs go ray by ray.
"""
from __future__ import annotations

import math

import numpy as np

from .jit import njit
from .ray import T_SLACK, R_D, R_INV, R_O, R_TMIN

F_OLO, F_OHI, F_ILO, F_IHI, F_TMIN, F_OK = 0, 3, 6, 9, 12, 13
F_LEN = 14
# below this many rays a bundle tests a node ray by ray (the bound costs about four rays' slabs)
MIN_RAYS = 4


@njit(cache=True, nogil=True, inline='always')
def at_least(m, n):
    """Does the uint64 mask m have at least n set bits?"""
    for _ in range(n - 1):
        m &= m - np.uint64(1)
    return m != np.uint64(0)


@njit(cache=True, nogil=True, _nrt=False)  # a call: once a bundle
def bound_rays(fr, rays, m):
    """fr (F_LEN,): the bounds of the rays (K, RAY_LEN) of mask m (uint64, nonzero)."""
    for c in range(3):
        fr[F_OLO + c] = math.inf
        fr[F_OHI + c] = -math.inf
        fr[F_ILO + c] = math.inf
        fr[F_IHI + c] = -math.inf
    fr[F_TMIN] = math.inf
    ok = 1.0
    r = 0
    while m != np.uint64(0):
        if m & np.uint64(1):
            for c in range(3):
                if rays[r, R_D + c] == 0.0:
                    ok = 0.0
                fr[F_OLO + c] = min(fr[F_OLO + c], rays[r, R_O + c])
                fr[F_OHI + c] = max(fr[F_OHI + c], rays[r, R_O + c])
                fr[F_ILO + c] = min(fr[F_ILO + c], rays[r, R_INV + c])
                fr[F_IHI + c] = max(fr[F_IHI + c], rays[r, R_INV + c])
            fr[F_TMIN] = min(fr[F_TMIN], rays[r, R_TMIN])
        m >>= np.uint64(1)
        r += 1
    fr[F_OK] = ok


@njit(cache=True, nogil=True, inline='always')
def _extent(base, fr, c):
    """The least and greatest (base - origin) * inv over the corners of the bounds, axis c."""
    lo = math.inf
    hi = -math.inf
    for o in (fr[F_OLO + c], fr[F_OHI + c]):
        d = base - o
        for inv in (fr[F_ILO + c], fr[F_IHI + c]):
            t = d * inv
            lo = min(lo, t)
            hi = max(hi, t)
    return lo, hi


@njit(cache=True, nogil=True, inline='always')
def misses_all(corners, fr):
    """Does every ray bounded by fr miss the box with corners (lo xyz, hi xyz, already
    shifted as ray.slab shifts them), as ray.slab_at would find ray by ray? False when it cannot
    tell."""
    if fr[F_OK] == 0.0:
        return False
    t_in = fr[F_TMIN]
    t_out = math.inf
    lo0, lo1, lo2, hi0, hi1, hi2 = corners
    for c in range(3):
        a_lo, a_hi = _extent(lo0 if c == 0 else (lo1 if c == 1 else lo2), fr, c)
        b_lo, b_hi = _extent(hi0 if c == 0 else (hi1 if c == 1 else hi2), fr, c)
        near = min(a_lo, b_lo)
        far = max(a_hi, b_hi)
        far += abs(far) * T_SLACK
        if near > t_in:
            t_in = near
        if far < t_out:
            t_out = far
    # a margin far above any rounding of the bounds, none of which should be needed
    return t_in > t_out + abs(t_out) * 2.0 ** -40
