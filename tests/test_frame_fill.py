"""A frame nobody watches is allocated unwritten and traced in groups of units (trace_rays): the tile kernel writes every channel
of each pixel it traces, and pixels a cancel leaves untraced get their miss values at the end. Here
the unwritten channels start as poison, and must come out byte for byte as the frame filled first
(the one on_tile shows while it is traced); the tile kernel is also called through its bound entry
point (variants.bound), and must give the dispatcher's bytes."""
from __future__ import annotations

import threading

import numpy as np
import pytest

import tracer.render as render_module
from tracer.kernel_channels import KERNEL_CHANNELS
from tracer.options import Options
from tracer.render import render, work_units
from viewer_util import teapot  # noqa: F401

SIZE = (40, 29)


def poisoned(height, width, filled=True):
    """kernel_channels.allocate, with every unfilled channel holding a value no pixel can have."""
    channels = ORIGINAL_ALLOCATE(height, width, filled)
    if not filled:
        for c in KERNEL_CHANNELS:
            a = channels[c.name]
            a[...] = True if a.dtype == bool else (-12345 if a.dtype.kind == "i" else 7.25e30)
    return channels


ORIGINAL_ALLOCATE = render_module.allocate


@pytest.fixture
def poison(monkeypatch):
    monkeypatch.setattr(render_module, "allocate", poisoned)


def channels(frame) -> dict:
    return {c.name: getattr(frame, c.name) for c in KERNEL_CHANNELS}


@pytest.mark.parametrize("order", ("scanline", "peano", "itembuffer"))
@pytest.mark.parametrize("bundle", ("1x1", "8x8"))
@pytest.mark.parametrize("threads", (1, 2))
def test_an_unwatched_frame_is_the_watched_one(teapot, poison, order, bundle, threads):  # noqa: F811
    opts = Options().with_(order=order, bundle=bundle, threads=threads, tile_size=16, criterion="adaptive")
    watched = render(teapot, opts, size=SIZE, lighting=False, on_tile=lambda frame, unit: None)
    unwatched = render(teapot, opts, size=SIZE, lighting=False)
    assert watched.hit.any() and not watched.hit.all()
    for name, a in channels(watched).items():
        if threads == 2 and name in ("cache_hits", "cache_misses"):
            continue  # which thread's cache serves a unit is not fixed
        b = getattr(unwatched, name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name


def test_pixels_a_cancel_leaves_untraced_read_as_misses(teapot, poison):  # noqa: F811
    opts = Options().with_(tile_size=8, threads=1)
    whole = render(teapot, opts, size=SIZE, lighting=False)
    cancel = threading.Event()
    done = []

    def progress(n):
        done.append(n)
        if len(done) == 8:
            cancel.set()

    part = render(teapot, opts, size=SIZE, lighting=False, cancel=cancel, progress=progress)
    assert part.tiles_done == 8 < part.tiles_total
    traced = np.zeros(part.hit.shape, bool)
    for unit in work_units(*SIZE, opts)[:8]:  # one thread: the first eight units, in order
        traced[unit.pixels[:, 0], unit.pixels[:, 1]] = True
    assert part.hit[traced].any() and whole.hit[~traced].any()
    for c in KERNEL_CHANNELS:
        mine, full = getattr(part, c.name), getattr(whole, c.name)
        assert np.array_equal(mine[traced], full[traced], equal_nan=mine.dtype.kind == "f"), c.name
        miss = np.full(mine[~traced].shape, c.miss, mine.dtype)
        assert np.array_equal(mine[~traced], miss, equal_nan=mine.dtype.kind == "f"), c.name


def test_a_lit_frame_unwatched_is_the_watched_one(teapot, poison):  # noqa: F811
    """Grouped units (unit_loop.guided_groups) are shaded unit by unit, as when watched."""
    opts = Options().with_(threads=2, tile_size=8, light_samples=6)
    watched = render(teapot, opts, size=SIZE, on_tile=lambda frame, unit: None)
    unwatched = render(teapot, opts, size=SIZE)
    for name in ("hit", "t", "normal", "patch", "radiance", "shadow", "shadow_rays", "penumbra"):
        a, b = getattr(watched, name), getattr(unwatched, name)
        assert a is not None and a.tobytes() == b.tobytes(), name


def test_bound_is_the_compiled_entry_point_of_exactly_those_types():
    import numba

    from tracer.variants import bound

    @numba.njit
    def total(a, b):
        return a.sum() * b

    ints, scale = np.arange(6, dtype=np.int32), 2.5
    total(ints, scale)  # compiled for (int32[::1], float64)
    fast = bound(total, (ints, scale))
    assert fast is not total and fast(ints, scale) == total(ints, scale) == 37.5
    assert bound(total, (ints.astype(np.int64), scale)) is total  # no overload of these types
    assert bound(total, (ints[::2], scale)) is total  # another layout is another type
    plain = total.py_func
    assert bound(plain, (ints, scale)) is plain  # not a dispatcher


def test_type_keys_part_whatever_numba_types_apart():
    """Two values with one type_key have one numba type (entry_point relies on it: an entry point
    does not check its arguments), over arrays of every layout, flag and rank, records, tuples and
    scalars at the edges of int64."""
    import collections

    import numba

    from tracer.variants import entry_point, type_key

    Pair = collections.namedtuple("Pair", "a b")
    base = np.zeros((3, 4))
    frozen = base.copy()
    frozen.flags.writeable = False
    unaligned = np.frombuffer(bytearray(8 * 12 + 1), np.float64, 12, 1).reshape(3, 4)
    arrays = [base, base[:, :2], base.T, base[0], base[:, 0], np.zeros((0, 2)), np.zeros((1, 1)), frozen, unaligned,
              base.astype(np.float32), base.astype(np.int32), np.zeros((3, 4, 1)),
              np.zeros(3, bool), np.zeros(5, np.uint64)]
    scalars = [0, -1, 2 ** 63 - 1, 2 ** 63, True, False, 0.5, None, np.int32(1), np.float32(1.0), np.uint64(3)]
    values = arrays + scalars + [(base, 1), (1, base), (base, base), (base.T, base), Pair(base, 1), Pair(1, base),
                                 (Pair(base, 0.5), (frozen, None))]
    for x in values:
        for y in values:
            if type_key(x) == type_key(y):
                assert numba.typeof(x) == numba.typeof(y), (x, y)

    @numba.njit
    def first(a, b):
        return a[0] + b

    ints = np.arange(4, dtype=np.int32)
    first(ints, 1)
    call = entry_point(first, (ints, 1))
    assert call is not first and call(ints, 2) == 2
    assert entry_point(first, (np.arange(4), 1)) is first  # no overload of these types: the dispatcher
    assert entry_point(first.py_func, (ints, 1)) is first.py_func
