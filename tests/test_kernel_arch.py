"""The kernel's architecture: query drivers, aggregate counters, variants, channels.

Any hit against closest hit (drivers.py): for a ray limit T, the any-hit search finds a hit
exactly when the closest-hit search with the same T does (both explore the same boxes until
the first hit), and with T at the exit of the closest hit's box it finds one. (What lies
before a hit box's entry depends on T: a half kept because its sibling lies beyond T is not
hull-tested against that sibling, and may end in a hit box of its own.) Counters against a numpy walk: on a ray that hits nothing, nothing prunes the
BVH walk, so it visits exactly the nodes whose boxes the ray meets and searches every leaf
among them.
"""
import math

import numpy as np
import pytest

from tracer.camera import primary_rays, view_of
from tracer.geometry import prepare
from tracer.kernel_channels import CHANNEL_NAMES
from tracer.options import Options
from tracer.ray import H_TIN, H_TOUT, HIT_LEN, RAY_LEN, make_ray
from tracer.records import C_EFFORT, C_NODES, C_PATCHES, COUNTER_LEN, no_trace
from tracer.render import kernel_inputs, render
from tracer.scene import load_scene
from tracer.tile_kernel import tile_scratch
from tracer.variants import compile_report, compiled, label, variant_for

import scenes as S

SIZE = (24, 24)


def _scene(name):
    return load_scene(S.SAMPLES / f"{name}.json")


def _one_ray(geom, opts, origin, direction, t_max, driver):
    """(found, entry and exit t of the hit box, counters) of one ray through the ray kernel with the given driver."""
    inputs = kernel_inputs(geom, opts, 0.0)
    ray = np.zeros(RAY_LEN)
    hit = np.zeros(HIT_LEN)
    counts = np.zeros(COUNTER_LEN, np.int64)
    make_ray(ray, *origin, *direction, 0.0, 0.0, 0.0)
    hit[H_TIN] = t_max
    args = (ray, hit, inputs.scene, inputs.query, no_trace(), counts, tile_scratch(inputs))
    compiled("ray", variant_for(geom, opts, driver=driver), args)(*args)
    return hit[H_TIN] < t_max, hit[H_TIN], hit[H_TOUT], counts.copy()


@pytest.mark.parametrize("name", ["teapot", "plate"])
@pytest.mark.parametrize("criterion", ["float", "adaptive"])
def test_any_hit_agrees_with_closest_hit(name, criterion):
    scene = _scene(name)
    opts = Options(criterion=criterion)
    geom = prepare(scene, opts.precision)
    origins, dirs = primary_rays(view_of(scene), *SIZE, opts.precision)
    closest = render(scene, opts, size=SIZE, geometry=geom)
    assert closest.hit.sum() > 50
    rng = np.random.default_rng(1)
    pixels = [tuple(p) for p in np.argwhere(closest.hit)[rng.choice(int(closest.hit.sum()), 40, replace=False)]]
    pixels += [tuple(p) for p in np.argwhere(~closest.hit)[:10]]
    for y, x in pixels:
        o, d = origins[y, x], dirs[y, x]
        found, t_in, t_out, _ = _one_ray(geom, opts, o, d, math.inf, "closest")
        assert found == closest.hit[y, x]
        assert _one_ray(geom, opts, o, d, math.inf, "any")[0] == found, (y, x)
        if found:
            for t_max in (0.5 * t_in, t_in, 0.5 * (t_in + t_out), t_out):
                any_found, any_t, _, _ = _one_ray(geom, opts, o, d, t_max, "any")
                assert any_found == _one_ray(geom, opts, o, d, t_max, "closest")[0], (y, x, t_max)
                assert not any_found or any_t < t_max
            assert _one_ray(geom, opts, o, d, t_out, "any")[0], (y, x)


