"""`psrt bench --coherence` and `--penumbra-sweep`: the commands around bench_coherence and
bench_penumbra (their flags are added to cli.py's
bench parser: --coherence, --tables, --scenes, --penumbra-sweep)."""
from __future__ import annotations

import sys
import time

from . import memory
from .bench_coherence import TABLES
from .bench_scenes import NAMES, scene_label, scene_path

DEFAULT_SIZE = (256, 256)
DEFAULT_RUNS = 3


def add_flags(parser) -> None:
    parser.add_argument("--coherence", action="store_true",
                        help="the coherence tables instead: ray bundles, acceleration structures, pixel orders with "
                             "the surface-tree cache, each row's speed-up against the plain setting in the same run "
                             f"(default size {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}, {DEFAULT_RUNS} runs, one render "
                             "thread timed by CPU time)")
    parser.add_argument("--penumbra-sweep", action="store_true",
                        help="the fast penumbra against light size instead (Lukaszewski's table 4.4): the scene's "
                             "sphere light at radii 0.02-0.2 of the scene's diagonal, 32 samples, every method "
                             "checked bit for bit against off (default size 256x256, 3 runs, one thread, CPU time)")
    parser.add_argument("--tables", nargs="+", choices=TABLES, metavar="TABLE",
                        help=f"with --coherence: the tables to run (default: all of {', '.join(TABLES)})")
    parser.add_argument("--scenes", nargs="+", metavar="SCENE",
                        help=f"with --coherence: scenes by name ({', '.join(NAMES)}) or file "
                             f"(default: all four)")


def _compile_log(log):
    """on_compile for the runs: a line for each kernel variant that took over a second."""
    if log is None:
        return None

    def note(variant, seconds=None):
        if seconds is not None and seconds > 1.0:
            from .variants import label
            log(f"compiled the {label(variant)} kernel in {seconds:.1f} s")
    return note


def _threads_given(args) -> bool:
    return args.opt_threads is not None or any(s.split("=", 1)[0].strip() == "threads" for s in args.set)


def cmd_bench_penumbra(args) -> int:
    from .bench_penumbra import format_penumbra, run_penumbra
    from .cli import _default_scene, _write_json, load_inputs, options_from_args, planned_outputs

    scene_path = args.scene or str(_default_scene())
    outs = planned_outputs(("--json", args.json, True), scene=scene_path)
    size = args.size or DEFAULT_SIZE
    log = None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    with outs:
        scene = load_inputs(outs, scene_path)
        memory.check_render(*size, frames=6, limit=args.memory_limit)
        result = run_penumbra(scene, options_from_args(args), size=size, runs=args.runs or DEFAULT_RUNS, log=log)
        result["scene"] = scene_path
        if args.json:
            _write_json(outs, result, args.json)
    print(format_penumbra(result))
    return 0


def cmd_bench_coherence(args) -> int:
    from .bench_coherence import run_coherence
    from .bench_tables import format_result
    from .cli import _write_json, options_from_args, planned_outputs
    from .scene import load_scene

    if args.scene is not None:
        raise ValueError("--scene: with --coherence, name the scenes with --scenes")
    outs = planned_outputs(("--json", args.json, True))
    base = options_from_args(args)
    if not _threads_given(args):
        base = base.with_(threads=1)  # one thread: frames timed by CPU time
    size = args.size or DEFAULT_SIZE
    runs = args.runs or DEFAULT_RUNS
    log = None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    with outs:
        paths = {scene_label(name): scene_path(name) for name in (args.scenes or NAMES)}
        outs.refuse_inputs(paths.values(), "a scene file")
        memory.check_render(*size, frames=1, limit=args.memory_limit)
        scenes = {}
        for label, path in paths.items():
            start = time.perf_counter()
            scenes[label] = load_scene(path)
            if log is not None:
                log(f"{label}: loaded {path} in {time.perf_counter() - start:.1f} s")
        result = run_coherence(scenes, base, size=size, runs=runs, tables=args.tables or TABLES, log=log,
                               on_compile=_compile_log(log))
        result["scene_files"] = {label: str(path) for label, path in paths.items()}
        if args.json:
            _write_json(outs, result, args.json)
    print(format_result(result))
    return 0
