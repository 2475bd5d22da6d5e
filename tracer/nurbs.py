"""B-spline and NURBS curves and surfaces, and their exact conversion to Bezier pieces.

Points are stored as the Scene stores them: Euclidean coordinates followed by
the weight w (not premultiplied). All arithmetic that mixes points happens on
the homogeneous form (w*x, ..., w).

Conversion to Bezier (Dammertz 2.8) is knot insertion (Boehm): the ends of the
parameter range and every knot inside it are raised to multiplicity p, after
which each non-empty knot span k owns the Bezier control points k-p .. k. The
same insertion clamps an unclamped knot vector and cuts a surface down to a
parameter sub-range, so neither needs a separate path. Neighbouring Bezier
pieces share their boundary control points bit for bit (they are the same
entries of one refined net), so no crack opens between them.

Patch order: a surface's Bezier patches come row by row, v span outer and u
span inner (u varies fastest), like the control points inside a patch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from tracer.fixed_order import dot, sandwich

MAX_DEGREE = 20


class NurbsError(ValueError):
    """Invalid spline data: degree, knot vector, weights or parameter range."""


# ---- knot vectors ------------------------------------------------------------------

def check_knots(knots, degree: int, n_points: int, what: str = "knot vector") -> np.ndarray:
    """Validate a knot vector for `n_points` control points of `degree`; returns float64."""
    if not 1 <= degree <= MAX_DEGREE:
        raise NurbsError(f"degree {degree} out of range (allowed 1..{MAX_DEGREE})")
    if n_points < degree + 1:
        raise NurbsError(f"degree {degree} needs at least {degree + 1} control points, "
                         f"got {n_points}")
    k = np.asarray(knots, dtype=np.float64).ravel()
    if len(k) != n_points + degree + 1:
        raise NurbsError(f"{what}: {n_points} control points of degree {degree} need "
                         f"{n_points + degree + 1} knots, got {len(k)}")
    if not np.all(np.isfinite(k)):
        raise NurbsError(f"{what}: knots must be finite")
    if np.any(np.diff(k) < 0):
        i = int(np.argmax(np.diff(k) < 0))
        raise NurbsError(f"{what}: knots must not decrease (knot {i + 1} = {k[i + 1]:g} "
                         f"< knot {i} = {k[i]:g})")
    if np.any(k[degree + 1:] == k[:n_points]):
        raise NurbsError(f"{what}: a knot has multiplicity above degree + 1 = {degree + 1} "
                         f"(a basis function would vanish)")
    if not k[degree] < k[n_points]:
        raise NurbsError(f"{what}: empty parameter domain [{k[degree]:g}, {k[n_points]:g}]")
    return k


def bezier_knots(breaks, degree: int) -> np.ndarray:
    """Knot vector of a piecewise Bezier with the given segment breaks (OBJ `cstype bezier`).

    s segments of degree p have s*p + 1 control points; each inner break gets
    multiplicity p, the ends p + 1.
    """
    b = np.asarray(breaks, dtype=np.float64)
    return np.concatenate([[b[0]], np.repeat(b, degree), [b[-1]]])


def _check_range(knots, degree, n, lo, hi, what):
    d0, d1 = knots[degree], knots[n]
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise NurbsError(f"{what}: parameter range [{lo:g}, {hi:g}] is empty or not finite")
    if lo < d0 or hi > d1:
        raise NurbsError(f"{what}: parameter range [{lo:g}, {hi:g}] leaves the knot "
                         f"domain [{d0:g}, {d1:g}]")


def insert_knot(knots: np.ndarray, ctrl: np.ndarray, degree: int, x: float):
    """Boehm's algorithm: insert x once. ctrl is homogeneous, axis 0 runs over control points.

    Returns (new knots, new control array with one more row).
    """
    n = ctrl.shape[0]
    k = int(np.searchsorted(knots, x, side="right")) - 1
    k = min(max(k, degree), n - 1)  # x = end of the domain belongs to the last span
    out = np.empty((n + 1,) + ctrl.shape[1:], dtype=np.float64)
    out[:k - degree + 1] = ctrl[:k - degree + 1]
    out[k + 1:] = ctrl[k:]
    i = np.arange(k - degree + 1, k + 1)
    den = knots[i + degree] - knots[i]
    alpha = np.where(den > 0, (x - knots[i]) / np.where(den > 0, den, 1.0), 0.0)
    alpha = alpha.reshape((-1,) + (1,) * (ctrl.ndim - 1))
    out[i] = alpha * ctrl[i] + (1.0 - alpha) * ctrl[i - 1]
    return np.insert(knots, k + 1, x), out


@lru_cache(maxsize=4096)
def _decomposition(knots: tuple, degree: int, lo: float, hi: float):
    """Linear map from B-spline control points to the Bezier pieces on [lo, hi].

    Returns (T, starts, spans): T (rows, n) float64 so that refined = T @ ctrl;
    piece s has rows starts[s] .. starts[s] + degree and covers spans[s].
    Cached: files repeat the same knot vectors many times.
    """
    U = np.array(knots)
    n = len(U) - degree - 1
    T = np.eye(n)
    inner = np.unique(U[(U > lo) & (U < hi)])
    for x in [lo, hi, *inner]:
        mult = int(np.count_nonzero(U == x))
        for _ in range(degree - mult):
            U, T = insert_knot(U, T, degree, x)
    starts, spans = [], []
    for k in range(degree, len(U) - degree - 1):
        if U[k] < U[k + 1] and U[k] >= lo and U[k + 1] <= hi:
            starts.append(k - degree)
            spans.append((float(U[k]), float(U[k + 1])))
    T.setflags(write=False)
    return T, tuple(starts), tuple(spans)


def decomposition(knots, degree: int, lo: float | None = None, hi: float | None = None):
    """(T, starts, spans) of the Bezier pieces of a spline on [lo, hi] (default: its domain)."""
    k = np.asarray(knots, dtype=np.float64)
    n = len(k) - degree - 1
    lo = float(k[degree]) if lo is None else float(lo)
    hi = float(k[n]) if hi is None else float(hi)
    return _decomposition(tuple(k.tolist()), degree, lo, hi)


# ---- homogeneous helpers -----------------------------------------------------------

def homogeneous(points: np.ndarray) -> np.ndarray:
    """Euclidean + weight rows (..., d+1) -> homogeneous (w*x, ..., w)."""
    p = np.asarray(points, dtype=np.float64)
    return np.concatenate([p[..., :-1] * p[..., -1:], p[..., -1:]], axis=-1)


def euclidean(h: np.ndarray) -> np.ndarray:
    """Homogeneous rows -> Euclidean + weight rows."""
    return np.concatenate([h[..., :-1] / h[..., -1:], h[..., -1:]], axis=-1)


def _check_weights(points, what):
    w = points[..., -1]
    if not np.all(np.isfinite(points)):
        raise NurbsError(f"{what}: control points must be finite")
    if np.any(w <= 0):
        raise NurbsError(f"{what}: weights must be > 0, got {float(w[w <= 0].flat[0]):g}")


def de_boor(knots: np.ndarray, degree: int, ctrl_h: np.ndarray, x: float) -> np.ndarray:
    """Point of a homogeneous spline at x by de Boor's algorithm (axis 0 = control points)."""
    n = ctrl_h.shape[0]
    k = int(np.searchsorted(knots, x, side="right")) - 1
    k = min(max(k, degree), n - 1)
    d = [ctrl_h[j + k - degree].astype(np.float64) for j in range(degree + 1)]
    for r in range(1, degree + 1):
        for j in range(degree, r - 1, -1):
            i = j + k - degree
            den = knots[i + 1 + degree - r] - knots[i]
            a = (x - knots[i]) / den if den > 0 else 0.0
            d[j] = (1.0 - a) * d[j - 1] + a * d[j]
    return d[degree]


