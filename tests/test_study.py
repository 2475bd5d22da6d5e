"""`psrt study SCENE` (tracer/study.py, study_truth.py, study_report.py, cli_study.py): the Newton
truth against a hand-made patch, scoring, the outputs and bad input. Images are 12x12; no timing
is asserted."""
import json
import math
from pathlib import Path
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from psrt.cli import main
from tracer import study
from tracer.study_coherence import Trial, run_trial, settings
from tracer.study_report import format_targets, markdown, series_points, targets
from tracer.scene import load_scene
from tracer.study_peers import tessellate
from tracer.study_povray import available, bicubic_nets, read_ppm16
from tracer.study_truth import newton, surface_and_partials

TEAPOT = str(Path(__file__).resolve().parents[1] / "sample_models" / "teapot.json")


def saddle_grid():
    """One bicubic grid (1, 4, 4, 4) of z = (x - 1.5)(y - 1.5) / 4 over [0, 3]^2 (exact in the Bernstein
    basis: a bilinear function degree-elevated), weights 1."""
    g = np.zeros((1, 4, 4, 4))
    for i in range(4):
        for j in range(4):
            g[0, i, j] = (i, j, (i - 1.5) * (j - 1.5) / 4, 1.0)
    return g


def test_partials_match_differences():
    g = saddle_grid()
    g[0, 1, 2, :] *= 2.0   # a weight of 2: rational
    u, v, h = np.array([0.3]), np.array([0.6]), 1e-6
    s, su, sv = surface_and_partials(g, u, v)
    diff_u = (surface_and_partials(g, u + h, v)[0] - surface_and_partials(g, u - h, v)[0]) / (2 * h)
    diff_v = (surface_and_partials(g, u, v + h)[0] - surface_and_partials(g, u, v - h)[0]) / (2 * h)
    assert np.allclose(su, diff_u, atol=1e-7) and np.allclose(sv, diff_v, atol=1e-7)  # central differences


def test_newton_finds_the_saddle_point_exactly():
    g = saddle_grid()
    x, y = 1.1, 2.2                      # u = x / 3, v = y / 3 on this grid
    z = (x - 1.5) * (y - 1.5) / 4
    origin, direction = np.array([[x, y, 5.0]]), np.array([[0.0, 0.0, -1.0]])
    u, v, t, point, residual = newton(g, np.array([0.4]), np.array([0.7]), np.array([4.0]), origin, direction)
    assert math.isclose(u[0], x / 3, abs_tol=1e-14) and math.isclose(v[0], y / 3, abs_tol=1e-14)
    assert math.isclose(point[0, 2], z, abs_tol=1e-14) and residual[0] < 1e-14


def test_score_counts_holes_false_hits_wrong_surfaces():
    ref = SimpleNamespace(hit=np.array([[True, True, True, False]]), patch=np.array([[0, 1, 2, -1]]),
                          ray_origin=np.zeros((1, 4, 3)), ray_dir=np.ones((1, 4, 3)), t=np.ones((1, 4)))
    truth = study.Truth(ref, np.zeros((1, 4, 3)), np.array([[True, True, True, False]]), 2.0)
    position = np.zeros((1, 4, 3))
    position[0, 1] = (0.5, 0.0, -0.5)     # L1 error 1, over size 2
    s = study.score(np.array([[False, True, True, True]]), position, np.array([[-1, 1, 5, 0]]),
                    position - 0.1, position + 0.1, truth)
    assert (s.holes, s.false_hits, s.wrong_surface, s.compared) == (1, 1, 1, 2)
    assert math.isclose(s.mean_error, 0.25) and math.isclose(s.max_error, 0.5)
    assert s.inside == 0.5                # the displaced point's box misses the truth


def test_cli_outputs_on_the_teapot(tmp_path, capsys):
    out, md, png = tmp_path / "s.json", tmp_path / "s.md", tmp_path / "s.png"
    assert main(["study", "--scheduler", "none", TEAPOT, "--size", "12x12", "--precisions", "f32", "--no-coherence", "--json", str(out),
                 "--markdown", str(md), "--chart", str(png), "--tessellations", "2", "16", "--flatnesses", "-q"]) == 0
    data = json.loads(out.read_text())
    names = {p["series"] for p in data["points"]}
    assert names == {"psrt float f32", "psrt fixed f32", "psrt adaptive f32", "psrt mantissa f32",
                     "embree first image", "embree per frame"}
    psrt_points = 1 + len(study.FIXED_FRACTIONS) + len(study.PIXEL_FRACTIONS) + len(study.MANTISSA_ULPS)
    assert len(data["points"]) == psrt_points + 4
    embree = {(p["series"], p["parameter"]): p for p in data["points"] if p["series"].startswith("embree")}
    first, fine = embree["embree first image", 2], embree["embree first image", 16]
    assert first["inside"] is None and fine["mean_error"] < first["mean_error"]  # finer: closer to the truth
    assert embree["embree per frame", 16]["mean_error"] == fine["mean_error"]
    assert 0 < data["truth_accepted"] <= data["reference_hits"] and data["float32_floor"] > 0
    best = next(p for p in data["points"] if p["series"] == "psrt float f32")
    assert best["holes"] == 0 and best["false_hits"] == 0 and best["mean_error"] < 4 * data["float32_floor"]
    assert md.read_text() == capsys.readouterr().out.rstrip("\n") + "\n" == markdown(data)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(series_points(data)) == names


