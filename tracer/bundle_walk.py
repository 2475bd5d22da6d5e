"""The BVH walk of a ray bundle (bundle.py): the bundle walks the tree as one, a node staying on
its stack while any of its rays meets it. Its node tests go eight rays at a time (lanes.py), each
ray's interval into a node in a row of node_tin, and its counters stay in lanes until the walk
ends; each visited leaf's patches are searched for the rays that reach it."""
from __future__ import annotations

import math

import numpy as np

from .aggregate import BvhNodes  # noqa: F401 (the record the walk reads)
from .bundle_steps import (ONE, W_BOX_TESTS, W_NODES, W_PATCHES, W_SURFACES, ZERO, ahead_in, lowest_bit,
                           nearest_in, take_group)
from .frustum import MIN_RAYS, at_least, bound_rays, misses_all
from .jit import njit, specialise
from .lanes import L_D, L_DT, L_FAR, L_HIT, L_INV, L_O, L_T0, L_TMIN, WIDTH, count_lanes, slab_lanes, slab_pair_lanes
from .ray import H_TIN, R_D, R_DT, R_INV, R_O, R_T0, R_TMIN
from .records import C_BOX_TESTS, C_NODES, C_PATCHES, C_SURFACES


@njit(cache=True, nogil=True, inline='always')
def _node_corners(node_box, node):
    """A BVH node's box as slab_at takes it (slab's shift by NO_SHIFT, -0.0, leaves every corner as
    it is)."""
    box = node_box[node]
    return box[0], box[1], box[2], box[3], box[4], box[5]


@njit(cache=True, nogil=True, inline='always')
def _load_lanes(br, m):
    """The rays of m into the walk's lanes (lanes.py), and their counters there zeroed."""
    lanes = br.lanes
    wc = br.walk_counts
    for k in range(wc.shape[0]):
        for r in range(wc.shape[1]):
            wc[k, r] = 0
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        ray = br.rays[r]
        for c in range(3):
            lanes[L_O + c, r] = ray[R_O + c]
            lanes[L_D + c, r] = ray[R_D + c]
            lanes[L_INV + c, r] = ray[R_INV + c]
        lanes[L_TMIN, r] = ray[R_TMIN]
        lanes[L_FAR, r] = math.inf
        lanes[L_HIT, r] = np.nextafter(br.hits[r, H_TIN], np.inf)  # the walk lets ties through (ray.search_limit)
        lanes[L_T0, r] = ray[R_T0]
        lanes[L_DT, r] = ray[R_DT]


@njit(cache=True, nogil=True, inline='always')
def _store_counts(br, m):
    """The walk's counters, kept in lanes, added to the rays' own."""
    wc = br.walk_counts
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        br.counts[r, C_BOX_TESTS] += wc[W_BOX_TESTS, r]
        br.counts[r, C_SURFACES] += wc[W_SURFACES, r]
        br.counts[r, C_NODES] += wc[W_NODES, r]
        br.counts[r, C_PATCHES] += wc[W_PATCHES, r]


@njit(cache=True, nogil=True, inline='always')
def _count_walk(br, m, row, n):
    """walk_counts[row, r] += n for every ray r of m."""
    rest = m
    while rest != ZERO:
        g, _, bits, rest = take_group(rest)
        count_lanes(br.walk_counts, row, g, bits, n)


@njit(cache=True, nogil=True, inline='always')
def _node_rays(node_box, node, br, row, m):
    """Slab-test a BVH node against the rays of m (intervals into node_tin[row]); the rays that
    meet it before their own closest hit."""
    alive = ZERO
    lo0, lo1, lo2, hi0, hi1, hi2 = _node_corners(node_box, node)
    rest = m
    while rest != ZERO:
        g, shift, bits, rest = take_group(rest)
        met = slab_lanes(br.lanes, L_O, g, lo0, lo1, lo2, hi0, hi1, hi2, br.node_tin, None, row, br.lanes,
                         L_TMIN, br.lanes, L_FAR) & bits
        alive |= met << shift
    return alive


