"""Ray bundles (Dammertz 2.5.1): the rays of a block of pixels share one subdivision stack.

A bundle is up to 64 rays, one bit each in a uint64 mask. Every sub-patch on the stack carries
the mask of the rays still active in it, and each ray its own slab interval there (tin, tout);
a ray drops out where it misses a box, where its own closest hit prunes the box, or where the
hull tests drop a half for it. Each ray keeps its own hit, its own criterion (its threshold of
detail, its hit box on the grid) and its own counters, so what a ray reports is what it would
report alone: the boxes are the same, split in the same direction (the box alone decides it
under the `length` split, whatever the criterion: the adaptive criterion's shrink test reads the
box's own measure; with `cross` the first ray still active decides for the bundle), tested by the
same steps. Only the order in which the bundle visits two halves both of its rays meet differs
(the half nearer to the bundle's nearest ray first), and no order decides a hit: the tie rule
(ray.search_limit, ray.before_best) picks the same box among those entered at the same t. The
lanes prune by t alone, so within the best hit's own leaf they let a box entered at the best t
through (bundle_steps.lane_limit), and the report asks the key.

The bundle walks the BVH as one (bundle_walk.py). The steps of its search are in bundle_steps.py:
the slab tests of sub-patch boxes, the prune by each ray's closest hit, the nearest entry and
the adaptive criterion's threshold go eight rays at a time (lanes.py: the rays' origins,
directions, closest hits and thresholds in columns, each lane the scalar test's operations), the
rest ray by ray over the mask's bits.
Bundles serve primary rays, and shadow and reflected rays (shadow_bundles.py); they carry no box
budget and record no trace.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .bundle_alone import _rays_alone_lanes, alone_lanes
from .bundle_steps import (ONE, W_LEN, ZERO, add_count, ahead_in, bit, judge_detail, lane_limit, lowest_bit, open_root,
                           push_halves)
from .drivers import WIDE_BITS, wide_leaves, wide_slots
from .frustum import F_LEN
from .jit import njit, specialise
from .lanes import L_BEST, L_HIT, L_LEN, L_PO, padded
from .ray import H_PATCH, H_TIN, RAY_LEN, R_O, before_best, search_limit
from .records import C_CACHE_HITS, C_CACHE_MISSES, C_EFFORT
from .search_steps import (ADAPTIVE, ahead, halve, hull_accepts, judge_known, near_and_far, open_slot, report,
                           root_at)
from .search_steps import tighten, trim_accepts, trim_state
from .subpatch import I_DEPTH, I_LAST, I_STALLED, M_DPAR, M_TIN, M_TOUT, M_U0, M_V0, patch_info
from .surface_cache import S_DEPTH, S_FIRST, S_HITS, S_MISSES, copy_slot, keep_halves, take_pair, touch

MAX_RAYS = 64

# A bundle's rays: rays and lrays (K, RAY_LEN) (lrays: moved into the searched patch's frame),
# hits (K, HIT_LEN), counts (K, COUNTER_LEN) int64, lengths (K,) |direction|; per position of
# the sub-patch stack: slot (S,) uint32, mask (S,) uint64 and row (S,) int32, the row of tin, tout
# (S, K) holding the rays' slab intervals; free (S,) uint32 working slots not in use; the BVH walk's
# stack: node (D,) int32, node_mask (D,) uint64, node_row (D,) int32, the row of node_tin (D, K).
# Slots are unsigned, as tile_scratch's order: a signed slot index costs every array access a
# negative-index fix-up (measured: float 8x8 8 % slower, adaptive 3 %).
# waiting (K,) uint32: the working slot a ray left alone waits in (_bundle_search); alone: the lane
# slots rays alone go on in, eight at a time (bundle_alone.AloneLanes).
# row and node_row are permutations: moving an entry's intervals to another position moves its
# row index, not K floats. bounds (frustum.F_LEN,): the bounds of the bundle's rays (the walk's).
# The walk's rays in lanes (lanes.py: (L_LEN, K') with K' = K rounded up to whole groups of
# WIDTH, as node_tin's rows are) and its counters there, walk_counts (W_LEN, K') int64.
BundleRays = namedtuple("BundleRays", "rays lrays hits counts lengths slot mask row tin tout free node node_mask "
                        "node_row node_tin bounds lanes walk_counts waiting alone")
# A ray left alone in a sub-patch waits there until the bundle pops an entry that holds it, or
# until this many wait; then the waiting rays go on alone, in one call (_rays_alone). Each waiting
# ray holds a working slot (tile_kernel.working_slots counts them).
WAITING = 16


def _solo_search(sl, start, pa, lv, trims, q, br, r, base, free, nfree):
    """The rest of working slot start's subtree for ray r alone, the bundle's last ray in it: the
    single ray's steps (drivers._search) on the bundle's stack above position `base`, without a
    mask, a row of intervals or a loop over rays. start's interval is in its slot; it is live and
    not trimmed away (start is not a name of the loop's, whose slots are unsigned). The same
    boxes, tests and order as the bundle's steps for a mask of one ray (push_halves: a tie in t
    puts a on top, as sort_halves makes it the near half). Returns the free slots' count."""
    lr = br.lrays[r]
    hit = br.hits[r]
    mf = sl.mf
    stack = br.slot
    stack[base] = start
    top = base + 1
    checked = True  # a passed the bundle's own trim test (its prune lets ties within the leaf through)
    while top > base:
        top -= 1
        a = stack[top]
        if not ahead(sl, a, pa, hit) or (HAS_TRIMS and not checked and trim_state(sl, a, pa, trims) < 0):  # noqa: F821
            free[nfree] = a
            nfree += 1
            checked = False
            continue
        checked = False
        stop, d_crit, shrank, _ = judge_known(sl, a, pa, lv, lr, q, -1.0)
        if stop:
            if hull_accepts(sl, a, pa, lv, lr, q) and (not HAS_TRIMS or trim_accepts(sl, a, pa, trims)):  # noqa: F821
                report(hit, sl, a, pa, lv)
            free[nfree] = a
            nfree += 1
            continue
        br.counts[r, C_EFFORT] += 2
        t_start = mf[a, M_TIN]
        t_stop = mf[a, M_TOUT]
        tighten(sl, a, pa, lv)
        nfree -= 1
        b = free[nfree]
        direction = halve(sl, a, b, pa, lr, q, d_crit, shrank, HAS_GENERAL)  # noqa: F821
        alive_a, met_a = open_slot(sl, a, pa, lr, t_start, t_stop, hit)
        alive_b, met_b = open_slot(sl, b, pa, lr, t_start, t_stop, hit)
        far, near, alive_far, alive_near, _ = near_and_far(sl, a, b, pa, lr, direction, alive_a, alive_b,
                                                           met_a & met_b)
        for half, alive in ((far, alive_far), (near, alive_near)):  # the near half on top
            if alive:
                stack[top] = half
                top += 1
            else:
                free[nfree] = half
                nfree += 1
    return nfree


