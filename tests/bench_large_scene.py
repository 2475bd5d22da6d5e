"""How long a large scene takes from file to image: 100,000 bilinear patches (a 4.3 MB .bpt).

    .venv/bin/python tests/bench_large_scene.py [PATCHES ...]

For each count (default 1000 10000 100000): the seconds of load_scene, of prepare (leaves,
frames, boxes and the BVH), of the BVH build alone (build_bvh over the prepared leaf boxes,
timed again by itself) and of a 32x32 float32 render with the prepared geometry, and their
total (load + prepare + render). Best of --runs runs (default 3). The kernel is compiled (or
loaded from the cache) by a warm-up render first and is not counted.
"""
import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_bpt_load import write  # noqa: E402

from tracer.bvh import build_bvh  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import load_scene  # noqa: E402

SIZE = (32, 32)


def timed(f, *args, **kwargs):
    t = time.perf_counter()
    out = f(*args, **kwargs)
    return out, time.perf_counter() - t


def measure(path, opts):
    """{step: seconds} of one run from the file to the image."""
    scene, load = timed(load_scene, path)
    geom, prep = timed(prepare, scene, opts.precision)
    _, bvh = timed(build_bvh, geom.leaf_box)
    frame, draw = timed(render, scene, opts, size=SIZE, geometry=geom)
    return {"load": load, "prepare": prep, "bvh": bvh, "render": draw, "total": load + prep + draw,
            "hits": int(frame.hit.sum()), "leaves": geom.n_patches}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("counts", nargs="*", type=int, default=[1000, 10_000, 100_000])
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args(argv)
    opts = Options()
    with tempfile.TemporaryDirectory() as d:
        warm = os.path.join(d, "warm.bpt")
        write(warm, 4)
        render(load_scene(warm), opts, size=(4, 4))
        print(f"{'patches':>8} {'leaves':>8} {'MB':>5} {'load':>6} {'prepare':>8} {'(bvh)':>6} "
              f"{'render':>7} {'total':>6}  (seconds, best of {args.runs})")
        for n in args.counts:
            path = os.path.join(d, f"grid{n}.bpt")
            write(path, n)
            runs = [measure(path, opts) for _ in range(args.runs)]
            best = {k: min(r[k] for r in runs) for k in ("load", "prepare", "bvh", "render", "total")}
            print(f"{n:>8} {runs[0]['leaves']:>8} {os.path.getsize(path) / 1e6:>5.1f} {best['load']:>6.2f} "
                  f"{best['prepare']:>8.2f} {best['bvh']:>6.2f} {best['render']:>7.2f} {best['total']:>6.2f}",
                  flush=True)


if __name__ == "__main__":
    main()
