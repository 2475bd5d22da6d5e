"""Work items mapped over a Dask cluster or run in this process (issue 14 item 3).

`open_client(scheduler)` gives a dask.distributed Client: to a running scheduler ('tcp://host:8786'),
to a LocalCluster started for the run ('local': one worker process per core, one thread each, the
client's NUMBA_CACHE_DIR passed on), or None ('none': no Dask, run here). `map_items(fn, items,
client)` runs fn on every item and returns the results in the items' order, reporting each as it
finishes. Items are small (paths and option records): each worker loads what it needs itself.

Tasks are pure (the same item gives the same result), so a worker that dies has its tasks re-run
on another worker by the scheduler. Timed items (`timed=True`) run one at a time per worker and
come back as Timed records, flagged `contended` when the process (with the children it waited for)
got under CONTENDED_CPU of the wall time: another process had its core.

`psrt study` maps its points the same way: `with open_client(args.scheduler) as client:
results = map_items(run_point, points, client, progress=bar_step, timed=True)`, where run_point
is a module-level function of one picklable point that loads the scene from its path.
"""
from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass

CONNECT_TIMEOUT = 10.0   # seconds to reach a scheduler before the run is refused
CONTENDED_CPU = 0.8      # a timed item's process CPU time over its wall time below which it is flagged
TIMED = "timed"          # the worker resource that admits one timed item at a time


@dataclass(frozen=True)
class Timed:
    """A timed item's result, its wall and process CPU seconds, and whether its core was shared."""

    value: object
    wall: float
    cpu: float

    @property
    def contended(self) -> bool:
        return self.wall > 0.05 and self.cpu < CONTENDED_CPU * self.wall  # too short to judge: not flagged


def process_cpu() -> float:
    """CPU seconds of this process and of its children waited for (a POV-Ray peer point runs povray)."""
    import resource
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def run_timed(fn, item) -> Timed:
    """fn(item) with its wall and CPU time (the process's and its children's)."""
    wall, cpu = time.perf_counter(), process_cpu()
    value = fn(item)
    return Timed(value, time.perf_counter() - wall, process_cpu() - cpu)


def check_address(scheduler: str) -> str:
    """The scheduler address, or ValueError naming the flag and the form expected."""
    host = scheduler.partition("://")[2] if "://" in scheduler else scheduler
    name, _, port = host.rpartition(":")
    if not name or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"--scheduler: {scheduler!r} is not an address like tcp://host:8786, "
                         f"'local' or 'none'")
    return scheduler if "://" in scheduler else f"tcp://{scheduler}"


def worker_env() -> dict:
    """The environment LocalCluster workers start with: the client's numba cache directory, so a
    kernel compiled once serves every worker."""
    return {k: os.environ[k] for k in ("NUMBA_CACHE_DIR",) if k in os.environ}


@contextlib.contextmanager
def open_client(scheduler: str | None, workers: int | None = None):
    """A Client for `scheduler` (see the module's docstring), closed (with its cluster) on exit; None
    for 'none' or None. A scheduler that cannot be reached, or has no worker, within CONNECT_TIMEOUT
    each is a ValueError."""
    if scheduler in (None, "none"):
        yield None
        return
    import logging
    from distributed import Client, LocalCluster
    logging.getLogger("distributed").setLevel(logging.ERROR)  # a run's own lines only on stderr
    if scheduler == "local":
        n = workers or os.cpu_count() or 1
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                          resources={TIMED: 1}, env=worker_env()) as cluster, Client(cluster) as client:
            yield client
        return
    address = check_address(scheduler)
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except Exception as e:  # refused, timed out, or something else answering there (garbage, a huge frame)
        raise ValueError(f"--scheduler: no Dask scheduler reachable at {address} within "
                         f"{CONNECT_TIMEOUT:g} s ({type(e).__name__})") from None
    with client:
        try:  # a scheduler without workers would leave the run waiting for ever
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
        except TimeoutError:
            raise ValueError(f"--scheduler: the Dask scheduler at {address} has no workers (start some with "
                             f"`dask worker {address}`)") from None
        yield client


def describe(client) -> str:
    """Where the work runs, for a summary line: 'in this process', 'on 2 Dask workers (tcp://...)'."""
    if client is None:
        return "in this process"
    threads = client.nthreads()
    return f"on {len(threads)} Dask workers, {sum(threads.values())} threads ({client.scheduler.address})"


def timed_resources(client) -> dict | None:
    """The task resources that keep timed items one per worker: {'timed': 1} when every worker
    offers it; None when every worker has one thread anyway; else ValueError saying how to start them."""
    workers = client.scheduler_info()["workers"].values()
    if workers and all(w.get("resources", {}).get(TIMED, 0) >= 1 for w in workers):
        return {TIMED: 1}
    if all(w.get("nthreads", 1) == 1 for w in workers):
        return None
    raise ValueError("--scheduler: timed work needs workers started with `--nthreads 1` or "
                     f"`--resources {TIMED}=1`")


def map_items(fn, items, client=None, progress=None, timed=False) -> list:
    """[fn(item) for item in items] (Timed records if `timed`), on the client's workers or here
    (client None); progress(index, result) as each finishes. fn must be a module-level function."""
    items = list(items)
    call = (lambda item: run_timed(fn, item)) if timed else fn
    if client is None:
        out = []
        for i, item in enumerate(items):
            out.append(call(item))
            if progress is not None:
                progress(i, out[-1])
        return out
    from distributed import as_completed
    resources = timed_resources(client) if timed else None
    futures = [client.submit(run_timed if timed else fn, *((fn, item) if timed else (item,)), pure=True,
                             resources=resources, key=f"psrt-{i}-{_token(fn, item, timed)}")
               for i, item in enumerate(items)]
    index = {f.key: i for i, f in enumerate(futures)}
    out = [None] * len(items)
    try:
        for fut in as_completed(futures):
            i = index[fut.key]
            out[i] = fut.result()
            if progress is not None:
                progress(i, out[i])
    finally:
        client.cancel(futures)
    return out


def _token(fn, item, timed: bool) -> str:
    """A task's key from what it computes: the same item twice is one task (pure), timed or not two."""
    from dask.base import tokenize
    return tokenize(fn.__module__, fn.__qualname__, item, timed)


# ---- what a worker keeps between tasks -------------------------------------------------------

_SCENES: dict = {}


def loaded_scene(path: str, label: str | None = None):
    """The scene at `path` (absolute: a worker's directory is not the client's), loaded once per
    process while the file is unchanged (keyed by its modification time and size), its path
    reading `label` as the client's does (messages name the file as the user gave it)."""
    import dataclasses
    from .scene import load_scene
    st = os.stat(path)
    key = (path, label, st.st_mtime_ns, st.st_size)
    if key not in _SCENES:
        _SCENES.clear()  # one scene at a time: runs follow each other on a long-lived worker
        scene = load_scene(path)
        _SCENES[key] = scene if label is None else dataclasses.replace(scene, path=label)
    return _SCENES[key]


def worker_threads(threads: int) -> int:
    """The render threads of a task: `threads` if set, else the Dask worker's own thread count (so
    workers sharing a machine do not share cores), else 0 (one per core) outside a worker."""
    if threads > 0:
        return threads
    try:
        from distributed import get_worker
        return get_worker().state.nthreads
    except (ImportError, ValueError, AttributeError):
        return 0
