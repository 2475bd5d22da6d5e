"""The BVH (tracer/bvh.py): the node arrays form one tree over every patch, boxes nest, and the
closest hit found through it is the closest hit over all patches searched one by one.

Seeded; random boxes for the structure, small random patch scenes for the hits.
"""
from __future__ import annotations

import numpy as np
import pytest

import reference as ref
import scenes as S
from tracer.bvh import build_bvh
from tracer.geometry import prepare
from tracer.options import Options


def random_boxes(rng, count: int) -> np.ndarray:
    """(count, 6) boxes of mixed sizes, some overlapping, some far apart, some flat."""
    centre = rng.uniform(-10, 10, (count, 3))
    half = 10.0 ** rng.uniform(-3, 1, (count, 3))
    half[rng.random((count, 3)) < 0.1] = 0.0  # flat boxes (a planar patch along an axis)
    return np.hstack([centre - half, centre + half])


def walk(bvh):
    """(parent of each reached node, depth of each reached node, patches in leaf order) from
    the root with an explicit stack, as the kernel walks it; a node reached twice is an error."""
    parent, depth, leaves = {0: -1}, {0: 1}, []
    stack = [0]
    while stack:
        node = stack.pop()
        left, right = bvh.node_child[node]
        if left < 0:
            assert right < 0 and bvh.node_patch[node] >= 0, f"node {node}: half a leaf"
            leaves.append(int(bvh.node_patch[node]))
            continue
        assert bvh.node_patch[node] == -1, f"inner node {node} also names patch {bvh.node_patch[node]}"
        for child in (int(left), int(right)):
            assert child not in parent, f"node {child} reached twice"
            parent[child] = node
            depth[child] = depth[node] + 1
            stack.append(child)
    return parent, depth, leaves


COUNTS = [1, 2, 3, 7, 64, 257]


@pytest.mark.parametrize("count", COUNTS)
def test_every_patch_reachable_exactly_once(count):
    bvh = build_bvh(random_boxes(np.random.default_rng(count), count))
    parent, depth, leaves = walk(bvh)
    assert sorted(leaves) == list(range(count))
    assert len(parent) == len(bvh.node_patch) == 2 * count - 1  # no unreachable nodes either
    # Bvh.depth sizes the kernel's traversal stack: it must be the real depth
    assert bvh.depth == max(depth.values())


@pytest.mark.parametrize("count", COUNTS)
def test_child_boxes_nest_in_their_parents(count):
    bvh = build_bvh(random_boxes(np.random.default_rng(100 + count), count))
    box = bvh.node_box
    for child, par in walk(bvh)[0].items():
        if par < 0:
            continue
        assert child > par, f"node {child} comes before its parent {par}"  # Bvh.depth relies on it
        assert np.all(box[child, :3] >= box[par, :3]) and np.all(box[child, 3:] <= box[par, 3:]), (
            f"node {child} {box[child]} sticks out of its parent {par} {box[par]}")


@pytest.mark.parametrize("count", COUNTS)
def test_leaf_boxes_contain_their_patch_boxes(count):
    boxes = random_boxes(np.random.default_rng(200 + count), count)
    bvh = build_bvh(boxes)
    leaf = bvh.node_patch >= 0
    mine = boxes[bvh.node_patch[leaf]]
    assert np.all(bvh.node_box[leaf, :3] <= mine[:, :3]) and np.all(bvh.node_box[leaf, 3:] >= mine[:, 3:])
    assert np.array_equal(bvh.node_box[0, :3], boxes[:, :3].min(axis=0))  # the root is the scene's box
    assert np.array_equal(bvh.node_box[0, 3:], boxes[:, 3:].max(axis=0))


def grid_boxes(rng, side: int) -> np.ndarray:
    """Unit-quad boxes of a side x side grid, a few lifted, shuffled: many equal centroids along
    every axis, so the tie-breaking order decides most splits."""
    i, j = np.meshgrid(np.arange(side, dtype=float), np.arange(side, dtype=float))
    lo = np.column_stack([i.ravel(), j.ravel(), np.zeros(side * side)])
    hi = lo + [1.0, 1.0, 0.0]
    hi[rng.random(side * side) < 0.2, 2] = 0.5
    return np.hstack([lo, hi])[rng.permutation(side * side)]


TREES = [("random", 1), ("random", 2), ("random", 300), ("random", 1000), ("grid", 5), ("grid", 24),
         ("duplicates", 200)]


@pytest.mark.parametrize("kind,count", TREES)
def test_tree_is_the_reference_builders_bit_for_bit(kind, count):
    """The compiled builder makes the tree of the per-node stable argsort (tests/reference.py),
    node for node, so renders through it are unchanged."""
    rng = np.random.default_rng(300 + count)
    if kind == "random":
        boxes = random_boxes(rng, count)
    elif kind == "grid":
        boxes = grid_boxes(rng, count)
    else:  # a few distinct boxes, each many times
        boxes = random_boxes(rng, 7)[rng.integers(7, size=count)]
    bvh = build_bvh(boxes)
    node_box, node_child, node_patch = ref.build_bvh(boxes)
    assert np.array_equal(bvh.node_child, node_child)
    assert np.array_equal(bvh.node_patch, node_patch)
    assert np.array_equal(bvh.node_box, node_box)


