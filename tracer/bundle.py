"""Ray bundles (Dammertz 2.5.1): the rays of a block of pixels share one subdivision stack.

A bundle is up to 64 rays, one bit each in a uint64 mask. Every sub-patch on the stack carries
the mask of the rays still active in it, and each ray its own slab interval there (tin, tout);
a ray drops out where it misses a box, where its own closest hit prunes the box, or where the
hull tests drop a half for it. Each ray keeps its own hit, its own criterion (its threshold of
detail, its hit box on the grid) and its own counters, so what a ray reports is what it would
report alone: the boxes are the same, split in the same direction (the box alone decides it
under the `length` split and the float, fixed and mantissa criteria; otherwise the first ray
still active decides for the bundle), tested by the same steps. Only the order in which the
bundle visits two halves both of its rays meet differs (the half nearer to the bundle's nearest
ray first), which can change which of two boxes holding a crossing at the same t is reported.

The bundle walks the BVH as one: a node stays on the stack while any of its rays meets it.
Bundles serve primary rays (closest hit); they carry no box budget and record no trace.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

from .aggregate import BvhNodes  # noqa: F401 (the record the walk reads)
from .drivers import WIDE_BITS, wide_leaves, wide_slots
from .frustum import F_LEN, MIN_RAYS, at_least, bound_rays, misses_all
from .jit import njit, specialise
from .ray import H_TIN, RAY_LEN, R_O, R_TMIN, slab_at
from .records import C_BOX_TESTS, C_CACHE_HITS, C_CACHE_MISSES, C_EFFORT, C_NODES, C_PATCHES, C_SURFACES
from .search_steps import ADAPTIVE, halve, hull_accepts, judge_known, near_and_far, report, root_at, tighten
from .search_steps import trim_accepts, trim_state
from .subpatch import (I_DEPTH, I_LAST, I_STALLED, M_DPAR, M_OX, M_TIN, M_TOUT, hull_behind, hull_hit, hull_off_plane,
                       patch_info)
from .subpatch import open_box, seam_plane
from .surface_cache import S_DEPTH, S_FIRST, S_HITS, S_MISSES, copy_slot, take_pair, touch

ONE = np.uint64(1)
ZERO = np.uint64(0)
MAX_RAYS = 64

# A bundle's rays: rays and lrays (K, RAY_LEN) (lrays: moved into the searched patch's frame),
# hits (K, HIT_LEN), counts (K, COUNTER_LEN) int64, lengths (K,) |direction|; per position of
# the sub-patch stack: slot (S,) int32, mask (S,) uint64 and row (S,) int32, the row of tin, tout
# (S, K) holding the rays' slab intervals; free (S,) int32 working slots not in use; the BVH walk's
# stack: node (D,) int32, node_mask (D,) uint64, node_row (D,) int32, the row of node_tin (D, K).
# row and node_row are permutations: moving an entry's intervals to another position moves its
# row index, not K floats. bounds (frustum.F_LEN,): the bounds of the bundle's rays (the walk's).
BundleRays = namedtuple("BundleRays", "rays lrays hits counts lengths slot mask row tin tout free node node_mask "
                        "node_row node_tin bounds")

if numba.config.DISABLE_JIT:
    def _trailing_zeros(m):
        return (int(m) & -int(m)).bit_length() - 1
else:
    from numba.cpython.unsafe.numbers import trailing_zeros as _trailing_zeros


@njit(cache=True, nogil=True, inline='always')
def lowest_bit(m):
    """Index (int64: numba would unify a uint64 with int64 indices to a float) of the lowest set
    bit of a nonzero mask."""
    return np.int64(_trailing_zeros(m))


@njit(cache=True, nogil=True, inline='always')
def bit(r):
    return ONE << np.uint64(r)


@njit(cache=True, nogil=True, inline='always')
def add_count(counts, m, column, n):
    """counts[r, column] += n for every ray r of mask m."""
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        counts[r, column] += n


@njit(cache=True, nogil=True, inline='always')
def ahead(tin, row, hits, m, counts, column):
    """The rays of m whose entry t into the box of `row` (tin[row, r]) lies before their own
    closest hit: the others drop out of it. Each counted in counts[r, column] unless column < 0
    (a constant at every call: the test folds away)."""
    live = ZERO
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        if tin[row, r] < hits[r, H_TIN]:
            live |= bit(r)
            if column >= 0:
                counts[r, column] += 1
    return live


@njit(cache=True, nogil=True, inline='always')
def _enters(corners, rays, tin, hits, row, r):
    """Ray r (of rays) against a box's corners, shifted as slab shifts them: its entry t into
    tin[row, r]; (does it meet the box before its own closest hit, its exit t)."""
    lo0, lo1, lo2, hi0, hi1, hi2 = corners
    ok, t_in, t_out = slab_at(lo0, lo1, lo2, hi0, hi1, hi2, rays[r])
    tin[row, r] = t_in
    return ok and t_in < hits[r, H_TIN], t_out


@njit(cache=True, nogil=True, inline='always')
def _meets(corners, br, row, r):
    """Ray r against a slot's box, its corners shifted by the slot's offset (_corners): its
    interval into tin[row, r], tout[row, r]; does it meet the box before its own closest hit?"""
    alive, t_out = _enters(corners, br.lrays, br.tin, br.hits, row, r)
    br.tout[row, r] = t_out
    return alive


@njit(cache=True, nogil=True, inline='always')
def _corners(sl, s):
    """Slot s's box shifted into the patch's frame (lo xyz, hi xyz), as ray.slab shifts it: once
    for all the rays that test it."""
    box = sl.box
    mf = sl.mf
    return (box[s, 0] + mf[s, M_OX], box[s, 1] + mf[s, M_OX + 1], box[s, 2] + mf[s, M_OX + 2],
            box[s, 3] + mf[s, M_OX], box[s, 4] + mf[s, M_OX + 1], box[s, 5] + mf[s, M_OX + 2])


@njit(cache=True, nogil=True, inline='always')
def _behind(sl, s, pa, br, row, r):
    """Is slot s, whose box holds ray r's origin, wholly behind the ray's side plane (as
    search_steps.open_child drops it for the single ray)?"""
    return br.tin[row, r] <= br.lrays[r, R_TMIN] and hull_behind(sl, s, pa, br.lrays[r])


@njit(cache=True, nogil=True, inline='always')
def open_rays(sl, s, pa, br, row, m):
    """Slab-test slot s's box against the rays of m (intervals into tin[row], tout[row]); the
    rays that meet it before their own closest hit (and are not behind it: _behind)."""
    alive = ZERO
    corners = _corners(sl, s)
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        if _meets(corners, br, row, r) and not _behind(sl, s, pa, br, row, r):
            alive |= bit(r)
    return alive


@njit(cache=True, nogil=True, inline='always')
def open_pair(sl, a, b, pa, br, row_a, row_b, m):
    """open_rays for the halves a and b in one pass over the rays (each ray's two slab tests side
    by side); the rays of each half. (The bundle's bounds, frustum.py, rarely reject a half: counted
    on the teapot, 12 % of the halves tested by four rays or more, saving less than they cost.)"""
    alive_a = ZERO
    alive_b = ZERO
    corners_a = _corners(sl, a)
    corners_b = _corners(sl, b)
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        if _meets(corners_a, br, row_a, r) and not _behind(sl, a, pa, br, row_a, r):
            alive_a |= bit(r)
        if _meets(corners_b, br, row_b, r) and not _behind(sl, b, pa, br, row_b, r):
            alive_b |= bit(r)
    return alive_a, alive_b


@njit(cache=True, nogil=True, inline='always')
def _alone(sl, s, pa, lr, hit):
    """Slot s's box against one ray (its interval into the slot, as the single ray's search tests
    it): does the ray meet it before its closest hit, and not only behind its side plane? 1 or 0
    (open_rays for a mask of one ray)"""
    alive, _ = open_box(sl, s, lr, hit[H_TIN])
    return 1 if alive and not (sl.mf[s, M_TIN] <= lr[R_TMIN] and hull_behind(sl, s, pa, lr)) else 0


@njit(cache=True, nogil=True, inline='always')
def nearest(tin, row, m):
    """The smallest entry t into the box of `row` (tin[row, r]) over the rays of m."""
    t = np.inf
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        t = min(t, tin[row, r])
    return t


@njit(cache=True, nogil=True, inline='always')
def push_halves(sl, a, b, sp, pa, br, go, direction):
    """The halves a and b (b past the seam) at stack positions sp and sp + 1 for the rays of `go`:
    each ray's intervals, the single ray's hull tests where it meets both, the bundle's nearer
    half on top. Returns the new stack height and the halves no ray keeps (-1 for none)."""
    row_a = br.row[sp]
    row_b = br.row[sp + 1]
    keep_a, keep_b = open_pair(sl, a, b, pa, br, row_a, row_b, go)
    both = keep_a & keep_b
    while both != ZERO:  # as sort_halves: the far half across the seam plane and the ray's planes first
        r = lowest_bit(both)
        both &= both - ONE
        lr = br.lrays[r]
        a_near = br.tin[row_a, r] <= br.tin[row_b, r]
        far = b if a_near else a
        near = a if a_near else b
        w0, w1, w2 = seam_plane(sl, b, pa, direction, lr)
        if hull_off_plane(sl, far, pa, lr, w0, w1, w2) or not hull_hit(sl, far, pa, lr):
            if far == a:
                keep_a &= ~bit(r)
            else:
                keep_b &= ~bit(r)
        elif hull_off_plane(sl, near, pa, lr, w0, w1, w2) or not hull_hit(sl, near, pa, lr):
            if near == a:
                keep_a &= ~bit(r)
            else:
                keep_b &= ~bit(r)
    if keep_a != ZERO and keep_b != ZERO:
        if nearest(br.tin, row_a, keep_a) <= nearest(br.tin, row_b, keep_b):  # a nearer: a on top
            br.row[sp], br.row[sp + 1] = row_b, row_a
            a, b, keep_a, keep_b = b, a, keep_b, keep_a
        br.slot[sp], br.slot[sp + 1] = a, b
        br.mask[sp], br.mask[sp + 1] = keep_a, keep_b
        return sp + 2, -1, -1
    if keep_a == ZERO and keep_b == ZERO:
        return sp, a, b
    if keep_b != ZERO:  # only b: to position sp
        br.row[sp], br.row[sp + 1] = row_b, row_a
        br.slot[sp] = b
        br.mask[sp] = keep_b
        return sp + 1, a, -1
    br.slot[sp] = a
    br.mask[sp] = keep_a
    return sp + 1, b, -1


def _solo_search(sl, a, pa, lv, trims, q, br, r, base, free, nfree):
    """The rest of working slot a's subtree for ray r alone, the bundle's last ray in it: the
    single ray's steps (drivers._search) on the bundle's stack above position `base`, without a
    mask, a row of intervals or a loop over rays. a's interval is in its slot; it is live and
    not trimmed away. The same boxes, tests and order as the bundle's steps for a mask of one ray
    (push_halves: a tie in t puts a on top, as sort_halves makes it the near half). Returns the
    free slots' count."""
    lr = br.lrays[r]
    hit = br.hits[r]
    mf = sl.mf
    stack = br.slot
    stack[base] = a
    top = base + 1
    checked = True  # a passed the bundle's own prune and trim tests
    while top > base:
        top -= 1
        a = stack[top]
        if not checked:
            if mf[a, M_TIN] >= hit[H_TIN] or (HAS_TRIMS and trim_state(sl, a, pa, trims) < 0):  # noqa: F821
                free[nfree] = a
                nfree += 1
                continue
        checked = False
        stop, d_crit, shrank, _ = judge_known(sl, a, pa, lv, lr, q, -1.0)
        if stop:
            if hull_accepts(sl, a, pa, lr, q) and (not HAS_TRIMS or trim_accepts(sl, a, pa, trims)):  # noqa: F821
                report(hit, sl, a, pa, lv)
            free[nfree] = a
            nfree += 1
            continue
        br.counts[r, C_EFFORT] += 2
        tighten(sl, a, pa, lv)
        nfree -= 1
        b = free[nfree]
        direction = halve(sl, a, b, pa, lr, q, d_crit, shrank, HAS_GENERAL)  # noqa: F821
        alive_a = _alone(sl, a, pa, lr, hit)
        alive_b = _alone(sl, b, pa, lr, hit)
        far, near, alive_far, alive_near, _ = near_and_far(sl, a, b, pa, lr, direction, alive_a, alive_b)
        for half, alive in ((far, alive_far), (near, alive_near)):  # the near half on top
            if alive:
                stack[top] = half
                top += 1
            else:
                free[nfree] = half
                nfree += 1
    return nfree


