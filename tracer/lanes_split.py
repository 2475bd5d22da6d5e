"""Eight sub-patches halved and judged at once, one in each lane (LLVM IR through numba
intrinsics): the rays a bundle leaves alone go on eight at a time (bundle_alone.py), each with its
own integral bicubic or bilinear, halved in its own direction.

A lane's sub-patch lives in a column of the lane slots: points (3, 16, COLUMNS) in the slots'
dtype, point k = i + 4 j of coordinate c of lane j's sub-patch at [c, k, j] (a slot's buf[s, c, k],
records.Slots), box (6, COLUMNS), mf (MF_LEN, COLUMNS) float64 and mi (MI_LEN, COLUMNS) int32 (a
slot's rows, in columns); column LANES + j holds lane j's high half after a halving.
- halve_lanes, halve_lanes_linear: search_steps.halving_direction, subpatch.split_bounds, the split
  (simd.split_u_cubic / split_v_cubic, bezier._split_linear), subpatch.split_intervals,
  search_steps.finish_halves and subpatch.open_box's slab test, with open_slot's verdicts;
- judge_lanes: search_steps.judge_known (not the mantissa criterion) and tightening's test;
- keep_high_lanes: the lanes that keep their high half move it into their own column.
Each lane gets exactly what the single ray's steps give a slot: the same operations in the same
order, lane by lane (no fused or reordered arithmetic). A lane halving along v has its points
transposed on the way in and out, so that one pass along u serves every lane: its lines are then
the v pass's, point for point and in the same order, and the control boxes are reduced in the
scalar split's order (its four vectors, then lanes 0 with 2 and 1 with 3, then the two), so a bound
that is a zero has the sign the slot's would have. tests/test_lanes_split.py compares them with
the single ray's steps on slots, byte for byte. With NUMBA_DISABLE_JIT=1 the same names are numpy
versions doing the same operations in the same order.
"""
from __future__ import annotations

import functools

import numpy as np
from llvmlite import ir
from numba import config
from numba.core import cgutils, types
from numba.extending import intrinsic

from .ray import R_D, R_INV, R_O, T_SLACK
from .search_steps import ADAPTIVE, FIXED, GRID_PREFILTER
from .subpatch import (I_DEPTH, I_LAST, I_STALLED, I_TRIM, M_D, M_DPAR, M_E, M_GULP, M_MAG, M_OX, M_TIN, M_TOUT, M_U0,
                       M_U1, M_V0, M_V1, M_W, MF_LEN, MI_LEN, RECENTRE, REFINE, SPLIT_CROSS)

LANES = 8
COLUMNS = 2 * LANES
# Rows of the lanes' rays (LANE_RAY, LANES): origin in the patch's frame xyz, direction xyz and
# 1 / direction xyz (rows ray.R_O, R_D, R_INV), then the adaptive criterion's threshold of detail
# at t = 0 and its growth, the t the ray's search goes up to (its hit's H_TIN), its R_REACH and
# R_TMIN; and of a halving's per-lane inputs (STEP_LEN, LANES): the parent's criterion diameter
# (the halves' M_DPAR) and whether its box shrank (1.0 or 0.0).
LR_T0, LR_DT, LR_LIMIT, LR_REACH, LR_TMIN = 9, 10, 11, 12, 13
LANE_RAY = 14
S_DCRIT, S_SHRANK = 0, 1
STEP_LEN = 2


# The corners split_direction measures, as (u edges, v edges), each edge (end, start) point indices.
CUBIC_EDGES = (((3, 0), (15, 12)), ((12, 0), (15, 3)))
LINEAR_EDGES = (((1, 0), (3, 2)), ((2, 0), (3, 1)))


def _halves(mid, curve):
    """de Casteljau at 1/2 of a cubic's four points (simd._make_split's lerps): (low, high)."""
    p0, p1, p2, p3 = curve
    q0, q1, q2 = mid(p0, p1), mid(p1, p2), mid(p2, p3)
    s0, s1 = mid(q0, q1), mid(q1, q2)
    m = mid(s0, s1)
    return [p0, q0, s0, m], [m, s1, q2, p3]


def _lines(along_u):
    """The point indices of the four lines a halving runs along: rows j through i along u,
    columns i through j along v. Each line's points are one of the four vectors simd's split
    reduces first for the box, in that order."""
    return [[i + 4 * line for i in range(4)] if along_u else [line + 4 * j for j in range(4)] for line in range(4)]


def _split_pass(mid, vmin, vmax, points, along_u):
    """One direction's halving of a coordinate's 16 points: (low, high, {(half, op): bound})."""
    low, high, acc = [None] * 16, [None] * 16, {}
    for ks in _lines(along_u):
        for half, half_points in enumerate(_halves(mid, [points[k] for k in ks])):
            for op in (vmin, vmax):
                value = half_points[0]
                for point in half_points[1:]:
                    value = op(value, point)
                acc.setdefault((half, op), []).append(value)
            for k, value in zip(ks, half_points):
                (low, high)[half][k] = value
    bounds = {key: key[1](key[1](a[0], a[2]), key[1](a[1], a[3])) for key, a in acc.items()}
    return low, high, bounds


# ---- numpy versions (NUMBA_DISABLE_JIT=1), and the reference the intrinsics are tested against ----

def _np_min(a, b):
    return np.where(a < b, a, b)


def _np_max(a, b):
    return np.where(a > b, a, b)


