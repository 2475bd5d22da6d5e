"""Leaf kernels (tracer.bezier, intersect.slab) against the slow references in reference.py.

Seeded random cases, many per test; grids P[i, j, xyz] in the references, the kernels'
slot buffers buf[slot, xyz, k] with k = j*(m+1) + i.
"""
import functools
import inspect
import math
from fractions import Fraction

import numpy as np
import pytest
from numba import config as numba_config

import reference as ref
from tracer import bezier, simd
from tracer.bezier import control_box, evaluate, normal_at, split_u, split_v
from tracer.ray import RAY_LEN, make_ray, slab

DTYPES = (np.float32, np.float64)
EPS = {np.float32: 2.0 ** -24, np.float64: 2.0 ** -53}


# ---- kernel adapters ------------------------------------------------------------------

def to_buf(P, dtype, slots=2):
    """A slot buffer holding grid P in slot 0."""
    pts = ref.flat(P)
    buf = np.zeros((slots, 3, len(pts)), dtype)
    buf[0] = pts.T
    return buf


def from_buf(buf, slot, m, n):
    return ref.grid(buf[slot].T.astype(np.float64), m, n)


def call(fn, **available):
    """Call a numba kernel with the arguments its signature names, taken from `available`.

    The kernel signatures grow (rational patches added `ncoord`, `rational`, a 4th row of
    work space); binding by name keeps these tests about behaviour, not argument order.
    """
    names = list(inspect.signature(python_function(fn)).parameters)
    missing = [k for k in names if k not in available]
    if missing:
        raise TypeError(f"{python_function(fn).__name__}{tuple(names)}: the test has no value for {missing}")
    return fn(*(available[k] for k in names))


def python_function(fn):
    """A kernel's Python source function (with NUMBA_DISABLE_JIT=1 the kernel is that function)."""
    return getattr(fn, "py_func", fn)


def _takes_box(fn):
    return "box" in inspect.signature(python_function(fn)).parameters


FAST_SPLITS = {(3, 3): (bezier.split_u_cubic, bezier.split_v_cubic),
               (1, 1): (bezier.split_u_linear, bezier.split_v_linear)}


def kernel_split(P, axis, dtype, fast=False):
    """Split grid P at 1/2 with the kernel: (lower half, upper half, boxes written or None);
    fast: the degree's specialised split (bicubic, bilinear) instead of the generic one."""
    m, n = P.shape[0] - 1, P.shape[1] - 1
    buf = to_buf(P, dtype)
    box = np.full((2, 6), np.nan)
    fast = fast and (m, n) in FAST_SPLITS
    fn = FAST_SPLITS[(m, n)][axis] if fast else (split_u if axis == 0 else split_v)
    call(fn, buf=buf, src=0, dst=1, m=m, n=n, ncoord=3, box=box)
    written = box if fast and _takes_box(fn) else None  # the fast splits box the halves as they split
    return from_buf(buf, 0, m, n), from_buf(buf, 1, m, n), written


def kernel_box(P, dtype):
    buf = to_buf(P, dtype, 1)
    box = np.zeros((1, 6))
    call(control_box, buf=buf, slot=0, count=buf.shape[2], box=box)
    return box[0]


def _pts(P):
    pts = np.ones((4, (P.shape[0]) * (P.shape[1])))  # row 3: weight 1 for kernels that read it
    pts[:3] = ref.flat(P).T
    return pts


def kernel_evaluate(P, u, v):
    m, n = P.shape[0] - 1, P.shape[1] - 1
    out = np.zeros((4, 4))
    call(evaluate, pts=_pts(P), m=m, n=n, u=u, v=v, ncoord=3, scratch=np.zeros((4, 16)), out=out)
    return out[:, :3]


def kernel_normal(P, u, v):
    m, n = P.shape[0] - 1, P.shape[1] - 1
    out = np.zeros(3)
    ok = call(normal_at, pts=_pts(P), m=m, n=n, u=u, v=v, rational=False, ncoord=3,
              scratch=np.zeros((4, 16)), d=np.zeros((6, 4)), out=out)
    return ok, out


