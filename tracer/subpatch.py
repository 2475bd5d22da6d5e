"""Sub-patch operations: small functions of one slot of the sub-patch stack (records.Slots).

A sub-patch is slot s of a thread's Slots: its control points buf[s] (working dtype, relative
to the offset M_OX.. inside the patch's frame), its widened local box box[s], and per-slot
metadata mf[s] (float64, columns M_*) and mi[s] (int32, columns I_*). The operations here
split, bound, re-centre and re-derive sub-patches and test their boxes against a ray (their
control hulls: hull.py); the drivers (drivers.py) are made of them.

Where the arithmetic happens: every box is widened by the slot's error bound (M_E): the
rounding of the stored control points plus that of every split and re-centring on the way
down, so it contains the true surface and neighbouring patches cannot leave a crack whatever
their frames. A sub-patch whose bound grows past 1/REFINE of its box is re-derived from the
float64 leaf (refine). Ray-box slabs run in float64 on frame-relative = local + offset.
"""
from __future__ import annotations

import math

import numpy as np
from .jit import njit

from .binary import pow2, ulp
from .bezier import (control_box, control_box_rational, restrict, restrict_err, split_u, split_u_cubic,
                     split_u_linear, split_v, split_v_cubic, split_v_linear)
from .ray import R_D, R_REACH, before_best, slab_at
from .records import PatchInfo

# Split heuristics (codes as in options.SPLIT_CODE).
SPLIT_LENGTH, SPLIT_CROSS = 0, 1
# Per-slot float metadata.
M_U0, M_U1, M_V0, M_V1 = 0, 1, 2, 3  # parameter interval
M_TIN, M_TOUT = 4, 5                  # slab interval of the box
M_D = 6                               # L1 diameter of the widened local box
M_DPAR = 7                            # the parent's criterion diameter
M_OX = 8                              # 8, 9, 10: offset, patch frame = local + offset
M_MAG = 11                            # largest |local coordinate| of the box
M_GULP = 12                           # the coarsest grid step (float64: its ulp at the frame magnitude)
M_W = 13                              # L1 size of the widening (error bounds) in M_D
M_E = 14                              # 14, 15, 16: bound on |stored - true surface| per axis
MF_LEN = 17
# Per-slot int metadata: depth, stalled (the box did not shrink), last split (0 u, 1 v, -1 none),
# trace step (-1 none), trim state (0 undecided, 1 wholly in the kept region).
I_DEPTH, I_STALLED, I_LAST, I_STEP, I_TRIM = 0, 1, 2, 3, 4
MI_LEN = 5

RECENTRE = 16.0     # re-centre once the box is this many times smaller than its coordinates
REFINE = 64.0       # re-derive from float64 once the data error is over 1/64 of the box
SUB_ERR_BITS = 8    # float64: a split's rounding stays below 2^-(bits - 8) of the magnitude
# Calls or inlines. numba inlines an inline='always' helper into its own IR once per call site,
# and its type inference, SSA and lowering then cost more than linearly in the kernel's size; a
# plain call is typed and lowered once, and LLVM still inlines it where that pays. So leaf
# operations used at several call sites are calls (_CALLED: point, hull.hull_range, raw_box,
# snap_*, ulp), and so are the rare re-centring and re-deriving (_COLD); operations given a
# variant flag as an argument stay inlined, so that the flag stays a constant their branches are
# pruned by (split, tighten, open_child). The hull and slab tests stay inlined too (LLVM leaves
# them as calls, which cost the search 8 %), and so does widen (a call taking two arrays, LLVM
# left it a call: 13 % of a float frame), but for the hull's loop over the points (hull_range:
# inlined at every hull test it lengthened cold compiles). A call takes the arrays it needs,
# never a record: numba passes a record's every array as some ten words, most of them on the
# stack (Slots with its cache is some 170 words: a fifth of recentre's time went to pushing them).


def max_depth_for(precision_bits: int) -> int:
    """Subdivision depth cap: both directions down to the precision, with room to spare."""
    return 2 * (precision_bits + 16)


@njit(cache=True, nogil=True, inline='always')
def patch_info(lv, p, bits, has_rational, has_cubic, has_linear):
    """The PatchInfo of leaf p, its slots' arithmetic `bits` wide (has_*: the kernel variant's
    patch kinds, compile-time flags)."""
    m = lv.deg_u[p]
    n = lv.deg_v[p]
    rational = has_rational and lv.rational[p] != 0
    cumulative = bits < 53
    return PatchInfo(p, m, n, (m + 1) * (n + 1), lv.pstart[p], rational,
                     has_cubic and m == 3 and n == 3 and not rational,
                     has_linear and m == 1 and n == 1 and not rational,
                     bits, cumulative,
                     0.0 if cumulative else pow2(SUB_ERR_BITS - bits),
                     pow2(-bits) if cumulative else 0.0,
                     1.0 - pow2(4 - bits))  # a real decrease: more than 16 ulps


