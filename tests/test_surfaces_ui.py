"""What the Scene panel and the inspector say about surfaces (viewer.surface_info), and the
inspector's dump of a hit on the trimmed plate from the real window under Xvfb."""
from __future__ import annotations

import importlib.util
import json
import math

import numpy as np
import pytest

from tracer.formats.obj import load_obj
from tracer.options import Options
from tracer.render import render
from tracer.scene import load_scene
from tracer.trace_one import trace_pixel
from tracer.trim import loops_for_plot
from viewer.surface_info import (count_lines, hit_surface, import_rows, info_json, scene_counts,
                                 summary_rows, surface_location)
from viewer_util import REPO, run_view, xvfb  # noqa: F401 (fixture)

SAMPLES = REPO / "sample_models"
SIZE = (96, 96)
PLATE_PIXEL = (48, 48)  # on the plate between its holes, patch 1


def _make_samples():
    """sample_models/make_samples.py: the plate's analytic trim region (PLATE_OUTER, PLATE_HOLES)."""
    spec = importlib.util.spec_from_file_location("make_samples", SAMPLES / "make_samples.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def plate():
    return load_scene(SAMPLES / "plate.json")


@pytest.fixture(scope="module")
def sphere():
    return load_scene(SAMPLES / "sphere.json")


@pytest.fixture(scope="module")
def hole_pixel(plate):
    """A pixel whose ray, with trims off, hits the plate inside the larger hole (nearest its
    centre), found from the renderer's own uv."""
    frame = render(plate, Options(trims=False), size=SIZE)
    on_plate = frame.hit & (plate.patch_surface[np.maximum(frame.patch, 0)] == 0) & (frame.patch >= 0)
    cu, cv, r = _make_samples().PLATE_HOLES[1]
    d = np.where(on_plate, np.hypot(frame.uv[..., 0] - cu, frame.uv[..., 1] - cv), np.inf)
    y, x = np.unravel_index(np.argmin(d), d.shape)
    assert d[y, x] < 0.5 * r, "no pixel of the 96x96 plate view sees the hole's middle"
    return int(x), int(y)


# ---- counts and import reports ------------------------------------------------------------

@pytest.mark.parametrize("name, want", [
    ("sphere", dict(patches=9, integral=1, rational=8, trimmed=0, plain=1, surfaces=1, surface_patches=8,
                    trimmed_surfaces=0, kinds={"rational bspline": [1, 8]})),
    ("plate", dict(patches=5, integral=5, rational=0, trimmed=4, plain=1, surfaces=1, surface_patches=4,
                   trimmed_surfaces=1, kinds={"bspline": [1, 4]})),
    ("teapot", dict(patches=33, integral=33, rational=0, trimmed=0, plain=33, surfaces=0, surface_patches=0,
                    trimmed_surfaces=0, kinds={})),
])
def test_scene_counts(name, want):
    scene = load_scene(SAMPLES / f"{name}.json")
    got = scene_counts(scene)
    assert got == want
    assert got["integral"] + got["rational"] == got["patches"] == got["plain"] + got["surface_patches"]
    lines = count_lines(got)
    assert f"{want['rational']} rational patch" in lines[1] and f"{want['trimmed']} trimmed patch" in lines[2]
    if want["surfaces"]:
        assert f"-> {want['surface_patches']} Bezier patches" in lines[3]
    else:
        assert len(lines) == 3  # no NURBS line for a scene of plain Bezier patches


def test_import_rows_obj_and_iges():
    rows = dict(import_rows(load_scene(SAMPLES / "plate.json").import_report["plate.obj"]))
    assert rows["format"] == "OBJ" and rows["surfaces"] == "1 (1 trimmed)" and rows["trim curves"] == "10"
    report = {"format": "iges", "system": "CAD 1", "units": "MM", "tolerance": 1e-8, "surfaces": 3, "trimmed": 2,
              "counts": {"converted": {144: 2, 128: 1}, "consumed": {142: 2, 126: 9},
                         "unsupported": {186: 1}, "non_geometry": {314: 1}},
              "unsupported": {186: 1, 143: 2},
              "failed": [{"de": 41, "type": 143, "reason": "surface of type 143 is not supported"}] * 2,
              "trim_widest_gap_rel": 0.003, "trim_widest_gap_de": 77, "time_s": 0.5}
    rows = dict(import_rows(report))
    assert rows["format"] == "IGES from CAD 1" and rows["units"] == "MM"
    assert rows["tolerance"].startswith("1e-08")
    assert rows["converted"] == "2 x 144, 1 x 128" and rows["unsupported"] == "2 x 143, 1 x 186"
    assert rows["failed"].startswith("2, e.g. DE 41 (type 143)")
    assert rows["non geometry"] == "1 x 314" and "DE 77" in rows["widest trim gap"]


def test_surface_location_names_the_iges_entity():
    from tracer.nurbs import SurfaceInfo
    iges = SurfaceInfo("144@31", "a.igs", "nurbs", True, True, (3, 3), (0, 1, 0, 1),
                       entity={"type": 144, "de": 31, "surface_type": 128, "surface_de": 3, "label": ""})
    assert surface_location(iges) == "IGES 144 DE 31, surface 128 DE 3"
    plain = SurfaceInfo("s", "/x/a.igs", "nurbs", True, False, (3, 3), (0, 1, 0, 1),
                        entity={"type": 128, "de": 5, "surface_type": 128, "surface_de": 5, "label": "FACE"})
    assert surface_location(plain) == "IGES 128 DE 5 'FACE'"
    obj = SurfaceInfo("s", "/x/s.obj", "bspline", False, False, (3, 3), (0, 1, 0, 1), entity={"line": 12})
    assert surface_location(obj) == "s.obj line 12"


def test_samples_are_listed_and_load():
    from viewer.ui_scene import sample_files
    names = [p.rsplit("/", 1)[-1] for p in sample_files()]
    assert {"teapot.json", "sphere.json", "torus.json", "plate.json"} <= set(names)
    for path in sample_files():
        assert load_scene(path).n_patches > 0
    assert sample_files(SAMPLES / "no-such-folder") == []


def test_scene_panel_summary_is_made_once_per_scene(sphere):
    """The Scene panel's lines over all patches (types, counts, bounds) are computed when a scene
    is first drawn, not every frame: a 100,000-patch scene must not cost a frame that long."""
    from collections import Counter

    from viewer import ui_scene
    scene = load_scene(SAMPLES / "teapot.json")
    kinds = Counter(("rational " if r else "") + ui_scene.DEGREE_NAMES.get((int(m), int(n)), f"degree {m}x{n}")
                    for m, n, r in zip(scene.degree_u, scene.degree_v, scene.rational))  # one by one
    assert ui_scene.patch_types(scene) == [f"{c} {k}" for k, c in kinds.most_common()] == ["32 bicubic", "1 bilinear"]
    assert ui_scene.patch_types(sphere) == ["8 rational biquadratic", "1 bilinear"]
    first = ui_scene.scene_summary(scene)
    assert first["types"] == "33 patches: 32 bicubic, 1 bilinear" and first["counts"] == count_lines(scene_counts(scene))
    calls = []
    real = ui_scene.scene_counts
    ui_scene.scene_counts = lambda sc: calls.append(sc) or real(sc)
    try:
        assert ui_scene.scene_summary(scene) is first and not calls  # the same scene: nothing recomputed
        assert ui_scene.scene_summary(sphere)["types"].startswith("9 patches") and calls == [sphere]
    finally:
        ui_scene.scene_counts = real


# ---- a hit's surface ----------------------------------------------------------------------

def test_sphere_hit_reports_the_nurbs_surface_and_its_parameters(sphere):
    t = trace_pixel(sphere, Options(), 48, 48, size=SIZE)
    assert t.hit and sphere.patch_surface[t.patch] == 0
    info = hit_surface(sphere, t.patch, t.uv)
    assert info["surface"] == 0 and info["name"] == "sphere" and info["kind"] == "rational bspline"
    assert info["location"] == "sphere.obj line 51" and info["entity"] == {"line": 51}
    assert info["rational"] and info["degree"] == [2, 2] and not info["trimmed"] and "loops" not in info
    first, count = info["surface_patches"]
    assert first <= t.patch < first + count == 8
    u0, u1, v0, v1 = info["patch_domain"]
    assert u0 <= t.uv[0] <= u1 and v0 <= t.uv[1] <= v1 and info["uv"] == [float(x) for x in t.uv]
    assert all(0.0 <= x <= 1.0 for x in info["patch_uv"])
    # uv is the NURBS parameter: the file's surface there is the hit point (float32 hit: 1e-5).
    surface = load_obj(SAMPLES / "sphere.obj").surfaces[0].surface
    assert np.allclose(surface.evaluate(*t.uv), t.position, atol=1e-5)
    assert math.isclose(np.linalg.norm(t.position), 1.0, abs_tol=1e-5)  # radius 1
    rows = dict(summary_rows(info))
    assert rows["from"] == "sphere.obj line 51" and rows["trims"] == "none"


def test_plain_patch_hit_has_no_surface(sphere):
    info = hit_surface(sphere, 8, (0.25, 0.5))  # the floor
    assert info["surface"] == -1 and info["object"] == "floor" and info["patch_uv"] == [0.25, 0.5]
    assert "floor" in dict(summary_rows(info))["surface"]
    assert hit_surface(sphere, -1, (0, 0)) is None


def test_plate_hit_has_its_trim_loops(plate):
    t = trace_pixel(plate, Options(), *PLATE_PIXEL, size=SIZE)
    assert t.hit and t.patch == 1
    info = hit_surface(plate, t.patch, t.uv)
    assert info["trimmed"] and info["inside"] and info["location"] == "plate.obj line 119"
    assert [loop["kind"] for loop in info["loops"]] == ["trim", "hole", "hole"]
    for loop, want in zip(info["loops"], loops_for_plot(plate.trims, 0)):
        assert np.array_equal(loop["points"], want["points"])
        assert np.array_equal(loop["points"][0], loop["points"][-1])  # closed polylines
    # the loops are the sample's analytic region: hole loops on their circles
    ms = _make_samples()
    for loop, (cu, cv, r) in zip(info["loops"][1:], ms.PLATE_HOLES):
        assert np.allclose(np.hypot(loop["points"][:, 0] - cu, loop["points"][:, 1] - cv), r, atol=1e-3)
    dumped = json.loads(json.dumps(info_json(info)))
    assert dumped["loops"][1]["kind"] == "hole" and len(dumped["loops"][1]["points"][0]) == 2
    assert "inside the kept region" in dict(summary_rows(info))["trims"]


def test_hit_in_a_hole_with_trims_off_is_flagged(plate, hole_pixel):
    cu, cv, r = _make_samples().PLATE_HOLES[1]
    t = trace_pixel(plate, Options(trims=False), *hole_pixel, size=SIZE)
    info = hit_surface(plate, t.patch, t.uv)
    assert info["surface"] == 0 and math.hypot(t.uv[0] - cu, t.uv[1] - cv) < r
    assert info["trimmed"] and not info["inside"]
    assert "trimmed away" in dict(summary_rows(info))["trims"]
    kept = trace_pixel(plate, Options(), *hole_pixel, size=SIZE)  # trims on: through the hole
    assert not kept.hit or plate.patch_surface[kept.patch] != 0


# ---- the window under Xvfb ----------------------------------------------------------------

@pytest.fixture(scope="module")
def warm_kernels(plate):
    """Compile (or load) the kernels the window uses, outside its time limit."""
    from tracer.render import reference_frame
    reference_frame(plate, render(plate, Options(), size=(4, 4)))
    trace_pixel(plate, Options(), 2, 2, size=(4, 4))
    trace_pixel(plate, Options(precision="f64", criterion="float"), 2, 2, size=(4, 4))


def test_inspector_dump_has_the_plate_surface(xvfb, warm_kernels, tmp_path, plate):
    dump = tmp_path / "trace.json"
    x, y = PLATE_PIXEL
    code, _, err = run_view(xvfb, [SAMPLES / "plate.json", "--size", "96x96",
                                   "--click", f"{x},{y}", "--dump-inspector", dump], tmp_path)
    assert code == 0, err
    got = json.loads(dump.read_text())
    assert got["hit"] and got["patch"] == 1
    s = got["surface"]
    assert s["surface"] == 0 and s["name"] == "plate" and s["location"] == "plate.obj line 119"
    assert s["uv"] == got["uv"] and s["trimmed"] and s["inside"]
    u0, u1, v0, v1 = s["patch_domain"]
    assert u0 <= s["uv"][0] <= u1 and v0 <= s["uv"][1] <= v1
    assert [loop["kind"] for loop in s["loops"]] == ["trim", "hole", "hole"]
    # the same kernel on the same ray: the headless surface info, bit for bit
    t = trace_pixel(plate, Options(), x, y, size=SIZE)
    assert s == json.loads(json.dumps(info_json(hit_surface(plate, t.patch, t.uv))))


def test_trims_off_in_the_window_shows_the_hole_hit(xvfb, warm_kernels, tmp_path, hole_pixel):
    dump = tmp_path / "trace.json"
    code, status, err = run_view(xvfb, [SAMPLES / "plate.json", "--size", "96x96", "--no-trims",
                                        "--click", "{},{}".format(*hole_pixel), "--dump-inspector", dump], tmp_path)
    assert code == 0, err
    assert status["options"]["trims"] is False
    s = json.loads(dump.read_text())["surface"]
    assert s["surface"] == 0 and s["trimmed"] and s["inside"] is False
