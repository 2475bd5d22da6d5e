"""The `psrt` console script: render, trace, bench, stress (tracer/cli.py) and view (viewer/cli_view.py).

This is the one module that knows both packages: tracer/ never imports viewer/, and the
viewer's `view` command adds its flags without loading glfw or OpenGL (the window starts
only when the command runs). Bad input (scene errors, option values, sizes, output paths)
prints one line naming the file, key or flag on stderr and exits with status 2 (usage errors
too: `--help` shows the usage); a failed write exits with 1. Set PSRT_TRACEBACK=1 to get the
traceback instead. Run as the program (main() without argv: the console script, python -m
psrt), `view` ends the process as soon as the window has closed.
"""
from __future__ import annotations

import argparse
import os
import sys

from tracer import cli as tracer_cli
from tracer.errors import SceneError
from viewer.cli_view import add_view_command


def _one_line(error) -> str:
    return " ".join(str(error).split())


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (status 2), without the usage."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {_one_line(message)} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="psrt", description="Parametric-surface ray tracer "
                    "(floating-point precision subdivision of Bezier patches).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    tracer_cli.add_commands(sub)
    add_view_command(sub)
    return parser


def main(argv=None) -> int:
    """Entry point of the `psrt` console script; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse: bad usage (2) or --help (0)
        return e.code if isinstance(e.code, int) else 2
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    args.end_process = argv is None  # the program, not a caller in the same process
    try:
        return args.func(args) or 0
    except (SceneError, ValueError) as e:
        if os.environ.get("PSRT_TRACEBACK"):
            raise
        print(f"psrt {args.command}: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except (OSError, MemoryError) as e:
        if os.environ.get("PSRT_TRACEBACK"):
            raise
        what = _one_line(e) if isinstance(e, OSError) else "out of memory (see --memory-limit in the README)"
        print(f"psrt {args.command}: error: {what}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