def random_grid(rng, m, n, scale=1.0, centre=0.0):
    return centre + scale * rng.uniform(-1, 1, (m + 1, n + 1, 3))


def degrees(rng, count, top=15):
    return [(int(rng.integers(1, top + 1)), int(rng.integers(1, top + 1))) for _ in range(count)]


# ---- split ---------------------------------------------------------------------------

def exact_point(P, u, v):
    """S(u, v) of an object grid of Fractions, exactly (the Bernstein sum, no numpy floats)."""
    m, n = P.shape[0] - 1, P.shape[1] - 1
    return sum(ref.bernstein(m, i, u) * ref.bernstein(n, j, v) * P[i, j] for i in range(m + 1) for j in range(n + 1))


def test_reference_restriction_is_exact():
    """The reference's sub-patches (blossoming, in Fractions) are the parent exactly: the
    restriction to [t0, t1] at s is the parent at t0 + s (t1 - t0); both halves of a split too."""
    rng = np.random.default_rng(5)
    for m, n in degrees(rng, 8, top=6):
        P = ref.exact(rng.integers(-50, 51, (m + 1, n + 1, 3)).astype(np.float64))
        axis = int(rng.integers(2))
        t0, t1 = sorted(Fraction(int(k), 17) for k in rng.choice(18, 2, replace=False))
        lower, upper = ref.split(P, axis, t1)
        for sub, a, b in ((ref.restrict(P, axis, t0, t1), t0, t1), (lower, 0, t1), (upper, t1, 1)):
            for s, w in ((Fraction(1, 3), Fraction(5, 7)), (Fraction(0), Fraction(1)), (Fraction(1), Fraction(2, 9))):
                t = a + s * (b - a)
                got = exact_point(sub, s, w) if axis == 0 else exact_point(sub, w, s)
                want = exact_point(P, t, w) if axis == 0 else exact_point(P, w, t)
                assert np.array_equal(got, want), f"degree {m}x{n}, axis {axis}, [{a}, {b}] at {s}"


@pytest.mark.interpreted
@pytest.mark.parametrize("axis", [0, 1])
def test_split_halves_reproduce_parent(axis):
    """Lower half at s is the parent at s/2, upper half at s the parent at (1+s)/2 (float64)."""
    rng = np.random.default_rng(10 + axis)
    for m, n in degrees(rng, 60):
        P = random_grid(rng, m, n, scale=rng.choice([1e-3, 1.0, 1e3]), centre=rng.uniform(-5, 5))
        lo, hi, _ = kernel_split(P, axis, np.float64)
        scale = np.abs(P).max()
        tol = 64 * EPS[np.float64] * scale * max(m, n)  # rounding of the split and of the evaluation
        for s, w in rng.uniform(0, 1, (8, 2)):
            a, b = (s, w) if axis == 0 else (w, s)
            for half, (pa, pb) in ((lo, (a / 2, b) if axis == 0 else (a, b / 2)),
                                   (hi, ((1 + a) / 2, b) if axis == 0 else (a, (1 + b) / 2))):
                np.testing.assert_allclose(ref.evaluate(half, a, b), ref.evaluate(P, pa, pb), rtol=0, atol=tol,
                                           err_msg=f"degree {m}x{n}, axis {axis}, (s, w) = ({s}, {w})")


@pytest.mark.interpreted
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("axis", [0, 1])
def test_split_is_exact_when_representable(dtype, axis):
    """Small integer control points: every de Casteljau midpoint is representable, so the
    kernel's halves equal the exact rational halves bit for bit (degrees up to 15)."""
    rng = np.random.default_rng(20 + axis)
    top = 2 ** 7 if dtype == np.float32 else 2 ** 30  # magnitude bits + 15 halvings fit the mantissa
    for m, n in degrees(rng, 25):
        P = rng.integers(-top, top + 1, (m + 1, n + 1, 3)).astype(np.float64)
        lo, hi, _ = kernel_split(P, axis, dtype)
        elo, ehi = ref.split(ref.exact(P), axis)
        assert np.array_equal(lo, elo.astype(np.float64)), f"degree {m}x{n}"
        assert np.array_equal(hi, ehi.astype(np.float64)), f"degree {m}x{n}"


