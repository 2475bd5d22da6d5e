"""One search for a bundle of shadow rays: the cone from a point to a light's box.

The shadow rays of a point run from its origin o to points o + d + e of the light, d to the
light's centre and e within the light's box (half extent h per axis). Together they fill the
cone C = {o + s (d + e) : 0 <= s <= 1, |e_k| <= h_k}. A patch search that tests its boxes
against C instead of one ray ("sheared slabs": per axis, s (d_k - h_k) <= hi_k - o_k and
s (d_k + h_k) >= lo_k - o_k) and accepts every box that reaches the criterion answers for all
the rays at once: if it finds nothing, none of the rays' own searches finds a hit in this patch.

That holds box for box when the rays' searches build the same tree of sub-patches (criteria
float, fixed and mantissa with the `length` split: no split or stop depends on the ray), since
every box a ray meets, the cone meets (the boxes here are padded beyond the slab test's own
slack: REL). The fast penumbra (penumbra.py) uses it for the leaves that hold the shading point,
where its samples' searches used to run one by one; other settings keep those searches.
Integral patches only (rational ones are searched in float64 slots: drivers.make_search).
"""
from __future__ import annotations

from .hull import hull_behind
from .jit import njit, specialise
from .ray import R_D, R_O
from .search_steps import enter_frame, halve, judge, root, tighten, trim_state
from .subpatch import M_OX, M_TIN, M_TOUT, patch_info

REL = 2.0 ** -44  # relative slack beyond the slab test's own (it widens its exits by 2^-50)


@njit(cache=True, nogil=True, inline='always')
def cone_meets(box, fx, fy, fz, ray, half, t_max):
    """(meets, s_in): does the cone from the ray's origin to the box of half extents `half` around
    origin + direction meet the box bx (lo xyz, hi xyz) shifted by (fx, fy, fz) for s in [0, t_max]?
    Conservative: the box's sides (relative to the origin, computed as the slab test computes them),
    the light's extent and the bounds on s are each widened by REL of their size, so a ray to a
    light point that the slab test lets meet the box always leaves the cone meeting it."""
    s_lo = 0.0
    s_hi = t_max
    for c in range(3):
        f = fx if c == 0 else (fy if c == 1 else fz)
        o = ray[R_O + c]
        d = ray[R_D + c]
        lo = box[c] + f - o
        hi = box[3 + c] + f - o
        lo -= abs(lo) * REL
        hi += abs(hi) * REL
        h = half[c] * (1.0 + REL) + REL * (abs(d) + abs(o))
        below = d - h  # s * below <= hi
        if below > 0.0:
            bound = hi / below
            s_hi = min(s_hi, bound + abs(bound) * REL)
        elif below < 0.0:
            bound = hi / below
            s_lo = max(s_lo, bound - abs(bound) * REL)
        elif hi < 0.0:
            return False, s_lo
        above = d + h  # s * above >= lo
        if above > 0.0:
            bound = lo / above
            s_lo = max(s_lo, bound - abs(bound) * REL)
        elif above < 0.0:
            bound = lo / above
            s_hi = min(s_hi, bound + abs(bound) * REL)
        elif lo > 0.0:
            return False, s_lo
    return s_lo <= s_hi, s_lo


@njit(cache=True, nogil=True, inline='always')
def _open(sl, s, pa, ray, half, t_max):
    """Does the cone meet slot s's box (and, where the box holds the origin, not only behind the
    side plane every ray of the cone leaves in front of: ray.set_side, lighting._proven_lit)?"""
    mf = sl.mf
    ok, s_in = cone_meets(sl.box[s], mf[s, M_OX], mf[s, M_OX + 1], mf[s, M_OX + 2], ray, half, t_max)
    mf[s, M_TIN] = s_in
    mf[s, M_TOUT] = t_max
    if ok and s_in <= 0.0 and hull_behind(sl, s, pa, ray):
        ok = False
    return 1 if ok else 0


def _cone_search(p, lv, trims, ray, half, q, sl, budget):
    """The cone search template (see make_cone_search)."""
    pa = patch_info(lv, p, q.bits, False, HAS_CUBIC, HAS_LINEAR)  # noqa: F821
    lray = enter_frame(sl, ray, lv, p)
    order = sl.order
    mf = sl.mf
    s = root(sl, pa, lv)
    effort = 1
    sp = _open(sl, s, pa, lray, half, 1.0)
    while sp > 0:
        if effort >= budget:
            return True, effort  # too costly to settle: the rays will tell
        sp -= 1
        a = order[sp]
        if HAS_TRIMS and trim_state(sl, a, pa, trims) < 0:  # noqa: F821
            continue
        stop, d_crit, shrank = judge(sl, a, pa, lv, lray, q)
        if stop:
            return True, effort
        tighten(sl, a, pa, lv)
        b = order[sp + 1]
        halve(sl, a, b, pa, lray, q, d_crit, shrank, HAS_GENERAL)  # noqa: F821
        alive_a = _open(sl, a, pa, lray, half, 1.0)
        alive_b = _open(sl, b, pa, lray, half, 1.0)
        near_a = mf[a, M_TIN] <= mf[b, M_TIN]
        far = b if near_a else a
        near = a if near_a else b
        alive_far = alive_b if near_a else alive_a
        alive_near = alive_a if near_a else alive_b
        order[sp] = far if alive_far else near
        order[sp + 1] = near if alive_far else far
        sp += alive_far + alive_near
        effort += 2
    return False, effort


def make_cone_search(variant):
    """cone_search(p, lv, trims, ray, half, q, sl, budget) -> (maybe hit, boxes): the search of
    leaf p for the cone of `ray` (origin, direction to the light's centre) and the light's half
    extents `half` (3,), over s in [0, 1]; True where some box reached the criterion or the
    search spent `budget` boxes. For integral variants (variant.rational False)."""
    template = specialise(_cone_search, HAS_TRIMS=variant.trims, HAS_CUBIC=variant.cubic,
                          HAS_LINEAR=variant.linear, HAS_GENERAL=variant.general)
    return njit(cache=True, nogil=True, _nrt=False)(template)

