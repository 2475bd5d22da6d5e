"""Ray-patch intersection by recursive de Casteljau subdivision (Dammertz 2005, ch. 2).

The search keeps an explicit stack of sub-patches. A popped sub-patch whose
box is hit either meets the termination criterion (hit: its box is the hit
interval) or is halved in u or v; each half's box is tested at once, and the
nearer half is visited first, so a hit shortens the ray and prunes the rest.

Where the arithmetic happens: control points are stored in the working dtype
relative to their patch's frame, and a sub-patch is re-centred on its own box
once the box is much smaller than its coordinates, so midpoints round relative
to the box, not to the object or the world origin. Every box is widened by its
sub-patch's error bound (M_E): the rounding of the stored control points (exact,
measured at load) plus that of every split and re-centring on the way down, so it
contains the true surface and neighbouring patches cannot leave a crack whatever
their frames. A sub-patch whose bound grows past 1/REFINE of its box is re-derived
from the float64 leaf (_refine), which resets the bound to its own rounding. The search
runs in the patch's frame (the ray origin is moved there once, in float64);
ray-box slabs run in float64 on frame-relative = local + offset.

The float criterion is Dammertz's "the box stopped shrinking", applied to the box rounded
outward onto the leaf's grid (geometry.grid_steps: the float32 spacing at the leaf's largest
world coordinate, or finer where the scene is far from the world origin), its L1 diameter
exact: the search ends where float32 numbers can no longer tell the boxes apart, and that
grid box, moved to world coordinates, is the reported hit box. The other criteria are tested
on the same grid box, so what they promise holds for what is reported. In float64 there is no
grid: the reference resolves as far as its boxes shrink.

Kernels that allocate nothing are compiled with numba's `_nrt=False`: they only borrow the
arrays they are given, and without it numba keeps atomic reference counts of them across the
inlined helpers, inside the loop (a fifth of the search time).

Scratch (one set per thread), S = max depth + 2 slots:
  buf   (S, 4, P) working dtype   control points per slot (row 3: weights of rational patches)
  box   (S, 6)    float64         widened local box per slot: lo xyz, hi xyz
  mf    (S, 21)   float64         per slot, columns M_*
  mi    (S, 5)    int32           per slot: depth, stalled, last split (0 u, 1 v), trace step,
                                  trim state (0 undecided, 1 wholly in the kept region)
  order (S,)      uint32          stack position -> slot (children swap order without copying;
                                  unsigned, so numba adds no negative-index fix-ups)
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .bezier import (control_box, control_box_rational, restrict, restrict_err, split_u, split_u_cubic,
                     split_u_linear, split_v, split_v_cubic, split_v_linear)
from .trim_kernel import rect_meets_loops, trim_inside
from .ray import (H_DEPTH, H_DU, H_DV, H_HI, H_LO, H_PATCH, H_TIN, H_TOUT, H_U, H_V, R_D, R_DT, R_N1,
                  R_N2, R_O, R_T0, slab)

# Termination criteria and split heuristics (codes as in options.CRITERION_CODE / SPLIT_CODE).
FLOAT, FIXED, ADAPTIVE, MANTISSA = 0, 1, 2, 3
SPLIT_LENGTH, SPLIT_CROSS = 0, 1
# Trace events.
MISS, PRUNED, SPLIT, HIT = 0, 1, 2, 3
EVENT_NAMES = ("miss", "pruned", "split", "hit")
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
M_EH = 17                             # 17, 18, 19: rational, float32: bound on |stored - float64
M_EW = 20                             # leaf| of the homogeneous w x, w y, w z, and of w (M_EW)
MF_LEN = 21
# Trace record columns (float64): u0 u1 v0 v1 lo xyz hi xyz diameter; (int32): patch depth event.
TRACE_F, TRACE_I = 11, 3

RECENTRE = 16.0     # re-centre once the box is this many times smaller than its coordinates
REFINE = 64.0       # re-derive from float64 once the data error is over 1/64 of the box
SUB_ERR_BITS = 8    # rational patches: a split's rounding stays below 2^-(bits - 8) of the magnitude
GRID_PREFILTER = 64.0  # boxes wider than this many grid ulps certainly still shrink on the grid


def max_depth_for(precision_bits: int) -> int:
    """Subdivision depth cap: both directions down to the precision, with room to spare."""
    return 2 * (precision_bits + 16)


@njit(cache=True, nogil=True, inline='always')
def _ulp(x, bits):
    """Spacing of `bits`-bit floats at |x| (x != 0)."""
    return math.ldexp(1.0, math.frexp(x)[1] - bits)


@njit(cache=True, nogil=True, inline='always')
def _snap_down(q, g):
    """The largest multiple of the grid step g <= q (exact: g is a power of two); q itself when
    there is no grid (g = 0, float64)."""
    return math.floor(q / g) * g if g > 0.0 else q


@njit(cache=True, nogil=True, inline='always')
def _snap_up(q, g):
    return math.ceil(q / g) * g if g > 0.0 else q


@njit(cache=True, nogil=True, inline='always')
def _to_working(q, bits):
    """q rounded to the working precision."""
    return q if bits >= 53 else np.float64(np.float32(q))


@njit(cache=True, nogil=True, inline='always')
def _widen(box, mf, s, sub_scale):
    """Widen the raw control box of slot s by its error bound (M_E); sets M_MAG, M_W and M_D.

    sub_scale: 0 where M_E carries the subdivision's rounding (float32, integral patches), else
    2^-(bits - SUB_ERR_BITS), a per-level bound relative to the magnitude."""
    mag = 0.0
    for k in range(6):
        mag = max(mag, abs(box[s, k]))
    mf[s, M_MAG] = mag
    sub = mag * sub_scale
    widening = 0.0
    for c in range(3):
        e = mf[s, M_E + c] + sub
        box[s, c] -= e
        box[s, 3 + c] += e
        widening += 2.0 * e
    mf[s, M_W] = widening
    mf[s, M_D] = (box[s, 3] - box[s, 0]) + (box[s, 4] - box[s, 1]) + (box[s, 5] - box[s, 2])


@njit(cache=True, nogil=True, inline='always')
def _rational_bound(buf, box, mf, s, count, eps64, p):
    """M_E of a rational slot from its homogeneous bounds (M_EH, M_EW), before widening: the
    stored surface N~/W~ differs from the float64 leaf's N/W by (dN - S~ dW) / W per axis, with
    |dN| <= M_EH, |dW| <= M_EW, |S~| <= the raw box and W >= the least stored weight - M_EW;
    plus the leaf's own bound (eps64). Infinite if the weights' bound reaches the weights."""
    w_min = math.inf
    for k in range(count):
        w_min = min(w_min, np.float64(buf[s, 3, k]))
    denom = w_min - mf[s, M_EW]
    for c in range(3):
        x = max(abs(box[s, c]), abs(box[s, 3 + c]))
        e = (mf[s, M_EH + c] + x * mf[s, M_EW]) / denom * (1.0 + 2.0 ** -40) if denom > 0.0 else math.inf
        mf[s, M_E + c] = eps64[p, c] + e


@njit(cache=True, nogil=True, inline='always')
def _grid_l1(box, mf, s, grid, p):
    """L1 diameter of slot s's box rounded outward onto the leaf's grid (exact)."""
    total = 0.0
    for c in range(3):
        o = mf[s, M_OX + c]
        total += _snap_up(box[s, 3 + c] + o, grid[p, c]) - _snap_down(box[s, c] + o, grid[p, c])
    return total


@njit(cache=True, nogil=True, inline='always')
def _within_ulps(box, mf, s, ulps, bits, grid, frame, p):
    """Are the grid box's world corners within `ulps` units in the last place (of `bits`-bit
    floats) of each other, per coordinate?"""
    for c in range(3):
        o = mf[s, M_OX + c]
        lo = _snap_down(box[s, c] + o, grid[p, c]) + frame[p, c]
        hi = _snap_up(box[s, 3 + c] + o, grid[p, c]) + frame[p, c]
        mag = max(abs(lo), abs(hi))
        if mag > 0.0 and hi - lo > ulps * _ulp(mag, bits):
            return False
    return True


@njit(cache=True, nogil=True, inline='always')
def _raw_box(buf, box, s, count, is_rational):
    if is_rational:
        control_box_rational(buf, s, count, box)
    else:
        control_box(buf, s, count, box)


@njit(cache=True, nogil=True, inline='always')
def _recentre(buf, box, mf, s, count, is_rational, homogeneous, bits, sub_scale, round_unit, eps64, p):
    """Shift slot s's control points so its box is centred near 0 (the shift rounded to the
    working precision: for points close to the shift the subtraction is exact, Sterbenz; the
    others round by at most half an ulp of the result, added to the slot's error bound)."""
    for c in range(3):
        shift = _to_working(0.5 * (box[s, c] + box[s, 3 + c]), bits)
        offset = mf[s, M_OX + c]
        if offset != 0.0:  # a multiple of the offset's float64 ulp: offset + shift stays exact
            q = math.ldexp(1.0, math.frexp(offset)[1] - 53)
            shift = math.floor(shift / q + 0.5) * q
        if is_rational:
            big = 0.0
            w_max = 0.0
            for k in range(count):  # w x - shift w, with one rounding
                buf[s, c, k] = float(buf[s, c, k]) - shift * float(buf[s, 3, k])
                big = max(big, abs(np.float64(buf[s, c, k])))
                w_max = max(w_max, np.float64(buf[s, 3, k]))
            # The weights' error moves by the shift; the product and difference round once each.
            mf[s, M_EH + c] += abs(shift) * mf[s, M_EW] + (round_unit + 2.0 ** -52) * (big + abs(shift) * w_max)
        else:
            for k in range(count):
                buf[s, c, k] = float(buf[s, c, k]) - shift
        mf[s, M_OX + c] += shift
    _raw_box(buf, box, s, count, is_rational)
    if homogeneous:
        _rational_bound(buf, box, mf, s, count, eps64, p)
    elif not is_rational:
        for c in range(3):
            mf[s, M_E + c] += round_unit * max(abs(box[s, c]), abs(box[s, 3 + c]))
    _widen(box, mf, s, sub_scale)