def basis_functions(knots: np.ndarray, degree: int, n_points: int, x):
    """Non-zero B-spline basis values at many parameters (NURBS Book A2.2, vectorised).

    Returns (span (N,) int, values (N, degree+1)): value r belongs to control point span-degree+r.
    """
    x = np.atleast_1d(np.asarray(x, dtype=np.float64))
    span = np.clip(np.searchsorted(knots, x, side="right") - 1, degree, n_points - 1)
    vals = np.zeros((len(x), degree + 1))
    vals[:, 0] = 1.0
    left = np.zeros((len(x), degree + 1))
    right = np.zeros((len(x), degree + 1))
    for j in range(1, degree + 1):
        left[:, j] = x - knots[span + 1 - j]
        right[:, j] = knots[span + j] - x
        saved = np.zeros(len(x))
        for r in range(j):
            temp = vals[:, r] / (right[:, r + 1] + left[:, j - r])
            vals[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        vals[:, j] = saved
    return span, vals


def de_casteljau(ctrl_h: np.ndarray, s: float) -> np.ndarray:
    """Point of a homogeneous Bezier (axis 0 = control points) at s."""
    pts = np.array(ctrl_h, dtype=np.float64)
    for r in range(1, len(pts)):
        pts = (1.0 - s) * pts[:-1] + s * pts[1:]
    return pts[0]


def split_bezier(ctrl_h: np.ndarray, s: float = 0.5):
    """de Casteljau split of a homogeneous Bezier (axis 0) at s: (left, right)."""
    pts = np.array(ctrl_h, dtype=np.float64)
    left, right = [pts[0]], [pts[-1]]
    while len(pts) > 1:
        pts = (1.0 - s) * pts[:-1] + s * pts[1:]
        left.append(pts[0])
        right.append(pts[-1])
    return np.array(left), np.array(right[::-1])


def bezier_surface_point(grid: np.ndarray, s: float, t: float) -> np.ndarray:
    """Euclidean point of a Bezier patch. grid (n+1, m+1, 4) [j, i] Euclidean + weight."""
    h = homogeneous(grid)
    row = de_casteljau(np.moveaxis(h, 1, 0), s)  # along u: (n+1, 4)
    p = de_casteljau(row, t)
    return p[:3] / p[3]


# ---- curves and surfaces ------------------------------------------------------------

@dataclass(frozen=True)
class NurbsCurve:
    """A NURBS curve in any dimension d: points (n, d+1) Euclidean + weight."""
    degree: int
    knots: np.ndarray
    points: np.ndarray
    domain: tuple[float, float] | None = None  # parameter range used; default the knot domain

    def __post_init__(self):
        pts = np.asarray(self.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] < 2:
            raise NurbsError(f"curve control points must be (n, d+1), got shape {pts.shape}")
        _check_weights(pts, "curve")
        k = check_knots(self.knots, self.degree, len(pts))
        dom = (float(k[self.degree]), float(k[len(pts)])) if self.domain is None \
            else (float(self.domain[0]), float(self.domain[1]))
        _check_range(k, self.degree, len(pts), *dom, "curve")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "knots", k)
        object.__setattr__(self, "domain", dom)

    @property
    def rational(self) -> bool:
        return bool(np.any(self.points[:, -1] != 1.0))

    def evaluate(self, t: float) -> np.ndarray:
        """Euclidean point at parameter t (de Boor on the homogeneous points)."""
        h = de_boor(self.knots, self.degree, homogeneous(self.points), t)
        return h[:-1] / h[-1]

    def evaluate_many(self, t) -> np.ndarray:
        """Euclidean points (N, d) at many parameters."""
        h = homogeneous(self.points)
        span, vals = basis_functions(self.knots, self.degree, len(h), t)
        idx = span[:, None] - self.degree + np.arange(self.degree + 1)
        p = np.einsum("nr,nrc->nc", vals, h[idx])
        return p[:, :-1] / p[:, -1:]

    def bezier_segments(self) -> list[tuple[np.ndarray, tuple[float, float]]]:
        """Exact Bezier pieces on the domain: [(ctrl (p+1, d+1) Euclidean + w, (t0, t1))]."""
        T, starts, spans = decomposition(self.knots, self.degree, *self.domain)
        p = self.degree
        if self.rational:
            refined = euclidean(dot(T, homogeneous(self.points)))
        else:  # keep w == 1 exactly for integral curves
            refined = np.column_stack([dot(T, self.points[:, :-1]), np.ones(len(T))])
        return [(refined[a:a + p + 1].copy(), span) for a, span in zip(starts, spans)]


