"""A bundle's rays eight at a time: the slab test of a box, the prune by each ray's closest hit, the
nearest entry and the counters, in 8-lane vectors (LLVM IR through numba intrinsics).

The BVH walk of a bundle (bundle.py) tests every node against its rays one by one, a loop over a
mask's set bits that numba compiles to scalar code. Here the rays are columns of a `lanes` record
(L_LEN, K rounded up to a multiple of 8), and each intrinsic takes one group of eight columns and
the mask of its rays that count (one bit a lane). Each lane does ray.slab_at's operations in its
order (a subtraction, a product, a swap, the widened exit, the running max and min; no fused or
reordered arithmetic), so every ray's entry t and verdict are those of the scalar test: lanes
whose rays are not in the mask are computed too, and their results are masked off or written
into intervals nobody reads. With NUMBA_DISABLE_JIT=1 the same names are numpy versions.
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import config
from numba.core import cgutils, types
from numba.extending import intrinsic

from .ray import T_SLACK

WIDTH = 8
# lanes rows: origin xyz, direction xyz, 1 / direction xyz, t_min, the ray's closest hit's entry t,
# the origin in the frame of the patch being searched (bundle.lrays), the threshold of detail at t = 0
# and its growth per unit t (ray.R_T0, R_DT: the adaptive criterion's), the closest hit's entry t
# kept while a search bumps it (bundle._closest_rays), and inf (the exit a root's or a BVH node's
# interval starts from: slab_lanes)
L_O, L_D, L_INV, L_TMIN, L_HIT, L_PO, L_T0, L_DT, L_BEST, L_FAR = 0, 3, 6, 9, 10, 11, 14, 15, 16, 17
L_LEN = 18


def padded(count: int) -> int:
    """Columns of a lanes record for `count` rays: whole groups of WIDTH."""
    return -(-count // WIDTH) * WIDTH


def _is_2d(arr, dtype) -> bool:
    return isinstance(arr, types.Array) and arr.ndim == 2 and arr.layout == 'C' and arr.dtype == dtype


class _Lanes:
    """Vector loads and stores at (row, WIDTH * group) of 2-D C arrays, inside one codegen."""

    def __init__(self, context, builder):
        self.context, self.builder = context, builder

    def pointer(self, arr_ty, arr_v, row, group, elem):
        arr = self.context.make_array(arr_ty)(self.context, self.builder, arr_v)
        intp = self.context.get_value_type(types.intp)
        column = self.builder.mul(group, ir.Constant(intp, WIDTH))
        row = row if isinstance(row, ir.Value) else ir.Constant(intp, row)
        ptr = cgutils.get_item_pointer2(self.context, self.builder, arr.data,
                                        cgutils.unpack_tuple(self.builder, arr.shape),
                                        cgutils.unpack_tuple(self.builder, arr.strides), 'C', [row, column])
        return self.builder.bitcast(ptr, ir.VectorType(elem, WIDTH).as_pointer())

    def load(self, arr_ty, arr_v, row, group, elem=ir.DoubleType()):
        return self.builder.load(self.pointer(arr_ty, arr_v, row, group, elem), align=8)

    def store(self, value, arr_ty, arr_v, row, group, elem=ir.DoubleType()):
        self.builder.store(value, self.pointer(arr_ty, arr_v, row, group, elem), align=8)

    def splat(self, scalar, elem=ir.DoubleType()):
        vec = ir.VectorType(elem, WIDTH)
        one = self.builder.insert_element(ir.Constant(vec, ir.Undefined), scalar, ir.IntType(32)(0))
        return self.builder.shuffle_vector(one, one, ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH))

    def constant(self, value, elem=ir.DoubleType()):
        return ir.Constant(ir.VectorType(elem, WIDTH), [ir.Constant(elem, value)] * WIDTH)

    def mask(self, bits):
        """The low WIDTH bits of an int64 as a vector of i1."""
        low = self.builder.trunc(bits, ir.IntType(WIDTH))
        return self.builder.bitcast(low, ir.VectorType(ir.IntType(1), WIDTH))

    def bits(self, mask):
        """A vector of i1 as the low WIDTH bits of an int64 (uint64 result)."""
        return self.builder.zext(self.builder.bitcast(mask, ir.IntType(WIDTH)), ir.IntType(64))

    def index(self, value, ty):
        return self.context.cast(self.builder, value, ty, types.intp)


def _slab_vectors(v, builder, row, first, corners, t_in, t_out):
    """ray.slab_at's operations for the eight rays of a group (row(k): lanes row k of the group;
    first: the origins' first row) against the box `corners` (lo xyz, hi xyz), from the vectors
    t_in, t_out: (entry, exit, meets)."""
    intp = v.context.get_value_type(types.intp)
    zero = v.constant(0.0)
    fail = ir.Constant(ir.VectorType(ir.IntType(1), WIDTH), [0] * WIDTH)
    vec = ir.VectorType(ir.DoubleType(), WIDTH)
    fabs = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vec, [vec]), f'llvm.fabs.v{WIDTH}f64')
    for c in range(3):
        origin = row(builder.add(first, ir.Constant(intp, c)))
        lo = builder.fsub(v.splat(corners[c]), origin)
        hi = builder.fsub(v.splat(corners[3 + c]), origin)
        flat = builder.fcmp_ordered('==', row(L_D + c), zero)  # slab tests this axis by containment
        outside = builder.or_(builder.fcmp_ordered('>', lo, zero), builder.fcmp_ordered('<', hi, zero))
        fail = builder.or_(fail, builder.and_(flat, outside))
        inv = row(L_INV + c)
        a = builder.fmul(lo, inv)
        b = builder.fmul(hi, inv)
        swap = builder.fcmp_ordered('>', a, b)
        a, b = builder.select(swap, b, a), builder.select(swap, a, b)
        b = builder.fadd(b, builder.fmul(builder.call(fabs, [b]), v.constant(T_SLACK)))
        sloped = builder.not_(flat)
        t_in = builder.select(builder.and_(sloped, builder.fcmp_ordered('>', a, t_in)), a, t_in)
        t_out = builder.select(builder.and_(sloped, builder.fcmp_ordered('<', b, t_out)), b, t_out)
    meets = builder.and_(builder.not_(fail), builder.fcmp_ordered('<=', t_in, t_out))
    return t_in, t_out, meets


def _verdict_bits(v, builder, t_in, meets, hit):
    """bit k where lane k meets the box before its closest hit (`hit`), bit WIDTH + k where it
    meets it at all (uint64)."""
    ahead = builder.and_(meets, builder.fcmp_ordered('<', t_in, hit))
    return builder.or_(v.bits(ahead), builder.shl(v.bits(meets), ir.Constant(ir.IntType(64), WIDTH)))


def _slab_args_ok(lanes, tin, tout, start, stop) -> bool:
    return (_is_2d(lanes, types.float64) and _is_2d(tin, types.float64) and _is_2d(start, types.float64)
            and _is_2d(stop, types.float64) and (tout == types.none or _is_2d(tout, types.float64)))


def slab_lanes(typingctx, lanes, origin, group, lo0, lo1, lo2, hi0, hi1, hi2, tin, tout, row, start, start_row,
               stop, stop_row):
    """The rays of lanes' group, from the origins in rows origin..origin + 2 (L_O, or L_PO in the
    searched patch's frame), against the box (lo xyz, hi xyz) as ray.slab_at tests it within the
    intervals [start[start_row], stop[stop_row]] (lanes[L_TMIN] and lanes[L_FAR], or a parent box's
    rows of tin and tout): each ray's entry t into tin[row, its column], its exit t into
    tout[row, ...] (tout None: not kept); bit k (uint64) set where ray WIDTH * group + k meets the
    box before its closest hit (lanes[L_HIT]), bit WIDTH + k where it meets the box at all."""
    if not _slab_args_ok(lanes, tin, tout, start, stop):
        return None
    keep_out = tout != types.none
    sig = types.uint64(lanes, origin, group, *([types.float64] * 6), tin, tout, row, start, start_row, stop,
                       stop_row)

    def codegen(context, builder, signature, args):
        lanes_ty, origin_ty, group_ty = signature.args[:3]
        tin_ty, tout_ty, row_ty, start_ty, start_row_ty, stop_ty, stop_row_ty = signature.args[9:]
        lanes_v, origin_v, group_v, *corners, tin_v, tout_v, row_v, start_v, start_row_v, stop_v, stop_row_v = args
        v = _Lanes(context, builder)
        g = v.index(group_v, group_ty)

        def row(k):
            return v.load(lanes_ty, lanes_v, k, g)
        t_in = v.load(start_ty, start_v, v.index(start_row_v, start_row_ty), g)
        t_out = v.load(stop_ty, stop_v, v.index(stop_row_v, stop_row_ty), g)
        t_in, t_out, meets = _slab_vectors(v, builder, row, v.index(origin_v, origin_ty), corners, t_in, t_out)
        v.store(t_in, tin_ty, tin_v, v.index(row_v, row_ty), g)
        if keep_out:
            v.store(t_out, tout_ty, tout_v, v.index(row_v, row_ty), g)
        return _verdict_bits(v, builder, t_in, meets, row(L_HIT))

    return sig, codegen


def slab_pair_lanes(typingctx, lanes, origin, group, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, tin, tout,
                    row_a, row_b, start, start_row, stop, stop_row):
    """slab_lanes for two boxes a and b (a BVH node's children, a sub-patch's halves) within the same
    intervals, which may be a's own rows (every load comes before the stores): a's intervals into
    row_a, b's into row_b; a's bits as slab_lanes returns them, b's shifted up by 2 * WIDTH."""
    if not _slab_args_ok(lanes, tin, tout, start, stop):
        return None
    keep_out = tout != types.none
    sig = types.uint64(lanes, origin, group, *([types.float64] * 12), tin, tout, row_a, row_b, start, start_row,
                       stop, stop_row)

    def codegen(context, builder, signature, args):
        lanes_ty, origin_ty, group_ty = signature.args[:3]
        tin_ty, tout_ty, row_a_ty, row_b_ty, start_ty, start_row_ty, stop_ty, stop_row_ty = signature.args[15:]
        (lanes_v, origin_v, group_v, *corners, tin_v, tout_v, row_a_v, row_b_v, start_v, start_row_v, stop_v,
         stop_row_v) = args
        v = _Lanes(context, builder)
        g = v.index(group_v, group_ty)

        def row(k):  # (both boxes load a row alike before any store: LLVM keeps one load)
            return v.load(lanes_ty, lanes_v, k, g)
        t_in = v.load(start_ty, start_v, v.index(start_row_v, start_row_ty), g)
        t_out = v.load(stop_ty, stop_v, v.index(stop_row_v, stop_row_ty), g)
        hit = row(L_HIT)
        first = v.index(origin_v, origin_ty)
        in_a, out_a, meets_a = _slab_vectors(v, builder, row, first, corners[:6], t_in, t_out)
        in_b, out_b, meets_b = _slab_vectors(v, builder, row, first, corners[6:], t_in, t_out)
        for t_in_x, t_out_x, row_v, row_ty in ((in_a, out_a, row_a_v, row_a_ty), (in_b, out_b, row_b_v, row_b_ty)):
            v.store(t_in_x, tin_ty, tin_v, v.index(row_v, row_ty), g)
            if keep_out:
                v.store(t_out_x, tout_ty, tout_v, v.index(row_v, row_ty), g)
        bits_a = _verdict_bits(v, builder, in_a, meets_a, hit)
        bits_b = _verdict_bits(v, builder, in_b, meets_b, hit)
        return builder.or_(bits_a, builder.shl(bits_b, ir.Constant(ir.IntType(64), 2 * WIDTH)))

    return sig, codegen