def split_cubic_lanes_python(points, dirs, box):
    """numpy version of split_cubic_lanes."""
    half = points.dtype.type(0.5)
    along_v = dirs != 0
    for c in range(3):
        pts = [points[c, k, :LANES].copy() for k in range(16)]
        passes = [_split_pass(lambda a, b: (a + b) * half, _np_min, _np_max, pts, along_u) for along_u in (True, False)]
        for h in range(2):
            column = slice(h * LANES, (h + 1) * LANES)
            for row, op in ((c, _np_min), (3 + c, _np_max)):
                box[row, column] = np.where(along_v, passes[1][2][(h, op)], passes[0][2][(h, op)])
            for k in range(16):
                points[c, k, column] = np.where(along_v, passes[1][h][k], passes[0][h][k])


def _slab_python(lo, hi, lray, t_in, t_out):
    fail = np.zeros(LANES, bool)
    for c in range(3):
        a0 = lo[c] - lray[R_O + c]
        b0 = hi[c] - lray[R_O + c]
        flat = lray[R_D + c] == 0.0
        fail |= flat & ((a0 > 0.0) | (b0 < 0.0))
        with np.errstate(invalid='ignore', over='ignore'):  # (a flat axis's products are not used)
            a = a0 * lray[R_INV + c]
            b = b0 * lray[R_INV + c]
            a, b = np.where(a > b, b, a), np.where(a > b, a, b)
            b = b + np.abs(b) * T_SLACK
        t_in = np.where(~flat & (a > t_in), a, t_in)
        t_out = np.where(~flat & (b < t_out), b, t_out)
    return t_in, t_out, ~fail & (t_in <= t_out)


def _direction_python(points, mi, lray, step, split_mode, all_edges):
    """subpatch.split_direction for integral bicubics or bilinears (all_edges: CUBIC_EDGES,
    LINEAR_EDGES), or the other direction than last time where the box did not shrink."""
    corner = {k: [points[c, k, :LANES].astype(np.float64) for c in range(3)] for edges in all_edges
              for edge in edges for k in edge}
    lengths = []
    for edges in all_edges:  # u edges, v edges
        longest = np.zeros(LANES)
        for b, a in edges:
            ex, ey, ez = (corner[b][c] - corner[a][c] for c in range(3))
            if split_mode == SPLIT_CROSS:
                dx, dy, dz = (lray[R_D + c] for c in range(3))
                ex, ey, ez = ey * dz - ez * dy, ez * dx - ex * dz, ex * dy - ey * dx
            longest = np.maximum(longest, ex * ex + ey * ey + ez * ez)
        lengths.append(longest)
    last = mi[I_LAST, :LANES]
    other = np.where(last >= 0, 1 - last, 0)
    return np.where(step[S_SHRANK] != 0.0, np.where(lengths[0] > lengths[1], 0, 1), other).astype(np.int32)


def split_linear_lanes_python(points, dirs, box):
    """numpy version of bezier._split_linear for each lane's bilinear (points 0..3), in columns."""
    half = points.dtype.type(0.5)
    along_v = dirs != 0
    pairs = np.where(along_v[None, :], np.array([[0], [2], [1], [3]]), np.array([[0], [1], [2], [3]]))
    lanes = np.arange(LANES)
    for c in range(3):
        pa0, pa1, pb0, pb1 = (points[c, pairs[n], lanes].copy() for n in range(4))
        m0 = (pa0 + pa1) * half
        m1 = (pb0 + pb1) * half
        for h, values in enumerate(((pa0, m0, pb0, m1), (m0, pa1, m1, pb1))):
            for n in range(4):
                points[c, pairs[n], lanes + LANES * h] = values[n]
            lo = hi = values[0]
            for v in values[1:]:  # numba's min and max of several: the first of equals stays
                lo = np.where(v < lo, v, lo)
                hi = np.where(v > hi, v, hi)
            box[c, LANES * h:LANES * (h + 1)] = lo
            box[3 + c, LANES * h:LANES * (h + 1)] = hi