def _bundle_search(p, lv, trims, q, sl, br, active):
    """The bundle patch search template (specialised by make_bundle_search): the single ray's
    steps (drivers._search, _cached_search with CACHED) for the rays of a mask, on a stack of
    positions that hold a slot (a working slot, or a cached node), a mask and the rays' intervals."""
    pa = patch_info(lv, p, WIDE_BITS if WIDE else q.bits, HAS_RATIONAL, HAS_CUBIC, HAS_LINEAR)  # noqa: F821
    m = active
    while m != ZERO:  # each ray moved into the patch's frame
        r = lowest_bit(m)
        m &= m - ONE
        for k in range(RAY_LEN):
            br.lrays[r, k] = br.rays[r, k]
        for c in range(3):
            br.lrays[r, R_O + c] = br.rays[r, R_O + c] - lv.frame[p, c]
    cache = sl.cache
    first = cache.state[S_FIRST] if CACHED else br.free.shape[0]  # noqa: F821
    ncoord = 4 if pa.rational else 3
    free = br.free
    nfree = br.free.shape[0]
    for k in range(nfree):  # every working slot is free when a search starts
        free[k] = k
    s = -1
    if CACHED:  # noqa: F821
        touch(cache, p)
        s = cache.root[p]
        add_count(br.counts, active, C_CACHE_HITS if s >= 0 else C_CACHE_MISSES, 1)
        cache.state[S_HITS if s >= 0 else S_MISSES] += 1
        if s < 0:
            s = take_pair(cache, p)
            if s >= 0:
                cache.root[p] = s
                cache.child[s - first] = -1
                root_at(sl, s, pa, lv)
    if s < 0:
        nfree -= 1
        s = free[nfree]
        root_at(sl, s, pa, lv)
    add_count(br.counts, active, C_EFFORT, 1)
    br.slot[0] = s
    br.mask[0] = open_rays(sl, s, pa, br, br.row[0], active)
    sp = 1 if br.mask[0] != ZERO else 0
    while sp > 0:
        sp -= 1
        a = br.slot[sp]
        cached = a >= first
        row = br.row[sp]
        live = ahead(br.tin, row, br.hits, br.mask[sp], br.counts, -1)
        if live == ZERO or (HAS_TRIMS and trim_state(sl, a, pa, trims) < 0):  # noqa: F821
            if not cached:
                free[nfree] = a
                nfree += 1
            continue
        if SOLO:  # noqa: F821
            if not cached and (live & (live - ONE)) == ZERO:  # one ray left: on alone (_solo_search)
                r = lowest_bit(live)
                sl.mf[a, M_TIN] = br.tin[row, r]
                sl.mf[a, M_TOUT] = br.tout[row, r]
                nfree = solo(sl, a, pa, lv, trims, q, br, r, sp, free, nfree)  # noqa: F821
                continue
        go = ZERO
        first_ray = 0
        d_first = 0.0
        shrank_first = False
        kept = -1  # the box's trim verdict, once a ray needs it
        # The criterion is judged once for the box, per ray only where it reads the ray (adaptive:
        # its threshold at the ray's t), the box's grid diameter computed at most once.
        per_ray = q.criterion == ADAPTIVE
        stop, d_crit, shrank, g = False, 0.0, False, -1.0
        if not per_ray:
            stop, d_crit, shrank, g = judge_known(sl, a, pa, lv, br.lrays[lowest_bit(live)], q, g)
        m = live
        while m != ZERO:
            r = lowest_bit(m)
            m &= m - ONE
            sl.mf[a, M_TIN] = br.tin[row, r]  # the steps read the ray's interval from the slot
            sl.mf[a, M_TOUT] = br.tout[row, r]
            if per_ray:
                stop, d_crit, shrank, g = judge_known(sl, a, pa, lv, br.lrays[r], q, g)
            if not stop:
                if go == ZERO:
                    first_ray, d_first, shrank_first = r, d_crit, shrank
                go |= bit(r)
            elif hull_accepts(sl, a, pa, br.lrays[r], q):
                if HAS_TRIMS and kept < 0:  # noqa: F821
                    kept = 1 if trim_accepts(sl, a, pa, trims) else 0
                if kept != 0:
                    report(br.hits[r], sl, a, pa, lv)
        if go == ZERO:
            if not cached:
                free[nfree] = a
                nfree += 1
            continue
        add_count(br.counts, go, C_EFFORT, 2)
        lr = br.lrays[first_ray]
        kid = -1
        if CACHED and cached and sl.mi[a, I_DEPTH] < cache.state[S_DEPTH]:  # noqa: F821
            kid = cache.child[a - first]
            if kid < 0:  # compute the halves once, from a working copy, and keep them
                kid = take_pair(cache, p)
                if kid >= 0:
                    w = free[nfree - 1]
                    b = free[nfree - 2]
                    copy_slot(sl, a, w, ncoord, pa.count)
                    tighten(sl, w, pa, lv)
                    halve(sl, w, b, pa, lr, q, d_first, shrank_first, HAS_GENERAL)  # noqa: F821
                    copy_slot(sl, w, kid, ncoord, pa.count)
                    copy_slot(sl, b, kid + 1, ncoord, pa.count)
                    cache.child[a - first] = kid
                    cache.child[kid - first] = -1
                    cache.child[kid + 1 - first] = -1
        if kid >= 0:  # the cached halves, with the first ray's view of their parent
            for c in (kid, kid + 1):
                sl.mf[c, M_DPAR] = d_first
                sl.mi[c, I_STALLED] = 0 if shrank_first else 1
            sp, _, _ = push_halves(sl, kid, kid + 1, sp, pa, br, go, sl.mi[kid, I_LAST])
            continue
        if cached:  # below the cached levels (or the pool is full): on in working slots
            nfree -= 1
            w = free[nfree]
            copy_slot(sl, a, w, ncoord, pa.count)
            a = w
        tighten(sl, a, pa, lv)
        nfree -= 1
        b = free[nfree]
        direction = halve(sl, a, b, pa, lr, q, d_first, shrank_first, HAS_GENERAL)  # noqa: F821
        sp, dropped, dropped2 = push_halves(sl, a, b, sp, pa, br, go, direction)
        for c in (dropped, dropped2):
            if c >= 0:
                free[nfree] = c
                nfree += 1


