"""The steps a patch search is made of (drivers.py puts them together): set up the root
sub-patch, classify against the trims, judge the termination criterion, accept a hit box,
subdivide, and record the trace. Each is a function of the sub-patch stack (records.Slots),
the patch (records.PatchInfo) and a ray record.

The float criterion is Dammertz's "the box stopped shrinking", applied to the box rounded
outward onto the leaf's grid (geometry.grid_steps), its L1 diameter exact: the search ends
where float32 numbers can no longer tell the boxes apart, and that grid box, moved to world
coordinates, is the reported hit box. The other criteria are tested on the same grid box, so
what they promise holds for what is reported. In float64 there is no grid.
"""
from __future__ import annotations

import math

from .jit import njit

from .ray import (H_DEPTH, H_DU, H_DV, H_HI, H_LO, H_PATCH, H_TIN, H_TOUT, H_U, H_U0, H_V, H_V0, R_DT, R_O, R_T0,
                  R_TMIN, before_best)
from .hull import hull_behind, hull_hit, hull_off_plane, seam_plane, stop_hull_meets
from .subpatch import (I_DEPTH, I_LAST, I_STALLED, I_STEP, I_TRIM, M_D, M_DPAR, M_E, M_GULP, M_MAG, M_OX, M_TIN,
                       M_TOUT, M_U0, M_U1, M_V0, M_V1, M_W, REFINE, RECENTRE, grid_l1, open_box, raw_box, recentre,
                       refine, snap_down, snap_up, split, split_direction, ulp, widen, within_ulps)
from .trim_kernel import rect_meets_loops, trim_inside

# Termination criteria (codes as in options.CRITERION_CODE).
FLOAT, FIXED, ADAPTIVE, MANTISSA = 0, 1, 2, 3
# Trace events.
MISS, PRUNED, SPLIT, HIT = 0, 1, 2, 3
EVENT_NAMES = ("miss", "pruned", "split", "hit")
GRID_PREFILTER = 64.0  # boxes wider than this many grid ulps certainly still shrink on the grid


# ---- the trace ----------------------------------------------------------------------------

@njit(cache=True, nogil=True, inline='always')
def record(trace, sl, s, pa, lv, event):
    """Append slot s's box (in world coordinates) to the trace; returns its step index
    (-1 when the trace is full)."""
    tf = trace.steps_f
    k = trace.state[0]
    if k >= tf.shape[0]:
        trace.state[1] = 1  # truncated
        return -1
    trace.state[0] = k + 1
    mf = sl.mf
    for c in range(4):
        tf[k, c] = mf[s, M_U0 + c]
    for c in range(3):
        tf[k, 4 + c] = sl.box[s, c] + mf[s, M_OX + c] + lv.frame[pa.p, c]
        tf[k, 7 + c] = sl.box[s, 3 + c] + mf[s, M_OX + c] + lv.frame[pa.p, c]
    tf[k, 10] = mf[s, M_D]
    trace.steps_i[k, 0] = pa.p
    trace.steps_i[k, 1] = sl.mi[s, I_DEPTH]
    trace.steps_i[k, 2] = event
    return k


@njit(cache=True, nogil=True, inline='always')
def set_event(trace, sl, s, event):
    step = sl.mi[s, I_STEP]
    if step >= 0:
        trace.steps_i[step, 2] = event


@njit(cache=True, nogil=True, inline='always')
def open_slot(sl, s, pa, ray, t_start, t_stop, hit):
    """Test slot s's (widened) box against the ray within [t_start, t_stop] (its parent's
    interval; the ray's t_min and inf at the root: subpatch.open_box). Returns (alive, met), 1 or
    0: it stays a candidate against the best hit; the ray meets it (whatever the best hit)."""
    alive, ok = open_box(sl, s, ray, t_start, t_stop, hit, pa.p)
    if ok and sl.mf[s, M_TIN] <= ray[R_TMIN] and hull_behind(sl, s, pa, ray):  # a box holding the origin
        alive = ok = False  # the ray misses it
    return 1 if alive else 0, 1 if ok else 0