@njit(cache=True, nogil=True, inline='always')
def _refine(buf, box, mf, s, m, n, count, ctrl64, start, eps64, p, w64, bits):
    """Re-derive slot s's (integral) control points from the float64 leaf over its parameter
    interval, stored relative to a new offset at the box centre: their error bound drops from the
    leaf's rounding to the sub-patch's own, so the error band no longer outgrows the box.

    Without it, grazing rays meet the band of the float32 leaf data ahead of the true crossing."""
    for c in range(3):
        for k in range(count):
            w64[c, k] = ctrl64[c, start + k]
    restrict(w64, m, n, 3, mf[s, M_U0], mf[s, M_U1], mf[s, M_V0], mf[s, M_V1])
    rel = restrict_err(m, n)
    for c in range(3):
        lo = math.inf
        hi = -math.inf
        big = 0.0
        for k in range(count):
            lo = min(lo, w64[c, k])
            hi = max(hi, w64[c, k])
            big = max(big, abs(ctrl64[c, start + k]))
        offset = _to_working(0.5 * (lo + hi), bits)
        err = 0.0
        for k in range(count):
            local = w64[c, k] - offset  # rounds by at most an ulp of itself (counted below)
            buf[s, c, k] = local
            err = max(err, abs(np.float64(buf[s, c, k]) - local) + abs(local) * 2.0 ** -52)
        mf[s, M_OX + c] = offset
        mf[s, M_E + c] = err + big * rel + eps64[p, c]
    _raw_box(buf, box, s, count, False)
    _widen(box, mf, s, 0.0)  # the bound carries every rounding (float32, integral: see search_patch)