def _slab_hits(boxes, o, d):
    """Which boxes (N, 6) the ray o + t d, t >= 0, meets (plain numpy, no shared code)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (boxes[:, :3] - o) / d
        b = (boxes[:, 3:] - o) / d
    lo = np.where(d == 0, np.where((boxes[:, :3] <= o) & (o <= boxes[:, 3:]), -np.inf, np.inf), np.minimum(a, b))
    hi = np.where(d == 0, np.where((boxes[:, :3] <= o) & (o <= boxes[:, 3:]), np.inf, -np.inf), np.maximum(a, b))
    t_in = np.maximum(lo.max(axis=1), 0.0)
    t_out = hi.min(axis=1)
    return t_in <= t_out * (1 + 1e-12)


def test_counters_of_missing_rays_match_a_numpy_walk():
    scene = _scene("teapot")
    geom = prepare(scene, "f64")
    bvh = geom.bvh
    leaf = bvh.node_child[:, 0] < 0
    rng = np.random.default_rng(5)
    checked = 0
    for _ in range(400):
        o = rng.uniform(-12, 12, 3)
        d = rng.normal(size=3)
        found, _, _, counts = _one_ray(geom, Options(precision="f64"), o, d, math.inf, "closest")
        met = _slab_hits(bvh.node_box, o, d)
        near_edge = np.abs(_slab_hits(bvh.node_box * (1 + 1e-9), o, d).astype(int) - met.astype(int)).sum()
        if found or near_edge:
            continue
        assert counts[C_NODES] == met.sum()
        assert counts[C_PATCHES] == (met & leaf).sum()
        assert counts[C_EFFORT] >= counts[C_PATCHES]
        checked += 1
    assert checked > 100


def test_counter_channels_reach_the_frame_and_hold_their_order():
    scene = _scene("teapot")
    frame = render(scene, Options(), size=SIZE)
    assert set(CHANNEL_NAMES) <= set(frame.aovs())
    hit = frame.hit
    assert np.all(frame.nodes[hit] >= 1) and np.all(frame.patches_tested[hit] >= 1)
    assert np.all(frame.patches_tested <= frame.nodes)
    assert np.all(frame.effort >= frame.patches_tested)
    assert frame.nodes.max() > frame.patches_tested.max() > 1


def test_variant_of_an_integral_untrimmed_scene_leaves_out_rational_and_trims():
    teapot = prepare(_scene("teapot"), "f32")
    v = variant_for(teapot, Options())
    assert (v.rational, v.cubic, v.linear, v.general, v.trims, v.trace) == (False, True, True, False, False, False)
    deg97 = prepare(S.patches_scene([S.smooth_patch(np.random.default_rng(6), 9, 7)]), "f32")
    assert (variant_for(deg97, Options()).general, variant_for(deg97, Options()).cubic) == (True, False)
    plate = prepare(_scene("plate"), "f32")
    assert variant_for(plate, Options()).trims and not variant_for(plate, Options(trims=False)).trims
    sphere = prepare(_scene("sphere"), "f32")
    assert variant_for(sphere, Options()).rational
    render(_scene("teapot"), Options(), size=(4, 4), geometry=teapot)
    assert label(v) in [r["variant"] for r in compile_report()]


def _deps(module):
    from tracer.jit import PACKAGE, _imports
    seen, todo = set(), [PACKAGE / f"{module}.py"]
    while todo:
        path = todo.pop()
        if path not in seen:
            seen.add(path)
            todo.extend(_imports(path))
    return {p.stem for p in seen}


def test_cache_keys_follow_the_modules_a_kernel_depends_on():
    """An edit recompiles what depends on it: the trim kernel does not depend on the search,
    the drivers depend on the sub-patch operations and the trim kernel."""
    assert _deps("trim_kernel") == {"trim_kernel", "jit"}
    assert {"subpatch", "search_steps", "bezier", "simd", "ray", "trim_kernel"} <= _deps("drivers")
    assert "drivers" not in _deps("subpatch") and "tile_kernel" not in _deps("drivers")


def test_a_fresh_process_loads_the_kernels_from_the_cache():
    """Specialised kernels (jit.specialise) are found again by a new process: their cache key is
    the same there (numba's own key pickles the kernels a closure calls, which differs)."""
    import json
    import os
    import subprocess
    import sys
    scene = _scene("teapot")
    render(scene, Options(), size=(4, 4))  # compiled or loaded here, so now on disk
    code = ("import json; from tracer.scene import load_scene; from tracer.render import render; "
            "from tracer.options import Options; from tracer.variants import compile_report; "
            f"render(load_scene({str(S.SAMPLES / 'teapot.json')!r}), Options(), size=(4, 4)); "
            "print(json.dumps(compile_report()))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ),
                         timeout=600, check=True)
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report and all(r["cached"] for r in report), report


def test_a_box_budget_with_bundles_is_refused():
    from tracer.render import trace_rays
    scene = _scene("teapot")
    geom = prepare(scene, "f64")
    origins, dirs = primary_rays(view_of(scene), 8, 8, "f64")
    with pytest.raises(ValueError, match="a box budget bounds single rays: bundle 8x8"):
        trace_rays(geom, Options(precision="f64", bundle="8x8"), origins, dirs, 0.0,
                   budget=(1.0, np.zeros((8, 8), np.int32)))


def test_a_box_budget_bounds_each_ray_and_marks_where_it_ran_out():
    """The float64 reference's bound: a ray may compute `budget` boxes; one that needed fewer is
    untouched, one that needed more stops there (a box or two over) and is marked unresolved."""
    from tracer.records import BUDGET_FLOOR
    from tracer.render import trace_rays
    scene = _scene("teapot")
    geom = prepare(scene, "f64")
    view = view_of(scene)
    origins, dirs = primary_rays(view, 24, 24, "f64")
    opts = Options(precision="f64", bundle="1x1")  # a budget bounds single rays
    free = trace_rays(geom, opts, origins, dirs, 0.0)
    budget = 200
    cut = trace_rays(geom, opts, origins, dirs, 0.0,
                     budget=(budget / BUDGET_FLOOR, np.zeros(free.hit.shape, np.int32)))
    under = free.effort < budget
    over = free.effort > budget + 1
    assert under.any() and over.any() and not free.unresolved.any()
    assert cut.unresolved[over].all() and not cut.unresolved[under].any()
    assert cut.effort.max() <= budget + 2
    for name in CHANNEL_NAMES:
        if name != "unresolved":
            assert np.array_equal(getattr(cut, name)[under], getattr(free, name)[under], equal_nan=True), name