@pytest.mark.interpreted
@pytest.mark.parametrize("dtype", DTYPES)
def test_split_error_within_level_ulps(dtype):
    """General inputs: each level of midpoints rounds once, so a point of level k is within
    k/2 ulps (of the largest coordinate) of the exact split of the same inputs."""
    rng = np.random.default_rng(30)
    for m, n in degrees(rng, 20):
        P = random_grid(rng, m, n, scale=3.0).astype(dtype).astype(np.float64)
        axis = int(rng.integers(2))
        lo, hi, _ = kernel_split(P, axis, dtype)
        elo, ehi = ref.split(ref.exact(P), axis)
        ulp = ref.ulp(np.abs(P).max(), 24 if dtype == np.float32 else 53)
        k = m if axis == 0 else n
        for got, want in ((lo, elo), (hi, ehi)):
            err = np.abs(got - want.astype(np.float64)).max()
            assert err <= 0.5 * k * ulp + 1e-300, f"degree {m}x{n}: {err / ulp:.2f} ulps"


@pytest.mark.interpreted
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("degree", list(FAST_SPLITS))
def test_fast_split_bit_identical_to_generic(dtype, axis, degree):
    rng = np.random.default_rng(40 + axis)
    shape = (degree[0] + 1, degree[1] + 1, 3)
    for case in range(200):
        spread = 10.0 ** rng.uniform(-6, 6, shape)  # mixed magnitudes stress the rounding
        P = (rng.uniform(-1, 1, shape) * spread).astype(dtype).astype(np.float64)
        glo, ghi, _ = kernel_split(P, axis, dtype)
        clo, chi, box = kernel_split(P, axis, dtype, fast=True)
        assert np.array_equal(glo, clo) and np.array_equal(ghi, chi), f"case {case}"
        if box is not None:  # the boxes written during the split are those of the halves
            assert np.array_equal(box[0], ref.box(glo)), f"case {case}: lower box"
            assert np.array_equal(box[1], ref.box(ghi)), f"case {case}: upper box"


def _awkward_cubic_points(rng, dtype):
    """(3, 16) control points over the dtype's whole range (subnormals, sums that overflow), of
    one sign or mixed, in some cases with signed zeros, ties, infinities and NaNs: only the same
    operations in the same order, and the same choice between equal or unordered lanes in the
    box's min and max, reproduce every bit."""
    info = np.finfo(dtype)
    exponent = rng.uniform(np.log10(info.smallest_subnormal), np.log10(info.max), (3, 16))
    sign = (1.0, -1.0, rng.choice([-1.0, 1.0], (3, 16)))[rng.integers(3)]
    pts = (sign * 10.0 ** exponent).astype(dtype)
    if rng.uniform() < 0.5:
        specials = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, pts.flat[0]], dtype)
        where = rng.uniform(size=pts.shape) < rng.uniform(0.1, 0.9)
        pts[where] = rng.choice(specials, where.sum())
    return pts


def _same_bits(a, b) -> bool:
    """Bit for bit, signed zeros included, except that any NaN equals any NaN: LLVM may commute an
    fadd, so which operand's NaN payload and sign survive is not defined."""
    nan = np.isnan(a)
    return np.array_equal(nan, np.isnan(b)) and a[~nan].tobytes() == b[~nan].tobytes()


@pytest.mark.interpreted
def test_numpy_cubic_split_runs_exactly_when_jit_is_off():
    """With NUMBA_DISABLE_JIT=1 the kernels call simd's numpy split (an intrinsic cannot run in
    Python); compiled, they keep the intrinsic."""
    fallbacks = (simd.split_u_cubic_python, simd.split_v_cubic_python)
    if numba_config.DISABLE_JIT:
        assert (simd.split_u_cubic, simd.split_v_cubic) == fallbacks
    else:
        assert simd.split_u_cubic not in fallbacks and simd.split_v_cubic not in fallbacks


