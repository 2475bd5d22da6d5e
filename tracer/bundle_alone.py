"""A bundle's rays left alone, eight at a time (bundle._rays_alone, for integral bicubics and
bilinears).

Each ray left alone in a sub-patch goes on with the single ray's steps (bundle._solo_search) on
its own stack: below the levels the bundle shares, where a float ray makes most of its halvings,
a ray's search is independent of the others'. Here eight of them run side by side, one in each
lane: a lane's current sub-patch is a column of the lane slots (AloneLanes), the halving of all
eight is one pass of vector code (lanes_split), and the other steps are the single ray's own
functions, run lane by lane on the lane slots seen as slots (lane_slots: column j is slot j; 0..7
the lanes' current sub-patches, 8..15 their high halves); tightening and a pushed half work on a
copy in a working slot. Each lane makes its ray's steps in _solo_search's order, on its own stack
(the far half on it, the near one on at once), so every box, hit and counter is the same.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .bundle_steps import ONE, ZERO, bit, lane_limit, lowest_bit
from .hull import hull_behind
from .jit import njit
from .lanes import L_HIT
from .lanes_split import (COLUMNS, LANE_RAY, LANES, LR_DT, LR_LIMIT, LR_REACH, LR_T0, LR_TMIN, S_DCRIT, S_SHRANK,
                          STEP_LEN, halve_lanes, halve_lanes_linear, judge_lanes, keep_high_lanes)
from .ray import H_TIN, R_D, R_DT, R_INV, R_O, R_REACH, R_T0, R_TMIN, before_best
from .records import C_EFFORT, Slots
from .search_steps import (MANTISSA, ahead, hull_accepts, judge_known, near_and_far, order_halves, report,
                           tighten, tightening)
from .subpatch import MF_LEN, MI_LEN, M_TIN, M_TOUT, M_U0, M_V0, patch_info

# The lane slots: points (3, 16, COLUMNS) in the slots' dtype, box (6, COLUMNS), mf (MF_LEN,
# COLUMNS), mi (MI_LEN, COLUMNS) int32 (lanes_split: column j < LANES lane j's current sub-patch,
# LANES + j its high half after a halving), and the same seen as slots (points_s (COLUMNS, 3, 16),
# box_s (COLUMNS, 6), ...: slot j is column j), made in numpy (numba's transpose with axes needs its
# runtime). dirs (LANES,) int32: each lane's halving direction. ray (LANES,) uint64: the bundle ray
# in each lane (NO_RAY: none), lray (LANE_RAY, LANES) what the vector code reads of it
# (lanes_split.LR_*); current (LANES,) int64: where the lane holds a sub-patch to go on with (1,
# or KEPT), 0 where it pops. stack (LANES, S) uint32: each lane's stack of working slots (far
# halves it pushed), top (LANES,) its height. step (STEP_LEN, LANES): a halving's inputs.
NO_RAY = np.uint64(2 ** 64 - 1)  # a lane without a ray
KEPT = 2  # current: the half the last halving kept (1: a sub-patch popped or a ray's start)
AloneLanes = namedtuple("AloneLanes", "points box mf mi points_s box_s mf_s mi_s dirs ray lray current stack top "
                                      "step")


def alone_lanes(slots: int, dtype) -> AloneLanes:
    """Lane slots for eight rays alone in `dtype` slots, each stack up to `slots` deep."""
    points, box = np.zeros((3, 16, COLUMNS), dtype), np.zeros((6, COLUMNS))
    mf, mi = np.zeros((MF_LEN, COLUMNS)), np.zeros((MI_LEN, COLUMNS), np.int32)
    return AloneLanes(points, box, mf, mi, points.transpose(2, 0, 1), box.T, mf.T, mi.T, np.zeros(LANES, np.int32),
                      np.full(LANES, NO_RAY), np.zeros((LANE_RAY, LANES)), np.zeros(LANES, np.int64),
                      np.zeros((LANES, slots), np.uint32), np.zeros(LANES, np.int64), np.zeros((STEP_LEN, LANES)))


@njit(cache=True, nogil=True, inline='always')
def lane_slots(al, sl):
    """The lane slots as a records.Slots whose slot j is column j; the rest of sl as it is."""
    return Slots(al.points_s, al.box_s, al.mf_s, al.mi_s, sl.order, sl.lray, sl.w64, sl.trim_h, sl.trim_m,
                 sl.buf64, sl.cache)


@njit(cache=True, nogil=True, inline='always')
def _copy_sub_patch(buf, box, mf, mi, s, to_buf, to_box, to_mf, to_mi, d, count):
    """Slot s of one set of slot arrays into slot d of another (count: its control points)."""
    for c in range(3):
        for k in range(count):
            to_buf[d, c, k] = buf[s, c, k]
    for k in range(6):
        to_box[d, k] = box[s, k]
    for k in range(MF_LEN):
        to_mf[d, k] = mf[s, k]
    for k in range(MI_LEN):
        to_mi[d, k] = mi[s, k]


@njit(cache=True, nogil=True, inline='always')
def to_slot(al, column, sl, s, count):
    """Column `column` of the lane slots into working slot s (count: its control points)."""
    _copy_sub_patch(al.points_s, al.box_s, al.mf_s, al.mi_s, column, sl.buf, sl.box, sl.mf, sl.mi, s, count)


@njit(cache=True, nogil=True, inline='always')
def from_slot(al, column, sl, s, count):
    """Working slot s into column `column` of the lane slots (count: its control points)."""
    _copy_sub_patch(sl.buf, sl.box, sl.mf, sl.mi, s, al.points_s, al.box_s, al.mf_s, al.mi_s, column, count)


@njit(cache=True, nogil=True, inline='always')
def _take_ray(al, lane, lr, hit):
    for k in range(3):
        al.lray[R_O + k, lane] = lr[R_O + k]
        al.lray[R_D + k, lane] = lr[R_D + k]
        al.lray[R_INV + k, lane] = lr[R_INV + k]
    al.lray[LR_T0, lane] = lr[R_T0]
    al.lray[LR_DT, lane] = lr[R_DT]
    al.lray[LR_LIMIT, lane] = hit[H_TIN]
    al.lray[LR_REACH, lane] = lr[R_REACH]
    al.lray[LR_TMIN, lane] = lr[R_TMIN]


@njit(cache=True, nogil=True, inline='always')
def _verdict(al, ls, column, pa, ray, hit, met):
    """search_steps.open_slot's verdict on a column halve_lanes slab-tested (met: 1 where the ray
    meets its box): (alive, met), 1 or 0."""
    ok = met != 0
    t_in = al.mf[M_TIN, column]
    alive = ok and al.mf[M_TOUT, column] >= ray[R_REACH] and before_best(t_in, al.mf[M_U0, column],
                                                                          al.mf[M_V0, column], hit, pa.p)
    if ok and t_in <= ray[R_TMIN] and hull_behind(ls, column, pa, ray):  # a box holding the origin (rare)
        alive = ok = False
    return 1 if alive else 0, 1 if ok else 0


def _rays_alone_lanes(p, lv, trims, q, sl, br, waiting, base, nfree):
    """bundle._rays_alone for a bicubic's rays eight at a time (see the module's doc); other
    patches' rays one after another (rays_alone)."""
    pa = patch_info(lv, p, q.bits, False, HAS_CUBIC, HAS_LINEAR)  # noqa: F821
    if HAS_GENERAL and not (pa.cubic or pa.linear):  # noqa: F821 (without it, rays_alone is None)
        return rays_alone(p, lv, trims, q, sl, br, waiting, base, nfree)  # noqa: F821
    al = br.alone
    ls = lane_slots(al, sl)
    free = br.free
    queue = waiting
    for lane in range(LANES):
        al.ray[lane] = NO_RAY
        al.current[lane] = 0
        al.top[lane] = 0
    mantissa = q.criterion == MANTISSA
    grid = lv.grid
    while True:
        have = ZERO
        for k in range(LANES):  # every lane to its next sub-patch still ahead, or out of rays
            lane = np.uint64(k)  # (unsigned indices: no negative-index fix-ups)
            while True:
                r = al.ray[lane]
                if r == NO_RAY:
                    if queue == ZERO:
                        break
                    r = np.uint64(lowest_bit(queue))
                    queue &= queue - ONE
                    al.ray[lane] = r
                    _take_ray(al, lane, br.lrays[r], br.hits[r])
                    start = br.waiting[r]
                    from_slot(al, lane, sl, start, pa.count)
                    free[nfree] = start
                    nfree += 1
                    al.current[lane] = 1
                elif al.current[lane] == 0:
                    if al.top[lane] == 0:  # the ray's search is over
                        br.lanes[L_HIT, r] = lane_limit(br.hits[r], pa.p)
                        al.ray[lane] = NO_RAY
                        continue
                    al.top[lane] -= 1
                    s = al.stack[lane, al.top[lane]]
                    from_slot(al, lane, sl, s, pa.count)
                    free[nfree] = s
                    nfree += 1
                    al.current[lane] = 1
                # (a half kept at the last halving passed the same test then, against the same hit)
                if al.current[lane] == KEPT or ahead(ls, lane, pa, br.hits[r]):
                    have |= bit(lane)
                    break
                al.current[lane] = 0
        if have == ZERO:
            return nfree
        if mantissa:  # (the criterion's test reads the ray: one lane at a time)
            stop = ZERO
            tight = (ONE << np.uint64(LANES)) - ONE  # (every lane asks search_steps.tightening)
            m = have
            while m != ZERO:
                lane = np.uint64(lowest_bit(m))
                m &= m - ONE
                stopped, d_crit, shrank, _ = judge_known(ls, lane, pa, lv, br.lrays[al.ray[lane]], q, -1.0)
                al.step[S_DCRIT, lane] = d_crit
                al.step[S_SHRANK, lane] = 1.0 if shrank else 0.0
                if stopped:
                    stop |= bit(lane)
        else:
            verdicts = judge_lanes(al.box, al.mf, al.mi, al.lray, al.step, grid[p, 0], grid[p, 1], grid[p, 2],
                                   q.criterion, q.param, q.max_depth, pa.shrink_factor, pa.rational, pa.cumulative)
            stop = verdicts & np.uint64(0xFF)
            tight = verdicts >> np.uint64(LANES)
        ready = ZERO
        m = have
        while m != ZERO:
            lane = np.uint64(lowest_bit(m))
            m &= m - ONE
            r = al.ray[lane]
            if (stop >> np.uint64(lane)) & ONE:
                lr = br.lrays[r]
                if hull_accepts(ls, lane, pa, lv, lr, q):
                    report(br.hits[r], ls, lane, pa, lv)
                    al.lray[LR_LIMIT, lane] = br.hits[r, H_TIN]
                al.current[lane] = 0
                continue
            br.counts[r, C_EFFORT] += 2
            if (tight >> lane) & ONE and tightening(ls, lane, pa) != 0:  # (rare) on a copy in a working slot
                spare = free[nfree - 1]
                to_slot(al, lane, sl, spare, pa.count)
                tighten(sl, spare, pa, lv)
                from_slot(al, lane, sl, spare, pa.count)
            ready |= bit(lane)
        if ready == ZERO:
            continue
        if pa.cubic:
            verdicts = halve_lanes(al.points, al.dirs, al.box, al.mf, al.mi, al.lray, al.step,
                                   pa.m * pa.round_unit, pa.sub_scale, q.split_mode)
        else:
            verdicts = halve_lanes_linear(al.points, al.dirs, al.box, al.mf, al.mi, al.lray, al.step,
                                          pa.m * pa.round_unit, pa.sub_scale, q.split_mode)
        met_bits = verdicts & np.uint64(0xFFFF)
        low_alive = (verdicts >> np.uint64(2 * LANES)) & np.uint64(0xFF)
        high_alive = (verdicts >> np.uint64(3 * LANES)) & np.uint64(0xFF)
        special = (verdicts >> np.uint64(4 * LANES)) & ready
        plain = ready & ~special  # at most one half alive: it goes on, or the lane pops
        take = plain & high_alive & ~low_alive
        m = plain
        while m != ZERO:
            lane = np.uint64(lowest_bit(m))
            m &= m - ONE
            al.current[lane] = KEPT if ((low_alive | high_alive) >> lane) & ONE else 0
        m = special
        while m != ZERO:  # the single ray's verdicts, lane by lane
            lane = np.uint64(lowest_bit(m))
            m &= m - ONE
            r = al.ray[lane]
            hit = br.hits[r]
            lr = br.lrays[r]
            a = lane
            b = np.uint64(LANES) + lane
            direction = al.dirs[lane]
            alive_a, met_a = _verdict(al, ls, a, pa, lr, hit, (met_bits >> np.uint64(a)) & ONE)
            alive_b, met_b = _verdict(al, ls, b, pa, lr, hit, (met_bits >> np.uint64(b)) & ONE)
            if (met_a & met_b) != 0 and (alive_a | alive_b) != 0:  # the hull tests
                far, near, alive_far, alive_near, _ = near_and_far(ls, a, b, pa, lr, direction, alive_a, alive_b, 1)
                if alive_far and alive_near:  # the far half waits on the lane's stack, in a working slot
                    nfree -= 1
                    to_slot(al, far, sl, free[nfree], pa.count)
                    al.stack[lane, al.top[lane]] = free[nfree]
                    al.top[lane] += 1
            else:
                far, near, alive_far, alive_near = order_halves(ls, a, b, alive_a, alive_b)
            if (near == b) if alive_near else (alive_far and far == b):  # the kept half is the high one
                take |= bit(lane)
            al.current[lane] = KEPT if (alive_near or alive_far) else 0
        if take != ZERO:
            keep_high_lanes(al.points, al.box, al.mf, al.mi, take)
