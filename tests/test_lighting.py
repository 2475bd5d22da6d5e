"""Secondary rays (tracer/lighting.py): shadows without acne or leaks at any scale, the fast
penumbra's bit-identical images, reproducible light samples, reflection and refraction."""
import math
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import scenes as S  # noqa: E402
from tracer import light_samples as LS  # noqa: E402
from tracer.cone_search import cone_meets  # noqa: E402
from tracer.ray import RAY_LEN, make_ray, slab  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.origins import robust_origins  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import SceneError, Light  # noqa: E402

SIZE = (40, 40)


def quad(x0, x1, y0, y1, z):
    return {"degree": [1, 1], "points": [[x0, y0, z], [x1, y0, z], [x0, y1, z], [x1, y1, z]]}


def tilt(angle):
    """Rotation about the x axis by `angle` radians (3x3)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


HIGH, GRAZING = ((0.3, 0.2, 2.0), 0.0, 0.5), ((20.0, 0.1, 1.2), 0.5, 0.05)  # light, occluder's x and height


def shadow_scene(scale, offset, case, rotation):
    """A floor [-1, 1]^2 at z = 0 and an occluding square of side 0.5 centred at (x, 0, height) under
    a point light, all rotated, scaled and moved: (scene, the world-to-canonical map)."""
    light, cx, h = case
    m = np.eye(4)
    m[:3, :3] = scale * rotation
    m[:3, 3] = offset
    transform = m.ravel().tolist()
    world = lambda p: (m[:3, :3] @ np.asarray(p, float)) + m[:3, 3]  # noqa: E731
    eye = world([0.2, -2.2, 2.6])
    data = {"objects": [{"patches": [quad(-1, 1, -1, 1, 0.0)], "transform": transform},
                        {"patches": [quad(cx - 0.25, cx + 0.25, -0.25, 0.25, h)], "transform": transform}],
            "lights": [{"type": "point", "position": world(light).tolist()}],
            "materials": {"m": {"color": [0.8, 0.8, 0.8]}},
            "camera": {"eye": eye.tolist(), "look_at": world([0, 0, 0]).tolist(),
                       "up": (m[:3, :3] @ [0, 0, 1.0]).tolist(), "fov_deg": 45}}
    inverse = lambda p: np.linalg.solve(m[:3, :3], (p - m[:3, 3]).T).T  # noqa: E731
    return S.load(data, f"shadow x{scale:g} +{offset}"), inverse


def expected_shadow(p, case):
    """1 where the floor point p (canonical, z = 0) sees the light past the occluder, else 0; and the
    distance (canonical units) from the shadow's edge."""
    light, cx, h = case
    light = np.asarray(light, float)
    k = light[2] / (light[2] - h)  # the occluder's square projected from the light onto z = 0
    lo = light[:2] + (np.array([cx - 0.25, -0.25]) - light[:2]) * k
    hi = light[:2] + (np.array([cx + 0.25, 0.25]) - light[:2]) * k
    inside = np.all((p[:, :2] > lo) & (p[:, :2] < hi), axis=1)
    edge = np.min(np.abs(np.concatenate([p[:, :2] - lo, p[:, :2] - hi], axis=1)), axis=1)
    return np.where(inside, 0.0, 1.0), edge


@pytest.mark.parametrize("scale, offset", [(1.0, (0, 0, 0)), (1e-4, (0, 0, 0)), (1e4, (0, 0, 0)),
                                           (1e-4, (1e5, 0, 0)), (1.0, (1e5, -1e5, 1e5))])
@pytest.mark.parametrize("case", [HIGH, GRAZING], ids=["high", "grazing"])
def test_no_acne_and_no_leaks_at_any_scale(scale, offset, case):
    scene, canonical = shadow_scene(scale, np.asarray(offset, float), case, tilt(0.3))
    frame = render(scene, Options(reflections=False), size=SIZE)
    p = canonical(frame.position[frame.hit])
    on_floor = np.abs(p[:, 2]) < 0.01
    on_top = p[:, 2] > 0.6 * case[2]
    want, edge = expected_shadow(p[on_floor], case)
    clear = edge > 0.02  # pixels are about 0.05 canonical units: leave the edge's pixels alone
    got = frame.shadow[frame.hit]
    assert on_floor.sum() > 500 and clear.sum() > 400 and (want[clear] == 0).sum() > 20
    assert np.array_equal(got[on_floor][clear], want[clear]), "acne (0 where lit) or leaks (1 in shadow)"
    assert np.all(got[on_top] == 1.0), "the occluder's lit face shadows itself"