def _compare(op, lanes_row, doc):
    """An intrinsic f(tin, row, lanes, group, bits): bits (uint64, the group's rays) where
    tin[row] `op` lanes[lanes_row] holds."""
    def compare(typingctx, tin, row, lanes, group, bits):
        if not (_is_2d(lanes, types.float64) and _is_2d(tin, types.float64)):
            return None
        sig = types.uint64(tin, row, lanes, group, types.uint64)

        def codegen(context, builder, signature, args):
            tin_ty, row_ty, lanes_ty, group_ty, _ = signature.args
            tin_v, row_v, lanes_v, group_v, bits_v = args
            v = _Lanes(context, builder)
            g = v.index(group_v, group_ty)
            t = v.load(tin_ty, tin_v, v.index(row_v, row_ty), g)
            holds = builder.fcmp_ordered(op, t, v.load(lanes_ty, lanes_v, lanes_row, g))
            return v.bits(builder.and_(holds, v.mask(bits_v)))

        return sig, codegen

    compare.__doc__ = doc
    return compare


ahead_lanes = _compare('<', L_HIT, """bits less the rays whose entry t (tin[row]) is not before their
closest hit (lanes[L_HIT]): the prune of bundle_steps.ahead_in.""")
at_start_lanes = _compare('<=', L_TMIN, """bits where the entry t (tin[row]) is at or before t_min: the
boxes holding a ray's origin, which bundle_steps._off_side tests further.""")


