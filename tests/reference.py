"""Slow, obviously right references for the kernels (STYLE rule 6).

Everything here is plain numpy or exact rational arithmetic, written for
clarity, never for speed: Bernstein sums straight from the definition,
sub-patches by blossoming (not de Casteljau's midpoints, which the kernels and
tracer.geometry use), an exact slab test, and a float64 ray-patch intersection
by interval subdivision followed by Newton polishing.

Control grids are arrays P[i, j, xyz] (i along u, j along v), unlike the
kernels' flat point order k = j*(m+1) + i; `grid` and `flat` convert.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np

F32_BITS = 24


# ---- layout -----------------------------------------------------------------------

def grid(points, m: int, n: int) -> np.ndarray:
    """Flat points (count, 3) in the contract's order k = j*(m+1) + i -> P[i, j, :]."""
    pts = np.asarray(points)
    return pts.reshape(n + 1, m + 1, pts.shape[-1]).transpose(1, 0, 2)


def flat(P) -> np.ndarray:
    """P[i, j, :] -> flat points (count, 3), k = j*(m+1) + i."""
    P = np.asarray(P)
    return P.transpose(1, 0, 2).reshape(-1, P.shape[-1])


# ---- floats -----------------------------------------------------------------------

def ulp(x, bits: int = F32_BITS):
    """The kernel's unit in the last place of |x| for `bits`-bit mantissas: 2^(exponent - bits),
    with x = f * 2^exponent, 0.5 <= f < 1 (so ulp(1.0) = 2^-23 for float32). ulp(0) = 0."""
    x = np.abs(np.asarray(x, np.float64))
    _, e = np.frexp(x)
    return np.where(x > 0, np.ldexp(1.0, e - bits), 0.0)


def round32(x) -> np.ndarray:
    """Round float64 values to the nearest float32 and widen back."""
    return np.asarray(x, np.float64).astype(np.float32).astype(np.float64)


# ---- Bernstein form ---------------------------------------------------------------

def bernstein(n: int, i: int, t):
    """B_i^n(t) = C(n, i) t^i (1 - t)^(n - i); works for floats and Fractions."""
    return math.comb(n, i) * t ** i * (1 - t) ** (n - i)


def evaluate(P, u: float, v: float) -> np.ndarray:
    """S(u, v) = sum_ij B_i^m(u) B_j^n(v) P_ij, float64, straight from the definition."""
    P = np.asarray(P, np.float64)
    m, n = P.shape[0] - 1, P.shape[1] - 1
    bu = np.array([bernstein(m, i, u) for i in range(m + 1)])
    bv = np.array([bernstein(n, j, v) for j in range(n + 1)])
    return np.einsum("i,j,ijc->c", bu, bv, P)


def derivatives(P, u: float, v: float):
    """(S, dS/du, dS/dv, d2S/dudv) at (u, v) from the difference grids (hodographs)."""
    P = np.asarray(P, np.float64)
    m, n = P.shape[0] - 1, P.shape[1] - 1
    s = evaluate(P, u, v)
    su = m * evaluate(P[1:] - P[:-1], u, v) if m > 0 else np.zeros(3)
    sv = n * evaluate(P[:, 1:] - P[:, :-1], u, v) if n > 0 else np.zeros(3)
    d2 = P[1:, 1:] - P[1:, :-1] - P[:-1, 1:] + P[:-1, :-1]
    suv = m * n * evaluate(d2, u, v) if m > 0 and n > 0 else np.zeros(3)
    return s, su, sv, suv


def normal(P, u: float, v: float) -> np.ndarray:
    """Unit dS/du x dS/dv (no fallback: use it away from degenerate points)."""
    _, su, sv, _ = derivatives(P, u, v)
    c = np.cross(su, sv)
    return c / np.linalg.norm(c)


# ---- sub-patches by blossoming -------------------------------------------------------

@lru_cache(maxsize=None)
def restriction_matrix(n: int, t0, t1) -> np.ndarray:
    """(n+1, n+1) object matrix M: the control points of a degree-n Bezier curve P restricted to
    [t0, t1] are Q = M @ P. Q_k is the blossom of the curve at (t0 x (n - k), t1 x k), and the
    blossom of B_i^n there is sum_a B_a^(n-k)(t0) B_(i-a)^k(t1) (a of the i factors t taken at
    t0, the others at t1). Exact when t0 and t1 are Fractions."""
    M = np.empty((n + 1, n + 1), dtype=object)
    for k in range(n + 1):
        for i in range(n + 1):
            M[k, i] = sum(bernstein(n - k, a, t0) * bernstein(k, i - a, t1)
                          for a in range(max(0, i - k), min(i, n - k) + 1))
    return M


def restrict(P, axis: int, t0, t1) -> np.ndarray:
    """The control points of P (any array, Bernstein coefficients along `axis`) on [t0, t1] of that
    parameter. An object array of Fractions is restricted exactly (t0, t1 taken as Fractions)."""
    P = np.asarray(P)
    exact = P.dtype == object
    M = restriction_matrix(P.shape[axis] - 1, *((Fraction(t0), Fraction(t1)) if exact else (t0, t1)))
    Q = np.tensordot(M if exact else M.astype(np.float64), np.moveaxis(P, axis, 0), axes=(1, 0))
    return np.moveaxis(Q, 0, axis)