@njit(cache=True, nogil=True, inline='always')
def open_child(sl, s, pa, lv, ray, t_start, t_stop, hit, trace, tracing):
    """open_slot, recording the box in the trace when tracing."""
    alive, ok = open_slot(sl, s, pa, ray, t_start, t_stop, hit)
    if tracing:
        event = SPLIT if alive else (PRUNED if ok else MISS)  # SPLIT stands until it is popped
        sl.mi[s, I_STEP] = record(trace, sl, s, pa, lv, event)
    return alive, ok


# ---- the steps ----------------------------------------------------------------------------

@njit(cache=True, nogil=True, inline='always')
def enter_frame(sl, ray, lv, p):
    """The ray moved into patch p's frame (float64), in the slots' ray record."""
    lray = sl.lray
    for k in range(lray.shape[0]):
        lray[k] = ray[k]
    for c in range(3):
        lray[R_O + c] = ray[R_O + c] - lv.frame[p, c]
    return lray


@njit(cache=True, nogil=True, inline='always')
def ahead(sl, a, pa, hit):
    """Can slot a, popped from the stack, still hold a hit box that beats the best hit
    (ray.before_best)?"""
    mf = sl.mf
    return before_best(mf[a, M_TIN], mf[a, M_U0], mf[a, M_V0], hit, pa.p)


@njit(cache=True, nogil=True, inline='always')
def root(sl, pa, lv):
    """The whole patch into the first slot, its box widened by the stored points' error."""
    return root_at(sl, sl.order[0], pa, lv)


@njit(cache=True, nogil=True, inline='always')
def root_at(sl, s, pa, lv):
    """The whole patch into slot s (see root)."""
    buf = sl.buf
    mf = sl.mf
    mi = sl.mi
    p = pa.p
    for c in range(4 if pa.rational else 3):
        for k in range(pa.count):
            buf[s, c, k] = lv.ctrl[c, pa.start + k]
    mf[s, M_U0] = 0.0
    mf[s, M_U1] = 1.0
    mf[s, M_V0] = 0.0
    mf[s, M_V1] = 1.0
    mf[s, M_DPAR] = math.inf
    for c in range(3):
        mf[s, M_OX + c] = 0.0
        mf[s, M_E + c] = lv.eps[p, c]
    mi[s, I_DEPTH] = 0
    mi[s, I_STALLED] = 0
    mi[s, I_LAST] = -1
    mi[s, I_TRIM] = 0
    raw_box(sl.buf, sl.box, s, pa.count, pa.rational)
    widen(sl.box, mf, s, pa.sub_scale)
    frame_mag = 0.0
    for k in range(6):
        frame_mag = max(frame_mag, abs(sl.box[s, k]))
    gulp = max(lv.grid[p, 0], lv.grid[p, 1], lv.grid[p, 2])
    if gulp == 0.0:  # no grid (float64): its own ulps
        gulp = ulp(frame_mag, pa.bits) if frame_mag > 0.0 else 0.0
    mf[s, M_GULP] = gulp
    return s


@njit(cache=True, nogil=True, inline='always')
def _domain_point(dom, p, u, v):
    return dom[p, 0] + u * (dom[p, 1] - dom[p, 0]), dom[p, 2] + v * (dom[p, 3] - dom[p, 2])


@njit(cache=True, nogil=True, inline='always')
def trim_state(sl, a, pa, trims):
    """Slot a against its surface's trimming loops, tested every other level while undecided:
    clear of every curve, one parity test decides the whole sub-patch. Returns 1 (wholly kept),
    0 (undecided) or -1 (trimmed away as a whole)."""
    state = sl.mi[a, I_TRIM]
    surface = trims.patch_trim[pa.p]
    if surface < 0 or state != 0 or sl.mi[a, I_DEPTH] % 2 != 0:
        return state
    mf = sl.mf
    u0, v0 = _domain_point(trims.domain, pa.p, mf[a, M_U0], mf[a, M_V0])
    u1, v1 = _domain_point(trims.domain, pa.p, mf[a, M_U1], mf[a, M_V1])
    if rect_meets_loops(surface, min(u0, u1), max(u0, u1), min(v0, v1), max(v0, v1), trims.seg_points,
                        trims.seg_start, trims.surf_seg_start, trims.seg_box, sl.trim_h, sl.trim_m):
        return 0
    if trim_inside(surface, 0.5 * (u0 + u1), 0.5 * (v0 + v1), trims.seg_points, trims.seg_start,
                   trims.surf_seg_start, trims.start_inside, sl.trim_h, sl.trim_m):
        sl.mi[a, I_TRIM] = 1
        return 1
    return -1