@pytest.mark.skipif(numba_config.DISABLE_JIT, reason="compares the compiled intrinsic with its fallback")
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("axis", [0, 1])
def test_python_cubic_split_bit_identical_to_simd(dtype, axis):
    """simd's numpy split (used with NUMBA_DISABLE_JIT=1) writes the same bits as the intrinsic:
    both halves' points and both boxes, and leaves other slots alone."""
    compiled = (bezier.split_u_cubic, bezier.split_v_cubic)[axis]
    python = (simd.split_u_cubic_python, simd.split_v_cubic_python)[axis]
    rng = np.random.default_rng(45 + axis)
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf and overflowing sums are part of the test
        for case in range(300):
            buf = np.zeros((3, 4, 16), dtype)
            buf[0, :3] = _awkward_cubic_points(rng, dtype)
            buf[2, :3] = _awkward_cubic_points(rng, dtype)  # a slot neither split may touch
            box = np.full((3, 6), np.nan)
            buf_py, box_py = buf.copy(), box.copy()
            compiled(buf, 0, 1, box)
            python(buf_py, 0, 1, box_py)
            assert _same_bits(buf, buf_py), f"case {case}: points differ"
            assert _same_bits(box, box_py), f"case {case}: boxes differ"


def _dist_range_loop(buf, s, n0, n1, n2):
    """hull.hull_off_plane's scalar loop over 16 points, as numba runs it (min, max: keep the
    accumulator unless the new value is smaller, larger)."""
    lo, hi = math.inf, -math.inf
    for k in range(16):
        d = float(buf[s, 0, k]) * n0 + float(buf[s, 1, k]) * n1 + float(buf[s, 2, k]) * n2
        lo = d if d < lo else lo
        hi = d if d > hi else hi
    return lo, hi


@functools.cache
def _dist_range_jit():
    from numba import njit
    return njit(lambda buf, s, n0, n1, n2: simd.dist_range_cubic(buf, s, n0, n1, n2))


def _dist_range_compiled(*args):
    return _dist_range_jit()(*args)


@pytest.mark.parametrize("dtype", DTYPES)
def test_hull_extent_in_vectors_is_the_scalar_loops(dtype):
    """simd.dist_range_cubic (compiled, and its numpy fallback) returns the scalar loop's least and
    greatest distance across a plane, NaNs skipped, equal up to the sign of a zero."""
    rng = np.random.default_rng(61)
    with np.errstate(invalid="ignore", over="ignore"):
        for case in range(300):
            buf = np.zeros((2, 4, 16), dtype)
            buf[1, :3] = _awkward_cubic_points(rng, dtype) if case % 2 else rng.normal(0, 10, (3, 16)).astype(dtype)
            n = rng.normal(size=3)
            n /= np.linalg.norm(n)
            want = _dist_range_loop(buf, 1, *n)
            for got in (_dist_range_compiled(buf, 1, *n), simd.dist_range_cubic_python(buf, 1, *n)):
                for w, g in zip(want, got):
                    assert w == g or (math.isnan(w) and math.isnan(g)), (case, want, got)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("degree", [(3, 3), (1, 1), (2, 5), (9, 7), (15, 15)])
def test_sub_patch_boxes_inside_parent(dtype, degree):
    """Random descents to beyond the working precision: every child's control box lies inside
    its parent's. Exact in both precisions: fl(a + b) / 2 lies between a and b (no underflow)."""
    m, n = degree
    rng = np.random.default_rng(50 + m * 16 + n)
    depth = 70 if dtype == np.float32 else 130
    for trial in range(6 if m * n > 20 else 20):
        P = random_grid(rng, m, n, scale=10.0 ** rng.uniform(-3, 3), centre=rng.uniform(-100, 100))
        P = P.astype(dtype).astype(np.float64)
        for level in range(depth):
            parent = ref.box(P)
            axis = int(rng.integers(2))
            halves = kernel_split(P, axis, dtype, fast=True)[:2]
            for h in halves:
                child = kernel_box(h, dtype)
                assert np.all(child[:3] >= parent[:3]) and np.all(child[3:] <= parent[3:]), (
                    f"trial {trial} level {level}: child box {child} outside parent {parent}")
            P = halves[int(rng.integers(2))]


