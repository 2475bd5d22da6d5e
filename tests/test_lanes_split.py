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
