"""How fast any bit-identical fast-penumbra method could be: `off` against an oracle.

    .venv/bin/python tests/bench_penumbra_bound.py [--radius 0.02] [--samples 32] [--size 256] [--runs 3]

The sample teapot with its sphere light's radius set to a fraction of the scene's diagonal,
rendered with `penumbra=off` (every sample traced, in bundles), one render thread, CPU time.
Each shading point's samples are traced as usual; then the samples of the points whose samples
differ (some occluded, some not: the true penumbra) are traced once more on their own, timed apart.
The oracle's frame is `off`'s without the first tracing and with the second: what a method would
cost that knew for free which points are wholly lit or wholly dark and skipped their samples, as
`expanded`, `tmax` and `umbra` do where they can prove it. Its time bounds every such method's
speed-up against `off` (issue 13's target is 3x at a radius of 0.02).
"""
import argparse
import os
import statistics
import sys
import time
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import tracer.lighting as lighting  # noqa: E402
from tracer.fixed_order import dot3, norm  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import load_scene  # noqa: E402

TEAPOT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "sample_models", "teapot.json")


class Tally:
    """Seconds of the frame's shadow rays, of the penumbra points' rays traced again, and points."""

    def __init__(self):
        self.all_rays = self.mixed_rays = 0.0
        self.mixed = self.points = 0


def watch(tally: Tally):
    """Wrap Lighting._visibility: after the usual tracing, trace the mixed points' rays again."""
    usual = lighting.Lighting._visibility

    def visibility(self, v, lp, li, origin):
        before = self.seconds["shadow_rays"]
        visible, traced, cls = usual(self, v, lp, li, origin)
        if origin is None:
            return visible, traced, cls
        tally.all_rays += self.seconds["shadow_rays"] - before
        front = dot3(v.normal[:, None, :], lp - v.pos[:, None]) > 0.0
        mixed = (front & ~visible).any(axis=1) & visible.any(axis=1)
        tally.mixed += int(mixed.sum())
        tally.points += len(mixed)
        rows, cols = np.nonzero(front & mixed[:, None])
        start = time.perf_counter()
        rays = self.shadow_rays(v, lp, origin, rows, cols)
        again = self.bundles.occluded(rays, rows)[0] if self.bundles is not None else self.tracer.occluded(rays)[0]
        tally.mixed_rays += time.perf_counter() - start
        assert np.array_equal(~again, visible[rows, cols]), "the mixed points' rays traced again differ"
        return visible, traced, cls

    lighting.Lighting._visibility = visibility


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--radius", type=float, default=0.02, help="the light's radius over the scene's diagonal")
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    scene = load_scene(TEAPOT)
    lo, hi = scene.bounds()
    scene.lights[0] = replace(scene.lights[0], radius=args.radius * norm(np.asarray(hi) - np.asarray(lo)))
    opts = Options().with_(threads=1, light_samples=args.samples, penumbra="off")
    geom = prepare(scene, opts.precision)
    size = (args.size, args.size)
    tally = Tally()
    watch(tally)
    render(scene, opts, size=size, geometry=geom)  # compiled or loaded first
    rows = []
    for _ in range(args.runs):
        tally.__init__()
        start = time.process_time()
        render(scene, opts, size=size, geometry=geom)
        total = time.process_time() - start
        off, oracle = total - tally.mixed_rays, total - tally.all_rays
        rows.append((off, oracle, tally.all_rays, tally.mixed_rays))
        print(f"off {off:.3f} s (its shadow rays {tally.all_rays:.3f} s), oracle {oracle:.3f} s (the mixed points' "
              f"rays {tally.mixed_rays:.3f} s): off / oracle {off / oracle:.2f}")
    off, oracle = (statistics.median(r[k] for r in rows) for k in (0, 1))
    print(f"radius {args.radius:g}, {args.samples} samples, {args.size}x{args.size}, one thread, CPU s, median of "
          f"{args.runs}: off {off:.3f}, oracle {oracle:.3f}, at most {off / oracle:.2f}x; {tally.mixed} of "
          f"{tally.points} shading points have samples that differ")


if __name__ == "__main__":
    main()
