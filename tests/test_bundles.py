"""Ray bundles (tracer/bundle.py): a ray in a bundle reports what it reports alone.

Under the float criterion with the length split the box alone decides every step, so every
channel but the effort (which follows the visiting order) is bit for bit the 1x1 render's.
Under the adaptive criterion and the cross split the bundle's first active ray decides the split
direction where the rays' own choices differ: hits and patches stay the same, and a position may
move to the neighbouring grid box.
"""
import numpy as np
import pytest

import digests as D
from tracer.geometry import prepare
from tracer.options import BUNDLES, Options
from tracer.render import render

EXACT = ("hit", "t", "position", "box_min", "box_max", "normal", "uv", "patch")
SCENES = ["teapot", "sphere", "plate", "stress/lid apex", "stress/degree 9x7"]


def _frames(name, opts, bundles, size=(20, 20)):
    scene, view = D.catalogue()[name][0]()
    geom = prepare(scene, opts.precision)
    return [render(scene, opts.with_(bundle=b), size=size, view=view, geometry=geom) for b in bundles]


@pytest.mark.parametrize("precision", ["f32", "f64"])
@pytest.mark.parametrize("name", SCENES)
def test_float_criterion_bundles_report_the_single_rays_bits(name, precision):
    alone, *bundled = _frames(name, Options(precision=precision), ("1x1",) + BUNDLES[1:])
    assert alone.hit.sum() > 20
    for frame, shape in zip(bundled, BUNDLES[1:]):
        moved = [c for c in EXACT if not np.array_equal(getattr(frame, c), getattr(alone, c), equal_nan=True)]
        assert not moved, (shape, moved)
        assert frame.effort[frame.hit].min() > 0


@pytest.mark.parametrize("name", ["teapot", "stress/lid apex"])
def test_adaptive_and_cross_bundles_keep_hits_and_boxes_within_a_cell(name):
    opts = Options(criterion="adaptive", split="cross")
    alone, bundled = _frames(name, opts, ("1x1", "8x8"), size=(32, 32))
    assert np.array_equal(alone.hit, bundled.hit) and np.array_equal(alone.patch, bundled.patch)
    hit = alone.hit
    size = np.maximum(alone.box_max - alone.box_min, bundled.box_max - bundled.box_min)[hit]
    assert np.all(np.abs(alone.position[hit] - bundled.position[hit]) <= size)


def test_bundle_counters_count_each_ray_as_if_alone():
    alone, bundled = _frames("teapot", Options(), ("1x1", "4x4"), size=(24, 24))
    for name in ("nodes", "patches_tested", "surfaces_tested"):
        a, b = getattr(alone, name), getattr(bundled, name)
        assert np.all((a > 0) == (b > 0)), name
    # The same boxes, visited in another order: a ray's own closest hit prunes differently.
    assert abs(int(bundled.effort.sum()) - int(alone.effort.sum())) < 0.05 * alone.effort.sum()
