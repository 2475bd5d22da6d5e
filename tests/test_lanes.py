"""The bundle's 8-lane tests (tracer/lanes.py) against the scalar ones they stand for: ray.slab_at
ray by ray, and the mask loops bundle.py ran before (the prune by the closest hit, the nearest
entry, the counters). Compiled intrinsics and their numpy fallbacks alike, on awkward rays and
boxes: zero, tiny and huge direction components, origins on and inside faces, infinite corners.
"""
import functools
import math

import numpy as np
import pytest
from numba import config as numba_config
from numba import njit

import digests as D
from tracer import lanes as L
from tracer.geometry import prepare
from tracer.options import Options
from tracer.ray import R_TMIN, RAY_LEN, make_ray, slab_at
from tracer.render import render

GROUPS = 2  # two groups of eight lanes: the group index is exercised too


@functools.cache
def _compiled():
    return dict(
        slab=njit(lambda lanes, origin, g, c, tin, tout, row, start: L.slab_lanes(
            lanes, origin, g, c[0], c[1], c[2], c[3], c[4], c[5], tin, tout, row, start, 0, start, 1)),
        slab_no_out=njit(lambda lanes, origin, g, c, tin, row, start: L.slab_lanes(
            lanes, origin, g, c[0], c[1], c[2], c[3], c[4], c[5], tin, None, row, start, 0, start, 1)),
        pair=njit(lambda lanes, origin, g, a, b, tin, tout, row_a, row_b, start, stop: L.slab_pair_lanes(
            lanes, origin, g, a[0], a[1], a[2], a[3], a[4], a[5], b[0], b[1], b[2], b[3], b[4], b[5], tin, tout, row_a,
            row_b, start, row_a, stop, row_a)),
        ahead=njit(lambda tin, row, lanes, g, bits: L.ahead_lanes(tin, row, lanes, g, bits)),
        at_start=njit(lambda tin, row, lanes, g, bits: L.at_start_lanes(tin, row, lanes, g, bits)),
        nearest=njit(lambda tin, row, g, bits: L.nearest_lanes(tin, row, g, bits)),
        within_detail=njit(lambda tin, row, lanes, g, bits, size: L.within_detail_lanes(tin, row, lanes, g, bits,
                                                                                         size)),
        count=njit(lambda counts, column, g, bits, n: L.count_lanes(counts, column, g, bits, n)))


def _python():
    return dict(
        slab=lambda lanes, origin, g, c, tin, tout, row, start: L.slab_lanes_python(lanes, origin, g, *c, tin, tout,
                                                                                   row, start, 0, start, 1),
        slab_no_out=lambda lanes, origin, g, c, tin, row, start: L.slab_lanes_python(lanes, origin, g, *c, tin, None,
                                                                                     row, start, 0, start, 1),
        pair=lambda lanes, origin, g, a, b, tin, tout, row_a, row_b, start, stop: L.slab_pair_lanes_python(
            lanes, origin, g, *a, *b, tin, tout, row_a, row_b, start, row_a, stop, row_a),
        ahead=L.ahead_lanes_python, at_start=L.at_start_lanes_python, nearest=L.nearest_lanes_python,
        within_detail=L.within_detail_lanes_python, count=L.count_lanes_python)


def _kinds():
    return [_python()] if numba_config.DISABLE_JIT else [_compiled(), _python()]


def _awkward(rng, size):
    """Coordinates with zeros of both signs, tiny, huge and ordinary values."""
    pick = rng.integers(0, 6, size)
    values = rng.normal(0.0, 3.0, size)
    values[pick == 0] = 0.0
    values[pick == 1] = -0.0
    values[pick == 2] = rng.normal(0.0, 1e-300, (pick == 2).sum())
    values[pick == 3] = rng.normal(0.0, 1e200, (pick == 3).sum())
    return values


def _rays(rng, count):
    rays = np.zeros((count, RAY_LEN))
    for r in range(count):
        o = rng.normal(0.0, 2.0, 3)
        d = _awkward(rng, 3)
        make_ray(rays[r], o[0], o[1], o[2], d[0], d[1], d[2], abs(rng.normal()) * (r % 3 == 0), 0.0, 0.0)
    return rays


def _lanes_of(rays, hits_tin):
    lanes = np.full((L.L_LEN, L.padded(len(rays))), np.nan)
    for r, ray in enumerate(rays):
        lanes[L.L_O:L.L_O + 3, r] = ray[0:3]
        lanes[L.L_D:L.L_D + 3, r] = ray[3:6]
        lanes[L.L_INV:L.L_INV + 3, r] = ray[6:9]
        lanes[L.L_TMIN, r] = ray[R_TMIN]
        lanes[L.L_HIT, r] = hits_tin[r]
        lanes[L.L_PO:L.L_PO + 3, r] = ray[0:3] - 0.75  # as if moved into a patch's frame
    return lanes


