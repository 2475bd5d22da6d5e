"""The bundle's adaptive judgement as masks (bundle_steps.judge_detail) against the single ray's
search_steps.judge_known, ray by ray: which rays stop, which go on, and for the first of those
the criterion diameter and whether the box shrank (which its halves inherit).

Boxes on a power-of-two grid, with diameters on both sides of the prefilter, thresholds on,
just below and just above a box's own and its grid box's diameter, parents that make the box
shrink or not, stalled boxes, rational patches, the depth cap and spent intervals.
"""
import math

import numpy as np
import pytest
from numba import config as numba_config
from numba import njit

from tracer import bundle as B
from tracer import bundle_steps
from tracer import lanes as L
from tracer.ray import R_DT, R_T0, RAY_LEN
from tracer.records import Leaves, PatchInfo, Query, Slots
from tracer.search_steps import ADAPTIVE, GRID_PREFILTER, judge_known
from tracer.subpatch import (I_DEPTH, I_STALLED, M_D, M_DPAR, M_GULP, M_OX, M_TIN, M_U0, M_U1, M_V0, M_V1, M_W,
                             MF_LEN, MI_LEN, grid_l1)

RAYS = 20  # three groups of lanes, the last one partly filled
MAX_DEPTH = 60
STEP = 2.0 ** -12  # the leaf's grid


def _judge_rays(sl, pa, lv, q, br, row, live):
    return bundle_steps.judge_detail(sl, 0, pa, lv, q, br, row, live)


def _judge_one(sl, pa, lv, q, ray):
    return judge_known(sl, 0, pa, lv, ray, q, -1.0)


def _kernels():
    if numba_config.DISABLE_JIT:
        return _judge_rays, _judge_one
    return njit(_judge_rays), njit(_judge_one)


def _records(rng):
    """One slot (0) holding a box on the grid, a leaf, a bundle's records; the box's d and g."""
    mf = np.zeros((2, MF_LEN))
    mi = np.zeros((2, MI_LEN), np.int32)
    box = np.zeros((2, 6))
    lo = rng.uniform(-1.0, 1.0, 3)
    box[0, :3] = lo
    box[0, 3:] = lo + rng.choice([1e-5, 3e-4, 2e-3, 0.03, 0.4]) * rng.uniform(0.0, 1.0, 3)
    mf[0, M_OX:M_OX + 3] = rng.choice([0.0, 0.25], 3)
    mf[0, M_D] = float(np.sum(box[0, 3:] - box[0, :3]))
    mf[0, M_GULP] = STEP
    grid = np.full((1, 3), STEP)
    sl = Slots(np.zeros((2, 4, 16)), box, mf, mi, np.arange(2).astype(np.uint32), np.zeros(RAY_LEN),
               np.zeros((4, 16)), np.zeros((1, 1, 3)), np.zeros((1, 6)), np.zeros((2, 4, 16)), None)
    empty = np.zeros((1, 1))
    lv = Leaves(empty, np.zeros(1, np.int64), np.full(1, 3), np.full(1, 3), np.zeros(1, np.int8), np.zeros((1, 3)),
                grid, np.zeros((1, 3)), empty, np.zeros((1, 3)))
    br = B.bundle_rays(RAYS, 2, 2)
    return sl, lv, br, mf[0, M_D], grid_l1(sl, 0, grid, 0)


@pytest.mark.interpreted
def test_judge_detail_is_judge_known_ray_by_ray():
    judge_rays, judge_one = _kernels()
    rng = np.random.default_rng(91)
    q = Query(ADAPTIVE, 1.0, 0, MAX_DEPTH, 24, 0.0, np.zeros((1, 1), np.int32))
    seen = set()
    for case in range(150 if numba_config.DISABLE_JIT else 600):
        sl, lv, br, d, g = _records(rng)
        mf, mi = sl.mf, sl.mi
        rational = bool(rng.integers(0, 2))
        pa = PatchInfo(0, 3, 3, 16, 0, rational, not rational, False, 24, True, 0.0, 2.0 ** -24, 1.0 - 2.0 ** -20)
        mf[0, M_DPAR] = rng.choice([math.inf, d, g, g / pa.shrink_factor, 1.5 * d, 0.9 * g])
        mf[0, M_W] = rng.choice([0.0, d / 1.0625, 0.5 * d])
        mf[0, M_U0], mf[0, M_U1], mf[0, M_V0], mf[0, M_V1] = 0.25, 0.5, 0.5, 0.75
        if rng.random() < 0.05:
            mf[0, M_V1] = mf[0, M_V0]  # spent
        mi[0, I_STALLED] = rng.integers(0, 2)
        mi[0, I_DEPTH] = MAX_DEPTH if rng.random() < 0.05 else rng.integers(0, MAX_DEPTH)
        row = 1
        tin = rng.uniform(0.1, 4.0, RAYS)
        br.tin[row, :RAYS] = tin
        for r in range(RAYS):  # thresholds around d, g and the prefilter
            target = rng.choice([d, g, GRID_PREFILTER * STEP, 0.5 * d, 2.0 * g])
            target = np.nextafter(target, rng.choice([0.0, math.inf])) if rng.random() < 0.5 else target
            br.rays[r, R_T0] = rng.choice([0.0, 0.25 * target])
            br.rays[r, R_DT] = (target - br.rays[r, R_T0]) / tin[r]
            br.lanes[L.L_T0, r] = br.rays[r, R_T0]
            br.lanes[L.L_DT, r] = br.rays[r, R_DT]
        live = np.uint64(int(rng.integers(1, 1 << RAYS)))
        stop, go, first_ray, d_first, shrank_first = judge_rays(sl, pa, lv, q, br, row, live)
        assert int(stop) & int(go) == 0 and int(stop) | int(go) == int(live)
        first = None
        for r in range(RAYS):
            if not int(live) >> r & 1:
                continue
            mf[0, M_TIN] = tin[r]
            want_stop, want_d, want_shrank, _ = judge_one(sl, pa, lv, q, br.rays[r])
            assert bool(int(stop) >> r & 1) == want_stop, (case, r)
            seen.add((bool(want_stop), bool(want_shrank), want_d == g))
            if not want_stop and first is None:
                first = r
                assert first_ray == r and d_first == want_d and shrank_first == want_shrank, (case, r)
    assert len(seen) >= 6  # stops and goes, shrunk or not, judged by d or by g