def halve_lanes_python(points, dirs, box, mf, mi, lray, step, levels, sub_scale, split_mode, linear=False):
    """numpy version of halve_lanes (linear: halve_lanes_linear's)."""
    low, high = slice(0, LANES), slice(LANES, COLUMNS)
    dirs[:] = _direction_python(points, mi, lray, step, split_mode, LINEAR_EDGES if linear else CUBIC_EDGES)
    along_v = dirs != 0
    for c in range(3):  # subpatch.split_bounds
        bound = mf[M_E + c, low] + levels * np.maximum(np.abs(box[c, low]), np.abs(box[3 + c, low]))
        mf[M_E + c, high] = bound
        mf[M_E + c, low] = bound
    (split_linear_lanes_python if linear else split_cubic_lanes_python)(points, dirs, box)
    for r in range(4):  # subpatch.split_intervals
        mf[M_U0 + r, high] = mf[M_U0 + r, low]
    mid_u = 0.5 * (mf[M_U0, low] + mf[M_U1, low])
    mid_v = 0.5 * (mf[M_V0, low] + mf[M_V1, low])
    mf[M_U1, low] = np.where(along_v, mf[M_U1, low], mid_u)
    mf[M_U0, high] = np.where(along_v, mf[M_U0, high], mid_u)
    mf[M_V1, low] = np.where(along_v, mid_v, mf[M_V1, low])
    mf[M_V0, high] = np.where(along_v, mid_v, mf[M_V0, high])
    for r in (M_OX, M_OX + 1, M_OX + 2, M_GULP):
        mf[r, high] = mf[r, low]
    start, stop = mf[M_TIN, low].copy(), mf[M_TOUT, low].copy()  # the parent's interval
    mi[I_TRIM, high] = mi[I_TRIM, low]  # search_steps.finish_halves' places in the tree
    for column in (high, low):
        mi[I_DEPTH, column] = mi[I_DEPTH, low] + 1
        mi[I_STALLED, column] = np.where(step[S_SHRANK] != 0.0, 0, 1)
        mi[I_LAST, column] = dirs
    verdicts = []
    for h, column in enumerate((low, high)):  # widen, M_DPAR, open_box
        mag = np.zeros(LANES)
        for k in range(6):
            mag = np.maximum(mag, np.abs(box[k, column]))
        mf[M_MAG, column] = mag
        sub = mag * sub_scale
        widening = np.zeros(LANES)
        for c in range(3):
            e = mf[M_E + c, column] if sub_scale == 0.0 else mf[M_E + c, column] + sub
            box[c, column] -= e
            box[3 + c, column] += e
            widening = widening + 2.0 * e
        mf[M_W, column] = widening
        mf[M_D, column] = ((box[3, column] - box[0, column]) + (box[4, column] - box[1, column])
                           + (box[5, column] - box[2, column]))
        mf[M_DPAR, column] = step[S_DCRIT]
        lo = [box[c, column] + mf[M_OX + c, column] for c in range(3)]
        hi = [box[3 + c, column] + mf[M_OX + c, column] for c in range(3)]
        t_in, t_out, meets = _slab_python(lo, hi, lray, start, stop)
        mf[M_TIN, column] = t_in
        mf[M_TOUT, column] = t_out
        alive = meets & (t_out >= lray[LR_REACH]) & (t_in < lray[LR_LIMIT])
        odd = meets & (((t_in == lray[LR_LIMIT]) & (t_out >= lray[LR_REACH])) | (t_in <= lray[LR_TMIN]))
        verdicts.append((meets, alive, odd))
    (met_a, alive_a, odd_a), (met_b, alive_b, odd_b) = verdicts
    special = odd_a | odd_b | (met_a & met_b & (alive_a | alive_b))
    bits = 0
    for lane in range(LANES):
        for k, flag in enumerate((met_a, met_b, alive_a, alive_b, special)):
            if flag[lane]:
                bits |= 1 << (LANES * k + lane)
    return np.uint64(bits)


def judge_lanes_python(box, mf, mi, lray, step, grid0, grid1, grid2, criterion, param, max_depth, shrink_factor,
                       rational, cumulative):
    """numpy version of judge_lanes."""
    grid = (grid0, grid1, grid2)
    low = slice(0, LANES)
    d = mf[M_D, low]
    box_limit = GRID_PREFILTER * mf[M_GULP, low]
    if criterion == FIXED:
        box_limit = np.maximum(box_limit, param)
    limit = box_limit
    detail = np.zeros(LANES)
    if criterion == ADAPTIVE:
        detail = lray[LR_T0] + lray[LR_DT] * mf[M_TIN, low]
        limit = np.maximum(limit, detail)
    total = np.zeros(LANES)
    for c in range(3):
        lo = box[c, low] + mf[M_OX + c, low]
        hi = box[3 + c, low] + mf[M_OX + c, low]
        if grid[c] > 0.0:
            inv = 1.0 / grid[c]
            total = total + (np.ceil(hi * inv) * grid[c] - np.floor(lo * inv) * grid[c])
        else:
            total = total + (hi - lo)
    d_crit = np.where(d <= limit, total, d)
    d_box = np.where(d <= box_limit, total, d)
    stop = mi[I_DEPTH, low] >= max_depth
    if criterion == FIXED:
        stop |= d_crit <= param
    elif criterion == ADAPTIVE:
        stop |= d_crit <= detail
    shrank = (d_box < mf[M_DPAR, low] * shrink_factor) & (d > 1.0625 * mf[M_W, low])
    stop |= (mf[M_U0, low] == mf[M_U1, low]) | (mf[M_V0, low] == mf[M_V1, low])
    stop |= ~shrank & (mi[I_STALLED, low] == 1) & ~(rational & (d > limit))
    step[S_DCRIT] = d_box
    step[S_SHRANK] = np.where(shrank, 1.0, 0.0)
    ext = box[3, low] - box[0, low]
    for c in (1, 2):  # search_steps.tightening
        ext = np.where(box[3 + c, low] - box[c, low] > ext, box[3 + c, low] - box[c, low], ext)
    tight = ((mf[M_E, low] + mf[M_E + 1, low] + mf[M_E + 2, low]) * REFINE > ext) & cumulative
    tight |= ext * RECENTRE < mf[M_MAG, low]
    return np.uint64(sum(1 << lane for lane in range(LANES) if stop[lane])
                     | sum(1 << (LANES + lane) for lane in range(LANES) if tight[lane]))


def keep_high_lanes_python(points, box, mf, mi, take):
    """numpy version of keep_high_lanes."""
    for lane in range(LANES):
        if (int(take) >> lane) & 1:
            for arr in (box, mf, mi):
                arr[:, lane] = arr[:, LANES + lane]
            points[:, :, lane] = points[:, :, LANES + lane]


