"""Walks of the spatial subdivisions (aggregate.py's kd-tree and uniform grid): the cells a ray
crosses, near to far, each cell's patches handed to the patch search.

Both share the visit of a cell (`_visit_cell`), in one of two ways (the record's `mailbox`, a run-
time flag: the check costs nothing next to a search, and one compiled walk serves both):
  clamped  (default; Dammertz's kd-tree, no mailbox) each cell searches its patches with the ray
           clamped to the cell: a box must reach the cell's entry (ray[R_REACH]) and begin before
           the search's t_max (hit[H_TIN]), the nearer of the best hit and the cell's exit; both
           are restored afterwards unless a search found a hit, which is then the best hit so far.
           The ray's t_min stays: a box's entry t, where the adaptive criterion reads the
           threshold of detail and the tie rule compares hits, is the same in every cell;
  mailbox  (Lischinski) each patch is searched once per ray, along the whole ray: a per-thread
           array holds the last ray id that met each patch, ids counted per thread in the scratch.
Either way the walk ends at the first cell that begins after the best hit so far (Lischinski's
V_last: the cell holding the closest hit is the last one visited). A patch's box
(geometry.leaf_box) is slab-tested before its search, as the BVH tests a leaf's box.

Cell boundaries are computed in float64 from the ray; their rounding is covered by widening every
cell's interval by a slack in world units (CELL_SLACK of the scene's and the origin's
coordinates) over the ray's speed across the boundary's axis, so a crossing on a boundary is inside
the interval of both cells. A hit found in a cell may therefore lie a hair beyond its nominal exit:
the walk goes on to the next cell while that cell's widened entry comes before the hit.

Bookkeeping as the BVH walk's: counts[C_NODES] nodes (kd-tree) or cells (grid) visited,
C_SURFACES patch boxes tested, C_PATCHES searches started, C_BOX_TESTS the walk's own box tests
(the scene box and the patch boxes), C_EFFORT the searches' boxes; the box budget ends the walk.
"""
from __future__ import annotations

import math

from .jit import njit, specialise
from .ray import H_PATCH, H_TIN, R_BUDGET, R_D, R_INV, R_O, R_REACH, slab
from .records import C_BOX_TESTS, C_EFFORT, C_NODES, C_PATCHES, C_SURFACES, C_UNRESOLVED

GO_ON, STOP = 0, 1
CELL_SLACK = 2.0 ** -40  # relative to the coordinates: far above the rounding of cell boundaries


def _visit_cell(agg, first, count, t_enter, t_exit, lv, trims, ray, hit, q, sl, ws, trace, counts):
    """Search the patches agg.items[first:first + count] of a cell whose (widened) interval along the
    ray is [t_enter, t_exit]; returns STOP when the walk must end (budget, or any hit found)."""
    reach = ray[R_REACH]
    best = hit[H_TIN]
    best_patch = hit[H_PATCH]
    limit = best
    ray_id = ws.ray_id[0]
    if not agg.mailbox:
        limit = min(best, t_exit)
        ray[R_REACH] = max(reach, t_enter)
        hit[H_TIN] = limit
        if limit < best:  # the cell's exit, not a hit: no leaf may tie with it (ray.search_limit)
            hit[H_PATCH] = -1.0
    for k in range(first, first + count):
        p = agg.items[k]
        if agg.mailbox:
            if ws.mailbox[p] == ray_id:
                continue
            ws.mailbox[p] = ray_id
        counts[C_SURFACES] += 1
        counts[C_BOX_TESTS] += 1
        ok, t_box, t_leave = slab(agg.patch_box[p], 0.0, 0.0, 0.0, ray)
        if not ok or t_box > hit[H_TIN] or t_leave < ray[R_REACH]:
            continue
        counts[C_PATCHES] += 1
        spent = search(p, lv, trims, ray, hit, q, sl, trace)  # noqa: F821
        counts[C_EFFORT] += spent
        if spent >= ray[R_BUDGET]:  # the budget ran out in this search: stop here
            counts[C_UNRESOLVED] = 1
            break
        ray[R_BUDGET] -= spent
        if STOP_AT_FIRST and hit[H_TIN] < limit:  # noqa: F821
            break
    ray[R_REACH] = reach
    if hit[H_TIN] >= limit:  # nothing found here (or a tie with the best, the best now): the clamp goes
        hit[H_TIN] = best
        if limit < best:
            hit[H_PATCH] = best_patch
    elif STOP_AT_FIRST:  # noqa: F821
        return STOP
    return STOP if counts[C_UNRESOLVED] != 0 else GO_ON


def _slack(agg, ray):
    """World-unit slack of cell boundaries along this ray (see the module docstring)."""
    far = agg.reach
    for c in range(3):
        far = max(far, abs(ray[R_O + c]))
    return CELL_SLACK * far


