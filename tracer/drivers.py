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

from .jit import njit, specialise

from .ray import H_TIN, R_BUDGET
from .search_steps import HIT, MISS, PRUNED, accept, enter_frame, judge, open_child, report, root, set_event
from .search_steps import subdivide, tighten, trace_hit, trim_state
from .subpatch import M_TIN, patch_info


def _search(p, lv, trims, ray, hit, q, sl, trace):
    """The patch search template (specialised by make_search)."""
    pa = patch_info(lv, p, q.bits, HAS_RATIONAL, HAS_CUBIC, HAS_LINEAR)  # noqa: F821 (make_search's)
    lray = enter_frame(sl, ray, lv, p)
    s = root(sl, pa, lv)
    effort = 1
    budget = ray[R_BUDGET]
    sp = open_child(sl, s, pa, lv, lray, hit[H_TIN], trace, TRACING)  # noqa: F821
    while sp > 0 and effort < budget:
        sp -= 1
        a = sl.order[sp]
        if sl.mf[a, M_TIN] >= hit[H_TIN]:
            if TRACING:  # noqa: F821
                set_event(trace, sl, a, PRUNED)
            continue
        if HAS_TRIMS and trim_state(sl, a, pa, trims) < 0:  # noqa: F821
            if TRACING:  # noqa: F821
                set_event(trace, sl, a, MISS)  # trimmed away as a whole
            continue
        stop, d_crit, shrank = judge(sl, a, pa, lv, lray, q)
        if stop:
            found = accept(sl, a, pa, lray, q, trims, HAS_TRIMS)  # noqa: F821
            if TRACING:  # noqa: F821
                set_event(trace, sl, a, HIT if found else MISS)
            if found:
                report(hit, sl, a, pa, lv)
                if TRACING:  # noqa: F821
                    trace_hit(trace, sl, a, hit)
                if STOP_AT_FIRST:  # noqa: F821
                    return effort
            continue
        tighten(sl, a, pa, lv, HAS_RATIONAL)  # noqa: F821
        sp = subdivide(sl, a, sp, pa, lv, lray, q, hit[H_TIN], d_crit, shrank, trace, TRACING,  # noqa: F821
                       HAS_GENERAL)  # noqa: F821
        effort += 2
    return effort


def make_search(variant, any_hit: bool):
    """The patch search of one variant: search(p, lv, trims, ray, hit, q, sl, trace) -> boxes
    computed; updates `hit` when it finds a hit box before hit[H_TIN] (any_hit: the first one
    found, then it stops). It stops, too, once it has computed ray[R_BUDGET] boxes. lv: records.Leaves, trims: records.Trims, q: records.Query,
    sl: records.Slots, trace: records.Trace (written only by tracing variants)."""
    search = specialise(_search, HAS_RATIONAL=variant.rational, HAS_CUBIC=variant.cubic,
                        HAS_LINEAR=variant.linear, HAS_GENERAL=variant.general or variant.rational,
                        HAS_TRIMS=variant.trims, TRACING=variant.trace, STOP_AT_FIRST=any_hit)
    return njit(cache=True, nogil=True, _nrt=False)(search)
