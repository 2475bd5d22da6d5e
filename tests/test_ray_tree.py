"""A pixel's ray tree (tracer/ray_tree.py) is what the full render traced and computed there:
the same rays in the same order with the same answers, the same shadow, shadow rays and
radiance; each ray's subdivision trace finds what its batch kernel found."""
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import scenes as S  # noqa: E402
from psrt.cli import main  # noqa: E402
from tracer.camera import view_of  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.lighting import Lighting  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.ray_batch import RB_D, RB_O  # noqa: E402
from tracer.ray_tree import TESTS, ray_tree, trace_steps  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import load_scene  # noqa: E402

TEAPOT = Path(__file__).resolve().parents[1] / "sample_models" / "teapot.json"
SIZE = (24, 24)


def quad(x0, x1, y0, y1, z):
    return {"degree": [1, 1], "points": [[x0, y0, z], [x1, y0, z], [x0, y1, z], [x1, y1, z]]}


def glass_scene():
    """A glass sheet over a red square on a half-mirror floor, under a small sphere light."""
    return S.load({"objects": [{"patches": [quad(-4, 4, -4, 4, 0.0)], "material": "mirror"},
                               {"patches": [quad(-0.5, 0.5, -0.5, 0.5, 0.6)], "material": "red"},
                               {"patches": [quad(-1.5, 1.5, -1.5, 1.5, 1.5)], "material": "glass"}],
                   "materials": {"mirror": {"color": [0.3, 0.3, 0.3], "reflect": 0.5},
                                 "red": {"color": [1, 0, 0]},
                                 "glass": {"color": [0.1, 0.1, 0.1], "transmit": 0.8, "ior": 1.5}},
                   "lights": [{"type": "sphere", "center": [1, -1, 5], "radius": 0.3, "samples": 4}],
                   "camera": {"eye": [0, -5, 4], "look_at": [0, 0, 0.5], "up": [0, 0, 1], "fov_deg": 40}})


def rendered_rays(scene, opts, size):
    """The full render, and per pixel (x, y) the rays its lighting traced, as (kind, code, light,
    origin, direction, hit, patch) in the order traced (one thread: units one after another)."""
    seen = {}
    shade_unit = Lighting.shade_unit

    def watching(self, frame, pixels, ids=None):
        hit = frame.hit[pixels[:, 0], pixels[:, 1]]
        where = [(int(x), int(y)) for y, x in pixels[hit]]

        def record(kind, **b):
            if kind == "samples":
                return
            for i, p in enumerate(b["pix"]):
                if kind == "proven_lit":
                    row = ("penumbra_test", b["code"][i], b["light"], b["origin"][i], None, not b["lit"][i], -1)
                elif kind == "proven_umbra":
                    row = ("umbra_test", b["code"][i], b["light"], b["origin"][i], None, b["patch"][i] >= 0,
                           b["patch"][i])
                elif kind == "shadow":
                    row = ("shadow", b["code"][i], b["light"], b["origin"][i], b["rays"][i, RB_D:RB_D + 3],
                           b["occluded"][i], -1)
                else:
                    code = b["code"][i]
                    row = ("reflected" if code % 2 == 0 else "refracted", code, -1, b["origin"][i], b["direction"][i],
                           b["hit"].hit[0, i], b["hit"].patch[0, i])
                seen.setdefault(where[p], []).append(row)

        self.recorder = record
        return shade_unit(self, frame, pixels, ids)

    Lighting.shade_unit = watching
    try:
        frame = render(scene, opts.with_(threads=1), size=size)
    finally:
        Lighting.shade_unit = shade_unit
    return frame, seen


def tree_rows(tree):
    return [(r.kind, r.code, r.light, r.origin, None if r.kind in TESTS else r.direction, r.hit,
             r.patch if r.kind in ("reflected", "refracted", "umbra_test") else -1) for r in tree.rays[1:]]


