"""The loop over a frame's work units, on the calling thread and `threads - 1` helpers.

Units are taken in order from one shared iterator, so the frame's order (scanline, Peano, item
buffer) is the order units start in. The calling thread traces units too and reports every
finished unit (its own at once, the helpers' as it passes between units), so a callback such as
the viewer's upload always runs on it. No thread pool and no future per unit: a unit of a coarse
criterion takes a fraction of a millisecond, and a hand-over per unit was a tenth of the frame.
Where nobody watches units finish, consecutive units go to the kernel in groups (guided_groups):
with two threads each hand-over also waits for the other's hold on the interpreter, about 20 us.
"""
from __future__ import annotations

import queue
import threading

import numpy as np

_HELPER_DONE = object()


def run_units(units, work, finished, threads: int) -> None:
    """finished(work(u)) for every unit u, work on `threads` threads (the caller's among them),
    finished on the calling thread. The first exception stops every thread from taking another
    unit and is raised once the helpers have stopped."""
    todo = iter(units)
    take = threading.Lock()
    stop = threading.Event()
    done = queue.SimpleQueue()  # helpers' finished units and exceptions, and _HELPER_DONE

    def next_unit():
        if stop.is_set():
            return None
        with take:
            return next(todo, None)

    def helper():
        try:
            while (u := next_unit()) is not None:
                done.put((work(u), None))
        except BaseException as exc:  # handed to the calling thread, which raises it
            stop.set()
            done.put((None, exc))
        finally:
            done.put(_HELPER_DONE)

    helpers = [threading.Thread(target=helper, daemon=True) for _ in range(max(threads, 1) - 1)]
    for t in helpers:
        t.start()
    running = len(helpers)
    error = None

    def report(item) -> None:
        nonlocal running, error
        if item is _HELPER_DONE:
            running -= 1
            return
        result, exc = item
        if exc is not None:
            error = error or exc
        elif error is None:
            finished(result)

    try:
        while error is None and (u := next_unit()) is not None:
            finished(work(u))
            while error is None:
                try:
                    report(done.get_nowait())
                except queue.Empty:
                    break
        while running:
            report(done.get())
    except BaseException:
        stop.set()
        for t in helpers:
            t.join()
        raise
    if error is not None:
        raise error


def guided_groups(units: list, threads: int, watched: bool):
    """The units in consecutive groups, each one kernel call: one unit a group where somebody
    watches units finish (a display, a progress bar); otherwise a shrinking share of what is left,
    remaining / (2 threads) units (guided self-scheduling): few hand-overs while there is much to
    do, small groups to balance the threads at the end."""
    i = 0
    while i < len(units):
        n = 1 if watched else max(1, (len(units) - i) // (2 * max(threads, 1)))
        yield units[i:i + n]
        i += n


def joined_pixels(group: list):
    """(pixels, blocks) of a group of units (render.Unit) as one unit's: their pixels in sequence,
    their bundles in sequence."""
    if len(group) == 1:
        return group[0].pixels, group[0].blocks
    starts = np.cumsum([0] + [len(u.pixels) for u in group])
    blocks = np.concatenate([u.blocks[:-1] + s for u, s in zip(group, starts)] + [starts[-1:]])
    return np.concatenate([u.pixels for u in group]), blocks.astype(np.int32)
