"""Fast penumbra against light size, as Lukaszewski's table 4.4: the sample teapot under one sphere
light of growing radius, every sample traced (off) against the expanded and tmax methods.

    .venv/bin/python tests/bench_penumbra.py [--size 256] [--samples 32] [--runs 3] [--radii 0.02 0.05 0.1 0.2]

Radii are fractions of the scene's diagonal. Times are CPU seconds of one render thread (the
median of --runs renders, the methods taking turns within each run, so drift of the machine's
speed hits them alike), with the primary rays alone (no shadows, no reflections) for scale.
Each method's image is checked bit for bit against `off`.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import load_scene  # noqa: E402

TEAPOT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "sample_models", "teapot.json")
METHODS = ("off", "expanded", "tmax")


def cpu(f):
    start = time.process_time()
    out = f()
    return time.process_time() - start, out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--radii", type=float, nargs="+", default=[0.02, 0.05, 0.1, 0.2])
    args = parser.parse_args(argv)
    scene = load_scene(TEAPOT)
    geom = prepare(scene, "f32")
    lo, hi = scene.bounds()
    diagonal = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    size = (args.size, args.size)
    base = Options(threads=1, light_samples=args.samples)
    primary = base.with_(shadows=False, reflections=False)
    render(scene, primary, size=size, geometry=geom)
    t_primary = statistics.median(cpu(lambda: render(scene, primary, size=size, geometry=geom))[0]
                                  for _ in range(args.runs))
    print(f"teapot {args.size}x{args.size}, {args.samples} samples, 1 thread, CPU s; primary rays alone "
          f"{t_primary:.3f} s")
    print(f"{'radius':>7} {'off s':>7} {'expanded s':>10} {'tmax s':>7} {'speed-up':>8} {'lit %':>6} "
          f"{'rays/hit off':>12} {'rays/hit tmax':>13} {'tmax/primary':>12}")
    for fraction in args.radii:
        scene.lights[0].radius = fraction * diagonal
        times = {m: [] for m in METHODS}
        frames = {}
        for m in METHODS:  # warm-up: compile, build the expanded data sets
            frames[m] = render(scene, base.with_(penumbra=m), size=size, geometry=geom)
        for _ in range(args.runs):
            for m in METHODS:
                seconds, frames[m] = cpu(lambda: render(scene, base.with_(penumbra=m), size=size, geometry=geom))
                times[m].append(seconds)
        for m in METHODS[1:]:
            assert np.array_equal(frames[m].radiance, frames["off"].radiance, equal_nan=True), m
        med = {m: statistics.median(v) for m, v in times.items()}
        hit = frames["off"].hit
        lit = float(np.mean(frames["tmax"].penumbra[hit] == 0)) * 100
        rays = {m: frames[m].shadow_rays[hit].mean() for m in ("off", "tmax")}
        print(f"{fraction:7.2f} {med['off']:7.3f} {med['expanded']:10.3f} {med['tmax']:7.3f} "
              f"{med['off'] / med['tmax']:8.2f} {lit:6.1f} {rays['off']:12.1f} {rays['tmax']:13.1f} "
              f"{med['tmax'] / t_primary:12.2f}")
    print("images bit-identical to off for every method and radius")
    return 0


if __name__ == "__main__":
    sys.exit(main())
