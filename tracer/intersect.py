"""Ray-patch intersection by recursive de Casteljau subdivision (Dammertz 2005, ch. 2).

The search keeps an explicit stack of sub-patches. A popped sub-patch whose
box is hit either meets the termination criterion (hit: its box is the hit
interval) or is halved in u or v; each half's box is tested at once, and the
nearer half is visited first, so a hit shortens the ray and prunes the rest.

Precision: control points are stored relative to a per-object frame origin in
the working dtype (float32 or float64); midpoints round relative to the size of
those local coordinates, not of the world ones. Ray-box slabs run in float64
on the (exactly widened) box corners, so the ray is never rounded again.

Scratch layout (one set per thread), S = max depth + 2 slots:
  buf   (S, 4, P) working dtype   control points per slot (row 3: weights of rational patches)
  box   (S, 6)    float64         local box per slot: lo xyz, hi xyz
  mf    (S, 8)    float64         per slot: u0 u1 v0 v1 t_in t_out diameter parent_diameter
  mi    (S, 4)    int32           per slot: depth, stalled, last split (0 u, 1 v), trace step
  order (S,)      int32           stack position -> slot (children swap order without copying)
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .bezier import control_box, control_box_rational, normal_at, split_u, split_u_cubic, split_v, split_v_cubic

# Termination criteria and split heuristics (codes as in options.CRITERION_CODE / SPLIT_CODE).
FLOAT, FIXED, ADAPTIVE, MANTISSA = 0, 1, 2, 3
SPLIT_LENGTH, SPLIT_CROSS = 0, 1
# Trace events.
MISS, PRUNED, SPLIT, HIT = 0, 1, 2, 3
EVENT_NAMES = ("miss", "pruned", "split", "hit")

# Ray record (float64): origin, direction, 1/direction, t_min, threshold of detail T(t) = T0 + dT*t.
R_O, R_D, R_INV, R_TMIN, R_T0, R_DT = 0, 3, 6, 9, 10, 11
RAY_LEN = 12
# Hit record (float64): entry/exit t of the hit box, world box, (u, v), patch, depth, interval sizes.
H_TIN, H_TOUT, H_LO, H_HI, H_U, H_V, H_PATCH, H_DEPTH, H_DU, H_DV = 0, 1, 2, 5, 8, 9, 10, 11, 12, 13
HIT_LEN = 14
# Per-slot float metadata.
M_U0, M_U1, M_V0, M_V1, M_TIN, M_TOUT, M_D, M_DPAR = 0, 1, 2, 3, 4, 5, 6, 7
# Trace record columns (float64): u0 u1 v0 v1 lo xyz hi xyz diameter; (int32): patch depth event.
TRACE_F, TRACE_I = 11, 3

_T_SLACK = 4.0 * 2.0 ** -52  # widen slab exits by a few float64 ulps: grazing rays keep their boxes


def max_depth_for(precision_bits: int) -> int:
    """Subdivision depth cap: both directions down to the precision, with room to spare."""
    return 2 * (precision_bits + 16)


@njit(cache=True, nogil=True)
def make_ray(ray, ox, oy, oz, dx, dy, dz, t_min, t0, dt):
    """Fill a ray record; zero direction components get an infinite inverse (handled in `slab`)."""
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


@njit(cache=True, nogil=True, inline='always')
def slab(bx, fx, fy, fz, ray):
    """Ray against the box bx (lo xyz, hi xyz) shifted by (fx, fy, fz); float64 throughout.

    Returns (hit, t_in, t_out) with t_in clamped to the ray's t_min. A zero
    direction component is tested by containment instead of by division, so
    no inf * 0 = NaN can appear.
    """
    t_in = ray[R_TMIN]
    t_out = math.inf
    for c in range(3):
        f = fx if c == 0 else (fy if c == 1 else fz)
        lo = bx[c] + f - ray[R_O + c]
        hi = bx[3 + c] + f - ray[R_O + c]
        if ray[R_D + c] == 0.0:
            if lo > 0.0 or hi < 0.0:
                return False, t_in, t_out
            continue
        inv = ray[R_INV + c]
        a = lo * inv
        b = hi * inv
        if a > b:
            a, b = b, a
        b += abs(b) * _T_SLACK
        if a > t_in:
            t_in = a
        if b < t_out:
            t_out = b
    return t_in <= t_out, t_in, t_out


@njit(cache=True, nogil=True, inline='always')
def _l1(box, s):
    """L1 diameter of box[s]; rounded in float64 (box corners are exact widenings)."""
    return (box[s, 3] - box[s, 0]) + (box[s, 4] - box[s, 1]) + (box[s, 5] - box[s, 2])


@njit(cache=True, nogil=True, inline='always')
def _within_ulps(box, s, fx, fy, fz, ulps, bits):
    """Are the box's world corners within `ulps` units in the last place (of `bits`-bit floats)?"""
    for c in range(3):
        f = fx if c == 0 else (fy if c == 1 else fz)
        lo = box[s, c] + f
        hi = box[s, 3 + c] + f
        mag = max(abs(lo), abs(hi))
        if mag == 0.0:
            continue
        ulp = math.ldexp(1.0, math.frexp(mag)[1] - bits)
        if hi - lo > ulps * ulp:
            return False
    return True


