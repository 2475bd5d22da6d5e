"""The study's truth (issue 14 item 1): psrt's float64 hits polished by Newton's method on the patch.

The truth must not come from the search being measured: the float64 reference's hit (its patch
and parameters) only starts Newton's method on S(u, v) = o + t d in (u, v, t), evaluated from the
scene's control points in float64 by Bernstein sums; a polished root is accepted only where it
stays inside the reference's hit box (the search's bound; widened by BOX_SLACK_ULPS), its parameters in [0, 1]^2 and its
residual tiny, so a root that wandered to another sheet of the surface is dropped, not scored.
"""
from __future__ import annotations

import numpy as np

from .curvature import patch_grids, patch_parameters
from .trim import bernstein

NEWTON_STEPS = 8
RESIDUAL = 1e-12    # accepted residual, relative to the scene's size
# The reference's float64 box is a few ulps wide, and the root is only known to within the rounding
# of o + t d: the box is widened by this many float64 ulps of the ray's magnitude |o| + t |d| per
# coordinate before the test (about 1e-14 of the scene's size; the errors scored are far above it).
BOX_SLACK_ULPS = 8


def _bernstein_with_derivative(deg: int, t: np.ndarray):
    """(B, dB), each (k, deg + 1): Bernstein polynomials of degree deg at t (k,) and their derivatives."""
    b = bernstein(deg, t)
    if deg == 0:
        return b, np.zeros_like(b)
    b1 = bernstein(deg - 1, t)
    db = np.zeros_like(b)
    db[:, 1:] += deg * b1      # d/dt B_i^n = n (B_{i-1}^{n-1} - B_i^{n-1})
    db[:, :-1] -= deg * b1
    return b, db


def surface_and_partials(grids: np.ndarray, u: np.ndarray, v: np.ndarray):
    """(S, S_u, S_v), each (k, 3): points and first partials of homogeneous grids (k, m + 1, n + 1, 4)
    at (u, v), rational or not (quotient rule on the homogeneous sums)."""
    m, n = grids.shape[1] - 1, grids.shape[2] - 1
    bu, dbu = _bernstein_with_derivative(m, u)
    bv, dbv = _bernstein_with_derivative(n, v)
    h = hu = hv = 0.0
    for i in range(m + 1):  # term by term (fixed_order.py): the same bits on every machine
        for j in range(n + 1):
            g = grids[:, i, j]
            h = h + (bu[:, i] * bv[:, j])[:, None] * g
            hu = hu + (dbu[:, i] * bv[:, j])[:, None] * g
            hv = hv + (bu[:, i] * dbv[:, j])[:, None] * g
    w = h[:, 3:]
    s = h[:, :3] / w
    return s, (hu[:, :3] - s * hu[:, 3:]) / w, (hv[:, :3] - s * hv[:, 3:]) / w


def _det3(a, b, c):
    """Determinants of the 3 x 3 matrices with columns a, b, c (k, 3), term by term."""
    return (a[:, 0] * (b[:, 1] * c[:, 2] - b[:, 2] * c[:, 1]) - b[:, 0] * (a[:, 1] * c[:, 2] - a[:, 2] * c[:, 1])
            + c[:, 0] * (a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]))


def newton(grids, u, v, t, origin, direction, steps: int = NEWTON_STEPS):
    """(u, v, t, point, residual) after Newton's method on S(u, v) - o - t d = 0 (Cramer's rule)."""
    for _ in range(steps):
        s, su, sv = surface_and_partials(grids, u, v)
        f = s - origin - t[:, None] * direction
        det = _det3(su, sv, -direction)
        with np.errstate(invalid="ignore", divide="ignore"):
            du = _det3(f, sv, -direction) / det
            dv = _det3(su, f, -direction) / det
            dt = _det3(su, sv, f) / det
        ok = np.isfinite(du) & np.isfinite(dv) & np.isfinite(dt)
        u, v, t = u - np.where(ok, du, 0.0), v - np.where(ok, dv, 0.0), t - np.where(ok, dt, 0.0)
    s = surface_and_partials(grids, u, v)[0]
    residual = np.sum(np.abs(s - origin - t[:, None] * direction), axis=1)
    return u, v, t, s, residual


def box_slack(origin, direction, t):
    """(k, 3): how far a point on the rays (k, 3) at t (k,) is only known, BOX_SLACK_ULPS float64 ulps of
    |o| + t |d| per coordinate; hit boxes are widened by it before they are asked to hold the truth."""
    return BOX_SLACK_ULPS * np.spacing(np.abs(origin) + np.abs(t[:, None] * direction))


def polished_truth(scene, ref_geometry, ref, size: float):
    """(positions (H, W, 3) float64, accepted (H, W) bool): the float64 reference's hits polished by
    Newton, accepted where the root stays in the reference's hit box, in the patch's [0, 1]^2 and
    with residual at most RESIDUAL * size."""
    h, w = ref.hit.shape
    truth = np.full((h, w, 3), np.nan)
    accepted = np.zeros((h, w), bool)
    rows = np.flatnonzero(ref.hit.reshape(-1))
    if rows.size == 0:
        return truth, accepted
    patch = ref.patch.reshape(-1)[rows].astype(np.int64)
    uv = patch_parameters(ref_geometry, patch, ref.uv.reshape(-1, 2)[rows])
    origin = ref.ray_origin.reshape(-1, 3)[rows].astype(np.float64)
    direction = ref.ray_dir.reshape(-1, 3)[rows].astype(np.float64)
    t0 = ref.t.reshape(-1)[rows].astype(np.float64)
    lo, hi = ref.box_min.reshape(-1, 3)[rows], ref.box_max.reshape(-1, 3)[rows]
    slack = box_slack(origin, direction, t0)
    lo, hi = lo - slack, hi + slack
    flat_truth, flat_ok = truth.reshape(-1, 3), accepted.reshape(-1)
    for (_m, _n), (idx, grids) in patch_grids(scene, patch).items():
        u, v, t, point, residual = newton(grids, uv[idx, 0], uv[idx, 1], t0[idx], origin[idx], direction[idx])
        ok = ((u >= 0) & (u <= 1) & (v >= 0) & (v <= 1) & (residual <= RESIDUAL * size)
              & np.all((point >= lo[idx]) & (point <= hi[idx]), axis=1))
        flat_truth[rows[idx]] = point
        flat_ok[rows[idx]] = ok
    return truth, accepted
