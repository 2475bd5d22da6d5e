"""Where a single ray's subdivisions lie against the size of a pixel: how much of a ray's search a
ray bundle or the surface-tree cache could share at all (rays of a bundle part ways below a pixel).

    .venv/bin/python tests/float_levels.py [--scene teapot] [--size 512] [--block 64] [--set criterion=adaptive]

Traces the --block x --block rays at the centre of a --size frame (1x1, one thread, interpreted:
NUMBA_DISABLE_JIT=1, so each subdivision can be looked at) and sorts every subdivision by the box's
L1 diameter over three pixel widths at the box's entry t (a cube one pixel wide measures 1): above
8 pixels, 1 to 8, below one. Deterministic; a 64 x 64 block takes about a minute.
"""
import argparse
import os
import sys

os.environ["NUMBA_DISABLE_JIT"] = "1"  # before numba is imported
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import tracer.drivers as drivers  # noqa: E402
from tracer.bench_scenes import scene_label, scene_path  # noqa: E402
from tracer.camera import primary_rays, view_of  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options, parse_assignment  # noqa: E402
from tracer.render import trace_rays  # noqa: E402
from tracer.scene import load_scene  # noqa: E402
from tracer.subpatch import M_D, M_TIN  # noqa: E402

CLASSES = ("above 8 pixels", "1 to 8 pixels", "below a pixel")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="teapot")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--block", type=int, default=64)
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    args = ap.parse_args(argv)
    opts = Options()
    for pair in args.set:
        opts = parse_assignment(opts, pair)  # as the CLI's --set: checked against the option's range
    opts = opts.with_(threads=1, bundle="1x1")
    scene = load_scene(scene_path(args.scene))
    view = view_of(scene)
    geom = prepare(scene, opts.precision)
    origins, dirs = primary_rays(view, args.size, args.size, opts.precision, threads=1)
    first = (args.size - args.block) // 2
    block = slice(first, first + args.block)
    origins, dirs = origins[block, block].copy(), dirs[block, block].copy()
    angle = view.pixel_angle(args.size)
    counts = dict.fromkeys(CLASSES, 0)
    subdivide = drivers.subdivide

    def counted(sl, a, *rest):
        width = 3.0 * max(sl.mf[a, M_TIN], 0.0) * angle  # the L1 diameter of a cube a pixel wide
        pixels = sl.mf[a, M_D] / width if width > 0.0 else float("inf")
        counts[CLASSES[0] if pixels > 8.0 else (CLASSES[1] if pixels > 1.0 else CLASSES[2])] += 1
        return subdivide(sl, a, *rest)

    drivers.subdivide = counted
    frame = trace_rays(geom, opts, origins, dirs, angle, view=view)
    total = sum(counts.values())
    rays = args.block * args.block
    print(f"{scene_label(args.scene)}: the centre {args.block}x{args.block} rays of {args.size}x{args.size}, "
          f"{opts.criterion}, {int(frame.hit.sum())} hits, {total:,} subdivisions ({total / rays:.1f} a ray)")
    for name in CLASSES:
        print(f"  {name:15s} {counts[name]:9,d}  {100.0 * counts[name] / max(total, 1):5.1f} %")


if __name__ == "__main__":
    main()
