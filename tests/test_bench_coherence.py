"""`psrt bench --coherence`: three tables per scene with the rows bench_coherence promises, each
row's speed-up against its plain row of the same run, the counters in the JSON, and the checks
of issue 12's targets. Tiny images, no timing assertions."""
import contextlib
import io
import json

import pytest

from psrt.cli import main
from tracer import bench_coherence as BC
from tracer.bench_tables import TITLES, checks, format_checks

TEAPOT_ROWS = 26 + 15 + 12  # bundles, accel, order


def run(*argv):
    return main([str(a) for a in argv])


@pytest.fixture(scope="module")
def teapot_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "coherence.json"
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = run("bench", "--coherence", "--scenes", "teapot", "--size", "8x6", "--runs", "2", "--json", out)
    return code, text.getvalue(), json.loads(out.read_text())


def test_the_command_prints_three_tables_with_every_row(teapot_run):
    code, text, result = teapot_run
    assert code == 0
    rows = result["scenes"]["teapot"]["rows"]
    assert len(rows) == TEAPOT_ROWS
    assert [sum(r["table"] == t for r in rows) for t in BC.TABLES] == [26, 15, 12]
    for title in TITLES.values():
        assert title in text
    for label in ("float 1x1", "adaptive 8x8 + cache + peano", "fixed 4x2", "no subdivision", "BVH",
                  "kd-tree sah 10", "kd-tree middle 30", "kd-tree middle 20, mailbox", "grid 0.25, mailbox",
                  "grid 1", "scanline, no cache", "itembuffer, cache 4 MB", "peano, cache 60 MB",
                  "peano, cache unbounded"):
        assert label in text and any(r["label"].startswith(label) or r["label"].endswith(label) for r in rows)
    assert "CPU time of the process" in text and "targets (issue 12)" in text
    assert "re-made" in text and "(trees re-made 0 / 0)" in text  # 8x6: every bound holds the frame's trees


def test_rows_measure_against_their_plain_row_in_the_same_runs(teapot_run):
    _, _, result = teapot_run
    assert result["runs"] == 2 and result["size"] == [8, 6] and result["timing"] == "cpu"
    by_label = {r["label"]: r for r in result["scenes"]["teapot"]["rows"]}
    for plain in ("float 1x1", "adaptive 1x1", "fixed 1x1", "BVH", "scanline, no cache"):
        assert by_label[plain]["speedup"] == 1.0
    assert by_label["BVH"]["times"] == by_label["float 1x1"]["times"]  # one configuration, timed once a run
    for r in by_label.values():
        assert len(r["times"]) == 2 and r["time"] > 0 and r["speedup"] > 0
        assert r["stats"]["rays"] == 48


def test_the_counters_and_the_cache_figures_are_sane(teapot_run):
    _, _, result = teapot_run
    rows = result["scenes"]["teapot"]["rows"]
    for r in rows:
        c = r["stats"]["coherence"]
        assert c["surfaces_searched_per_ray"] <= c["surfaces_tested_per_ray"] <= c["box_tests_per_ray"]
        assert (c["cache"] is not None) == r["options"].get("cache", False)
        if c["cache"] is not None:
            assert 0.0 <= c["cache_hit_ratio"] <= 1.0 and c["cache_misses_per_surface"] >= 1.0
    for r in rows:
        if "unbounded" in r["label"]:  # room for every tree: each made once, none released
            c = r["stats"]["coherence"]
            assert c["cache"]["released"] == 0 and c["cache_misses_per_surface"] == 1.0
            assert c["cache"]["misses"] == c["cache"]["surfaces"]  # the table's re-made: 0
    accel = [r for r in rows if r["table"] == "accel"]
    assert all((r["build_seconds"] is None) == ("mailbox" in r["label"]) for r in accel)
    assert {r["stats"]["accel"]["kind"] for r in accel} == {"bvh", "kdtree", "grid"}


