"""`psrt study SCENE`: run time against error on the same primary rays (tracer/study.py).

The Markdown table goes to stdout (to stderr when `--json -` takes stdout); --json, --markdown and
--chart write the same results to files; --report DIR adds the coherence benchmark and the stress
suite on the scene and writes them with the machine into DIR/report.md (issue 14 item 4). Exit
status 0, or 2 on bad input as for every command.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

from . import cli, memory, study
from .options import PRECISIONS
from .study_coherence import CANDIDATES, ROUNDS, settings
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


def coherence_setting(text: str) -> str:
    try:
        settings(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


REPORT_FILES = ("report.md", "study.png", "study.json")  # what --report DIR writes


def report_paths(directory) -> list:
    """The report's files in `directory` (made if missing; its parent must exist)."""
    if os.path.exists(directory) and not os.path.isdir(directory):
        raise ValueError(f"--report {directory}: not a directory")
    if not os.path.isdir(os.path.dirname(os.path.abspath(directory))):
        raise ValueError(f"--report {directory}: its parent directory does not exist")
    os.makedirs(directory, exist_ok=True)
    return [os.path.join(directory, name) for name in REPORT_FILES]


def stress_table(scene, args) -> str:
    """The stress suite's table on the scene at --stress-size, with a progress bar."""
    from tqdm import tqdm

    from . import stress
    chosen = stress.variants()
    with tqdm(total=len(chosen), desc="stress", unit="variant", file=sys.stderr, disable=args.quiet,
              leave=False) as bar:
        results = stress.run(scene, chosen, args.stress_size, progress=lambda r: bar.update(1))
    return stress.table(results)


def coherence_tables(scene, args) -> str:
    """`psrt bench --coherence` on the scene alone at --bench-size, --bench-runs (one render thread)."""
    from .bench_coherence import run_coherence
    from .bench_tables import format_result
    from .options import Options
    log = None if args.quiet else (lambda text: print(f"coherence: {text}", file=sys.stderr, flush=True))
    label = os.path.splitext(os.path.basename(str(args.scene)))[0]
    return format_result(run_coherence({label: scene}, Options(threads=1), size=args.bench_size,
                                       runs=args.bench_runs, log=log))


def write_report(outs, args, scene, result, table: str, png: bytes) -> None:
    from .study_document import document, machine
    md, chart, data = report_paths(args.report)
    coherence = coherence_tables(scene, args)
    stress_text = stress_table(scene, args)
    sizes = {"study": f"{args.size[0]}x{args.size[1]}", "coherence": f"{args.bench_size[0]}x{args.bench_size[1]}, "
             f"{args.bench_runs} run(s)", "stress": f"{args.stress_size[0]}x{args.stress_size[1]}"}
    notes = {k: f"Image size {v}." for k, v in sizes.items()}
    outs.write(chart, lambda f: f.write(png))
    cli._write_json(outs, result, data)
    outs.write_text(md, document(str(args.scene), table, os.path.basename(chart), coherence, stress_text,
                                 machine(), notes))


def cmd_study(args) -> int:
    planned = [("--json", args.json, True), ("--markdown", args.markdown), ("--chart", args.chart)]
    if args.report:
        planned += [("--report", path) for path in report_paths(args.report)]
    outs = cli.planned_outputs(*planned, scene=args.scene)
    with outs:
        scene = cli.load_inputs(outs, args.scene)
        cli._import_losses(args, scene)
        # the first frame, its reference and the truth are held while each point's frame is traced
        memory.check_render(*args.size, reference=True, frames=3, limit=args.memory_limit)
        total = study.unit_count(scene, args.precisions, not args.no_coherence, args.tessellations, args.flatnesses)
        from tqdm import tqdm
        with tqdm(total=total, desc="study", unit="unit", file=sys.stderr, disable=args.quiet,
                  leave=False) as bar:
            bar.set_postfix_str("truth: float32 rays, float64 reference, Newton")

            def step(label):
                bar.update(1)
                if label is not None:
                    bar.set_postfix_str(label)
            from .distributed import describe, open_client
            start = time.perf_counter()
            with open_client(args.scheduler, args.workers) as client:
                where = describe(client)
                result = study.run(scene, args.size, precisions=args.precisions, coherence=not args.no_coherence,
                                   runs=args.runs, tessellations=args.tessellations,
                                   flatnesses=args.flatnesses, progress=step, client=client,
                                   candidates=args.coherence_candidates, rounds=args.coherence_rounds)
            result["wall_seconds"], result["ran_on"] = time.perf_counter() - start, where
        result["scene"] = str(args.scene)
        from .study_report import chart_png, markdown
        table = markdown(result)
        if args.json:
            cli._write_json(outs, result, args.json)
        if args.markdown:
            outs.write_text(args.markdown, table)
        png = chart_png(result) if args.chart or args.report else b""
        if args.chart:
            outs.write(args.chart, lambda f: f.write(png))
        if args.report:
            write_report(outs, args, scene, result, table, png)
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
                   help="leave out the coherence trials and the series with the fastest coherence setting")
    p.add_argument("--coherence-candidates", nargs="+", type=coherence_setting, default=list(CANDIDATES),
                   metavar="SPEC", help="coherence settings tried against the plain one for each criterion and "
                   "precision, the fastest giving that criterion's coherence series: a bundle (4x4, 8x8, ...), "
                   "'cache', a structure (grid, kdtree) and 'mailbox', joined by '+' (default: "
                   f"{' '.join(CANDIDATES)})")
    p.add_argument("--coherence-rounds", type=cli.positive_int, default=ROUNDS,
                   help=f"timed rounds of a coherence trial, the settings taking turns (default: {ROUNDS})")
    p.add_argument("--tessellations", nargs="*", type=cli.positive_int, default=list(TESSELLATIONS), metavar="N",
                   help="the tessellation peer's N x N quads per patch, traced with Embree (none: leave the peer "
                        f"out; default: {' '.join(map(str, TESSELLATIONS))})")
    p.add_argument("--flatnesses", nargs="*", type=positive_float, default=list(FLATNESSES), metavar="F",
                   help="POV-Ray's bicubic_patch flatness values (none: leave the peer out; default: "
                        f"{' '.join(map(str, FLATNESSES))}; only with povray installed and an integral bicubic scene)")
    p.add_argument("--json", metavar="OUT", help="write every point's score as JSON ('-': stdout)")
    p.add_argument("--markdown", metavar="OUT.md", help="write the table as Markdown")
    p.add_argument("--chart", metavar="PNG", help="log-log chart of time against error with the float32 floor")
    p.add_argument("--report", metavar="DIR", help="also run the coherence benchmark and the stress suite on the "
                   f"scene and write one Markdown report with the machine, the chart and every table ({', '.join(REPORT_FILES)})")
    p.add_argument("--bench-size", type=cli.parse_size, default=(256, 256),
                   help="--report: the coherence benchmark's image size (default: 256x256)")
    p.add_argument("--bench-runs", type=cli.positive_int, default=3,
                   help="--report: the coherence benchmark's timed runs (default: 3)")
    p.add_argument("--stress-size", type=cli.parse_size, default=(64, 64),
                   help="--report: the stress suite's image size (default: 64x64)")
    cli.add_scheduler_flags(p, default="local")
    cli._add_memory_limit(p)
    cli._add_quiet(p)
    cli._add_strict(p)
    p.set_defaults(func=cmd_study)
