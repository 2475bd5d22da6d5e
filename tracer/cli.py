"""The tracer's commands of the `psrt` command line: render, trace, bench, stress (cli_stress.py),
study (cli_study.py).

`add_commands` adds them to the subparsers of psrt/cli.py, which adds the viewer's
`view` beside them and runs the chosen command. Tracer option flags are generated
from `tracer.options.option_fields()`, so the CLI and the viewer expose the same
options with the same names, ranges and help.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import asdict
from pathlib import Path

from . import memory
from .limits import check_extent
from .options import CRITERIA, PRECISIONS, SPLITS
from .output_files import STDOUT, OutputFiles
from .stats import CHANNELS
from .cli_args import (add_option_flags, flag_options, options_from_args, parse_map, parse_memory,  # noqa: F401
                       parse_pixel, parse_size, positive_int)

SWEPT = ("criterion", "split", "precision", "mode")  # bench sweeps these instead of taking flags


def scene_files(scene) -> list:
    """The files a loaded scene was read from: the scene file and every file it refers to."""
    base = os.path.dirname(os.path.abspath(scene.path))
    return [scene.path] + [os.path.join(base, o.source) for o in scene.objects
                           if o.source not in ("inline", scene.path)]


def planned_outputs(*outputs, scene=None) -> OutputFiles:
    """The run's outputs, (flag, path[, stdout allowed]) each, checked before any work (see
    output_files): none may be the scene file."""
    outs = OutputFiles()
    for flag, path, *stdout in outputs:
        outs.add(flag, path, stdout=bool(stdout and stdout[0]))
    outs.refuse_inputs([scene], "the scene file")
    return outs


def load_inputs(outs: OutputFiles, path):
    """Load the scene; refuse any output that is a file the scene refers to (before any render)."""
    from .scene import load_scene
    scene = load_scene(path)
    outs.refuse_inputs(scene_files(scene)[1:], "a file the scene refers to")
    return scene


def _bar(total: int, desc: str, quiet: bool):
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit="tile", file=sys.stderr, disable=quiet, leave=False)


def _write_json(outs: OutputFiles, data, path):
    from .stats import json_safe
    outs.write_text(path, json.dumps(json_safe(data), indent=1) + "\n")


def _write_png(outs: OutputFiles, image, path):
    """A PIL image as PNG (whatever the file name says)."""
    outs.write(path, lambda f: image.save(f, format="PNG"))


def _compile_note(args, bar):
    """on_compile for render: a step of its own while a kernel variant is compiled (or loaded
    from the cache), so a first run does not sit silently at 0 %."""
    if args.quiet:
        return None
    desc = bar.desc

    def note(variant, seconds=None):
        from .variants import label
        if seconds is None:
            bar.set_description_str(f"compiling the {label(variant)} kernel")
        else:
            bar.set_description_str(desc)
            if seconds > 1.0:
                bar.write(f"compiled the {label(variant)} kernel in {seconds:.1f} s", file=sys.stderr)
    return note


def _build_note(args, bar):
    """on_build for render: a kd-tree or grid build is a step of its own on the progress bar, and a
    line when it took over a second (accel.aggregate_for)."""
    if args.quiet:
        return None
    desc = bar.desc

    def note(structure, seconds=None):
        if seconds is None:
            bar.set_description_str(f"building the {structure}")
        else:
            bar.set_description_str(desc)
            if seconds > 1.0:
                bar.write(f"built the {structure} in {seconds:.1f} s", file=sys.stderr)
    return note


def _accel_summary(accel: dict) -> str:
    """', kd-tree built in 0.04 s' (or 'reused') for the summary line; nothing for the BVH."""
    if not accel or accel.get("kind") == "bvh":
        return ""
    from .accel import KIND_NAMES
    how = f"built in {accel['build_seconds']:.3f} s" if accel["built_now"] else "reused"
    return f"; {KIND_NAMES[accel['kind']]} {how}"


def _say(args, text):
    if not args.quiet:
        print(text, file=sys.stderr)


def _import_losses(args, scene) -> None:
    """What free-form imports did not convert, on stderr (--quiet too); --strict: an error."""
    from .formats.losses import loss_lines, strict_check
    if args.strict:
        strict_check(scene.import_report)
    for source, report in scene.import_report.items():
        for i, line in enumerate(loss_lines(source, report)):
            print(f"psrt {args.command}: warning: {line}" if i == 0 else line, file=sys.stderr)


# ---- commands ---------------------------------------------------------------------

def cmd_render(args) -> int:
    from .render import reference_frame, unit_count
    from .shade import shade, to_png
    from .stats import channel_image, error_stats, frame_stats

    maps = dict(args.map)
    outs = planned_outputs(("-o", args.output), ("--aov", args.aov), ("--effort-map", args.effort_map),
                           ("--error-map", args.error_map), ("--stats", args.stats, True),
                           *((f"--map {name}", path) for name, path in maps.items()), scene=args.scene)
    opts = options_from_args(args)
    with outs:  # every output replaces its file at the end, or none does
        scene = load_inputs(outs, args.scene)
        _import_losses(args, scene)
        for warning in check_extent(scene, opts.precision):  # what it cannot bound raises, before any work
            print(f"psrt {args.command}: warning: {warning}", file=sys.stderr)
        width, height = args.size or scene.image_size or (512, 512)
        needs_ref = bool(args.error_map or args.stats or any(CHANNELS[name].needs_reference for name in maps))
        memory.check_render(width, height, reference=needs_ref, limit=args.memory_limit)
        with _bar(unit_count(width, height, opts), "render", args.quiet) as bar:
            frame = _render(args, scene, opts, (width, height), bar)
        outs.write(args.output, lambda f: to_png(shade(frame, scene, opts.mode), f))
        if args.aov:
            outs.write(args.aov, frame.save_npz)
        if args.effort_map:
            _write_png(outs, channel_image("effort", frame), args.effort_map)
        ref = None
        if needs_ref:
            with _bar(frame.tiles_total, "float64 reference", args.quiet) as bar:
                ref = reference_frame(scene, frame, progress=bar.update, on_compile=_compile_note(args, bar))
        if args.error_map:
            _write_png(outs, channel_image("error", frame, ref), args.error_map)
        for name, path in maps.items():
            _write_png(outs, channel_image(name, frame, ref), path)
        fs = frame_stats(frame)
        if args.stats:
            from .formats.losses import summary
            from .variants import compile_report
            _write_json(outs, {"scene": str(args.scene), "size": [width, height], "options": asdict(opts), **fs,
                               "reference_time": ref.seconds, "error": error_stats(frame, ref),
                               "kernels": compile_report(),
                               "imports": {src: summary(r) for src, r in scene.import_report.items()}},
                        args.stats)
    _say(args, f"{args.output}: {width}x{height}, {fs['hits']} hits of {fs['rays']} rays in "
               f"{fs['time']:.3f} s{_accel_summary(fs.get('accel'))}, mean effort {fs['effort']['mean']:.1f} box tests/ray")
    return 0


def _render(args, scene, opts, size, bar):
    """The frame, traced here or on the Dask workers of --scheduler (tracer/distributed_render.py)."""
    if args.scheduler == "none":
        from .render import render
        return render(scene, opts, size=size, progress=bar.update, on_compile=_compile_note(args, bar),
                      on_build=_build_note(args, bar))
    from .distributed import open_client
    from .distributed_render import render_distributed
    with open_client(args.scheduler, args.workers) as client:
        return render_distributed(client, scene, opts, size=size, progress=bar.update)


def cmd_trace(args) -> int:
    from .geometry import prepare
    from .plot import trace_plot
    from .ray_tree import ray_tree
    from .trace_one import trace_pixel

    output = args.output or STDOUT
    outs = planned_outputs(("-o", output, True), ("--plot", args.plot), scene=args.scene)
    opts = options_from_args(args)
    with outs:
        scene = load_inputs(outs, args.scene)
        _import_losses(args, scene)
        for warning in check_extent(scene, opts.precision):  # what it cannot bound raises, before any work
            print(f"psrt {args.command}: warning: {warning}", file=sys.stderr)
        x, y = args.pixel
        geom = prepare(scene, opts.precision)
        tr = trace_pixel(scene, opts, x, y, size=args.size, geometry=geom)
        out = tr.to_json()
        tree = ray_tree(scene, opts, x, y, size=args.size, geometry=geom, steps=args.ray_steps) \
            if args.rays or args.ray_steps else None
        if tree is not None:  # a new key: the contract's keys stay as they are
            out["ray_tree"] = tree.to_json(steps=args.ray_steps)
        _write_json(outs, out, output)
        if args.plot:
            outs.write(args.plot, lambda f: trace_plot(tr, f))
    ev = tr.events
    counts = ", ".join(f"{ev.count(k)} {k}" for k in ("split", "miss", "pruned", "hit"))
    what = (f"hit patch {tr.patch} at t={tr.t:.9g}, box {tr.hit_step()}" if tr.hit else "miss")
    _say(args, f"pixel {x},{y}: {what}; {len(ev)} boxes ({counts}), effort {tr.effort}"
               + (" [trace truncated]" if tr.truncated else ""))
    if tree is not None:
        _say(args, f"ray tree: {tree.census()}")
    return 0


def cmd_bench(args) -> int:
    from .bench import format_table, run_bench

    if args.coherence:
        from .cli_coherence import cmd_bench_coherence
        return cmd_bench_coherence(args)
    if args.penumbra_sweep:
        from .cli_coherence import cmd_bench_penumbra
        return cmd_bench_penumbra(args)
    if args.scenes or args.tables:
        raise ValueError(f"{'--scenes' if args.scenes else '--tables'}: only with --coherence")
    args.scene = args.scene or str(_default_scene())
    size, runs = args.size or (512, 512), args.runs or 5
    outs = planned_outputs(("--json", args.json, True), scene=args.scene)
    base = options_from_args(args)
    with outs:
        scene = load_inputs(outs, args.scene)
        memory.check_render(*size, reference=True, frames=2, limit=args.memory_limit)
        log = None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
        result = run_bench(scene, base, size=size, runs=runs, criteria=args.criteria,
                           splits=args.splits, precisions=args.precisions, log=log)
        result["scene"] = str(args.scene)
        if args.json:
            _write_json(outs, result, args.json)
    print(format_table(result))
    return 0


def _add_quiet(parser):
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bars or summary lines on stderr")


def _add_strict(parser):
    parser.add_argument("--strict", action="store_true",
                        help="fail (exit 2) if an imported file (IGES) lost anything: entities not "
                             "converted, or a file cut short")


def _add_memory_limit(parser):
    parser.add_argument("--memory-limit", type=parse_memory, metavar="SIZE",
                        help=f"refuse a render estimated to need more memory than this, e.g. 8G or 512M "
                             f"(default: ${memory.ENV}, else {memory.DEFAULT_FRACTION * 100:.0f}%% of physical memory)")


def add_scheduler_flags(parser, default: str) -> None:
    """--scheduler and --workers (tracer/distributed.py)."""
    parser.add_argument("--scheduler", default=default, metavar="ADDRESS",
                        help="run the work units on the Dask scheduler at ADDRESS (tcp://host:8786), on a "
                             "LocalCluster started for the run ('local'), or in this process ('none'; "
                             f"default: {default})")
    parser.add_argument("--workers", type=positive_int, metavar="N",
                        help="worker processes of --scheduler local (default: one per core)")


def add_commands(sub) -> None:
    """Add render, trace, bench and stress to an argparse subparsers object (each sets func=cmd_...)."""
    p = sub.add_parser("render", help="render a scene to a PNG, with optional per-pixel outputs")
    p.add_argument("scene", help="scene .json or .bpt file")
    p.add_argument("-o", "--output", required=True, metavar="IMG.png", help="image in the --mode display")
    p.add_argument("--size", type=parse_size, help="image size WxH (default: the scene's, else 512x512)")
    p.add_argument("--aov", metavar="OUT.npz", help="per-pixel arrays of the contract (scene-format.md)")
    p.add_argument("--effort-map", metavar="PNG", help="box tests per ray on a colour map with a legend")
    p.add_argument("--error-map", metavar="PNG",
                   help="L1 position error against the float64 reference of the same rays (holes red, "
                        "false hits magenta, pixels the reference could not resolve within its box budget orange)")
    p.add_argument("--map", action="append", default=[], type=parse_map, metavar="CHANNEL=PNG",
                   help="any per-pixel channel on a colour map with a legend, e.g. nodes=nodes.png "
                        f"(repeatable; channels: {', '.join(CHANNELS)})")
    p.add_argument("--stats", metavar="JSON", help="rays, hits, time, effort and error statistics, the kernel "
                   "variants compiled and their compile times, the acceleration structure's build time and size "
                   "(computes the float64 reference)")
    add_scheduler_flags(p, default="none")
    add_option_flags(p)
    _add_memory_limit(p)
    _add_quiet(p)
    _add_strict(p)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("trace", help="one pixel's subdivision trace as JSON (and a plot)")
    p.add_argument("scene", help="scene .json or .bpt file")
    p.add_argument("--pixel", type=parse_pixel, required=True, metavar="X,Y", help="column,row; row 0 at the top")
    p.add_argument("-o", "--output", metavar="TRACE.json", help="write the trace here (default: stdout)")
    p.add_argument("--plot", metavar="PNG", help="box diameter over box index, with Dammertz's optimum")
    p.add_argument("--size", type=parse_size, help="image size WxH (default: the scene's, else 512x512)")
    p.add_argument("--rays", action="store_true", help="add the pixel's ray tree under `ray_tree`: its primary, "
                   "shadow, reflected and refracted rays and penumbra tests, as the render traced them")
    p.add_argument("--ray-steps", action="store_true", help="--rays with each ray's subdivision trace")
    add_option_flags(p)
    _add_quiet(p)
    _add_strict(p)
    p.set_defaults(func=cmd_trace)

    p = sub.add_parser("bench", help="time and check every criterion x split x precision (--coherence: the "
                       "coherence options; --penumbra-sweep: the fast penumbra against light size)")
    p.add_argument("--scene", help="scene (default: sample_models/teapot.json)")
    p.add_argument("--size", type=parse_size, help="image size WxH (default: 512x512; --coherence 256x256)")
    p.add_argument("--runs", type=positive_int, help="timed runs per configuration after one warm-up "
                   "(default: 5, --coherence 3; the median is reported)")
    p.add_argument("--json", metavar="OUT", help="write all results as JSON")
    p.add_argument("--criteria", nargs="+", choices=CRITERIA, default=list(CRITERIA), metavar="C",
                   help=f"criteria to run (default: all of {', '.join(CRITERIA)})")
    p.add_argument("--splits", nargs="+", choices=SPLITS, default=list(SPLITS), metavar="S",
                   help=f"split heuristics (default: {', '.join(SPLITS)})")
    p.add_argument("--precisions", nargs="+", choices=PRECISIONS, default=list(PRECISIONS), metavar="P",
                   help=f"precisions (default: {', '.join(PRECISIONS)})")
    from .cli_coherence import add_flags
    add_flags(p)
    add_option_flags(p, exclude=SWEPT)
    _add_memory_limit(p)
    _add_quiet(p)
    p.set_defaults(func=cmd_bench)
    from .cli_stress import add_stress_command  # in its own module: this one is long enough
    add_stress_command(sub)
    from .cli_study import add_study_command
    add_study_command(sub)


def _default_scene() -> Path:
    from .bench import DEFAULT_SCENE
    return DEFAULT_SCENE if DEFAULT_SCENE.exists() else Path("sample_models/teapot.json")