@dataclass(frozen=True)
class BezierNet:
    """The Bezier patches of one NURBS surface, in patch order (v span outer, u inner)."""
    degree_u: int
    degree_v: int
    points: list[np.ndarray]   # each ((n+1)*(m+1), 4) float64, row k = j*(m+1)+i, Euclidean + w
    domains: np.ndarray        # (n_patches, 4) float64: u0 u1 v0 v1
    rational: list[bool]


@dataclass(frozen=True)
class NurbsSurface:
    """A tensor-product NURBS surface.

    points (n_v, n_u, 4) indexed [j, i] (i along u), Euclidean x y z and weight w.
    domain (u0, u1, v0, v1): the parameter rectangle used, default the knot domain.
    """
    degree_u: int
    degree_v: int
    knots_u: np.ndarray
    knots_v: np.ndarray
    points: np.ndarray
    domain: tuple[float, float, float, float] | None = None

    def __post_init__(self):
        pts = np.asarray(self.points, dtype=np.float64)
        if pts.ndim != 3 or pts.shape[2] != 4:
            raise NurbsError(f"surface control net must be (n_v, n_u, 4), got shape {pts.shape}")
        nv, nu = pts.shape[:2]
        _check_weights(pts, "surface")
        ku = check_knots(self.knots_u, self.degree_u, nu, "u knot vector")
        kv = check_knots(self.knots_v, self.degree_v, nv, "v knot vector")
        if self.domain is None:
            dom = (ku[self.degree_u], ku[nu], kv[self.degree_v], kv[nv])
        else:
            dom = tuple(float(x) for x in self.domain)
        _check_range(ku, self.degree_u, nu, dom[0], dom[1], "u")
        _check_range(kv, self.degree_v, nv, dom[2], dom[3], "v")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "knots_u", ku)
        object.__setattr__(self, "knots_v", kv)
        object.__setattr__(self, "domain", tuple(float(x) for x in dom))

    @property
    def rational(self) -> bool:
        return bool(np.any(self.points[..., 3] != 1.0))

    def evaluate(self, u: float, v: float) -> np.ndarray:
        """Euclidean point at (u, v): de Boor along u for every row, then along v."""
        h = homogeneous(self.points)
        rows = de_boor(self.knots_u, self.degree_u, np.moveaxis(h, 1, 0), u)  # (n_v, 4)
        p = de_boor(self.knots_v, self.degree_v, rows, v)
        return p[:3] / p[3]

    def evaluate_many(self, u, v) -> np.ndarray:
        """Euclidean points (N, 3) at many parameter pairs."""
        h = homogeneous(self.points)
        nv, nu = h.shape[:2]
        su, bu = basis_functions(self.knots_u, self.degree_u, nu, u)
        sv, bv = basis_functions(self.knots_v, self.degree_v, nv, v)
        iu = su[:, None] - self.degree_u + np.arange(self.degree_u + 1)
        iv = sv[:, None] - self.degree_v + np.arange(self.degree_v + 1)
        block = h[iv[:, :, None], iu[:, None, :]]           # (N, q+1, p+1, 4)
        p = np.einsum("ns,nr,nsrc->nc", bv, bu, block)
        return p[:, :3] / p[:, 3:]

    def bezier_patches(self) -> BezierNet:
        """Exact Bezier patches covering the domain, v span outer, u span inner."""
        p, q = self.degree_u, self.degree_v
        u0, u1, v0, v1 = self.domain
        Tu, su, spu = decomposition(self.knots_u, p, u0, u1)
        Tv, sv, spv = decomposition(self.knots_v, q, v0, v1)
        rational = self.rational
        if rational:
            net = euclidean(sandwich(Tv, homogeneous(self.points), Tu))
        else:  # integral: refine x y z only so that w stays exactly 1
            xyz = sandwich(Tv, self.points[..., :3], Tu)
            net = np.concatenate([xyz, np.ones(xyz.shape[:2] + (1,))], axis=2)
        pts, doms, rat = [], [], []
        for a, (va, vb) in zip(sv, spv):
            for b, (ua, ub) in zip(su, spu):
                block = net[a:a + q + 1, b:b + p + 1].reshape(-1, 4)
                pts.append(np.ascontiguousarray(block))
                doms.append((ua, ub, va, vb))
                rat.append(bool(rational and np.any(block[:, 3] != 1.0)))
        return BezierNet(p, q, pts, np.array(doms, dtype=np.float64).reshape(-1, 4), rat)


