"""Lischinski's counters of a render (stats.coherence_stats): per ray surfaces box-tested, searched
and ray-box tests; with the surface-tree cache its hit ratio and misses per surface searched; in
frame_stats, `render --stats` and the viewer's Stats panel."""
import json

import numpy as np
import pytest

import digests as D
import scenes as S
from test_stats import synthetic_frame
from tracer.geometry import prepare
from tracer.options import Options
from tracer.render import fresh_caches, render
from tracer.stats import coherence_stats, frame_stats
from viewer_util import teapot, warm_kernels, xvfb  # noqa: F401 (fixtures of the window test)

SIZE = (24, 24)


@pytest.fixture(scope="module")
def sample():
    scene, view = D.catalogue()["teapot"][0]()
    return scene, view, prepare(scene, "f32")


def _frame(sample, opts, fresh=True):
    scene, view, geom = sample
    if fresh:
        fresh_caches(geom, opts)
    return render(scene, opts, size=SIZE, view=view, geometry=geom)


def test_per_ray_counters_are_the_channels_means():
    f = synthetic_frame()
    f.surfaces_tested[:] = f.patches_tested + 2
    f.box_tests[:] = f.effort + f.nodes
    c = coherence_stats(f)
    assert c["surfaces_searched_per_ray"] == pytest.approx(f.patches_tested.mean())
    assert c["surfaces_tested_per_ray"] == pytest.approx(f.patches_tested.mean() + 2)
    assert c["box_tests_per_ray"] == pytest.approx((f.effort + f.nodes).mean())
    assert c["cache"] is None and c["cache_hit_ratio"] is None and c["cache_misses_per_surface"] is None


def test_a_cold_cache_makes_each_searched_surface_once_and_a_warm_one_none(sample):
    opts = Options(threads=1, cache=True, cache_mb=256.0, bundle="1x1")  # one ray a search
    cold = frame_stats(_frame(sample, opts))["coherence"]
    frame = _frame(sample, opts, fresh=False)  # the trees of the frame before are still there
    warm = frame_stats(frame)["coherence"]
    c, w = cold["cache"], warm["cache"]
    assert c["released"] == 0 and c["misses"] == c["surfaces"] > 0 and cold["cache_misses_per_surface"] == 1.0
    assert w["misses"] == 0 and w["surfaces"] == c["surfaces"] and warm["cache_misses_per_surface"] == 0.0
    assert warm["cache_hit_ratio"] == 1.0 and 0.0 < cold["cache_hit_ratio"] < 1.0
    searches = int(frame.patches_tested.sum())
    assert w["hits"] == searches == int(frame.cache_hits.sum())  # one thread, one ray a search
    for s in (cold, warm):
        assert s["surfaces_searched_per_ray"] <= s["surfaces_tested_per_ray"] <= s["box_tests_per_ray"]
    scene, view, geom = sample
    few = frame_stats(render(scene, opts, size=(3, 3), view=view, geometry=geom))["coherence"]["cache"]
    assert 0 < few["surfaces"] < c["surfaces"] // 10  # counted afresh for each frame


def test_a_small_cache_remakes_trees(sample):
    opts = Options(threads=1, cache=True, cache_mb=1.0, cache_depth=30)
    c = frame_stats(_frame(sample, opts))["coherence"]
    assert c["cache"]["released"] > 0 and c["cache_misses_per_surface"] > 1.0
    assert c["cache"]["nodes"] <= c["cache"]["capacity"]


def test_each_thread_counts_the_surfaces_its_cache_searched(sample):
    one = frame_stats(_frame(sample, Options(threads=1, cache=True)))["coherence"]["cache"]
    two = frame_stats(_frame(sample, Options(threads=2, tile_size=8, cache=True)))["coherence"]["cache"]
    assert two["threads"] == 2 and two["misses"] == two["surfaces"]
    assert one["surfaces"] <= two["surfaces"] <= 2 * one["surfaces"]


def test_without_the_cache_there_are_no_cache_figures(sample):
    c = frame_stats(_frame(sample, Options(threads=1)))["coherence"]
    assert c["cache"] is None and c["cache_hit_ratio"] is None and c["surfaces_searched_per_ray"] > 0


def test_render_stats_json_has_the_coherence_section(tmp_path):
    from psrt.cli import main
    out = tmp_path / "s.json"
    assert main(["render", str(S.SAMPLES / "teapot.json"), "-o", str(tmp_path / "i.png"), "--size", "16x12",
                 "--cache", "--threads", "1", "--stats", str(out), "-q"]) == 0
    c = json.loads(out.read_text())["coherence"]
    assert 0.0 <= c["cache_hit_ratio"] <= 1.0 and c["cache_misses_per_surface"] >= 1.0
    assert c["surfaces_searched_per_ray"] <= c["surfaces_tested_per_ray"]
    assert set(c["cache"]) >= {"hits", "misses", "surfaces", "released", "nodes", "bytes"}


def test_the_viewers_stats_panel_shows_them(sample):
    from viewer.ui_stats import coherence_lines
    assert coherence_lines(None) == []
    plain = coherence_lines(frame_stats(_frame(sample, Options(threads=1)))["coherence"])
    assert len(plain) == 1 and "surfaces box-tested" in plain[0]
    c = frame_stats(_frame(sample, Options(threads=1, cache=True)))["coherence"]
    text = " ".join(coherence_lines(c))
    assert f"hit ratio {c['cache_hit_ratio']:.3f}" in text and f"{c['cache']['surfaces']} surfaces" in text
    assert np.isfinite(c["box_tests_per_ray"])


def test_the_viewer_shows_them_in_a_real_window(xvfb, warm_kernels, tmp_path):
    """The Stats panel, its tab selected (tests/view_hooks.py), draws the coherence lines of a cached
    render: an error in a panel is logged as an internal error."""
    from viewer_util import TEAPOT, run_view
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "32x32", "--set", "cache=true", "--set", "threads=1",
                                        "--screenshot", tmp_path / "view.png"], tmp_path, hooks="stats-tab")
    assert code == 0, err
    errors = [m["text"] for m in status["messages"] if m["level"] == "error"]
    assert not errors, errors
    c = status["render"]["stats"]["coherence"]
    assert c["cache"]["threads"] == 1 and 0.0 <= c["cache_hit_ratio"] <= 1.0
    assert c["surfaces_searched_per_ray"] <= c["surfaces_tested_per_ray"]
