"""Trimming loops: flat layout, the reference parity test against analytic regions, remapping."""
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from tracer.nurbs import NurbsCurve
from tracer.revolution import CircleParam, circle_arc
from tracer.trim import (TrimError, build_trimset, curve_segments, empty_trimset, fit_cubics,
                         inside, loops_for_plot, make_loop, remap_segments, sample_segment,
                         signed_area)

pytestmark = pytest.mark.interpreted  # small enough to run with NUMBA_DISABLE_JIT=1 too (test_interpreted.py)

SAMPLES = Path(__file__).resolve().parents[1] / "sample_models"


def polygon(points, kind):
    pts = np.asarray(points, dtype=np.float64)
    segs = [np.array([[*pts[i], 1.0], [*pts[(i + 1) % len(pts)], 1.0]]) for i in range(len(pts))]
    return make_loop(kind, segs, 0.0)


def circle(cu, cv, r, kind, a0=0.0):
    c, _ = circle_arc((cu, cv), r, a0, a0 + 2 * math.pi)
    return make_loop(kind, curve_segments(c), 0.0)


SQUARE = [(0.1, 0.1), (0.9, 0.1), (0.9, 0.9), (0.1, 0.9)]


def test_layout_and_kinds():
    ts = build_trimset([[polygon(SQUARE, "trim"), circle(0.3, 0.6, 0.2, "hole")], [],
                        [circle(0.5, 0.5, 0.1, "hole")]])
    assert ts.n_surfaces == 3 and ts.has_trim.tolist() == [True, False, True]
    assert ts.start_inside.tolist() == [False, False, True]   # holes only: start inside
    assert ts.surf_seg_start.tolist() == [0, 8, 8, 12]
    assert ts.seg_degree.tolist() == [1] * 4 + [2] * 8
    assert ts.seg_start[-1] == len(ts.seg_points) and ts.seg_points.shape[1] == 3
    assert np.all(np.diff(ts.seg_start) == ts.seg_degree + 1)
    assert ts.loop_kind.tolist() == [1, -1, -1]
    assert ts.surf_loop_start.tolist() == [0, 2, 2, 3] and ts.loop_seg_start.tolist() == [0, 4, 8, 12]
    for arr, dt in [(ts.seg_points, np.float64), (ts.seg_start, np.int64),
                    (ts.seg_degree, np.int32), (ts.surf_seg_start, np.int64)]:
        assert arr.dtype == dt
    e = empty_trimset(2)
    assert e.has_trim.tolist() == [False, False] and e.seg_points.shape == (0, 3)
    assert inside(e, 1, 0.5, 0.5) and inside(ts, -1, 5.0, 5.0)


def test_orientation_normalised():
    cw_square = polygon(SQUARE[::-1], "trim")
    assert signed_area(cw_square.segments) > 0     # trims turned counter-clockwise
    hole = circle(0.5, 0.5, 0.2, "hole")
    assert signed_area(hole.segments) < 0          # holes clockwise
    assert signed_area(hole.segments) == pytest.approx(-math.pi * 0.04, rel=1e-2)


def test_square_with_circle_hole_matches_analytic():
    ts = build_trimset([[polygon(SQUARE, "trim"), circle(0.3, 0.6, 0.2, "hole")],
                        [circle(0.3, 0.6, 0.2, "hole")]])
    rng = np.random.default_rng(0)
    pts = np.vstack([rng.uniform(-0.1, 1.1, (1500, 2)),
                     np.stack(np.meshgrid(np.linspace(0, 1, 21), np.linspace(0, 1, 21)), -1)
                     .reshape(-1, 2)])   # grid points share coordinates with control points
    in_circle = (pts[:, 0] - 0.3) ** 2 + (pts[:, 1] - 0.6) ** 2 < 0.04
    in_square = np.all((pts > 0.1) & (pts < 0.9), axis=1)
    # points exactly on a curve may go either way
    on = (np.abs(np.hypot(pts[:, 0] - 0.3, pts[:, 1] - 0.6) - 0.2) < 1e-12) | \
         np.any(np.isclose(pts, 0.1) | np.isclose(pts, 0.9), axis=1)
    for (u, v), c, sq, skip in zip(pts, in_circle, in_square, on):
        if skip:
            continue
        assert inside(ts, 0, u, v) == (sq and not c), (u, v)
        assert inside(ts, 1, u, v) == (not c), (u, v)


def test_nested_loops_by_parity():
    """Outer trim, a hole in it, and an island inside the hole."""
    ts = build_trimset([[polygon([(0, 0), (1, 0), (1, 1), (0, 1)], "trim"),
                         circle(0.5, 0.5, 0.4, "hole"), polygon(SQUARE[:0] or
                         [(0.4, 0.4), (0.6, 0.4), (0.6, 0.6), (0.4, 0.6)], "trim")]])
    assert inside(ts, 0, 0.05, 0.05)        # between the outer square and the hole
    assert not inside(ts, 0, 0.5, 0.2)      # in the hole
    assert inside(ts, 0, 0.5, 0.5)          # on the island
    assert not inside(ts, 0, 1.5, 0.5)      # outside everything