def test_fixed_epsilon_shows_acne_where_box_corner_has_none():
    scene, _ = shadow_scene(1e4, np.array([1e5, 0, 0]), GRAZING, tilt(0.3))
    small = Options(reflections=False, origin="fixed_epsilon", origin_epsilon=1e-9)
    corner = render(scene, Options(reflections=False), size=SIZE)
    eps = render(scene, small, size=SIZE)
    top = corner.shadow == 1.0
    assert np.mean(eps.shadow[top] < 1.0) > 0.05  # a world-size epsilon too small for this scale


def teapot_light(samples=8, penumbra="off", **kw):
    scene = S.load({"objects": [{"file": S.TEAPOT_BPT}, {"patches": [quad(-6, 6, -6, 6, 0.0)]}],
                    "materials": {}, "lights": [{"type": "sphere", "center": [4, -3, 7], "radius": 0.6,
                                                 "samples": samples}],
                    "camera": {"eye": [6, -9, 5], "look_at": [0, 0, 1.5], "up": [0, 0, 1], "fov_deg": 40}})
    return scene, Options(penumbra=penumbra, **kw)


@pytest.mark.parametrize("method, settings", [("expanded", {}), ("tmax", {}), ("tmax", {"split": "cross"}),
                                              ("tmax", {"criterion": "fixed", "fixed_size": 0.05})],
                         ids=["expanded", "tmax", "tmax-samples-decide", "tmax-fixed"])
def test_fast_penumbra_is_bit_identical_and_traces_fewer_rays(method, settings):
    scene, off = teapot_light(**settings)
    base = render(scene, off, size=SIZE)
    fast = render(scene, off.with_(penumbra=method), size=SIZE)
    for name in ("radiance", "shadow"):
        assert np.array_equal(getattr(base, name), getattr(fast, name), equal_nan=True), name
    lit = fast.penumbra == 0
    assert lit.sum() > 50 and np.all(fast.shadow[lit] == 1.0)
    assert np.all(fast.shadow_rays[lit] == 0) and fast.shadow_rays.sum() < 0.9 * base.shadow_rays.sum()
    assert np.all(base.penumbra[base.hit] == -1)
    assert np.any((base.shadow > 0.0) & (base.shadow < 1.0))  # there is a penumbra


def test_triviality_tests_decide_rays_behind_the_surface_and_change_nothing():
    scene, opts = teapot_light(samples=4)
    with_tests = render(scene, opts, size=SIZE)
    without = render(scene, opts.with_(trivial_tests=False), size=SIZE)
    assert np.array_equal(with_tests.radiance, without.radiance, equal_nan=True)
    decided = with_tests.extras["lighting"]["trivially_decided"]
    assert decided > 0 and without.extras["lighting"]["trivially_decided"] == 0
    assert without.shadow_rays.sum() - with_tests.shadow_rays.sum() == decided


def test_renders_are_reproducible_across_threads_orders_and_tiles():
    scene, opts = teapot_light(samples=4, penumbra="tmax")
    a = render(scene, opts.with_(threads=1), size=SIZE)
    b = render(scene, opts.with_(threads=2, order="peano", tile_size=8), size=SIZE)
    assert np.array_equal(a.radiance, b.radiance, equal_nan=True)
    assert np.array_equal(a.shadow_rays, b.shadow_rays)


def test_cone_meets_every_box_a_ray_into_the_light_meets():
    rng = np.random.default_rng(3)
    ray = np.zeros(RAY_LEN)
    for _ in range(400):
        o, c = rng.normal(size=3), rng.normal(size=3) * 3
        half = rng.uniform(0, 0.5, 3)
        lo = rng.normal(size=3) * 2
        box = np.concatenate([lo, lo + rng.uniform(0, 1, 3)])
        make_ray(ray, *o, *(c - o), 0.0, 0.0, 0.0)
        meets = cone_meets(box, 0.0, 0.0, 0.0, ray, half, 1.0)[0]
        for e in rng.uniform(-1, 1, (20, 3)) * half:
            make_ray(ray, *o, *(c + e - o), 0.0, 0.0, 0.0)
            ok, t_in, _ = slab(box, 0.0, 0.0, 0.0, ray)
            assert not (ok and t_in < 1.0) or meets
        make_ray(ray, *o, *(c - o), 0.0, 0.0, 0.0)
        beyond = max(o[0], c[0] + half[0]) + 0.1  # every point of the cone has a smaller x
        far = np.array([beyond, -9.0, -9.0, beyond + 1.0, 9.0, 9.0])
        assert not cone_meets(far, 0.0, 0.0, 0.0, ray, half, 1.0)[0]