def _exact_restrict(line, t0, t1):
    """A curve's control points restricted to [t0, t1], in exact rationals (blossoms: point i
    is B(t0, .., t0, t1, .., t1) with i arguments t1)."""
    deg = len(line) - 1
    out = []
    for i in range(deg + 1):
        pts = list(line)
        for t in [t0] * (deg - i) + [t1] * i:
            pts = [a + t * (b - a) for a, b in zip(pts[:-1], pts[1:])]
        out.append(pts[0])
    return out


@pytest.mark.interpreted
@pytest.mark.parametrize("degree", [(1, 1), (3, 3), (2, 5), (4, 1)])
def test_restrict_within_its_bound(degree):
    """bezier.restrict (float64, in place) gives the sub-patch over [u0, u1] x [v0, v1] within
    restrict_err of the largest point, against exact rational arithmetic."""
    from fractions import Fraction
    m, n = degree
    rng = np.random.default_rng(80 + 8 * m + n)
    for case in range(4):
        P = rng.uniform(-1, 1, (m + 1, n + 1, 3)) * 10.0 ** rng.uniform(-3, 3)
        u0, u1 = np.sort(rng.uniform(0, 1, 2))
        v0, v1 = np.sort(rng.uniform(0, 1, 2))
        if case == 0:
            u0, v1 = 0.0, 1.0  # one end of each interval kept
        pts = np.ones((4, (m + 1) * (n + 1)))
        pts[:3] = ref.flat(P).T
        _restrict_kernel()(pts, m, n, u0, u1, v0, v1)
        bound = bezier.restrict_err(m, n) * np.abs(P).max()
        F = [[[Fraction(float(x)) for x in P[i, j]] for j in range(n + 1)] for i in range(m + 1)]
        fu0, fu1, fv0, fv1 = map(Fraction, (float(u0), float(u1), float(v0), float(v1)))
        for c in range(3):
            rows = [_exact_restrict([F[i][j][c] for i in range(m + 1)], fu0, fu1) for j in range(n + 1)]
            grid = [_exact_restrict([rows[j][i] for j in range(n + 1)], fv0, fv1) for i in range(m + 1)]
            for j in range(n + 1):
                for i in range(m + 1):
                    err = abs(float(Fraction(float(pts[c, j * (m + 1) + i])) - grid[i][j]))
                    assert err <= bound, f"case {case}: point ({i}, {j}) off by {err:.3g} > {bound:.3g}"


@functools.lru_cache(maxsize=None)
def _restrict_kernel():
    """restrict is inlined into the search; a small wrapper calls it from Python."""
    from numba import njit

    @njit(cache=False)
    def run(pts, m, n, u0, u1, v0, v1, ncoord=3):
        bezier.restrict(pts, m, n, ncoord, u0, u1, v0, v1)
    return run


@pytest.mark.interpreted
@pytest.mark.parametrize("dtype", DTYPES)
def test_control_box_is_min_max(dtype):
    rng = np.random.default_rng(60)
    for m, n in degrees(rng, 40):
        P = random_grid(rng, m, n, scale=rng.uniform(0.1, 100)).astype(dtype).astype(np.float64)
        assert np.array_equal(kernel_box(P, dtype), ref.box(P))


# ---- evaluation and normals ----------------------------------------------------------------