@njit(cache=True, nogil=True, inline='always')
def _children_rays(node_box, left, right, br, row_l, row_r, m, surfaces):
    """Both children of a BVH node against the rays of m (intervals into node_tin[row_l] and
    [row_r]), eight rays at a time, counting each ray's two box tests and the surfaces of the leaf
    children among them; the rays of each child. With enough rays, a child the bundle's bounds
    miss (frustum.py: the same verdicts) is not tested ray by ray."""
    l0, l1, l2, l3, l4, l5 = _node_corners(node_box, left)
    r0, r1, r2, r3, r4, r5 = _node_corners(node_box, right)
    test_l = True
    test_r = True
    if at_least(m, MIN_RAYS):
        test_l = not misses_all((l0, l1, l2, l3, l4, l5), br.bounds)
        test_r = not misses_all((r0, r1, r2, r3, r4, r5), br.bounds)
    alive_l = ZERO
    alive_r = ZERO
    lanes = br.lanes
    rest = m
    while rest != ZERO:
        g, shift, bits, rest = take_group(rest)
        count_lanes(br.walk_counts, W_BOX_TESTS, g, bits, 2)
        if surfaces:
            count_lanes(br.walk_counts, W_SURFACES, g, bits, surfaces)
        if test_l and test_r:
            both = slab_pair_lanes(lanes, L_O, g, l0, l1, l2, l3, l4, l5, r0, r1, r2, r3, r4, r5, br.node_tin, None,
                                   row_l, row_r, lanes, L_TMIN, lanes, L_FAR)
            alive_l |= (both & bits) << shift
            alive_r |= ((both >> np.uint64(2 * WIDTH)) & bits) << shift
        elif test_l:
            alive_l |= (slab_lanes(lanes, L_O, g, l0, l1, l2, l3, l4, l5, br.node_tin, None, row_l, lanes, L_TMIN,
                                    lanes, L_FAR)
                        & bits) << shift
        elif test_r:
            alive_r |= (slab_lanes(lanes, L_O, g, r0, r1, r2, r3, r4, r5, br.node_tin, None, row_r, lanes, L_TMIN,
                                    lanes, L_FAR)
                        & bits) << shift
    return alive_l, alive_r


def _bvh_bundle_walk(agg, lv, trims, q, sl, br, active):
    """The BVH walk of a bundle (template, specialised by make_bvh_bundle_walk): its node tests
    eight rays at a time (lanes.py), its counters kept in lanes until it ends."""
    node_child = agg.node_child
    _load_lanes(br, active)
    _count_walk(br, active, W_BOX_TESTS, 1)
    if node_child[0, 0] < 0:
        _count_walk(br, active, W_SURFACES, agg.leaf_count[0])
    bound_rays(br.bounds, br.rays, active)
    m = _node_rays(agg.node_box, 0, br, br.node_row[0], active)
    if m == ZERO:
        _store_counts(br, active)
        return
    br.node[0] = 0
    br.node_mask[0] = m
    top = 1
    while top > 0:
        top -= 1
        node = br.node[top]
        live = ahead_in(br.node_tin, br, br.node_row[top], br.node_mask[top], True)
        if live == ZERO:
            continue
        left = node_child[node, 0]
        if left < 0:
            first = agg.leaf_first[node]
            _count_walk(br, live, W_PATCHES, agg.leaf_count[node])  # the searches below count no patches
            for k in range(first, first + agg.leaf_count[node]):  # (each hit they report goes into the lanes)
                search(agg.items[k], lv, trims, q, sl, br, live)  # noqa: F821
            continue
        right = node_child[node, 1]
        surfaces = 0
        for child in (left, right):
            if node_child[child, 0] < 0:
                surfaces += agg.leaf_count[child]
        # Both children's intervals go where they will be popped from: the nearer on top.
        row_l = br.node_row[top]
        row_r = br.node_row[top + 1]
        ml, mr = _children_rays(agg.node_box, left, right, br, row_l, row_r, live, surfaces)
        if ml == ZERO and mr == ZERO:
            continue
        if ml == ZERO or mr == ZERO:
            only = left if ml != ZERO else right
            br.node[top] = only
            br.node_mask[top] = ml | mr
            if only == right:
                br.node_row[top], br.node_row[top + 1] = row_r, row_l
            top += 1
            continue
        if nearest_in(br.node_tin, br, row_l, ml) <= nearest_in(br.node_tin, br, row_r, mr):  # left nearer: right below it
            br.node_row[top], br.node_row[top + 1] = row_r, row_l
            br.node[top], br.node[top + 1] = right, left
            br.node_mask[top], br.node_mask[top + 1] = mr, ml
        else:
            br.node[top], br.node[top + 1] = left, right
            br.node_mask[top], br.node_mask[top + 1] = ml, mr
        top += 2
    _store_counts(br, active)


def make_bvh_bundle_walk(search):
    """walk(agg, lv, trims, q, sl, br, active): the bundle through the BVH, each visited leaf's
    patches searched for the rays that reach it."""
    return njit(cache=True, nogil=True, _nrt=False, inline='always')(specialise(_bvh_bundle_walk, search=search))