def _rays_alone(p, lv, trims, q, sl, br, waiting, base, nfree):
    """The rays of mask `waiting` each on alone from the slot it waits in (br.waiting; _solo_search
    above stack position `base`), one after another. Returns the free slots' count. Compiled
    apart from the bundle search, so that the machine code of the steps that take most of a
    float frame does not move with every change to the shared ones (coherence-history, stop 37)."""
    pa = patch_info(lv, p, WIDE_BITS if WIDE else q.bits, HAS_RATIONAL, HAS_CUBIC, HAS_LINEAR)  # noqa: F821
    free = br.free
    m = waiting
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        nfree = solo(sl, br.waiting[r], pa, lv, trims, q, br, r, base, free, nfree)  # noqa: F821
        br.lanes[L_HIT, r] = lane_limit(br.hits[r], pa.p)
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
            br.lanes[L_PO + c, r] = br.lrays[r, R_O + c]
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
    br.mask[0] = open_root(sl, s, pa, br, br.row[0], active, SIDED)  # noqa: F821
    sp = 1 if br.mask[0] != ZERO else 0
    waiting = ZERO  # the rays left alone, each in its slot (br.waiting): a ray's own search is
    nwaiting = 0    # all it waits for, so they go on before the next entry that holds one of them
    while sp > 0 or waiting != ZERO:
        if SOLO:  # noqa: F821
            if waiting != ZERO and (sp == 0 or nwaiting == WAITING or (br.mask[sp - 1] & waiting) != ZERO):
                nfree = rays_alone(p, lv, trims, q, sl, br, waiting, sp, nfree)  # noqa: F821
                waiting = ZERO
                nwaiting = 0
                continue
        sp -= 1
        a = br.slot[sp]
        cached = a >= first
        row = br.row[sp]
        live = ahead_in(br.tin, br, row, br.mask[sp], False)
        if live == ZERO or (HAS_TRIMS and trim_state(sl, a, pa, trims) < 0):  # noqa: F821
            if not cached:
                free[nfree] = a
                nfree += 1
            continue
        if SOLO:  # noqa: F821
            if not cached and (live & (live - ONE)) == ZERO:  # one ray left: on alone, soon (_rays_alone)
                r = lowest_bit(live)
                sl.mf[a, M_TIN] = br.tin[row, r]
                sl.mf[a, M_TOUT] = br.tout[row, r]
                br.waiting[r] = a
                waiting |= bit(r)
                nwaiting += 1
                continue
        # The criterion is judged once for the box where it reads no ray; under adaptive, for
        # each ray (its threshold at its entry t), eight at a time.
        if q.criterion == ADAPTIVE:
            stop, go, first_ray, d_first, shrank_first = judge_detail(sl, a, pa, lv, q, br, row, live)
        else:
            first_ray = lowest_bit(live)
            stop_box, d_first, shrank_first, _ = judge_known(sl, a, pa, lv, br.lrays[first_ray], q, -1.0)
            stop = live if stop_box else ZERO
            go = live & ~stop
        kept = -1  # the box's trim verdict, once a ray needs it
        m = stop
        while m != ZERO:
            r = lowest_bit(m)
            m &= m - ONE
            # (the lanes let a box entered at the best t within its leaf through: the key decides)
            if before_best(br.tin[row, r], sl.mf[a, M_U0], sl.mf[a, M_V0], br.hits[r], pa.p) and hull_accepts(
                    sl, a, pa, lv, br.lrays[r], q):
                if HAS_TRIMS and kept < 0:  # noqa: F821
                    kept = 1 if trim_accepts(sl, a, pa, trims) else 0
                if kept != 0:
                    sl.mf[a, M_TIN] = br.tin[row, r]  # report reads the ray's interval from the slot
                    sl.mf[a, M_TOUT] = br.tout[row, r]
                    report(br.hits[r], sl, a, pa, lv)
                    br.lanes[L_HIT, r] = lane_limit(br.hits[r], pa.p)
        if go == ZERO:
            if not cached:
                free[nfree] = a
                nfree += 1
            continue
        add_count(br.counts, go, C_EFFORT, 2)
        lr = br.lrays[first_ray]
        kid = -1
        build = False
        if CACHED and cached and sl.mi[a, I_DEPTH] < cache.state[S_DEPTH]:  # noqa: F821
            kid = cache.child[a - first]
            if kid < 0:  # compute the halves once, in working slots, and keep them
                kid = take_pair(cache, p)
                build = kid >= 0
        if kid >= 0 and not build:  # the cached halves, with the first ray's view of their parent
            for c in (kid, kid + 1):
                sl.mf[c, M_DPAR] = d_first
                sl.mi[c, I_STALLED] = 0 if shrank_first else 1
            a = np.uint32(kid)  # (unsigned, as the stack's slots)
            b = np.uint32(kid + 1)
            direction = sl.mi[kid, I_LAST]
        else:
            node = a
            if cached:  # below the cached levels (or the pool is full): on in working slots
                nfree -= 1
                w = free[nfree]
                copy_slot(sl, a, w, ncoord, pa.count)
                a = w
            tighten(sl, a, pa, lv)
            nfree -= 1
            b = free[nfree]
            direction = halve(sl, a, b, pa, lr, q, d_first, shrank_first, HAS_GENERAL)  # noqa: F821
            if CACHED and build:  # noqa: F821 (into the cache; the working slots go back)
                nfree = keep_halves(sl, cache, node, a, b, kid, ncoord, pa.count, free, nfree)
                a = np.uint32(kid)
                b = np.uint32(kid + 1)
        # One inlined copy of the halving and of push_halves for cached and computed halves (a
        # copy in each branch: float 8x8 with the cache 3 % slower, adaptive 5 %).
        sp, dropped, dropped2 = push_halves(sl, a, b, sp, pa, br, go, direction, SIDED)  # noqa: F821
        if kid < 0:  # (cached halves stay in the cache)
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