@pytest.mark.interpreted
def test_evaluate_matches_bernstein_sum():
    """Point and first derivatives and the twist, degrees up to 15x15, corners included."""
    rng = np.random.default_rng(70)
    for m, n in degrees(rng, 60) + [(15, 15), (1, 1), (15, 1), (1, 15)]:
        P = random_grid(rng, m, n, scale=rng.choice([1e-4, 1.0, 1e4]))
        scale = np.abs(P).max()
        params = [(0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (1.0, 0.0)] + [tuple(x) for x in rng.uniform(0, 1, (6, 2))]
        for u, v in params:
            got = kernel_evaluate(P, u, v)
            want = ref.derivatives(P, u, v)
            # derivative magnitudes grow by the degree per differentiation
            for k, factor in enumerate((1, m, n, m * n)):
                np.testing.assert_allclose(got[k], want[k], rtol=0, atol=1e-12 * scale * max(factor, 1) * (m + n),
                                           err_msg=f"degree {m}x{n} at ({u}, {v}), row {k}")


@pytest.mark.interpreted
def test_normal_matches_cross_product():
    rng = np.random.default_rng(80)
    checked = 0
    for m, n in degrees(rng, 60):
        P = random_grid(rng, m, n)
        for u, v in rng.uniform(0.02, 0.98, (5, 2)):
            _, su, sv, _ = ref.derivatives(P, u, v)
            cross = np.linalg.norm(np.cross(su, sv))
            if cross < 1e-3 * np.linalg.norm(su) * np.linalg.norm(sv):
                continue  # nearly parallel derivatives: the normal is ill-conditioned
            ok, got = kernel_normal(P, u, v)
            assert ok
            np.testing.assert_allclose(got, ref.normal(P, u, v), atol=1e-9,
                                       err_msg=f"degree {m}x{n} at ({u}, {v})")
            checked += 1
    assert checked > 200


def collapse(P, edge):
    """P with one boundary edge collapsed to a point: 'v0', 'v1' (rows j = 0, n) or 'u0', 'u1'."""
    P = P.copy()
    if edge == "v0":
        P[:, 0] = P[0, 0]
    elif edge == "v1":
        P[:, -1] = P[0, -1]
    elif edge == "u0":
        P[0, :] = P[0, 0]
    else:
        P[-1, :] = P[-1, 0]
    return P


def _inside(edge, s, eps):
    """(u, v) on the edge at position s, moved eps into the patch."""
    return {"v0": (s, eps), "v1": (s, 1 - eps), "u0": (eps, s), "u1": (1 - eps, s)}[edge]


@pytest.mark.interpreted
@pytest.mark.parametrize("edge", ["v0", "v1", "u0", "u1"])
def test_normal_at_collapsed_edge_is_interior_limit(edge):
    """On a collapsed edge (and a hair inside it, where one derivative underflows the kernel's
    threshold) the normal is the limit from inside: compare with the plain cross product of
    the reference derivatives a little inside the patch."""
    rng = np.random.default_rng(90 + ["v0", "v1", "u0", "u1"].index(edge))
    from scenes import smooth_patch
    checked = 0
    for m, n in degrees(rng, 25, top=6) + [(3, 3), (15, 15)]:
        P = collapse(smooth_patch(rng, max(m, 2), max(n, 2)), edge)
        for s in rng.uniform(0.05, 0.95, 4):
            inner = ref.normal(P, *_inside(edge, s, 1e-6))
            outer = ref.normal(P, *_inside(edge, s, 1e-4))
            if np.linalg.norm(inner - outer) > 1e-3:
                continue  # the limit is not settled yet this close to the edge
            for eps in (0.0, 1e-12, 2.0 ** -40):
                ok, got = kernel_normal(P, *_inside(edge, s, eps))
                assert ok, f"no normal at {edge} s={s} eps={eps}"
                assert np.linalg.norm(got - inner) < 1e-3, (
                    f"degree {P.shape[0] - 1}x{P.shape[1] - 1}, edge {edge}, s={s}, eps={eps}: "
                    f"kernel {got}, interior limit {inner}")
            checked += 1
    assert checked > 40


@pytest.mark.interpreted
def test_teapot_collapsed_patches_normals():
    """The teapot's lid and bottom patches (v = 0 collapsed): normals at the apex side."""
    from scenes import grids_of, teapot
    grids = grids_of(teapot())
    collapsed = [P for P in grids if np.ptp(P[:, 0], axis=0).max() == 0]
    assert len(collapsed) == 8
    for P in collapsed:
        for s in np.linspace(0.05, 0.95, 7):
            inner = ref.normal(P, s, 1e-6)
            for eps in (0.0, 1e-12):
                ok, got = kernel_normal(P, s, eps)
                assert ok and np.linalg.norm(got - inner) < 1e-3, (s, eps, got, inner)


@pytest.mark.interpreted
def test_normal_of_fully_degenerate_patch_is_reported():
    P = np.ones((4, 4, 3))
    ok, got = kernel_normal(P, 0.3, 0.6)
    assert not ok and np.all(np.isfinite(got))


# ---- ray against box -----------------------------------------------------------------------

def kernel_slab(bx, origin, direction, frame=(0.0, 0.0, 0.0), t_min=0.0):
    ray = np.zeros(RAY_LEN)
    make_ray(ray, *map(float, origin), *map(float, direction), t_min, 0.0, 0.0)
    return slab(np.asarray(bx, np.float64), *map(float, frame), ray)


@pytest.mark.interpreted
def test_slab_agrees_with_exact_test():
    """Random boxes and rays, some direction components zero: the float64 slab agrees with the
    exact rational test whenever the exact answer has a margin, and never yields NaN."""
    rng = np.random.default_rng(100)
    agreed = 0
    for case in range(3000):
        lo = rng.uniform(-10, 10, 3)
        bx = np.concatenate([lo, lo + rng.uniform(0, 5, 3) * (rng.uniform(size=3) > 0.1)])
        o = rng.uniform(-20, 20, 3)
        d = rng.normal(size=3) * (rng.uniform(size=3) > 0.25)
        if not d.any():
            d[int(rng.integers(3))] = 1.0
        ok, t_in, t_out = kernel_slab(bx, o, d)
        assert not (math.isnan(t_in) or math.isnan(t_out)), f"case {case}: NaN"
        eok, et_in, et_out = ref.slab_exact(bx, o, d)
        if eok:
            margin = (et_out - et_in) if et_out != math.inf else math.inf
            if margin > 1e-9 * (1 + abs(float(et_in))):
                assert ok, f"case {case}: exact hit [{float(et_in)}, {float(et_out)}] missed"
                assert abs(t_in - float(et_in)) <= 1e-12 * (1 + abs(float(et_in)))
                agreed += 1
        elif et_in is None or et_in - et_out > 1e-9 * (1 + abs(float(et_out))):
            assert not ok, f"case {case}: exact miss reported as a hit [{t_in}, {t_out}]"
            agreed += 1
    assert agreed > 1000


@pytest.mark.interpreted
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_slab_ray_in_face_plane(axis):
    """A ray with a zero component lying exactly in a face plane of the box hits (bounds
    included); one float64 ulp outside that plane it misses."""
    bx = np.array([-1.0, -2.0, -3.0, 1.0, 2.0, 3.0])
    for side in (0, 3):
        o = np.array([-5.0, -5.0, -5.0])
        o[axis] = bx[side + axis]
        d = np.array([1.0, 1.0, 1.0])
        d[axis] = 0.0
        ok, t_in, t_out = kernel_slab(bx, o, d)
        assert ok and np.isfinite(t_in) and np.isfinite(t_out) and t_in <= t_out
        outward = -1.0 if side == 0 else 1.0
        o[axis] = np.nextafter(bx[side + axis], outward * np.inf)
        ok, t_in, t_out = kernel_slab(bx, o, d)
        assert not ok and not math.isnan(t_in) and not math.isnan(t_out)
        d[axis] = -0.0  # a negative zero is a zero component too
        o[axis] = bx[side + axis]
        ok, _, _ = kernel_slab(bx, o, d)
        assert ok


@pytest.mark.interpreted
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_slab_axis_parallel_rays(axis):
    """Rays along one axis (two zero components): containment in the other two slabs decides."""
    bx = np.array([0.0, 0.0, 0.0, 1.0, 2.0, 4.0])
    rng = np.random.default_rng(110 + axis)
    for case in range(500):
        o = rng.uniform(-1, 5, 3)
        if case % 5 == 0:  # on a face or an edge of the box
            others = [c for c in range(3) if c != axis]
            o[others[case % 2]] = bx[others[case % 2] + 3 * (case % 3 == 0)]
        d = np.zeros(3)
        d[axis] = rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-3, 3)
        ok, t_in, t_out = kernel_slab(bx, o, d)
        eok, et_in, et_out = ref.slab_exact(bx, o, d)
        assert not (math.isnan(t_in) or math.isnan(t_out))
        assert ok == eok, f"case {case}: origin {o}, direction {d}"
        if ok:
            assert t_in == pytest.approx(float(et_in), abs=1e-12) and t_out >= float(et_out)