def test_light_samples_are_stratified_seeded_and_on_the_light():
    seed = LS.seeds(np.arange(5), 1, 0)
    assert np.array_equal(seed, LS.seeds(np.arange(5), 1, 0)) and len(set(seed.tolist())) == 5
    u = LS.stratified(seed, 9, 2)
    cells = np.floor(u * 3).astype(int)
    assert all(len({tuple(c) for c in cells[k]}) == 9 for k in range(5))  # one sample per cell
    rect = Light("rect", 1.0, np.ones(3), corner=np.zeros(3), edge1=np.array([2.0, 0, 0]), edge2=np.array([0, 1.0, 0]))
    pts = LS.points(rect, np.zeros((5, 3)) + [0, 0, 5], seed, 9)
    assert np.all((pts[..., 0] >= 0) & (pts[..., 0] <= 2) & (pts[..., 1] >= 0) & (pts[..., 1] <= 1))
    ball = Light("sphere", 1.0, np.ones(3), center=np.array([1.0, 2, 3]), radius=0.5)
    pts = LS.points(ball, np.zeros((5, 3)), seed, 16)
    assert np.all(np.linalg.norm(pts - ball.center, axis=-1) <= 0.5 + 1e-12)


def test_box_corner_origin_moves_whole_ulps_outwards():
    lo, hi = np.array([[1.0, 2.0, 3.0]]), np.array([[1.5, 2.5, 3.5]])
    o = robust_origins("box_corner", lo=lo, hi=hi, position=(lo + hi) / 2, normal=np.array([[0.6, -0.8, 0.0]]),
                       ulp=np.full((1, 3), 2.0 ** -20), ulps=7)
    assert np.array_equal(o, [[1.5 + 7 * 2.0 ** -20, 2.0 - 7 * 2.0 ** -20, 3.5 + 7 * 2.0 ** -20]])


def test_mirror_floor_reflects_and_clear_glass_shows_what_is_behind():
    red = {"patches": [quad(-0.5, 0.5, -0.5, 0.5, 1.0)], "material": "red"}
    data = {"objects": [{"patches": [quad(-4, 4, -4, 4, 0.0)], "material": "mirror"}, red],
            "materials": {"mirror": {"color": [0.1, 0.1, 0.1], "reflect": 1.0}, "red": {"color": [1, 0, 0]}},
            "lights": [{"type": "point", "position": [0, 0, 5]}],
            "camera": {"eye": [0, -6, 3], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 40}}
    mirror = render(S.load(data), Options(), size=SIZE)
    floor = mirror.hit & (mirror.patch == 0)
    seen = mirror.radiance[floor]
    assert np.any(seen[:, 0] > 3 * seen[:, 1] + 0.02)  # the red square in the mirror
    flat = render(S.load(data), Options(reflections=False), size=SIZE)
    assert not np.any(flat.radiance[floor][:, 0] > 3 * flat.radiance[floor][:, 1] + 0.02)
    data["materials"]["mirror"] = {"color": [0.1, 0.1, 0.1], "transmit": 1.0, "ior": 1.0}
    data["objects"][0]["patches"] = [quad(-4, 4, -4, 4, 2.0)]  # glass above the red square
    glass = render(S.load(data), Options(), size=SIZE)
    through = glass.hit & (glass.patch == 0)
    assert np.any(glass.radiance[through][:, 0] > 3 * glass.radiance[through][:, 1] + 0.02)


def test_lighting_options_and_materials_are_checked():
    base = {"objects": [{"patches": [quad(0, 1, 0, 1, 0)], "material": "m"}], "materials": {"m": {}}}
    for materials, key in (({"m": {"transmit": 1.5}}, "transmit"), ({"m": {"ior": -1}}, "ior"),
                           ({"m": {"reflect": 0.6, "transmit": 0.6}}, "materials.m")):
        with pytest.raises(SceneError, match=key):
            S.load({**base, "materials": materials})
    with pytest.raises(SceneError, match="samples"):
        S.load({**base, "lights": [{"type": "point", "position": [0, 0, 1], "samples": 4}]})
    with pytest.raises(SceneError, match="samples"):
        S.load({**base, "lights": [{"type": "sphere", "center": [0, 0, 1], "radius": 1, "samples": 0}]})
    scene = S.load({**base, "lights": [{"type": "segment", "a": [0, 0, 1], "b": [1, 0, 1], "samples": 3}]})
    assert scene.lights[0].samples == 3
    frame = render(scene, Options(shadows=False), size=(8, 8))
    assert frame.shadow is None and frame.penumbra is None and frame.radiance is not None


def room_faces(half=6.0):
    """The six faces of a cube [-half, half]^3, each as 2 x 2 bilinear patches (seams to leak through)."""
    out = []
    for axis in range(3):
        for side in (-half, half):
            for a0, a1 in ((-half, 0.0), (0.0, half)):
                for b0, b1 in ((-half, 0.0), (0.0, half)):
                    pts = []
                    for b in (b0, b1):
                        for a in (a0, a1):
                            p = [0.0, 0.0, 0.0]
                            p[axis], p[(axis + 1) % 3], p[(axis + 2) % 3] = side, a, b
                            pts.append(p)
                    out.append({"degree": [1, 1], "points": pts})
    return out


