"""Trimming loops in a surface's parameter space, flat arrays for the kernel, a reference test.

A loop is a closed chain of 2-D (rational) Bezier segments, each stored as
rows (u, v, w): Euclidean parameter point and weight, not premultiplied (the
Scene convention). `trim` loops keep their inside, `hole` loops remove it.

Inside test (Dammertz 2.6): shoot the ray from (u, v) towards +u and count
crossings over all loops of the surface; (u, v) is kept iff
`start_inside[surface] XOR odd`. start_inside is True for a surface with holes
but no outer loop (its outer boundary is the parameter rectangle), so nested
loops (outer trim, holes, islands in holes) all come out right.

Crossings use half-open sides: a point is "above" when its v >= the query v.
Per segment (cases 1-4 of Dammertz 2.6): box left of the point or wholly
above/below -> no crossing; box right of the point -> parity from the two
endpoints' sides; otherwise split at t = 1/2 and recurse, until the box's L1
diameter stops shrinking (float precision), where the endpoint rule decides.
Segment endpoints are taken from the stored Euclidean values (never
recomputed as wu/w), and consecutive segments of a loop share their joint
exactly, so the sides of a joint agree between the two segments.

Orientation: loops are normalised so that `trim` loops run counter-clockwise
and `hole` loops clockwise in the (u, v) plane (kept region on the left).
The parity test does not need it; a winding-number test could use it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.fixed_order import dot
from tracer.nurbs import NurbsCurve, homogeneous, split_bezier

KINDS = {"trim": 1, "hole": -1}
MAX_SPLIT_DEPTH = 96  # float64 boxes stop shrinking long before this


class TrimError(ValueError):
    """A loop that is not closed, empty, or otherwise unusable."""


@dataclass
class TrimLoop:
    """One closed loop: segments of (deg+1, 3) arrays (u, v, w)."""
    kind: str                      # 'trim' | 'hole'
    segments: list[np.ndarray]
    bridged_gap: float = 0.0       # widest gap closed with a straight segment


def signed_area(segments, samples: int = 16) -> float:
    """Signed area of the closed chain (positive = counter-clockwise), from a sampled polygon."""
    pts = np.concatenate([s[:1, :2] if len(s) == 2 else sample_segment(s, samples)[:-1]
                          for s in segments])
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def bernstein(n: int, t: np.ndarray) -> np.ndarray:
    """(len(t), n+1) Bernstein basis values of degree n."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    i = np.arange(n + 1)
    coef = np.array([math.comb(n, k) for k in i], dtype=np.float64)
    return coef * t ** i * (1 - t) ** (n - i)


def evaluate_segment(seg: np.ndarray, t, derivative: bool = False):
    """Points (len(t), 2) of a rational Bezier segment (u, v, w rows); with derivative, also d/dt."""
    h = homogeneous(seg)
    n = len(h) - 1
    p = dot(bernstein(n, t), h)
    xy = p[:, :2] / p[:, 2:3]
    if not derivative:
        return xy
    d = n * dot(bernstein(n - 1, t), np.diff(h, axis=0))
    return xy, (d[:, :2] - xy * d[:, 2:3]) / p[:, 2:3]


def sample_segment(seg: np.ndarray, samples: int) -> np.ndarray:
    """(samples, 2) points along one rational Bezier segment, ends exact."""
    out = evaluate_segment(seg, np.linspace(0.0, 1.0, samples))
    out[0], out[-1] = seg[0, :2], seg[-1, :2]
    return out


def make_loop(kind: str, segments, close_tol: float) -> TrimLoop:
    """Chain Bezier segments into a closed loop.

    Gaps (between consecutive segments and from the last back to the first)
    up to close_tol are closed with a straight segment, so the chain is closed
    exactly; a wider gap is a TrimError. The loop is then oriented (trim CCW,
    hole CW).
    """
    if kind not in KINDS:
        raise TrimError(f"loop kind must be 'trim' or 'hole', got {kind!r}")
    segs = [np.array(s, dtype=np.float64) for s in segments]
    if not segs:
        raise TrimError("empty trimming loop")
    out, widest = [], 0.0
    for i, s in enumerate(segs):
        if s.ndim != 2 or s.shape[1] != 3 or len(s) < 2:
            raise TrimError(f"segment {i}: expected (degree+1, 3) points u v w, got {s.shape}")
        if np.any(s[:, 2] <= 0) or not np.all(np.isfinite(s)):
            raise TrimError(f"segment {i}: points must be finite with weights > 0")
    chain = segs + [segs[0]]
    for i, s in enumerate(segs):
        out.append(s)
        a, b = s[-1, :2], chain[i + 1][0, :2]
        if np.array_equal(a, b):
            continue
        gap = float(np.hypot(*(a - b)))
        if gap > close_tol:
            where = "last and first" if i == len(segs) - 1 else f"{i} and {i + 1}"
            raise TrimError(f"trimming loop is not closed: gap {gap:.3g} between segments {where} "
                            f"(allowed {close_tol:.3g})")
        widest = max(widest, gap)
        out.append(np.array([[a[0], a[1], 1.0], [b[0], b[1], 1.0]]))
    if signed_area(out) * KINDS[kind] < 0:
        out = [s[::-1].copy() for s in reversed(out)]
    return TrimLoop(kind, out, widest)