@njit(cache=True, nogil=True, inline='always')
def judge(sl, a, pa, lv, ray, q):
    """Does slot a meet the termination criterion? Returns (stop, the box's criterion diameter,
    whether the box really shrank since its parent)."""
    stop, d_crit, shrank, _ = judge_known(sl, a, pa, lv, ray, q, -1.0)
    return stop, d_crit, shrank


@njit(cache=True, nogil=True, inline='always')
def judge_known(sl, a, pa, lv, ray, q, g):
    """judge, given slot a's grid box L1 diameter g where a ray of the bundle needed it already
    (-1: not yet); returns it too (still -1 if this ray did not need it either)."""
    mf = sl.mf
    d = mf[a, M_D]
    depth = sl.mi[a, I_DEPTH]
    criterion = q.criterion
    param = q.param
    # The criteria's measure: the grid box's L1 diameter (>= d) once d is near a threshold.
    box_limit = GRID_PREFILTER * mf[a, M_GULP]
    if criterion == FIXED:
        box_limit = max(box_limit, param)
    limit = box_limit
    detail = 0.0
    if criterion == ADAPTIVE:
        detail = ray[R_T0] + ray[R_DT] * mf[a, M_TIN]
        limit = max(limit, detail)
    d_crit = d
    if d <= limit:
        if g < 0.0:
            g = grid_l1(sl, a, lv.grid, pa.p)
        d_crit = g
    # The box's own measure, the same for every ray (the threshold of detail is the ray's): what
    # the shrink test and the halves' M_DPAR read, so a bundle's rays split a shared box alike.
    d_box = g if d <= box_limit else d
    stop = depth >= q.max_depth
    if criterion == FIXED:
        stop = stop or d_crit <= param
    elif criterion == ADAPTIVE:
        stop = stop or d_crit <= detail
    elif criterion == MANTISSA:
        stop = stop or within_ulps(sl, a, param, q.bits, lv, pa.p)  # the working precision's ulps
    # Float precision: the box did not shrink, even after halving the other direction too.
    # "Shrink" means by more than rounding noise: in float64 (its own grid) the widened box
    # otherwise keeps losing last bits forever. An interval that can no longer halve is spent.
    # A box that is mostly error bound cannot get meaningfully smaller either.
    shrank = d_box < mf[a, M_DPAR] * pa.shrink_factor and d > 1.0625 * mf[a, M_W]
    if (mf[a, M_U0] == mf[a, M_U1]) or (mf[a, M_V0] == mf[a, M_V1]):
        stop = True  # the parameter interval cannot be halved any more
    if not shrank and sl.mi[a, I_STALLED] == 1 and not (pa.rational and d > limit):
        stop = True  # (a rational box can stall far above the float limit while extreme
        # weights spread its control points: that is no loss of precision, split on)
    return stop, d_box, shrank, g


@njit(cache=True, nogil=True, inline='always')
def hull_accepts(sl, a, pa, lv, ray, q):
    """Does the ray meet the control hull of slot a, which met the criterion
    (hull.stop_hull_meets)? At the depth cap the precision is spent: accept rather than reject (a
    rejection there would send the search through every branch)."""
    return sl.mi[a, I_DEPTH] >= q.max_depth or stop_hull_meets(sl, a, pa, lv, ray)


@njit(cache=True, nogil=True, inline='always')
def trim_accepts(sl, a, pa, trims):
    """Does slot a's parameter centre lie in the kept region (no trims, or decided kept: yes)?"""
    if trims.patch_trim[pa.p] < 0 or sl.mi[a, I_TRIM] != 0:
        return True
    mf = sl.mf
    u, v = _domain_point(trims.domain, pa.p, 0.5 * (mf[a, M_U0] + mf[a, M_U1]), 0.5 * (mf[a, M_V0] + mf[a, M_V1]))
    return trim_inside(trims.patch_trim[pa.p], u, v, trims.seg_points, trims.seg_start, trims.surf_seg_start,
                       trims.start_inside, sl.trim_h, sl.trim_m)