# ---- the intrinsics ----

def _is_c(arr, ndim, dtypes) -> bool:
    return isinstance(arr, types.Array) and arr.ndim == ndim and arr.layout == 'C' and arr.dtype in dtypes


class _Columns:
    """Vector access to rows of (rows, COLUMNS) C arrays: a row's LANES low or high columns."""

    def __init__(self, context, builder, signature, args):
        self.context, self.builder, self.signature, self.args = context, builder, signature, args

    def base(self, k, elem):
        arr = self.context.make_array(self.signature.args[k])(self.context, self.builder, self.args[k])
        return self.builder.bitcast(arr.data, ir.VectorType(elem, LANES).as_pointer())

    def at(self, ptr, row, high):
        return self.builder.gep(ptr, [ir.IntType(32)(2 * row + high)])

    def load(self, ptr, row, high=0):
        return self.builder.load(self.at(ptr, row, high), align=8)

    def store(self, value, ptr, row, high=0):
        self.builder.store(value, self.at(ptr, row, high), align=8)

    def splat(self, value, elem=ir.DoubleType()):
        """A scalar in every lane."""
        vec = ir.VectorType(elem, LANES)
        one = self.builder.insert_element(ir.Constant(vec, ir.Undefined), value, ir.IntType(32)(0))
        return self.builder.shuffle_vector(one, ir.Constant(vec, ir.Undefined),
                                           ir.Constant(ir.VectorType(ir.IntType(32), LANES), [0] * LANES))

    def const(self, value):
        return ir.Constant(ir.VectorType(ir.DoubleType(), LANES), [ir.Constant(ir.DoubleType(), value)] * LANES)

    def row(self, ptr, k):
        """Row k of a (rows, LANES) array (the lanes' rays, a halving's inputs)."""
        return self.builder.load(self.builder.gep(ptr, [ir.IntType(32)(k)]), align=8)


def _ops(builder, vec):
    def vmin(a, b):
        return builder.select(builder.fcmp_ordered('<', a, b), a, b)

    def vmax(a, b):
        return builder.select(builder.fcmp_ordered('>', a, b), a, b)

    def fabs(value):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vec, [vec]),
                                            f'llvm.fabs.v{LANES}f{64 if vec.element == ir.DoubleType() else 32}')
        return builder.call(fn, [value])
    return vmin, vmax, fabs