def same_rows(a, b) -> bool:
    return len(a) == len(b) and all(
        x[:3] == y[:3] and np.array_equal(x[3], y[3]) and (x[4] is None) == (y[4] is None)
        and (x[4] is None or np.array_equal(x[4], np.asarray(y[4], float))) and bool(x[5]) == bool(y[5])
        and int(x[6]) == int(y[6]) for x, y in zip(a, b))


def check_pixels(scene, opts, pixels, size=SIZE):
    """Each pixel's ray tree against the full render; returns the trees."""
    frame, seen = rendered_rays(scene, opts, size)
    geom = prepare(scene, opts.precision)
    trees = []
    for x, y in pixels:
        tree = ray_tree(scene, opts, x, y, size=size, geometry=geom)
        primary = tree.rays[0]
        assert primary.kind == "primary" and primary.hit == frame.hit[y, x] and primary.patch == frame.patch[y, x]
        assert tree.shadow_rays == frame.shadow_rays[y, x] == sum(r.kind == "shadow" for r in tree.rays)
        if frame.shadow is None:  # shadows off
            assert tree.shadow is None and tree.penumbra == -1
        else:
            assert np.array_equal(np.float32(np.nan if tree.shadow is None else tree.shadow), frame.shadow[y, x],
                                  equal_nan=True), (x, y)
            assert tree.penumbra == frame.penumbra[y, x]
        want = frame.radiance[y, x]
        got = want * np.nan if tree.radiance is None else tree.radiance.astype(np.float32)
        assert np.array_equal(got, want, equal_nan=True), (x, y)  # bit for bit
        assert same_rows(tree_rows(tree), seen.get((x, y), [])), (x, y)
        trees.append(tree)
    return trees


def test_teapot_trees_are_the_render_s_rays():
    scene = load_scene(TEAPOT)
    pixels = [(x, y) for y in range(1, SIZE[1], 3) for x in range(1, SIZE[0], 3)]
    trees = check_pixels(scene, Options(light_samples=64), pixels)  # enough samples for umbra's lit test
    rays = [r for t in trees for r in t.rays]
    assert any(r.kind == "umbra_test" and r.hit for r in rays)
    kinds = {k: [r for r in rays if r.kind == k] for k in ("shadow", "penumbra_test", "reflected")}
    assert any(r.hit for r in kinds["shadow"]) and any(not r.hit for r in kinds["shadow"])
    assert any(not r.hit for r in kinds["penumbra_test"]) and any(r.hit for r in kinds["penumbra_test"])
    assert any(r.hit for r in kinds["reflected"])
    assert any(0.0 < t.shadow < 1.0 for t in trees if t.shadow is not None)  # a pixel in the penumbra
    assert any(not t.rays[0].hit and len(t.rays) == 1 for t in trees)  # the background: the primary alone