def _by_kind(p, lv, trims, q, sl, br, active):
    if lv.rational[p] != 0:
        wide(p, wide_leaves(lv), trims, q, wide_slots(sl), br, active)  # noqa: F821
    else:
        narrow(p, lv, trims, q, sl, br, active)  # noqa: F821


def _rational_only(p, lv, trims, q, sl, br, active):
    wide(p, wide_leaves(lv), trims, q, wide_slots(sl), br, active)  # noqa: F821


def make_bundle_search(variant, alone: bool = True):
    """search(p, lv, trims, q, sl, br, active): patch p searched for the rays of mask `active` of
    the bundle br (BundleRays); each ray's hit shrinks as it finds closer hit boxes. Integral
    patches in the working precision, rational ones in float64 slots (as drivers.make_search),
    from the thread's surface-tree cache if the variant has it. alone: a ray left alone in a
    sub-patch goes on with the single ray's steps (_solo_search: a second copy of the steps to
    compile, about 15 s cold; it pays for primary rays under `float`, not for shadow rays)."""
    flags = dict(HAS_TRIMS=variant.trims, CACHED=variant.cache, SOLO=alone)
    kernel = njit(cache=True, nogil=True, _nrt=False)

    def solo(general):
        if not alone:
            return None
        return njit(cache=True, nogil=True, _nrt=False, inline='always')(
            specialise(_solo_search, HAS_TRIMS=variant.trims, HAS_GENERAL=general))
    narrow = None
    if variant.cubic or variant.linear or variant.general:
        narrow = kernel(specialise(_bundle_search, WIDE=False, HAS_RATIONAL=False, HAS_CUBIC=variant.cubic,
                                   HAS_LINEAR=variant.linear, HAS_GENERAL=variant.general,
                                   solo=solo(variant.general), **flags))
    if not variant.rational:
        return narrow
    wide = kernel(specialise(_bundle_search, WIDE=True, HAS_RATIONAL=True, HAS_CUBIC=False, HAS_LINEAR=False,
                             HAS_GENERAL=True, solo=solo(True), **flags))
    dispatch = _rational_only if narrow is None else _by_kind
    return njit(cache=True, nogil=True, _nrt=False, inline='always')(specialise(dispatch, wide=wide, narrow=narrow))


