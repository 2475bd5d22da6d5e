"""The steps a bundle's search is made of (bundle.py puts them together), as search_steps.py's
are a single ray's: a bundle's masks (a bit a ray in a uint64), the slab tests of sub-patch
boxes eight rays at a time (lanes.py) within their parents' intervals, the single ray's hull
tests ray by ray where a ray meets both halves, the halves pushed for their rays, the prune by
each ray's closest hit and the adaptive criterion as masks."""
from __future__ import annotations

import numba
import numpy as np

from .hull import hull_behind, hull_hit, hull_off_plane, seam_plane
from .jit import njit
from .lanes import (L_FAR, L_PO, L_TMIN, WIDTH, ahead_lanes, at_start_lanes, count_lanes, nearest_lanes, slab_lanes,
                    slab_pair_lanes, within_detail_lanes)
from .ray import H_PATCH, H_TIN
from .search_steps import GRID_PREFILTER
from .subpatch import I_DEPTH, I_STALLED, M_D, M_DPAR, M_GULP, M_OX, M_U0, M_U1, M_V0, M_V1, M_W, grid_l1

ONE = np.uint64(1)
ZERO = np.uint64(0)
GROUP = np.uint64((1 << WIDTH) - 1)
# the walk's counters, rows of walk_counts
W_BOX_TESTS, W_SURFACES, W_NODES, W_PATCHES = range(4)
W_LEN = 4


if numba.config.DISABLE_JIT:
    def _trailing_zeros(m):
        return (int(m) & -int(m)).bit_length() - 1
else:
    from numba.cpython.unsafe.numbers import trailing_zeros as _trailing_zeros


@njit(cache=True, nogil=True, inline='always')
def lowest_bit(m):
    """Index (int64: numba would unify a uint64 with int64 indices to a float) of the lowest set
    bit of a nonzero mask."""
    return np.int64(_trailing_zeros(m))


@njit(cache=True, nogil=True, inline='always')
def bit(r):
    return ONE << np.uint64(r)


@njit(cache=True, nogil=True, inline='always')
def take_group(rest):
    """The lowest lanes group holding a ray of mask `rest`: (its index g, its shift WIDTH * g, its
    rays as the group's low bits, rest less them). Loops over a mask's groups visit only these."""
    g = lowest_bit(rest) // WIDTH
    shift = np.uint64(WIDTH * g)
    return g, shift, (rest >> shift) & GROUP, rest & ~(GROUP << shift)


@njit(cache=True, nogil=True, inline='always')
def add_count(counts, m, column, n):
    """counts[r, column] += n for every ray r of mask m."""
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        counts[r, column] += n


@njit(cache=True, nogil=True, inline='always')
def _corners(sl, s):
    """Slot s's box shifted into the patch's frame (lo xyz, hi xyz), as ray.slab shifts it: once
    for all the rays that test it."""
    box = sl.box
    mf = sl.mf
    return (box[s, 0] + mf[s, M_OX], box[s, 1] + mf[s, M_OX + 1], box[s, 2] + mf[s, M_OX + 2],
            box[s, 3] + mf[s, M_OX], box[s, 4] + mf[s, M_OX + 1], box[s, 5] + mf[s, M_OX + 2])


@njit(cache=True, nogil=True, inline='always')
def _off_side(sl, s, pa, br, row, g, alive, met, sided):
    """(alive, met) of group g in slot s less the rays wholly behind the side plane of a ray whose
    origin the box holds, as search_steps.open_child drops it for the single ray. sided: the rays
    may have side planes (secondary rays); primary rays have none, and then the boxes holding a
    ray's origin are not looked for."""
    if not sided:
        return alive, met
    start = at_start_lanes(br.tin, row, br.lanes, g, met)
    shift = np.uint64(WIDTH * g)
    while start != ZERO:  # boxes that hold a ray's origin: the single ray's side-plane test
        k = lowest_bit(start)
        start &= start - ONE
        r = np.int64(shift) + k
        if hull_behind(sl, s, pa, br.lrays[r]):
            met &= ~bit(k)
            alive &= ~bit(k)
    return alive, met


