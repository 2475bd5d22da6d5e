"""Rational patches and trimming in the kernel: box containment, the exact sphere, trim parity."""
import functools
from pathlib import Path

import numpy as np
import pytest

from tracer.bezier import control_box_rational
from tracer.geometry import prepare
from tracer.options import Options
from tracer.render import reference_frame, render
from tracer.scene import load_scene, scene_from_dict
from tracer.trim import inside
from tracer.trim_kernel import trim_inside, trim_scratch

SAMPLES = Path(__file__).resolve().parent.parent / "sample_models"


def test_rational_box_contains_the_homogenised_points():
    """The box holds every exact quotient x/w of the stored points, weights 1e-3..1e3."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        count = int(rng.integers(2, 17))
        w = 10.0 ** rng.uniform(-3, 3, count)
        xyz = rng.normal(0, 10.0 ** rng.uniform(-3, 3), (count, 3))
        for dtype in (np.float32, np.float64):
            buf = np.zeros((1, 4, count), dtype)
            buf[0, :3] = (xyz * w[:, None]).T
            buf[0, 3] = w
            box = np.zeros((1, 6))
            control_box_rational(buf, 0, count, box)
            from fractions import Fraction
            for c in range(3):
                exact = [Fraction(float(buf[0, c, k])) / Fraction(float(buf[0, 3, k])) for k in range(count)]
                assert Fraction(box[0, c]) <= min(exact) and max(exact) <= Fraction(box[0, 3 + c])


def random_rational_patch(rng, degree=(3, 3)):
    m, n = degree
    pts = []
    for j in range(n + 1):
        for i in range(m + 1):
            p = [i / m * 2 - 1, j / n * 2 - 1, rng.normal(0, 0.3)]
            pts.append(p + [float(10.0 ** rng.uniform(-3, 3))])
    return {"degree": [m, n], "points": pts}


@functools.lru_cache(maxsize=None)
def random_rational_frames(seed):
    """The float32 render (48 x 48) of one random rational patch and its float64 reference."""
    rng = np.random.default_rng(seed)
    scene = scene_from_dict({"objects": [{"patches": [random_rational_patch(rng)]}],
                             "camera": {"eye": [0.3, -0.4, 4.0], "look_at": [0, 0, 0], "up": [0, 1, 0],
                                        "fov_deg": 40}}, "random rational", ".")
    frame = render(scene, Options(), size=(48, 48))
    return frame, reference_frame(scene, frame)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_rational_patches_no_holes_no_false_hits(seed):
    frame, ref = random_rational_frames(seed)
    assert ref.hit.sum() > 200
    assert not np.any(ref.hit & ~frame.hit), "holes"
    assert not np.any(frame.hit & ~ref.hit), "false hits"


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_rational_hit_boxes_hold_the_reference(seed):
    """Weights from 1e-3 to 1e3: rational patches are searched in float64 slots and stop on the
    float32 grid, so the float64 point lies in the float32 hit box for every hit (float32 slots
    with homogeneous bounds left 0.2-5 % outside, up to 160 ulps, near corners where a
    sub-patch's weights differ by 1e6)."""
    frame, ref = random_rational_frames(seed)
    both = frame.hit & ref.hit
    lo, hi, p = frame.box_min[both], frame.box_max[both], ref.position[both]
    inside = np.all((lo <= p) & (p <= hi), axis=-1)
    assert np.mean(inside) >= 0.9999, f"{100 * np.mean(inside):.3f} % inside"


def test_nurbs_sphere_hit_boxes_hold_the_reference():
    scene = load_scene(SAMPLES / "sphere.json")
    frame = render(scene, Options(), size=(64, 64))
    ref = reference_frame(scene, frame)
    both = frame.hit & ref.hit
    assert both.sum() > 1000 and np.array_equal(frame.hit, ref.hit)
    p = ref.position[both]
    inside = np.all((frame.box_min[both] <= p) & (p <= frame.box_max[both]), axis=-1)
    assert np.mean(inside) >= 0.9999, f"{100 * np.mean(inside):.3f} % inside"


def test_exact_sphere_within_4_ulps_of_its_radius():
    """Every float32 hit on the rational NURBS sphere lies within 4 ulps of the analytic sphere."""
    scene = load_scene(SAMPLES / "sphere.json")
    sphere = [i for i, o in enumerate(scene.objects) if o.source.endswith(".obj")][0]
    obj = scene.objects[sphere]
    first, last = obj.first_patch, obj.first_patch + obj.patch_count
    pts = scene.points[scene.point_start[first]:scene.point_start[last], :3]
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    radius = 0.5 * (pts.max(axis=0) - pts.min(axis=0)).max()
    frame = render(scene, Options(), size=(64, 64))
    on = frame.hit & (frame.patch >= first) & (frame.patch < last)
    assert on.sum() > 500
    dist = np.linalg.norm(frame.position[on] - centre, axis=1)
    ulp = np.spacing(np.float32(radius)).astype(float)
    assert np.max(np.abs(dist - radius)) <= 4 * ulp, f"{np.max(np.abs(dist - radius)) / ulp:.2f} ulps"


def test_kernel_trim_parity_matches_the_reference():
    """trim_inside (numba) agrees with tracer.trim.inside on the trimmed plate, point for point."""
    scene = load_scene(SAMPLES / "plate.json")
    geom = prepare(scene, "f32")
    surfaces = sorted({int(s) for s in geom.patch_trim if s >= 0})
    assert surfaces
    seg_points, seg_start, surf_seg_start, start_inside, _ = geom.trim_arrays
    h, m = trim_scratch(geom.trim_points)
    rng = np.random.default_rng(3)
    for surface in surfaces:
        dom = scene.patch_domain[scene.patch_surface == surface]
        lo, hi = dom[:, [0, 2]].min(axis=0), dom[:, [1, 3]].max(axis=0)
        for u, v in rng.uniform(lo, hi, (400, 2)):
            assert trim_inside(surface, u, v, seg_points, seg_start, surf_seg_start, start_inside, h, m) \
                == inside(scene.trims, surface, u, v), (surface, u, v)


def test_trimmed_plate_pixels_match_the_trim_region():
    """A hit on the plate is kept iff its (u, v) is inside the loops; trims off shows the whole plate."""
    scene = load_scene(SAMPLES / "plate.json")
    on = render(scene, Options(), size=(64, 64))
    off = render(scene, Options(trims=False), size=(64, 64))
    plate = scene.patch_surface >= 0
    hit_on = on.hit & plate[np.maximum(on.patch, 0)]
    hit_off = off.hit & plate[np.maximum(off.patch, 0)]
    assert hit_off.sum() > hit_on.sum() > 0  # the holes and the cut corners are gone
    for y, x in zip(*np.nonzero(hit_off)):
        u, v = off.uv[y, x]
        expect = inside(scene.trims, int(scene.patch_surface[off.patch[y, x]]), u, v)
        if expect:
            assert hit_on[y, x], (x, y)  # kept surface stays (the same ray finds it)
    for y, x in zip(*np.nonzero(hit_on)):
        u, v = on.uv[y, x]
        assert inside(scene.trims, int(scene.patch_surface[on.patch[y, x]]), u, v), (x, y)