def test_quiet_and_bad_usage(capsys, tmp_path):
    assert run("bench", "--scenes", "teapot", "--size", "8x8") == 2
    assert "--scenes: only with --coherence" in capsys.readouterr().err
    assert run("bench", "--tables", "accel", "--size", "8x8") == 2
    assert "--tables: only with --coherence" in capsys.readouterr().err
    assert run("bench", "--coherence", "--scene", "x.json") == 2
    assert "--scenes" in capsys.readouterr().err
    assert run("bench", "--coherence", "--scenes", str(tmp_path / "missing.json"), "--size", "4x4", "-q") == 2
    assert "missing.json" in capsys.readouterr().err


def _fake(scanline_ratio, peano_ratio, bounded, unbounded):
    def row(label, times, ratio=None, speedup=1.0):
        return {"table": "order", "label": label, "times": times, "time": times[0], "speedup": speedup,
                "stats": {"coherence": {"cache_hit_ratio": ratio}}}
    rows = [row("scanline, cache 60 MB", bounded, scanline_ratio), row("peano, cache 60 MB", bounded, peano_ratio),
            row("scanline, cache unbounded (99 MB)", unbounded, 0.5)]
    return {"size": [8, 8], "scenes": {"flying": {"rows": rows}}}


def test_the_checks_say_when_a_target_is_missed():
    met = {what: ok for what, _, _, ok in checks(_fake(0.5, 0.6, [1.0, 1.0], [0.95, 0.95]))}
    assert all(met.values()) and len(met) == 2
    missed = {what: ok for what, _, _, ok in checks(_fake(0.6, 0.5, [1.0, 1.0], [0.8, 0.8]))}
    assert not any(missed.values())
    assert "NOT met" in format_checks(_fake(0.6, 0.5, [1.0, 1.0], [0.8, 0.8]))


def test_tables_chooses_the_tables_and_quiet_keeps_stderr_empty(capsys):
    assert run("bench", "--coherence", "--scenes", "teapot", "--tables", "order", "--size", "4x4", "--runs", "1",
               "-q") == 0
    captured = capsys.readouterr()
    assert captured.err == "" and TITLES["order"] in captured.out
    assert TITLES["bundles"] not in captured.out and TITLES["accel"] not in captured.out
    assert captured.out.count("peano, ") == 4 and "no subdivision" not in captured.out


def test_the_frame_without_subdivision_is_judged_by_its_fastest_row_at_512():
    def flat(seconds, size, scene="teapot"):
        rows = [{"table": "bundles", "label": f"fixed 5 {b}: no subdivision", "times": [t], "time": t,
                 "speedup": 2.0, "stats": {}} for b, t in zip(("1x1", "8x8"), seconds)]
        return {"size": size, "scenes": {scene: {"rows": rows}}}

    def verdict(result):
        (what, figure, _, ok), = [c for c in checks(result) if "without subdivision" in c[0]]
        return what, figure, ok

    what, figure, ok = verdict(flat([0.09, 0.035], [512, 512]))
    assert ok is True and "8x8" in what and figure.startswith("0.035 s")
    assert verdict(flat([0.09, 0.05], [512, 512]))[2] is False
    assert verdict(flat([0.01, 0.01], [64, 64]))[2] is None  # only the teapot at 512x512 is judged
    assert verdict(flat([0.01, 0.01], [512, 512], "flying"))[2] is None


def test_a_figure_beside_its_target_never_reads_as_the_other_verdict():
    def best(speedup):
        rows = [{"table": "bundles", "label": f"float {b}", "times": [t], "time": t, "speedup": s, "stats": {}}
                for b, t, s in (("1x1", 1.0, 1.0), ("8x8", 1.0 / speedup, speedup))]
        (c,) = [c for c in checks({"size": [512, 512], "scenes": {"teapot": {"rows": rows}}}) if "float" in c[0]]
        return c[1], c[3]

    assert best(1.1996) == ("1.1996x", False)  # not "1.20x ... NOT met"
    assert best(1.2) == ("1.20x", True)
    assert best(1.2049) == ("1.20x", True) and best(1.0437) == ("1.04x", False)
    assert best(1.19999999) == ("1.19999999x", False)
