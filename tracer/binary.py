"""Powers of two and units in the last place from a float64's bits, without a library call.

math.ldexp and math.frexp compile to calls into numba's C helpers (about 10 ns each): the search
made one pair per re-centring and two ldexp per patch search, and the mantissa criterion three
pairs per box, 1 % of a float32 teapot frame. Building the float from its exponent field gives the
same power of two, exactly; the rare values outside the normal range take the math functions.
With NUMBA_DISABLE_JIT=1 the bit casts are numpy views.
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import config
from numba.core import types
from numba.extending import intrinsic

from .jit import njit

_EXPONENT_SHIFT = 52
_EXPONENT_MASK = 0x7FF
_BIAS = 1023


def _float_bits(typingctx, x):
    if x != types.float64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


def _bits_float(typingctx, i):
    if i != types.int64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


def _float_bits_python(x):
    return int(np.array(x, np.float64).view(np.int64))


def _bits_float_python(i):
    return float(np.array(i, np.int64).view(np.float64))


if config.DISABLE_JIT:
    float_bits, bits_float = _float_bits_python, _bits_float_python
else:
    float_bits, bits_float = intrinsic(_float_bits), intrinsic(_bits_float)


@njit(cache=True, nogil=True, inline='always')
def pow2(k):
    """2.0 ** k, exactly, for integral k in the normal range [-1022, 1023]."""
    return bits_float(np.int64(k + _BIAS) << _EXPONENT_SHIFT)


@njit(cache=True, nogil=True, _nrt=False)
def ulp(x, bits):
    """Spacing of `bits`-bit floats at |x| (x != 0): math.ldexp(1.0, math.frexp(x)[1] - bits)."""
    e = (float_bits(np.float64(x)) >> _EXPONENT_SHIFT) & _EXPONENT_MASK
    if 0 < e < _EXPONENT_MASK and e >= bits:  # x normal, the result too: 2^(e - bias + 1 - bits)
        return bits_float(np.int64(e + 1 - bits) << _EXPONENT_SHIFT)
    return math.ldexp(1.0, math.frexp(x)[1] - bits)
