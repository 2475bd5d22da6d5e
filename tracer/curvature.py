"""Surface curvature at hits, for the threshold of detail of reflected and refracted rays.

A ray beam of width w that meets a surface of curvature k leaves it spread by about 2 k w more
per unit length (a curved mirror), so a secondary ray of the adaptive criterion grows its
threshold of detail by that much beside its parent's growth (lighting.py; Lempitsky 3.6 keeps
the parent's growth only). The largest principal curvature is taken from second differences of
the patch in float64 (any degree, rational or not), at the hit's parameters within its patch.
"""
from __future__ import annotations

import numpy as np

from .trim import bernstein

STEP = 1e-4  # parameter step of the differences


def _points(grids: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(k, 3) surface points of homogeneous grids (k, m + 1, n + 1, 4) at (u, v)."""
    m, n = grids.shape[1] - 1, grids.shape[2] - 1
    bu, bv = bernstein(m, u), bernstein(n, v)
    h = 0.0
    for i in range(m + 1):  # term by term (fixed_order.py): the same bits on every machine
        for j in range(n + 1):
            h = h + (bu[:, i] * bv[:, j])[:, None] * grids[:, i, j]
    return h[:, :3] / h[:, 3:]


def patch_grids(scene, patches: np.ndarray):
    """{(m, n): (indices into patches, homogeneous grids (k, m + 1, n + 1, 4))} of scene patches."""
    out = {}
    m_all, n_all = np.asarray(scene.degree_u)[patches], np.asarray(scene.degree_v)[patches]
    for m, n in set(zip(m_all.tolist(), n_all.tolist())):
        idx = np.nonzero((m_all == m) & (n_all == n))[0]
        start = np.asarray(scene.point_start)[patches[idx]]
        rows = start[:, None] + np.arange((m + 1) * (n + 1))[None, :]
        pts = np.asarray(scene.points)[rows]  # Euclidean + weight, v-major (j * (m + 1) + i)
        h = np.concatenate([pts[..., :3] * pts[..., 3:], pts[..., 3:]], axis=-1)
        out[(m, n)] = (idx, h.reshape(len(idx), n + 1, m + 1, 4).transpose(0, 2, 1, 3))
    return out


def max_curvature(scene, patches: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(k,) the largest absolute principal curvature of scene patches (k,) at parameters uv (k, 2)
    in [0, 1]^2 of each patch; 0 where the surface is degenerate there."""
    kappa = np.zeros(len(patches))
    for (m, n), (idx, grids) in patch_grids(scene, np.asarray(patches)).items():
        u = np.clip(uv[idx, 0], STEP, 1.0 - STEP)
        v = np.clip(uv[idx, 1], STEP, 1.0 - STEP)
        at = {(a, b): _points(grids, u + a * STEP, v + b * STEP) for a in (-1, 0, 1) for b in (-1, 0, 1)}
        su = (at[1, 0] - at[-1, 0]) / (2 * STEP)
        sv = (at[0, 1] - at[0, -1]) / (2 * STEP)
        suu = (at[1, 0] - 2 * at[0, 0] + at[-1, 0]) / STEP ** 2
        svv = (at[0, 1] - 2 * at[0, 0] + at[0, -1]) / STEP ** 2
        suv = (at[1, 1] - at[1, -1] - at[-1, 1] + at[-1, -1]) / (4 * STEP ** 2)
        normal = np.cross(su, sv)
        area = np.linalg.norm(normal, axis=1)
        ok = area > 0
        normal[ok] /= area[ok, None]
        e, f, g = (np.sum(a * b, axis=1) for a, b in ((su, su), (su, sv), (sv, sv)))
        l_, m_, n_ = (np.sum(normal * s, axis=1) for s in (suu, suv, svv))
        det = e * g - f * f  # principal curvatures: roots of det k^2 - b k + c
        b = e * n_ - 2 * f * m_ + g * l_
        c = l_ * n_ - m_ * m_
        with np.errstate(invalid="ignore", divide="ignore"):
            root = np.sqrt(np.maximum(b * b - 4 * det * c, 0.0))
            k = (np.abs(b) + root) / (2 * det)
        kappa[idx] = np.where(ok & (det > 0) & np.isfinite(k), k, 0.0)
    return kappa


def patch_parameters(geom, patches: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The hits' (u, v) in [0, 1]^2 of their scene patches, from the surface's parameters (a NURBS
    surface's, where the patch is one of its Bezier pieces) that the kernel reports."""
    n = int(geom.leaf_patch.max()) + 1
    lo = np.full((n, 2), np.inf)
    hi = np.full((n, 2), -np.inf)
    dom = np.asarray(geom.leaf_domain)
    np.minimum.at(lo, geom.leaf_patch, dom[:, [0, 2]])
    np.maximum.at(hi, geom.leaf_patch, dom[:, [1, 3]])
    span = hi[patches] - lo[patches]
    return np.where(span > 0, (uv - lo[patches]) / np.where(span > 0, span, 1.0), 0.5)