@njit(cache=True, nogil=True, inline='always')
def _slot_rays(sl, s, pa, br, row, g, bits, start, start_row, stop, stop_row, sided):
    """The rays of group g in bits (the group's low bits) against slot s's box, eight at a time,
    each within [start[start_row], stop[stop_row]] (the rays' t_min and inf at a root:
    subpatch.open_box): their intervals into tin[row], tout[row]. Returns (the rays that meet it
    before their own closest hit's limit, those that meet it at all), less those behind a side
    plane (_off_side)."""
    lo0, lo1, lo2, hi0, hi1, hi2 = _corners(sl, s)
    both = slab_lanes(br.lanes, L_PO, g, lo0, lo1, lo2, hi0, hi1, hi2, br.tin, br.tout, row, start, start_row, stop,
                      stop_row)
    return _off_side(sl, s, pa, br, row, g, both & bits, (both >> np.uint64(WIDTH)) & bits, sided)


@njit(cache=True, nogil=True, inline='always')
def open_root(sl, s, pa, br, row, m, sided):
    """Slab-test root slot s's box against the rays of m from their t_min (intervals into
    tin[row], tout[row]); the rays that meet it before their own closest hit (and are not behind
    it: _slot_rays)."""
    alive = ZERO
    rest = m
    while rest != ZERO:
        g, shift, bits, rest = take_group(rest)
        kept, _ = _slot_rays(sl, s, pa, br, row, g, bits, br.lanes, L_TMIN, br.lanes, L_FAR, sided)
        alive |= kept << shift
    return alive


@njit(cache=True, nogil=True, inline='always')
def open_pair(sl, a, b, pa, br, row_a, row_b, m, sided):
    """The halves a and b against the rays of m, group by group, within their parent's intervals,
    which row_a holds until their own overwrite it (lanes.slab_pair_lanes loads first): (the rays
    of each half, the rays that meet both boxes). (The bundle's bounds, frustum.py, rarely reject a
    half: counted on the teapot, 12 % of the halves tested by four rays or more, saving less than
    they cost.) sided: as _off_side."""
    alive_a = ZERO
    alive_b = ZERO
    met_both = ZERO
    rest = m
    while rest != ZERO:
        g, shift, bits, rest = take_group(rest)
        # (the corners loaded in the loop: kept live across it they cost float 8x8 2-6 %)
        a0, a1, a2, a3, a4, a5 = _corners(sl, a)
        b0, b1, b2, b3, b4, b5 = _corners(sl, b)
        both = slab_pair_lanes(br.lanes, L_PO, g, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, br.tin, br.tout,
                               row_a, row_b, br.tin, row_a, br.tout, row_a)
        kept_a, met_a = _off_side(sl, a, pa, br, row_a, g, both & bits, (both >> np.uint64(WIDTH)) & bits, sided)
        kept_b, met_b = _off_side(sl, b, pa, br, row_b, g, (both >> np.uint64(2 * WIDTH)) & bits,
                                  (both >> np.uint64(3 * WIDTH)) & bits, sided)
        alive_a |= kept_a << shift
        alive_b |= kept_b << shift
        met_both |= (met_a & met_b) << shift
    return alive_a, alive_b, met_both


@njit(cache=True, nogil=True, inline='always')
def nearest_in(tin, br, row, m):
    """nearest for an interval row of tin (the sub-patch stack's or the walk's), from the lanes."""
    t = np.inf
    rest = m
    while rest != ZERO:
        g, _, bits, rest = take_group(rest)
        t = min(t, nearest_lanes(tin, row, g, bits))
    return t


@njit(cache=True, nogil=True, inline='always')
def ahead_in(tin, br, row, m, count_nodes):
    """The rays of m whose entry t into the box of `row` (tin[row, r]) lies before their own
    closest hit: the others drop out of it (from the lanes). count_nodes: each live ray counts a
    node (the walk's)."""
    live = ZERO
    rest = m
    while rest != ZERO:
        g, shift, bits, rest = take_group(rest)
        kept = ahead_lanes(tin, row, br.lanes, g, bits)
        if count_nodes:
            count_lanes(br.walk_counts, W_NODES, g, kept, 1)
        live |= kept << shift
    return live


@njit(cache=True, nogil=True, inline='always')
def lane_limit(hit, p):
    """A ray's limit in the lanes (L_HIT), which prune by t alone, in a search of leaf p: its
    search limit, or the next float past it where its best hit lies in p itself (there a box
    entered at the best t may hold a lower corner: the lanes let it through, ray.before_best
    decides at the report)."""
    t = hit[H_TIN]
    if hit[H_PATCH] == p and t < np.inf:
        return np.nextafter(t, np.inf)
    return t