def _emit_split(cols, elem, pts, boxes, along_v):
    """IR of split_cubic_lanes: points and box rows (both (..., COLUMNS)) from the lanes' points.
    A lane halving along v first has its points transposed (point i + 4 j to j + 4 i, a select a
    point), so that one pass along u serves every lane: its lines are then the v pass's columns,
    point for point and in the same order, so the midpoints and the bounds' order of reduction are
    the v pass's too; the halves are transposed back as they are stored."""
    builder = cols.builder
    vf = ir.VectorType(elem, LANES)
    vd = ir.VectorType(ir.DoubleType(), LANES)
    half = ir.Constant(vf, [ir.Constant(elem, 0.5)] * LANES)
    vmin, vmax, _ = _ops(builder, vf)
    size = cols.context.get_abi_sizeof(elem)

    def mid(a, b):
        return builder.fmul(builder.fadd(a, b), half)

    def transposed(points):
        return [builder.select(along_v, points[4 * (k % 4) + k // 4], points[k]) for k in range(16)]

    for c in range(3):
        pts_c = transposed([builder.load(cols.at(pts, 16 * c + k, 0), align=size) for k in range(16)])
        low, high, bounds = _split_pass(mid, vmin, vmax, pts_c, True)
        for h, half_points in enumerate((low, high)):
            for k, value in enumerate(transposed(half_points)):
                builder.store(value, cols.at(pts, 16 * c + k, h), align=size)
            for row, op in ((c, vmin), (3 + c, vmax)):
                value = bounds[(h, op)]
                cols.store(builder.fpext(value, vd) if elem != ir.DoubleType() else value, boxes, row, h)


def _emit_split_linear(cols, elem, pts, boxes, along_v):
    """IR of bezier._split_linear for each lane's bilinear (points 0..3): a lane halving along v
    has points 1 and 2 swapped on the way in and out, so one pass along u serves every lane."""
    builder = cols.builder
    vf = ir.VectorType(elem, LANES)
    vd = ir.VectorType(ir.DoubleType(), LANES)
    half = ir.Constant(vf, [ir.Constant(elem, 0.5)] * LANES)
    size = cols.context.get_abi_sizeof(elem)

    def swapped(p):
        return [p[0], builder.select(along_v, p[2], p[1]), builder.select(along_v, p[1], p[2]), p[3]]

    for c in range(3):
        pa0, pa1, pb0, pb1 = swapped([builder.load(cols.at(pts, 16 * c + k, 0), align=size) for k in range(4)])
        m0 = builder.fmul(builder.fadd(pa0, pa1), half)
        m1 = builder.fmul(builder.fadd(pb0, pb1), half)
        for h, values in enumerate(((pa0, m0, pb0, m1), (m0, pa1, m1, pb1))):
            for k, value in enumerate(swapped(list(values))):
                builder.store(value, cols.at(pts, 16 * c + k, h), align=size)
            lo = hi = values[0]
            for v in values[1:]:  # numba's min and max of several: the first of equals stays
                lo = builder.select(builder.fcmp_ordered('<', v, lo), v, lo)
                hi = builder.select(builder.fcmp_ordered('>', v, hi), v, hi)
            for row, value in ((c, lo), (3 + c, hi)):
                cols.store(builder.fpext(value, vd) if elem != ir.DoubleType() else value, boxes, row, h)


def split_cubic_lanes(typingctx, points, dirs, box):
    """Halve each lane's bicubic (points: (3, 16, COLUMNS), columns 0..LANES-1; the low half stays
    there, the high half goes to column LANES + lane) in its direction (dirs: (LANES,) int32, 0 u,
    1 v); both halves' control boxes into the same columns of box ((6, COLUMNS) float64)."""
    if not (_is_c(points, 3, (types.float32, types.float64)) and _is_c(dirs, 1, (types.int32,))
            and _is_c(box, 2, (types.float64,))):
        return None
    sig = types.void(points, dirs, box)

    def codegen(context, builder, signature, args):
        cols = _Columns(context, builder, signature, args)
        elem = context.get_value_type(signature.args[0].dtype)
        vi = ir.VectorType(ir.IntType(32), LANES)
        along_v = builder.icmp_signed('!=', builder.load(cols.base(1, ir.IntType(32)), align=4),
                                      ir.Constant(vi, [0] * LANES))
        _emit_split(cols, elem, cols.base(0, elem), cols.base(2, ir.DoubleType()), along_v)
        return context.get_dummy_value()

    return sig, codegen


def _make_halve(linear: bool):
    def halve_lanes(typingctx, points, dirs, box, mf, mi, lray, step, levels, sub_scale, split_mode):
        """A halving of every lane's bicubic, its column of the lane slots (points, box, mf) into the
        low half (in place) and the high half (column LANES + lane), as the single ray's steps make
        it: search_steps.halving_direction (into dirs; split_mode: options.SPLIT_CODE's),
        subpatch.split_bounds (levels: the split's rounding per unit of magnitude), the split in
        dirs' direction, split_intervals, the halves' widening (sub_scale: PatchInfo.sub_scale) and
        M_DPAR (step[S_DCRIT]), their depth, stall flag (step[S_SHRANK]), direction and trim state
        (mi), and each half's slab test against its lane's ray (lray: (LANE_RAY, LANES)) within the
        parent's interval (M_TIN, M_TOUT, then the halves'). Returns (uint64) the lanes (LANES bits
        each, lowest first) where the ray meets the low half, the high half, where the low half
        stays a candidate (search_steps.open_slot: it reaches R_REACH and is entered before the
        search's limit), the high half does, and where the lane needs the single ray's own verdict
        (an entry at the limit itself, a box holding the origin, or the hull tests: both halves met
        and one alive)."""
        if not (_is_c(points, 3, (types.float32, types.float64)) and _is_c(dirs, 1, (types.int32,))
                and all(_is_c(a, 2, (types.float64,)) for a in (box, mf, lray, step)) and _is_c(mi, 2, (types.int32,))):
            return None
        sig = types.uint64(points, dirs, box, mf, mi, lray, step, types.float64, types.float64, types.int64)

        def codegen(context, builder, signature, args):
            cols = _Columns(context, builder, signature, args)
            double = ir.DoubleType()
            elem = context.get_value_type(signature.args[0].dtype)
            vd = ir.VectorType(double, LANES)
            vi = ir.VectorType(ir.IntType(32), LANES)
            pts, boxes, meta = cols.base(0, elem), cols.base(2, double), cols.base(3, double)
            rays, steps = cols.base(5, double), cols.base(6, double)
            vmin, vmax, fabs = _ops(builder, vd)
            splat, const = cols.splat, cols.const

            def ray_row(k):
                return cols.row(rays, k)

            def step_row(k):
                return cols.row(steps, k)

            levels_v, sub_scale_v = splat(args[7]), splat(args[8])
            # search_steps.halving_direction: split_direction's edge lengths (corners 0, 3, 12, 15 in
            # float64), or the other direction than last time where the box did not shrink
            all_edges = LINEAR_EDGES if linear else CUBIC_EDGES
            corner = {k: [builder.fpext(builder.load(cols.at(pts, 16 * c + k, 0), align=4), vd)
                          if elem != double else builder.load(cols.at(pts, 16 * c + k, 0), align=8) for c in range(3)]
                      for edges in all_edges for edge in edges for k in edge}
            cross = builder.icmp_signed('==', args[9], ir.Constant(ir.IntType(64), SPLIT_CROSS))
            d = [ray_row(R_D + c) for c in range(3)]
            lengths = []
            for edges in all_edges:  # u edges, v edges
                longest = const(0.0)
                for b_k, a_k in edges:
                    ex, ey, ez = (builder.fsub(corner[b_k][c], corner[a_k][c]) for c in range(3))
                    cx = builder.fsub(builder.fmul(ey, d[2]), builder.fmul(ez, d[1]))
                    cy = builder.fsub(builder.fmul(ez, d[0]), builder.fmul(ex, d[2]))
                    cz = builder.fsub(builder.fmul(ex, d[1]), builder.fmul(ey, d[0]))
                    ex, ey, ez = (builder.select(cross, crossed, plain)
                                  for crossed, plain in ((cx, ex), (cy, ey), (cz, ez)))
                    length = builder.fadd(builder.fadd(builder.fmul(ex, ex), builder.fmul(ey, ey)),
                                          builder.fmul(ez, ez))
                    longest = vmax(longest, length)
                lengths.append(longest)
            i32 = ir.IntType(32)
            by_length = builder.select(builder.fcmp_ordered('>', lengths[0], lengths[1]), ir.Constant(vi, [0] * LANES),
                                       ir.Constant(vi, [1] * LANES))
            mis = cols.base(4, i32)
            last = cols.load(mis, I_LAST)
            other = builder.select(builder.icmp_signed('>=', last, ir.Constant(vi, [0] * LANES)),
                                   builder.sub(ir.Constant(vi, [1] * LANES), last), ir.Constant(vi, [0] * LANES))
            shrank = builder.fcmp_ordered('!=', step_row(S_SHRANK), const(0.0))
            dirs = builder.select(shrank, by_length, other)
            builder.store(dirs, cols.base(1, i32), align=4)
            along_v = builder.icmp_signed('!=', dirs, ir.Constant(vi, [0] * LANES))
            for c in range(3):  # subpatch.split_bounds, from the parent's (widened) box
                bound = builder.fadd(cols.load(meta, M_E + c), builder.fmul(
                    levels_v, vmax(fabs(cols.load(boxes, c)), fabs(cols.load(boxes, 3 + c)))))
                cols.store(bound, meta, M_E + c, 1)
                cols.store(bound, meta, M_E + c, 0)
            (_emit_split_linear if linear else _emit_split)(cols, elem, pts, boxes, along_v)
            u0, u1, v0, v1 = (cols.load(meta, r) for r in (M_U0, M_U1, M_V0, M_V1))  # subpatch.split_intervals
            half = const(0.5)
            mid_u = builder.fmul(half, builder.fadd(u0, u1))
            mid_v = builder.fmul(half, builder.fadd(v0, v1))
            cols.store(builder.select(along_v, u0, mid_u), meta, M_U0, 1)
            cols.store(builder.select(along_v, u1, mid_u), meta, M_U1, 0)
            cols.store(u1, meta, M_U1, 1)
            cols.store(builder.select(along_v, mid_v, v0), meta, M_V0, 1)
            cols.store(builder.select(along_v, mid_v, v1), meta, M_V1, 0)
            cols.store(v1, meta, M_V1, 1)
            for r in (M_OX, M_OX + 1, M_OX + 2, M_GULP):
                cols.store(cols.load(meta, r), meta, r, 1)
            start, stop = cols.load(meta, M_TIN), cols.load(meta, M_TOUT)  # the parent's interval
            mis = cols.base(4, i32)  # search_steps.finish_halves' places in the tree
            cols.store(cols.load(mis, I_TRIM), mis, I_TRIM, 1)
            depth = builder.add(cols.load(mis, I_DEPTH), ir.Constant(vi, [1] * LANES))
            stalled = builder.select(shrank, ir.Constant(vi, [0] * LANES), ir.Constant(vi, [1] * LANES))
            for h in range(2):
                cols.store(depth, mis, I_DEPTH, h)
                cols.store(stalled, mis, I_STALLED, h)
                cols.store(dirs, mis, I_LAST, h)
            unshared = builder.fcmp_ordered('!=', sub_scale_v, const(0.0))
            verdicts = []
            for h in range(2):  # search_steps.finish_halves' widening and M_DPAR, subpatch.open_box
                corners = [cols.load(boxes, k, h) for k in range(6)]
                mag = const(0.0)
                for k in range(6):
                    mag = vmax(mag, fabs(corners[k]))
                cols.store(mag, meta, M_MAG, h)
                sub = builder.fmul(mag, sub_scale_v)
                widening = const(0.0)
                for c in range(3):
                    e = cols.load(meta, M_E + c, h)
                    e = builder.select(unshared, builder.fadd(e, sub), e)
                    corners[c] = builder.fsub(corners[c], e)
                    corners[3 + c] = builder.fadd(corners[3 + c], e)
                    widening = builder.fadd(widening, builder.fmul(const(2.0), e))
                for k in range(6):
                    cols.store(corners[k], boxes, k, h)
                cols.store(widening, meta, M_W, h)
                cols.store(builder.fadd(builder.fadd(builder.fsub(corners[3], corners[0]),
                                                     builder.fsub(corners[4], corners[1])),
                                        builder.fsub(corners[5], corners[2])), meta, M_D, h)
                cols.store(step_row(S_DCRIT), meta, M_DPAR, h)
                t_in, t_out = start, stop
                fail = ir.Constant(ir.VectorType(ir.IntType(1), LANES), [0] * LANES)
                for c in range(3):  # ray.slab_at's operations, as lanes._slab_vectors
                    offset = cols.load(meta, M_OX + c, h)
                    origin = ray_row(R_O + c)
                    lo = builder.fsub(builder.fadd(corners[c], offset), origin)
                    hi = builder.fsub(builder.fadd(corners[3 + c], offset), origin)
                    flat = builder.fcmp_ordered('==', ray_row(R_D + c), const(0.0))
                    outside = builder.or_(builder.fcmp_ordered('>', lo, const(0.0)),
                                          builder.fcmp_ordered('<', hi, const(0.0)))
                    fail = builder.or_(fail, builder.and_(flat, outside))
                    inv = ray_row(R_INV + c)
                    a = builder.fmul(lo, inv)
                    b = builder.fmul(hi, inv)
                    swap = builder.fcmp_ordered('>', a, b)
                    a, b = builder.select(swap, b, a), builder.select(swap, a, b)
                    b = builder.fadd(b, builder.fmul(fabs(b), const(T_SLACK)))
                    sloped = builder.not_(flat)
                    t_in = builder.select(builder.and_(sloped, builder.fcmp_ordered('>', a, t_in)), a, t_in)
                    t_out = builder.select(builder.and_(sloped, builder.fcmp_ordered('<', b, t_out)), b, t_out)
                cols.store(t_in, meta, M_TIN, h)
                cols.store(t_out, meta, M_TOUT, h)
                meets = builder.and_(builder.not_(fail), builder.fcmp_ordered('<=', t_in, t_out))
                limit, reach = ray_row(LR_LIMIT), ray_row(LR_REACH)
                reaching = builder.fcmp_ordered('>=', t_out, reach)
                alive = builder.and_(builder.and_(meets, reaching), builder.fcmp_ordered('<', t_in, limit))
                odd = builder.and_(meets, builder.or_(builder.and_(builder.fcmp_ordered('==', t_in, limit), reaching),
                                                      builder.fcmp_ordered('<=', t_in, ray_row(LR_TMIN))))
                verdicts.append((meets, alive, odd))
            (met_a, alive_a, odd_a), (met_b, alive_b, odd_b) = verdicts
            special = builder.or_(builder.or_(odd_a, odd_b),
                                  builder.and_(builder.and_(met_a, met_b), builder.or_(alive_a, alive_b)))
            bits = ir.Constant(ir.IntType(64), 0)
            for k, flag in enumerate((met_a, met_b, alive_a, alive_b, special)):
                flag = builder.zext(builder.bitcast(flag, ir.IntType(LANES)), ir.IntType(64))
                bits = builder.or_(bits, builder.shl(flag, ir.Constant(ir.IntType(64), LANES * k)))
            return bits

        return sig, codegen

    halve_lanes.__name__ = halve_lanes.__qualname__ = 'halve_lanes_linear' if linear else 'halve_lanes'
    return halve_lanes


def judge_lanes(typingctx, box, mf, mi, lray, step, grid0, grid1, grid2, criterion, param, max_depth,
                shrink_factor, rational, cumulative):
    """search_steps.judge_known for every lane's current sub-patch (column lane) under the float,
    fixed or adaptive criterion (not mantissa, whose test is the ray's: judge_known), as it judges
    a slot: its grid box's L1 diameter (grid0..2: the leaf's grid steps) where the criteria need
    it. Writes each lane's box measure and whether the box shrank (step[S_DCRIT], step[S_SHRANK]);
    returns bit lane where the lane's sub-patch meets the criterion, LANES + lane where
    search_steps.tightening would tighten it (cumulative: PatchInfo.cumulative) (uint64)."""
    if not (all(_is_c(a, 2, (types.float64,)) for a in (box, mf, lray, step)) and _is_c(mi, 2, (types.int32,))):
        return None
    sig = types.uint64(box, mf, mi, lray, step, types.float64, types.float64, types.float64, types.int64,
                       types.float64, types.int64, types.float64, types.boolean, types.boolean)

    def codegen(context, builder, signature, args):
        cols = _Columns(context, builder, signature, args)
        double = ir.DoubleType()
        vd = ir.VectorType(double, LANES)
        vi = ir.VectorType(ir.IntType(32), LANES)
        boxes, meta, mis, rays, steps = (cols.base(0, double), cols.base(1, double), cols.base(2, ir.IntType(32)),
                                         cols.base(3, double), cols.base(4, double))
        vmin, vmax, _ = _ops(builder, vd)
        splat, const, row = cols.splat, cols.const, cols.row

        def rounded(name, value):
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vd, [vd]), f'llvm.{name}.v{LANES}f64')
            return builder.call(fn, [value])

        criterion, param = args[8], splat(args[9])
        is_fixed = builder.icmp_signed('==', criterion, ir.Constant(ir.IntType(64), FIXED))
        is_adaptive = builder.icmp_signed('==', criterion, ir.Constant(ir.IntType(64), ADAPTIVE))
        d = cols.load(meta, M_D)
        box_limit = builder.fmul(const(GRID_PREFILTER), cols.load(meta, M_GULP))
        box_limit = builder.select(is_fixed, vmax(box_limit, param), box_limit)
        detail = builder.fadd(row(rays, LR_T0), builder.fmul(row(rays, LR_DT), cols.load(meta, M_TIN)))
        limit = builder.select(is_adaptive, vmax(box_limit, detail), box_limit)
        total = const(0.0)
        for c in range(3):  # subpatch.grid_l1
            offset = cols.load(meta, M_OX + c)
            lo = builder.fadd(cols.load(boxes, c), offset)
            hi = builder.fadd(cols.load(boxes, 3 + c), offset)
            g = splat(args[5 + c])
            inv = builder.fdiv(const(1.0), g)
            snapped = builder.fsub(builder.fmul(rounded('ceil', builder.fmul(hi, inv)), g),
                                   builder.fmul(rounded('floor', builder.fmul(lo, inv)), g))
            on_grid = builder.fcmp_ordered('>', args[5 + c], ir.Constant(double, 0.0))
            total = builder.fadd(total, builder.select(on_grid, snapped, builder.fsub(hi, lo)))
        d_crit = builder.select(builder.fcmp_ordered('<=', d, limit), total, d)
        d_box = builder.select(builder.fcmp_ordered('<=', d, box_limit), total, d)
        false = ir.Constant(ir.VectorType(ir.IntType(1), LANES), [0] * LANES)
        depth = cols.load(mis, I_DEPTH)
        max_depth = builder.trunc(args[10], ir.IntType(32))
        max_depth_v = cols.splat(max_depth, ir.IntType(32))
        stop = builder.icmp_signed('>=', depth, max_depth_v)
        stop = builder.or_(stop, builder.and_(builder.fcmp_ordered('<=', d_crit, param),
                                              builder.select(is_fixed, builder.not_(false), false)))
        stop = builder.or_(stop, builder.and_(builder.fcmp_ordered('<=', d_crit, detail),
                                              builder.select(is_adaptive, builder.not_(false), false)))
        shrank = builder.and_(builder.fcmp_ordered('<', d_box, builder.fmul(cols.load(meta, M_DPAR), splat(args[11]))),
                              builder.fcmp_ordered('>', d, builder.fmul(const(1.0625), cols.load(meta, M_W))))
        spent = builder.or_(builder.fcmp_ordered('==', cols.load(meta, M_U0), cols.load(meta, M_U1)),
                            builder.fcmp_ordered('==', cols.load(meta, M_V0), cols.load(meta, M_V1)))
        stalled = builder.icmp_signed('==', cols.load(mis, I_STALLED), ir.Constant(vi, [1] * LANES))
        rational = builder.select(args[12], builder.not_(false), false)
        exempt = builder.and_(rational, builder.fcmp_ordered('>', d, limit))
        stop = builder.or_(builder.or_(stop, spent),
                           builder.and_(builder.and_(builder.not_(shrank), stalled), builder.not_(exempt)))
        builder.store(d_box, builder.gep(steps, [ir.IntType(32)(S_DCRIT)]), align=8)
        builder.store(builder.select(shrank, const(1.0), const(0.0)), builder.gep(steps, [ir.IntType(32)(S_SHRANK)]),
                      align=8)
        ext = builder.fsub(cols.load(boxes, 3), cols.load(boxes, 0))
        for c in (1, 2):  # search_steps.tightening (max of several: the first of equals stays)
            extent = builder.fsub(cols.load(boxes, 3 + c), cols.load(boxes, c))
            ext = builder.select(builder.fcmp_ordered('>', extent, ext), extent, ext)
        bound = builder.fadd(builder.fadd(cols.load(meta, M_E), cols.load(meta, M_E + 1)), cols.load(meta, M_E + 2))
        cumulative = builder.select(args[13], builder.not_(false), false)
        tight = builder.and_(builder.fcmp_ordered('>', builder.fmul(bound, const(REFINE)), ext), cumulative)
        tight = builder.or_(tight, builder.fcmp_ordered('<', builder.fmul(ext, const(RECENTRE)),
                                                        cols.load(meta, M_MAG)))
        stops = builder.zext(builder.bitcast(stop, ir.IntType(LANES)), ir.IntType(64))
        tights = builder.zext(builder.bitcast(tight, ir.IntType(LANES)), ir.IntType(64))
        return builder.or_(stops, builder.shl(tights, ir.Constant(ir.IntType(64), LANES)))

    return sig, codegen


def keep_high_lanes(typingctx, points, box, mf, mi, take):
    """Where bit lane of `take` is set, column LANES + lane of the lane slots into column lane."""
    if not (_is_c(points, 3, (types.float32, types.float64)) and _is_c(box, 2, (types.float64,))
            and _is_c(mf, 2, (types.float64,)) and _is_c(mi, 2, (types.int32,))):
        return None
    sig = types.void(points, box, mf, mi, types.uint64)

    def codegen(context, builder, signature, args):
        cols = _Columns(context, builder, signature, args)
        mask = builder.bitcast(builder.trunc(args[4], ir.IntType(LANES)), ir.VectorType(ir.IntType(1), LANES))
        elem = context.get_value_type(signature.args[0].dtype)
        for k, elem_k, rows in ((0, elem, 48), (1, ir.DoubleType(), 6), (2, ir.DoubleType(), MF_LEN),
                                (3, ir.IntType(32), MI_LEN)):
            base = cols.base(k, elem_k)
            for row in range(rows):
                cols.store(builder.select(mask, cols.load(base, row, 1), cols.load(base, row, 0)), base, row, 0)
        return context.get_dummy_value()

    return sig, codegen


if config.DISABLE_JIT:
    split_cubic_lanes = split_cubic_lanes_python  # noqa: F811
    halve_lanes = halve_lanes_python  # noqa: F811
    halve_lanes_linear = functools.partial(halve_lanes_python, linear=True)
    judge_lanes = judge_lanes_python  # noqa: F811
    keep_high_lanes = keep_high_lanes_python  # noqa: F811
else:
    split_cubic_lanes = intrinsic(split_cubic_lanes)  # noqa: F811
    halve_lanes = intrinsic(_make_halve(False))
    halve_lanes_linear = intrinsic(_make_halve(True))
    judge_lanes = intrinsic(judge_lanes)  # noqa: F811
    keep_high_lanes = intrinsic(keep_high_lanes)  # noqa: F811
