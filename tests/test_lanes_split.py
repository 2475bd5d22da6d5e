"""The eight-lane bicubic halving (tracer/lanes_split.py) against the slot's (simd.split_u_cubic,
split_v_cubic) lane by lane, byte for byte: points and boxes, each lane in its own direction, on
points with signed zeros, ties, NaN and huge and tiny values; the intrinsic and its numpy version."""
import numpy as np
import pytest
from numba import config as numba_config
from numba import njit

from tracer import simd
from tracer.lanes_split import LANES, split_cubic_lanes, split_cubic_lanes_python


@njit(cache=False)
def _slot_splits(buf, dirs, box):
    """Each lane's bicubic halved as a slot: slot 2 l keeps the low half, 2 l + 1 gets the high."""
    for lane in range(buf.shape[0] // 2):
        if dirs[lane] == 0:
            simd.split_u_cubic(buf, 2 * lane, 2 * lane + 1, box)
        else:
            simd.split_v_cubic(buf, 2 * lane, 2 * lane + 1, box)


@njit(cache=False)
def _lanes(points, dirs, box):
    split_cubic_lanes(points, dirs, box)


def _awkward_points(rng, dtype):
    """(3, 16, LANES) control points: mostly random, with runs of +0 / -0, equal values, NaN, and
    huge and tiny magnitudes."""
    pts = rng.normal(size=(3, 16, LANES)).astype(dtype)
    pick = rng.random(pts.shape)
    pts[pick < 0.15] = 0.0
    pts[(pick >= 0.15) & (pick < 0.3)] = -0.0
    pts[(pick >= 0.3) & (pick < 0.35)] = 1.5
    pts[(pick >= 0.35) & (pick < 0.37)] = np.nan
    pts[(pick >= 0.37) & (pick < 0.40)] *= dtype(1e30)
    pts[(pick >= 0.40) & (pick < 0.43)] *= dtype(1e-38)
    return pts


def _expected(points, dirs):
    """The slots' halves and boxes, as (low points, high points, low box, high box) in lanes."""
    buf = np.zeros((2 * LANES, 4, 16), points.dtype)
    for lane in range(LANES):
        buf[2 * lane, :3] = points[:, :, lane]
    box = np.zeros((2 * LANES, 6))
    _slot_splits(buf, dirs, box)
    low = np.stack([buf[2 * lane, :3] for lane in range(LANES)], axis=-1)
    high = np.stack([buf[2 * lane + 1, :3] for lane in range(LANES)], axis=-1)
    return low, high, box[0::2].T.copy(), box[1::2].T.copy()


def _versions():
    python = split_cubic_lanes_python
    return [python] if numba_config.DISABLE_JIT else [_lanes, python]


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("version", range(2))
def test_lanes_split_is_each_slots_split_bit_for_bit(version, dtype):
    versions = _versions()
    if version >= len(versions):
        pytest.skip("numba's JIT is off: only the numpy version")
    split = versions[version]
    rng = np.random.default_rng(40 + version)
    for case in range(60):
        points = _awkward_points(rng, dtype)
        dirs = rng.integers(0, 2, LANES).astype(np.int32)
        if case % 10 == 0:
            dirs[:] = case % 20 // 10  # every lane the same way
        low, high, low_box, high_box = _expected(points, dirs)
        columns = np.concatenate([points, np.full_like(points, 7.0)], axis=-1)
        box = np.zeros((6, 2 * LANES))
        split(columns, dirs, box)
        for name, want, got in (("low", low, columns[..., :LANES]), ("high", high, columns[..., LANES:]),
                                ("low box", low_box, box[:, :LANES]), ("high box", high_box, box[:, LANES:])):
            assert want.tobytes() == got.tobytes(), f"case {case}: {name} differs"


def test_lanes_split_refuses_other_layouts():
    """The intrinsic types only C-contiguous points and float64 boxes."""
    if numba_config.DISABLE_JIT:
        pytest.skip("numba's JIT is off")
    points = np.zeros((3, 16, 2 * LANES))
    with pytest.raises(Exception):
        _lanes(points, np.zeros(LANES, np.int32), np.zeros((6, 2 * LANES), np.float32))


# ---- a whole halving, and the criterion, against the single ray's steps on slots ----

from collections import namedtuple  # noqa: E402

from tracer import lanes_split as LS  # noqa: E402
from tracer.ray import H_TIN, R_D, R_DT, R_INV, R_O, R_REACH, R_T0, RAY_LEN  # noqa: E402
from tracer.records import PatchInfo, Query  # noqa: E402
from tracer.search_steps import finish_halves, halving_direction, judge_known, tightening  # noqa: E402
from tracer.subpatch import (I_DEPTH, I_LAST, I_STALLED, I_TRIM, M_D, M_DPAR, M_E, M_GULP, M_MAG,  # noqa: E402
                             M_OX, M_TIN, M_TOUT, M_U0, M_U1, M_V0, M_V1, M_W, MF_LEN, MI_LEN, open_box, split)

Grids = namedtuple("Grids", "grid frame")


@njit(cache=False)
def _slot_halvings(buf, box, mf, mi, rays, pa, q, dcrit, shrank, start, stop, met, alive):
    """Lane l's halving on slots 2 l (low half) and 2 l + 1 (high), as the single ray makes it."""
    hit = np.full(32, np.inf)
    hit[H_TIN] = 2.5  # (the search's limit: some boxes entered after it)
    for lane in range(LANES):
        a, b = 2 * lane, 2 * lane + 1
        ray = rays[lane]
        mf[a, M_TIN] = start[lane]
        mf[a, M_TOUT] = stop[lane]
        direction = halving_direction(_slots(buf, box, mf, mi), a, pa, ray, q, shrank[lane] != 0.0)
        sl = _slots(buf, box, mf, mi)
        split(sl, a, b, pa, direction, False)
        finish_halves(sl, a, b, pa, dcrit[lane], shrank[lane] != 0.0, direction)
        alive[lane], met[lane] = open_box(sl, a, ray, start[lane], stop[lane], hit, 0)
        alive[LANES + lane], met[LANES + lane] = open_box(sl, b, ray, start[lane], stop[lane], hit, 0)


SlotsLike = namedtuple("SlotsLike", "buf box mf mi")


@njit(cache=False)
def _slots(buf, box, mf, mi):
    return SlotsLike(buf, box, mf, mi)


@njit(cache=False)
def _slot_judgements(box, mf, mi, rays, pa, q, grids, stop, dcrit, shrank, tight):
    sl = SlotsLike(np.zeros((1, 4, 16), np.float32), box, mf, mi)
    for lane in range(LANES):
        s, d, sh, _ = judge_known(sl, lane, pa, grids, rays[lane], q, -1.0)
        stop[lane] = s
        dcrit[lane] = d
        shrank[lane] = sh
        tight[lane] = tightening(sl, lane, pa) != 0


@njit(cache=False)
def _lanes_halving(points, dirs, box, mf, mi, lray, step, levels, sub_scale, split_mode, linear):
    if linear:
        return LS.halve_lanes_linear(points, dirs, box, mf, mi, lray, step, levels, sub_scale, split_mode)
    return LS.halve_lanes(points, dirs, box, mf, mi, lray, step, levels, sub_scale, split_mode)


@njit(cache=False)
def _lanes_judgement(box, mf, mi, lray, step, g0, g1, g2, criterion, param, max_depth, shrink_factor, cumulative):
    return LS.judge_lanes(box, mf, mi, lray, step, g0, g1, g2, criterion, param, max_depth, shrink_factor, False,
                          cumulative)


def _patch(linear, dtype):
    bits = 24 if dtype == np.float32 else 53
    m = 1 if linear else 3
    cumulative = bits < 53
    return PatchInfo(0, m, m, (m + 1) ** 2, 0, False, not linear, linear, bits, cumulative,
                     0.0 if cumulative else 2.0 ** (8 - bits), 2.0 ** -bits if cumulative else 0.0,
                     1.0 - 2.0 ** (4 - bits))


def _random_lanes(rng, pa, dtype):
    """Slots 2 l of eight lanes (points, widened box, metadata) and a ray each: awkward values."""
    buf = np.zeros((COLUMNS_SLOTS, 4, 16), dtype)
    for lane in range(LANES):
        pts = rng.normal(size=(3, pa.count)).astype(dtype)
        pts[rng.random(pts.shape) < 0.2] = 0.0
        buf[2 * lane, :3, :pa.count] = pts
    box = np.zeros((COLUMNS_SLOTS, 6))
    mf = np.zeros((COLUMNS_SLOTS, MF_LEN))
    mi = np.zeros((COLUMNS_SLOTS, MI_LEN), np.int32)
    rays = np.zeros((LANES, RAY_LEN))
    for lane in range(LANES):
        s = 2 * lane
        pts = buf[s, :3, :pa.count].astype(np.float64)
        e = rng.random(3) * 1e-6
        box[s, :3] = pts.min(axis=1) - e
        box[s, 3:] = pts.max(axis=1) + e
        mf[s, M_E:M_E + 3] = e
        mf[s, M_OX:M_OX + 3] = rng.normal(size=3) * (0.0 if lane % 3 == 0 else 10.0)
        u0, v0 = rng.random(2) * 0.5
        mf[s, M_U0], mf[s, M_U1], mf[s, M_V0], mf[s, M_V1] = u0, u0 + 0.25, v0, v0 + (0.0 if lane == 5 else 0.25)
        mf[s, M_GULP] = 2.0 ** -20
        mf[s, M_DPAR] = rng.random() * 4.0
        mf[s, M_W] = 2.0 * e.sum()
        mf[s, M_D] = (box[s, 3:] - box[s, :3]).sum()
        mf[s, M_TIN] = rng.random()
        mi[s, I_DEPTH] = rng.integers(0, 70)
        mi[s, I_STALLED] = rng.integers(0, 2)
        mi[s, I_LAST] = rng.integers(-1, 2)
        mi[s, I_TRIM] = rng.integers(0, 2)
        d = rng.normal(size=3)
        d[rng.random(3) < 0.15] = 0.0
        rays[lane, R_O:R_O + 3] = rng.normal(size=3) * 3.0
        rays[lane, R_D:R_D + 3] = d
        with np.errstate(divide='ignore'):
            rays[lane, R_INV:R_INV + 3] = np.where(d != 0.0, 1.0 / np.where(d != 0.0, d, 1.0), np.inf)
        rays[lane, R_REACH] = -np.inf
        rays[lane, R_T0], rays[lane, R_DT] = rng.random() * 1e-3, rng.random() * 1e-3
    return buf, box, mf, mi, rays


COLUMNS_SLOTS = 2 * LANES


def _to_lanes(buf, box, mf, mi, rays):
    points = np.zeros((3, 16, LS.COLUMNS), buf.dtype)
    points[:, :, :LANES] = buf[0::2, :3, :].transpose(1, 2, 0)
    lbox = np.zeros((6, LS.COLUMNS))
    lbox[:, :LANES] = box[0::2].T
    lmf = np.zeros((MF_LEN, LS.COLUMNS))
    lmf[:, :LANES] = mf[0::2].T
    lmi = np.zeros((MI_LEN, LS.COLUMNS), np.int32)
    lmi[:, :LANES] = mi[0::2].T
    lray = np.zeros((LS.LANE_RAY, LANES))
    for k in range(3):
        lray[R_O + k], lray[R_D + k], lray[R_INV + k] = rays[:, R_O + k], rays[:, R_D + k], rays[:, R_INV + k]
    lray[LS.LR_T0], lray[LS.LR_DT] = rays[:, R_T0], rays[:, R_DT]
    return points, lbox, lmf, lmi, lray


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("linear", [False, True])
@pytest.mark.parametrize("split_mode", [0, 1])
def test_halve_lanes_is_the_single_rays_halving(linear, dtype, split_mode):
    pa = _patch(linear, dtype)
    q = Query(0, 0.0, split_mode, 80, pa.bits, 0.0, 0)
    rng = np.random.default_rng(7 + 2 * linear + split_mode)
    for version in _halve_versions():
        for case in range(40):
            buf, box, mf, mi, rays = _random_lanes(rng, pa, dtype)
            points, lbox, lmf, lmi, lray = _to_lanes(buf, box, mf, mi, rays)
            step = np.zeros((LS.STEP_LEN, LANES))
            step[LS.S_DCRIT] = rng.random(LANES)
            step[LS.S_SHRANK] = rng.integers(0, 2, LANES)
            start = np.where(rng.random(LANES) < 0.3, -np.inf, rng.normal(size=LANES))
            stop = np.where(rng.random(LANES) < 0.5, np.inf, rng.normal(size=LANES) + 3.0)
            lmf[M_TIN, :LANES] = start
            lmf[M_TOUT, :LANES] = stop
            met = np.zeros(COLUMNS_SLOTS, np.bool_)
            alive = np.zeros(COLUMNS_SLOTS, np.bool_)
            lray[LS.LR_LIMIT] = 2.5
            lray[LS.LR_REACH] = -np.inf
            lray[LS.LR_TMIN] = 0.0
            _slot_halvings(buf, box, mf, mi, rays, pa, q, step[LS.S_DCRIT].copy(), step[LS.S_SHRANK].copy(),
                           start, stop, met, alive)
            dirs = np.zeros(LANES, np.int32)
            bits = int(version(points, dirs, lbox, lmf, lmi, lray, step, pa.m * pa.round_unit, pa.sub_scale,
                               split_mode, linear))
            assert dirs.tolist() == mi[0::2, I_LAST].tolist(), f"case {case}: directions"
            assert lmi[:, :LANES].tobytes() == mi[0::2].T.tobytes(), f"case {case}: low halves' places"
            assert lmi[:, LANES:].tobytes() == mi[1::2].T.tobytes(), f"case {case}: high halves' places"
            for lane in range(LANES):
                odd = any(met[LANES * h + lane] and lmf[M_TIN, LANES * h + lane] <= 0.0 for h in range(2))
                special = odd or (met[lane] and met[LANES + lane] and (alive[lane] or alive[LANES + lane]))
                assert ((bits >> (4 * LANES + lane)) & 1) == special, f"case {case} lane {lane}: special"
                for h in range(2):
                    if not special:
                        assert ((bits >> (2 * LANES + LANES * h + lane)) & 1) == alive[LANES * h + lane]
                    s, column = 2 * lane + h, LANES * h + lane
                    where = f"case {case} lane {lane} half {h}"
                    assert ((bits >> column) & 1) == met[LANES * h + lane], where + ": slab verdict"
                    assert points[:, :pa.count, column].tobytes() == buf[s, :3, :pa.count].tobytes(), where + ": points"
                    assert lbox[:, column].tobytes() == box[s].tobytes(), where + ": box"
                    rows = [r for r in range(MF_LEN) if r not in (M_TIN, M_TOUT) or met[LANES * h + lane]]
                    assert lmf[rows, column].tobytes() == mf[s, rows].tobytes(), where + ": metadata"


def _halve_versions():
    python = LS.halve_lanes_python
    return [python] if numba_config.DISABLE_JIT else [_lanes_halving, python]


@pytest.mark.parametrize("criterion", [0, 1, 2])
def test_judge_lanes_is_the_single_rays_criterion(criterion):
    pa = _patch(False, np.float32)
    rng = np.random.default_rng(70 + criterion)
    versions = [LS.judge_lanes_python] if numba_config.DISABLE_JIT else [
        lambda *args: _lanes_judgement(*args[:12], args[13]), LS.judge_lanes_python]
    for version in versions:
        for case in range(60):
            buf, box, mf, mi, rays = _random_lanes(rng, pa, np.float32)
            scale = 2.0 ** rng.integers(-30, -2)
            mf[:, M_D] *= scale
            box *= scale
            grid = np.array([2.0 ** -24, 0.0 if case % 4 == 0 else 2.0 ** -26, 2.0 ** -25])
            param = float(rng.random() * 4 * scale)
            q = Query(criterion, param, 0, 80, 24, 0.0, 0)
            stop = np.zeros(LANES, np.bool_)
            dcrit = np.zeros(LANES)
            shrank = np.zeros(LANES, np.bool_)
            tight = np.zeros(LANES, np.bool_)
            mf[:, M_MAG] = np.abs(box).max(axis=1) * (2.0 ** rng.integers(0, 8))
            _slot_judgements(box[0::2].copy(), mf[0::2].copy(), mi[0::2].copy(), rays, pa, q,
                             Grids(grid[None, :], np.zeros((1, 3))), stop, dcrit, shrank, tight)
            _, lbox, lmf, lmi, lray = _to_lanes(buf, box, mf, mi, rays)
            step = np.zeros((LS.STEP_LEN, LANES))
            bits = int(version(lbox, lmf, lmi, lray, step, grid[0], grid[1], grid[2], criterion, param, 80,
                               pa.shrink_factor, False, pa.cumulative))
            assert [(bits >> lane) & 1 for lane in range(LANES)] == stop.astype(int).tolist(), f"case {case}: stops"
            assert [(bits >> (LANES + lane)) & 1 for lane in range(LANES)] == tight.astype(int).tolist(), \
                f"case {case}: tightening"
            assert step[LS.S_DCRIT].tobytes() == dcrit.tobytes(), f"case {case}: box measures"
            assert (step[LS.S_SHRANK] != 0.0).tolist() == shrank.tolist(), f"case {case}: shrank"