def test_precision_near_a_circle():
    """Points 1e-9 inside or outside a rational circle are told apart (float64 subdivision)."""
    ts = build_trimset([[circle(0.4, 0.55, 0.3, "trim", a0=0.3)]])
    rng = np.random.default_rng(1)
    for th in rng.uniform(0, 2 * math.pi, 40):
        for d, want in ((-1e-9, True), (1e-9, False)):
            r = 0.3 + d
            assert inside(ts, 0, 0.4 + r * math.cos(th), 0.55 + r * math.sin(th)) == want


def test_effort_is_counted_and_small_far_from_curves():
    ts = build_trimset([[circle(0.5, 0.5, 0.3, "trim")]])
    far, near = [0], [0]
    inside(ts, 0, 0.5, 0.5, far)
    inside(ts, 0, 0.8 - 1e-10, 0.5 + 1e-7, near)
    assert far[0] <= 16 < near[0]


def test_bspline_curve_loop_matches_its_points():
    """A B-spline curv2 becomes Bezier segments that trace the same curve."""
    rng = np.random.default_rng(2)
    ang = np.sort(rng.uniform(0, 2 * math.pi, 8))
    rad = rng.uniform(0.2, 0.4, 8)
    pts = np.column_stack([0.5 + rad * np.cos(ang), 0.5 + rad * np.sin(ang), np.ones(8)])
    pts = np.vstack([pts, pts[:3]])            # periodic cubic: wrap 3 points
    knots = np.arange(len(pts) + 4, dtype=float)
    curve = NurbsCurve(3, knots, pts)          # unclamped: domain [3, 11], a closed loop
    segs = curve_segments(curve)
    assert len(segs) == 8
    # segment k at local t is the curve at 3 + k + t
    t = np.linspace(0, 1, 9)
    for k, seg in enumerate(segs):
        assert np.allclose(sample_segment(seg, 9), curve.evaluate_many(3 + k + t), 0, 1e-14)
    loop = make_loop("trim", segs, 1e-12)
    ts = build_trimset([[loop]])
    dense = curve.evaluate_many(np.linspace(3, 11, 8001))
    checked = 0
    for u, v in rng.uniform(0, 1, (300, 2)):
        if np.min(np.hypot(dense[:, 0] - u, dense[:, 1] - v)) < 1e-3:
            continue
        # the winding number of the dense polygon decides the analytic answer
        turn = np.diff(np.unwrap(np.arctan2(dense[:, 1] - v, dense[:, 0] - u)))
        assert inside(ts, 0, u, v) == (abs(turn.sum()) > math.pi), (u, v)
        checked += 1
    assert checked > 250


def test_plate_sample_matches_analytic_region():
    spec = importlib.util.spec_from_file_location("make_samples", SAMPLES / "make_samples.py")
    ms = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ms)
    from tracer.formats.obj import load_obj
    model = load_obj(SAMPLES / "plate.obj")
    ts = build_trimset([model.surfaces[0].loops])
    rng = np.random.default_rng(3)
    uv = rng.uniform(0, 1, (2500, 2))
    far = ms.plate_distance(uv[:, 0], uv[:, 1]) > 1e-5
    want = ms.plate_region(uv[:, 0], uv[:, 1])
    got = np.array([inside(ts, 0, u, v) for u, v in uv])
    assert far.sum() > 2400
    assert np.array_equal(got[far], want[far])


def test_make_loop_bridges_small_gaps_and_rejects_wide_ones():
    a = np.array([[0, 0, 1], [1, 0, 1.0]])
    b = np.array([[1, 1e-9, 1], [0, 1, 1.0]])
    c = np.array([[0, 1, 1], [0, 0, 1.0]])
    loop = make_loop("trim", [a, b, c], 1e-8)
    assert len(loop.segments) == 4 and loop.bridged_gap == pytest.approx(1e-9)
    ts = build_trimset([[loop]])
    assert inside(ts, 0, 0.2, 0.2) and not inside(ts, 0, 0.8, 0.8)
    with pytest.raises(TrimError, match="not closed: gap 1e-09 between segments 0 and 1"):
        make_loop("trim", [a, b, c], 1e-10)
    with pytest.raises(TrimError, match="'trim' or 'hole'"):
        make_loop("keep", [a], 1)


def test_loops_for_plot():
    ts = build_trimset([[polygon(SQUARE, "trim"), circle(0.3, 0.6, 0.2, "hole")]])
    loops = loops_for_plot(ts, 0)
    assert [l["kind"] for l in loops] == ["trim", "hole"]
    sq, hole = loops[0]["points"], loops[1]["points"]
    assert len(sq) == 5 and np.array_equal(sq[0], sq[-1])
    assert np.allclose(np.hypot(hole[:, 0] - 0.3, hole[:, 1] - 0.6), 0.2, 0, 1e-15)
    assert loops_for_plot(ts, 5) == []


