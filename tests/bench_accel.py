"""Acceleration structures side by side on fields of teapots: the accel table of
`psrt bench --coherence` (tracer/bench_coherence.py) on scenes made here.

    .venv/bin/python tests/bench_accel.py [--size 256] [--runs 5] [--teapots 36 800] [--threads 1]

Scenes: the sample teapot on its floor, and fields of N teapots (32 patches each; a jittered
square grid, each teapot scaled 0.6-1.4 and turned about z, seeded) for each N of --teapots. For
each scene: the BVH, kd-trees and grids with their build time and size, and the frame time of a
float32 render with its speed-up against the BVH's in the same run (one render thread: CPU
time; more: wall time). `psrt bench --coherence --tables accel` runs the same rows on the
teapot, the tea set, the impeller and the 25,000 patches of sample_models/flying.json.
"""
from __future__ import annotations

import argparse
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import scenes as S  # noqa: E402
from tracer.bench_coherence import run_coherence  # noqa: E402
from tracer.bench_tables import footer, format_table  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.scene import load_scene  # noqa: E402


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


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--teapots", type=int, nargs="*", default=[36, 800])
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)
    scenes = {"teapot": load_scene(S.SAMPLES / "teapot.json")}
    scenes.update({f"{n} teapots": teapot_field(n) for n in args.teapots})
    log = lambda text: print(text, file=sys.stderr, flush=True)  # noqa: E731
    result = run_coherence(scenes, Options(threads=args.threads), size=(args.size, args.size), runs=args.runs,
                           tables=("accel",), log=log)
    for label, scene in result["scenes"].items():
        print(format_table("accel", label, scene), end="\n\n")
    print(footer(result))


if __name__ == "__main__":
    main()