@njit(cache=True, nogil=True, inline='always')
def _refine_rational(buf, box, mf, s, m, n, count, ctrl64, start, eps64, p, w64, bits):
    """_refine for rational slots: the homogeneous float64 leaf restricted to the slot's interval,
    moved to a new offset at the centre of its (Euclidean) box, stored with fresh bounds."""
    for c in range(4):
        for k in range(count):
            w64[c, k] = ctrl64[c, start + k]
    restrict(w64, m, n, 4, mf[s, M_U0], mf[s, M_U1], mf[s, M_V0], mf[s, M_V1])
    rel = restrict_err(m, n)
    big_w = 0.0
    w_err = 0.0
    for k in range(count):
        big_w = max(big_w, abs(ctrl64[3, start + k]))
        buf[s, 3, k] = w64[3, k]
        w_err = max(w_err, abs(np.float64(buf[s, 3, k]) - w64[3, k]))
    w_bound = w_err + big_w * rel  # |stored weight - the float64 leaf's|
    mf[s, M_EW] = w_bound
    for c in range(3):
        lo = math.inf
        hi = -math.inf
        big = 0.0
        for k in range(count):
            q = w64[c, k] / w64[3, k]
            lo = min(lo, q)
            hi = max(hi, q)
            big = max(big, abs(ctrl64[c, start + k]))
        offset = _to_working(0.5 * (lo + hi), bits)
        err = 0.0
        for k in range(count):
            local = w64[c, k] - offset * w64[3, k]  # two roundings of at most an ulp (below)
            buf[s, c, k] = local
            err = max(err, abs(np.float64(buf[s, c, k]) - local)
                      + (abs(local) + abs(offset * w64[3, k])) * 2.0 ** -52)
        mf[s, M_OX + c] = offset
        mf[s, M_EH + c] = err + big * rel + abs(offset) * w_bound
    _raw_box(buf, box, s, count, True)
    _rational_bound(buf, box, mf, s, count, eps64, p)
    _widen(box, mf, s, 0.0)


