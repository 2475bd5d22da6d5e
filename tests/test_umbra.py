"""Umbra detection (tracer/umbra.py): a patch proven to cover an area light seen from a point does
cover it (checked against the exact projection of flat patches), a clear cover is proven, and
renders with penumbra 'umbra' are bit-identical to tracing every sample."""
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import scenes as S  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.ray_tree import ray_tree  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import Light, load_scene  # noqa: E402
from tracer.umbra import UmbraTest  # noqa: E402

SIZE = (40, 40)
HEIGHT = 1.0  # the flat patch's plane z = HEIGHT; the shadow rays leave the origin (0, 0, 0)


def flat_patch(rng, degree=3):
    """A patch whose image is exactly the square [-1, 1]^2 at z = HEIGHT: boundary points spread
    unevenly along the square's edges, inner points jittered within the plane."""
    t = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0.1, 0.9, degree - 1)]))
    x, y = np.meshgrid(2 * t - 1, 2 * t - 1, indexing="ij")
    inner = (slice(1, -1), slice(1, -1))
    x[inner] += rng.uniform(-0.1, 0.1, x[inner].shape)
    y[inner] += rng.uniform(-0.1, 0.1, y[inner].shape)
    return np.stack([x, y, np.full_like(x, HEIGHT)], axis=-1)


def lights(rng, count):
    """Sphere, segment and rect lights above the plane, some inside the square's cone, some across
    its edges."""
    out = []
    for _ in range(count):
        c = np.array([*rng.uniform(-3.5, 3.5, 2), rng.uniform(2.0, 4.0)])
        size = rng.uniform(0.05, 0.8)
        a, b = rng.normal(size=3), rng.normal(size=3)
        kind = rng.integers(3)
        if kind == 0:
            out.append(Light("sphere", 1.0, np.ones(3), center=c, radius=size))
        elif kind == 1:
            out.append(Light("segment", 1.0, np.ones(3), a=c - size * a / 2, b=c + size * a / 2))
        else:
            e1 = size * a / np.linalg.norm(a)
            e2 = np.cross(a, b)
            e2 = size * e2 / np.linalg.norm(e2)
            out.append(Light("rect", 1.0, np.ones(3), corner=c - (e1 + e2) / 2, edge1=e1, edge2=e2))
    return out


def light_points(light, rng, n=400):
    """Points spread over the light (a sphere's surface, where its cone's edge lies)."""
    if light.type == "sphere":
        d = rng.normal(size=(n, 3))
        return light.center + light.radius * d / np.linalg.norm(d, axis=1, keepdims=True)
    s = rng.uniform(0, 1, (n, 2))
    if light.type == "segment":
        return light.a + s[:, :1] * (light.b - light.a)
    return light.corner + s[:, :1] * light.edge1 + s[:, 1:] * light.edge2


def margin_inside(light, rng):
    """How far inside the square [-1, 1]^2 the rays from the origin to the light cross the plane
    z = HEIGHT (negative: some cross outside), over points on the light and its outline."""
    p = light_points(light, rng)
    if light.type == "rect":  # the outline: where the extremes are
        s = np.linspace(0, 1, 200)[:, None]
        c, e1, e2 = light.corner, light.edge1, light.edge2
        p = np.concatenate([p, c + s * e1, c + e1 + s * e2, c + s * e2, c + e2 + s * e1])
    elif light.type == "segment":
        p = np.concatenate([p, [light.a, light.b]])
    xy = p[:, :2] * (HEIGHT / p[:, 2:])
    return float(np.min(1.0 - np.abs(xy)))


@pytest.mark.parametrize("degree", [1, 3])
def test_a_flat_patch_is_proven_to_cover_exactly_the_lights_its_square_holds(degree):
    rng = np.random.default_rng(7 + degree)
    scene = S.patches_scene([flat_patch(rng, degree)])
    test = UmbraTest(scene, prepare(scene))
    origin = np.zeros((1, 3))
    proven = clear = 0
    for light in lights(rng, 150):
        covered = test(light, origin, np.ones(1, bool))[0] >= 0
        inside = margin_inside(light, np.random.default_rng(1))
        if covered:  # sound: every ray to the light crosses the square
            assert inside > 0.0, (light, inside)
            proven += 1
        if inside > 0.02:  # and complete, away from the edges
            assert covered, (light, inside)
            clear += 1
    assert proven >= 20 and clear >= 20


def test_the_patch_must_lie_between_the_point_and_the_light():
    rng = np.random.default_rng(3)
    scene = S.patches_scene([flat_patch(rng)])
    test = UmbraTest(scene, prepare(scene))
    sphere = Light("sphere", 1.0, np.ones(3), center=np.array([0.1, 0.0, 3.0]), radius=0.3)
    ask = np.ones(1, bool)
    assert test(sphere, np.zeros((1, 3)), ask)[0] == 0
    behind = Light("sphere", 1.0, np.ones(3), center=np.array([0.1, 0.0, 0.5]), radius=0.1)
    assert test(behind, np.zeros((1, 3)), ask)[0] == -1  # the light is nearer than the patch
    touching = Light("sphere", 1.0, np.ones(3), center=np.array([0.1, 0.0, 1.2]), radius=0.3)
    assert test(touching, np.zeros((1, 3)), ask)[0] == -1  # the light reaches through the patch
    assert test(sphere, np.array([[0.0, 0.0, 1.0]]), ask)[0] == -1  # the origin on the patch
    assert test(sphere, np.zeros((1, 3)), np.zeros(1, bool))[0] == -1  # not asked


