"""Acceleration structures side by side: build time, size and frame time of the BVH, kd-tree and grid.

    .venv/bin/python tests/bench_accel.py [--size 256] [--runs 5] [--teapots 36 800] [--threads 0]

Scenes: the sample teapot on its floor, and fields of N teapots (32 patches each; a jittered
square grid, each teapot scaled 0.6-1.4 and turned about z, seeded) for each N of --teapots. For
each scene and configuration: the structure's build (seconds, best of --runs builds; the BVH's by
build_bvh over the same leaves), its size, and the frame time of a float32 render (median of
--runs; the configurations take turns within each run, so drift of the machine's speed hits them
alike) with its ratio to the BVH's frame, and the mean counters per ray. Kernels are compiled (or
loaded from the cache) by a warm-up render first.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import scenes as S  # noqa: E402
from tracer import accel  # noqa: E402
from tracer.bvh import build_bvh  # noqa: E402
from tracer.camera import view_of  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import load_scene, scene_from_dict  # noqa: E402

CONFIGS = [("bvh", Options()),
           ("kd sah 20", Options(accel="kdtree")),
           ("kd sah 20 mailbox", Options(accel="kdtree", mailbox=True)),
           ("kd sah 10", Options(accel="kdtree", kd_depth=10)),
           ("kd sah 30", Options(accel="kdtree", kd_depth=30)),
           ("kd middle 20", Options(accel="kdtree", kd_split="middle")),
           ("kd middle 20 mailbox", Options(accel="kdtree", kd_split="middle", mailbox=True)),
           ("grid 1", Options(accel="grid")),
           ("grid 1 mailbox", Options(accel="grid", mailbox=True)),
           ("grid 0.25", Options(accel="grid", grid_scale=0.25)),
           ("grid 0.25 mailbox", Options(accel="grid", grid_scale=0.25, mailbox=True))]


def teapot_field(count: int, seed: int = 1):
    """`count` teapots on a jittered square grid (spacing 8), each scaled and turned at random."""
    import numpy as np
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(count))
    objects = []
    for k in range(count):
        s, a = rng.uniform(0.6, 1.4), rng.uniform(0, 2 * math.pi)
        x, y = 8.0 * (k % side - side / 2) + rng.uniform(-1, 1), 8.0 * (k // side - side / 2) + rng.uniform(-1, 1)
        c, n = s * math.cos(a), s * math.sin(a)
        objects.append({"file": S.TEAPOT_BPT, "transform": [c, -n, 0, x, n, c, 0, y, 0, 0, s, 0, 0, 0, 0, 1]})
    half = 4.0 * side
    camera = {"eye": [0.3 * half, -1.6 * half, 0.9 * half], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 45}
    return S.load({"objects": objects, "camera": camera}, f"{count} teapots")


def bench(scene, size, runs, threads):
    geom = prepare(scene, "f32")
    view = view_of(scene)
    rows = {}
    for name, opts in CONFIGS:
        opts = opts.with_(threads=threads)
        frame = render(scene, opts, size=size, view=view, geometry=geom)  # compiles; builds
        builds = []
        for _ in range(runs):
            start = time.perf_counter()
            build_bvh(geom.leaf_box) if opts.accel == "bvh" else accel.build_structure(geom, opts)
            builds.append(time.perf_counter() - start)
        rows[name] = {"opts": opts, "build": min(builds), "accel": frame.extras["accel"], "times": [],
                      "counters": {k: float(getattr(frame, k).mean())
                                   for k in ("nodes", "surfaces_tested", "patches_tested", "effort")}}
    for _ in range(runs):
        for name, row in rows.items():
            row["times"].append(render(scene, row["opts"], size=size, view=view, geometry=geom).seconds)
    base = statistics.median(rows["bvh"]["times"])
    print(f"{scene.path}: {scene.n_patches} patches, {geom.n_patches} leaves, {size[0]}x{size[1]}, "
          f"{runs} runs, threads {threads or 'all'}")
    print(f"{'structure':<22}{'build s':>9}{'MiB':>8}{'nodes/cells':>12}{'items':>9}{'per leaf':>9}"
          f"{'frame s':>9}{'/ bvh':>7}{'nodes':>8}{'boxes':>7}{'searches':>9}{'effort':>8}")
    for name, row in rows.items():
        a = row["accel"]
        c = row["counters"]
        frame = statistics.median(row["times"])
        per = a.get("mean_items_per_full_leaf", a.get("mean_items_per_full_cell", a.get("mean_items_per_leaf")))
        print(f"{name:<22}{row['build']:9.3f}{a['bytes'] / 2**20:8.2f}{a.get('cells', a.get('nodes')):12d}"
              f"{a['items']:9d}{per:9.2f}{frame:9.3f}{frame / base:7.2f}{c['nodes']:8.1f}"
              f"{c['surfaces_tested']:7.2f}{c['patches_tested']:9.2f}{c['effort']:8.1f}")
    print()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--teapots", type=int, nargs="*", default=[36, 800])
    parser.add_argument("--threads", type=int, default=0)
    args = parser.parse_args(argv)
    size = (args.size, args.size)
    bench(load_scene(S.SAMPLES / "teapot.json"), size, args.runs, args.threads)
    for n in args.teapots:
        bench(teapot_field(n), size, args.runs, args.threads)


if __name__ == "__main__":
    main()
