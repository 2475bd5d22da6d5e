"""The per-pixel quantities the tile kernel computes, declared once.

Each entry names a channel of the output contract (scene-format.md), its dtype, its trailing
shape and its value on a miss. The renderer allocates the kernel's outputs from this list
(records.Outputs follows it field by field), Frame carries them, the `.npz` writes them, and
the counters (`effort`, `nodes`, `patches_tested`) become overlays, CLI maps and `--stats`
summaries through stats.py. A new kernel quantity is one entry here and one line in the
tile kernel that writes it.
"""
from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class KernelChannel:
    name: str
    dtype: object
    tail: tuple          # trailing shape after (H, W)
    miss: object         # value where the ray hits nothing (and before it is traced)
    help: str
    counter: bool = False  # an effort counter: shown as a map and summarised in --stats
    label: str = ""
    units: str = ""


KERNEL_CHANNELS = (
    KernelChannel("hit", bool, (), False, "the primary ray hit a surface"),
    KernelChannel("t", np.float64, (), np.inf, "ray parameter of the reported hit"),
    KernelChannel("position", np.float64, (3,), np.nan, "centre of the final hit box"),
    KernelChannel("box_min", np.float64, (3,), np.nan, "the final hit box, low corner"),
    KernelChannel("box_max", np.float64, (3,), np.nan, "the final hit box, high corner"),
    KernelChannel("normal", np.float64, (3,), 0.0, "unit surface normal at the hit, as used for shading"),
    KernelChannel("uv", np.float64, (2,), np.nan, "patch parameters of the hit"),
    KernelChannel("patch", np.int32, (), -1, "global index of the hit patch in scene order"),
    KernelChannel("effort", np.int32, (), 0, "bounding-box tests spent on the primary ray (all candidate patches)",
                  counter=True, label="effort", units="box tests"),
    KernelChannel("nodes", np.int32, (), 0, "aggregate nodes the primary ray visited", counter=True,
                  label="nodes visited", units="nodes"),
    KernelChannel("patches_tested", np.int32, (), 0, "patches whose bounds the primary ray met and whose search "
                  "was started", counter=True, label="patches tested", units="patches"),
    KernelChannel("surfaces_tested", np.int32, (), 0, "patches whose outermost bounding box was tested against "
                  "the primary ray (Lischinski's surfaces tested)", counter=True, label="surfaces tested",
                  units="patches"),
    KernelChannel("box_tests", np.int32, (), 0, "ray-box tests of the primary ray: aggregate nodes, patch boxes, "
                  "cached surface-tree nodes and sub-patch boxes", counter=True, label="ray-box tests", units="boxes"),
    KernelChannel("cache_hits", np.int32, (), 0, "patch searches of the primary ray that started from a cached "
                  "surface tree", counter=True, label="cache hits", units="searches"),
    KernelChannel("cache_misses", np.int32, (), 0, "patch searches of the primary ray that found no cached surface "
                  "tree (with the cache on)", counter=True, label="cache misses", units="searches"),
    KernelChannel("unresolved", bool, (), False, "the ray's box budget ran out (renders given one: the float64 "
                  "reference): its hit, or miss, is not known to be the closest"),
)
CHANNEL_NAMES = tuple(c.name for c in KERNEL_CHANNELS)
COUNTERS = tuple(c for c in KERNEL_CHANNELS if c.counter)

# The tile kernel's outputs, one array per channel, in the order above.
Outputs = namedtuple("Outputs", CHANNEL_NAMES)


def allocate(height: int, width: int, filled: bool = True) -> dict:
    """Every kernel channel for an image, filled with its miss value; unfilled (filled=False) where
    the tile kernel will write every pixel before anybody reads one (it writes every channel of
    each pixel it traces, hit or miss)."""
    if not filled:
        return {c.name: np.empty((height, width) + c.tail, c.dtype) for c in KERNEL_CHANNELS}
    return {c.name: np.full((height, width) + c.tail, c.miss, c.dtype) for c in KERNEL_CHANNELS}


def fill_miss(channels, rows, columns) -> None:
    """Give pixels (rows[i], columns[i]) of every kernel channel (an object with one attribute per
    channel, as Frame or Outputs) its miss value: pixels never traced."""
    for c in KERNEL_CHANNELS:
        getattr(channels, c.name)[rows, columns] = c.miss
