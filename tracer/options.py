"""The one options record, shared by the command line and the viewer.

Each field carries its default, help text, choices or range and a UI hint in
its metadata (tracer/record.py), so `cli.py` builds its arguments and the viewer
its widgets from this single description. Kernels receive plain scalars derived
from it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial

from .record import Record, assign, described

CRITERIA = ("float", "fixed", "adaptive", "mantissa")
SPLITS = ("length", "cross")
PRECISIONS = ("f32", "f64")
MODES = ("shaded", "normal", "uv", "depth", "patch")

# Kernel codes: small ints so the numba kernels take scalars, not strings.
CRITERION_CODE = {name: i for i, name in enumerate(CRITERIA)}
SPLIT_CODE = {name: i for i, name in enumerate(SPLITS)}

_opt = partial(described, group="Tracer")


@dataclass(frozen=True)
class Options(Record):
    """Everything that changes what the tracer computes or shows."""

    NOUN = "option"

    criterion: str = _opt("float", "termination criterion of the subdivision", choices=CRITERIA)
    fixed_size: float = _opt(1e-3, "fixed: stop when the box's L1 diameter is at most this (world units)",
                             lo=1e-9, hi=10.0, log=True, when={"criterion": "fixed"})
    pixel_fraction: float = _opt(0.5, "adaptive: stop when the box's L1 diameter is at most this fraction "
                                 "of the pixel footprint at its distance", lo=0.01, hi=8.0, log=True,
                                 when={"criterion": "adaptive"})
    mantissa_ulps: int = _opt(64, "mantissa: stop when box corners lie within this many ulps per coordinate "
                              "(of the patch-frame coordinates the arithmetic uses)",
                              lo=0, hi=1 << 20, log=True, when={"criterion": "mantissa"})
    split: str = _opt("length", "split heuristic: longer parameter direction, or cross product with the ray",
                      choices=SPLITS)
    precision: str = _opt("f32", "working precision of the subdivision", choices=PRECISIONS)
    trims: bool = _opt(True, "apply trimming curves (off: show trimmed surfaces whole)")
    mode: str = _opt("shaded", "what the image shows", choices=MODES, group="Display")
    tile_size: int = _opt(32, "tile edge in pixels (tiles render in parallel)", lo=4, hi=256, group="Render")
    threads: int = _opt(0, "render threads (0: one per core)", lo=0, hi=256, group="Render")


def option_fields():
    """The dataclass fields of Options, in declaration order."""
    return dataclasses.fields(Options)


def parse_assignment(opts: Options, text: str) -> Options:
    """Apply one `name=value` assignment (as given to `--set`) to an options record."""
    return assign((opts,), text)[0]