@njit(cache=True, nogil=True, _nrt=False)  # a call (see _CALLED)
def snap_down(q, g):
    """The largest multiple of the grid step g <= q (exact: g is a power of two); q itself when
    there is no grid (g = 0, float64)."""
    return math.floor(q / g) * g if g > 0.0 else q


@njit(cache=True, nogil=True, _nrt=False)  # a call (see _CALLED)
def snap_up(q, g):
    return math.ceil(q / g) * g if g > 0.0 else q


@njit(cache=True, nogil=True, inline='always')
def _to_working(q, bits):
    """q rounded to the working precision."""
    return q if bits >= 53 else np.float64(np.float32(q))


@njit(cache=True, nogil=True, inline='always')  # (see _CALLED)
def widen(box, mf, s, sub_scale):
    """Widen the raw control box of slot s (box: Slots.box, mf: Slots.mf) by its error bound
    (M_E); sets M_MAG, M_W and M_D.

    sub_scale: 0 where M_E carries the subdivision's rounding (float32, integral patches), else
    2^-(bits - SUB_ERR_BITS), a per-level bound relative to the magnitude."""
    mag = 0.0
    for k in range(6):
        mag = max(mag, abs(box[s, k]))
    mf[s, M_MAG] = mag
    sub = mag * sub_scale
    widening = 0.0
    for c in range(3):
        # sub_scale 0: sub is +0 (mag is finite: limits.py bounds float32 scenes), so the bound
        # need not wait for mag's chain of maxima (measured: 6-10 % of a float frame)
        e = mf[s, M_E + c] if sub_scale == 0.0 else mf[s, M_E + c] + sub
        box[s, c] -= e
        box[s, 3 + c] += e
        widening += 2.0 * e
    mf[s, M_W] = widening
    mf[s, M_D] = (box[s, 3] - box[s, 0]) + (box[s, 4] - box[s, 1]) + (box[s, 5] - box[s, 2])


@njit(cache=True, nogil=True, inline='always')
def grid_l1(sl, s, grid, p):
    """L1 diameter of slot s's box rounded outward onto the leaf's grid (exact): snap_up minus
    snap_down per axis, with one division instead of two (the step g is a power of two, so 1 / g
    is exact and q * (1 / g) is q / g to the bit)."""
    total = 0.0
    for c in range(3):
        o = sl.mf[s, M_OX + c]
        lo = sl.box[s, c] + o
        hi = sl.box[s, 3 + c] + o
        g = grid[p, c]
        if g > 0.0:
            inv = 1.0 / g
            total += math.ceil(hi * inv) * g - math.floor(lo * inv) * g
        else:
            total += hi - lo
    return total


@njit(cache=True, nogil=True, inline='always')
def within_ulps(sl, s, ulps, bits, lv, p):
    """Are the grid box's world corners within `ulps` units in the last place (of `bits`-bit
    floats) of each other, per coordinate?"""
    for c in range(3):
        o = sl.mf[s, M_OX + c]
        lo = snap_down(sl.box[s, c] + o, lv.grid[p, c]) + lv.frame[p, c]
        hi = snap_up(sl.box[s, 3 + c] + o, lv.grid[p, c]) + lv.frame[p, c]
        mag = max(abs(lo), abs(hi))
        if mag > 0.0 and hi - lo > ulps * ulp(mag, bits):
            return False
    return True


@njit(cache=True, nogil=True, _nrt=False)  # a call (see _CALLED)
def raw_box(buf, box, s, count, is_rational):
    """Slot s's control box (buf, box: Slots.buf, Slots.box) before widening."""
    if is_rational:
        control_box_rational(buf, s, count, box)
    else:
        control_box(buf, s, count, box)


@njit(cache=True, nogil=True, _nrt=False)  # rare: a call, not inlined (see _COLD)
def recentre(buf, box, mf, s, pa):
    """Shift slot s's control points so its box is centred near 0 (the shift rounded to the
    working precision: for points close to the shift the subtraction is exact, Sterbenz; the
    others round by at most half an ulp of the result, added to the slot's error bound in float32,
    covered by the per-level bound in float64, where rational slots are searched). Arrays, not
    records (see _CALLED)."""
    count = pa.count
    for c in range(3):
        shift = _to_working(0.5 * (box[s, c] + box[s, 3 + c]), pa.bits)
        offset = mf[s, M_OX + c]
        if offset != 0.0:  # a multiple of the offset's float64 ulp: offset + shift stays exact
            q = ulp(offset, 53)
            shift = math.floor(shift / q + 0.5) * q
        if pa.rational:
            for k in range(count):  # w x - shift w
                buf[s, c, k] = float(buf[s, c, k]) - shift * float(buf[s, 3, k])
        else:
            for k in range(count):
                buf[s, c, k] = float(buf[s, c, k]) - shift
        mf[s, M_OX + c] += shift
    raw_box(buf, box, s, count, pa.rational)
    if not pa.rational:
        for c in range(3):
            mf[s, M_E + c] += pa.round_unit * max(abs(box[s, c]), abs(box[s, 3 + c]))
    widen(box, mf, s, pa.sub_scale)