@njit(cache=True, nogil=True, inline='always')
def _node_corners(node_box, node):
    """A BVH node's box as slab_at takes it (slab's shift by NO_SHIFT, -0.0, leaves every corner as
    it is)."""
    box = node_box[node]
    return box[0], box[1], box[2], box[3], box[4], box[5]


@njit(cache=True, nogil=True, inline='always')
def _node_rays(node_box, node, br, row, m):
    """Slab-test a BVH node against the rays of m (intervals into node_tin[row]); the rays that
    meet it before their own closest hit."""
    alive = ZERO
    corners = _node_corners(node_box, node)
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        if _enters(corners, br.rays, br.node_tin, br.hits, row, r)[0]:
            alive |= bit(r)
    return alive


@njit(cache=True, nogil=True, inline='always')
def _children_rays(node_box, left, right, br, row_l, row_r, m, surfaces):
    """Both children of a BVH node against the rays of m (intervals into node_tin[row_l] and
    [row_r]) in one pass over the rays, which also counts each ray's two box tests and the
    surfaces of the leaf children among them; the rays of each child. With enough rays, a child
    the bundle's bounds miss (frustum.py: the same verdicts) is not tested ray by ray."""
    corners_l = _node_corners(node_box, left)
    corners_r = _node_corners(node_box, right)
    test_l = True
    test_r = True
    if at_least(m, MIN_RAYS):
        test_l = not misses_all(corners_l, br.bounds)
        test_r = not misses_all(corners_r, br.bounds)
    alive_l = ZERO
    alive_r = ZERO
    counts = br.counts
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        counts[r, C_BOX_TESTS] += 2
        counts[r, C_SURFACES] += surfaces
        if test_l and _enters(corners_l, br.rays, br.node_tin, br.hits, row_l, r)[0]:
            alive_l |= bit(r)
        if test_r and _enters(corners_r, br.rays, br.node_tin, br.hits, row_r, r)[0]:
            alive_r |= bit(r)
    return alive_l, alive_r