def test_tessellation_faces_follow_patches():
    scene = load_scene(TEAPOT)
    vertices, faces, face_patch = tessellate(scene, 3)
    assert vertices.shape == (scene.n_patches * 16, 3) and faces.shape == (scene.n_patches * 18, 3)
    assert np.all(faces // 16 == face_patch[:, None])          # every face's corners are its patch's points
    corners = vertices.reshape(scene.n_patches, 4, 4, 3)[:, [0, 0, -1, -1], [0, -1, 0, -1]]
    m, d = scene.degree_u[:, None], scene.degree_v[:, None]
    net = scene.points[scene.point_start[:scene.n_patches, None] + np.hstack([0 * m, m, (m + 1) * d, (m + 1) * (d + 1) - 1])][..., :3]
    assert np.allclose(corners, net, atol=1e-12)                 # a patch interpolates its corner points


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    assert main(["study", "--scheduler", "none", str(tmp_path / "missing.json"), "--size", "8x8", "-q"]) == 2
    assert main(["study", "--scheduler", "none", TEAPOT, "--size", "0x8", "-q"]) == 2
    assert main(["study", "--scheduler", "none", TEAPOT, "--chart", str(tmp_path / "no" / "dir" / "c.png"), "-q"]) == 2
    assert main(["study", "--scheduler", "none", TEAPOT, "--size", "16384x16384", "--memory-limit", "1G", "-q"]) == 2  # refused before work
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 4 and all(line.startswith("psrt study: error: ") for line in lines)


def test_elevated_nets_are_the_same_surfaces():
    scene = load_scene(TEAPOT)
    nets, why = bicubic_nets(scene)
    assert why is None and nets.shape == (scene.n_patches, 16, 3)
    elevated = replace(scene, points=np.column_stack([nets.reshape(-1, 3), np.ones(16 * scene.n_patches)]),
                       point_start=np.arange(scene.n_patches + 1) * 16, degree_u=np.full(scene.n_patches, 3),
                       degree_v=np.full(scene.n_patches, 3))
    assert np.allclose(tessellate(elevated, 4)[0], tessellate(scene, 4)[0], atol=1e-12)


def test_ppm16_reader(tmp_path):
    pixels = (np.arange(2 * 3 * 3) * 3000).astype(">u2").reshape(2, 3, 3)  # big-endian, as PPM is
    (tmp_path / "a.ppm").write_bytes(b"P6\n# a comment\n3 2\n65535\n" + pixels.tobytes())
    assert np.array_equal(read_ppm16(tmp_path / "a.ppm"), pixels)


@pytest.mark.skipif(not available(), reason="povray not installed (scripts/setup --povray)")
def test_povray_peer_on_the_teapot(tmp_path):
    out = tmp_path / "s.json"
    assert main(["study", "--scheduler", "none", TEAPOT, "--size", "12x12", "--precisions", "f32", "--no-coherence", "--tessellations",
                 "--flatnesses", "0.1", "0.001", "--json", str(out), "-q"]) == 0
    rows = {p["parameter"]: p for p in json.loads(out.read_text())["points"] if p["series"] == "povray first image"}
    assert set(rows) == {0.1, 0.001} and rows[0.001]["compared"] > 0
    assert rows[0.001]["mean_error"] < rows[0.1]["mean_error"] < 0.05   # flatter: closer; the depth read back


def test_report_directory(tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["study", "--scheduler", "none", TEAPOT, "--size", "8x8", "--precisions", "f32", "--no-coherence", "--tessellations", "2",
                 "--flatnesses", "--report", str(out), "--bench-size", "8x8", "--bench-runs", "1",
                 "--stress-size", "8x8", "-q"]) == 0
    text = (out / "report.md").read_text()
    assert "![time against error](study.png)" in text and "| CPU |" in text
    assert "## Coherence" in text and "## Numerical stress" in text and "| psrt float f32 |" in text
    assert (out / "study.png").read_bytes()[:4] == b"\x89PNG" and json.loads((out / "study.json").read_text())
    assert main(["study", "--scheduler", "none", TEAPOT, "--report", str(tmp_path / "no" / "dir"), "-q"]) == 2


def test_targets_read_off_the_results():
    pts = [{"series": "psrt float f32", "parameter": None, "mean_error": 1e-8, "seconds": 1.0, "holes": 0},
           {"series": "embree first image", "parameter": 128, "mean_error": 2e-6, "seconds": 2.0, "holes": 0},
           {"series": "embree first image", "parameter": 256, "mean_error": 5e-7, "seconds": 8.0, "holes": 0},
           {"series": "povray first image", "parameter": 0.01, "mean_error": 1e-4, "seconds": 0.5, "holes": 3},
           {"series": "psrt adaptive f32", "parameter": 2.0, "mean_error": 3e-4, "seconds": 0.1, "holes": 0},
           {"series": "psrt adaptive f32", "parameter": 0.5, "mean_error": 1e-4, "seconds": 0.6, "holes": 0},
           {"series": "psrt adaptive f32 8x8", "parameter": 0.5, "mean_error": 1e-4, "seconds": 0.4, "holes": 0}]
    rows = targets({"float32_floor": 6e-9, "points": pts})
    # 1.7 x floor; 50 x below embree, the floor 83 x; faster; 1/N^2 a check; the fastest adaptive point
    # as accurate as POV-Ray (8x8 at 0.5 px, not the faster but coarser 2 px) is faster, with fewer holes
    assert [ok for _, ok, _ in rows] == [True, False, True, None, True]
    assert "83 x below that peer point, so 100 x is out of" in rows[1][2]
    assert "4.00 x where 1/N^2 gives 4.00 x" in rows[3][2]
    assert rows[4][2].startswith("psrt adaptive f32 8x8 at 0.5 px")
    pts[-1]["mean_error"] = pts[-2]["mean_error"] = 2e-4        # none as accurate: not met
    assert targets({"float32_floor": 6e-9, "points": pts})[-1][1] is False
    assert "- check: the tessellation" in format_targets({"float32_floor": 6e-9, "points": pts})


def test_coherence_settings_and_the_choice():
    assert settings("8x8+cache") == {"bundle": "8x8", "cache": True}
    assert settings("grid+mailbox") == {"accel": "grid", "mailbox": True}
    for bad in ("8x8+grid", "mailbox", "1x1", "9x9", "bvh"):
        with pytest.raises(ValueError, match=bad.replace("+", r"\+")):
            settings(bad)
    times = {"1x1": [3.0, 3.0, 3.0, 3.0], "4x4": [9.0, 2.0, 2.5, 2.0], "8x8": [9.0, 2.2, 2.1, 2.2]}  # warm-up first
    seen = []

    def trace_seconds(opts):
        seen.append(opts.bundle)
        return times[opts.bundle][sum(b == opts.bundle for b in seen) - 1]
    plain = study.Options(threads=1, criterion="adaptive", bundle="1x1")
    trial = Trial("adaptive", "f32", 0.5, plain, ("4x4", "8x8"), rounds=3)
    out = run_trial(trace_seconds, trial)
    assert seen == ["1x1", "4x4", "8x8"] * 4                     # one warm-up, then the settings take turns
    assert out["seconds"] == {"plain": 3.0, "4x4": 2.0, "8x8": 2.2} and out["chosen"] == "4x4"
    assert out["speedup"] == 1.5


def test_the_plain_series_and_trials_trace_single_rays_whatever_the_default():
    """The default bundle is 8x8; the study's plain series and each trial's plain setting are the
    plain setting (options.PLAIN), and a coherence series only adds its own."""
    from tracer.options import PLAIN
    from tracer.study_coherence import trials
    base = study.Options(bundle="4x4", cache=True)  # as a user's flags could leave it
    fields = study.sweep_options(1.0)
    plain = [p.opts for p in study.points(1.0, base, ("f32",))]
    coherent = [p.opts for p in study.points(1.0, base, ("f32",), {(c, "f32"): "8x8" for c in study.SWEEPS})]
    assert plain and all(getattr(o, k) == v for o in plain for k, v in PLAIN.items())
    assert {o.bundle for o in coherent} == {"1x1", "8x8"}
    assert all(getattr(t.opts, k) == v for t in trials(fields, ("f32",), base) for k, v in PLAIN.items())


def test_coherence_series_use_the_chosen_setting(tmp_path):
    out = tmp_path / "s.json"
    assert main(["study", "--scheduler", "none", TEAPOT, "--size", "8x8", "--precisions", "f32", "--tessellations",
                 "--flatnesses", "--coherence-candidates", "4x4+cache", "--coherence-rounds", "1",
                 "--json", str(out), "-q"]) == 0
    data = json.loads(out.read_text())
    tried = data["coherence"]["trials"]
    assert [(t["criterion"], t["chosen"]) for t in tried] == [(c, "4x4+cache") for c in study.SWEEPS]
    assert set(tried[0]["seconds"]) == {"plain", "4x4+cache"} and data["coherence"]["rounds"] == 1
    rows = {(p["series"], p["parameter"]): p for p in data["points"]}
    assert len(rows) == len(data["points"]) == 2 * sum(map(len, study.SWEEPS.values()))
    assert rows["psrt float f32 4x4+cache", None]["mean_error"] == rows["psrt float f32", None]["mean_error"]
    text = markdown(data)
    assert "| adaptive f32 | 0.5 px |" in text and "| 4x4+cache |" in text
    assert main(["study", "--scheduler", "none", TEAPOT, "--coherence-candidates", "8x8+grid", "-q"]) == 2
