"""The loop over a frame's work units (tracer/unit_loop.py): every unit once, reported on the
calling thread, started in order, and the first exception raised after the helpers stop."""
import threading
import time

import pytest

from tracer.unit_loop import run_units


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
