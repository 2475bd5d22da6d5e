"""Query drivers: a patch search put together from the steps in search_steps.py.

Two queries, as pbrt's shapes answer Intersect and IntersectP:
  closest hit  the nearest hit box before hit[H_TIN] (primary rays; later reflected and
               refracted ones): a found hit shortens the ray and prunes the rest;
  any hit      the first hit box in (t_min, hit[H_TIN]) ends the search (shadow rays).
Both keep an explicit stack of sub-patches, near half first (Dammertz 2005, ch. 2).

Drivers are built per kernel variant (variants.Variant): its flags are compile-time constants
(jit.specialise), so numba compiles only the code paths a scene needs (no rational, trim or trace
code for an integral untrimmed scene). Kernels that allocate nothing compile with numba's
`_nrt=False`: they only borrow arrays, and without it numba keeps atomic reference counts of
them inside the loop (a fifth of the search time).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import njit, specialise

from .ray import H_PATCH, H_TIN, R_BUDGET, R_TMIN, search_limit
from .records import Leaves, Slots
from .search_steps import HIT, MISS, PRUNED, accept, ahead, enter_frame, halve, judge, open_child, report, root, root_at
from .search_steps import set_event, sort_halves, subdivide, tighten, trace_hit, trim_state
from .subpatch import I_DEPTH, I_LAST, I_STALLED, M_DPAR, M_TIN, M_TOUT, patch_info
from .surface_cache import S_DEPTH, S_FIRST, S_HITS, S_MISSES, copy_slot, keep_halves, take_pair, touch

WIDE_BITS = 53  # rational patches are searched in float64 slots whatever the working precision


def _search(p, lv, trims, ray, hit, q, sl, trace):
    """The patch search template (specialised by make_search)."""
    pa = patch_info(lv, p, WIDE_BITS if WIDE else q.bits, HAS_RATIONAL, HAS_CUBIC, HAS_LINEAR)  # noqa: F821
    lray = enter_frame(sl, ray, lv, p)
    s = root(sl, pa, lv)
    effort = 1
    budget = ray[R_BUDGET]
    sp, _ = open_child(sl, s, pa, lv, lray, lray[R_TMIN], math.inf, hit, trace, TRACING)  # noqa: F821
    while sp > 0 and effort < budget:
        sp -= 1
        a = sl.order[sp]
        if not ahead(sl, a, pa, hit):
            if TRACING:  # noqa: F821
                set_event(trace, sl, a, PRUNED)
            continue
        if HAS_TRIMS and trim_state(sl, a, pa, trims) < 0:  # noqa: F821
            if TRACING:  # noqa: F821
                set_event(trace, sl, a, MISS)  # trimmed away as a whole
            continue
        stop, d_crit, shrank = judge(sl, a, pa, lv, lray, q)
        if stop:
            found = accept(sl, a, pa, lv, lray, q, trims, HAS_TRIMS)  # noqa: F821
            if TRACING:  # noqa: F821
                set_event(trace, sl, a, HIT if found else MISS)
            if found:
                report(hit, sl, a, pa, lv)
                if TRACING:  # noqa: F821
                    trace_hit(trace, sl, a, hit)
                if STOP_AT_FIRST:  # noqa: F821
                    return effort
            continue
        tighten(sl, a, pa, lv)
        sp = subdivide(sl, a, sp, pa, lv, lray, q, hit, d_crit, shrank, trace, TRACING,  # noqa: F821
                       HAS_GENERAL)  # noqa: F821
        effort += 2
    return effort


@njit(cache=True, nogil=True, inline='always')
def _halve_working(sl, a, cached, pa, lv, lray, q, d_crit, shrank, free, nfree, ncoord, has_general):
    """Halve slot a in working slots, a cached node copied into one first: (a, b, the direction,
    the free slots' count)."""
    if cached:
        nfree -= 1
        w = free[nfree]
        copy_slot(sl, a, w, ncoord, pa.count)
        a = w
    tighten(sl, a, pa, lv)
    nfree -= 1
    b = free[nfree]
    return a, b, halve(sl, a, b, pa, lray, q, d_crit, shrank, has_general), nfree


def _cached_search(p, lv, trims, ray, hit, q, sl, trace):
    """The patch search template with the surface-tree cache (surface_cache.py): the steps of
    _search, on a stack of slots that are cached nodes (never freed) or working slots."""
    cache = sl.cache
    pa = patch_info(lv, p, WIDE_BITS if WIDE else q.bits, HAS_RATIONAL, HAS_CUBIC, HAS_LINEAR)  # noqa: F821
    lray = enter_frame(sl, ray, lv, p)
    first = cache.state[S_FIRST]
    ncoord = 4 if pa.rational else 3
    free = cache.free_slots
    nfree = first
    for k in range(nfree):  # every working slot is free when a search starts
        free[k] = k
    stack = cache.stack
    mf = sl.mf
    touch(cache, p)
    s = cache.root[p]
    if s >= 0:
        cache.state[S_HITS] += 1
    else:
        cache.state[S_MISSES] += 1
        s = take_pair(cache, p)
        if s >= 0:
            cache.root[p] = s
            cache.child[s - first] = -1
        else:  # the pool cannot hold even a root: search as without the cache
            nfree -= 1
            s = free[nfree]
        root_at(sl, s, pa, lv)
    effort = 1
    budget = ray[R_BUDGET]
    sp = 0
    if open_child(sl, s, pa, lv, lray, lray[R_TMIN], math.inf, hit, trace, False)[0]:
        stack[0] = s
        sp = 1
    while sp > 0 and effort < budget:
        sp -= 1
        a = stack[sp]
        cached = a >= first
        if not ahead(sl, a, pa, hit) or (HAS_TRIMS and trim_state(sl, a, pa, trims) < 0):  # noqa: F821
            if not cached:
                free[nfree] = a
                nfree += 1
            continue
        stop, d_crit, shrank = judge(sl, a, pa, lv, lray, q)
        if stop:
            if accept(sl, a, pa, lv, lray, q, trims, HAS_TRIMS):  # noqa: F821
                report(hit, sl, a, pa, lv)
                if STOP_AT_FIRST:  # noqa: F821
                    return effort
            if not cached:
                free[nfree] = a
                nfree += 1
            continue
        effort += 2
        t_start = mf[a, M_TIN]  # the halves' intervals lie within their parent's
        t_stop = mf[a, M_TOUT]
        if WIDE:  # noqa: F821 (float64 slots, general degree: a copy of the halving in each branch)
            kid = -1
            if cached and sl.mi[a, I_DEPTH] < cache.state[S_DEPTH]:
                kid = cache.child[a - first]
                if kid < 0:  # compute the halves once, in working slots, and keep them
                    kid = take_pair(cache, p)
                    if kid >= 0:  # (_halve_working takes two free slots, keep_halves gives them back)
                        w, b, _, taken = _halve_working(sl, a, True, pa, lv, lray, q, d_crit, shrank, free, nfree,
                                                       ncoord, HAS_GENERAL)  # noqa: F821
                        keep_halves(sl, cache, a, w, b, kid, ncoord, pa.count, free, taken)
            if kid >= 0:  # the cached halves, with this ray's view of their parent
                for c in (kid, kid + 1):
                    mf[c, M_DPAR] = d_crit
                    sl.mi[c, I_STALLED] = 0 if shrank else 1
                far, near, alive_far, alive_near = sort_halves(sl, np.uint32(kid), np.uint32(kid + 1), pa, lv, lray,
                                                               t_start, t_stop, hit, sl.mi[kid, I_LAST], trace,
                                                               False)
            else:  # computed halves in working slots
                a, b, direction, nfree = _halve_working(sl, a, cached, pa, lv, lray, q, d_crit, shrank, free, nfree,
                                                        ncoord, HAS_GENERAL)  # noqa: F821
                far, near, alive_far, alive_near = sort_halves(sl, a, b, pa, lv, lray, t_start, t_stop, hit,
                                                               direction, trace, False)
                for c, alive in ((far, alive_far), (near, alive_near)):
                    if not alive:
                        free[nfree] = c
                        nfree += 1
        else:
            kid = -1
            build = False
            if cached and sl.mi[a, I_DEPTH] < cache.state[S_DEPTH]:
                kid = cache.child[a - first]
                if kid < 0:  # compute the halves once, in working slots, and keep them
                    kid = take_pair(cache, p)
                    build = kid >= 0
            if kid >= 0 and not build:  # the cached halves, with this ray's view of their parent
                for c in (kid, kid + 1):
                    mf[c, M_DPAR] = d_crit
                    sl.mi[c, I_STALLED] = 0 if shrank else 1
                a = np.uint32(kid)  # (unsigned, as the stack's slots)
                b = np.uint32(kid + 1)
                direction = sl.mi[kid, I_LAST]
            else:  # computed halves in working slots
                node = a
                a, b, direction, nfree = _halve_working(sl, a, cached, pa, lv, lray, q, d_crit, shrank, free, nfree,
                                                        ncoord, HAS_GENERAL)  # noqa: F821
                if build:  # into the cache; the working slots go back
                    nfree = keep_halves(sl, cache, node, a, b, kid, ncoord, pa.count, free, nfree)
                    a = np.uint32(kid)
                    b = np.uint32(kid + 1)
            # One inlined copy of the halving and of sort_halves for cached and computed halves: with
            # a copy in each branch the teapot's float frame with the cache took 0.83 s, not 0.64 s.
            far, near, alive_far, alive_near = sort_halves(sl, a, b, pa, lv, lray, t_start, t_stop, hit, direction,
                                                           trace, False)
            if kid < 0:
                for c, alive in ((far, alive_far), (near, alive_near)):
                    if not alive:
                        free[nfree] = c
                        nfree += 1
        if alive_far:
            stack[sp] = far
            sp += 1
        if alive_near:
            stack[sp] = near
            sp += 1
    return effort


@njit(cache=True, nogil=True, inline='always')
def wide_leaves(lv):
    """The leaves as the float64 search of rational patches reads them: float64 points and bounds."""
    return Leaves(lv.ctrl64, lv.pstart, lv.deg_u, lv.deg_v, lv.rational, lv.frame, lv.grid, lv.eps64,
                  lv.ctrl64, lv.eps64)


@njit(cache=True, nogil=True, inline='always')
def wide_slots(sl):
    """The thread's slots with float64 points (everything else is shared: one search at a time)."""
    return Slots(sl.buf64, sl.box, sl.mf, sl.mi, sl.order, sl.lray, sl.w64, sl.trim_h, sl.trim_m, sl.buf64, sl.cache)


def _by_kind(p, lv, trims, ray, hit, q, sl, trace):
    """Rational patches to the float64 search, the others to the working precision's."""
    if lv.rational[p] != 0:
        return wide(p, wide_leaves(lv), trims, ray, hit, q, wide_slots(sl), trace)  # noqa: F821
    return narrow(p, lv, trims, ray, hit, q, sl, trace)  # noqa: F821


def _rational_only(p, lv, trims, ray, hit, q, sl, trace):
    return wide(p, wide_leaves(lv), trims, ray, hit, q, wide_slots(sl), trace)  # noqa: F821


def _closest(p, lv, trims, ray, hit, q, sl, trace):
    """search (the closest-hit query) up to ray.search_limit: the tie rule."""
    best = hit[H_TIN]
    hit[H_TIN] = search_limit(hit, p)
    effort = search(p, lv, trims, ray, hit, q, sl, trace)  # noqa: F821
    if hit[H_PATCH] != p:  # nothing found: the best stays
        hit[H_TIN] = best
    return effort


def make_search(variant, any_hit: bool):
    """The patch search of one variant: search(p, lv, trims, ray, hit, q, sl, trace) -> boxes
    computed; updates `hit` when it finds a hit box before hit[H_TIN] (any_hit: the first one
    found, then it stops). It stops, too, once it has computed ray[R_BUDGET] boxes.
    lv: records.Leaves, trims: records.Trims, q: records.Query, sl: records.Slots, trace:
    records.Trace (written only by tracing variants).

    Integral patches are searched in the working precision. Rational ones are searched in float64
    slots (re-derived from the float64 leaf, per-level bounds) and stop on the working precision's
    grid: in float32, weights 1e-3..1e3 apart made float32 error bands dominate their boxes near
    corners, and 0.2-5 % of float64 points fell outside the hit box."""
    flags = dict(HAS_TRIMS=variant.trims, TRACING=variant.trace, STOP_AT_FIRST=any_hit)
    kernel = njit(cache=True, nogil=True, _nrt=False)
    template = _cached_search if variant.cache else _search
    narrow = None
    if variant.cubic or variant.linear or variant.general:
        narrow = kernel(specialise(template, WIDE=False, HAS_RATIONAL=False, HAS_CUBIC=variant.cubic,
                                   HAS_LINEAR=variant.linear, HAS_GENERAL=variant.general, **flags))
    search = narrow
    if variant.rational:
        wide = kernel(specialise(template, WIDE=True, HAS_RATIONAL=True, HAS_CUBIC=False, HAS_LINEAR=False,
                                 HAS_GENERAL=True, **flags))
        dispatch = specialise(_rational_only, wide=wide) if narrow is None else specialise(_by_kind, wide=wide,
                                                                                           narrow=narrow)
        search = njit(cache=True, nogil=True, _nrt=False, inline='always')(dispatch)
    if any_hit:
        return search
    return njit(cache=True, nogil=True, _nrt=False, inline='always')(specialise(_closest, search=search))
