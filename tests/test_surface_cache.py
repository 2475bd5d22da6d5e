"""The surface-tree cache (tracer/surface_cache.py): a search with the cache is the search without it.

Under the float, fixed and mantissa criteria with the length split the cached trees are the ones
the box alone decides, so every channel, effort included, is bit for bit the uncached render's:
on a first frame, on a second frame that finds the trees made by the first, and with a pool so
small that trees are released all the time. The least-recently-used queue and the pool's
bookkeeping are checked against a plain Python model.
"""
import numpy as np
import pytest

import digests as D
import tracer.surface_cache as SC
from tracer.geometry import prepare
from tracer.options import PLAIN, Options
from tracer.render import cache_summary, render

CHANNELS = ("hit", "t", "position", "box_min", "box_max", "normal", "uv", "patch", "effort", "nodes",
            "patches_tested", "surfaces_tested")


def _render(name, opts, size=(24, 24)):
    scene, view = D.catalogue()[name][0]()
    geom = prepare(scene, opts.precision)
    return geom, [render(scene, o, size=size, view=view, geometry=geom) for o in opts]


def _same(a, b):
    return [c for c in CHANNELS if not np.array_equal(getattr(a, c), getattr(b, c), equal_nan=True)]


@pytest.mark.parametrize("criterion", ["float", "fixed", "mantissa"])
@pytest.mark.parametrize("name", ["teapot", "sphere", "plate", "impeller", "stress/degree 9x7"])
def test_cached_renders_are_the_uncached_bits(name, criterion):
    scene, view = D.catalogue()[name][0]()
    geom = prepare(scene, "f32")
    plain = Options(criterion=criterion, threads=1, **PLAIN)
    alone = render(scene, plain, size=(24, 24), view=view, geometry=geom)
    first = render(scene, plain.with_(cache=True), size=(24, 24), view=view, geometry=geom)
    again = render(scene, plain.with_(cache=True), size=(24, 24), view=view, geometry=geom)
    assert not _same(first, alone) and not _same(again, alone)
    searches = first.patches_tested.sum()
    assert first.cache_hits.sum() + first.cache_misses.sum() == searches
    assert again.cache_misses.sum() == 0 and again.cache_hits.sum() == searches  # the trees were kept
    assert cache_summary(geom)["nodes"] > 0


def test_a_pool_too_small_for_the_scene_releases_trees_and_changes_nothing():
    scene, view = D.catalogue()["teapot"][0]()
    geom = prepare(scene, "f32")
    alone = render(scene, Options(threads=1, **PLAIN), size=(32, 32), view=view, geometry=geom)
    tiny = Options(threads=1, **PLAIN).with_(cache=True, cache_mb=1.0, cache_depth=30)
    frame = render(scene, tiny, size=(32, 32), view=view, geometry=geom)
    assert not _same(frame, alone)
    summary = cache_summary(geom)
    assert summary["nodes"] <= summary["capacity"] and summary["released"] > 100


def test_the_queue_and_the_pool_follow_a_python_model():
    """take_pair, touch and release against lists: the least recently searched tree goes first,
    never the one being searched, and every pair is either free or in exactly one tree."""
    cache = SC.new_cache(n_leaves=6, working=4, pairs=5, depth=3)
    first = int(cache.state[SC.S_FIRST])
    model_queue, trees = [], {}
    rng = np.random.default_rng(3)
    for _ in range(400):
        p = int(rng.integers(6))
        SC.touch(cache, p)
        if p in model_queue:
            model_queue.remove(p)
        model_queue.append(p)
        node = SC.take_pair(cache, p)
        expected_victims = []
        free = 5 - sum(len(v) for v in trees.values())
        while free == 0 and model_queue and model_queue[0] != p:
            victim = model_queue.pop(0)
            expected_victims.append(victim)
            free += len(trees.pop(victim, []))
        if free == 0:
            assert node == -1
            continue
        assert node >= first and (node - first) % 2 == 0
        if cache.root[p] < 0:
            cache.root[p] = node
            cache.child[node - first] = -1
            cache.child[node + 1 - first] = -1
            trees.setdefault(p, []).append(node)
        else:  # hang the pair under the tree's root as its halves
            SC.release(cache, p)
            model_queue.remove(p) if p in model_queue else None
            trees.pop(p, None)
            SC.touch(cache, p)
            model_queue.append(p)
            cache.root[p] = node
            cache.child[node - first] = -1
            trees[p] = [node]
        held = {n for v in trees.values() for n in v}
        assert int(cache.state[SC.S_NODES]) == 2 * len(held)
        assert all(cache.root[q] in trees.get(q, [-1]) for q in range(6))
    queue, p = [], int(cache.state[SC.S_HEAD])
    while p >= 0:
        queue.append(p)
        p = int(cache.lru_next[p])
    assert [q for q in queue if q in trees] == [q for q in model_queue if q in trees]


@pytest.mark.parametrize("bundle", ["2x2", "8x8"])
def test_bundles_share_the_cache_and_change_nothing(bundle):
    scene, view = D.catalogue()["teapot"][0]()
    geom = prepare(scene, "f32")
    alone = render(scene, Options(threads=1, **PLAIN), size=(24, 24), view=view, geometry=geom)
    opts = Options(threads=1, bundle=bundle, cache=True)
    first = render(scene, opts, size=(24, 24), view=view, geometry=geom)
    again = render(scene, opts, size=(24, 24), view=view, geometry=geom)
    exact = CHANNELS[:8]  # not the counters: bundles visit nodes and boxes in another order
    for frame in (first, again):
        assert not [c for c in exact if not np.array_equal(getattr(frame, c), getattr(alone, c), equal_nan=True)]
    assert np.array_equal(first.cache_hits + first.cache_misses, first.patches_tested)
    assert again.cache_misses.sum() == 0