def _box(rng, rays):
    kind = rng.integers(0, 4)
    lo = rng.normal(0.0, 2.0, 3)
    hi = lo + np.abs(rng.normal(0.0, 2.0, 3))
    if kind == 1:  # flat in one axis, through some ray's origin
        axis = rng.integers(0, 3)
        lo[axis] = hi[axis] = rays[rng.integers(0, len(rays)), axis]
    elif kind == 2:
        lo[rng.integers(0, 3)] = -math.inf
        hi[rng.integers(0, 3)] = math.inf
    elif kind == 3:  # holding an origin
        o = rays[rng.integers(0, len(rays)), 0:3]
        lo, hi = np.minimum(lo, o), np.maximum(hi, o)
    return tuple(float(x) for x in np.concatenate([lo, hi]))


def _case(rng, count):
    """Rays, their closest hits' t (some inf) and their lanes."""
    rays = _rays(rng, count)
    hits = np.where(rng.random(count) < 0.3, rng.uniform(0.0, 5.0, count), math.inf)
    return rays, hits, _lanes_of(rays, hits)


def _parent(rng, lanes, count):
    """A parent box's interval, rows (entries, exits): its entry at or past t_min, its exit."""
    interval = np.full((2, lanes.shape[1]), math.inf)
    interval[0] = lanes[L.L_TMIN]
    interval[0, :count] += np.where(rng.random(count) < 0.5, rng.uniform(0.0, 3.0, count), 0.0)
    interval[1, :count] = np.where(rng.random(count) < 0.5, rng.uniform(0.0, 6.0, count), math.inf)
    return interval


def _bits(flags):
    return sum(1 << k for k, f in enumerate(flags) if f)


@pytest.mark.interpreted
def test_slab_lanes_are_the_scalar_slab_ray_by_ray():
    """Each lane's verdicts (meets the box before its closest hit; meets it) are slab_at's within the lane's
    interval (the ray's t_min and inf, or a parent's entry and exit); where it meets, its entry and
    exit t are slab_at's bits; lanes of other rays keep their verdict bit clear."""
    rng = np.random.default_rng(71)
    count = L.WIDTH * GROUPS
    with np.errstate(all="ignore"):
        for case in range(60 if numba_config.DISABLE_JIT else 400):
            rays, hits, lanes = _case(rng, count)
            corners = _box(rng, rays)
            start = np.full((2, lanes.shape[1]), math.inf)  # rows: the interval's start, its stop
            start[0] = lanes[L.L_TMIN]
            if case % 2:
                start = _parent(rng, lanes, count)
            for origin in (L.L_O, L.L_PO):
                moved = rays.copy()
                moved[:, 0:3] = lanes[origin:origin + 3, :count].T
                want = [slab_at(*corners, moved[r], start[0, r], start[1, r]) for r in range(count)]
                for kind in _kinds():
                    tin = np.full((3, lanes.shape[1]), np.nan)
                    tout = tin.copy()
                    for g in range(GROUPS):
                        got = int(kind["slab"](lanes, origin, g, corners, tin, tout, 1, start))
                        assert got == int(kind["slab_no_out"](lanes, origin, g, corners, tin.copy(), 1, start))
                        for k in range(L.WIDTH):
                            r = L.WIDTH * g + k
                            ok, t_in, t_out = want[r]
                            assert bool(got >> k & 1) == (ok and t_in < hits[r]), (case, r, corners, moved[r])
                            assert bool(got >> (L.WIDTH + k) & 1) == ok, (case, r)
                            if ok:
                                assert np.float64(tin[1, r]).tobytes() == np.float64(t_in).tobytes(), (case, r)
                                assert np.float64(tout[1, r]).tobytes() == np.float64(t_out).tobytes(), (case, r)
                    assert np.isnan(tin[[0, 2]]).all() and np.isnan(tout[[0, 2]]).all()  # other rows untouched


@pytest.mark.interpreted
def test_lane_prune_nearest_and_counts_are_the_mask_loops():
    rng = np.random.default_rng(72)
    count = L.WIDTH * GROUPS
    for case in range(50):
        tin = rng.choice([0.0, -0.0, 1.0, 2.5, math.inf, 1e-300], (2, count))
        hits = rng.choice([0.0, 1.0, 2.5, math.inf], count)
        lanes = _lanes_of(_rays(rng, count), hits)
        lanes[L.L_TMIN, :count] = rng.choice([0.0, 1.0], count)
        for kind in _kinds():
            counts = np.zeros((3, count), np.int64)
            for g in range(GROUPS):
                cols = range(L.WIDTH * g, L.WIDTH * g + L.WIDTH)
                bits = np.uint64(rng.integers(0, 256))
                member = [bool(int(bits) >> k & 1) for k in range(L.WIDTH)]
                ahead = kind["ahead"](tin, 1, lanes, g, bits)
                assert int(ahead) == _bits(m and tin[1, r] < hits[r] for m, r in zip(member, cols))
                start = kind["at_start"](tin, 1, lanes, g, bits)
                assert int(start) == _bits(m and tin[1, r] <= lanes[L.L_TMIN, r] for m, r in zip(member, cols))
                least = min([tin[1, r] for m, r in zip(member, cols) if m], default=math.inf)
                assert kind["nearest"](tin, 1, g, bits) == least
                kind["count"](counts, 2, g, bits, 3)
                assert list(counts[2, cols]) == [3 * m for m in member]
            assert not counts[:2].any()


