"""Argument types and option flags of the tracer's commands (cli.py): plain ASCII numbers,
sizes, pixels, channel maps, and one flag per field of tracer.options.Options."""
from __future__ import annotations

import argparse
import re
from dataclasses import replace

from . import memory
from .options import Options, option_fields, parse_assignment
from .record import quote, read_value
from .stats import CHANNELS

MAX_SIDE = 16384
_INT = "([0-9]{1,9})"  # a plain ASCII integer (no '_', no other scripts' digits), not absurdly long
_SIZE, _PIXEL, _COUNT = (re.compile(p, re.ASCII) for p in (f"{_INT}[xX]{_INT}", f"{_INT},{_INT}", _INT))


def _ints(pattern, text: str):
    """The integers of text matched whole by pattern, or None."""
    m = pattern.fullmatch(text)
    return None if m is None else tuple(int(g) for g in m.groups())


def parse_size(text: str):
    """'WxH' -> (W, H), integers in 1..MAX_SIDE."""
    size = _ints(_SIZE, text)
    if size is None or not all(1 <= side <= MAX_SIDE for side in size):
        raise argparse.ArgumentTypeError(f"expected WxH with integer sides in 1..{MAX_SIDE} (e.g. 512x512), "
                                         f"got {quote(text)}")
    return size


def positive_int(text: str) -> int:
    """A plain ASCII integer >= 1."""
    value = _ints(_COUNT, text)
    if value is None or value[0] < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {quote(text)}")
    return value[0]


def parse_memory(text: str) -> int:
    try:
        return memory.parse_bytes(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def parse_map(text: str):
    """'CHANNEL=PNG' -> (channel, path), the channel one of stats.CHANNELS."""
    name, sep, path = text.partition("=")
    if not sep or not path:
        raise argparse.ArgumentTypeError(f"expected CHANNEL=PNG, got {quote(text)}")
    if name not in CHANNELS:
        raise argparse.ArgumentTypeError(f"unknown channel {quote(name)} (known: {', '.join(CHANNELS)})")
    return name, path


def parse_pixel(text: str):
    """'X,Y' -> (X, Y): column and row (row 0 at the top)."""
    pixel = _ints(_PIXEL, text)
    if pixel is None:
        raise argparse.ArgumentTypeError(f"expected X,Y with non-negative integer column and row, got {quote(text)}")
    return pixel


def option_type(f):
    """The argparse type of field f's flag: read_value (type, integrality, range) as argparse errors."""
    def read(raw):
        try:
            return read_value(f, raw)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    read.__name__ = type(f.default).__name__
    return read


def option_flag(f) -> str:
    return "--" + (f.metadata.get("cli") or f.name.replace("_", "-"))


def add_option_flags(parser, exclude=()):
    """One flag per Options field (type, choices, range and default from its metadata), and --set."""
    groups = {}
    for f in option_fields():
        if f.name in exclude:
            continue
        meta = f.metadata
        group = groups.get(meta["group"]) or groups.setdefault(
            meta["group"], parser.add_argument_group(f"{meta['group'].lower()} options"))
        extra = f"; {'integer' if type(f.default) is int else 'range'} {meta['lo']}..{meta['hi']}" \
            if meta["lo"] is not None else ""
        if isinstance(f.default, bool):  # --trims / --no-trims
            group.add_argument(option_flag(f), dest=f"opt_{f.name}", action=argparse.BooleanOptionalAction,
                               default=None, help=f"{meta['help']} (default: {'on' if f.default else 'off'})")
            continue
        group.add_argument(option_flag(f), dest=f"opt_{f.name}", type=option_type(f), default=None,
                           choices=meta["choices"], metavar=None if meta["choices"] else f.name.upper(),
                           help=f"{meta['help']} (default: {f.default}{extra})")
    parser.add_argument("--set", action="append", default=[], metavar="OPTION=VALUE",
                        help="set any option by name, e.g. --set fixed_size=1e-4 (repeatable, applied last)")


def flag_options(args) -> Options:
    """Options() with the given option flags (the opt_<name> attributes) applied, validated."""
    return replace(Options(), **{f.name: getattr(args, f"opt_{f.name}") for f in option_fields()
                                 if getattr(args, f"opt_{f.name}", None) is not None})


def options_from_args(args) -> Options:
    """Options() with the given flags, then the --set assignments, applied and validated."""
    opts = flag_options(args)
    for text in args.set:
        opts = parse_assignment(opts, text)
    return opts
