"""The kd-tree and the uniform grid (tracer/kdtree.py, grid.py, cell_walk.py, accel.py).

Structure: every patch is listed where its box (kd-tree) or its true surface (grid) lies, checked
by points, not by re-running the builders' rules. Hits: through either structure, with either
mailbox setting, the closest hit is the brute force's over all patches and the BVH's, pixel for
pixel: the same hit mask and patch, the position within the BVH's hit box size (the tolerance of
tests/test_iges_render.py: which of two boxes holding the crossing is accepted can depend on the
interval a search was given, and a cell's search is clamped to the cell), and the very same box in
nearly every pixel. Seeded, tiny images, float32 only (one compiled variant per scene kind).
"""
from __future__ import annotations

import gc

import numpy as np
import pytest

import reference as ref
import scenes as S
from test_bvh import random_boxes, random_rays, spread_patches
from tracer import accel
from tracer.camera import primary_rays, view_of
from tracer.geometry import prepare
from tracer.grid import build_grid
from tracer.kdtree import build_kdtree
from tracer.options import Options
from tracer.records import BUDGET_FLOOR
from tracer.render import render, trace_rays
from tracer.scene import load_scene
from tracer.stats import frame_stats

SIZE = (24, 24)
KINDS = [Options(accel="kdtree"), Options(accel="kdtree", mailbox=True), Options(accel="kdtree", kd_split="middle"),
         Options(accel="grid"), Options(accel="grid", mailbox=True)]
KIND_IDS = ["kd-sah", "kd-sah-mailbox", "kd-middle", "grid", "grid-mailbox"]


def _sample(name):
    return load_scene(S.SAMPLES / f"{name}.json")


# ---- structure -----------------------------------------------------------------------------

def kd_leaves_of(tree, point):
    """The leaves whose closed voxel holds `point`, by descending the tree (both sides on a plane)."""
    out, todo = [], [0]
    while todo:
        node = todo.pop()
        axis = tree.node_axis[node]
        if axis < 0:
            out.append(node)
            continue
        x, split = point[axis], tree.node_split[node]
        if x <= split:
            todo.append(node + 1)
        if x >= split:
            todo.append(tree.node_above[node])
    return out


def kd_listed(tree, leaf):
    return set(tree.items[tree.node_first[leaf]:tree.node_first[leaf] + tree.node_count[leaf]].tolist())


@pytest.mark.parametrize("rule", ["sah", "middle"])
@pytest.mark.parametrize("count", [pytest.param(1, marks=pytest.mark.interpreted),
                                   pytest.param(7, marks=pytest.mark.interpreted), 2, 300])
def test_kdtree_lists_every_patch_wherever_its_box_lies(rule, count):
    """Points inside each box (its corners too): some leaf whose voxel holds the point lists the
    patch, and a point strictly inside one leaf's voxel has only that leaf to be listed in."""
    rng = np.random.default_rng(count)
    boxes = random_boxes(rng, count)
    tree = build_kdtree(boxes, 12, rule)
    assert tree.depth <= 12
    inner = np.flatnonzero(tree.node_axis >= 0)
    assert np.all(tree.node_above[inner] > inner + 1)  # the below child is node + 1, the above one later
    leaves = tree.node_axis < 0
    assert tree.node_count[leaves].sum() == len(tree.items)
    assert set(tree.items.tolist()) == set(range(count))
    for p in range(count):
        lo, hi = boxes[p, :3], boxes[p, 3:]
        corners = np.array([[(hi if k >> a & 1 else lo)[a] for a in range(3)] for k in range(8)])
        for point in np.vstack([corners, rng.uniform(lo, hi, (6, 3))]):
            assert any(p in kd_listed(tree, leaf) for leaf in kd_leaves_of(tree, point)), (p, point)


def test_kdtree_stops_at_its_depth_and_on_patches_no_plane_separates():
    rng = np.random.default_rng(4)
    boxes = random_boxes(rng, 200)
    for depth in (0, 1, 5):
        tree = build_kdtree(boxes, depth, "sah")
        assert tree.depth <= depth
    same = np.tile(boxes[:1], (50, 1))  # fifty copies of one box: no plane splits any off
    tree = build_kdtree(same, 20, "middle")
    assert len(tree.node_axis) == 1 and tree.node_count[0] == 50
    tree = build_kdtree(same, 20, "sah")
    assert len(tree.node_axis) == 1


