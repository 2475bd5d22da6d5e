"""The one options record, shared by the command line and the viewer.

Each field carries its default, help text, choices or range and a UI hint in
its metadata, so `cli.py` builds its arguments and the viewer its widgets from
this single description. Kernels receive plain scalars derived from it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, fields, replace

CRITERIA = ("float", "fixed", "adaptive", "mantissa")
SPLITS = ("length", "cross")
PRECISIONS = ("f32", "f64")
MODES = ("shaded", "normal", "uv", "depth", "patch")

# Kernel codes: small ints so the numba kernels take scalars, not strings.
CRITERION_CODE = {name: i for i, name in enumerate(CRITERIA)}
SPLIT_CODE = {name: i for i, name in enumerate(SPLITS)}


def _opt(default, help, *, choices=None, lo=None, hi=None, log=False, group="Tracer", cli=None, when=None):
    meta = {"help": help, "choices": choices, "lo": lo, "hi": hi, "log": log, "group": group, "cli": cli,
            "when": when}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class Options:
    """Everything that changes what the tracer computes or shows."""

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

    def with_(self, **changes) -> "Options":
        """A copy with some fields changed, validated."""
        return replace(self, **changes)

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            meta = f.metadata
            if meta["choices"] is not None and value not in meta["choices"]:
                raise ValueError(f"option {f.name}: {value!r} is not one of {', '.join(meta['choices'])}")
            if meta["lo"] is not None and not (meta["lo"] <= value <= meta["hi"]):
                raise ValueError(f"option {f.name}: {value!r} is outside [{meta['lo']}, {meta['hi']}]")


def option_fields():
    """The dataclass fields of Options, in declaration order."""
    return dataclasses.fields(Options)


def parse_assignment(opts: Options, text: str) -> Options:
    """Apply one `name=value` assignment (as given to `--set`) to an options record."""
    if "=" not in text:
        raise ValueError(f"expected option=value, got {text!r}")
    name, raw = (s.strip() for s in text.split("=", 1))
    by_name = {f.name: f for f in option_fields()}
    if name not in by_name:
        raise ValueError(f"unknown option {name!r} (known: {', '.join(by_name)})")
    kind = type(getattr(Options(), name))
    try:
        value = parse_bool(raw) if kind is bool else kind(float(raw)) if kind in (int, float) else kind(raw)
    except ValueError:
        raise ValueError(f"option {name}: cannot read {raw!r} as {kind.__name__}") from None
    return replace(opts, **{name: value})


def parse_bool(raw: str) -> bool:
    """true/false, on/off, yes/no, 1/0."""
    word = raw.strip().lower()
    if word in ("true", "on", "yes", "1"):
        return True
    if word in ("false", "off", "no", "0"):
        return False
    raise ValueError(f"cannot read {raw!r} as a boolean (true/false)")
