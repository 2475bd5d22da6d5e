"""Work on Dask (tracer/distributed.py, tracer/distributed_render.py; issue 14 item 3): one
LocalCluster of 2 worker processes with a thread each serves the module; its results equal the
local ones exactly (timings aside), a worker killed mid-task has its task re-run, and a scheduler
that is malformed or unreachable is one line and exit 2. Images are tiny."""
import os
import time
from pathlib import Path

import cloudpickle
import numpy as np
import pytest

from psrt.cli import main
from tracer import distributed, stress
from tracer.distributed import map_items, open_client
from tracer.scene import load_scene

TEAPOT = str(Path(__file__).resolve().parents[1] / "sample_models" / "teapot.json")
cloudpickle.register_pickle_by_value(__import__(__name__))  # the workers need not import tests/


@pytest.fixture(scope="module")
def client():
    with open_client("local", workers=2) as c:
        c.wait_for_workers(2, timeout=120)
        yield c


def square(x):
    return x * x


def die_once(marker):
    """Ends its worker process the first time (the marker file not yet there), then returns 7."""
    if not os.path.exists(marker):
        Path(marker).write_text("killed")
        os._exit(1)
    return 7


def test_items_come_back_in_order_with_progress(client):
    seen = []
    assert map_items(square, range(6), client, progress=lambda i, r: seen.append((i, r))) == [0, 1, 4, 9, 16, 25]
    assert sorted(seen) == [(i, i * i) for i in range(6)]
    assert map_items(square, range(6)) == [0, 1, 4, 9, 16, 25]


def test_timed_items_run_one_per_worker_and_carry_their_times(client):
    out = map_items(square, [3, 4], client, timed=True)
    assert [t.value for t in out] == [9, 16]
    assert all(t.wall >= 0 and t.cpu >= 0 for t in out)
    assert distributed.timed_resources(client) == {distributed.TIMED: 1}


def test_contention_flag():
    assert distributed.Timed(None, wall=1.0, cpu=0.5).contended
    assert not distributed.Timed(None, wall=1.0, cpu=0.95).contended
    assert not distributed.Timed(None, wall=0.01, cpu=0.0).contended  # too short to judge


def test_a_dead_workers_task_is_rerun(client, tmp_path):
    marker = str(tmp_path / "killed-once")
    assert map_items(die_once, [marker], client) == [7]
    assert os.path.exists(marker)
    client.wait_for_workers(2, timeout=120)  # the nanny restarts it, for the tests after this one


def test_stress_scores_on_the_cluster_equal_local(client):
    scene = load_scene(TEAPOT)
    chosen = stress.select(["as-is", "scale-1e3", "move-1e6", "grazing-90", "ulps-1"])  # move-1e6 warns
    here = stress.run(scene, chosen, (16, 16))
    there = stress.run(scene, chosen, (16, 16), client=client)
    assert here[2].warnings and here[2].warnings[0].startswith(TEAPOT)  # the path as given, not the worker's
    assert [(r.variant, r.score, r.refused, r.warnings) for r in here] == \
           [(r.variant, r.score, r.refused, r.warnings) for r in there]


def test_render_on_the_scheduler_is_bit_identical(client, tmp_path):
    local, remote = tmp_path / "local.npz", tmp_path / "remote.npz"
    common = ["render", TEAPOT, "--size", "24x16", "--tile-size", "8", "-q"]  # 6 tiles: tasks on both workers
    assert main(common + ["-o", str(tmp_path / "l.png"), "--aov", str(local)]) == 0
    assert main(common + ["-o", str(tmp_path / "r.png"), "--aov", str(remote), "--scheduler", client.scheduler.address]) == 0
    a, b = np.load(local), np.load(remote)
    assert sorted(a.files) == sorted(b.files) and "shadow" in a.files
    for name in a.files:  # exactly equal, NaN where NaN
        assert np.array_equal(a[name], b[name], equal_nan=a[name].dtype.kind == "f"), name
    assert (tmp_path / "l.png").read_bytes() == (tmp_path / "r.png").read_bytes()


@pytest.mark.parametrize("address, needle", [
    ("tcp://127.0.0.1:1", "no Dask scheduler reachable at tcp://127.0.0.1:1"),
    ("not-an-address", "is not an address like tcp://host:8786"),
])
def test_bad_scheduler_is_one_line_and_exit_2(address, needle, tmp_path, capsys):
    start = time.monotonic()
    assert main(["render", TEAPOT, "--size", "8x8", "-q", "-o", str(tmp_path / "x.png"), "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1
    assert time.monotonic() - start < distributed.CONNECT_TIMEOUT + 60  # bounded, generously under load


def test_a_scheduler_without_workers_is_refused_not_waited_on(tmp_path, capsys, monkeypatch):
    from distributed import LocalCluster
    monkeypatch.setattr(distributed, "CONNECT_TIMEOUT", 2.0)
    with LocalCluster(n_workers=0, processes=False, protocol="tcp", dashboard_address=":0") as empty:
        assert main(["render", TEAPOT, "--size", "8x8", "-q", "-o", str(tmp_path / "x.png"),
                     "--scheduler", empty.scheduler_address]) == 2
    err = capsys.readouterr().err
    assert "has no workers" in err and len(err.strip().splitlines()) == 1


def test_study_units_on_the_cluster_score_as_local(client):
    """Issue 14's target: a distributed study gives the same errors as a local one; psrt's points,
    the coherence trials and the peers' points all run on the workers."""
    from tracer import study
    from tracer.study_povray import available
    scene = load_scene(TEAPOT)
    flatnesses = (0.01,) if available() else ()  # CI has no povray
    kwargs = dict(precisions=("f32",), tessellations=(2, 8), flatnesses=flatnesses, candidates=("8x8",), rounds=1)
    here = study.run(scene, (12, 12), **kwargs)
    seen = []
    there = study.run(scene, (12, 12), client=client, progress=seen.append, **kwargs)
    assert len(seen) == study.unit_count(scene, ("f32",), True, (2, 8), flatnesses) and seen[0] is None
    timing = ("seconds", "contended", "povray_wall_cpu")
    strip = [{k: v for k, v in row.items() if k not in timing} for row in here["points"]]
    assert strip == [{k: v for k, v in row.items() if k not in timing} for row in there["points"]]
    assert all("contended" in row for row in there["points"]) and len(strip) == 2 * 17 + 4 + len(flatnesses)
    assert {row["series"] for row in there["points"]} >= {"embree first image", "embree per frame"}
    trials = there["coherence"]["trials"]
    assert [t["chosen"] for t in trials] == ["8x8"] * 4 and all("contended" in t for t in trials)