def test_glass_and_mirror_trees_under_other_options():
    scene = glass_scene()
    opts = Options(penumbra="off", origin="shift", max_depth=2)
    pixels = [(x, y) for y in range(2, SIZE[1], 4) for x in range(2, SIZE[0], 4)]
    trees = check_pixels(scene, opts, pixels)
    rays = [r for t in trees for r in t.rays]
    deep = [r for r in rays if r.kind == "refracted" and r.depth == 2]  # code 2c + 1 of a depth-1 vertex
    assert deep and all(r.parent == r.code // 2 for r in deep)
    assert any(r.kind == "shadow" and r.depth == 2 for r in rays)
    assert all(r.corner is None for r in rays)  # no box corner with the shift method
    assert all(r.depth <= 2 for r in rays)


TWO_LIGHTS = [{"type": "point", "position": [-4, -3, 6], "intensity": 0.5},
              {"type": "rect", "corner": [3, -3, 7], "edge1": [1, 0, 0], "edge2": [0, 1, 0], "samples": 4}]


@pytest.mark.parametrize("lights, settings", [(TWO_LIGHTS, {"penumbra": "expanded", "light_samples": 3}),
                                              (None, {}), (TWO_LIGHTS, {"shadows": False, "trivial_tests": False})],
                         ids=["two-lights", "headlight", "no-shadows"])
def test_glass_teapot_trees_with_other_lights(lights, settings):
    data = {"objects": [{"file": S.TEAPOT_BPT, "material": "glass"},
                        {"patches": [quad(-6, 6, -6, 6, 0.0)], "material": "floor"}],
            "materials": {"glass": {"color": [0.2, 0.2, 0.2], "transmit": 0.5, "reflect": 0.2},
                          "floor": {"reflect": 0.3}},
            "camera": {"eye": [6, -9, 5], "look_at": [0, 0, 1.5], "up": [0, 0, 1], "fov_deg": 40}}
    if lights:
        data["lights"] = lights
    pixels = [(x, y) for y in range(1, SIZE[1], 4) for x in range(1, SIZE[0], 4)]
    trees = check_pixels(S.load(data), Options(**settings), pixels)
    lights_seen = {e["light"] for t in trees for e in t.lights}
    assert lights_seen == set(range(len(lights or [None])))
    assert any(r.kind == "refracted" for t in trees for r in t.rays)


def test_box_corner_and_subdivision_traces_of_each_ray():
    scene = glass_scene()
    opts = Options(penumbra="tmax")  # this pixel is in the umbra: no shadow rays with penumbra 'umbra'
    geom = prepare(scene, "f32")
    tree = ray_tree(scene, opts, 12, 10, size=SIZE, geometry=geom)
    assert {"shadow", "reflected", "refracted"} <= {r.kind for r in tree.rays}
    trace_steps(tree, scene, geom, opts, view_of(scene), SIZE)
    for r in tree.rays[1:]:
        lo, hi = r.from_box
        assert np.all((r.corner == lo) | (r.corner == hi))  # a corner of the box the ray leaves
        outward = np.where(r.corner == hi, r.origin - hi, lo - r.origin)
        assert np.all(outward > 0) and np.all(outward < 1e-4)  # moved out of it by a few ulps
        if r.kind in TESTS:
            assert r.steps is None
            continue
        assert r.steps.effort == r.effort and r.steps.hit == r.hit, r.kind
        if r.kind != "shadow" and r.hit:
            assert r.steps.patch == r.patch and np.array_equal(r.steps.box_min, r.box_min)
    assert tree.rays[0].steps.hit and tree.rays[0].steps.patch == tree.rays[0].patch


def test_trace_cli_adds_the_ray_tree_under_a_new_key(tmp_path):
    plain, rays = tmp_path / "plain.json", tmp_path / "rays.json"
    args = ["trace", str(TEAPOT), "--pixel", "11,14", "--size", "24x24", "-q"]
    assert main(args + ["-o", str(plain)]) == 0 and main(args + ["-o", str(rays), "--ray-steps"]) == 0
    a, b = json.loads(plain.read_text()), json.loads(rays.read_text())
    assert "ray_tree" not in a and set(b) == set(a) | {"ray_tree"}
    assert all(b[k] == a[k] for k in a)  # the contract's keys as they were
    tree = b["ray_tree"]
    want = ray_tree(load_scene(TEAPOT), Options(), 11, 14, size=SIZE)
    assert tree["pixel"] == [11, 14] and len(tree["rays"]) == len(want.rays) > 1
    assert tree["shadow_rays"] == want.shadow_rays and tree["shadow"] == want.shadow
    first = tree["rays"][0]
    assert first["kind"] == "primary" and first["trace"]["steps"] == a["steps"]
    for got, ray in zip(tree["rays"], want.rays):
        assert got["kind"] == ray.kind and got["origin"] == ray.ray[RB_O:RB_O + 3].tolist()
        assert got["outcome"] == ray.outcome() and ("trace" in got) == (ray.kind not in TESTS)


@pytest.mark.parametrize("pixel", [(-1, 0), (24, 3)])
def test_a_pixel_outside_the_image_is_refused(pixel):
    with pytest.raises(ValueError, match="outside"):
        ray_tree(load_scene(TEAPOT), Options(), *pixel, size=SIZE)