def curve_segments(curve: NurbsCurve, lo: float | None = None, hi: float | None = None):
    """Bezier segments (u, v, w) of a 2-D NURBS curve on [lo, hi] (default its domain)."""
    if lo is not None or hi is not None:
        curve = NurbsCurve(curve.degree, curve.knots, curve.points,
                           (curve.domain[0] if lo is None else lo,
                            curve.domain[1] if hi is None else hi))
    return [seg for seg, _ in curve.bezier_segments()]


# ---- remapping loops through a monotone change of parameter ------------------------

def fit_cubics(f, df, tol: float, max_depth: int = 40, breaks=(0.0, 1.0)):
    """Cubic Bezier pieces (Hermite: ends and end tangents) of a plane curve f(s), s in [0, 1].

    breaks: parameters where f may lose smoothness (pieces start and end there).
    f(s) -> (N, 2) points and df(s) -> (N, 2) derivatives, vectorised over s.
    An interval is halved until its cubic is within tol of f at nine interior
    parameters (same parameter, so an upper bound of the distance between the
    curves up to sampling). Returns [(s0, s1, ctrl (4, 2))] in order of s.
    """
    r = np.linspace(0, 1, 11)
    hermite = np.column_stack([(1 - r) ** 2 * (1 + 2 * r), r * (1 - r) ** 2,
                               -r * r * (1 - r), r * r * (3 - 2 * r)])  # q0, d0, d1, q1
    b = np.asarray(breaks, dtype=np.float64)
    todo, pieces = np.column_stack([b[:-1], b[1:]]), []
    for depth in range(max_depth + 1):
        s = (todo[:, :1] + r * (todo[:, 1:] - todo[:, :1])).ravel()
        q = f(s).reshape(len(todo), 11, 2)
        dq = df(s).reshape(len(todo), 11, 2) * (todo[:, 1:] - todo[:, :1])[:, :, None]
        q0, q1, d0, d1 = q[:, 0], q[:, -1], dq[:, 0], dq[:, -1]
        approx = np.einsum("rk,kic->irc", hermite, np.stack([q0, d0, d1, q1]))
        err = np.hypot(*np.moveaxis(approx - q, 2, 0)).max(axis=1)
        done = (err <= tol) | (depth == max_depth)
        for i in np.flatnonzero(done):
            cubic = np.array([q0[i], q0[i] + d0[i] / 3, q1[i] - d1[i] / 3, q1[i]])
            pieces.append((float(todo[i, 0]), float(todo[i, 1]), cubic))
        rest = todo[~done]
        mid = 0.5 * (rest[:, :1] + rest[:, 1:])
        todo = np.concatenate([np.column_stack([rest[:, :1], mid]),
                               np.column_stack([mid, rest[:, 1:]])])
        if not len(todo):
            break
    pieces.sort(key=lambda x: x[0])
    return pieces


def _crossings(seg, maps, samples: int = 65) -> list[float]:
    """Parameters s in (0, 1) where a mapped coordinate of the segment crosses a break of its map.

    A map may offer `breaks()` (e.g. the knots of a circle parameterisation,
    where the map is only C1); fitting piecewise from there converges fast.
    """
    s = np.linspace(0.0, 1.0, samples)
    xy = evaluate_segment(seg, s)
    cuts = []
    for k, m in enumerate(maps):
        if m is None or not hasattr(m, "breaks"):
            continue
        for b in m.breaks():
            g = xy[:, k] - b
            for i in np.flatnonzero((g[:-1] < 0) != (g[1:] < 0)):
                lo, hi, glo = s[i], s[i + 1], g[i]
                for _ in range(60):  # bisection to float precision
                    mid = 0.5 * (lo + hi)
                    gm = evaluate_segment(seg, np.array([mid]))[0, k] - b
                    if (gm < 0) == (glo < 0):
                        lo, glo = mid, gm
                    else:
                        hi = mid
                cuts.append(0.5 * (lo + hi))
    cuts = sorted(c for c in cuts if 1e-12 < c < 1 - 1e-12)
    return [c for i, c in enumerate(cuts) if i == 0 or c > cuts[i - 1]]