@pytest.mark.interpreted
def test_slab_with_frame_offset():
    """Boxes are stored relative to a frame origin; the shift happens inside the slab."""
    rng = np.random.default_rng(120)
    for case in range(500):
        frame = rng.uniform(-1e4, 1e4, 3).astype(np.float32).astype(np.float64)
        local = np.sort(rng.uniform(-3, 3, (2, 3)), axis=0).astype(np.float32).astype(np.float64).reshape(-1)
        world = np.concatenate([local[:3] + frame, local[3:] + frame])
        o = frame + rng.uniform(-10, 10, 3)
        d = rng.normal(size=3) * (rng.uniform(size=3) > 0.2)
        if not d.any():
            d[0] = 1.0
        ok, t_in, _ = kernel_slab(local, o, d, frame)
        eok, et_in, et_out = ref.slab_exact(world, o, d)
        if eok and et_out - et_in > 1e-9:
            assert ok and t_in == pytest.approx(float(et_in), rel=1e-12, abs=1e-12), f"case {case}"
        elif et_in is None or et_in - et_out > 1e-9:
            assert not ok, f"case {case}"


@pytest.mark.interpreted
def test_slab_t_min_clamps_entry():
    bx = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    ok, t_in, t_out = kernel_slab(bx, (-1.0, 0.5, 0.5), (1.0, 0.0, 0.0), t_min=1.5)
    assert ok and t_in == 1.5 and t_out >= 2.0
    ok, _, _ = kernel_slab(bx, (-1.0, 0.5, 0.5), (1.0, 0.0, 0.0), t_min=2.5)
    assert not ok


