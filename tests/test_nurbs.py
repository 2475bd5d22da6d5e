"""NURBS curves and surfaces: exact Bezier conversion by knot insertion, circles, revolution."""
import math
import re

import numpy as np
import pytest

from tracer.nurbs import (NurbsCurve, NurbsError, NurbsSurface, bezier_knots, bezier_surface, bezier_surface_point,
                          de_casteljau, decomposition, homogeneous)
from tracer.revolution import CircleParam, circle_arc, revolve

TOL = 1e-12  # knot insertion vs de Boor, coordinates of order 1, weights in [0.1, 10]


def random_knots(rng, n, p, clamped, repeats):
    if clamped:
        inner = np.sort(rng.uniform(0, 1, n - p - 1))
        if repeats:
            inner = np.round(inner * 4) / 4
            inner = np.minimum(inner, 0.75)  # keep multiplicities <= p at 0.25 steps
        k = np.concatenate([np.zeros(p + 1), inner, np.ones(p + 1)])
    else:
        k = np.sort(rng.uniform(-1, 2, n + p + 1))
    return k


def random_surface(rng, rational=True, clamped=True, repeats=False, subrange=False):
    while True:
        p, q = (int(x) for x in rng.integers(1, 6, 2))
        nu, nv = int(rng.integers(p + 1, p + 6)), int(rng.integers(q + 1, q + 6))
        pts = np.concatenate([rng.normal(size=(nv, nu, 3)),
                              rng.uniform(0.1, 10, (nv, nu, 1)) if rational
                              else np.ones((nv, nu, 1))], axis=2)
        ku = random_knots(rng, nu, p, clamped, repeats)
        kv = random_knots(rng, nv, q, clamped, repeats)
        dom = None
        if subrange:
            a, b = np.sort(rng.uniform(ku[p], ku[nu], 2))
            c, d = np.sort(rng.uniform(kv[q], kv[nv], 2))
            dom = (a, b, c, d)
        try:
            return NurbsSurface(p, q, ku, kv, pts, dom)
        except NurbsError:
            continue  # random knots with a vanishing basis function; draw again


@pytest.mark.parametrize("kind", ["clamped", "unclamped", "repeated", "subrange", "integral"])
def test_bezier_patches_reproduce_surface(kind):
    """Every Bezier patch evaluates to the NURBS surface at the mapped parameters."""
    rng = np.random.default_rng({"clamped": 1, "unclamped": 2, "repeated": 3,
                                 "subrange": 4, "integral": 5}[kind])
    worst = 0.0
    for _ in range(25):
        s = random_surface(rng, rational=kind != "integral", clamped=kind != "unclamped",
                           repeats=kind == "repeated", subrange=kind == "subrange")
        net = s.bezier_patches()
        assert len(net.points) == len(net.domains) == len(net.rational)
        for pts, dom in zip(net.points, net.domains):
            grid = pts.reshape(s.degree_v + 1, s.degree_u + 1, 4)
            st = rng.uniform(size=(6, 2))
            want = s.evaluate_many(dom[0] + st[:, 0] * (dom[1] - dom[0]),
                                   dom[2] + st[:, 1] * (dom[3] - dom[2]))
            for (a, b), w in zip(st, want):
                got = bezier_surface_point(grid, a, b)
                assert np.allclose(got, s.evaluate(dom[0] + a * (dom[1] - dom[0]),
                                                   dom[2] + b * (dom[3] - dom[2])), 0, TOL)
                worst = max(worst, float(np.abs(got - w).max()))
    assert worst < TOL, worst


def test_patches_tile_domain_in_order_and_share_edges():
    rng = np.random.default_rng(7)
    s = NurbsSurface(3, 2, [0, 0, 0, 0, 0.3, 0.6, 1, 1, 1, 1], [0, 0, 0, 0.5, 1, 1, 1],
                     np.concatenate([rng.normal(size=(4, 6, 3)), rng.uniform(0.5, 2, (4, 6, 1))], 2))
    net = s.bezier_patches()
    # v span outer, u span inner
    assert net.domains.tolist() == [[0, 0.3, 0, 0.5], [0.3, 0.6, 0, 0.5], [0.6, 1, 0, 0.5],
                                    [0, 0.3, 0.5, 1], [0.3, 0.6, 0.5, 1], [0.6, 1, 0.5, 1]]
    g = [p.reshape(3, 4, 4) for p in net.points]
    # neighbours in u share a column, neighbours in v a row, bit for bit (no cracks)
    assert np.array_equal(g[0][:, -1], g[1][:, 0]) and np.array_equal(g[1][:, -1], g[2][:, 0])
    assert np.array_equal(g[0][-1], g[3][0]) and np.array_equal(g[2][-1], g[5][0])


def test_integral_surface_keeps_unit_weights():
    rng = np.random.default_rng(8)
    s = random_surface(rng, rational=False, clamped=False)
    net = s.bezier_patches()
    assert not s.rational and not any(net.rational)
    assert all(np.all(p[:, 3] == 1.0) for p in net.points)


def test_curve_bezier_segments_reproduce_curve():
    rng = np.random.default_rng(9)
    for trial in range(30):
        p = int(rng.integers(1, 6))
        n = int(rng.integers(p + 1, p + 8))
        pts = np.column_stack([rng.normal(size=(n, 2)), rng.uniform(0.1, 10, n)])
        try:
            c = NurbsCurve(p, random_knots(rng, n, p, trial % 2 == 0, trial % 3 == 0), pts)
        except NurbsError:
            continue
        for seg, (t0, t1) in c.bezier_segments():
            for a in rng.uniform(size=4):
                h = de_casteljau(homogeneous(seg), a)
                assert np.allclose(h[:2] / h[2], c.evaluate(t0 + a * (t1 - t0)), 0, TOL)