def _closest_rays(p, lv, trims, q, sl, br, active):
    """search for the rays of `active`, each up to its ray.search_limit (the tie rule). The walk's
    lanes hold the next float past each ray's best t (the walk lets boxes entered at the best t
    through), the search's the t it searches up to."""
    m = active
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        br.lanes[L_BEST, r] = br.hits[r, H_TIN]
        br.hits[r, H_TIN] = search_limit(br.hits[r], p)
        br.lanes[L_HIT, r] = lane_limit(br.hits[r], p)
    search(p, lv, trims, q, sl, br, active)  # noqa: F821
    m = active
    while m != ZERO:
        r = lowest_bit(m)
        m &= m - ONE
        if br.hits[r, H_PATCH] != p:  # nothing found: the best stays
            br.hits[r, H_TIN] = br.lanes[L_BEST, r]
        br.lanes[L_HIT, r] = np.nextafter(br.hits[r, H_TIN], np.inf)


def make_bundle_search(variant, alone: bool = True, sided: bool = True):
    """search(p, lv, trims, q, sl, br, active): patch p searched for the rays of mask `active` of
    the bundle br (BundleRays); each ray's hit shrinks as it finds closer hit boxes. Integral
    patches in the working precision, rational ones in float64 slots (as drivers.make_search),
    from the thread's surface-tree cache if the variant has it. alone: a ray left alone in a
    sub-patch goes on with the single ray's steps (_rays_alone, _solo_search: a second copy of
    the steps to compile; it pays for primary rays under `float`, not for shadow rays). sided:
    the rays may have side planes (ray.set_side: secondary rays; False for primary rays)."""
    flags = dict(HAS_TRIMS=variant.trims, CACHED=variant.cache, SOLO=alone, SIDED=sided)
    kernel = njit(cache=True, nogil=True, _nrt=False)

    def solo(general):
        return njit(cache=True, nogil=True, _nrt=False, inline='always')(
            specialise(_solo_search, HAS_TRIMS=variant.trims, HAS_GENERAL=general))

    def searcher(**kinds):
        alone_kernel = None
        if alone:
            lanes = (kinds["HAS_CUBIC"] or kinds["HAS_LINEAR"]) and not kinds["WIDE"] and not variant.trims
            if not (lanes and not kinds["HAS_GENERAL"]):  # (only lanes: the one-ray kernel is not compiled)
                alone_kernel = kernel(specialise(_rays_alone, solo=solo(kinds["HAS_GENERAL"]), **kinds, **flags))
            if lanes:  # eight at a time
                alone_kernel = kernel(specialise(_rays_alone_lanes, rays_alone=alone_kernel, **kinds, **flags))
        return kernel(specialise(_bundle_search, rays_alone=alone_kernel, **kinds, **flags))
    narrow = None
    if variant.cubic or variant.linear or variant.general:
        narrow = searcher(WIDE=False, HAS_RATIONAL=False, HAS_CUBIC=variant.cubic, HAS_LINEAR=variant.linear,
                          HAS_GENERAL=variant.general)
    search = narrow
    if variant.rational:
        wide = searcher(WIDE=True, HAS_RATIONAL=True, HAS_CUBIC=False, HAS_LINEAR=False, HAS_GENERAL=True)
        dispatch = _rational_only if narrow is None else _by_kind
        search = njit(cache=True, nogil=True, _nrt=False, inline='always')(specialise(dispatch, wide=wide,
                                                                                      narrow=narrow))
    return njit(cache=True, nogil=True, _nrt=False, inline='always')(specialise(_closest_rays, search=search))


def bundle_rays(count: int, slots: int, stack: int, dtype=np.float32) -> BundleRays:
    """A bundle's records for up to `count` rays, `slots` working sub-patch slots (the search's stack
    is no deeper) in `dtype` and a walk `stack` deep."""
    from .ray import HIT_LEN
    from .records import COUNTER_LEN
    return BundleRays(np.zeros((count, RAY_LEN)), np.zeros((count, RAY_LEN)), np.zeros((count, HIT_LEN)),
                      np.zeros((count, COUNTER_LEN), np.int64), np.zeros(count), np.zeros(slots, np.uint32),
                      np.zeros(slots, np.uint64), np.arange(slots, dtype=np.int32), np.zeros((slots, padded(count))),
                      np.zeros((slots, padded(count))), np.zeros(slots, np.uint32), np.zeros(stack, np.int32),
                      np.zeros(stack, np.uint64), np.arange(stack, dtype=np.int32),
                      np.zeros((stack, padded(count))), np.zeros(F_LEN), np.zeros((L_LEN, padded(count))),
                      np.zeros((W_LEN, padded(count)), np.int64), np.zeros(count, np.uint32), alone_lanes(slots, dtype))