@njit(cache=True, nogil=True, inline='always')
def _hull_off_plane(buf, s, count, is_rational, mf, ray, sub_scale, n0, n1, n2):
    """Is the convex hull of slot s's control points (widened by the error bounds) wholly on one
    side of the plane through the ray with unit normal (n0, n1, n2), normal to the ray?"""
    sub = mf[s, M_MAG] * sub_scale
    rel0 = mf[s, M_OX] - ray[R_O]
    rel1 = mf[s, M_OX + 1] - ray[R_O + 1]
    rel2 = mf[s, M_OX + 2] - ray[R_O + 2]
    offset = rel0 * n0 + rel1 * n1 + rel2 * n2
    lo = math.inf
    hi = -math.inf
    for k in range(count):
        dist = (_corner(buf, s, k, 0, is_rational) * n0 + _corner(buf, s, k, 1, is_rational) * n1
                + _corner(buf, s, k, 2, is_rational) * n2)
        lo = min(lo, dist)
        hi = max(hi, dist)
    slack = ((mf[s, M_E] + sub) * abs(n0) + (mf[s, M_E + 1] + sub) * abs(n1) + (mf[s, M_E + 2] + sub) * abs(n2)
             + 2.0 ** -51 * (abs(rel0) + abs(rel1) + abs(rel2) + max(abs(lo), abs(hi))))
    return offset + lo > slack or offset + hi < -slack


@njit(cache=True, nogil=True, inline='always')
def _hull_hit(buf, s, count, is_rational, mf, ray, sub_scale):
    """Does the ray meet the convex hull of slot s's control points (widened by the error
    bounds)? Tested as the hull's extent across two planes that meet in the ray, so a ray
    clipping a corner of a thin, tilted sub-patch's box is not taken for a hit."""
    for base in (R_N1, R_N2):
        if _hull_off_plane(buf, s, count, is_rational, mf, ray, sub_scale, ray[base], ray[base + 1], ray[base + 2]):
            return False
    return True


@njit(cache=True, nogil=True, inline='always')
def _seam_plane(buf, s, m, n, direction, rational, ray):
    """Unit normal of the plane through the ray along the seam a split just made (slot s's
    u = 0 edge after a u split, its v = 0 edge after a v split): the two halves lie on either
    side of it up to their curvature, so it separates the ray from the half it does not cross.
    (0, 0, 0) if the seam is parallel to the ray or collapsed."""
    end = n * (m + 1) if direction == 0 else m
    ex = _corner(buf, s, end, 0, rational) - _corner(buf, s, 0, 0, rational)
    ey = _corner(buf, s, end, 1, rational) - _corner(buf, s, 0, 1, rational)
    ez = _corner(buf, s, end, 2, rational) - _corner(buf, s, 0, 2, rational)
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


@njit(cache=True, nogil=True, inline='always')
def _corner(buf, s, k, c, rational):
    """Coordinate c of control point k in slot s, homogenised for rational patches."""
    if rational:
        return np.float64(buf[s, c, k]) / np.float64(buf[s, 3, k])  # numba: float(float32) stays float32
    return np.float64(buf[s, c, k])


