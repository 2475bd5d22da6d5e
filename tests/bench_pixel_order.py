"""How long the work units of a frame take to make, per pixel order: the teapot's geometry and view.

    .venv/bin/python tests/bench_pixel_order.py [--sizes 512 2048] [--bundles 1x1 4x4] [--runs 5] [--frame]

For each size, bundle and order: the seconds of render.work_units, first call in the process
(numpy's first large allocations) and the median of --runs calls after it. --frame also times
a float32 frame of each size (render, scanline; the kernel compiled or loaded first), the
figure the unit times should be small next to.
"""
import argparse
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tracer.camera import view_of  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import ORDERS, Options  # noqa: E402
from tracer.render import render, work_units  # noqa: E402
from tracer.scene import load_scene  # noqa: E402

TEAPOT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "sample_models", "teapot.json")


def seconds(f):
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[512, 2048])
    parser.add_argument("--bundles", nargs="+", default=["1x1", "4x4"])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--frame", action="store_true")
    args = parser.parse_args(argv)
    scene = load_scene(TEAPOT)
    geom, view = prepare(scene, "f32"), view_of(scene)
    for n in args.sizes:
        if args.frame:
            render(scene, Options(), size=(8, 8), geometry=geom)
            frame = render(scene, Options(), size=(n, n), geometry=geom)
            print(f"{n}x{n} frame (scanline, f32): {frame.seconds:.3f} s")
        for bundle in args.bundles:
            for order in ORDERS:
                opts = Options(order=order, bundle=bundle)
                make = lambda: work_units(n, n, opts, geom, view)  # noqa: E731
                first = seconds(make)
                runs = [seconds(make) for _ in range(args.runs)]
                print(f"{n}x{n} {bundle} {order:10s} {len(make()):5d} units  first {first:.3f} s  "
                      f"median {statistics.median(runs):.3f} s  min {min(runs):.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