def leaf_points(geom, p, k=7):
    """World points of leaf p's true (float64) surface on a k x k parameter grid."""
    m, n = int(geom.deg_u[p]), int(geom.deg_v[p])
    pts = geom.ctrl64[:, geom.pstart[p]:geom.pstart[p + 1]].T.reshape(n + 1, m + 1, 4).transpose(1, 0, 2)
    ts = np.linspace(0.0, 1.0, k)
    h = np.array([ref.evaluate(pts, u, v) for u in ts for v in ts])
    return h[:, :3] / h[:, 3:] + geom.frame[p]


def grid_cell_of(grid, point):
    i = np.clip(np.floor((point - grid.bounds[:3]) / grid.cell), 0, grid.dims - 1).astype(int)
    return (i[2] * grid.dims[1] + i[1]) * grid.dims[0] + i[0]


@pytest.mark.parametrize("name,scale", [("teapot", 1.0), ("teapot", 0.0625), ("teapot", 8.0), ("sphere", 1.0),
                                        ("plate", 1.0)])
def test_grid_lists_every_patch_in_the_cells_its_surface_passes(name, scale):
    """Points of each leaf's float64 surface (rational ones too): the cell holding the point lists
    the leaf. Each leaf is listed only in cells its box meets, and once."""
    geom = prepare(_sample(name), "f32")
    grid = build_grid(geom, scale)
    assert grid.cell_start[-1] == len(grid.items) and np.all(np.diff(grid.cell_start) >= 0)
    cell_of_item = np.repeat(np.arange(len(grid.cell_start) - 1), np.diff(grid.cell_start))
    pairs = cell_of_item * geom.n_patches + grid.items
    assert len(np.unique(pairs)) == len(pairs)
    for p in range(0, geom.n_patches, max(1, geom.n_patches // 300)):
        listed = set(cell_of_item[grid.items == p].tolist())
        cells = {grid_cell_of(grid, x) for x in leaf_points(geom, p)}
        assert cells <= listed, (p, sorted(cells - listed)[:5])
        lo = np.floor((geom.leaf_box[p, :3] - grid.bounds[:3]) / grid.cell) - 1
        hi = np.floor((geom.leaf_box[p, 3:] - grid.bounds[:3]) / grid.cell) + 1
        for c in listed:
            ijk = np.array([c % grid.dims[0], c // grid.dims[0] % grid.dims[1], c // (grid.dims[0] * grid.dims[1])])
            assert np.all((lo <= ijk) & (ijk <= hi)), (p, c)


def test_grid_resolution_follows_lischinskis_rule_and_its_memory_bound():
    from tracer import grid as G
    geom = prepare(S.patches_scene([S.smooth_patch(np.random.default_rng(3), 3, 3)]), "f32", presplit=0)
    g = build_grid(geom, 1.0)
    side = np.mean(geom.leaf_box[:, 3:] - geom.leaf_box[:, :3]) / 4.0
    extent = g.bounds[3:] - g.bounds[:3]
    assert np.array_equal(g.dims, np.maximum(1, np.ceil(extent / side)).astype(int)) and g.coarsened == 1.0
    fine = build_grid(geom, 8.0)
    assert np.array_equal(fine.dims, np.ceil(8.0 * extent / side).astype(int)) and np.all(fine.dims > 5 * g.dims)
    teapot = prepare(_sample("teapot"), "f32")
    capped = build_grid(teapot, 8.0)
    assert len(capped.cell_start) - 1 <= G.MAX_CELLS and capped.coarsened > 1.0


# ---- hits --------------------------------------------------------------------------------------

def _agree(frame, base, what, same_box=0.99):
    """frame agrees with the BVH's base frame: hit mask and patch everywhere, position within the
    base's hit box size, and the same hit box in at least `same_box` of the hits."""
    assert np.array_equal(frame.hit, base.hit), f"{what}: {np.sum(frame.hit != base.hit)} pixels hit differently"
    hit = base.hit
    assert np.array_equal(frame.patch[hit], base.patch[hit]), f"{what}: other patches"
    size = base.box_max[hit] - base.box_min[hit]
    assert np.all(np.abs(frame.position[hit] - base.position[hit]) <= size), what
    same = np.mean(np.all((frame.box_min[hit] == base.box_min[hit]) & (frame.box_max[hit] == base.box_max[hit]), -1))
    assert same >= same_box, f"{what}: the same hit box in {100 * same:.2f} % of the hits"


@pytest.mark.parametrize("opts", KINDS, ids=KIND_IDS)
@pytest.mark.parametrize("name", ["teapot", "plate", "sphere"])
def test_hits_are_the_bvh_hits(name, opts):
    scene = _sample(name)
    geom = prepare(scene, "f32")
    base = render(scene, Options(), size=SIZE, geometry=geom)
    frame = render(scene, opts, size=SIZE, geometry=geom)
    assert base.hit.sum() > 50
    _agree(frame, base, f"{name} {opts.accel}")
    a = frame.extras["accel"]
    assert a["kind"] == opts.accel and a["mailbox"] == opts.mailbox and a["items"] >= geom.n_patches
    # counters: every ray that hits visited a node or cell; a search is preceded by its box test
    assert np.all(frame.nodes[frame.hit] >= 1) and np.all(frame.patches_tested[frame.hit] >= 1)
    assert np.all(frame.patches_tested <= frame.surfaces_tested)
    assert np.all(frame.effort >= frame.patches_tested)
    assert np.all(frame.box_tests >= frame.surfaces_tested + frame.effort)
    if opts.mailbox:  # a patch is tested once per ray at most
        assert frame.surfaces_tested.max() <= geom.n_patches


def random_patch_scene(count, seed):
    """`count` small smooth bicubics scattered through a cube, tilted at random."""
    rng = np.random.default_rng(seed)
    grids = []
    for _ in range(count):
        P = S.smooth_patch(rng, 3, 3, size=rng.uniform(0.5, 1.5))
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        grids.append((P - P.mean(axis=(0, 1))) @ q.T + rng.uniform(-5, 5, 3))
    return S.patches_scene(grids, separate=True)


@pytest.fixture(scope="module")
def crowd():
    """300 random patches (4,800 leaves) seen from outside their cube, and the BVH's frame."""
    scene = random_patch_scene(300, 11)
    geom = prepare(scene, "f32")
    view = S.aim((0.0, 0.0, 0.0), (0.6, -0.7, 0.4), 22.0, 45.0)
    return scene, geom, view, render(scene, Options(), size=(32, 32), view=view, geometry=geom)


@pytest.mark.parametrize("opts", KINDS + [Options(accel="kdtree", kd_depth=4), Options(accel="kdtree", kd_depth=40),
                                          Options(accel="grid", grid_scale=0.0625),
                                          Options(accel="grid", grid_scale=8.0, mailbox=True)],
                         ids=KIND_IDS + ["kd-depth-4", "kd-depth-40", "grid-coarsest", "grid-finest-mailbox"])
def test_hits_among_hundreds_of_patches_are_the_bvh_hits(crowd, opts):
    scene, geom, view, base = crowd
    frame = render(scene, opts, size=(32, 32), view=view, geometry=geom)
    assert base.hit.sum() > 300
    _agree(frame, base, str(opts.accel))


@pytest.mark.parametrize("opts", KINDS, ids=KIND_IDS)
def test_closest_hit_is_the_closest_over_all_patches(opts):
    """Each patch traced alone (through the BVH of a one-patch scene) is the brute force. A scene of
    one patch resolves hits on a finer grid than the whole (geometry.grid_steps: never coarser than
    at the scene's half-extent), so positions agree to the two hit boxes' sizes together."""
    rng = np.random.default_rng(5)
    grids = spread_patches(rng, 12)
    origins, dirs = random_rays(rng, grids, 150)
    whole = S.trace(prepare(S.patches_scene(grids, separate=True), "f32", presplit=0), origins, dirs, opts)
    alone = [S.trace(prepare(S.patches_scene([P]), "f32", presplit=0), origins, dirs) for P in grids]
    t = np.stack([f.t[0] for f in alone])
    order = np.sort(t, axis=0)
    nearest = np.argmin(t, axis=0)
    hit = np.isfinite(order[0])
    with np.errstate(invalid="ignore"):  # inf - inf on rays that miss
        clear = ~hit | (order[1] - order[0] > 1e-4 * np.abs(order[0]))
    assert np.array_equal(whole.hit[0], hit)
    rays = np.flatnonzero(clear & hit)
    assert np.array_equal(whole.patch[0][rays], nearest[rays])
    for r in rays:
        mine = alone[nearest[r]]
        size = mine.box_max[0, r] - mine.box_min[0, r] + whole.box_max[0, r] - whole.box_min[0, r]
        assert np.all(np.abs(whole.position[0, r] - mine.position[0, r]) <= size), r
    assert hit.sum() > 120 and (np.isfinite(order[1]) & clear).sum() > 20  # many rays cross several patches


@pytest.mark.parametrize("opts", [Options(accel="kdtree"), Options(accel="grid", mailbox=True)], ids=["kd", "grid"])
def test_any_hit_finds_a_hit_exactly_where_closest_hit_does(opts):
    scene = _sample("teapot")
    geom = prepare(scene, "f32")
    view = view_of(scene)
    origins, dirs = primary_rays(view, *SIZE, "f32")
    closest = trace_rays(geom, opts, origins, dirs, 0.0)
    anyhit = trace_rays(geom, opts, origins, dirs, 0.0, driver="any")
    assert closest.hit.sum() > 50 and np.array_equal(anyhit.hit, closest.hit)
    assert np.all(anyhit.effort <= closest.effort)  # the same boxes up to its first hit box, where it stops


@pytest.mark.parametrize("opts", [Options(accel="kdtree"), Options(accel="grid")], ids=["kd", "grid"])
def test_a_box_budget_bounds_each_ray_and_marks_where_it_ran_out(opts):
    scene = _sample("teapot")
    geom = prepare(scene, "f32")
    origins, dirs = primary_rays(view_of(scene), *SIZE, "f32")
    free = trace_rays(geom, opts, origins, dirs, 0.0)
    budget = 80
    cut = trace_rays(geom, opts, origins, dirs, 0.0, budget=(budget / BUDGET_FLOOR, np.zeros(SIZE, np.int32)))
    under, over = free.effort < budget, free.effort > budget + 1
    assert under.any() and over.any() and not free.unresolved.any()
    assert cut.unresolved[over].all() and not cut.unresolved[under].any()
    assert cut.effort.max() <= budget + 2
    for name in ("hit", "t", "patch", "box_min", "effort"):
        assert np.array_equal(getattr(cut, name)[under], getattr(free, name)[under], equal_nan=True), name


# ---- degenerate scenes -------------------------------------------------------------------------

def _degenerate(kind):
    rng = np.random.default_rng(8)
    if kind == "one patch":
        return S.patches_scene([S.smooth_patch(rng, 3, 3)])
    if kind == "all in one place":
        return S.patches_scene([S.smooth_patch(np.random.default_rng(8), 3, 3)] * 20, separate=True)
    # a flat scene: bilinear quads in the plane z = 0
    quads = [np.array([[[x, y, 0.0], [x, y + 1, 0.0]], [[x + 1, y, 0.0], [x + 1, y + 1, 0.0]]])
             for x in range(-3, 3) for y in range(-3, 3)]
    return S.patches_scene(quads)


@pytest.mark.parametrize("kind", ["one patch", "all in one place", "flat"])
def test_degenerate_scenes_render_as_through_the_bvh(kind):
    scene = _degenerate(kind)
    geom = prepare(scene, "f32")
    view = S.aim((0.5, 0.5, 0.0), (0.3, -0.4, 1.0), 12.0, 40.0)
    base = render(scene, Options(), size=(16, 16), view=view, geometry=geom)
    assert base.hit.any()
    for opts in (Options(accel="kdtree", kd_split="middle"), Options(accel="kdtree", mailbox=True),
                 Options(accel="grid", grid_scale=8.0), Options(accel="grid", grid_scale=0.0625)):
        _agree(render(scene, opts, size=(16, 16), view=view, geometry=geom), base, f"{kind} {opts.accel}", 0.95)


@pytest.mark.interpreted
def test_both_walks_give_the_bvh_hits_on_a_few_rays():
    """Small enough to run interpreted too (tests/test_interpreted.py)."""
    scene = _degenerate("one patch")
    geom = prepare(scene, "f32")
    view = S.aim((1.0, 1.0, 0.0), (0.3, -0.4, 1.0), 6.0, 30.0)
    base = render(scene, Options(), size=(6, 6), view=view, geometry=geom)
    assert base.hit.sum() > 10
    for opts in (Options(accel="kdtree"), Options(accel="grid", mailbox=True)):
        _agree(render(scene, opts, size=(6, 6), view=view, geometry=geom), base, opts.accel, 1.0)


def test_boxes_that_are_not_finite_or_no_boxes_are_an_error():
    boxes = random_boxes(np.random.default_rng(9), 4)
    boxes[1, 2] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        build_kdtree(boxes)
    with pytest.raises(ValueError, match="empty"):
        build_kdtree(np.zeros((0, 6)))
    with pytest.raises(ValueError, match="split rule"):
        build_kdtree(random_boxes(np.random.default_rng(9), 4), 20, "median")


# ---- the cache and the report ------------------------------------------------------------------

def test_a_structure_is_built_once_per_geometry_and_parameters_and_goes_with_its_geometry():
    scene = _sample("teapot")
    geom = prepare(scene, "f32")
    before = accel.cached_count()
    first = render(scene, Options(accel="kdtree"), size=(4, 4), geometry=geom).extras["accel"]
    again = render(scene, Options(accel="kdtree", mailbox=True), size=(4, 4), geometry=geom).extras["accel"]
    other = render(scene, Options(accel="kdtree", kd_depth=8), size=(4, 4), geometry=geom).extras["accel"]
    assert first["built_now"] and not again["built_now"] and other["built_now"]
    assert again["build_seconds"] == first["build_seconds"] > 0 and other["depth"] <= 8
    for key in ("nodes", "leaves", "items", "depth", "mean_items_per_leaf", "bytes"):
        assert first[key] > 0, key
    assert accel.cached_count() == before + 2
    del geom
    gc.collect()
    assert accel.cached_count() == before


def test_the_report_reaches_the_stats():
    scene = _sample("teapot")
    frame = render(scene, Options(accel="grid"), size=(4, 4))
    stats = frame_stats(frame)["accel"]
    assert stats["kind"] == "grid" and stats["cells"] == np.prod(stats["dims"]) and stats["bytes"] > 0
    bvh = frame_stats(render(scene, Options(), size=(4, 4)))["accel"]
    assert bvh["kind"] == "bvh" and bvh["nodes"] == 2 * bvh["leaves"] - 1


def test_the_command_line_reports_the_build(tmp_path, capsys):
    import json

    from psrt.cli import main
    stats = tmp_path / "stats.json"
    teapot = str(S.SAMPLES / "teapot.json")
    assert main(["render", teapot, "-o", str(tmp_path / "img.png"), "--size", "12x10", "--accel", "kdtree",
                 "--kd-split", "middle", "--mailbox", "--stats", str(stats)]) == 0
    a = json.loads(stats.read_text())["accel"]
    assert a["kind"] == "kdtree" and a["parameters"] == {"kd_depth": 20, "kd_split": "middle"} and a["mailbox"]
    assert a["build_seconds"] >= 0 and a["nodes"] > 1 and a["bytes"] > 0
    assert "kd-tree built in" in capsys.readouterr().err or not a["built_now"]


def test_the_viewers_stats_panel_describes_each_structure():
    from viewer.ui_stats import accel_lines
    scene = _sample("teapot")
    geom = prepare(scene, "f32")
    for opts, word in ((Options(), "BVH"), (Options(accel="kdtree"), "leaves"), (Options(accel="grid"), "cells")):
        lines = accel_lines(render(scene, opts, size=(4, 4), geometry=geom).extras["accel"])
        assert lines and word in " ".join(lines)


def test_the_variant_and_the_pixel_inspector_follow_the_structure():
    from tracer.trace_one import trace_pixel
    from tracer.variants import label, variant_for
    scene = _sample("teapot")
    geom = prepare(scene, "f32")
    assert variant_for(geom, Options(accel="grid")).accel == "grid"
    assert label(variant_for(geom, Options(accel="kdtree"))).endswith(" kdtree")
    opts = Options(accel="kdtree")
    frame = render(scene, opts, size=SIZE, geometry=geom)
    for y, x in np.argwhere(frame.hit)[::97]:
        tr = trace_pixel(scene, opts, int(x), int(y), size=SIZE, geometry=geom)
        assert tr.hit and tr.patch == frame.patch[y, x] and np.array_equal(tr.box_min, frame.box_min[y, x])


@pytest.mark.parametrize("module", ["accel", "penumbra"])
def test_a_geometry_collected_during_a_build_does_not_deadlock(module):
    """A build holds the module's lock and allocates; the collector may free an earlier geometry
    there, whose finalizer (_forget) takes the same lock on the same thread. Found as a bit dump
    hanging for good in a kd-tree build."""
    import threading

    from tracer import penumbra
    mod = {"accel": accel, "penumbra": penumbra}[module]

    def build_while_collecting():
        with mod._LOCK:
            mod._forget(("a geometry", "collected", "meanwhile"))

    worker = threading.Thread(target=build_while_collecting, daemon=True)
    worker.start()
    worker.join(timeout=30)
    assert not worker.is_alive(), f"{module}._forget waited for the lock its own thread holds"
