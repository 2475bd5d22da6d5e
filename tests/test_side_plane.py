"""The side plane of secondary rays (ray.set_side, hull.hull_behind): a sub-patch whose box holds
a ray's origin is dropped once its hull lies wholly behind the plane through the origin that the
ray leaves in front of. Under the float criterion no answer moves and fewer boxes are computed;
under coarse criteria the only answers that move are hits on the origin's own patch, in a box
holding the origin, that the control hull met only on the ray's line behind the origin."""
import numpy as np
import pytest

from tracer.geometry import prepare
from tracer.options import Options
from tracer.origins import patch_ulps, robust_origins
from tracer.ray import R_SIDE, RAY_LEN, make_ray, set_side
from tracer.ray_batch import BatchTracer, batch_rays
from tracer.render import kernel_inputs, render
from tracer.scene import load_scene
from tracer.vertices import facing

import scenes as S


def _secondary(scene, geom, opts, light, size=24):
    """From every hit of a 24x24 frame: its reflected ray and its ray to `light` (both from the
    box-corner origin), with the side they leave on; returns (reflected, shadow, side), and the
    origin patch and origin of each."""
    frame = render(scene, opts.with_(shadows=False, reflections=False), size=(size, size), geometry=geom)
    hit = frame.hit
    d = frame.ray_dir[hit] / np.linalg.norm(frame.ray_dir[hit], axis=1, keepdims=True)
    n = facing(frame.normal[hit], d)
    patch = frame.patch[hit]
    origin = robust_origins("box_corner", lo=frame.box_min[hit], hi=frame.box_max[hit],
                            position=frame.position[hit], normal=n, ulp=patch_ulps(geom)[patch])
    cos_i = -np.sum(d * n, axis=1, keepdims=True)
    reflected = d + 2.0 * cos_i * n
    return origin, reflected, np.asarray(light, float) - origin, n, patch


@pytest.fixture(scope="module")
def teapot():
    scene = load_scene(S.SAMPLES / "teapot.json")
    return scene, prepare(scene, "f32")


def _trace(geom, opts, origin, d, n, t_max, kind):
    tracer = BatchTracer(geom, opts, kernel_inputs(geom, opts, 0.0))
    with_side, without = (batch_rays(origin, d, 0.0, t_max, side=s) for s in (n, None))
    return getattr(tracer, kind)(with_side), getattr(tracer, kind)(without)


def test_set_side_only_where_the_ray_leaves_in_front():
    ray = np.zeros(RAY_LEN)
    make_ray(ray, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    set_side(ray, 0.6, 0.8, 0.0)
    assert ray[R_SIDE:R_SIDE + 3].tolist() == [0.6, 0.8, 0.0]
    set_side(ray, -0.6, 0.8, 0.0)  # the ray goes behind it
    assert ray[R_SIDE:R_SIDE + 3].tolist() == [0.0, 0.0, 0.0]
    set_side(ray, 0.0, 1.0, 0.0)  # along the plane: no doubt allowed
    assert ray[R_SIDE:R_SIDE + 3].tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_float_answers_unchanged_with_fewer_boxes(teapot, precision):
    scene, _ = teapot
    geom = prepare(scene, precision)
    opts = Options(criterion="float", precision=precision, threads=1)
    origin, reflected, to_light, n, _ = _secondary(scene, geom, opts, (5.0, -5.0, 10.0))
    a, b = _trace(geom, opts, origin, reflected, n, np.inf, "closest")
    for name in ("hit", "t", "position", "box_min", "box_max", "normal", "uv", "patch"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.effort.sum() < 0.9 * b.effort.sum()
    (occ_a, effort_a), (occ_b, effort_b) = _trace(geom, opts, origin, to_light, n, 1.0, "occluded")
    np.testing.assert_array_equal(occ_a, occ_b)
    assert 0 < occ_a.sum() < len(occ_a)  # the teapot shades part of itself and the floor
    assert effort_a.sum() < effort_b.sum()


def test_coarse_criteria_lose_only_hits_at_the_origin_behind_it(teapot):
    scene, geom = teapot
    opts = Options(criterion="fixed", fixed_size=0.002, threads=1)
    origin, reflected, to_light, n, patch = _secondary(scene, geom, opts, (5.0, -5.0, 10.0), size=128)
    a, b = _trace(geom, opts, origin, reflected, n, np.inf, "closest")
    moved = np.nonzero((a.hit[0] != b.hit[0]) | (a.t[0] != b.t[0]))[0]
    assert 0 < len(moved) < 0.001 * len(patch)  # a coarse box at the origin, taken for a hit without the plane
    for i in moved:
        assert b.hit[0, i] and b.patch[0, i] == patch[i]
        assert np.all(b.box_min[0, i] <= origin[i]) and np.all(origin[i] <= b.box_max[0, i])
        assert not a.hit[0, i] or a.t[0, i] > b.t[0, i]
    same = np.setdiff1d(np.arange(len(patch)), moved)
    np.testing.assert_array_equal(a.patch[0, same], b.patch[0, same])
    (occ_a, _), (occ_b, _) = _trace(geom, opts, origin, to_light, n, 1.0, "occluded")
    # (here the test before a hit, across the planes along the sub-patch's edges, already drops
    # the coarse boxes these shadow rays met only behind their origin: none may move)
    assert np.sum(occ_a != occ_b) < 0.001 * len(patch)
    assert np.all(occ_b[occ_a])  # only shadows lost, none gained