@njit(cache=True, nogil=True, inline='always')
def _split_direction(buf, s, m, n, count, ray, split_mode, rational):
    """0 to halve u, 1 to halve v: the longer parameter direction ('length'), or the one
    whose edges are least parallel to the ray ('cross', Dammertz 2.5.2).

    Both opposite edges are measured, so a collapsed edge (teapot lid) cannot hide
    its direction."""
    last = count - 1  # P[m][n]
    lu = 0.0
    lv = 0.0
    for e in range(2):
        # u edges: P[0][j] -> P[m][j] for j = 0, n; v edges: P[i][0] -> P[i][n] for i = 0, m.
        ua = 0 if e == 0 else n * (m + 1)
        ub = m if e == 0 else last
        va = 0 if e == 0 else m
        vb = n * (m + 1) if e == 0 else last
        ex = _corner(buf, s, ub, 0, rational) - _corner(buf, s, ua, 0, rational)
        ey = _corner(buf, s, ub, 1, rational) - _corner(buf, s, ua, 1, rational)
        ez = _corner(buf, s, ub, 2, rational) - _corner(buf, s, ua, 2, rational)
        gx = _corner(buf, s, vb, 0, rational) - _corner(buf, s, va, 0, rational)
        gy = _corner(buf, s, vb, 1, rational) - _corner(buf, s, va, 1, rational)
        gz = _corner(buf, s, vb, 2, rational) - _corner(buf, s, va, 2, rational)
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
def _record(trace, p, depth, mf, box, s, event, frame):
    """Append slot s's box (in world coordinates) to the trace; returns its step index
    (-1 when the trace is full)."""
    tf, ti, tn = trace
    k = tn[0]
    if k >= tf.shape[0]:
        tn[1] = 1  # truncated
        return -1
    tn[0] = k + 1
    for c in range(4):
        tf[k, c] = mf[s, M_U0 + c]
    for c in range(3):
        tf[k, 4 + c] = box[s, c] + mf[s, M_OX + c] + frame[p, c]
        tf[k, 7 + c] = box[s, 3 + c] + mf[s, M_OX + c] + frame[p, c]
    tf[k, 10] = mf[s, M_D]
    ti[k, 0] = p
    ti[k, 1] = depth
    ti[k, 2] = event
    return k


@njit(cache=True, nogil=True, inline='always')
def _set_event(trace, step, event):
    if step >= 0:
        trace[1][step, 2] = event


@njit(cache=True, nogil=True, inline='always')
def _open_child(box, mf, mi, s, ray, best_t, p, frame, trace):
    """Test slot s's (widened) box against the ray; returns 1 if it stays a candidate."""
    ok, t_in, t_out = slab(box[s], mf[s, M_OX], mf[s, M_OX + 1], mf[s, M_OX + 2], ray)
    mf[s, M_TIN] = t_in
    mf[s, M_TOUT] = t_out
    alive = ok & (t_in < best_t)
    if trace is not None:
        event = SPLIT if alive else (PRUNED if ok else MISS)  # SPLIT stands until it is popped
        mi[s, 3] = _record(trace, p, mi[s, 0], mf, box, s, event, frame)
    return 1 if alive else 0


@njit(cache=True, nogil=True, inline='always')
def _report(hit, box, mf, a, p, depth, grid, frame):
    """Record slot a as the closest hit so far: its grid box, in world coordinates."""
    hit[H_TIN] = mf[a, M_TIN]
    hit[H_TOUT] = mf[a, M_TOUT]
    for c in range(3):
        o = mf[a, M_OX + c]
        hit[H_LO + c] = _snap_down(box[a, c] + o, grid[p, c]) + frame[p, c]
        hit[H_HI + c] = _snap_up(box[a, 3 + c] + o, grid[p, c]) + frame[p, c]
    hit[H_U] = 0.5 * (mf[a, M_U0] + mf[a, M_U1])
    hit[H_V] = 0.5 * (mf[a, M_V0] + mf[a, M_V1])
    hit[H_DU] = mf[a, M_U1] - mf[a, M_U0]
    hit[H_DV] = mf[a, M_V1] - mf[a, M_V0]
    hit[H_PATCH] = p
    hit[H_DEPTH] = depth


