"""binary.ulp and binary.pow2 against math.ldexp / math.frexp, bit for bit, compiled and interpreted."""
import math

import numpy as np
import pytest
from numba import njit

from tracer import binary


@njit(cache=True)
def _ulps(xs, bits):
    out = np.empty(xs.shape[0])
    for i in range(xs.shape[0]):
        out[i] = binary.ulp(xs[i], bits)
    return out


@njit(cache=True)
def _pow2s(ks):
    out = np.empty(ks.shape[0])
    for i in range(ks.shape[0]):
        out[i] = binary.pow2(ks[i])
    return out


def _values():
    rng = np.random.default_rng(7)
    special = [1.0, -1.0, 0.5, 2.0 ** -1022, 2.0 ** -1030, -2.0 ** -1074, 5e-324, np.nextafter(1.0, 2.0),
               np.nextafter(2.0, 0.0), 1.7976931348623157e308, 2.0 ** 52, 2.0 ** 53, 2.0 ** -1000, 3.0e-300]
    random = rng.standard_normal(2000) * np.exp2(rng.integers(-1074, 1023, 2000).astype(float))
    xs = np.concatenate([special, random])
    return xs[np.isfinite(xs) & (xs != 0.0)]


@pytest.mark.interpreted
def test_ulp_matches_ldexp_frexp_bit_for_bit():
    xs = _values()
    for bits in (24, 53, 11, 1):
        want = np.array([math.ldexp(1.0, math.frexp(x)[1] - bits) for x in xs])
        assert _ulps(xs, bits).tobytes() == want.tobytes(), bits


@pytest.mark.interpreted
def test_pow2_is_exact_over_the_normal_range():
    ks = np.arange(-1022, 1024, dtype=np.int64)
    want = np.array([math.ldexp(1.0, int(k)) for k in ks])
    assert _pow2s(ks).tobytes() == want.tobytes()


def test_interpreted_bit_casts_round_trip():
    for x in _values()[:200]:
        i = binary._float_bits_python(x)
        assert i == int(np.array(x).view(np.int64)) and binary._bits_float_python(i) == x