def test_tree_of_the_teapot_leaves_is_the_reference_builders():
    geom = prepare(S.teapot(floor=True), "f32")
    node_box, node_child, node_patch = ref.build_bvh(geom.leaf_box)
    assert np.array_equal(geom.bvh.node_child, node_child) and np.array_equal(geom.bvh.node_patch, node_patch)
    assert np.array_equal(geom.bvh.node_box, node_box)


@pytest.mark.parametrize("scale", [1e300, 1e-300])
def test_extreme_scales_build_the_tree_of_the_scene_at_unit_scale(scale):
    """Split costs are computed on boxes scaled by a power of two (bvh.cost_scale): at 1e300 the
    areas would overflow, at 1e-300 underflow to zero. The tree is the one of the same boxes
    near unit scale; node boxes stay the unscaled boxes' unions."""
    boxes = random_boxes(np.random.default_rng(7), 300)
    p2 = 2.0 ** np.round(np.log2(scale))
    big = build_bvh(boxes * p2)
    unit = build_bvh(boxes)
    assert np.array_equal(big.node_child, unit.node_child) and np.array_equal(big.node_patch, unit.node_patch)
    leaf = big.node_patch >= 0
    mine = boxes[big.node_patch[leaf]] * p2
    assert np.all(big.node_box[leaf, :3] <= mine[:, :3]) and np.all(big.node_box[leaf, 3:] >= mine[:, 3:])
    assert big.depth == unit.depth


def test_boxes_spanning_the_float64_range_build_a_tree():
    """Coordinates from -1.7e308 to 1.7e308: extents and centroid sums overflow unscaled."""
    boxes = random_boxes(np.random.default_rng(8), 100) * 8e306  # |coordinates| < 20
    bvh = build_bvh(boxes)
    _, _, leaves = walk(bvh)
    assert sorted(leaves) == list(range(100))


def test_boxes_that_are_not_finite_are_an_error():
    boxes = random_boxes(np.random.default_rng(9), 4)
    boxes[2, 4] = np.inf
    with pytest.raises(ValueError, match="not finite"):
        build_bvh(boxes)


def test_empty_scene_is_an_error():
    with pytest.raises(ValueError, match="empty"):
        build_bvh(np.zeros((0, 6)))


def test_scene_geometry_bvh_covers_every_leaf():
    """The BVH prepare() builds over the pre-split teapot leaves and its floor."""
    geom = prepare(S.teapot(floor=True), "f32")
    bvh = geom.bvh
    _, _, leaves = walk(bvh)
    assert sorted(leaves) == list(range(geom.n_patches))
    leaf = bvh.node_patch >= 0
    mine = geom.leaf_box[bvh.node_patch[leaf]]
    assert np.all(bvh.node_box[leaf, :3] <= mine[:, :3]) and np.all(bvh.node_box[leaf, 3:] >= mine[:, 3:])


# ---- closest hit through the BVH against a brute force over the patches ------------------

def spread_patches(rng, count: int) -> list:
    """Smooth random bicubics scattered through a cube, tilted at random: rays pass several."""
    grids = []
    for _ in range(count):
        P = S.smooth_patch(rng, 3, 3, size=rng.uniform(1.0, 3.0))
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))  # a random rotation (or reflection)
        grids.append((P - P.mean(axis=(0, 1))) @ q.T + rng.uniform(-4, 4, 3))
    return grids


def random_rays(rng, grids, count: int):
    """Rays from outside the patches' box, from random directions, aimed at random points of
    random patches (so most hit, and many cross other patches on the way)."""
    pts = np.concatenate([P.reshape(-1, 3) for P in grids])
    size = np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))
    which = rng.integers(len(grids), size=count)
    targets = np.array([ref.evaluate(grids[k], *rng.uniform(0, 1, 2)) for k in which])
    way = rng.normal(size=(count, 3))
    origins = targets + 2.0 * size * way / np.linalg.norm(way, axis=1, keepdims=True)
    return origins, targets - origins


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_closest_hit_through_the_bvh_is_the_closest_over_all_patches(seed):
    """presplit=0 makes every scene patch one BVH leaf; each patch traced alone (a one-leaf BVH:
    no traversal) is the brute force. float64, float criterion: a patch's search does not depend
    on the other patches, so t is the same bit for bit where the closest patch is clear."""
    rng = np.random.default_rng(seed)
    grids = spread_patches(rng, 12)
    origins, dirs = random_rays(rng, grids, 150)
    opts = Options(precision="f64")
    whole = S.trace(prepare(S.patches_scene(grids, separate=True), "f64", presplit=0), origins, dirs, opts)
    alone = np.stack([S.trace(prepare(S.patches_scene([P]), "f64", presplit=0), origins, dirs, opts).t[0]
                      for P in grids])  # (patches, rays)
    order = np.sort(alone, axis=0)
    nearest = np.argmin(alone, axis=0)
    hit = np.isfinite(order[0])
    # two patches within a hair of each other along the ray: either may be reported
    with np.errstate(invalid="ignore"):  # inf - inf on rays that miss
        clear = ~hit | (order[1] - order[0] > 1e-9 * np.abs(order[0]))
    assert np.array_equal(whole.hit[0], hit)
    assert np.array_equal(whole.t[0][clear], order[0][clear])
    assert np.array_equal(whole.patch[0][clear & hit], nearest[clear & hit])
    assert hit.sum() > 120 and (np.isfinite(order[1]) & clear).sum() > 20  # many rays cross several patches