def split(P, axis: int, t=0.5):
    """Split a grid P[i, j, :] at t along u (axis 0) or v (axis 1): (lower, upper)."""
    return restrict(P, axis, 0, t), restrict(P, axis, t, 1)


def exact(P) -> np.ndarray:
    """An object array of Fractions equal to the float array P."""
    return np.vectorize(Fraction, otypes=[object])(np.asarray(P, np.float64))


def box(points) -> np.ndarray:
    """Axis-aligned box (lo xyz, hi xyz) of points (..., 3)."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    return np.concatenate([pts.min(axis=0), pts.max(axis=0)])


# ---- ray against box ---------------------------------------------------------------

def slab_exact(bx, origin, direction, t_min=0.0):
    """Exact ray-box test in rational arithmetic: (hit, t_in, t_out) with t_in >= t_min.

    A zero direction component means: inside the slab (bounds included) or a miss, returned
    as (False, None, None); other misses return their empty interval t_in > t_out, so callers
    can tell by how much the ray missed.
    """
    t_in, t_out = Fraction(t_min), None
    for c in range(3):
        lo, hi = Fraction(bx[c]), Fraction(bx[3 + c])
        o, d = Fraction(origin[c]), Fraction(direction[c])
        if d == 0:
            if not lo <= o <= hi:
                return False, None, None
            continue
        a, b = sorted(((lo - o) / d, (hi - o) / d))
        t_in = max(t_in, a)
        t_out = b if t_out is None else min(t_out, b)
    if t_out is None:  # zero direction: the ray is a point inside the box
        return True, t_in, math.inf
    return t_in <= t_out, t_in, t_out


# ---- ray against patch -------------------------------------------------------------

@dataclass
class RefHit:
    """Closest ray-patch intersection found by `intersect_patch`.

    certain: False when some candidate region could not be resolved by Newton's method
    (tangent rays at silhouettes) and might hold a closer hit or a hit at all.
    """

    hit: bool
    t: float = math.inf
    u: float = math.nan
    v: float = math.nan
    point: np.ndarray | None = None
    certain: bool = True


def _ray_frame(d):
    w = d / np.linalg.norm(d)
    helper = np.eye(3)[int(np.argmin(np.abs(w)))]
    e1 = np.cross(w, helper)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(w, e1), w])


def _newton(P, o, d, frame, u, v, scale, iters=60):
    """Solve (S(u, v) - o) . e_k = 0 (k = 1, 2) from (u, v); returns (u, v) or None.

    Iterates until the residual stops decreasing (float64 noise), so the root is as accurate
    as float64 evaluation allows, and accepts it if the residual is tiny."""
    best, best_f, stale = None, math.inf, 0
    for _ in range(iters):
        s, su, sv, _ = derivatives(P, u, v)
        f = frame[:2] @ (s - o)
        size = float(np.abs(f).max())
        if size < best_f:
            best, best_f, stale = (u, v), size, 0
        else:
            stale += 1
        if size == 0.0 or stale >= 3:
            break
        jac = np.stack([frame[:2] @ su, frame[:2] @ sv], axis=1)
        if abs(np.linalg.det(jac)) < 1e-300:
            break
        du, dv = np.linalg.solve(jac, -f)
        u, v = u + du, v + dv
        if not (-0.5 < u < 1.5 and -0.5 < v < 1.5):
            break
    return best if best_f <= 1e-12 * scale else None


def intersect_patch(P, origin, direction, t_min=0.0, levels=12, max_leaves=512) -> RefHit:
    """Closest intersection of the ray origin + t*direction (t >= t_min) with patch P[i, j, :].

    Projects the grid onto the two planes through the ray, keeps the sub-patches whose
    projected control boxes contain the ray (de Casteljau quad splits, `levels` times), then
    polishes a root from the centre of every surviving leaf with Newton's method in float64.
    More than `max_leaves` survivors at any level (a ray along a collapsed edge): 64 of them,
    evenly spread, are polished and the answer is marked uncertain.
    """
    P = np.asarray(P, np.float64)
    o = np.asarray(origin, np.float64)
    d = np.asarray(direction, np.float64)
    length = float(np.linalg.norm(d))
    frame = _ray_frame(d)
    Q = (P - o) @ frame.T  # (m+1, n+1, 3): two distances from the ray, distance along it
    scale = float(np.abs(P).max() + np.abs(o).max())
    slack = 1e-12 * scale
    stack = Q[None]
    iv = np.array([[0.0, 1.0, 0.0, 1.0]])
    for level in range(levels + 1):
        flatq = stack.reshape(len(stack), -1, 3)
        lo, hi = flatq.min(axis=1), flatq.max(axis=1)
        keep = ((lo[:, 0] <= slack) & (hi[:, 0] >= -slack) & (lo[:, 1] <= slack) & (hi[:, 1] >= -slack)
                & (hi[:, 2] >= t_min * length - slack))
        stack, iv = stack[keep], iv[keep]
        if len(stack) == 0 or level == levels or len(stack) > max_leaves:
            break
        a, b = split(stack, 1)
        mid = 0.5 * (iv[:, 0] + iv[:, 1])
        iv = np.concatenate([np.column_stack([iv[:, 0], mid, iv[:, 2:]]),
                             np.column_stack([mid, iv[:, 1], iv[:, 2:]])])
        stack = np.concatenate([a, b])
        a, b = split(stack, 2)
        mid = 0.5 * (iv[:, 2] + iv[:, 3])
        iv = np.concatenate([np.column_stack([iv[:, :2], iv[:, 2], mid]),
                             np.column_stack([iv[:, :2], mid, iv[:, 3]])])
        stack = np.concatenate([a, b])
    best = RefHit(False)
    unresolved = []  # nearest distance along the ray of leaves Newton could not resolve
    if len(stack) > max_leaves:
        sample = np.linspace(0, len(stack) - 1, 64).astype(int)
        unresolved.append(stack[..., 2].min() / length)
        stack, iv = stack[sample], iv[sample]
    for q, (u0, u1, v0, v1) in zip(stack, iv):
        root = _newton(P, o, d, frame, 0.5 * (u0 + u1), 0.5 * (v0 + v1), scale)
        if root is None:
            unresolved.append(q[..., 2].min() / length)
            continue
        u, v = root
        wu, wv = u1 - u0, v1 - v0
        if not (u0 - wu <= u <= u1 + wu and v0 - wv <= v <= v1 + wv):
            # Newton left this leaf: a root inside it may have been skipped
            unresolved.append(q[..., 2].min() / length)
        if not (-1e-9 <= u <= 1 + 1e-9 and -1e-9 <= v <= 1 + 1e-9):
            continue  # a root of the extended surface, outside the patch
        u, v = min(max(u, 0.0), 1.0), min(max(v, 0.0), 1.0)
        s = evaluate(P, u, v)
        t = float((s - o) @ d) / length ** 2
        if t >= t_min and t < best.t:
            best = RefHit(True, t, u, v, s)
    best.certain = not any(t_leaf < best.t for t_leaf in unresolved)
    return best


def intersect_scene(patches, origin, direction, t_min=0.0, levels=12) -> RefHit:
    """Closest hit over a list of grids; the returned hit carries the patch index as `.patch`."""
    best, certain = RefHit(False), True
    best.patch = -1
    for k, P in enumerate(patches):
        h = intersect_patch(P, origin, direction, t_min, levels)
        certain = certain and h.certain
        if h.hit and h.t < best.t:
            best = h
            best.patch = k
    best.certain = certain
    return best


# ---- BVH ----------------------------------------------------------------------------

def _sah_area(lo, hi):
    e = np.maximum(hi - lo, 0.0)
    return 2.0 * (e[..., 0] * e[..., 1] + e[..., 1] * e[..., 2] + e[..., 2] * e[..., 0])


def _sah_split(boxes):
    """(order, count): the stable centroid order of the axis whose SAH cost of splitting after
    `count` of its boxes is lowest (first axis, then smallest count, on ties)."""
    centre = 0.5 * (boxes[:, :3] + boxes[:, 3:])
    best = (np.inf, None, 1)
    for axis in range(3):
        order = np.argsort(centre[:, axis], kind="stable")
        lo, hi = boxes[order, :3], boxes[order, 3:]
        left = _sah_area(np.minimum.accumulate(lo), np.maximum.accumulate(hi))[:-1]
        right = _sah_area(np.minimum.accumulate(lo[::-1]), np.maximum.accumulate(hi[::-1]))[::-1][1:]
        counts = np.arange(1, len(boxes))
        cost = left * counts + right * (len(boxes) - counts)
        k = int(np.argmin(cost))
        if cost[k] < best[0]:
            best = (cost[k], order, k + 1)
    return best[1], best[2]


def build_bvh(boxes):
    """(node_box, node_child, node_patch) of the full-sweep SAH BVH, built node by node with a
    stable argsort per node and axis (psrt's builder before the compiled one, O(n log^2 n))."""
    n = len(boxes)
    node_box = np.zeros((2 * n - 1, 6))
    node_child = np.full((2 * n - 1, 2), -1, np.int32)
    node_patch = np.full(2 * n - 1, -1, np.int32)
    count = 1
    work = [(0, np.arange(n))]  # (node, patches) still to place; the last pushed is built first
    while work:
        node, items = work.pop()
        sub = boxes[items]
        node_box[node, :3] = sub[:, :3].min(axis=0)
        node_box[node, 3:] = sub[:, 3:].max(axis=0)
        if len(items) == 1:
            node_patch[node] = items[0]
            continue
        order, k = _sah_split(sub)
        node_child[node] = (count, count + 1)
        work.append((count, items[order[:k]]))
        work.append((count + 1, items[order[k:]]))
        count += 2
    return node_box, node_child, node_patch