@njit(cache=True, nogil=True, inline='always')
def restricted_leaf(w64, mf, s, pa, ctrl64, ncoord):
    """The float64 leaf's (ctrl64: Leaves.ctrl64) first ncoord rows restricted to slot s's
    parameter interval (mf: Slots.mf), into w64 (Slots.w64); returns the restriction's relative
    error bound (bezier.restrict_err)."""
    for c in range(ncoord):
        for k in range(pa.count):
            w64[c, k] = ctrl64[c, pa.start + k]
    restrict(w64, pa.m, pa.n, ncoord, mf[s, M_U0], mf[s, M_U1], mf[s, M_V0], mf[s, M_V1])
    return restrict_err(pa.m, pa.n)


@njit(cache=True, nogil=True, inline='always')
def leaf_magnitude(ctrl64, pa, c):
    """The largest |float64 control point| of leaf pa.p along axis c (ctrl64: Leaves.ctrl64):
    times restricted_leaf's relative bound, what a restriction of the leaf may be off by there."""
    big = 0.0
    for k in range(pa.count):
        big = max(big, abs(ctrl64[c, pa.start + k]))
    return big


@njit(cache=True, nogil=True, _nrt=False)  # rare: a call, not inlined (see _COLD)
def refine(buf, box, mf, w64, s, pa, ctrl64, eps64):
    """Re-derive slot s's (integral) control points from the float64 leaf over its parameter
    interval, stored relative to a new offset at the box centre: their error bound drops from the
    leaf's rounding to the sub-patch's own, so the error band no longer outgrows the box.

    Without it, grazing rays meet the band of the float32 leaf data ahead of the true crossing.
    Arrays, not records (see _CALLED)."""
    count = pa.count
    rel = restricted_leaf(w64, mf, s, pa, ctrl64, 3)
    for c in range(3):
        lo = math.inf
        hi = -math.inf
        for k in range(count):
            lo = min(lo, w64[c, k])
            hi = max(hi, w64[c, k])
        big = leaf_magnitude(ctrl64, pa, c)
        offset = _to_working(0.5 * (lo + hi), pa.bits)
        err = 0.0
        for k in range(count):
            local = w64[c, k] - offset  # rounds by at most an ulp of itself (counted below)
            buf[s, c, k] = local
            err = max(err, abs(np.float64(buf[s, c, k]) - local) + abs(local) * 2.0 ** -52)
        mf[s, M_OX + c] = offset
        mf[s, M_E + c] = err + big * rel + eps64[pa.p, c]
    raw_box(buf, box, s, count, pa.rational)  # False: integral
    widen(box, mf, s, 0.0)  # the bound carries every rounding (float32, integral)


@njit(cache=True, nogil=True, _nrt=False)  # a call (see _CALLED)
def point(buf, s, k, rational):
    """Control point k of slot s in float64, homogenised for rational patches. (k an int64
    variable, never a literal: numba would compile a copy per literal value.)"""
    if rational:  # numba: float(float32) stays float32, hence np.float64
        w = np.float64(buf[s, 3, k])
        return np.float64(buf[s, 0, k]) / w, np.float64(buf[s, 1, k]) / w, np.float64(buf[s, 2, k]) / w
    return np.float64(buf[s, 0, k]), np.float64(buf[s, 1, k]), np.float64(buf[s, 2, k])


@njit(cache=True, nogil=True, inline='always')
def split_direction(sl, s, pa, ray, split_mode):
    """0 to halve u, 1 to halve v: the longer parameter direction ('length'), or the one
    whose edges are least parallel to the ray ('cross', Dammertz 2.5.2).

    Both opposite edges are measured, so a collapsed edge (teapot lid) cannot hide
    its direction."""
    buf = sl.buf
    m = pa.m
    n = pa.n
    rational = pa.rational
    last = pa.count - 1  # P[m][n]
    lu = 0.0
    lv = 0.0
    for e in range(2):
        # u edges: P[0][j] -> P[m][j] for j = 0, n; v edges: P[i][0] -> P[i][n] for i = 0, m.
        ua = 0 if e == 0 else n * (m + 1)
        ub = m if e == 0 else last
        va = 0 if e == 0 else m
        vb = n * (m + 1) if e == 0 else last
        xa, ya, za = point(buf, s, ua, rational)
        xb, yb, zb = point(buf, s, ub, rational)
        ex, ey, ez = xb - xa, yb - ya, zb - za
        xa, ya, za = point(buf, s, va, rational)
        xb, yb, zb = point(buf, s, vb, rational)
        gx, gy, gz = xb - xa, yb - ya, zb - za
        if split_mode == SPLIT_CROSS:
            dx = ray[R_D]
            dy = ray[R_D + 1]
            dz = ray[R_D + 2]
            ex, ey, ez = ey * dz - ez * dy, ez * dx - ex * dz, ex * dy - ey * dx
            gx, gy, gz = gy * dz - gz * dy, gz * dx - gx * dz, gx * dy - gy * dx
        lu = max(lu, ex * ex + ey * ey + ez * ez)
        lv = max(lv, gx * gx + gy * gy + gz * gz)
    return 0 if lu > lv else 1


