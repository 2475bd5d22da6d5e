"""The bicubic de Casteljau split and restriction in 4-wide vectors, the bicubic hull's extent across
a plane in 16-wide ones, and a bicubic's tangents (LLVM IR through numba intrinsics).

Numba compiles the scalar split to scalar instructions (it leaves LLVM's SLP vectoriser off),
and a split is a third of the search. Here the 4 x 4 control points of one coordinate are four
vectors, one per row of constant v (points k = 4 j + i): halving in v runs the same lerps on
whole rows; halving in u transposes first, so each vector holds a column. The arithmetic is
the scalar split's, lane by lane: (a + b) * 0.5 in the buffer's dtype, no fused or reordered
operations, so results are bit-identical (tests/test_bezier.py checks).

The hull test (hull.hull_off_plane) measures each of a slot's 16 control points across a
plane through the ray: here the 16 points are one vector per coordinate, converted to float64,
and x n0 + y n1 + z n2 is formed lane by lane as the scalar loop forms it; the least and greatest
value are exact (min and max do not round; which of two equal zeros comes out cannot matter
to the test, which adds them to an offset and compares), a NaN skipped as the loop's min and max
skip it.

A bicubic's float64 restriction to a parameter rectangle (restrict_cubic, for subpatch.refine)
runs bezier._restrict_line's lerps on four lines at once: the rows' points transposed into
columns for the lines in u, back into rows for the lines in v; each of a line's two stages is
always computed and kept where the scalar code's test (t0 > 0, t1 < 1) would have run it.

The hit normal's tangents (bicubic_tangents) hold a point's x, y and z in the lanes of one
vector: each lane sums its coordinate's terms in bezier.tangents' order, so the three sums are
the scalar ones, formed side by side.

Intrinsics cannot run in Python, so with NUMBA_DISABLE_JIT=1 the same names are bound to
numpy versions that do the same operations in the same order (split_u_cubic_python).
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import config
from numba.core import cgutils, types
from numba.extending import intrinsic

_TRANSPOSE_LOW = [0, 4, 1, 5]
_TRANSPOSE_HIGH = [2, 6, 3, 7]


def _shuffle(builder, a, b, lanes):
    return builder.shuffle_vector(a, b, ir.Constant(ir.VectorType(ir.IntType(32), len(lanes)), lanes))


def _transpose(builder, rows):
    """4 x 4 transpose of four 4-lane vectors."""
    r0, r1, r2, r3 = rows
    t0 = _shuffle(builder, r0, r1, _TRANSPOSE_LOW)
    t1 = _shuffle(builder, r0, r1, _TRANSPOSE_HIGH)
    t2 = _shuffle(builder, r2, r3, _TRANSPOSE_LOW)
    t3 = _shuffle(builder, r2, r3, _TRANSPOSE_HIGH)
    return [_shuffle(builder, t0, t2, [0, 1, 4, 5]), _shuffle(builder, t0, t2, [2, 3, 6, 7]),
            _shuffle(builder, t1, t3, [0, 1, 4, 5]), _shuffle(builder, t1, t3, [2, 3, 6, 7])]


def _min(builder, a, b):
    return builder.select(builder.fcmp_ordered('<', a, b), a, b)


def _max(builder, a, b):
    return builder.select(builder.fcmp_ordered('>', a, b), a, b)


def _reduce(builder, op, vectors):
    """op over every lane of the vectors, as a scalar."""
    acc = vectors[0]
    for v in vectors[1:]:
        acc = op(builder, acc, v)
    acc = op(builder, acc, _shuffle(builder, acc, acc, [2, 3, 0, 1]))
    acc = op(builder, acc, _shuffle(builder, acc, acc, [1, 0, 3, 2]))
    return builder.extract_element(acc, ir.IntType(32)(0))


def _make_split(along_u: bool):
    def split(typingctx, buf, src, dst, box):
        if not (isinstance(buf, types.Array) and buf.ndim == 3 and buf.layout == 'C'
                and buf.dtype in (types.float32, types.float64)
                and isinstance(box, types.Array) and box.ndim == 2 and box.dtype == types.float64):
            return None
        sig = types.void(buf, src, dst, box)

        def codegen(context, builder, signature, args):
            buf_ty, src_ty, dst_ty, box_ty = signature.args
            buf_v, src_v, dst_v, box_v = args
            src_i = context.cast(builder, src_v, src_ty, types.intp)
            dst_i = context.cast(builder, dst_v, dst_ty, types.intp)
            points = context.make_array(buf_ty)(context, builder, buf_v)
            boxes = context.make_array(box_ty)(context, builder, box_v)
            elem = context.get_value_type(buf_ty.dtype)
            vec = ir.VectorType(elem, 4)
            half = ir.Constant(vec, [ir.Constant(elem, 0.5)] * 4)
            align = context.get_abi_sizeof(elem)

            def item(arr, arr_ty, *indices):
                return cgutils.get_item_pointer2(context, builder, arr.data, cgutils.unpack_tuple(builder, arr.shape),
                                                 cgutils.unpack_tuple(builder, arr.strides), arr_ty.layout,
                                                 [context.get_constant(types.intp, k) if isinstance(k, int) else k
                                                  for k in indices])

            def rows_at(slot, c):
                base = builder.bitcast(item(points, buf_ty, slot, c, 0), vec.as_pointer())
                return [builder.gep(base, [ir.IntType(64)(j)]) for j in range(4)]

            def lerp(a, b):
                return builder.fmul(builder.fadd(a, b), half)

            def store_box(slot, c, lo, hi):
                for k, value in ((c, lo), (3 + c, hi)):
                    if elem != ir.DoubleType():
                        value = builder.fpext(value, ir.DoubleType())
                    builder.store(value, item(boxes, box_ty, slot, k))

            for c in range(3):
                src_rows = rows_at(src_i, c)
                dst_rows = rows_at(dst_i, c)
                p = [builder.load(ptr, align=align) for ptr in src_rows]
                if along_u:
                    p = _transpose(builder, p)
                q0, q1, q2 = lerp(p[0], p[1]), lerp(p[1], p[2]), lerp(p[2], p[3])
                s0, s1 = lerp(q0, q1), lerp(q1, q2)
                mid = lerp(s0, s1)
                low = [p[0], q0, s0, mid]
                high = [mid, s1, q2, p[3]]
                store_box(src_i, c, _reduce(builder, _min, low), _reduce(builder, _max, low))
                store_box(dst_i, c, _reduce(builder, _min, high), _reduce(builder, _max, high))
                if along_u:
                    low, high = _transpose(builder, low), _transpose(builder, high)
                for ptr, value in zip(src_rows, low):
                    builder.store(value, ptr, align=align)
                for ptr, value in zip(dst_rows, high):
                    builder.store(value, ptr, align=align)
            return context.get_dummy_value()

        return sig, codegen

    split.__name__ = split.__qualname__ = 'split_u_cubic' if along_u else 'split_v_cubic'
    return split


def _casteljau3(builder, p, t):
    """de Casteljau's triangle of four cubics at t, lane by lane: each lerp a + t (b - a), as
    bezier._restrict_line forms it; returns (a0, a2, b0, b1, c0) of levels 1, 2 and 3."""
    def lerp(a, b):
        return builder.fadd(a, builder.fmul(t, builder.fsub(b, a)))
    a0, a1, a2 = lerp(p[0], p[1]), lerp(p[1], p[2]), lerp(p[2], p[3])
    b0, b1 = lerp(a0, a1), lerp(a1, a2)
    return a0, a2, b0, b1, lerp(b0, b1)


def _restrict4(builder, p, t0, t1):
    """bezier._restrict_line for four cubics at once (vector i holds their points i): the right
    part at t0 where t0 > 0, then the left part at (t1 - t0) / (1 - t0) where t1 < 1 (both formed,
    the scalar test selecting)."""
    double = ir.DoubleType()
    vec = ir.VectorType(double, 4)

    def splat(x):
        lane = builder.insert_element(ir.Constant(vec, ir.Undefined), x, ir.IntType(32)(0))
        return _shuffle(builder, lane, lane, [0] * 4)

    _, a2, _, b1, c0 = _casteljau3(builder, p, splat(t0))
    right = builder.fcmp_ordered('>', t0, ir.Constant(double, 0.0))
    p = [builder.select(right, c0, p[0]), builder.select(right, b1, p[1]), builder.select(right, a2, p[2]), p[3]]
    one = ir.Constant(double, 1.0)
    t = builder.fdiv(builder.fsub(t1, t0), builder.fsub(one, t0))
    a0, _, b0, _, c0 = _casteljau3(builder, p, splat(t))
    left = builder.fcmp_ordered('<', t1, one)
    return [p[0], builder.select(left, a0, p[1]), builder.select(left, b0, p[2]), builder.select(left, c0, p[3])]


def restrict_cubic(typingctx, pts, c, u0, u1, v0, v1):
    """Coordinate c of the bicubic in pts (float64, points k = 4 j + i along the last axis)
    restricted to [u0, u1] x [v0, v1] in place: bezier.restrict's lines, four at a time."""
    if not (isinstance(pts, types.Array) and pts.ndim == 2 and pts.layout == 'C' and pts.dtype == types.float64):
        return None
    sig = types.void(pts, c, types.float64, types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        pts_ty, c_ty = signature.args[:2]
        pts_v, c_v, u0, u1, v0, v1 = args
        arr = context.make_array(pts_ty)(context, builder, pts_v)
        first = cgutils.get_item_pointer2(context, builder, arr.data, cgutils.unpack_tuple(builder, arr.shape),
                                          cgutils.unpack_tuple(builder, arr.strides), pts_ty.layout,
                                          [context.cast(builder, c_v, c_ty, types.intp),
                                           context.get_constant(types.intp, 0)])
        base = builder.bitcast(first, ir.VectorType(ir.DoubleType(), 4).as_pointer())
        ptrs = [builder.gep(base, [ir.IntType(64)(j)]) for j in range(4)]
        rows = [builder.load(ptr, align=8) for ptr in ptrs]  # row j: the points (i, j)
        columns = _restrict4(builder, _transpose(builder, rows), u0, u1)  # the rows' lines in u
        rows = _restrict4(builder, _transpose(builder, columns), v0, v1)  # the columns' lines in v
        for ptr, value in zip(ptrs, rows):
            builder.store(value, ptr, align=8)
        return context.get_dummy_value()

    return sig, codegen


def _reduce_lanes(builder, op, vector, lanes):
    """op over the `lanes` lanes of one vector, halving it each time, as a scalar."""
    while lanes > 1:
        lanes //= 2
        vector = op(builder, _shuffle(builder, vector, vector, list(range(lanes))),
                    _shuffle(builder, vector, vector, list(range(lanes, 2 * lanes))))
    return builder.extract_element(vector, ir.IntType(32)(0))


def _row16(context, builder, arr_ty, arr_v, indices):
    """The 16 values of arr from indices on (the last index's axis), as a 16-lane float64 vector
    (one load where the array is C-contiguous, else one a value: bundle_alone's lane slots)."""
    arr = context.make_array(arr_ty)(context, builder, arr_v)
    elem = context.get_value_type(arr_ty.dtype)
    shape, strides = cgutils.unpack_tuple(builder, arr.shape), cgutils.unpack_tuple(builder, arr.strides)
    if arr_ty.layout == 'C':
        ptr = cgutils.get_item_pointer2(context, builder, arr.data, shape, strides, arr_ty.layout, indices)
        row = builder.load(builder.bitcast(ptr, ir.VectorType(elem, 16).as_pointer()),
                           align=context.get_abi_sizeof(elem))
    else:
        row = ir.Constant(ir.VectorType(elem, 16), ir.Undefined)
        for k in range(16):
            at = indices[:-1] + [builder.add(indices[-1], context.get_constant(types.intp, k))]
            ptr = cgutils.get_item_pointer2(context, builder, arr.data, shape, strides, arr_ty.layout, at)
            row = builder.insert_element(row, builder.load(ptr), ir.IntType(32)(k))
    if elem != ir.DoubleType():
        row = builder.fpext(row, ir.VectorType(ir.DoubleType(), 16))
    return row


def dist_range_cubic(typingctx, buf, s, n0, n1, n2):
    """(least, greatest) of x n0 + y n1 + z n2 over the 16 control points of slot s, float64."""
    if not (isinstance(buf, types.Array) and buf.ndim == 3 and buf.layout in ('C', 'A')
            and buf.dtype in (types.float32, types.float64)):
        return None
    sig = types.UniTuple(types.float64, 2)(buf, s, types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        buf_ty, s_ty = signature.args[:2]
        buf_v, s_v, *normal = args
        s_i = context.cast(builder, s_v, s_ty, types.intp)
        double = ir.DoubleType()
        total = None
        for c in range(3):
            row = _row16(context, builder, buf_ty, buf_v, [s_i, context.get_constant(types.intp, c),
                                                           context.get_constant(types.intp, 0)])
            lane = builder.insert_element(ir.Constant(ir.VectorType(double, 16), ir.Undefined), normal[c],
                                          ir.IntType(32)(0))
            term = builder.fmul(row, _shuffle(builder, lane, lane, [0] * 16))
            total = term if total is None else builder.fadd(total, term)
        # The scalar loop's min(lo, dist) keeps lo where dist is NaN: NaN lanes count as +-inf.
        nan = builder.fcmp_unordered('uno', total, total)
        lanes = ir.VectorType(double, 16)
        low = builder.select(nan, ir.Constant(lanes, [ir.Constant(double, math.inf)] * 16), total)
        high = builder.select(nan, ir.Constant(lanes, [ir.Constant(double, -math.inf)] * 16), total)
        return context.make_tuple(builder, signature.return_type,
                                  [_reduce_lanes(builder, _min, low, 16), _reduce_lanes(builder, _max, high, 16)])

    return sig, codegen


def _point_vectors(builder, rows):
    """The 16 points (x, y, z, z) as 4-lane vectors, from one 16-lane vector per coordinate."""
    i32 = ir.IntType(32)
    points = []
    for k in range(16):
        p = ir.Constant(ir.VectorType(rows[0].type.element, 4), ir.Undefined)
        for lane, c in enumerate((0, 1, 2, 2)):
            p = builder.insert_element(p, builder.extract_element(rows[c], i32(k)), i32(lane))
        points.append(p)
    return points


def bicubic_tangents(typingctx, ctrl, start, bu0, bu1, bu2, bu3, bv0, bv1, bv2, bv3, du0, du1, du2, dv0, dv1, dv2,
                     work):
    """bezier.tangents for an integral bicubic (points ctrl[:3, start:start + 16]) with the Bernstein
    rows bu, bv (degree 3) and du, dv (degree 2), the three coordinates side by side in the lanes
    of one vector: work[1, :3] = dS/du, work[2, :3] = dS/dv, work[3, :3] = d2S/dudv, each lane's
    terms in tangents' order from the same 0.0, each weight du[i] * bv[j] formed as it forms it."""
    if not (isinstance(ctrl, types.Array) and ctrl.ndim == 2 and ctrl.layout == 'C'
            and ctrl.dtype in (types.float32, types.float64)
            and isinstance(work, types.Array) and work.ndim == 2 and work.dtype == types.float64):
        return None
    sig = types.void(ctrl, start, *([types.float64] * 14), work)

    def codegen(context, builder, signature, args):
        ctrl_ty, start_ty = signature.args[:2]
        work_ty = signature.args[-1]
        ctrl_v, start_v, *weights, work_v = args
        bu, bv, du, dv = weights[0:4], weights[4:8], weights[8:11], weights[11:14]
        start_i = context.cast(builder, start_v, start_ty, types.intp)
        double = ir.DoubleType()
        p = _point_vectors(builder, [_row16(context, builder, ctrl_ty, ctrl_v, [context.get_constant(types.intp, c),
                                                                                 start_i]) for c in range(3)])
        vec = ir.VectorType(double, 4)
        i32 = ir.IntType(32)

        def splat(x):
            one = builder.insert_element(ir.Constant(vec, ir.Undefined), x, i32(0))
            return _shuffle(builder, one, one, [0, 0, 0, 0])

        def total(terms):
            acc = ir.Constant(vec, [ir.Constant(double, 0.0)] * 4)
            for a, b, diff in terms:
                acc = builder.fadd(acc, builder.fmul(splat(builder.fmul(a, b)), diff))
            return acc
        su = total((du[i], bv[j], builder.fsub(p[4 * j + i + 1], p[4 * j + i])) for j in range(4) for i in range(3))
        sv = total((bu[i], dv[j], builder.fsub(p[4 * j + i + 4], p[4 * j + i])) for j in range(3) for i in range(4))
        suv = total((du[i], dv[j], builder.fadd(builder.fsub(builder.fsub(p[4 * j + i + 5], p[4 * j + i + 4]),
                                                             p[4 * j + i + 1]), p[4 * j + i]))
                    for j in range(3) for i in range(3))
        out = context.make_array(work_ty)(context, builder, work_v)
        out_shape = cgutils.unpack_tuple(builder, out.shape)
        out_strides = cgutils.unpack_tuple(builder, out.strides)
        for k, (value, factor) in enumerate(((su, 3.0), (sv, 3.0), (suv, 9.0))):
            value = builder.fmul(ir.Constant(vec, [ir.Constant(double, factor)] * 4), value)
            for c in range(3):
                ptr = cgutils.get_item_pointer2(context, builder, out.data, out_shape, out_strides, work_ty.layout,
                                                [context.get_constant(types.intp, 1 + k),
                                                 context.get_constant(types.intp, c)])
                builder.store(builder.extract_element(value, i32(c)), ptr)
        return context.get_dummy_value()

    return sig, codegen


# ---- the same operations in numpy, for NUMBA_DISABLE_JIT=1 --------------------------------
# Each 4-lane vector is a length-4 array in the buffer's dtype; the scalar one half has that
# dtype too, so every lane rounds as the vector instruction does.

_SWAP_HALVES = [2, 3, 0, 1]
_SWAP_PAIRS = [1, 0, 3, 2]


def _min_python(a, b):
    return np.where(a < b, a, b)  # as fcmp_ordered + select: a NaN or an equal pair gives b


def _max_python(a, b):
    return np.where(a > b, a, b)


def _reduce_python(op, vectors):
    acc = vectors[0]
    for v in vectors[1:]:
        acc = op(acc, v)
    acc = op(acc, acc[_SWAP_HALVES])
    acc = op(acc, acc[_SWAP_PAIRS])
    return acc[0]


def _make_split_python(along_u: bool):
    def split(buf, src, dst, box):
        half = buf.dtype.type(0.5)

        def lerp(a, b):
            return (a + b) * half

        for c in range(3):
            rows = buf[src, c].reshape(4, 4)  # vector j holds the points k = 4 j + i
            p = list((rows.T if along_u else rows).copy())
            q0, q1, q2 = lerp(p[0], p[1]), lerp(p[1], p[2]), lerp(p[2], p[3])
            s0, s1 = lerp(q0, q1), lerp(q1, q2)
            mid = lerp(s0, s1)
            low = np.array([p[0], q0, s0, mid])
            high = np.array([mid, s1, q2, p[3]])
            box[src, c], box[src, 3 + c] = _reduce_python(_min_python, low), _reduce_python(_max_python, low)
            box[dst, c], box[dst, 3 + c] = _reduce_python(_min_python, high), _reduce_python(_max_python, high)
            if along_u:
                low, high = low.T, high.T
            buf[src, c] = low.reshape(16)
            buf[dst, c] = high.reshape(16)

    split.__name__ = split.__qualname__ = 'split_u_cubic_python' if along_u else 'split_v_cubic_python'
    return split


split_u_cubic_python = _make_split_python(True)
split_v_cubic_python = _make_split_python(False)


def restrict_cubic_python(pts, c, u0, u1, v0, v1):
    from .bezier import _restrict_line  # the scalar lines themselves (bezier imports this module)
    for j in range(4):
        _restrict_line(pts, c, 4 * j, 1, 3, u0, u1)
    for i in range(4):
        _restrict_line(pts, c, i, 4, 3, v0, v1)


def dist_range_cubic_python(buf, s, n0, n1, n2):
    rows = buf[s, :3, :16].astype(np.float64)
    dist = rows[0] * n0 + rows[1] * n1 + rows[2] * n2
    nan = np.isnan(dist)
    return float(np.where(nan, np.inf, dist).min()), float(np.where(nan, -np.inf, dist).max())



def bicubic_tangents_python(ctrl, start, bu0, bu1, bu2, bu3, bv0, bv1, bv2, bv3, du0, du1, du2, dv0, dv1, dv2, work):
    p = [ctrl[:3, start + k].astype(np.float64) for k in range(16)]  # point k: (x, y, z)
    bu, bv, du, dv = (bu0, bu1, bu2, bu3), (bv0, bv1, bv2, bv3), (du0, du1, du2), (dv0, dv1, dv2)

    def total(terms):
        acc = np.zeros(3)
        for a, b, diff in terms:
            acc = acc + np.float64(a * b) * diff
        return acc
    su = total((du[i], bv[j], p[4 * j + i + 1] - p[4 * j + i]) for j in range(4) for i in range(3))
    sv = total((bu[i], dv[j], p[4 * j + i + 4] - p[4 * j + i]) for j in range(3) for i in range(4))
    suv = total((du[i], dv[j], p[4 * j + i + 5] - p[4 * j + i + 4] - p[4 * j + i + 1] + p[4 * j + i])
                for j in range(3) for i in range(3))
    work[1, :3] = 3.0 * su
    work[2, :3] = 3.0 * sv
    work[3, :3] = 9.0 * suv

if config.DISABLE_JIT:
    split_u_cubic, split_v_cubic = split_u_cubic_python, split_v_cubic_python
    dist_range_cubic = dist_range_cubic_python
    bicubic_tangents = bicubic_tangents_python
    restrict_cubic = restrict_cubic_python
else:
    split_u_cubic = intrinsic(_make_split(True))
    split_v_cubic = intrinsic(_make_split(False))
    dist_range_cubic = intrinsic(dist_range_cubic)
    bicubic_tangents = intrinsic(bicubic_tangents)
    restrict_cubic = intrinsic(restrict_cubic)
split_u_cubic.__doc__ = """Halve a bicubic in slot src at u = 1/2 (src keeps [0, 1/2], dst gets [1/2, 1]),
writing both halves' control boxes into box[src], box[dst]."""
split_v_cubic.__doc__ = """Halve a bicubic in slot src at v = 1/2, with both halves' boxes (see split_u_cubic)."""
