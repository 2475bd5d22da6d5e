"""`psrt study SCENE`: run time against error on the same primary rays (tracer/study.py).

The Markdown table goes to stdout (to stderr when `--json -` takes stdout); --json, --markdown and
--chart write the same results to files. Exit status 0, or 2 on bad input as for every command.
"""
from __future__ import annotations

import argparse
import math
import sys

from . import cli, study
from .options import PRECISIONS
from .study_peers import TESSELLATIONS
from .study_povray import FLATNESSES


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not value > 0 or math.isinf(value):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def cmd_study(args) -> int:
    outs = cli.planned_outputs(("--json", args.json, True), ("--markdown", args.markdown),
                               ("--chart", args.chart), scene=args.scene)
    with outs:
        scene = cli.load_inputs(outs, args.scene)
        cli._import_losses(args, scene)
        total = len(study.points(study.scene_size(scene), precisions=args.precisions,
                                 coherence=not args.no_coherence)) + 1 + len(args.tessellations) + len(args.flatnesses)
        from tqdm import tqdm
        with tqdm(total=total, desc="study", unit="point", file=sys.stderr, disable=args.quiet,
                  leave=False) as bar:
            bar.set_postfix_str("truth: float32 rays, float64 reference, Newton")

            def step(point):
                bar.update(1)
                if point is not None:
                    bar.set_postfix_str(f"{point.series} {'' if point.parameter is None else point.parameter}")
            result = study.run(scene, args.size, precisions=args.precisions, coherence=not args.no_coherence,
                               runs=args.runs, tessellations=args.tessellations,
                               flatnesses=args.flatnesses, progress=step)
        result["scene"] = str(args.scene)
        from .study_report import chart_png, markdown
        table = markdown(result)
        if args.json:
            cli._write_json(outs, result, args.json)
        if args.markdown:
            outs.write_text(args.markdown, table)
        if args.chart:
            png = chart_png(result)
            outs.write(args.chart, lambda f: f.write(png))
    print(table, file=sys.stderr if args.json == cli.STDOUT else sys.stdout)  # JSON owns stdout
    return 0


def add_study_command(sub) -> None:
    p = sub.add_parser("study", help="run time against error of every criterion's sweep on the same rays, "
                       "scored against a Newton-polished truth (Dammertz table 2.9)")
    p.add_argument("scene", help="scene .json or .bpt file")
    p.add_argument("--size", type=cli.parse_size, default=(512, 512), help="image size WxH (default: 512x512)")
    p.add_argument("--runs", type=cli.positive_int, default=1,
                   help="timed traces per point after one warm-up; the median is reported (default: 1)")
    p.add_argument("--precisions", nargs="+", choices=PRECISIONS, default=list(PRECISIONS), metavar="P",
                   help=f"precisions of psrt's series (default: {' '.join(PRECISIONS)})")
    p.add_argument("--no-coherence", action="store_true",
                   help="leave out the series with the fastest coherence setting (8x8 bundles, cache)")
    p.add_argument("--tessellations", nargs="*", type=cli.positive_int, default=list(TESSELLATIONS), metavar="N",
                   help="the tessellation peer's N x N quads per patch, traced with Embree (none: leave the peer "
                        f"out; default: {' '.join(map(str, TESSELLATIONS))})")
    p.add_argument("--flatnesses", nargs="*", type=positive_float, default=list(FLATNESSES), metavar="F",
                   help="POV-Ray's bicubic_patch flatness values (none: leave the peer out; default: "
                        f"{' '.join(map(str, FLATNESSES))}; only with povray installed and an integral bicubic scene)")
    p.add_argument("--json", metavar="OUT", help="write every point's score as JSON ('-': stdout)")
    p.add_argument("--markdown", metavar="OUT.md", help="write the table as Markdown")
    p.add_argument("--chart", metavar="PNG", help="log-log chart of time against error with the float32 floor")
    cli._add_quiet(p)
    cli._add_strict(p)
    p.set_defaults(func=cmd_study)