@njit(cache=True, nogil=True, inline='always')
def split(sl, a, b, pa, direction, has_general):
    """Halve slot a in u (direction 0) or v (1) into a and b: bounds, control points, raw boxes
    and parameter intervals (has_general: the variant has patches that are neither bicubic nor
    bilinear, or rational ones).

    Each of the split's de Casteljau levels rounds a point by at most half an ulp of the
    largest coordinate, and the errors of earlier levels stay in the points."""
    buf = sl.buf
    box = sl.box
    count = pa.count
    split_bounds(sl, a, b, pa, direction)
    if pa.cubic:
        if direction == 0:
            split_u_cubic(buf, a, b, box)
        else:
            split_v_cubic(buf, a, b, box)
    elif pa.linear:
        if direction == 0:
            split_u_linear(buf, a, b, box)
        else:
            split_v_linear(buf, a, b, box)
    elif has_general:
        ncoord = 4 if pa.rational else 3
        if direction == 0:
            split_u(buf, a, b, pa.m, pa.n, ncoord)
        else:
            split_v(buf, a, b, pa.m, pa.n, ncoord)
        raw_box(buf, box, a, count, pa.rational)
        raw_box(buf, box, b, count, pa.rational)
    split_intervals(sl, a, b, direction)


@njit(cache=True, nogil=True, inline='always')
def split_bounds(sl, a, b, pa, direction):
    """split's first step, before the points are halved: both halves' error bounds, the parent's
    (slot a's, its box still the parent's) plus a rounding per de Casteljau level."""
    box = sl.box
    mf = sl.mf
    levels = (pa.m if direction == 0 else pa.n) * pa.round_unit  # 0 in float64 (see sub_scale)
    for c in range(3):
        mf[b, M_E + c] = mf[a, M_E + c] + levels * max(abs(box[a, c]), abs(box[a, 3 + c]))
        mf[a, M_E + c] = mf[b, M_E + c]


@njit(cache=True, nogil=True, inline='always')
def split_intervals(sl, a, b, direction):
    """split's last step: the halves' parameter intervals, slot b's offset and grid step."""
    mf = sl.mf
    for c in range(4):
        mf[b, M_U0 + c] = mf[a, M_U0 + c]
    if direction == 0:
        mid = 0.5 * (mf[a, M_U0] + mf[a, M_U1])
        mf[a, M_U1] = mid
        mf[b, M_U0] = mid
    else:
        mid = 0.5 * (mf[a, M_V0] + mf[a, M_V1])
        mf[a, M_V1] = mid
        mf[b, M_V0] = mid
    for c in range(3):
        mf[b, M_OX + c] = mf[a, M_OX + c]
    mf[b, M_GULP] = mf[a, M_GULP]


@njit(cache=True, nogil=True, inline='always')
def open_box(sl, s, ray, t_start, t_stop, hit, p):
    """Slab-test slot s's widened box within [t_start, t_stop], its parent's interval (the ray's
    t_min and inf at a root) (its interval into M_TIN, M_TOUT); is it still a candidate against the
    best hit, and does it reach ray[R_REACH]? (alive, met).

    A box's interval lies within its parent's: a true crossing in a half lies in its parent's box
    too. So entry ts never decrease down the tree, and a box's key bounds every key below it
    (ray.search_limit); exits never increase, and a box that ends before a cell's entry holds
    nothing below it that reaches the cell."""
    mf = sl.mf
    box = sl.box
    ox = mf[s, M_OX]
    oy = mf[s, M_OX + 1]
    oz = mf[s, M_OX + 2]
    ok, t_in, t_out = slab_at(box[s, 0] + ox, box[s, 1] + oy, box[s, 2] + oz, box[s, 3] + ox, box[s, 4] + oy,
                              box[s, 5] + oz, ray, t_start, t_stop)
    mf[s, M_TIN] = t_in
    mf[s, M_TOUT] = t_out
    return ok & (t_out >= ray[R_REACH]) & before_best(t_in, mf[s, M_U0], mf[s, M_V0], hit, p), ok
