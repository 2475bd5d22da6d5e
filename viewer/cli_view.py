"""The `psrt view` subcommand: the interactive viewer, or a scripted run of it.

psrt/cli.py adds it beside the tracer's commands with `add_view_command(subparsers)` (sets
func=run_view) and dispatches with `args.func(args)`; `python -m viewer.cli_view` runs it on
its own. Nothing that loads glfw or OpenGL is imported before the command runs.
"""
from __future__ import annotations

import argparse
import os
import sys


def _pair(text: str, sep: str, what: str):
    try:
        a, b = (int(v) for v in text.lower().split(sep))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    return a, b


def _size(text):
    w, h = _pair(text, "x", "WIDTHxHEIGHT, e.g. 128x128")
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise argparse.ArgumentTypeError(f"image size {text!r} must be between 1x1 and 16384x16384")
    return w, h


def _click(text):
    return _pair(text, ",", "X,Y in image pixels (column, row; row 0 at the top)")


def _count(text):
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number of frames >= 0, got {text!r}")
    return n


def _seconds(text):
    try:
        t = float(text)
    except ValueError:
        t = float("nan")
    if not (0 < t < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return t


def add_view_command(subparsers) -> argparse.ArgumentParser:
    """Add `view` to an argparse subparsers object; returns the subparser.

    Tracer option flags (and --set) come from tracer.cli.add_option_flags, as for `render`;
    --set also takes the viewer's own settings (overlay=error, exposure=1, ...).
    """
    from tracer.cli import add_option_flags

    p = subparsers.add_parser(
        "view", help="open the interactive viewer (or run it scripted)",
        description="Open the interactive debugger window on a scene. With --click, --screenshot, "
                    "--dump-inspector, --status... the real window runs the given actions, writes the outputs once "
                    "the render has finished, and exits: 0 when every step worked, 3 on --timeout or --frames, "
                    "4 when the click failed, 5 when a scene failed to load, 6 when the render failed, 2 when an "
                    "output could not be written, 130 on Ctrl-C (with one line on stderr saying why).")
    p.add_argument("scene", nargs="?", help="scene .json or patch .bpt file")
    p.add_argument("--size", type=_size, metavar="WxH",
                   help="fixed image size in pixels (default: follow the window)")
    add_option_flags(p)
    add_script_flags(p)
    p.set_defaults(func=run_view)
    return p


def add_script_flags(p) -> None:
    p.add_argument("--at", action="append", default=[], metavar="WHEN:OPTION=VALUE",
                   help="change an option at UI frame WHEN, or WHEN=mid-render: once the first full-resolution "
                        "tile has arrived (the render waits there for it), or WHEN=after-render: once the frame "
                        "is traced")
    p.add_argument("--click", type=_click, metavar="X,Y", help="click image pixel X,Y once the render is done")
    p.add_argument("--load", metavar="FILE", help="open FILE in the running viewer after the first render")
    p.add_argument("--frames", type=_count, metavar="N",
                   help="give up (exit 3) after N UI frames drawn while the script waits for nothing (frames "
                        "spent waiting for a load, a compile or the render do not count: --timeout bounds those)")
    p.add_argument("--timeout", type=_seconds, metavar="SECONDS",
                   help="give up (exit 3, outputs written as they are) after SECONDS of wall clock; by default "
                        "a scripted run waits as long as its load, compiles and render take")
    p.add_argument("--screenshot", metavar="PNG", help="write the view (image, overlays, box outlines)")
    p.add_argument("--window-screenshot", metavar="PNG", help="write the whole window, panels included")
    p.add_argument("--dump-inspector", metavar="JSON", help="write the clicked pixel's trace (contract JSON)")
    p.add_argument("--aov", metavar="NPZ", help="write the final render's per-pixel arrays")
    p.add_argument("--status", metavar="JSON", help="write what happened (phases, timings, errors) as JSON")
    p.add_argument("--wait-reference", action="store_true",
                   help="also wait for the float64 reference before the outputs")


def _scripted(args) -> bool:
    return any((args.frames is not None, args.timeout is not None, args.screenshot, args.window_screenshot,
                args.dump_inspector, args.click, args.aov, args.status, args.at, args.load))


def run_view(args) -> int:
    """Run the viewer for parsed `psrt view` arguments; returns the exit code.

    Tracer options come from the option flags; --set assignments go to the options or the
    viewer settings. With args.end_process (the program's own command line) the process ends
    when the window has closed (end_process) instead of returning.
    """
    from tracer.cli import flag_options
    from viewer.script import Script, parse_at
    from viewer.state import ViewSettings, assign

    try:
        opts = flag_options(args)
        settings = ViewSettings()
        for text in args.set:
            opts, settings = assign(opts, settings, text)  # fail before any window opens
        at = [parse_at(text) for text in args.at]
        for _, text in at:
            assign(opts, settings, text)
    except ValueError as e:
        print(f"psrt view: error: {e}", file=sys.stderr)
        return 2
    if args.scene and not os.path.exists(args.scene):
        print(f"psrt view: error: {args.scene}: no such file", file=sys.stderr)
        return 2
    if args.dump_inspector and not args.click:
        print("psrt view: error: --dump-inspector needs --click X,Y", file=sys.stderr)
        return 2
    from viewer.app import run

    script = None
    if _scripted(args):
        script = Script(at=at, click=args.click, load=args.load, screenshot=args.screenshot,
                        window_screenshot=args.window_screenshot, dump_inspector=args.dump_inspector,
                        aov=args.aov, status=args.status, wait_reference=True if args.wait_reference else None,
                        frames=args.frames, timeout=args.timeout)
    try:
        code = run(args.scene, args.frames, size=args.size, script=script, opts=opts, settings=settings)
    except KeyboardInterrupt:  # a second Ctrl-C
        code = 130
    if getattr(args, "end_process", False):
        end_process(code)
    return code


def end_process(code: int) -> None:
    """End the program at once, its outputs written: a tile, load or shading still running on
    its thread cannot be interrupted and nothing waits for its result, while the interpreter's
    exit would wait for the tile threads and then tear down numba's modules (0.4-1 s here)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def main(argv=None, end_process=None) -> int:
    """`python -m viewer.cli_view SCENE ...`: the view command on its own. end_process: end the
    process when the window closes (default: when run as the program, argv None)."""
    parser = argparse.ArgumentParser(prog="psrt")
    add_view_command(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["view"] + list(sys.argv[1:] if argv is None else argv))
    args.end_process = argv is None if end_process is None else end_process
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
