"""`psrt stress SCENE`: the numerical stability suite (tracer/stress.py) on a user's scene.

Exit status: 0 no variant has a hole or a false hit; 1 some variant has (the table says which);
2 bad input (an unknown scene or variant, a bad flag), as for the other commands. A variant the
tracer refuses (limits.py: too large or too small for the precision) is a row "refused: why",
not a failure.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import asdict

from . import cli, stress


def parse_variant(text: str) -> str:
    """A variant's name or kind (stress.select), as an argparse error if unknown."""
    try:
        stress.select([text])
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--variants: ")) from None
    return text


def cmd_stress(args) -> int:
    outs = cli.planned_outputs(("--json", args.json, True), scene=args.scene)
    opts = cli.options_from_args(args)
    chosen = stress.select(args.variants) if args.variants else stress.variants()
    with outs:
        scene = cli.load_inputs(outs, args.scene)
        cli._import_losses(args, scene)
        from tqdm import tqdm
        with tqdm(total=len(chosen), desc="stress", unit="variant", file=sys.stderr, disable=args.quiet,
                  leave=False) as bar:
            def step(result):
                bar.set_postfix_str(result.variant.name)
                bar.update(1)
            from .distributed import describe, open_client
            start = time.perf_counter()
            with open_client(args.scheduler, args.workers) as client:
                where = describe(client)
                results = stress.run(scene, chosen, args.size, opts, progress=step, client=client)
            wall = time.perf_counter() - start  # with the cluster's start and stop: what the user waits
        failed = [r.variant.name for r in results if r.failed]
        if args.json:
            cli._write_json(outs, {"scene": str(args.scene), "size": list(args.size), "options": asdict(opts),
                                   "variants": [r.to_json() for r in results], "failed": failed,
                                   "wall_seconds": wall}, args.json)
    print(stress.table(results), file=sys.stderr if args.json == cli.STDOUT else sys.stdout)  # JSON owns stdout
    cli._say(args, f"psrt stress: {len(results)} variants in {wall:.2f} s {where}")
    if failed:
        print(f"psrt stress: holes or false hits in {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


def add_stress_command(sub) -> None:
    names = ", ".join(v.name for v in stress.variants())
    p = sub.add_parser("stress", help="float32 against float64 on the scene scaled, moved, seen grazing and "
                       "perturbed (exit 1 on any hole or false hit)",
                       description="Exit status: 0 clean; 1 a variant has holes or false hits; 2 bad input.")
    p.add_argument("scene", help="scene .json or .bpt file")
    p.add_argument("--size", type=cli.parse_size, default=(64, 64), help="image size WxH (default: 64x64)")
    p.add_argument("--json", metavar="OUT", help="write every variant's score as JSON ('-': stdout)")
    p.add_argument("--variants", nargs="+", type=parse_variant, metavar="V",
                   help=f"variants or kinds to run (default: all of {names})")
    cli.add_scheduler_flags(p, default="local")
    cli.add_option_flags(p)
    cli._add_quiet(p)
    cli._add_strict(p)
    p.set_defaults(func=cmd_stress)