@njit(cache=True, nogil=True, inline='always')
def _corner(buf, s, k, c, rational):
    """Coordinate c of control point k in slot s, homogenised for rational patches."""
    if rational:
        return float(buf[s, c, k]) / float(buf[s, 3, k])
    return float(buf[s, c, k])


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
def _record(trace, p, depth, mf, box, s, fx, fy, fz, d, event):
    """Append one box to the trace; returns its step index (-1 when the trace is full)."""
    tf, ti, tn = trace
    k = tn[0]
    if k >= tf.shape[0]:
        tn[1] = 1  # truncated
        return -1
    tn[0] = k + 1
    for c in range(4):
        tf[k, c] = mf[s, M_U0 + c]
    tf[k, 4] = box[s, 0] + fx
    tf[k, 5] = box[s, 1] + fy
    tf[k, 6] = box[s, 2] + fz
    tf[k, 7] = box[s, 3] + fx
    tf[k, 8] = box[s, 4] + fy
    tf[k, 9] = box[s, 5] + fz
    tf[k, 10] = d
    ti[k, 0] = p
    ti[k, 1] = depth
    ti[k, 2] = event
    return k


@njit(cache=True, nogil=True, inline='always')
def _set_event(trace, step, event):
    if step >= 0:
        trace[1][step, 2] = event


@njit(cache=True, nogil=True, inline='always')
def _open_child(box, mf, mi, s, fx, fy, fz, ray, best_t, p, trace):
    """Test the fresh sub-patch in slot s (its box already computed) against the ray;
    returns 1 if it stays a candidate."""
    mf[s, M_D] = _l1(box, s)
    ok, t_in, t_out = slab(box[s], fx, fy, fz, ray)
    mf[s, M_TIN] = t_in
    mf[s, M_TOUT] = t_out
    alive = ok and t_in < best_t
    if trace is not None:
        event = SPLIT if alive else (PRUNED if ok else MISS)  # SPLIT is a placeholder until popped
        mi[s, 3] = _record(trace, p, mi[s, 0], mf, box, s, fx, fy, fz, mf[s, M_D], event)
    return 1 if alive else 0


@njit(cache=True, nogil=True)
def search_patch(p, ctrl, pstart, deg_u, deg_v, rational, frame, ray, hit,
                 criterion, param, split_mode, max_depth, bits,
                 buf, box, mf, mi, order, trace):
    """Closest intersection of `ray` with patch p beyond t_min and before hit[H_TIN].

    Updates `hit` when a closer hit box is found; returns the number of boxes computed.
    ctrl: (4, total points) working dtype, local to frame[p] (float64 (n_patches, 3)); row 3
    holds the weights, rows 0-2 are premultiplied by them for rational[p] patches.
    criterion/param: FLOAT (-), FIXED (L1 size), ADAPTIVE (fraction folded into ray T0/dT),
    MANTISSA (ulps); every criterion also stops when the box stops shrinking.
    bits: mantissa bits of the working dtype (24 or 53). trace: None or (tf, ti, tn).
    """
    m = deg_u[p]
    n = deg_v[p]
    count = (m + 1) * (n + 1)
    is_rational = rational[p] != 0
    ncoord = 4 if is_rational else 3
    cubic = m == 3 and n == 3 and not is_rational
    start = pstart[p]
    fx = frame[p, 0]
    fy = frame[p, 1]
    fz = frame[p, 2]
    s = order[0]
    for c in range(ncoord):
        for k in range(count):
            buf[s, c, k] = ctrl[c, start + k]
    mf[s, M_U0] = 0.0
    mf[s, M_U1] = 1.0
    mf[s, M_V0] = 0.0
    mf[s, M_V1] = 1.0
    mf[s, M_DPAR] = math.inf
    mi[s, 0] = 0
    mi[s, 1] = 0
    mi[s, 2] = -1
    effort = 1
    if is_rational:
        control_box_rational(buf, s, count, box, bits)
    else:
        control_box(buf, s, count, box)
    sp = _open_child(box, mf, mi, s, fx, fy, fz, ray, hit[H_TIN], p, trace)
    while sp > 0:
        sp -= 1
        a = order[sp]
        if mf[a, M_TIN] >= hit[H_TIN]:
            if trace is not None:
                _set_event(trace, mi[a, 3], PRUNED)
            continue
        d = mf[a, M_D]
        depth = mi[a, 0]
        stop = depth >= max_depth
        if criterion == FIXED:
            stop = stop or d <= param
        elif criterion == ADAPTIVE:
            stop = stop or d <= ray[R_T0] + ray[R_DT] * mf[a, M_TIN]
        elif criterion == MANTISSA:
            stop = stop or _within_ulps(box, a, fx, fy, fz, param, bits)
        # Float precision: the box did not shrink, even after halving the other direction too.
        shrank = d < mf[a, M_DPAR]
        if not shrank and mi[a, 1] == 1:
            stop = True
        if stop:
            if trace is not None:
                _set_event(trace, mi[a, 3], HIT)
            hit[H_TIN] = mf[a, M_TIN]
            hit[H_TOUT] = mf[a, M_TOUT]
            hit[H_LO] = box[a, 0] + fx
            hit[H_LO + 1] = box[a, 1] + fy
            hit[H_LO + 2] = box[a, 2] + fz
            hit[H_HI] = box[a, 3] + fx
            hit[H_HI + 1] = box[a, 4] + fy
            hit[H_HI + 2] = box[a, 5] + fz
            hit[H_U] = 0.5 * (mf[a, M_U0] + mf[a, M_U1])
            hit[H_V] = 0.5 * (mf[a, M_V0] + mf[a, M_V1])
            hit[H_DU] = mf[a, M_U1] - mf[a, M_U0]
            hit[H_DV] = mf[a, M_V1] - mf[a, M_V0]
            hit[H_PATCH] = p
            hit[H_DEPTH] = depth
            continue
        if shrank:
            direction = _split_direction(buf, a, m, n, count, ray, split_mode, is_rational)
        else:
            direction = 1 - mi[a, 2] if mi[a, 2] >= 0 else 0
        b = order[sp + 1]
        if cubic:
            if direction == 0:
                split_u_cubic(buf, a, b, box)
            else:
                split_v_cubic(buf, a, b, box)
        else:
            if direction == 0:
                split_u(buf, a, b, m, n, ncoord)
            else:
                split_v(buf, a, b, m, n, ncoord)
            if is_rational:
                control_box_rational(buf, a, count, box, bits)
                control_box_rational(buf, b, count, box, bits)
            else:
                control_box(buf, a, count, box)
                control_box(buf, b, count, box)
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
        stalled = 0 if shrank else 1
        for child in (a, b):
            mf[child, M_DPAR] = d
            mi[child, 0] = depth + 1
            mi[child, 1] = stalled
            mi[child, 2] = direction
        alive_a = _open_child(box, mf, mi, a, fx, fy, fz, ray, hit[H_TIN], p, trace)
        alive_b = _open_child(box, mf, mi, b, fx, fy, fz, ray, hit[H_TIN], p, trace)
        effort += 2
        if alive_a and alive_b:
            near_a = mf[a, M_TIN] <= mf[b, M_TIN]
            order[sp] = b if near_a else a  # far half below, visited later
            order[sp + 1] = a if near_a else b
            sp += 2
        elif alive_a or alive_b:
            order[sp] = a if alive_a else b
            order[sp + 1] = b if alive_a else a
            sp += 1
    return effort