def bezier_surface(degree_u, degree_v, grid, breaks_u=(0.0, 1.0), breaks_v=(0.0, 1.0),
                   domain=None) -> NurbsSurface:
    """A (piecewise) Bezier surface as a NURBS surface; grid (n_v, n_u, 4) [j, i]."""
    return NurbsSurface(degree_u, degree_v, bezier_knots(breaks_u, degree_u),
                        bezier_knots(breaks_v, degree_v), grid, domain)


@dataclass
class SurfaceInfo:
    """Where a free-form surface came from; one per NURBS surface in Scene.surfaces."""
    name: str
    source: str                  # file as written in the scene
    kind: str                    # 'bezier' | 'bspline' | 'nurbs' | 'revolution'
    rational: bool
    trimmed: bool
    degree: tuple[int, int]
    domain: tuple[float, float, float, float]
    first_patch: int = -1        # global patch index, filled by the scene
    patch_count: int = 0
    object: int = -1
    entity: dict = field(default_factory=dict)  # OBJ: {'line': n}; IGES: type, DE number, ...


@dataclass
class FreeformSurface:
    """A loaded free-form surface: the NURBS, its trimming loops and where it came from.

    loops: list[tracer.trim.TrimLoop] in the surface's parameter space;
    curves: the loops as read, [(kind, [(NurbsCurve, t0, t1), ...]), ...] (for writers, tests).
    """
    surface: NurbsSurface
    info: SurfaceInfo
    loops: list = field(default_factory=list)
    curves: list = field(default_factory=list)


@dataclass
class FreeformModel:
    """What a free-form file loader returns: surfaces in file order and an import report."""
    surfaces: list[FreeformSurface]
    report: dict = field(default_factory=dict)
