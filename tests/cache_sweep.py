"""Trees the surface-tree cache had to make again, per pixel order and cache bound: the deterministic
counters behind the order table of `psrt bench --coherence`, over more bounds, and where the
re-made trees are searched in the image.

    .venv/bin/python tests/cache_sweep.py [--scenes teapot flying] [--size 256] [--mb 1 2 4 8 16]
        [--orders scanline peano] [--where 4] [--set cache_depth=2 ...]

Primary rays, one render thread, the plain options of the bench (float, 1x1, BVH) with the cache;
each frame starts with an empty cache. Per order and bound: the hit ratio and the trees re-made
(cache misses beyond each surface's first, the first ones being the same in every order); --where
MB: the image columns and rows that hold the most re-made trees at that bound (the seams where an
order comes back to surfaces it searched long before: a tiled scanline at its tile rows, the
Hilbert curve where its first and last quadrants meet).
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tracer.bench_coherence import PLAIN, unbounded_cache_mb  # noqa: E402
from tracer.bench_scenes import scene_label, scene_path  # noqa: E402
from tracer.camera import primary_rays, view_of  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.render import fresh_caches, trace_rays  # noqa: E402
from tracer.scene import load_scene  # noqa: E402


def _settings(pairs) -> dict:
    out = {}
    for pair in pairs:
        key, _, value = pair.partition("=")
        out[key] = type(getattr(Options(), key))(value)
    return out


def _most(counts, k=4) -> str:
    top = np.argsort(counts, kind="stable")[::-1][:k]
    return ", ".join(f"{i}: {counts[i]}" for i in top if counts[i] > 0) or "none"


def sweep(name: str, size: int, mbs, orders, where, settings) -> None:
    scene = load_scene(scene_path(name))
    base = Options().with_(**PLAIN).with_(threads=1, **settings)
    geom, view = prepare(scene, base.precision), view_of(scene)
    origins, dirs = primary_rays(view, size, size, base.precision)

    def frame(order, mb):
        opts = base.with_(order=order, cache=True, cache_mb=mb)
        fresh_caches(geom, opts)
        return trace_rays(geom, opts, origins, dirs, view.pixel_angle(size), view=view)

    every = unbounded_cache_mb(geom, base)
    first = {o: frame(o, every) for o in orders}  # room for every tree: each surface missed once
    searches = {o: int(f.patches_tested.sum()) for o, f in first.items()}
    assert len(set(searches.values())) == 1, f"the orders searched differently: {searches}"
    print(f"{scene_label(name)} at {size}x{size}: {searches[orders[0]]:,} searches of "
          f"{int(first[orders[0]].cache_misses.sum()):,} surfaces; every tree fits in {every:g} MB; "
          f"cache_depth {base.cache_depth}")
    print(f"{'MB':>6}" + "".join(f"  {o + ' ratio':>16} {'re-made':>8}" for o in orders))
    for mb in sorted(set(mbs) | {every}):
        cells = ""
        remade = {}
        for o in orders:
            f = frame(o, mb)
            hits, misses = int(f.cache_hits.sum()), int(f.cache_misses.sum())
            remade[o] = f.cache_misses.astype(np.int64) - first[o].cache_misses
            cells += f"  {hits / (hits + misses):16.6f} {int(remade[o].sum()):8d}"
        print(f"{mb:6g}{cells}", flush=True)
        if where is not None and mb == where:
            for o in orders:
                print(f"    {o}: re-made trees by column {_most(remade[o].sum(axis=0))}; "
                      f"by row {_most(remade[o].sum(axis=1))}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["teapot", "tea_set", "impeller", "flying"])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--mb", type=float, nargs="+", default=[1, 2, 3, 4, 6, 8, 16, 32, 60])
    parser.add_argument("--orders", nargs="+", default=["scanline", "peano"])
    parser.add_argument("--where", type=float, help="a bound (one of --mb) to say where trees were re-made")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE", help="options for every frame")
    args = parser.parse_args(argv)
    for name in args.scenes:
        sweep(name, args.size, args.mb, args.orders, args.where, _settings(args.set))
    return 0


if __name__ == "__main__":
    sys.exit(main())
