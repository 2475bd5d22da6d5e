"""Grazing rays: the hit box holds the ray's true crossing, however flat the angle.

A search accepts a sub-patch that met the criterion when its control hull meets the ray
(search_steps.hull_accepts). Across the two planes that meet in the ray (hull.hull_hit) a small
flat sub-patch seen nearly edge-on can straddle both while the ray passes just above it, so a ray
skimming a surface took such a sub-patch for its hit, ahead of the true crossing by up to the
sub-patch's width over the angle. The plane through the ray that faces the sub-patch
(hull.hull_off_facing) measures the ray's distance from it.

Rays here descend onto a tilted plane at angles from 1e-5 to 3e-2 radians; their crossings are
exact (rationals), against float32 boxes of ~1e-7."""
from fractions import Fraction

import numpy as np
import pytest

from tracer.geometry import prepare
from tracer.options import Options
from tracer.ray_batch import BatchTracer, batch_rays
from tracer.render import kernel_inputs
from tracer.stats import ulp32

import scenes as S

NORMAL = np.array([0.25, 0.125, -1.0])  # the plane x/4 + y/8 - z = 0: dyadic corners, exactly flat


def _plane_scene():
    P = np.array([[[x, y, x / 4 + y / 8] for y in (-1.0, 1.0)] for x in (-1.0, 1.0)])  # P[i, j]
    return S.patches_scene([P], "tilted plane")


def _grazing_rays(count, seed):
    """(origins, directions, crossings): rays that skim the plane at log-uniform angles and cross
    it at random points inside it, three units on."""
    rng = np.random.default_rng(seed)
    n = NORMAL / np.linalg.norm(NORMAL)
    e1 = np.cross(n, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    phi = rng.uniform(0.0, 2 * np.pi, count)
    angle = 10.0 ** rng.uniform(-5.0, np.log10(3e-2), count)
    along = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    dirs = np.cos(angle)[:, None] * along + np.sin(angle)[:, None] * n
    xy = rng.uniform(-0.8, 0.8, (count, 2))
    cross = np.column_stack([xy, xy @ NORMAL[:2]])
    origins = cross - 3.0 * dirs
    return origins, dirs, np.array([_crossing(o, d) for o, d in zip(origins, dirs)])


def _crossing(o, d):
    """The crossing of the float64 ray o + t d with the plane, exactly (rationals), rounded once: at
    an angle of 1e-5 float64 arithmetic alone would be off by ~1e-11."""
    n = [Fraction(c) for c in NORMAL]
    o, d = [Fraction(c) for c in o], [Fraction(c) for c in d]
    t = -sum(a * b for a, b in zip(n, o)) / sum(a * b for a, b in zip(n, d))
    return [float(a + t * b) for a, b in zip(o, d)]


@pytest.mark.parametrize("precision", ["f32", "f64"])
@pytest.mark.parametrize("criterion", ["float", "mantissa"])
def test_grazing_hit_box_holds_the_crossing(precision, criterion):
    scene = _plane_scene()
    geom = prepare(scene, precision)
    opts = Options(criterion=criterion, precision=precision, threads=1)
    origins, dirs, crossings = _grazing_rays(400, seed=7)
    out = BatchTracer(geom, opts, kernel_inputs(geom, opts, 0.0)).closest(batch_rays(origins, dirs))
    hit = out.hit[0]
    assert hit.all()
    lo, hi = out.box_min[0], out.box_max[0]
    slack = 4 * ulp32(np.maximum(np.abs(lo), np.abs(hi)))
    outside = np.maximum(np.maximum(lo - slack - crossings, crossings - hi - slack), 0.0).max(axis=1)
    bad = outside > 0.0
    assert not bad.any(), f"{bad.sum()} of {len(hit)} crossings outside their box, by up to {outside.max():.3g}"
