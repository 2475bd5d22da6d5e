"""A point's shadow rays as one bundle (shadow_bundles.py) answer as the rays one by one do."""
import numpy as np
import pytest

from tracer.bundle import MAX_RAYS
from tracer.geometry import prepare
from tracer.kernel_channels import COUNTERS
from tracer.options import Options
from tracer.ray_batch import BatchTracer, batch_rays
from tracer.render import kernel_inputs, render
from tracer.scene import load_scene
from tracer.shadow_bundles import PointBundles, bundle_starts, shares_tree

import scenes as S


def test_bundle_starts_pack_whole_points_and_cut_only_the_largest():
    point = np.array([0] * 3 + [2] * (MAX_RAYS + 5) + [7] + [8] * (MAX_RAYS - 5) + [9] * 6)
    starts = bundle_starts(point)  # 0 | 2's first MAX_RAYS | 2's last 5, 7 | 8 | 9 (8 and 9: one too many)
    assert starts.tolist() == [0, 3, 3 + MAX_RAYS, 3 + MAX_RAYS + 6, 3 + 2 * MAX_RAYS + 1, len(point)]
    assert bundle_starts(np.repeat(np.arange(10), 16)).tolist() == [0, 64, 128, 160]
    assert bundle_starts(np.zeros(0, np.int64)).tolist() == [0]


def test_only_settings_whose_tree_is_the_rays_own():
    assert shares_tree(Options(criterion="float"))
    assert shares_tree(Options(criterion="mantissa"))
    assert not shares_tree(Options(criterion="adaptive"))
    assert not shares_tree(Options(split="cross"))


def _shadow_rays(scene, geom, opts, rng):
    """Rays from a frame's hit points, lifted off the surface, to points scattered about the
    light, 1 to 150 a point (bundles of one, partly and wholly filled, and cut at MAX_RAYS);
    returns (rays, point of each ray)."""
    frame = render(scene, opts.with_(shadows=False, reflections=False), size=(20, 20), geometry=geom)
    hit = frame.hit
    pos = frame.position[hit].astype(np.float64)
    normal = frame.normal[hit].astype(np.float64)
    side = np.where(np.sum(normal * frame.ray_dir[hit], axis=1, keepdims=True) > 0, -1.0, 1.0)
    origin = pos + 1e-4 * side * normal
    counts = rng.integers(1, 151, len(origin))
    point = np.repeat(np.arange(len(origin)), counts)
    centre = np.asarray(scene.lights[0].centre())
    ends = centre + rng.normal(0.0, 1.5, (len(point), 3))
    return batch_rays(origin[point], ends - origin[point], 0.0, 1.0), point


@pytest.mark.parametrize("name", ["teapot", "tea_set"])
@pytest.mark.parametrize("criterion,precision", [("float", "f32"), ("float", "f64"), ("fixed", "f32"),
                                                 ("mantissa", "f32")])
def test_bundled_shadow_rays_answer_as_single_rays(name, criterion, precision):
    scene = load_scene(S.SAMPLES / f"{name}.json")
    opts = Options(criterion=criterion, precision=precision)
    geom = prepare(scene, precision)
    rays, point = _shadow_rays(scene, geom, opts, np.random.default_rng(7))
    tracer = BatchTracer(geom, opts, kernel_inputs(geom, opts, 0.0))
    alone, effort_alone = tracer.occluded(rays)
    bundled, effort = PointBundles(tracer).occluded(rays, point)
    assert 0.05 < alone.mean() < 0.95  # both answers occur
    np.testing.assert_array_equal(bundled, alone)
    # a ray that finds nothing computes the same boxes in the bundle (an occluded one looks on for
    # nearer hit boxes: the bundle's search is the closest hit's)
    np.testing.assert_array_equal(effort[~alone], effort_alone[~alone])


def _mirror_rays(scene, geom, opts):
    """Rays from a frame's hit points, lifted off the surface, mirrored about the normal, as the
    lighting spawns reflected rays from neighbouring pixels (batch order: the pixels' order)."""
    frame = render(scene, opts.with_(shadows=False, reflections=False), size=(40, 40), geometry=geom)
    hit = frame.hit
    pos = frame.position[hit].astype(np.float64)
    normal = frame.normal[hit].astype(np.float64)
    d = frame.ray_dir[hit].astype(np.float64)
    side = np.where(np.sum(normal * d, axis=1, keepdims=True) > 0, -1.0, 1.0) * normal
    mirrored = d - 2.0 * np.sum(d * side, axis=1, keepdims=True) * side
    return batch_rays(pos + 1e-4 * side, mirrored, 0.0, np.inf, side=side)


@pytest.mark.parametrize("name", ["teapot", "tea_set"])
@pytest.mark.parametrize("criterion,precision", [("float", "f32"), ("float", "f64"), ("mantissa", "f32")])
def test_bundled_reflected_rays_report_the_single_rays_channels(name, criterion, precision):
    scene = load_scene(S.SAMPLES / f"{name}.json")
    opts = Options(criterion=criterion, precision=precision)
    geom = prepare(scene, precision)
    rays = _mirror_rays(scene, geom, opts)
    tracer = BatchTracer(geom, opts, kernel_inputs(geom, opts, 0.0))
    alone = tracer.closest(rays)
    bundled = PointBundles(tracer).closest(rays)
    assert 0.05 < alone.hit.mean() < 0.95 and len(rays) > 3 * MAX_RAYS  # hits, misses, several bundles
    miss = ~alone.hit[0]
    for name_ in alone._fields:
        if name_ in [c.name for c in COUNTERS]:  # a hit prunes what its ray visits later: the bundle's order
            np.testing.assert_array_equal(getattr(bundled, name_)[0, miss], getattr(alone, name_)[0, miss],
                                          err_msg=name_)
        else:
            np.testing.assert_array_equal(getattr(bundled, name_), getattr(alone, name_), err_msg=name_)