def remap_segments(segments, maps, tol: float):
    """Push segments through per-axis monotone maps, e.g. angle -> rational circle parameter.

    maps: (map_u, map_v), each None (identity) or an object with vectorised
    `param(x)` and `dparam(x)`. Segments along a line of a mapped axis stay
    exact (their point set maps onto a line); others are replaced by cubic
    Hermite pieces, halved until they match the mapped curve within tol at
    nine interior samples. Returns (segments, number of approximated input segments).
    """
    out, approximated = [], 0

    def fwd(xy):
        return np.column_stack([m.param(xy[:, k]) if m else xy[:, k]
                                for k, m in enumerate(maps)])

    def fwd_d(xy, dxy):
        return np.column_stack([m.dparam(xy[:, k]) * dxy[:, k] if m else dxy[:, k]
                                for k, m in enumerate(maps)])

    for seg in segments:
        const = [bool(np.all(seg[:, k] == seg[0, k])) for k in (0, 1)]
        if all(const[k] or maps[k] is None for k in (0, 1)):
            mapped = seg.copy()
            mapped[:, :2] = fwd(seg[:, :2])
            out.append(mapped)
            continue
        if const[0] or const[1]:  # on an axis-parallel line: same point set, straight ends
            ab = fwd(seg[[0, -1], :2])
            out.append(np.column_stack([ab, np.ones(2)]))
            continue
        approximated += 1

        def f(s, seg=seg):
            return fwd(evaluate_segment(seg, s))

        def df(s, seg=seg):
            return fwd_d(*evaluate_segment(seg, s, derivative=True))

        cuts = _crossings(seg, maps)
        pieces = [np.column_stack([c, np.ones(4)])
                  for _, _, c in fit_cubics(f, df, tol, breaks=[0.0, *cuts, 1.0])]
        pieces[0][0, :2], pieces[-1][-1, :2] = fwd(seg[[0, -1], :2])  # ends from stored values
        for i in range(1, len(pieces)):  # joints bit-identical
            pieces[i][0, :2] = pieces[i - 1][-1, :2]
        out.extend(pieces)
    for i in range(1, len(out)):  # keep the chain closed exactly where it was
        if np.allclose(out[i][0, :2], out[i - 1][-1, :2], rtol=0, atol=tol):
            out[i][0, :2] = out[i - 1][-1, :2]
    return out, approximated


# ---- flat arrays ---------------------------------------------------------------------

@dataclass(frozen=True)
class TrimSet:
    """All trimming loops of a scene, flat.

    seg_points      (S_total, 3) float64  u, v, w of every control point (Euclidean + weight)
    seg_start       (n_segs + 1,) int64   segment s has points seg_start[s] .. seg_start[s+1]-1
    seg_degree      (n_segs,) int32       = points of the segment - 1
    surf_seg_start  (n_surfaces + 1,) int64  segments of surface f: surf_seg_start[f] .. [f+1]-1
    has_trim        (n_surfaces,) bool    False: skip all trimming work for the surface
    start_inside    (n_surfaces,) bool    initial parity (holes but no outer loop)
    surf_loop_start (n_surfaces + 1,) int64, loop_seg_start (n_loops + 1,) int64,
    loop_kind       (n_loops,) int8 (+1 trim, -1 hole): the loop structure, for plots and checks
    """
    seg_points: np.ndarray
    seg_start: np.ndarray
    seg_degree: np.ndarray
    surf_seg_start: np.ndarray
    has_trim: np.ndarray
    start_inside: np.ndarray
    surf_loop_start: np.ndarray
    loop_seg_start: np.ndarray
    loop_kind: np.ndarray

    @property
    def n_surfaces(self) -> int:
        return len(self.has_trim)

    @property
    def n_segments(self) -> int:
        return len(self.seg_degree)

    def segments(self, surface: int) -> list[np.ndarray]:
        a, b = self.surf_seg_start[surface], self.surf_seg_start[surface + 1]
        return [self.seg_points[self.seg_start[s]:self.seg_start[s + 1]] for s in range(a, b)]