def test_adaptive_reflections_of_a_curved_mirror_have_no_cracks():
    data = {"objects": [{"file": S.TEAPOT_BPT, "material": "mirror"}, {"patches": room_faces(), "material": "wall"}],
            "materials": {"mirror": {"color": [0.2, 0.2, 0.2], "reflect": 1.0}, "wall": {"color": [0.7, 0.6, 0.5]}},
            "lights": [{"type": "point", "position": [2, -2, 5]}],
            "camera": {"eye": [4, -5, 3], "look_at": [0, 0, 1.5], "up": [0, 0, 1], "fov_deg": 40}}
    scene = S.load(data)
    opts = Options(criterion="adaptive", pixel_fraction=2.0, shadows=False, max_depth=1)
    hits, effort = secondary_rays(scene, opts)
    assert len(hits) > 300 and hits.all(), f"{(~hits).sum()} reflected rays leaked out of a closed room"
    flat_hits, flat_effort = secondary_rays(scene, opts, curvature=False)
    assert flat_hits.all() and effort.sum() < 0.95 * flat_effort.sum()  # the spread beam stops earlier


def secondary_rays(scene, opts, curvature=True):
    """(hit, boxes) of every reflected or refracted ray of a render (lighting's recorder); without
    `curvature`, secondary rays keep their parent's threshold growth alone."""
    import tracer.lighting as lighting
    seen = []
    original_init, original_kappa = lighting.Lighting.__init__, lighting.max_curvature

    def recording(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        self.recorder = lambda kind, **r: seen.append((r["hit"].hit[0], r["hit"].effort[0])) \
            if kind == "secondary" else None
    lighting.Lighting.__init__ = recording
    if not curvature:
        lighting.max_curvature = lambda scene, patches, uv: np.zeros(len(patches))
    try:
        render(scene, opts, size=SIZE)
    finally:
        lighting.Lighting.__init__, lighting.max_curvature = original_init, original_kappa
    return np.concatenate([h for h, _ in seen]), np.concatenate([e for _, e in seen])


def test_curvature_of_sphere_and_plane():
    from tracer.curvature import max_curvature
    r = 2.0
    k = 0.5522847498 * r  # a quarter circle as a cubic, near enough: curvature within 1 %
    arc = np.array([[r, 0.0], [r, k], [k, r], [0.0, r]])
    cyl = [[arc[i, 0], arc[i, 1], z] for z in (0.0, 1.0) for i in range(4)]
    scene = S.load({"objects": [{"patches": [{"degree": [3, 1], "points": cyl}, quad(0, 1, 0, 1, 0)]}]})
    uv = np.array([[0.3, 0.5], [0.5, 0.5], [0.5, 0.5]])
    got = max_curvature(scene, np.array([0, 0, 1]), uv)
    assert abs(got[0] - 1 / r) < 1e-2 / r and abs(got[1] - 1 / r) < 1e-2 / r and got[2] == 0.0


def test_schlick_fresnel_and_total_internal_reflection():
    from tracer.vertices import schlick
    eta = np.array([1 / 1.5, 1 / 1.5, 1.5, 1.5, 1.0])
    cos_i = np.array([1.0, 0.0, 1.0, 0.5, 1.0])
    f = schlick(cos_i, eta)
    assert f[0] == pytest.approx(0.04) and f[1] == pytest.approx(1.0) and f[2] == pytest.approx(0.04)
    assert f[3] == 1.0  # from glass at 60 degrees: past the critical angle (41.8 degrees)
    assert f[4] == 0.0  # no change of index, straight on: nothing reflected


def test_bench_penumbra_sweep_prints_the_table(capsys, tmp_path):
    from psrt.cli import main
    out = tmp_path / "sweep.json"
    assert main(["bench", "--penumbra-sweep", "--size", "16x16", "--runs", "1", "-q", "--json", str(out)]) == 0
    table = capsys.readouterr().out
    from tracer.bench_penumbra import RADII
    assert table.count(" yes") == len(RADII) and "the scene's own light" in table and "umbra" in table
    import json
    rows = json.loads(out.read_text())["rows"]
    assert [r["radius"] for r in rows] == list(RADII) and all(r["identical"] for r in rows)
    assert all(set(r["seconds"]) == {"off", "expanded", "tmax", "umbra"} for r in rows)
    assert main(["bench", "--penumbra-sweep", "--scene", str(tmp_path / "none.json")]) == 2