@pytest.mark.interpreted
def test_within_detail_lanes_is_the_adaptive_criterions_scalar_test():
    """size <= t0 + dt * t_in lane by lane (judge_known's threshold, product and sum unfused), at
    sizes on, just below and just above each ray's threshold."""
    rng = np.random.default_rng(73)
    count = L.WIDTH * GROUPS
    for case in range(40):
        tin = rng.choice([0.0, -0.0, 1e-300, 0.37, 1.0 / 3.0, 2.5, 1e6], (2, count))
        lanes = _lanes_of(_rays(rng, count), np.full(count, math.inf))
        lanes[L.L_T0, :count] = rng.choice([0.0, 1e-7, 3e-4], count)
        lanes[L.L_DT, :count] = rng.uniform(1e-5, 1e-2, count)
        detail = [float(lanes[L.L_T0, r]) + float(lanes[L.L_DT, r]) * float(tin[1, r]) for r in range(count)]
        for size in (detail[rng.integers(0, count)], np.nextafter(detail[0], 0.0), np.nextafter(detail[1], 1.0),
                     0.0, math.inf):
            for kind in _kinds():
                for g in range(GROUPS):
                    cols = range(L.WIDTH * g, L.WIDTH * g + L.WIDTH)
                    bits = np.uint64(rng.integers(0, 256))
                    member = [bool(int(bits) >> k & 1) for k in range(L.WIDTH)]
                    got = kind["within_detail"](tin, 1, lanes, g, bits, float(size))
                    assert int(got) == _bits(m and size <= detail[r] for m, r in zip(member, cols)), (case, g)


@pytest.mark.interpreted
def test_bundles_report_the_single_rays_bits_interpreted_too():
    """The bundle walk and search through the lanes (numpy fallbacks when interpreted) give the
    1x1 render's channels (a small image of the teapot, float)."""
    scene, view = D.catalogue()["teapot"][0]()
    opts = Options()
    geom = prepare(scene, opts.precision)
    alone, bundled = (render(scene, opts.with_(bundle=b), size=(8, 8), view=view, geometry=geom)
                      for b in ("1x1", "8x8"))
    assert alone.hit.sum() > 10
    for name in ("hit", "t", "position", "box_min", "box_max", "normal", "uv", "patch"):
        assert np.array_equal(getattr(alone, name), getattr(bundled, name), equal_nan=True), name


@pytest.mark.interpreted
def test_slab_pair_lanes_are_two_slab_lanes():
    """The pair test is slab_lanes for each box, bit for bit, also where the boxes' interval is the
    first box's own rows (a sub-patch's halves within their parent's interval, as bundle_steps.open_pair
    tests them): every load comes before the stores."""
    rng = np.random.default_rng(72)
    count = L.WIDTH * GROUPS
    with np.errstate(all="ignore"):
        for case in range(40 if numba_config.DISABLE_JIT else 300):
            rays, hits, lanes = _case(rng, count)
            a, b = _box(rng, rays), _box(rng, rays)
            parent = _parent(rng, lanes, count)
            for kind in _kinds():
                for g in range(GROUPS):
                    want_in = np.full((3, lanes.shape[1]), np.nan)
                    want_out = want_in.copy()
                    bits_a = int(kind["slab"](lanes, L.L_PO, g, a, want_in, want_out, 1, parent))
                    bits_b = int(kind["slab"](lanes, L.L_PO, g, b, want_in, want_out, 2, parent))
                    # in place: the interval in rows 1 of tin (entries) and tout (exits), a's row
                    tin = np.full((3, lanes.shape[1]), np.nan)
                    tout = tin.copy()
                    tin[1], tout[1] = parent[0], parent[1]
                    both = kind["pair"](lanes, L.L_PO, g, a, b, tin, tout, 1, 2, tin, tout)
                    assert int(both) == bits_a | bits_b << (2 * L.WIDTH), case
                    cols = slice(L.WIDTH * g, L.WIDTH * g + L.WIDTH)
                    for row in (1, 2):
                        assert want_in[row, cols].tobytes() == tin[row, cols].tobytes(), (case, row)
                        assert want_out[row, cols].tobytes() == tout[row, cols].tobytes(), (case, row)