def within_detail_lanes(typingctx, tin, row, lanes, group, bits, size):
    """bits (uint64, the group's rays) where `size` <= the ray's threshold of detail at its entry t
    into the box of `row`, lanes[L_T0] + lanes[L_DT] * tin[row]: search_steps.judge_known's test,
    its product and sum unfused."""
    if not (_is_2d(lanes, types.float64) and _is_2d(tin, types.float64)):
        return None
    sig = types.uint64(tin, row, lanes, group, types.uint64, types.float64)

    def codegen(context, builder, signature, args):
        tin_ty, row_ty, lanes_ty, group_ty = signature.args[:4]
        tin_v, row_v, lanes_v, group_v, bits_v, size_v = args
        v = _Lanes(context, builder)
        g = v.index(group_v, group_ty)
        t = v.load(tin_ty, tin_v, v.index(row_v, row_ty), g)
        detail = builder.fadd(v.load(lanes_ty, lanes_v, L_T0, g),
                              builder.fmul(v.load(lanes_ty, lanes_v, L_DT, g), t))
        holds = builder.fcmp_ordered('<=', v.splat(size_v), detail)
        return v.bits(builder.and_(holds, v.mask(bits_v)))

    return sig, codegen


def nearest_lanes(typingctx, tin, row, group, bits):
    """The least entry t (tin[row]) of the group's rays in bits (uint64); inf for none."""
    if not _is_2d(tin, types.float64):
        return None
    sig = types.float64(tin, row, group, types.uint64)

    def codegen(context, builder, signature, args):
        tin_ty, row_ty, group_ty, _ = signature.args
        tin_v, row_v, group_v, bits_v = args
        v = _Lanes(context, builder)
        t = v.load(tin_ty, tin_v, v.index(row_v, row_ty), v.index(group_v, group_ty))
        t = builder.select(v.mask(bits_v), t, v.constant(math.inf))
        lanes = WIDTH
        while lanes > 1:  # halve the vector: min of the low and high halves
            lanes //= 2
            low = builder.shuffle_vector(t, t, ir.Constant(ir.VectorType(ir.IntType(32), lanes), list(range(lanes))))
            high = builder.shuffle_vector(t, t, ir.Constant(ir.VectorType(ir.IntType(32), lanes),
                                                            list(range(lanes, 2 * lanes))))
            t = builder.select(builder.fcmp_ordered('<', high, low), high, low)
        return builder.extract_element(t, ir.IntType(32)(0))

    return sig, codegen