@njit(cache=True, nogil=True, _nrt=False)
def search_patch(p, ctrl, pstart, deg_u, deg_v, rational, frame, grid, eps, ctrl64, eps64, ray, hit,
                 criterion, param, split_mode, max_depth, bits,
                 buf, box, mf, mi, order, lray, w64, trims, trim_h, trim_m, trace):
    """Closest intersection of `ray` with patch p beyond t_min and before hit[H_TIN].

    Updates `hit` when a closer hit box is found; returns the number of boxes computed.
    ctrl: (4, total points) working dtype, local to frame[p] (float64 (n_patches, 3)); row 3
    holds the weights, rows 0-2 are premultiplied by them for rational[p] patches.
    eps: (n_patches, 3) float64 bound of the stored points' rounding error per axis.
    grid: (n_patches, 3) float64 step of the grid hit boxes are rounded onto (geometry.grid_steps;
    0: none).
    ctrl64, eps64: the same points in float64 and their error bound; in working precisions below
    float64, sub-patches whose error band grows over 1/REFINE of their box are re-derived from them
    (w64: (4, points) float64 scratch).
    criterion/param: FLOAT (-), FIXED (L1 size), ADAPTIVE (uses the ray's T0, dT),
    MANTISSA (ulps); every criterion also stops when the box stops shrinking.
    bits: mantissa bits of the working dtype (24 or 53). lray: scratch ray record (the ray in
    the patch's frame). trims: (patch_trim, patch_domain, seg_points, seg_start, surf_seg_start,
    start_inside) with scratch trim_h, trim_m (see trim_kernel): a hit box whose parameter
    centre lies outside the kept region is no hit. trace: None or (tf, ti, tn).
    """
    m = deg_u[p]
    n = deg_v[p]
    count = (m + 1) * (n + 1)
    is_rational = rational[p] != 0
    ncoord = 4 if is_rational else 3
    cubic = m == 3 and n == 3 and not is_rational
    linear = m == 1 and n == 1 and not is_rational
    start = pstart[p]
    for k in range(lray.shape[0]):
        lray[k] = ray[k]
    for c in range(3):
        lray[R_O + c] = ray[R_O + c] - frame[p, c]
    ray = lray
    s = order[0]
    for c in range(ncoord):
        for k in range(count):
            buf[s, c, k] = ctrl[c, start + k]
    mf[s, M_U0] = 0.0
    mf[s, M_U1] = 1.0
    mf[s, M_V0] = 0.0
    mf[s, M_V1] = 1.0
    mf[s, M_DPAR] = math.inf
    for c in range(3):
        mf[s, M_OX + c] = 0.0
        mf[s, M_E + c] = eps[p, c]
    mi[s, 0] = 0
    mi[s, 1] = 0
    mi[s, 2] = -1
    mi[s, 4] = 0
    surface = trims[0][p]
    dom = trims[1]
    # Below float64, patches carry their subdivision rounding in the slot's error bound (M_E),
    # level by level (round_unit: a rounding moves a value by at most this much of it); rational
    # ones carry it for their homogeneous coordinates (M_EH, M_EW: _rational_bound turns them into
    # M_E). Float64, the reference, is widened by sub_scale of the current magnitude instead: its
    # early roundings (~1e-16 of the leaf) are far below anything it is compared with, and
    # carrying them would stop it 100x sooner.
    cumulative = bits < 53
    homogeneous = cumulative and is_rational  # rational, float32: homogeneous bounds (M_EH, M_EW)
    sub_scale = 0.0 if cumulative else math.ldexp(1.0, SUB_ERR_BITS - bits)
    round_unit = math.ldexp(1.0, -bits) if cumulative else 0.0
    shrink_factor = 1.0 - math.ldexp(1.0, 4 - bits)  # a real decrease: more than 16 ulps
    _raw_box(buf, box, s, count, is_rational)
    if homogeneous:  # bounds against the float64 leaf
        for c in range(4):
            err = 0.0
            for k in range(count):
                err = max(err, abs(np.float64(buf[s, c, k]) - ctrl64[c, start + k]))
            if c < 3:
                mf[s, M_EH + c] = err
            else:
                mf[s, M_EW] = err
        _rational_bound(buf, box, mf, s, count, eps64, p)
    _widen(box, mf, s, sub_scale)
    frame_mag = 0.0
    for k in range(6):
        frame_mag = max(frame_mag, abs(box[s, k]))
    gulp = max(grid[p, 0], grid[p, 1], grid[p, 2])
    if gulp == 0.0:  # no grid (float64): its own ulps
        gulp = _ulp(frame_mag, bits) if frame_mag > 0.0 else 0.0
    mf[s, M_GULP] = gulp
    effort = 1
    sp = _open_child(box, mf, mi, s, ray, hit[H_TIN], p, frame, trace)
    while sp > 0:
        sp -= 1
        a = order[sp]
        if mf[a, M_TIN] >= hit[H_TIN]:
            if trace is not None:
                _set_event(trace, mi[a, 3], PRUNED)
            continue
        d = mf[a, M_D]
        depth = mi[a, 0]
        if surface >= 0 and mi[a, 4] == 0 and depth % 2 == 0:
            # Clear of every trimming curve? Then one parity test decides the whole sub-patch.
            u0 = dom[p, 0] + mf[a, M_U0] * (dom[p, 1] - dom[p, 0])
            u1 = dom[p, 0] + mf[a, M_U1] * (dom[p, 1] - dom[p, 0])
            v0 = dom[p, 2] + mf[a, M_V0] * (dom[p, 3] - dom[p, 2])
            v1 = dom[p, 2] + mf[a, M_V1] * (dom[p, 3] - dom[p, 2])
            if not rect_meets_loops(surface, min(u0, u1), max(u0, u1), min(v0, v1), max(v0, v1), trims[4], trims[6]):
                if trim_inside(surface, 0.5 * (u0 + u1), 0.5 * (v0 + v1), trims[2], trims[3], trims[4], trims[5],
                               trim_h, trim_m):
                    mi[a, 4] = 1
                else:
                    if trace is not None:
                        _set_event(trace, mi[a, 3], MISS)  # trimmed away as a whole
                    continue
        # The criteria's measure: the grid box's L1 diameter (>= d) once d is near a threshold.
        limit = GRID_PREFILTER * mf[a, M_GULP]
        if criterion == FIXED:
            limit = max(limit, param)
        elif criterion == ADAPTIVE:
            limit = max(limit, ray[R_T0] + ray[R_DT] * mf[a, M_TIN])
        d_crit = _grid_l1(box, mf, a, grid, p) if d <= limit else d
        stop = depth >= max_depth
        if criterion == FIXED:
            stop = stop or d_crit <= param
        elif criterion == ADAPTIVE:
            stop = stop or d_crit <= ray[R_T0] + ray[R_DT] * mf[a, M_TIN]
        elif criterion == MANTISSA:
            stop = stop or _within_ulps(box, mf, a, param, bits, grid, frame, p)
        # Float precision: the box did not shrink, even after halving the other direction too.
        # "Shrink" means by more than rounding noise: in float64 (its own grid) the widened box
        # otherwise keeps losing last bits forever. An interval that can no longer halve is spent.
        # A box that is mostly error bound cannot get meaningfully smaller either.
        # (Not so for rational slots in float32: re-derived from float64, their bound keeps falling
        # with their weights' spread as they shrink.)
        shrank = d_crit < mf[a, M_DPAR] * shrink_factor and (d > 1.0625 * mf[a, M_W] or homogeneous)
        if (mf[a, M_U0] == mf[a, M_U1]) or (mf[a, M_V0] == mf[a, M_V1]):
            stop = True  # the parameter interval cannot be halved any more
        if not shrank and mi[a, 1] == 1 and not (is_rational and d > limit):
            stop = True  # (a rational box can stall far above the float limit while extreme
            # weights spread its control points: that is no loss of precision, split on)
        if stop:
            # At the depth cap the precision is spent: accept rather than reject (a rejection
            # there would send the search through every branch down to the cap).
            found = depth >= max_depth or _hull_hit(buf, a, count, is_rational, mf, ray, sub_scale)
            if found and surface >= 0 and mi[a, 4] == 0:
                u = dom[p, 0] + 0.5 * (mf[a, M_U0] + mf[a, M_U1]) * (dom[p, 1] - dom[p, 0])
                v = dom[p, 2] + 0.5 * (mf[a, M_V0] + mf[a, M_V1]) * (dom[p, 3] - dom[p, 2])
                found = trim_inside(surface, u, v, trims[2], trims[3], trims[4], trims[5], trim_h, trim_m)
            if trace is not None:
                _set_event(trace, mi[a, 3], HIT if found else MISS)
            if found:
                _report(hit, box, mf, a, p, depth, grid, frame)
                if trace is not None and mi[a, 3] >= 0:  # the hit step shows the reported grid box
                    for c in range(6):
                        trace[0][mi[a, 3], 4 + c] = hit[H_LO + c]
                    trace[2][2] = mi[a, 3]  # steps are in creation order; this one is reported
            continue
        ext = max(box[a, 3] - box[a, 0], box[a, 4] - box[a, 1], box[a, 5] - box[a, 2])
        if cumulative and (mf[a, M_E] + mf[a, M_E + 1] + mf[a, M_E + 2]) * REFINE > ext:
            if is_rational:
                _refine_rational(buf, box, mf, a, m, n, count, ctrl64, start, eps64, p, w64, bits)
            else:
                _refine(buf, box, mf, a, m, n, count, ctrl64, start, eps64, p, w64, bits)
        elif ext * RECENTRE < mf[a, M_MAG]:
            _recentre(buf, box, mf, a, count, is_rational, homogeneous, bits, sub_scale, round_unit, eps64, p)
        if shrank:
            direction = _split_direction(buf, a, m, n, count, ray, split_mode, is_rational)
        else:
            direction = 1 - mi[a, 2] if mi[a, 2] >= 0 else 0
        b = order[sp + 1]
        # Each of the split's de Casteljau levels rounds a point by at most half an ulp of the
        # largest coordinate, and the errors of earlier levels stay in the points.
        levels = (m if direction == 0 else n) * round_unit
        if is_rational:  # the same for the homogeneous coordinates (M_E follows from them below)
            for c in range(4):
                big = 0.0
                for k in range(count):
                    big = max(big, abs(np.float64(buf[a, c, k])))
                col = M_EH + c if c < 3 else M_EW
                mf[a, col] += levels * big
                mf[b, col] = mf[a, col]
        else:
            for c in range(3):
                mf[b, M_E + c] = mf[a, M_E + c] + levels * max(abs(box[a, c]), abs(box[a, 3 + c]))
                mf[a, M_E + c] = mf[b, M_E + c]
        if cubic:
            if direction == 0:
                split_u_cubic(buf, a, b, box)
            else:
                split_v_cubic(buf, a, b, box)
        elif linear:
            if direction == 0:
                split_u_linear(buf, a, b, box)
            else:
                split_v_linear(buf, a, b, box)
        else:
            if direction == 0:
                split_u(buf, a, b, m, n, ncoord)
            else:
                split_v(buf, a, b, m, n, ncoord)
            _raw_box(buf, box, a, count, is_rational)
            _raw_box(buf, box, b, count, is_rational)
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
        stalled = 0 if shrank else 1
        mi[b, 4] = mi[a, 4]
        for child in (a, b):
            if homogeneous:
                _rational_bound(buf, box, mf, child, count, eps64, p)
            _widen(box, mf, child, sub_scale)
            mf[child, M_DPAR] = d_crit
            mi[child, 0] = depth + 1
            mi[child, 1] = stalled
            mi[child, 2] = direction
        alive_a = _open_child(box, mf, mi, a, ray, hit[H_TIN], p, frame, trace)
        alive_b = _open_child(box, mf, mi, b, ray, hit[H_TIN], p, frame, trace)
        effort += 2
        # Push the far half below the near one; only live halves count. Selects, not branches:
        # which half survives is as good as random, and positions sp, sp+1 keep slots {a, b}.
        near_a = mf[a, M_TIN] <= mf[b, M_TIN]
        far = b if near_a else a
        near = a if near_a else b
        alive_far = alive_b if near_a else alive_a
        alive_near = alive_a if near_a else alive_b
        if alive_far and alive_near:
            # The ray meets both boxes: the control hulls (across two planes through the ray)
            # are much thinner than the boxes, and one of them usually misses (a side branch saved).
            # The plane along the new seam separates first (the half the ray does not cross is on
            # its far side); the planes of the ray's own frame catch the rest.
            w0, w1, w2 = _seam_plane(buf, b, m, n, direction, is_rational, ray)
            dropped = -1
            if (_hull_off_plane(buf, far, count, is_rational, mf, ray, sub_scale, w0, w1, w2)
                    or not _hull_hit(buf, far, count, is_rational, mf, ray, sub_scale)):
                alive_far = 0
                dropped = far
            elif (_hull_off_plane(buf, near, count, is_rational, mf, ray, sub_scale, w0, w1, w2)
                  or not _hull_hit(buf, near, count, is_rational, mf, ray, sub_scale)):
                alive_near = 0
                dropped = near
            if trace is not None and dropped >= 0:
                _set_event(trace, mi[dropped, 3], MISS)
        order[sp] = far if alive_far else near
        order[sp + 1] = near if alive_far else far
        sp += alive_far + alive_near
    return effort