def _kd_walk(agg, lv, trims, ray, hit, q, sl, ws, trace, counts):
    """The kd-tree walk template (pbrt's front-to-back traversal with a stack of far children)."""
    ok, t0, t1 = slab(agg.bounds, 0.0, 0.0, 0.0, ray)
    counts[C_BOX_TESTS] += 1
    if not ok or t0 > hit[H_TIN]:
        return
    ws.ray_id[0] += 1
    slack = _slack(agg, ray)
    ws.nodes[0] = 0
    ws.tin[0] = t0
    ws.tout[0] = t1
    top = 1
    while top > 0:
        top -= 1
        node = ws.nodes[top]
        t_lo = ws.tin[top]
        t_hi = ws.tout[top]
        if t_lo > hit[H_TIN]:
            continue
        while True:
            counts[C_NODES] += 1
            axis = agg.node_axis[node]
            if axis < 0:
                count = agg.node_count[node]
                if count > 0 and visit(agg, agg.node_first[node], count, t_lo, t_hi, lv, trims, ray,  # noqa: F821
                                       hit, q, sl, ws, trace, counts) == STOP:
                    return
                break
            split = agg.node_split[node]
            o = ray[R_O + axis]
            d = ray[R_D + axis]
            below_first = o < split or (o == split and d <= 0.0)
            near = node + 1 if below_first else agg.node_above[node]
            far = agg.node_above[node] if below_first else node + 1
            if d == 0.0:  # parallel to the plane: the ray stays on its side
                node = near
                continue
            t_plane = (split - o) * ray[R_INV + axis]
            pad = slack * abs(ray[R_INV + axis])
            if t_plane <= 0.0 or t_plane - pad > t_hi:  # moving away from the plane, or meets it too late
                node = near
            elif t_plane + pad < t_lo:  # met it before this voxel
                node = far
            else:
                ws.nodes[top] = far
                ws.tin[top] = max(t_plane - pad, t_lo)
                ws.tout[top] = t_hi
                top += 1
                node = near
                t_hi = min(t_plane + pad, t_hi)


def _boundary(agg, c, i, ray):
    """t where the ray meets the plane between cells i - 1 and i along axis c."""
    return (agg.bounds[c] + i * agg.cell[c] - ray[R_O + c]) * ray[R_INV + c]


def _grid_walk(agg, lv, trims, ray, hit, q, sl, ws, trace, counts):
    """The grid walk template (Amanatides and Woo's 3D-DDA in float64; the next boundary per axis
    is computed from the cell index, not accumulated, so its error does not grow along the ray)."""
    ok, t0, t1 = slab(agg.bounds, 0.0, 0.0, 0.0, ray)
    counts[C_BOX_TESTS] += 1
    if not ok or t0 > hit[H_TIN]:
        return
    ws.ray_id[0] += 1
    slack = _slack(agg, ray)
    idx, step, t_next = ws.nodes, ws.step, ws.tin  # the cell's index, its steps and next boundaries
    for c in range(3):
        n = agg.dims[c]
        d = ray[R_D + c]
        v = (ray[R_O + c] + t0 * d - agg.bounds[c]) / agg.cell[c]
        i = int(min(max(math.floor(v), 0.0), n - 1.0))
        # the entry cell by the boundaries' own arithmetic: its near boundary is met by t0
        if d > 0.0:
            while i > 0 and _boundary(agg, c, i, ray) > t0:
                i -= 1
            while i < n - 1 and _boundary(agg, c, i + 1, ray) <= t0:
                i += 1
            step[c] = 1
            t_next[c] = _boundary(agg, c, i + 1, ray)
        elif d < 0.0:
            while i < n - 1 and _boundary(agg, c, i + 1, ray) > t0:
                i += 1
            while i > 0 and _boundary(agg, c, i, ray) <= t0:
                i -= 1
            step[c] = -1
            t_next[c] = _boundary(agg, c, i, ray)
        else:
            step[c] = 0
            t_next[c] = math.inf
        idx[c] = i
    t_enter = t0
    while True:
        a = 0
        if t_next[1] < t_next[a]:
            a = 1
        if t_next[2] < t_next[a]:
            a = 2
        t_exit = t_next[a]
        last = t_exit >= t1
        counts[C_NODES] += 1
        cell = (idx[2] * agg.dims[1] + idx[1]) * agg.dims[0] + idx[0]
        first = agg.cell_start[cell]
        count = agg.cell_start[cell + 1] - first
        if count > 0:
            t_out = math.inf if last else t_exit + slack * abs(ray[R_INV + a])
            if visit(agg, first, count, t_enter, t_out, lv, trims, ray, hit, q, sl, ws, trace,  # noqa: F821
                     counts) == STOP:
                return
        if last:
            return
        idx[a] += step[a]
        if idx[a] < 0 or idx[a] >= agg.dims[a]:
            return
        t_enter = t_exit - slack * abs(ray[R_INV + a])
        if t_enter > hit[H_TIN]:
            return
        t_next[a] = _boundary(agg, a, idx[a] + (1 if step[a] > 0 else 0), ray)


_inline = njit(cache=True, nogil=True, _nrt=False, inline='always')
_boundary = _inline(_boundary)
_slack = _inline(_slack)


def make_visit(search, any_hit: bool):
    return _inline(specialise(_visit_cell, search=search, STOP_AT_FIRST=any_hit))


def make_kd_walk(search, any_hit: bool):
    """The kd-tree walk around one patch search (see the module docstring), inlined into its caller."""
    return _inline(specialise(_kd_walk, visit=make_visit(search, any_hit)))


def make_grid_walk(search, any_hit: bool):
    """The grid walk around one patch search (see the module docstring), inlined into its caller."""
    return _inline(specialise(_grid_walk, visit=make_visit(search, any_hit)))