def test_piecewise_bezier_knots():
    assert bezier_knots([0, 1], 3).tolist() == [0, 0, 0, 0, 1, 1, 1, 1]
    assert bezier_knots([0, 1, 3], 2).tolist() == [0, 0, 0, 1, 1, 3, 3, 3]
    # a 2-segment quadratic Bezier surface: each patch is its own slice of the net
    rng = np.random.default_rng(10)
    grid = np.concatenate([rng.normal(size=(3, 5, 3)), np.ones((3, 5, 1))], 2)
    net = bezier_surface(2, 2, grid, (0, 1, 3)).bezier_patches()
    assert net.domains.tolist() == [[0, 1, 0, 1], [1, 3, 0, 1]]
    assert np.array_equal(net.points[0].reshape(3, 3, 4), grid[:, :3])
    assert np.array_equal(net.points[1].reshape(3, 3, 4), grid[:, 2:])


def test_decomposition_is_cached_and_clamps():
    T, starts, spans = decomposition([0, 1, 2, 3, 4, 5], 2)  # unclamped: domain [2, 3]
    assert spans == ((2.0, 3.0),) and starts == (1,)
    assert np.allclose(T.sum(axis=1), 1.0)  # rows are affine combinations
    assert decomposition([0, 1, 2, 3, 4, 5], 2)[0] is T


@pytest.mark.parametrize("knots,n,p,words", [
    ([0, 0, 1, 0.5, 1, 1], 3, 2, "must not decrease"),
    ([0, 0, 0, 1, 1], 3, 2, "need 6 knots, got 5"),
    ([0, 0, 0, 0.5, 0.5, 0.5, 0.5, 1, 1, 1], 7, 2, "multiplicity above degree + 1"),
    ([-1, -1, 0, 0, 1, 1], 3, 2, "empty parameter domain"),
    ([0, 0, 1, 1], 2, 0, "degree 0 out of range"),
    ([0, 0, 0, 1, 1, 1], 2, 2, "needs at least 3 control points"),
])
def test_knot_errors(knots, n, p, words):
    with pytest.raises(NurbsError, match=re.escape(words)):
        NurbsCurve(p, knots, np.ones((n, 3)))


def test_range_and_weight_errors():
    grid = np.ones((2, 2, 4))
    with pytest.raises(NurbsError, match="leaves the knot domain"):
        NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], grid, (0, 2, 0, 1))
    with pytest.raises(NurbsError, match="is empty"):
        NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], grid, (0.5, 0.5, 0, 1))
    bad = grid.copy()
    bad[0, 0, 3] = 0
    with pytest.raises(NurbsError, match="weights must be > 0"):
        NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], bad)


def test_circle_param_inverse_and_derivative():
    for a0, a1 in [(0, 2 * math.pi), (0.3, 1.1), (-1, 2.5)]:
        c = CircleParam.for_sweep(a0, a1)
        th = np.linspace(a0, a1, 101)
        t = c.param(th)
        assert np.allclose(c.angle(t), th, 0, 1e-13)
        assert np.all(np.diff(t) > 0) and abs(t[0] - a0) < 1e-14 and abs(t[-1] - a1) < 1e-13
        # t(theta) is C1 at the knots but not C2: compare away from them
        knots = c.knots()
        th = th[np.min(np.abs(th[:, None] - knots[None]), axis=1) > 1e-3]
        h = 1e-6
        fd = (c.param(th + h) - c.param(th - h)) / (2 * h)
        assert np.allclose(c.dparam(th), fd, 0, 1e-8)


def test_circle_arc_exact_and_parameterised_by_circle_param():
    curve, circ = circle_arc((1.0, 2.0), 0.5, 0, 2 * math.pi)
    # the standard 9-point circle: exact corners, weights 1 and sqrt(2)/2
    assert curve.points[:, :2].tolist() == [[1.5, 2], [1.5, 2.5], [1, 2.5], [0.5, 2.5],
                                            [0.5, 2], [0.5, 1.5], [1, 1.5], [1.5, 1.5], [1.5, 2]]
    assert curve.points[1::2, 2].tolist() == [math.cos(math.pi / 4)] * 4
    th = np.linspace(0, 2 * math.pi, 57)
    p = curve.evaluate_many(circ.param(th))
    assert np.allclose(np.hypot(p[:, 0] - 1, p[:, 1] - 2), 0.5, 0, 1e-15)
    assert np.allclose(p, np.column_stack([1 + 0.5 * np.cos(th), 2 + 0.5 * np.sin(th)]), 0, 1e-15)


def test_revolve_matches_rotation_formula():
    """IGES 120: S(u, theta) = O + X cos(theta) + (D x X) sin(theta); v = circle param of theta."""
    rng = np.random.default_rng(11)
    gen = NurbsCurve(3, [0, 0, 0, 0, 0.4, 1, 1, 1, 1],
                     np.column_stack([rng.normal(size=(5, 3)), rng.uniform(0.5, 2, 5)]))
    origin, axis = np.array([0.2, -0.1, 0.3]), np.array([0.3, 0.4, 1.0])
    surf, circ = revolve(gen, origin, axis, 0.4, 5.0)
    d = axis / np.linalg.norm(axis)
    for u, th in rng.uniform([0, 0.4], [1, 5.0], (40, 2)):
        c = gen.evaluate(u) - origin
        x = c - d * (d @ c)
        want = origin + d * (d @ c) + x * math.cos(th) + np.cross(d, x) * math.sin(th)
        assert np.allclose(surf.evaluate(u, float(circ.param(th))), want, 0, 1e-13)
