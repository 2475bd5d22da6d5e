"""Uniform grid over the kernel's patches (Lischinski & Gonczarowski 1990, 3.1).

Resolution: Lischinski's voxel side D = B / 4, B the mean side length of the patches' boxes (the
leaves the kernel searches, geometry.leaf_box, all three sides of every box), divided by
`grid_scale`; each axis of the scene's box gets ceil(extent / D) cells, an axis where the scene is
flat one. Memory bound: at most MAX_CELLS cells (cell_start, 16 MiB as int32) and MAX_ITEMS
registrations (items, 64 MiB); a finer grid is coarsened by 2^(1/3) per axis until both hold, and
`coarsened` in the report says by how much the voxel side grew.

Registration follows his l_a(S) with k = 2: a patch whose box has every edge below D / 2 is
registered in every voxel the box overlaps, any other is split into quarters (de Casteljau in
float64 on the homogeneous float64 leaf, geometry.ctrl64) and each quarter registered the same
way. Boxes are conservative: a quarter's control box (rational points divided by their weights)
is padded as geometry._leaf_boxes pads the leaf's (the stored points' error and the kernel's
widening) and clipped to the leaf's box, both of which hold the true surface; overlaps are taken
with a further CELL_SLACK of the scene's coordinates. Splitting stops early where a box lies in a
single voxel (its quarters could only name that one) and at MAX_LEVELS (the whole box is then
registered). A voxel lists a patch once.

The quarters hold the true surface, not every box a search computes: under a coarse criterion
(fixed, adaptive) a hit box can reach voxels where its leaf's quarters are not registered, and the
walk would miss a hit the BVH reports. The grid built for those criteria registers each leaf's
whole box instead (build_grid's `quarters`, accel.registration).

Cells: cell (ix, iy, iz) has index (iz * ny + iy) * nx + ix; its patches are
items[cell_start[c]:cell_start[c + 1]], in increasing order. Built by a compiled kernel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .cell_walk import CELL_SLACK
from .jit import njit

MAX_CELLS = 1 << 22
MAX_ITEMS = 1 << 24
K = 2.0          # Lischinski's k: boxes are split until their edges are below D / k
MAX_LEVELS = 12  # quarter levels below a leaf at most


@dataclass(frozen=True)
class Grid:
    bounds: np.ndarray      # (6,) float64 the grid's box: the patches' box widened by the slack
    dims: np.ndarray        # (3,) int64 cells per axis
    cell: np.ndarray        # (3,) float64 cell side per axis
    cell_start: np.ndarray  # (cells + 1,) int32
    items: np.ndarray       # (I,) int32 patch indices, cell by cell
    voxel_rule: float       # Lischinski's voxel side times 1 / grid_scale, before any coarsening
    coarsened: float        # the voxel side's growth to keep within MAX_CELLS and MAX_ITEMS (1: none)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.bounds, self.dims, self.cell, self.cell_start, self.items))

    def report(self) -> dict:
        """Figures of the grid: cells, the empty ones, items, items per non-empty cell, voxel side."""
        per = np.diff(self.cell_start)
        full = per[per > 0]
        return {"cells": int(len(per)), "dims": [int(d) for d in self.dims], "empty_cells": int((per == 0).sum()),
                "items": int(len(self.items)), "mean_items_per_cell": float(per.mean()),
                "mean_items_per_full_cell": float(full.mean()) if len(full) else 0.0,
                "max_items_per_cell": int(per.max()), "voxel_side": [float(c) for c in self.cell],
                "coarsened": float(self.coarsened), "bytes": int(self.nbytes)}


def leaf_pads(geom) -> np.ndarray:
    """(n, 3) the padding geometry._leaf_boxes gives each leaf's boxes: the stored points' error,
    the kernel's widening at the leaf's magnitude, and the smallest normal float64."""
    local = geom.ctrl64[:3] / geom.ctrl64[3]
    magnitude = np.maximum.reduceat(np.abs(local).max(axis=0), geom.pstart[:-1])
    return geom.eps + magnitude[:, None] * 2.0 ** (9 - geom.bits) + np.finfo(np.float64).tiny


def resolution(extent: np.ndarray, voxel: float):
    """Cells per axis (3,) int64 for voxels of side `voxel` over `extent` (3,): at least one."""
    if not (voxel > 0.0 and math.isfinite(voxel)):
        return np.ones(3, np.int64)
    return np.array([max(1, math.ceil(min(e / voxel, MAX_CELLS))) for e in extent], np.int64)


def build_grid(geom, grid_scale: float = 1.0, quarters: bool = True) -> Grid:
    """The grid over geom's leaves (geometry.Geometry), its resolution Lischinski's times grid_scale;
    quarters: Lischinski's registration (the module docstring), else every leaf's whole box."""
    if not (grid_scale > 0.0 and math.isfinite(grid_scale)):
        raise ValueError(f"grid_scale must be a positive number, got {grid_scale!r}")
    boxes = np.ascontiguousarray(geom.leaf_box, np.float64)
    if len(boxes) == 0:
        raise ValueError("cannot build a grid over an empty scene")
    if not np.all(np.isfinite(boxes)):
        raise ValueError("cannot build a grid over boxes that are not finite")
    lo, hi = boxes[:, :3].min(axis=0), boxes[:, 3:].max(axis=0)
    reach = float(max(np.abs(lo).max(), np.abs(hi).max()))
    slack = CELL_SLACK * reach
    lo, hi = lo - slack, hi + slack
    extent = hi - lo
    rule = float(np.mean(boxes[:, 3:] - boxes[:, :3])) / 4.0 / float(grid_scale)
    voxel = rule
    pads = np.ascontiguousarray(leaf_pads(geom))
    while True:
        dims = resolution(extent, voxel)
        if int(np.prod(dims)) > MAX_CELLS:
            voxel *= 1.0001 * (int(np.prod(dims)) / MAX_CELLS) ** (1.0 / 3.0)
            continue
        cell = extent / dims
        n_items, cell_start, items = _register(geom.ctrl64, geom.pstart, geom.deg_u, geom.deg_v, geom.frame, pads,
                                               boxes, lo, cell, dims, voxel, slack, MAX_ITEMS, quarters)
        if n_items >= 0:
            break
        voxel = max(voxel, float(cell.max())) * 2.0 ** (1.0 / 3.0)  # too many registrations: coarser
    bounds = np.concatenate([lo, hi])
    return Grid(bounds, dims, cell, cell_start.astype(np.int32), items[:n_items].copy(), rule,
                voxel / rule if rule > 0.0 else 1.0)


@njit(cache=True, nogil=True)
def _halve(src, deg, stride, n_curves, curve_step, left, right, work):
    """de Casteljau at 1/2 of the n_curves curves of a control grid (4, points): curve q has its
    deg + 1 points at q * curve_step + i * stride."""
    for c in range(4):
        for q in range(n_curves):
            base = q * curve_step
            for i in range(deg + 1):
                work[i] = src[c, base + i * stride]
            left[c, base] = work[0]
            right[c, base + deg * stride] = work[deg]
            for r in range(1, deg + 1):
                for i in range(deg + 1 - r):
                    work[i] = 0.5 * (work[i] + work[i + 1])
                left[c, base + r * stride] = work[0]
                right[c, base + (deg - r) * stride] = work[deg - r]


@njit(cache=True, nogil=True)
def _register(ctrl, pstart, deg_u, deg_v, frame, pad, leaf_box, lo, cell, dims, voxel, slack, max_items, quarters):
    """Register every leaf in its voxels (l_a with k = 2, see the module docstring; quarters False:
    the leaf's whole box); returns (registrations, cell_start (cells + 1,) int64, items), or (-1, ...)
    past max_items.

    Boxes are small against Lischinski's one voxel side `voxel`, not against the cells' sides: an
    axis where the scene is flat has one cell as thin as the scene, which no padded box undercuts
    (a floor of 36 quads recursed to MAX_LEVELS along every cell boundary: 61 s for 146k items).

    ctrl: (4, points) float64 homogeneous, local to frame[p]; leaf p's points at pstart[p], j
    (v) major: point (i, j) at j * (deg_u + 1) + i."""
    n = len(deg_u)
    n_cells = dims[0] * dims[1] * dims[2]
    mark = np.zeros(n_cells, np.int32)  # 1 + the last leaf registered in each cell
    counts = np.zeros(n_cells + 1, np.int64)
    pair_cell = np.empty(max(16, 4 * n), np.int64)
    pair_leaf = np.empty(max(16, 4 * n), np.int32)
    max_points, max_deg = 1, 1
    for p in range(n):
        max_points = max(max_points, pstart[p + 1] - pstart[p])
        max_deg = max(max_deg, deg_u[p], deg_v[p])
    slots = 3 * MAX_LEVELS + 4
    sub = np.empty((slots, 4, max_points))
    level = np.zeros(slots, np.int64)
    half_a = np.empty((4, max_points))
    half_b = np.empty((4, max_points))
    work = np.empty(max_deg + 1)
    bx = np.empty(6)
    i0 = np.empty(3, np.int64)
    i1 = np.empty(3, np.int64)
    n_pairs = 0
    for p in range(n):
        m, nv, start = deg_u[p], deg_v[p], pstart[p]
        count = pstart[p + 1] - start
        for c in range(4):
            for k in range(count):
                sub[0, c, k] = ctrl[c, start + k]
        level[0] = 0
        top = 1
        while top > 0:
            top -= 1
            lev = level[top]
            for a in range(3):
                lo_a, hi_a = leaf_box[p, a], leaf_box[p, 3 + a]
                if lev > 0:  # the quarter's padded control box, clipped to the leaf's
                    x_lo, x_hi = np.inf, -np.inf
                    for k in range(count):
                        x = sub[top, a, k] / sub[top, 3, k]
                        x_lo, x_hi = min(x_lo, x), max(x_hi, x)
                    x_lo += frame[p, a] - pad[p, a]
                    x_hi += frame[p, a] + pad[p, a]
                    if x_lo <= hi_a and x_hi >= lo_a:  # (they overlap: both hold the surface)
                        lo_a, hi_a = max(lo_a, x_lo), min(hi_a, x_hi)
                bx[a], bx[3 + a] = lo_a, hi_a
            small, single = True, True
            for a in range(3):
                v0 = (bx[a] - slack - lo[a]) / cell[a]
                v1 = (bx[3 + a] + slack - lo[a]) / cell[a]
                i0[a] = int(min(max(math.floor(v0), 0.0), dims[a] - 1.0))
                i1[a] = int(min(max(math.floor(v1), 0.0), dims[a] - 1.0))
                small = small and bx[3 + a] - bx[a] < voxel / K
                single = single and i0[a] == i1[a]
            if small or single or lev >= MAX_LEVELS or not quarters:
                for iz in range(i0[2], i1[2] + 1):
                    for iy in range(i0[1], i1[1] + 1):
                        for ix in range(i0[0], i1[0] + 1):
                            c = (iz * dims[1] + iy) * dims[0] + ix
                            if mark[c] == p + 1:
                                continue
                            mark[c] = p + 1
                            if n_pairs >= max_items:
                                return -1, counts, pair_leaf
                            if n_pairs >= len(pair_cell):
                                grown_cell = np.empty(2 * len(pair_cell), np.int64)
                                grown_cell[:n_pairs] = pair_cell[:n_pairs]
                                pair_cell = grown_cell
                                grown_leaf = np.empty(2 * len(pair_leaf), np.int32)
                                grown_leaf[:n_pairs] = pair_leaf[:n_pairs]
                                pair_leaf = grown_leaf
                            pair_cell[n_pairs] = c
                            pair_leaf[n_pairs] = p
                            n_pairs += 1
                            counts[c + 1] += 1
                continue
            # quarters: halves in u (each row j), then each half in v (each column i)
            _halve(sub[top], m, 1, nv + 1, m + 1, half_a, half_b, work)
            _halve(half_a, nv, m + 1, m + 1, 1, sub[top], sub[top + 1], work)
            _halve(half_b, nv, m + 1, m + 1, 1, sub[top + 2], sub[top + 3], work)
            for k in range(4):
                level[top + k] = lev + 1
            top += 4
    for c in range(n_cells):
        counts[c + 1] += counts[c]
    items = np.empty(max(n_pairs, 1), np.int32)
    fill = counts[:n_cells].copy()
    for k in range(n_pairs):  # stable: a cell lists its leaves in increasing order
        c = pair_cell[k]
        items[fill[c]] = pair_leaf[k]
        fill[c] += 1
    return n_pairs, counts, items