def build_trimset(loops_per_surface: list[list[TrimLoop]]) -> TrimSet:
    """Flatten the loops of every surface (surface order = list order)."""
    pts, seg_start, deg, surf_seg, loop_seg, kinds, surf_loop = [], [0], [], [0], [0], [], [0]
    start_inside = []
    for loops in loops_per_surface:
        for loop in loops:
            for s in loop.segments:
                pts.append(s)
                seg_start.append(seg_start[-1] + len(s))
                deg.append(len(s) - 1)
            loop_seg.append(len(deg))
            kinds.append(KINDS[loop.kind])
        surf_seg.append(len(deg))
        surf_loop.append(len(kinds))
        start_inside.append(bool(loops) and not any(l.kind == "trim" for l in loops))
    n = len(loops_per_surface)
    surf_seg = np.array(surf_seg, np.int64)
    return TrimSet(
        seg_points=np.concatenate(pts).astype(np.float64) if pts else np.zeros((0, 3)),
        seg_start=np.array(seg_start, np.int64), seg_degree=np.array(deg, np.int32),
        surf_seg_start=surf_seg, has_trim=np.diff(surf_seg) > 0 if n else np.zeros(0, bool),
        start_inside=np.array(start_inside, bool),
        surf_loop_start=np.array(surf_loop, np.int64), loop_seg_start=np.array(loop_seg, np.int64),
        loop_kind=np.array(kinds, np.int8))


def empty_trimset(n_surfaces: int = 0) -> TrimSet:
    return build_trimset([[] for _ in range(n_surfaces)])


# ---- reference inside test ----------------------------------------------------------

def segment_parity(seg: np.ndarray, u: float, v: float, stats: list | None = None) -> int:
    """Parity (0/1) of the crossings of the ray from (u, v) towards +u with one segment."""
    odd = 0
    stack = [(homogeneous(seg), seg[0, :2], seg[-1, :2], math.inf, 0)]
    while stack:
        h, a, b, prev, depth = stack.pop()
        if stats is not None:
            stats[0] += 1
        pu = h[:, 0] / h[:, 2]
        pv = h[:, 1] / h[:, 2]
        pu[0], pv[0], pu[-1], pv[-1] = a[0], a[1], b[0], b[1]
        umin, umax, vmin, vmax = pu.min(), pu.max(), pv.min(), pv.max()
        if umax < u or vmin >= v or vmax < v:   # cases 1, 2: left of the point, above, below
            continue
        flip = (a[1] >= v) != (b[1] >= v)
        diam = (umax - umin) + (vmax - vmin)
        if umin > u or diam >= prev or depth >= MAX_SPLIT_DEPTH:  # case 3, or precision spent
            odd ^= flip
            continue
        left, right = split_bezier(h)           # case 4
        mid = left[-1, :2] / left[-1, 2]
        stack.append((left, a, mid, diam, depth + 1))
        stack.append((right, mid, b, diam, depth + 1))
    return odd


def inside(trims: TrimSet, surface: int, u: float, v: float, stats: list | None = None) -> bool:
    """Is (u, v) (surface parameters) in the kept region of the surface? Untrimmed: True.

    stats, if given as [0], counts the boxes examined (the effort).
    """
    if surface < 0 or not trims.has_trim[surface]:
        return True
    odd = int(trims.start_inside[surface])
    for seg in trims.segments(surface):
        odd ^= segment_parity(seg, float(u), float(v), stats)
    return bool(odd)


def loops_for_plot(trims: TrimSet, surface: int, samples: int = 24) -> list[dict]:
    """Polylines of the surface's loops: [{'kind': 'trim'|'hole', 'points': (N, 2)}]."""
    if surface < 0 or surface >= trims.n_surfaces:
        return []
    out = []
    names = {v: k for k, v in KINDS.items()}
    for loop in range(trims.surf_loop_start[surface], trims.surf_loop_start[surface + 1]):
        parts = []
        for s in range(trims.loop_seg_start[loop], trims.loop_seg_start[loop + 1]):
            seg = trims.seg_points[trims.seg_start[s]:trims.seg_start[s + 1]]
            parts.append(sample_segment(seg, 2 if len(seg) == 2 else samples)[:-1])
        pts = np.concatenate(parts)
        out.append({"kind": names[int(trims.loop_kind[loop])],
                    "points": np.vstack([pts, pts[:1]])})
    return out
