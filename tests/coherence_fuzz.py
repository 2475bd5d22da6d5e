"""Random views and coherence settings against the plain render (issue 12's bit-identity).

    .venv/bin/python tests/coherence_fuzz.py [--scenes teapot sphere ...] [--seeds 0 40] [--size 40]
                                            [--criteria float adaptive ...] [--set bundle=1x1 ...]

Each seed picks a scene of the digest catalogue, a view (a random direction, field of view and
aim inside the scene's box), a criterion and precision, and a random setting of bundle, accel,
mailbox, cache and order (--set fixes any of them), all with the length split; it renders the
plain setting (1x1, BVH, no cache, scanline) and the random one and prints every seed whose hit,
t, position, box, normal, uv or patch differ, with the pixels that moved. Deterministic per seed.
"""
import argparse
import random
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import digests as D  # noqa: E402
from tracer.camera import View, framing_view  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import BUNDLES, ORDERS, PLAIN, Options  # noqa: E402
from tracer.render import render  # noqa: E402

EXACT = ("hit", "t", "position", "box_min", "box_max", "normal", "uv", "patch")


def random_case(rng, scenes, criteria):
    name = rng.choice(sorted(scenes))
    lo, hi = (np.asarray(b, float) for b in scenes[name].bounds())
    d = np.array([rng.uniform(-1, 1) for _ in range(3)])
    if np.linalg.norm(d) < 0.1:
        d = np.array([0.5, -0.8, 0.4])
    framed = framing_view(lo, hi, fov_deg=rng.choice([35.0, 10.0, 3.0, 0.5]), direction=tuple(d))
    target = lo + np.array([rng.random() for _ in range(3)]) * (hi - lo)
    eye = np.asarray(framed.eye) + (target - np.asarray(framed.look_at)) * rng.choice([0.0, 1.0])
    look = target if rng.random() < 0.7 else np.asarray(framed.look_at)
    view = View(tuple(eye), tuple(look), framed.up, framed.fov_deg)
    plain = Options(criterion=rng.choice(criteria), precision=rng.choice(["f32", "f64"]), split="length", **PLAIN)
    setting = plain.with_(bundle=rng.choice(BUNDLES[1:]), accel=rng.choice(["bvh", "kdtree", "grid"]),
                          cache=rng.random() < 0.5, order=rng.choice(ORDERS), mailbox=rng.random() < 0.5)
    return name, view, plain, setting


def moved_pixels(a, b):
    """The channels that differ and the mask of pixels where any does (NaN equals NaN)."""
    moved, where = [], np.zeros(a.hit.shape, bool)
    for c in EXACT:
        x, y = getattr(a, c), getattr(b, c)
        differ = ~((x == y) | (np.isnan(x) & np.isnan(y))) if x.dtype.kind == "f" else x != y
        if differ.any():
            moved.append(c)
            where |= differ.reshape(differ.shape[0], differ.shape[1], -1).any(axis=2)
    return moved, where


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["teapot", "sphere", "torus", "plate"])
    ap.add_argument("--seeds", nargs=2, type=int, default=[0, 40], metavar=("FIRST", "END"))
    ap.add_argument("--size", type=int, default=40)
    ap.add_argument("--criteria", nargs="+", default=["float", "fixed", "mantissa", "adaptive"])
    ap.add_argument("--set", nargs="*", default=[], metavar="OPTION=VALUE", help="fix a coherence option")
    args = ap.parse_args(argv)
    catalogue = D.catalogue()
    scenes = {n: catalogue[n][0]()[0] for n in args.scenes}
    fixed = {}
    for item in args.set:
        key, value = item.split("=", 1)
        fixed[key] = {"true": True, "false": False}.get(value.lower(), value)
    bad = 0
    for seed in range(*args.seeds):
        name, view, plain, setting = random_case(random.Random(seed), scenes, args.criteria)
        setting = setting.with_(**fixed)
        geom = prepare(scenes[name], plain.precision)
        size = (args.size, args.size)
        a = render(scenes[name], plain, size=size, view=view, geometry=geom, lighting=False)
        b = render(scenes[name], setting, size=size, view=view, geometry=geom, lighting=False)
        moved, where = moved_pixels(a, b)
        if moved:
            bad += 1
            chosen = {k: getattr(setting, k) for k in ("bundle", "accel", "mailbox", "cache", "order")}
            print(f"seed {seed}: {name} {plain.criterion} {plain.precision} {chosen}: {moved} moved in "
                  f"{int(where.sum())} pixels, e.g. {np.argwhere(where)[:3].tolist()}", flush=True)
    print(f"{args.seeds[1] - args.seeds[0]} cases, {bad} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
