"""The bundle's bounds (tracer/frustum.py): a box they say every ray misses, every ray's own slab
test misses; and they say so for most boxes clear of the bundle (seeded property test)."""
import math

import numpy as np

from tracer.frustum import F_LEN, F_OK, bound_rays, misses_all
from tracer.ray import R_TMIN, RAY_LEN, make_ray, slab, slab_at


def _bundle(rng, origin_spread):
    """Up to 64 rays of a pixel block: nearby directions, one origin or scattered ones."""
    k = int(rng.integers(1, 65))
    base = rng.normal(size=3)
    eye = rng.normal(size=3) * rng.choice([1e-3, 1.0, 1e3])
    rays = np.zeros((64, RAY_LEN))
    for r in range(k):
        d = base + rng.normal(size=3) * rng.choice([1e-4, 1e-2, 0.3])
        d /= np.linalg.norm(d)
        o = eye + rng.normal(size=3) * origin_spread
        make_ray(rays[r], o[0], o[1], o[2], d[0], d[1], d[2], 0.0, 0.0, 0.0)
    mask = np.uint64((1 << k) - 1) if k < 64 else np.uint64(2 ** 64 - 1)
    return rays, k, mask


def test_a_box_the_bounds_reject_is_missed_by_every_ray():
    rng = np.random.default_rng(12)
    fr = np.zeros(F_LEN)
    rejected = tested = 0
    for trial in range(400):
        rays, k, mask = _bundle(rng, 0.0 if trial % 2 else 1e-3)
        bound_rays(fr, rays, mask)
        assert fr[F_OK] == 1.0
        for _ in range(50):
            centre = rays[0, :3] + rays[int(rng.integers(k)), 3:6] * rng.uniform(0.1, 10) + rng.normal(size=3) * 0.5
            half = np.abs(rng.normal(size=3)) * rng.choice([1e-4, 1e-2, 0.3])
            box = np.concatenate([centre - half, centre + half])
            shift = rng.normal(size=3) * rng.choice([0.0, 0.1])
            corners = tuple(box[c] + shift[c % 3] for c in range(6))
            tested += 1
            if misses_all(corners, fr):
                rejected += 1
                for r in range(k):
                    assert not slab(box, shift[0], shift[1], shift[2], rays[r])[0], (trial, r)
    assert rejected > tested // 4  # the bounds reject much of what lies beside the bundle


def test_a_zero_direction_component_leaves_the_bundle_unbounded():
    rays = np.zeros((64, RAY_LEN))
    make_ray(rays[0], 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    make_ray(rays[1], 0.0, 0.0, 0.0, 0.6, 0.8, 0.0, 0.0, 0.0, 0.0)
    fr = np.zeros(F_LEN)
    bound_rays(fr, rays, np.uint64(3))
    assert fr[F_OK] == 0.0
    assert not misses_all((5.0, 5.0, 5.0, 6.0, 6.0, 6.0), fr)


def test_slab_at_is_slab_on_the_shifted_corners():
    rng = np.random.default_rng(3)
    ray = np.zeros(RAY_LEN)
    for _ in range(2000):
        d = rng.normal(size=3)
        d[rng.integers(3)] *= rng.choice([0.0, 1.0])
        if not d.any():
            continue
        o = rng.normal(size=3)
        make_ray(ray, o[0], o[1], o[2], d[0], d[1], d[2], 0.0, 0.0, 0.0)
        box = np.sort(rng.normal(size=(2, 3)), axis=0).ravel()
        f = rng.normal(size=3) * rng.choice([0.0, 1e-3, 1.0])
        want = slab(box, f[0], f[1], f[2], ray)
        got = slab_at(*(box[c] + f[c % 3] for c in range(6)), ray, ray[R_TMIN], math.inf)
        assert want[0] == got[0] and np.array_equal(np.array(want[1:]), np.array(got[1:]))