@functools.lru_cache(maxsize=None)
def _restrict_lines_kernel():
    """The scalar reference: bezier._restrict_line on each row in u, then on each column in v,
    the degrees run-time values (the general loops)."""
    from numba import njit

    @njit(cache=True)
    def lines(pts, m, n, ncoord, u0, u1, v0, v1):
        for c in range(ncoord):
            for j in range(n + 1):
                bezier._restrict_line(pts, c, j * (m + 1), 1, m, u0, u1)
            for i in range(m + 1):
                bezier._restrict_line(pts, c, i, m + 1, n, v0, v1)
    return lines


@pytest.mark.interpreted
@pytest.mark.parametrize("degree", [3, 1])
def test_restrict_special_cases_are_the_general_lines_bit_for_bit(degree):
    """restrict's bicubic case (four lines at a time, simd.restrict_cubic) and bilinear case
    (unrolled) round as the general lines do, with either end of an interval at 0 or 1 (a stage
    left out) and ncoord 3 or 4."""
    rng = np.random.default_rng(91 + degree)
    count = (degree + 1) ** 2
    for case in range(300):
        pts = rng.standard_normal((4, count)) * 10.0 ** rng.uniform(-6, 6)
        u0, u1 = np.sort(rng.uniform(0, 1, 2))
        v0, v1 = np.sort(rng.uniform(0, 1, 2))
        if case % 5 == 1:
            u0, v1 = 0.0, 1.0
        elif case % 5 == 2:
            u1, v0 = 1.0, 0.0
        elif case % 5 == 3:
            u0, u1, v0, v1 = 0.0, 1.0, 0.0, 1.0
        ncoord = 3 + case % 2
        want, got = pts.copy(), pts.copy()
        _restrict_lines_kernel()(want, degree, degree, ncoord, u0, u1, v0, v1)
        _restrict_kernel()(got, degree, degree, u0, u1, v0, v1, ncoord)
        assert got.tobytes() == want.tobytes(), f"case {case}"
