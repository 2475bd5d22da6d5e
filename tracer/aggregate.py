"""Aggregates: what a ray visits before it searches patches.

An aggregate kind has a record of flat arrays (built once per scene) and a walk factory,
make_walk(search, any_hit) -> walk(agg, lv, trims, ray, hit, q, sl, stack, trace, counts),
that visits the nodes the ray meets in near-to-far order and hands every patch of a visited
leaf to the patch search (drivers.make_search), sharing the shrinking ray interval with it.
The closest-hit walk runs to the end; the any-hit walk stops at the first hit; both stop
when the ray's box budget (ray[R_BUDGET]) runs out, setting counts[C_UNRESOLVED]. counts
(records.C_*) gain the boxes the searches computed, the nodes visited and the patches
searched. The kind is fixed at compile time (variants.Variant.accel); each kind also makes
its walk's scratch (walk_scratch: the stack, and the mailbox of the spatial kinds), so the
drivers and the tile kernel are the same for every kind.

BVH (bvh.py): nodes in depth-first order, node 0 the root; a leaf lists its patches as
items[first:first + count].
kd-tree (kdtree.py) and uniform grid (grid.py): cells listing patches, walked by cell_walk.py;
`patch_box` holds the patches' boxes (geometry.leaf_box), tested before a patch's search,
`reach` the scene's largest coordinate (the slack of cell boundaries), and `mailbox` says how
a cell searches its patches (cell_walk: clamped to the cell, or once per ray).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .cell_walk import make_grid_walk, make_kd_walk
from .jit import njit, specialise
from .ray import H_TIN, NO_SHIFT, R_BUDGET, slab
from .records import C_BOX_TESTS, C_EFFORT, C_NODES, C_PATCHES, C_SURFACES, C_UNRESOLVED

BvhNodes = namedtuple("BvhNodes", "node_box node_child leaf_first leaf_count items")
KdNodes = namedtuple("KdNodes", "bounds reach node_axis node_split node_above node_first node_count items "
                     "patch_box mailbox")
GridCells = namedtuple("GridCells", "bounds reach dims cell cell_start items patch_box mailbox")
# The BVH walk's fixed stack: node indices and their entry t.
WalkStack = namedtuple("WalkStack", "nodes tin")
# The cell walks' scratch: the kd-tree's stack of far children (node, entry and exit t; the grid
# keeps its cell index and next boundaries in nodes[:3] and tin[:3]), the grid's steps, and the
# mailbox: the last ray id per patch (one entry when the mailbox is off) and the thread's ray count.
CellScratch = namedtuple("CellScratch", "nodes tin tout step mailbox ray_id")


def bvh_nodes(bvh) -> BvhNodes:
    """The BVH's record for the kernels (bvh.Bvh: one patch per leaf)."""
    leaf = bvh.node_child[:, 0] < 0
    return BvhNodes(bvh.node_box, bvh.node_child, np.arange(len(leaf), dtype=np.int32),
                    leaf.astype(np.int32), np.where(leaf, bvh.node_patch, -1).astype(np.int32))


def walk_stack(bvh) -> int:
    """Stack entries a walk of this BVH needs."""
    return bvh.depth + 2


def kd_nodes(tree, patch_box, mailbox: bool) -> KdNodes:
    """The kd-tree's record for the kernels (kdtree.KdTree; patch_box: geometry.leaf_box)."""
    return KdNodes(tree.bounds, _reach(tree.bounds), tree.node_axis, tree.node_split, tree.node_above,
                   tree.node_first, tree.node_count, tree.items, np.ascontiguousarray(patch_box), bool(mailbox))


def grid_cells(grid, patch_box, mailbox: bool) -> GridCells:
    """The grid's record for the kernels (grid.Grid; patch_box: geometry.leaf_box)."""
    return GridCells(grid.bounds, _reach(grid.bounds), grid.dims, grid.cell, grid.cell_start, grid.items,
                     np.ascontiguousarray(patch_box), bool(mailbox))


def _reach(bounds) -> float:
    return float(np.max(np.abs(bounds)))


def walk_scratch(agg, size: int):
    """The scratch of one kernel call's walk (tile_kernel.tile_scratch): the kind's own record,
    its stack `size` entries long."""
    if isinstance(agg, BvhNodes):
        return WalkStack(np.zeros(size, np.int32), np.zeros(size))
    size = max(size, 3)  # the grid's cell index and boundaries
    return CellScratch(np.zeros(size, np.int64), np.zeros(size), np.zeros(size), np.zeros(3, np.int64),
                       np.zeros(len(agg.patch_box) if agg.mailbox else 1, np.int64), np.zeros(1, np.int64))


def _bvh_walk(agg, lv, trims, ray, hit, q, sl, stack, trace, counts):
    """The BVH walk template (specialised by make_bvh_walk)."""
    node_box = agg.node_box
    node_child = agg.node_child
    t_max = hit[H_TIN]
    ok, t_in, _ = slab(node_box[0], NO_SHIFT, NO_SHIFT, NO_SHIFT, ray)
    counts[C_BOX_TESTS] += 1
    if node_child[0, 0] < 0:
        counts[C_SURFACES] += agg.leaf_count[0]
    if not ok:
        return
    stack.nodes[0] = 0
    stack.tin[0] = t_in
    top = 1
    while top > 0:
        top -= 1
        node = stack.nodes[top]
        if stack.tin[top] > hit[H_TIN]:  # (a box entered at the best t may hold a tie: ray.search_limit)
            continue
        counts[C_NODES] += 1
        left = node_child[node, 0]
        if left < 0:
            first = agg.leaf_first[node]
            for k in range(first, first + agg.leaf_count[node]):
                counts[C_PATCHES] += 1
                spent = search(agg.items[k], lv, trims, ray, hit, q, sl, trace)  # noqa: F821
                counts[C_EFFORT] += spent
                if spent >= ray[R_BUDGET]:  # the budget ran out in this search: stop here
                    counts[C_UNRESOLVED] = 1
                    return
                ray[R_BUDGET] -= spent
            if STOP_AT_FIRST and hit[H_TIN] < t_max:  # noqa: F821
                return
            continue
        right = node_child[node, 1]
        ok_l, tl, _ = slab(node_box[left], NO_SHIFT, NO_SHIFT, NO_SHIFT, ray)
        ok_r, tr, _ = slab(node_box[right], NO_SHIFT, NO_SHIFT, NO_SHIFT, ray)
        counts[C_BOX_TESTS] += 2
        for child in (left, right):  # a leaf's box is its patches' box (one patch a leaf)
            if node_child[child, 0] < 0:
                counts[C_SURFACES] += agg.leaf_count[child]
        ok_l = ok_l and tl <= hit[H_TIN]
        ok_r = ok_r and tr <= hit[H_TIN]
        if ok_l and ok_r:
            far_first = tl <= tr
            stack.nodes[top] = right if far_first else left
            stack.tin[top] = tr if far_first else tl
            stack.nodes[top + 1] = left if far_first else right
            stack.tin[top + 1] = tl if far_first else tr
            top += 2
        elif ok_l or ok_r:
            stack.nodes[top] = left if ok_l else right
            stack.tin[top] = tl if ok_l else tr
            top += 1


def make_bvh_walk(search, any_hit: bool):
    """The BVH walk around one patch search (see the module docstring), inlined into its caller."""
    walk = specialise(_bvh_walk, search=search, STOP_AT_FIRST=any_hit)
    return njit(cache=True, nogil=True, _nrt=False, inline='always')(walk)


WALKS = {"bvh": make_bvh_walk, "kdtree": make_kd_walk, "grid": make_grid_walk}