@njit(cache=True, nogil=True, inline='always')
def accept(sl, a, pa, lv, ray, q, trims, has_trims):
    """Is slot a, which met the criterion, a hit? Its control hull must meet the ray and its
    parameter centre lie in the kept region."""
    found = hull_accepts(sl, a, pa, lv, ray, q)
    if has_trims and found:
        found = trim_accepts(sl, a, pa, trims)
    return found


@njit(cache=True, nogil=True, inline='always')
def report(hit, sl, a, pa, lv):
    """Record slot a as the closest hit so far: its grid box, in world coordinates."""
    mf = sl.mf
    p = pa.p
    hit[H_TIN] = mf[a, M_TIN]
    hit[H_TOUT] = mf[a, M_TOUT]
    for c in range(3):
        o = mf[a, M_OX + c]
        hit[H_LO + c] = snap_down(sl.box[a, c] + o, lv.grid[p, c]) + lv.frame[p, c]
        hit[H_HI + c] = snap_up(sl.box[a, 3 + c] + o, lv.grid[p, c]) + lv.frame[p, c]
    hit[H_U] = 0.5 * (mf[a, M_U0] + mf[a, M_U1])
    hit[H_V] = 0.5 * (mf[a, M_V0] + mf[a, M_V1])
    hit[H_DU] = mf[a, M_U1] - mf[a, M_U0]
    hit[H_DV] = mf[a, M_V1] - mf[a, M_V0]
    hit[H_PATCH] = p
    hit[H_DEPTH] = sl.mi[a, I_DEPTH]
    hit[H_U0] = mf[a, M_U0]
    hit[H_V0] = mf[a, M_V0]


@njit(cache=True, nogil=True, inline='always')
def trace_hit(trace, sl, a, hit):
    """The hit step shows the reported grid box; steps are in creation order, this one is reported."""
    step = sl.mi[a, I_STEP]
    if step >= 0:
        for c in range(6):
            trace.steps_f[step, 4 + c] = hit[H_LO + c]
        trace.state[2] = step


@njit(cache=True, nogil=True, inline='always')
def tighten(sl, a, pa, lv):
    """Re-derive slot a from float64 when its error band nears its box (float32 slots: integral
    patches), else re-centre it when the box is much smaller than its coordinates (midpoints
    then round relative to the box)."""
    how = tightening(sl, a, pa)
    if how == REFINING:
        refine(sl.buf, sl.box, sl.mf, sl.w64, a, pa, lv.ctrl64, lv.eps64)
    elif how == RECENTRING:
        recentre(sl.buf, sl.box, sl.mf, a, pa)


REFINING, RECENTRING = 1, 2


@njit(cache=True, nogil=True, inline='always')
def tightening(sl, a, pa):
    """What tighten does to slot a: REFINING, RECENTRING or 0 (nothing)."""
    box = sl.box
    mf = sl.mf
    ext = max(box[a, 3] - box[a, 0], box[a, 4] - box[a, 1], box[a, 5] - box[a, 2])
    if pa.cumulative and (mf[a, M_E] + mf[a, M_E + 1] + mf[a, M_E + 2]) * REFINE > ext:
        return REFINING
    return RECENTRING if ext * RECENTRE < mf[a, M_MAG] else 0


@njit(cache=True, nogil=True, inline='always')
def halve(sl, a, b, pa, ray, q, d_crit, shrank, has_general):
    """Halve slot a (tightened first) into a and b, each with its widened box and its place in
    the tree: the longer direction or the ray's ('cross') while the box shrinks, else the other
    direction than last time. Returns the direction (0 u, 1 v)."""
    direction = halving_direction(sl, a, pa, ray, q, shrank)
    split(sl, a, b, pa, direction, has_general)
    finish_halves(sl, a, b, pa, d_crit, shrank, direction)
    return direction


@njit(cache=True, nogil=True, inline='always')
def halving_direction(sl, a, pa, ray, q, shrank):
    """halve's direction for slot a: 0 u, 1 v."""
    if shrank:
        return split_direction(sl, a, pa, ray, q.split_mode)
    last = sl.mi[a, I_LAST]
    return 1 - last if last >= 0 else 0