def count_lanes(typingctx, counts, column, group, bits, n):
    """counts[column, ray] += n (int64) for the group's rays in bits (uint64)."""
    if not _is_2d(counts, types.int64):
        return None
    sig = types.void(counts, column, group, types.uint64, types.int64)

    def codegen(context, builder, signature, args):
        counts_ty, column_ty, group_ty = signature.args[:3]
        counts_v, column_v, group_v, bits_v, n_v = args
        v = _Lanes(context, builder)
        i64 = ir.IntType(64)
        g = v.index(group_v, group_ty)
        k = v.index(column_v, column_ty)
        add = builder.select(v.mask(bits_v), v.splat(n_v, i64), v.constant(0, i64))
        total = builder.add(v.load(counts_ty, counts_v, k, g, i64), add)
        v.store(total, counts_ty, counts_v, k, g, i64)
        return context.get_dummy_value()

    return sig, codegen


# ---- the same operations in numpy, for NUMBA_DISABLE_JIT=1 --------------------------------

def _columns(group):
    return slice(WIDTH * int(group), WIDTH * int(group) + WIDTH)


def _to_bits(flags) -> np.uint64:
    return np.uint64(sum(1 << k for k, f in enumerate(flags) if f))


def _from_bits(bits) -> np.ndarray:
    return np.array([(int(bits) >> k) & 1 for k in range(WIDTH)], bool)


