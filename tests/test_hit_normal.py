"""The kernels' hit normal (hit_normal.py) against the general evaluator (bezier.normal_at): its
written-out bicubic and bilinear paths give the same bits, signed zeros included, on random and
degenerate integral patches in both precisions."""
import numpy as np
import pytest

from tracer.bezier import normal_at
from tracer.hit_normal import hit_normal
from tracer.ray import H_PATCH, H_U, H_V, HIT_LEN, RAY_LEN

PARAMS = (0.0, 1.0, 0.5, 0.25, 1.0 / 3.0, 1e-9, 1.0 - 2.0 ** -40, 2.0 ** -30)


def _reference(points, m, n, u, v, ray):
    pts = np.asarray(points, np.float64)
    out = np.zeros(3)
    found = normal_at(pts, m, n, u, v, False, np.zeros((4, 4)), np.zeros((6, 4)), out)
    if not found:
        return -np.asarray(ray[3:6]) / np.sqrt(ray[3] ** 2 + ray[4] ** 2 + ray[5] ** 2)
    if out[0] * ray[3] + out[1] * ray[4] + out[2] * ray[5] > 0.0:
        out = -out
    return out


def _kernel(points, m, n, u, v, ray):
    count = (m + 1) * (n + 1)
    ctrl = np.zeros((4, count + 3), points.dtype)  # the patch after a leading one, as in a scene
    ctrl[:, 3:] = points
    hit = np.zeros(HIT_LEN)
    hit[H_PATCH], hit[H_U], hit[H_V] = 1, u, v
    out = np.zeros(3)
    hit_normal(hit, ctrl, np.array([0, 3]), np.array([0, m]), np.array([0, n]), np.zeros(2, np.int8),
               np.asarray(ray, np.float64), np.zeros((4, 16)), np.zeros((4, 4)), np.zeros((6, 4)), out)
    return out


def _patches(rng, m, n, dtype):
    count = (m + 1) * (n + 1)
    for trial in range(60):
        pts = np.zeros((4, count))
        pts[:3] = rng.normal(size=(3, count)) * 10.0 ** rng.integers(-4, 5)
        pts[3] = 1.0
        if trial % 4 == 1:  # an edge collapsed to a point (the teapot's lid and bottom)
            pts[:3, :m + 1] = pts[:3, :1]
        elif trial % 4 == 2:  # the other direction, and a plane with a zero coordinate
            pts[:3, ::m + 1] = pts[:3, :1]
            pts[2] = 0.0
        elif trial % 4 == 3 and trial % 8 == 3:  # fully collapsed: no normal
            pts[:3] = pts[:3, :1]
        yield pts.astype(dtype)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("degree", [(1, 1), (3, 3), (2, 3)])
def test_hit_normal_is_normal_at_bit_for_bit(degree, dtype):
    m, n = degree
    rng = np.random.default_rng(m * 10 + n)
    compared = 0
    for pts in _patches(rng, m, n, dtype):
        for u in PARAMS:
            for v in PARAMS[::-1]:
                ray = np.zeros(RAY_LEN)
                ray[3:6] = rng.normal(size=3)
                want = _reference(pts, m, n, u, v, ray)
                got = _kernel(pts, m, n, u, v, ray)
                assert want.tobytes() == got.tobytes(), (pts, u, v, want, got)
                compared += 1
    assert compared == 60 * len(PARAMS) ** 2


@pytest.mark.interpreted
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_bicubic_tangents_fallback_is_the_intrinsic(dtype):
    """simd.bicubic_tangents' numpy version (NUMBA_DISABLE_JIT=1) writes the intrinsic's bits, and
    both are bezier.tangents' (the three coordinates' sums in its order)."""
    from numba import config, njit

    from tracer import bezier, simd
    rng = np.random.default_rng(83)
    compiled = None if config.DISABLE_JIT else njit(lambda c, s, w, work: simd.bicubic_tangents(
        c, s, w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7], w[8], w[9], w[10], w[11], w[12], w[13], work))
    for pts in _patches(rng, 3, 3, dtype):
        ctrl = np.zeros((4, 19), dtype)
        ctrl[:, 3:] = pts
        for u, v in zip(PARAMS, PARAMS[::-1]):
            rows = np.zeros((4, 4))
            for k, (deg, t) in enumerate(((3, u), (3, v), (2, u), (2, v))):
                bezier._bernstein_row(deg, t, rows[k])
            want = np.zeros((6, 4))
            for c in range(3):
                bezier.tangents(pts[c].astype(np.float64), 3, 3, rows[0], rows[1], rows[2], rows[3], c, want)
            weights = np.concatenate([rows[0], rows[1], rows[2, :3], rows[3, :3]])
            works = [np.zeros((6, 4))]
            simd.bicubic_tangents_python(ctrl, 3, *weights, works[0])
            if compiled is not None:
                works.append(np.zeros((6, 4)))
                compiled(ctrl, 3, weights, works[1])
            for work in works:
                assert work[1:4, :3].tobytes() == want[1:4, :3].tobytes(), (pts, u, v)