def test_trimmed_patches_are_no_candidates():
    scene = load_scene(str(S.SAMPLES / "plate.json"))
    test = UmbraTest(scene, prepare(scene))
    trimmed = np.unique(prepare(scene).leaf_patch[prepare(scene).patch_trim >= 0])
    assert len(trimmed) and not test.candidate[trimmed].any()


def teapot_light(light, samples=8):
    scene = S.load({"objects": [{"file": S.TEAPOT_BPT}, {"patches": [{"degree": [1, 1], "points": [
        [-6, -6, 0], [6, -6, 0], [-6, 6, 0], [6, 6, 0]]}]}], "materials": {},
        "lights": [dict(light, samples=samples)],
        "camera": {"eye": [6, -9, 5], "look_at": [0, 0, 1.5], "up": [0, 0, 1], "fov_deg": 40}})
    return scene


SPHERE = {"type": "sphere", "center": [4, -3, 7], "radius": 0.6}
SEGMENT = {"type": "segment", "a": [3, -4, 7], "b": [5, -2, 7]}
RECT = {"type": "rect", "corner": [3, -4, 7], "edge1": [1.2, 0, 0], "edge2": [0, 0.8, 0.3]}


@pytest.mark.parametrize("light, settings", [(SPHERE, {}), (SEGMENT, {}), (RECT, {}),
                                             (SPHERE, {"criterion": "adaptive"}),
                                             (SPHERE, {"split": "cross", "precision": "f64"})],
                         ids=["sphere", "segment", "rect", "adaptive", "cross-f64"])
def test_umbra_is_bit_identical_to_tracing_every_sample(light, settings):
    scene = teapot_light(light)
    off = Options(penumbra="off", **settings)
    base = render(scene, off, size=SIZE)
    tmax = render(scene, off.with_(penumbra="tmax"), size=SIZE)
    fast = render(scene, off.with_(penumbra="umbra"), size=SIZE)
    for name in ("radiance", "shadow"):
        assert np.array_equal(getattr(base, name), getattr(fast, name), equal_nan=True), name
    proven = (fast.penumbra == 2) & (base.shadow_rays > 0)  # in the umbra, and not trivially
    assert proven.sum() >= 10 and np.all(fast.shadow[proven] == 0.0) and np.all(fast.shadow_rays[proven] == 0)
    assert np.all(fast.shadow_rays <= base.shadow_rays) and fast.shadow_rays.sum() < base.shadow_rays.sum()
    assert np.all(tmax.penumbra[fast.penumbra == 0] == 0)  # proven lit by tmax's test too
    assert fast.extras["lighting"]["umbra_tests"] > 0


@pytest.mark.parametrize("light", [SPHERE, SEGMENT, RECT], ids=["sphere", "segment", "rect"])
def test_umbra_runs_the_lit_test_where_it_pays(light):
    """With the samples of a point traced as one bundle, umbra's lit test runs only for lights with
    WORTH_TESTING samples per unit of their angular size; where it runs, it proves what tmax's
    proves; where it does not, the points are sampled, and the image is the same."""
    pays = {"sphere": 100, "segment": 160, "rect": 100}[light["type"]]  # 700 x size at the teapot
    for samples, runs in ((8, False), (pays, True)):
        scene = teapot_light(light, samples)
        tmax = render(scene, Options(penumbra="tmax"), size=SIZE)
        fast = render(scene, Options(penumbra="umbra"), size=SIZE)
        assert np.array_equal(fast.radiance, tmax.radiance, equal_nan=True)
        if runs:
            assert np.array_equal(fast.penumbra == 0, tmax.penumbra == 0) and (fast.penumbra == 0).sum() > 50
            assert np.all(fast.shadow_rays <= tmax.shadow_rays)
        else:
            assert not (fast.penumbra == 0).any() and (tmax.penumbra == 0).sum() > 50


def test_the_ray_tree_shows_the_umbra_test_and_its_patch():
    scene = teapot_light(SPHERE)
    opts = Options(penumbra="umbra")
    frame = render(scene, opts, size=SIZE)
    ys, xs = np.nonzero((frame.penumbra == 2) & (frame.patch == frame.patch.max()))  # on the floor
    tree = ray_tree(scene, opts, int(xs[0]), int(ys[0]), size=SIZE)
    tests = [r for r in tree.rays if r.kind == "umbra_test"]
    assert len(tests) == 1 and tests[0].hit and 0 <= tests[0].patch < frame.patch.max()
    assert "proven umbra" in tests[0].outcome() and tree.shadow_rays == 0 and tree.penumbra == 2
    assert [e["proven_umbra"] for e in tree.lights if e["code"] == 1] == [True]
    assert not any(r.kind == "shadow" and r.code == 1 for r in tree.rays)
