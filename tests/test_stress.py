"""Numerical stress suite: float32 renders of awkward scenes against the float64 reference.

Scenes (tests/scenes.py `stress_cases`, each <= 64 x 64): the teapot scaled by 1e-4 and 1e4
and moved to (1e4, 1e4, 1e4), grazing views of silhouettes and of the floor, the collapsed
lid and bottom apexes, self-intersecting and folded patches, seams between the two halves of a
patch split at a non-dyadic parameter, and degree 9x7 and 15x15 patches.

Targets (issue 2), per scene, against `render.reference_frame` (float64, `float` criterion,
the same rays): zero holes, zero false hits, mean L1 position error <= 10x (aim, held here: 2x) the float32
rounding floor (the mean L1 error of rounding the reference positions to float32), and
>= 99.99 % of the reference positions inside the float32 hit box widened by 4 float32 ulps per
coordinate (the float32 spacing at each bound: stats.error_stats' inside_4ulp) -- with these image
sizes: all. Scored by tracer.stress.score, as `psrt stress` scores a user's scene; pixels the
reference could not resolve within its box budget, which the scoring leaves out, fail the first test.

`python tests/scenes.py` prints the per-scene table.
"""
import functools

import pytest

import scenes as S

CASES = {c.name: c for c in S.stress_cases()}

@functools.lru_cache(maxsize=None)
def result(name) -> S.Comparison:
    return S.run_case(CASES[name])


@pytest.mark.parametrize("name", list(CASES))
def test_no_holes_no_false_hits(name, tmp_path):
    cmp = result(name)
    assert cmp.hits > 100
    S.check(cmp, tmp_path, max_ratio=float("inf"), min_inside=0.0)


@pytest.mark.parametrize("name", list(CASES))
def test_mean_error_within_2x_float32_floor(name, tmp_path):
    """Issue 2 asks for 10x and aims at 2x: hold the aim."""
    cmp = result(name)
    assert cmp.hits > 100
    assert cmp.ratio <= 2.0, f"{S.TABLE_HEADER}\n{cmp.row()}"


@pytest.mark.parametrize("name", list(CASES))
def test_reference_inside_widened_float32_box(name, tmp_path):
    cmp = result(name)
    assert cmp.hits > 100
    assert cmp.inside >= 0.9999, f"{S.TABLE_HEADER}\n{cmp.row()}"



@pytest.mark.parametrize("name", list(CASES))
def test_reference_within_box_reach(name):
    """What holds where the 4-ulp containment does not: every reference point lies within
    2 x box L1 diameter / cos(angle between ray and normal), plus 4 ulps, of the float32 box --
    the box encloses a piece of surface the ray meets, and a locally flat surface meets the ray
    at most that far along it."""
    import numpy as np
    cmp = result(name)
    f, r = cmp.frame, cmp.reference
    both = f.hit & r.hit
    lo, hi, p = f.box_min[both], f.box_max[both], r.position[both]
    out = np.maximum(np.maximum(lo - p, p - hi), 0.0).max(axis=1)
    d = r.ray_dir[both] / np.linalg.norm(r.ray_dir[both], axis=1, keepdims=True)
    cos = np.maximum(np.abs((r.normal[both] * d).sum(axis=1)), 1e-6)
    reach = 2 * (hi - lo).sum(axis=1) / cos + 4 * S.ref.ulp(np.abs(p).max(axis=1))
    assert np.all(out <= reach), f"worst {np.max(out / reach):.2f} x the reach"