def test_remap_through_circle_parameter():
    """Loops in (u, angle) pushed to (u, circle parameter): exact on lines, within tol elsewhere."""
    circ = CircleParam.for_sweep(0.0, 2 * math.pi)
    maps = (None, circ)
    line_v = np.array([[0.2, 0.5, 1], [0.2, 5.5, 1.0]])        # along v: exact straight image
    line_u = np.array([[0.2, 5.5, 1], [0.8, 5.5, 1.0]])        # along u: exact
    curve = np.array([[0.8, 5.5, 1], [0.9, 3.0, 1], [0.2, 0.5, 1.0]])  # general: approximated
    out, n = remap_segments([line_v, line_u, curve], maps, 1e-11)
    assert n == 1
    assert np.array_equal(out[0][:, 1], circ.param(line_v[:, 1]))
    assert np.array_equal(out[1][:, 1], np.full(2, circ.param(5.5)))
    assert all(np.array_equal(out[i][-1, :2], out[i + 1][0, :2]) for i in range(len(out) - 1))
    assert np.array_equal(out[2][0, :2], [0.8, circ.param(5.5)])
    assert np.array_equal(out[-1][-1, :2], [0.2, circ.param(0.5)])


def test_fit_cubics_within_tolerance():
    """Cubic pieces match the mapped curve at the same parameter within tol."""
    circ = CircleParam.for_sweep(0.0, 2 * math.pi)
    ctrl = np.array([[0.8, 5.5], [0.9, 3.0], [0.2, 0.5]])

    def f(s):
        b = np.column_stack([(1 - s) ** 2, 2 * s * (1 - s), s * s])
        p = b @ ctrl
        return np.column_stack([p[:, 0], circ.param(p[:, 1])])

    def df(s):
        b = np.column_stack([2 * (s - 1), 2 - 4 * s, 2 * s])
        d = b @ ctrl
        p = np.column_stack([(1 - s) ** 2, 2 * s * (1 - s), s * s]) @ ctrl
        return np.column_stack([d[:, 0], circ.dparam(p[:, 1]) * d[:, 1]])

    knots_s = sorted((5.5 - k) / 5.0 for k in circ.breaks())   # v(s) = 5.5 - 5 s here
    pieces = fit_cubics(f, df, 1e-11, breaks=[0.0] + knots_s + [1.0])
    assert pieces[0][0] == 0 and pieces[-1][1] == 1 and 4 < len(pieces) < 2000
    assert all(a[1] == b[0] for a, b in zip(pieces, pieces[1:]))
    r = np.random.default_rng(4).uniform(size=50)
    bern = np.column_stack([(1 - r) ** 3, 3 * r * (1 - r) ** 2, 3 * r * r * (1 - r), r ** 3])
    worst = max(np.abs(bern @ c - f(s0 + r * (s1 - s0))).max() for s0, s1, c in pieces)
    assert worst < 2e-11


def test_rect_meets_loops_is_exact_enough_and_conservative():
    """The sub-patch classification: a rectangle the curves are said to miss holds no curve point
    (dense Bernstein samples) and is on one side of every loop (the reference parity at many of
    its points); rectangles far smaller than the segments' control boxes are decided, where the
    boxes alone kept every one near a curve undecided."""
    from tracer.trim_kernel import rect_meets_loops, segment_boxes, trim_scratch
    ts = build_trimset([[polygon(SQUARE, "trim"), circle(0.3, 0.6, 0.2, "hole"), circle(0.7, 0.3, 0.12, "hole")]])
    boxes = segment_boxes(ts.seg_points, ts.seg_start)
    stack_h, stack_m = trim_scratch(8)
    curve = np.concatenate([sample_segment(ts.seg_points[ts.seg_start[s]:ts.seg_start[s + 1]], 400)
                            for s in range(len(ts.seg_start) - 1)])
    rng = np.random.default_rng(7)
    decided_near = 0
    for _ in range(600):
        size = 10.0 ** rng.uniform(-9, -1)
        u0, v0 = rng.uniform(-0.05, 1.0, 2)
        u1, v1 = u0 + size * rng.uniform(0.3, 1.0), v0 + size * rng.uniform(0.3, 1.0)
        meets = rect_meets_loops(0, u0, u1, v0, v1, ts.seg_points, ts.seg_start, ts.surf_seg_start, boxes,
                                 stack_h, stack_m)
        if meets:
            continue
        assert not np.any((curve[:, 0] >= u0) & (curve[:, 0] <= u1) & (curve[:, 1] >= v0) & (curve[:, 1] <= v1))
        sides = {inside(ts, 0, u, v) for u, v in zip(rng.uniform(u0, u1, 6), rng.uniform(v0, v1, 6))}
        assert len(sides) == 1, (u0, u1, v0, v1)
        by_boxes = np.any((boxes[:, 1] >= u0) & (boxes[:, 0] <= u1) & (boxes[:, 3] >= v0) & (boxes[:, 2] <= v1))
        decided_near += bool(by_boxes)
    assert decided_near > 50  # the segments' boxes alone would have left these undecided
    # A rectangle on the circle is met, however small.
    u, v = 0.3 + 0.2, 0.6
    assert rect_meets_loops(0, u - 1e-12, u + 1e-12, v - 1e-12, v + 1e-12, ts.seg_points, ts.seg_start,
                            ts.surf_seg_start, boxes, stack_h, stack_m)