@njit(cache=True, nogil=True, inline='always')
def finish_halves(sl, a, b, pa, d_crit, shrank, direction):
    """halve's last step, once slots a and b hold the halves: their widened boxes and places in
    the tree."""
    mf = sl.mf
    mi = sl.mi
    stalled = 0 if shrank else 1
    depth = mi[a, I_DEPTH]
    mi[b, I_TRIM] = mi[a, I_TRIM]
    for child in (a, b):
        widen(sl.box, mf, child, pa.sub_scale)
        mf[child, M_DPAR] = d_crit
        mi[child, I_DEPTH] = depth + 1
        mi[child, I_STALLED] = stalled
        mi[child, I_LAST] = direction


@njit(cache=True, nogil=True, inline='always')
def sort_halves(sl, a, b, pa, lv, ray, t_start, t_stop, hit, direction, trace, tracing):
    """Test the halves a and b (b the one past the seam) against the ray within [t_start, t_stop],
    their parent's interval: (far, near, alive_far, alive_near), the far half to be pushed below
    the near one; only live halves count."""
    alive_a, met_a = open_child(sl, a, pa, lv, ray, t_start, t_stop, hit, trace, tracing)
    alive_b, met_b = open_child(sl, b, pa, lv, ray, t_start, t_stop, hit, trace, tracing)
    far, near, alive_far, alive_near, dropped = near_and_far(sl, a, b, pa, ray, direction, alive_a, alive_b,
                                                             met_a & met_b)
    if tracing and dropped >= 0:
        set_event(trace, sl, dropped, MISS)
    return far, near, alive_far, alive_near


@njit(cache=True, nogil=True, inline='always')
def near_and_far(sl, a, b, pa, ray, direction, alive_a, alive_b, met_both):
    """The halves a and b (b past the seam), whether each stays a candidate (alive_a, alive_b: 1
    or 0) and whether the ray meets both boxes, as (far, near, alive_far, alive_near, the live half
    the hull tests dropped or -1); a is the near one where both are entered at the same t.

    The hull tests run where the ray meets both boxes, whatever the best hit prunes: which half
    they drop is a matter of the ray and the boxes, the same in every order of visits."""
    far, near, alive_far, alive_near = order_halves(sl, a, b, alive_a, alive_b)
    dropped = -1
    if met_both and (alive_far or alive_near):
        # The ray meets both boxes: the control hulls (across two planes through the ray)
        # are much thinner than the boxes, and one of them usually misses (a side branch saved).
        # The plane along the new seam separates first (the half the ray does not cross is on
        # its far side); the planes of the ray's own frame catch the rest.
        w0, w1, w2 = seam_plane(sl, b, pa, direction, ray)
        if hull_off_plane(sl, far, pa, ray, w0, w1, w2) or not hull_hit(sl, far, pa, ray):
            if alive_far:
                dropped = far
            alive_far = 0
        elif hull_off_plane(sl, near, pa, ray, w0, w1, w2) or not hull_hit(sl, near, pa, ray):
            if alive_near:
                dropped = near
            alive_near = 0
    return far, near, alive_far, alive_near, dropped


@njit(cache=True, nogil=True, inline='always')
def order_halves(sl, a, b, alive_a, alive_b):
    """near_and_far's first step: (far, near, alive_far, alive_near), a the near half where both
    are entered at the same t."""
    mf = sl.mf
    # Selects, not branches: which half survives is as good as random.
    near_a = mf[a, M_TIN] <= mf[b, M_TIN]
    far = b if near_a else a
    near = a if near_a else b
    alive_far = alive_b if near_a else alive_a
    alive_near = alive_a if near_a else alive_b
    return far, near, alive_far, alive_near


@njit(cache=True, nogil=True, inline='always')
def subdivide(sl, a, sp, pa, lv, ray, q, hit, d_crit, shrank, trace, tracing, has_general):
    """Halve slot a (stack position sp; tightened first) and push the halves that stay
    candidates against the best hit, the near one on top. Returns the new stack height."""
    order = sl.order
    b = order[sp + 1]
    t_start = sl.mf[a, M_TIN]
    t_stop = sl.mf[a, M_TOUT]
    direction = halve(sl, a, b, pa, ray, q, d_crit, shrank, has_general)
    far, near, alive_far, alive_near = sort_halves(sl, a, b, pa, lv, ray, t_start, t_stop, hit, direction, trace,
                                                   tracing)
    # Positions sp, sp + 1 keep slots {a, b}.
    order[sp] = far if alive_far else near
    order[sp + 1] = near if alive_far else far
    return sp + alive_far + alive_near