@njit(cache=True, nogil=True)
def trace_ray(ray, hit, ctrl, pstart, deg_u, deg_v, rational, frame,
              node_box, node_child, node_patch,
              criterion, param, split_mode, max_depth, bits,
              buf, box, mf, mi, order, node_stack, node_tin, trace):
    """Closest hit of one ray in the scene: BVH traversal, near child first, sharing the
    shrinking ray interval with the patch searches. Returns the total effort (patch boxes).

    node_box: (N, 6) float64 world boxes; node_child: (N, 2) int32 children (-1 at a leaf);
    node_patch: (N,) int32 patch of a leaf. hit[H_TIN] must be the initial t_max (inf).
    """
    effort = 0
    ok, t_in, t_out = slab(node_box[0], 0.0, 0.0, 0.0, ray)
    if not ok:
        return 0
    top = 0
    node_stack[0] = 0
    node_tin[0] = t_in
    top = 1
    while top > 0:
        top -= 1
        node = node_stack[top]
        if node_tin[top] >= hit[H_TIN]:
            continue
        left = node_child[node, 0]
        if left < 0:
            effort += search_patch(node_patch[node], ctrl, pstart, deg_u, deg_v, rational, frame, ray, hit,
                                   criterion, param, split_mode, max_depth, bits,
                                   buf, box, mf, mi, order, trace)
            continue
        right = node_child[node, 1]
        ok_l, tl, _ = slab(node_box[left], 0.0, 0.0, 0.0, ray)
        ok_r, tr, _ = slab(node_box[right], 0.0, 0.0, 0.0, ray)
        ok_l = ok_l and tl < hit[H_TIN]
        ok_r = ok_r and tr < hit[H_TIN]
        if ok_l and ok_r:
            far_first = tl <= tr
            node_stack[top] = right if far_first else left
            node_tin[top] = tr if far_first else tl
            node_stack[top + 1] = left if far_first else right
            node_tin[top + 1] = tl if far_first else tr
            top += 2
        elif ok_l or ok_r:
            node_stack[top] = left if ok_l else right
            node_tin[top] = tl if ok_l else tr
            top += 1
    return effort


@njit(cache=True, nogil=True)
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


def scratch_for(n_points: int, max_depth: int, dtype):
    """Per-thread scratch arrays for search_patch / trace_ray (see module docstring)."""
    slots = max_depth + 2
    return (np.zeros((slots, 4, n_points), dtype), np.zeros((slots, 6)), np.zeros((slots, 8)),
            np.zeros((slots, 4), np.int32), np.arange(slots, dtype=np.int32),
            np.zeros(128, np.int32), np.zeros(128))
