"""The loop over a frame's work units (tracer/unit_loop.py): every unit once, reported on the
calling thread, started in order, and the first exception raised after the helpers stop."""
import threading
import time

import pytest

import numpy as np

from tracer.unit_loop import guided_groups, joined_pixels, run_units


@pytest.mark.parametrize("threads", [1, 2, 4])
def test_every_unit_once_reported_on_the_calling_thread(threads):
    started, workers, reported = [], set(), []
    lock = threading.Lock()

    def work(u):
        with lock:
            started.append(u)
            workers.add(threading.get_ident())
        time.sleep(0.001 * (u % 3))  # units of unequal cost finish out of order
        return u

    def finished(u):
        reported.append((u, threading.get_ident()))

    run_units(range(40), work, finished, threads)
    assert started == list(range(40))  # taken from one iterator, in the frame's order
    assert sorted(u for u, _ in reported) == list(range(40))
    assert {t for _, t in reported} == {threading.get_ident()}
    assert len(workers) <= threads


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_an_exception_stops_the_frame_and_is_raised(threads):
    started, threads_seen = [], set()
    lock = threading.Lock()

    def work(u):
        with lock:
            started.append(u)
            threads_seen.add(threading.current_thread())
        if u == 5:
            raise RuntimeError("unit 5 failed")
        time.sleep(0.002)
        return u

    reported = []
    with pytest.raises(RuntimeError, match="unit 5 failed"):
        run_units(range(1000), work, reported.append, threads)
    count = len(started)
    for t in threads_seen - {threading.current_thread()}:  # raised once every helper has stopped
        t.join(timeout=5.0)
        assert not t.is_alive()
    assert len(started) == count
    assert 5 not in reported and 5 in started
    if threads == 1:
        assert started == [0, 1, 2, 3, 4, 5]
    else:
        assert count < 1000


def test_an_exception_in_finished_stops_the_helpers():
    started = []

    def work(u):
        started.append(u)
        time.sleep(0.002)
        return u

    def finished(u):
        raise ValueError("callback failed")

    with pytest.raises(ValueError, match="callback failed"):
        run_units(range(1000), work, finished, 2)
    count = len(started)
    time.sleep(0.02)
    assert len(started) == count < 1000  # the helper stopped too


@pytest.mark.parametrize("threads", (1, 2, 3))
@pytest.mark.parametrize("count", (0, 1, 5, 256, 1000))
def test_guided_groups_cover_the_units_in_order_and_shrink(threads, count):
    units = list(range(count))
    groups = list(guided_groups(units, threads, watched=False))
    assert [u for g in groups for u in g] == units
    sizes = [len(g) for g in groups]
    assert all(a >= b for a, b in zip(sizes, sizes[1:]))  # large first, small at the end
    assert not sizes or sizes[-1] == 1
    if count >= 256:
        assert len(groups) < count // 8  # few hand-overs
    assert [len(g) for g in guided_groups(units, threads, watched=True)] == [1] * count


def test_joined_pixels_are_the_units_in_sequence():
    from tracer.render import Unit, rect_blocks
    units = [Unit(*rect_blocks(r, 2, 2), r) for r in ((0, 3, 0, 5), (0, 4, 5, 8), (3, 4, 0, 1))]
    pixels, blocks = joined_pixels(units)
    assert pixels.dtype == blocks.dtype == np.int32 and pixels.flags.c_contiguous
    expected = [u.pixels[a:b] for u in units for a, b in zip(u.blocks[:-1], u.blocks[1:])]
    assert len(blocks) == len(expected) + 1
    for (a, b), want in zip(zip(blocks[:-1], blocks[1:]), expected):
        assert np.array_equal(pixels[a:b], want)
    assert joined_pixels(units[:1])[0] is units[0].pixels