def slab_lanes_python(lanes, origin, group, lo0, lo1, lo2, hi0, hi1, hi2, tin, tout, row, start, start_row, stop,
                      stop_row):
    cols = _columns(group)
    t_in = start[start_row, cols].copy()
    t_out = stop[stop_row, cols].copy()
    fail = np.zeros(WIDTH, bool)
    with np.errstate(all="ignore"):
        for c, (lo_c, hi_c) in enumerate(((lo0, hi0), (lo1, hi1), (lo2, hi2))):
            lo = lo_c - lanes[origin + c, cols]
            hi = hi_c - lanes[origin + c, cols]
            flat = lanes[L_D + c, cols] == 0.0
            fail |= flat & ((lo > 0.0) | (hi < 0.0))
            a = lo * lanes[L_INV + c, cols]
            b = hi * lanes[L_INV + c, cols]
            swap = a > b
            a, b = np.where(swap, b, a), np.where(swap, a, b)
            b = b + np.abs(b) * T_SLACK
            t_in = np.where(~flat & (a > t_in), a, t_in)
            t_out = np.where(~flat & (b < t_out), b, t_out)
    tin[row, cols] = t_in
    if tout is not None:
        tout[row, cols] = t_out
    meets = ~fail & (t_in <= t_out)
    return np.uint64(_to_bits(meets & (t_in < lanes[L_HIT, cols])) | (_to_bits(meets) << np.uint64(WIDTH)))


def slab_pair_lanes_python(lanes, origin, group, a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, tin, tout, row_a,
                           row_b, start, start_row, stop, stop_row):
    parent = np.stack([start[start_row], stop[stop_row]])  # a copy: a's stores may overwrite its rows
    bits_a = slab_lanes_python(lanes, origin, group, a0, a1, a2, a3, a4, a5, tin, tout, row_a, parent, 0, parent, 1)
    bits_b = slab_lanes_python(lanes, origin, group, b0, b1, b2, b3, b4, b5, tin, tout, row_b, parent, 0, parent, 1)
    return np.uint64(int(bits_a) | (int(bits_b) << (2 * WIDTH)))


def ahead_lanes_python(tin, row, lanes, group, bits):
    cols = _columns(group)
    return _to_bits(_from_bits(bits) & (tin[row, cols] < lanes[L_HIT, cols]))


def at_start_lanes_python(tin, row, lanes, group, bits):
    cols = _columns(group)
    return _to_bits(_from_bits(bits) & (tin[row, cols] <= lanes[L_TMIN, cols]))


def within_detail_lanes_python(tin, row, lanes, group, bits, size):
    cols = _columns(group)
    return _to_bits(_from_bits(bits) & (size <= lanes[L_T0, cols] + lanes[L_DT, cols] * tin[row, cols]))


def nearest_lanes_python(tin, row, group, bits):
    t = np.where(_from_bits(bits), tin[row, _columns(group)], math.inf)
    return float(t.min())


def count_lanes_python(counts, column, group, bits, n):
    counts[column, _columns(group)] += np.where(_from_bits(bits), n, 0)


if config.DISABLE_JIT:
    slab_lanes, ahead_lanes, at_start_lanes = slab_lanes_python, ahead_lanes_python, at_start_lanes_python
    slab_pair_lanes = slab_pair_lanes_python
    nearest_lanes, count_lanes = nearest_lanes_python, count_lanes_python
    within_detail_lanes = within_detail_lanes_python
else:
    slab_lanes, ahead_lanes, at_start_lanes = intrinsic(slab_lanes), intrinsic(ahead_lanes), intrinsic(at_start_lanes)
    slab_pair_lanes = intrinsic(slab_pair_lanes)
    nearest_lanes, count_lanes = intrinsic(nearest_lanes), intrinsic(count_lanes)
    within_detail_lanes = intrinsic(within_detail_lanes)