@njit(cache=True, nogil=True, inline='always')
def push_halves(sl, a, b, sp, pa, br, go, direction, sided):
    """The halves a and b (b past the seam) at stack positions sp and sp + 1 for the rays of `go`:
    each ray's intervals, the single ray's hull tests where it meets both boxes (search_steps.near_and_far),
    the bundle's nearer half on top. Returns the new stack height and the halves no ray keeps (-1 for none)."""
    row_a = br.row[sp]
    row_b = br.row[sp + 1]
    keep_a, keep_b, met_both = open_pair(sl, a, b, pa, br, row_a, row_b, go, sided)
    both = met_both & (keep_a | keep_b)
    while both != ZERO:  # as sort_halves: the far half across the seam plane and the ray's planes first
        r = lowest_bit(both)
        both &= both - ONE
        lr = br.lrays[r]
        a_near = br.tin[row_a, r] <= br.tin[row_b, r]
        far = b if a_near else a
        near = a if a_near else b
        w0, w1, w2 = seam_plane(sl, b, pa, direction, lr)
        if hull_off_plane(sl, far, pa, lr, w0, w1, w2) or not hull_hit(sl, far, pa, lr):
            if far == a:
                keep_a &= ~bit(r)
            else:
                keep_b &= ~bit(r)
        elif hull_off_plane(sl, near, pa, lr, w0, w1, w2) or not hull_hit(sl, near, pa, lr):
            if near == a:
                keep_a &= ~bit(r)
            else:
                keep_b &= ~bit(r)
    if keep_a != ZERO and keep_b != ZERO:
        if nearest_in(br.tin, br, row_a, keep_a) <= nearest_in(br.tin, br, row_b, keep_b):  # a nearer: a on top
            br.row[sp], br.row[sp + 1] = row_b, row_a
            a, b, keep_a, keep_b = b, a, keep_b, keep_a
        br.slot[sp], br.slot[sp + 1] = a, b
        br.mask[sp], br.mask[sp + 1] = keep_a, keep_b
        return sp + 2, -1, -1
    if keep_a == ZERO and keep_b == ZERO:
        return sp, a, b
    if keep_b != ZERO:  # only b: to position sp
        br.row[sp], br.row[sp + 1] = row_b, row_a
        br.slot[sp] = b
        br.mask[sp] = keep_b
        return sp + 1, a, -1
    br.slot[sp] = a
    br.mask[sp] = keep_a
    return sp + 1, b, -1


@njit(cache=True, nogil=True, inline='always')
def _all_if(flag):
    return ~ZERO if flag else ZERO


@njit(cache=True, nogil=True, inline='always')
def _within_detail(br, row, m, size):
    """The rays of m whose threshold of detail at their entry t into the box of `row` is at least
    `size` (lanes.within_detail_lanes)."""
    within = ZERO
    rest = m
    while rest != ZERO:
        g, shift, bits, rest = take_group(rest)
        within |= within_detail_lanes(br.tin, row, br.lanes, g, bits, size) << shift
    return within


@njit(cache=True, nogil=True, inline='always')
def judge_detail(sl, a, pa, lv, q, br, row, live):
    """search_steps.judge_known under the adaptive criterion for each ray of `live` in slot a
    (its entry t in tin[row]), as masks: (the rays that stop, those that go on, the first ray that
    goes on (0 for none), the box's criterion diameter and whether the box shrank by it: the same
    for every ray). A ray needs the grid box's diameter g where d is within its limit (the
    prefilter's, or its threshold); it stops by g then, else by d."""
    mf = sl.mf
    d = mf[a, M_D]
    on_grid = d <= GRID_PREFILTER * mf[a, M_GULP]
    # (a select and a pass over the lanes, not a branch on the prefilter: measured 5-8 % faster)
    need = (_all_if(on_grid) | _within_detail(br, row, live, d)) & live
    g = -1.0
    crit = ZERO
    if need != ZERO:
        g = grid_l1(sl, a, lv.grid, pa.p)
        crit = _within_detail(br, row, need, g)  # d > the threshold where g is not needed
    d_box = g if on_grid else d  # (on_grid: every ray needed g)
    shrank = d_box < mf[a, M_DPAR] * pa.shrink_factor and d > 1.0625 * mf[a, M_W]
    stop = crit
    if sl.mi[a, I_DEPTH] >= q.max_depth or mf[a, M_U0] == mf[a, M_U1] or mf[a, M_V0] == mf[a, M_V1]:
        stop = live  # the depth cap, or an interval that can no longer halve
    if sl.mi[a, I_STALLED] == 1 and not shrank:  # stalled: a box that did not shrink again stops
        stop |= need | _all_if(not pa.rational)  # (a rational one only within its limit)
    stop &= live
    go = live & ~stop
    first_ray = lowest_bit(go) if go != ZERO else 0
    return stop, go, first_ray, d_box, shrank

