"""Scene patches in the layout the kernels read: flat arrays in the working precision.

Each scene patch is pre-split (in float64; its rounding joins eps) into leaves, and control
points are stored relative to one frame origin per leaf (the centre of its
control-point box, a float32 number where float32 reaches), so they round relative to the leaf's
own extent instead of its distance from the world origin. The exact
rounding error of the stored points is measured here (`eps`, per patch and
axis); the kernel widens every box by it, so boxes contain the true surface
and patches sharing an edge cannot leave a crack between them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bvh import Bvh, build_bvh
from .limits import PRECISION_BITS, check_extent, check_weights, spacing, weight_scale
from .subpatch import max_depth_for
from .trim_kernel import segment_boxes

PRECISION_DTYPE = {"f32": np.float32, "f64": np.float64}


@dataclass(frozen=True)
class Geometry:
    """Kernel arrays. The kernel's "patches" are leaves: each scene patch pre-split 4^k ways
    (k = `presplit`), so that every leaf has its own small frame (see module docstring)."""

    precision: str
    ctrl: np.ndarray      # (4, total points) working dtype, local to the leaf's frame; row 3 the
                          # weight, rows 0-2 premultiplied by it (homogeneous) for rational patches
    pstart: np.ndarray    # (n_leaves + 1,) int64
    deg_u: np.ndarray     # (n_leaves,) int32
    deg_v: np.ndarray     # (n_leaves,) int32
    rational: np.ndarray  # (n_leaves,) int8: 1 for rational patches
    frame: np.ndarray     # (n_leaves, 3) float64 frame origin of each leaf
    grid: np.ndarray      # (n_leaves, 3) float64 step of the grid hit boxes are rounded onto, per
                          # axis (a power of two; 0 in float64: no grid), see grid_steps
    eps: np.ndarray       # (n_leaves, 3) float64 bound on |stored surface - true surface| per axis
    ctrl64: np.ndarray    # ctrl in float64 (the same array at f64): the kernel re-derives small
                          # sub-patches from it, so their error shrinks with them (intersect._refine)
    eps64: np.ndarray     # (n_leaves, 3) float64 the same bound for ctrl64
    leaf_box: np.ndarray  # (n_leaves, 6) float64 tight world boxes (one quad split, padded)
    bvh: Bvh
    leaf_domain: np.ndarray   # (n_leaves, 4) float64 u0 u1 v0 v1: the leaf in its surface's parameters
    patch_trim: np.ndarray    # (n_leaves,) int32 surface whose trimming loops apply, -1: none
    trim_arrays: tuple        # seg_points, seg_start, surf_seg_start, start_inside, seg_box (trim_kernel)
    leaf_patch: np.ndarray    # (n_leaves,) int32 the scene patch of each leaf
    leaf_param: np.ndarray    # (n_leaves, 4) float64 the leaf's u0 u1 v0 v1 within its scene patch
    presplit: int = 0

    @property
    def patch_box(self) -> np.ndarray:
        """(n_scene_patches, 6) world box of each scene patch (the union of its leaves' boxes)."""
        n = int(self.leaf_patch.max()) + 1
        box = np.empty((n, 6))
        box[:, :3] = np.inf
        box[:, 3:] = -np.inf
        np.minimum.at(box[:, :3], self.leaf_patch, self.leaf_box[:, :3])
        np.maximum.at(box[:, 3:], self.leaf_patch, self.leaf_box[:, 3:])
        return box

    def trims_for(self, use_trims: bool) -> tuple:
        """The kernel's trim tuple; with use_trims False no patch is trimmed."""
        patch_trim = self.patch_trim if use_trims else np.full_like(self.patch_trim, -1)
        return (patch_trim, self.leaf_domain) + self.trim_arrays

    @property
    def trim_points(self) -> int:
        """Largest number of control points of a trimming segment (for scratch sizes)."""
        starts = self.trim_arrays[1]
        return int(np.max(np.diff(starts))) if len(starts) > 1 else 2

    @property
    def n_patches(self) -> int:
        return len(self.deg_u)

    @property
    def max_points(self) -> int:
        return int(np.max(np.diff(self.pstart)))

    @property
    def bits(self) -> int:
        return PRECISION_BITS[self.precision]

    @property
    def max_depth(self) -> int:
        return max_depth_for(self.bits)

    def patch_points(self, p: int) -> np.ndarray:
        """World control points of leaf p as stored (working precision widened), (count, 3);
        with presplit 0 the leaves are the scene patches."""
        a, b = self.pstart[p], self.pstart[p + 1]
        local = self.ctrl[:, a:b].T.astype(np.float64)
        return local[:, :3] / local[:, 3:] + self.frame[p]


V, U = -3, -2  # the axes of a control grid [..., j, i, 4]: v rows, u columns


def halve(grid: np.ndarray, axis: int):
    """de Casteljau at 1/2 of control grids along `axis` (V or U; any leading axes are a batch of
    grids); returns both halves (float64)."""
    g = np.moveaxis(np.asarray(grid, np.float64), axis, 0)
    left, right = [g[0]], [g[-1]]
    level = g
    while len(level) > 1:
        level = 0.5 * (level[:-1] + level[1:])
        left.append(level[0])
        right.append(level[-1])
    return np.moveaxis(np.stack(left), 0, axis), np.moveaxis(np.stack(right[::-1]), 0, axis)


def tight_box(grid: np.ndarray) -> np.ndarray:
    """Union of the control boxes of the four quarter patches (Lischinski & Gonczarowski 3.1).

    grid: (..., n+1, m+1, 4) homogeneous points (w x, w y, w z, w) indexed [j, i], leading axes a
    batch; the quarters are split in 4-D and homogenised. Returns (..., 6): lo xyz, hi xyz.
    """
    quarters = [q for half in halve(grid, U) for q in halve(half, V)]
    pts = np.concatenate([q.reshape(q.shape[:-3] + (-1, 4)) for q in quarters], axis=-2)
    pts = pts[..., :3] / pts[..., 3:]
    return np.concatenate([pts.min(axis=-2), pts.max(axis=-2)], axis=-1)


def _degree_groups(deg_u, deg_v):
    """(m, n, indices) for each pair of degrees: the indices of the patches of degrees m x n."""
    pairs, which = np.unique(np.column_stack([deg_u, deg_v]), axis=0, return_inverse=True)
    which = which.ravel()
    for g, (m, n) in enumerate(pairs):
        yield int(m), int(n), np.flatnonzero(which == g)


def _grids(points, start, idx, m: int, n: int) -> np.ndarray:
    """The control grids (len(idx), n+1, m+1, width) of patches idx, all of degrees m x n."""
    count = (m + 1) * (n + 1)
    return points[np.asarray(start)[idx][:, None] + np.arange(count)].reshape(len(idx), n + 1, m + 1, -1)


MAX_LEAVES = 16384  # pre-splitting stops before a scene would exceed this many leaves


def auto_presplit(n_patches: int) -> int:
    """Pre-split levels for a scene: up to 3 (64 leaves a patch) while leaves stay few."""
    k = 0
    while k < 3 and n_patches * 4 ** (k + 1) <= MAX_LEAVES:
        k += 1
    return k


def _leaves(scene, k: int):
    """Each scene patch split 2^k x 2^k ways in float64 (homogeneous, exact up to float64 rounding).

    Returns points (Euclidean + weight), starts, degrees, rational flags, the scene patch and the
    (u0, u1, v0, v1) within it of every leaf, in scene patch order, v-major within a patch."""
    n = scene.n_patches
    if k == 0:
        return (scene.points, np.asarray(scene.point_start, np.int64), scene.degree_u, scene.degree_v,
                scene.rational, np.arange(n, dtype=np.int32), np.tile([0.0, 1.0, 0.0, 1.0], (n, 1)))
    cells = 2 ** k
    per = cells * cells  # leaves of a patch, j (v) major
    deg_u, deg_v = np.asarray(scene.degree_u), np.asarray(scene.degree_v)
    du, dv = np.repeat(deg_u, per).astype(np.int32), np.repeat(deg_v, per).astype(np.int32)
    starts = np.zeros(n * per + 1, np.int64)
    np.cumsum((du + 1).astype(np.int64) * (dv + 1), out=starts[1:])
    points = np.empty((starts[-1], 4))
    for m, nv, idx in _degree_groups(deg_u, deg_v):  # all patches of one degree pair at once
        g = _grids(scene.points, scene.point_start, idx, m, nv)
        rows = [np.concatenate([g[..., :3] * g[..., 3:], g[..., 3:]], axis=-1)]
        for _ in range(k):  # halve along v: rows of sub-grids, bottom to top
            rows = [h for r in rows for h in halve(r, V)]
        for j, row in enumerate(rows):
            cols = [row]
            for _ in range(k):
                cols = [h for c in cols for h in halve(c, U)]
            for i, q in enumerate(cols):
                e = np.concatenate([q[..., :3] / q[..., 3:], q[..., 3:]], axis=-1).reshape(len(idx), -1, 4)
                first = starts[idx * per + j * cells + i]
                points[first[:, None] + np.arange(e.shape[1])] = e
    i, j = np.tile(np.arange(cells), cells), np.repeat(np.arange(cells), cells)
    param = np.tile(np.column_stack([i / cells, (i + 1) / cells, j / cells, (j + 1) / cells]), (n, 1))
    return (points, starts, du, dv, np.repeat(np.asarray(scene.rational, bool), per),
            np.repeat(np.arange(n, dtype=np.int32), per), param)


def prepare(scene, precision: str = "f32", presplit: int | None = None) -> Geometry:
    """Kernel arrays for a loaded scene (tracer.scene.Scene) in the given precision.

    presplit: pre-split levels (None: `auto_presplit`); 0 keeps the scene's patches as they are.
    A scene the precision cannot bound or resolve is a SceneError (limits.check_extent and
    check_weights; the warnings are the CLI's to print)."""
    if precision not in PRECISION_DTYPE:
        raise ValueError(f"precision must be one of {', '.join(PRECISION_DTYPE)}, got {precision!r}")
    if scene.n_patches == 0:
        raise ValueError(f"{scene.path or 'scene'}: no patches to render")
    check_extent(scene, precision)
    k = auto_presplit(scene.n_patches) if presplit is None else int(presplit)
    all_points, start, deg_u, deg_v, rational, leaf_patch, leaf_param = _leaves(scene, k)
    dtype = PRECISION_DTYPE[precision]
    bits = PRECISION_BITS[precision]
    n = len(deg_u)
    xyz = all_points[:, :3]
    patch_of_point = np.repeat(np.arange(n), np.diff(start))
    weight = _weights(scene, all_points[:, 3], start, patch_of_point, leaf_patch)
    lo, hi = _per_leaf(np.minimum, xyz, start), _per_leaf(np.maximum, xyz, start)
    frame = _frames(lo, hi)
    local = xyz - frame[patch_of_point]
    homogeneous = np.hstack([local * weight, weight])
    ctrl64 = np.ascontiguousarray(homogeneous.T)
    ctrl = ctrl64 if dtype == np.float64 else np.ascontiguousarray(ctrl64.astype(dtype))
    stored = ctrl.T.astype(np.float64)
    eps = _rounding_bounds(local, weight, stored, start)
    eps64 = _rounding_bounds(local, weight, homogeneous, start)
    if k:  # the float64 pre-split rounded too: a few ulps of the world coordinates
        split_err = _per_leaf(np.maximum, np.abs(xyz) * (k + 1) * 2.0 ** -52, start)
        eps = eps + split_err
        eps64 = eps64 + split_err
    boxes = _leaf_boxes(stored, start, deg_u, deg_v, eps, frame, bits)
    grid = grid_steps(boxes, bits)
    patch_trim, trim_arrays = _trim_arrays(scene)
    domain = np.asarray(scene.patch_domain, np.float64)[leaf_patch]
    leaf_domain = np.column_stack([
        domain[:, 0] + leaf_param[:, 0] * (domain[:, 1] - domain[:, 0]),
        domain[:, 0] + leaf_param[:, 1] * (domain[:, 1] - domain[:, 0]),
        domain[:, 2] + leaf_param[:, 2] * (domain[:, 3] - domain[:, 2]),
        domain[:, 2] + leaf_param[:, 3] * (domain[:, 3] - domain[:, 2])])
    return Geometry(precision, ctrl, start, np.asarray(deg_u, np.int32), np.asarray(deg_v, np.int32),
                    np.asarray(rational, np.int8), frame, grid, eps, ctrl64, eps64, boxes, build_bvh(boxes),
                    np.ascontiguousarray(leaf_domain), patch_trim[leaf_patch], trim_arrays,
                    leaf_patch, np.ascontiguousarray(leaf_param, np.float64), k)


def _leaf_boxes(stored, start, deg_u, deg_v, eps, frame, bits: int) -> np.ndarray:
    """(n_leaves, 6) world boxes: each leaf's tight_box of its stored points, padded as the kernel
    widens boxes (by eps and the subdivision's rounding bound, subpatch.widen)."""
    boxes = np.zeros((len(deg_u), 6))
    for m, n, idx in _degree_groups(deg_u, deg_v):  # all leaves of one degree pair at once
        grid = _grids(stored, start, idx, m, n)
        box = tight_box(grid)
        magnitude = np.abs(grid[..., :3] / grid[..., 3:]).max(axis=(1, 2, 3))
        pad = eps[idx] + magnitude[:, None] * 2.0 ** (9 - bits) + np.finfo(np.float64).tiny
        boxes[idx, :3] = box[:, :3] - pad + frame[idx]
        boxes[idx, 3:] = box[:, 3:] + pad + frame[idx]
    return boxes


def grid_steps(boxes: np.ndarray, bits: int) -> np.ndarray:
    """Per leaf and axis, the grid the `float` criterion resolves hits to: the working precision's
    spacing at the leaf's largest world coordinate (float32 numbers there can tell no finer
    points apart), but never coarser than at the scene's half-extent, so that a scene far from
    the world origin is resolved as finely as one at it. None in float64 (zeros): the reference
    resolves as far as its boxes shrink.

    boxes: (n_leaves, 6) world boxes."""
    n = len(boxes)
    if bits >= 53 or n == 0:
        return np.zeros((n, 3))
    magnitude = np.maximum(np.abs(boxes[:, :3]), np.abs(boxes[:, 3:]))
    half_extent = 0.5 * float(np.max(boxes[:, 3:].max(axis=0) - boxes[:, :3].min(axis=0)))
    tiniest = 2.0 ** (-126 - bits)  # below every positive working-precision number
    return np.minimum(spacing(np.maximum(magnitude, tiniest), bits), spacing(max(half_extent, tiniest), bits))


def _trim_arrays(scene):
    """Per-patch trimmed surface (-1 where there is nothing to test) and the flat loop arrays."""
    trims = getattr(scene, "trims", None)
    surface = np.asarray(scene.patch_surface, np.int32)
    if trims is None or trims.n_surfaces == 0:
        empty = (np.zeros((0, 3)), np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(0, np.int8),
                 np.zeros((0, 4)))
        return np.full(scene.n_patches, -1, np.int32), empty
    has = np.asarray(trims.has_trim, bool)
    patch_trim = np.where((surface >= 0) & has[np.maximum(surface, 0)], surface, -1).astype(np.int32)
    seg_points = np.ascontiguousarray(trims.seg_points, np.float64)
    seg_start = np.asarray(trims.seg_start, np.int64)
    arrays = (seg_points, seg_start, np.asarray(trims.surf_seg_start, np.int64),
              np.asarray(trims.start_inside, np.int8), segment_boxes(seg_points, seg_start))
    return patch_trim, arrays


def _frames(lo, hi):
    """Each leaf's frame origin: the centre of its control box rounded to float32; outside float32's
    normal numbers (only a float64 scene gets there, limits.check_extent) the float64 centre."""
    centre = 0.5 * (lo + hi)
    with np.errstate(over="ignore"):
        frame = centre.astype(np.float32).astype(np.float64)
    normal32 = np.isfinite(frame) & ((np.abs(centre) >= np.finfo(np.float32).tiny) | (centre == 0))
    return np.where(normal32, frame, centre)


def _weights(scene, w, start, patch_of_point, leaf_patch):
    """(total points, 1) the weights the leaves are stored with: checked (limits.check_weights) and
    scaled by a power of two per leaf where they lie far from 1 (limits.weight_scale)."""
    wmin, wmax = _per_leaf(np.minimum, w, start), _per_leaf(np.maximum, w, start)
    check_weights(scene, wmin, wmax, leaf_patch)
    scale = weight_scale(wmax)
    return (w if np.all(scale == 1.0) else w * scale[patch_of_point])[:, None]


def _per_leaf(ufunc, values, start):
    """ufunc (np.minimum or np.maximum) over each leaf's points: values (total points, ...) with
    leaf p's at start[p]:start[p + 1] (never empty)."""
    return ufunc.reduceat(values, start[:-1], axis=0)


def _rounding_bounds(local, weight, stored, start):
    """Per patch and axis, a bound on how far the surface of the stored (rounded) points lies
    from the true one: the largest error of a stored Euclidean point, plus, for rational
    patches, what rounded weights can move a convex combination (2 du diameter)."""
    euclid = stored[:, :3] / stored[:, 3:]
    point_err = np.abs(euclid - local) + np.abs(local) * 2.0 ** -52
    weight_err = np.abs(stored[:, 3:] - weight) / weight
    eps = _per_leaf(np.maximum, point_err, start)
    lo, hi = _per_leaf(np.minimum, local, start), _per_leaf(np.maximum, local, start)
    wmax = _per_leaf(np.maximum, weight_err[:, 0] + 2.0 ** -52, start)
    return eps + 4.0 * wmax[:, None] * (hi - lo)