def _bvh_bundle_walk(agg, lv, trims, q, sl, br, active):
    """The BVH walk of a bundle (template, specialised by make_bvh_bundle_walk)."""
    node_child = agg.node_child
    counts = br.counts
    add_count(counts, active, C_BOX_TESTS, 1)
    if node_child[0, 0] < 0:
        add_count(counts, active, C_SURFACES, agg.leaf_count[0])
    bound_rays(br.bounds, br.rays, active)
    m = _node_rays(agg.node_box, 0, br, br.node_row[0], active)
    if m == ZERO:
        return
    br.node[0] = 0
    br.node_mask[0] = m
    top = 1
    while top > 0:
        top -= 1
        node = br.node[top]
        live = ahead(br.node_tin, br.node_row[top], br.hits, br.node_mask[top], counts, C_NODES)  # counted too
        if live == ZERO:
            continue
        left = node_child[node, 0]
        if left < 0:
            first = agg.leaf_first[node]
            add_count(counts, live, C_PATCHES, agg.leaf_count[node])  # the searches below count no patches
            for k in range(first, first + agg.leaf_count[node]):
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
        if nearest(br.node_tin, row_l, ml) <= nearest(br.node_tin, row_r, mr):  # left nearer: right below it
            br.node_row[top], br.node_row[top + 1] = row_r, row_l
            br.node[top], br.node[top + 1] = right, left
            br.node_mask[top], br.node_mask[top + 1] = mr, ml
        else:
            br.node[top], br.node[top + 1] = left, right
            br.node_mask[top], br.node_mask[top + 1] = ml, mr
        top += 2


def make_bvh_bundle_walk(search):
    """walk(agg, lv, trims, q, sl, br, active): the bundle through the BVH, each visited leaf's
    patches searched for the rays that reach it."""
    return njit(cache=True, nogil=True, _nrt=False, inline='always')(specialise(_bvh_bundle_walk, search=search))


def bundle_rays(count: int, slots: int, stack: int) -> BundleRays:
    """A bundle's records for up to `count` rays, `slots` working sub-patch slots (the search's stack
    is no deeper) and a walk `stack` deep."""
    from .ray import HIT_LEN
    from .records import COUNTER_LEN
    return BundleRays(np.zeros((count, RAY_LEN)), np.zeros((count, RAY_LEN)), np.zeros((count, HIT_LEN)),
                      np.zeros((count, COUNTER_LEN), np.int64), np.zeros(count), np.zeros(slots, np.int32),
                      np.zeros(slots, np.uint64), np.arange(slots, dtype=np.int32), np.zeros((slots, count)),
                      np.zeros((slots, count)), np.zeros(slots, np.int32), np.zeros(stack, np.int32),
                      np.zeros(stack, np.uint64), np.arange(stack, dtype=np.int32), np.zeros((stack, count)),
                      np.zeros(F_LEN))
