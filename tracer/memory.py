"""The memory a render needs, estimated before it starts and held against a documented limit.

Per pixel and frame: the primary rays (origins and directions, float64) and every kernel
channel (kernel_channels.KERNEL_CHANNELS); on top of that the larger of two peaks, measured
with tracemalloc on a scene that fills the image (a scene that hits fewer pixels needs less)
and rounded up: shading and writing the image, or the float64 reference's channels with the
maps and error statistics drawn from it. Memory proportional to the scene (its patches and
their prepared leaves) is not counted.

The limit is DEFAULT_FRACTION of the physical memory (or of the cgroup's limit, if lower); the
environment variable PSRT_MEMORY_LIMIT or the CLI's --memory-limit (e.g. 8G, 512M) sets it.
"""
from __future__ import annotations

import math
import os
import re

import numpy as np

from .kernel_channels import KERNEL_CHANNELS
from .record import quote

ENV = "PSRT_MEMORY_LIMIT"
DEFAULT_FRACTION = 0.5
RAY_BYTES = 2 * 3 * 8  # origins and directions, (H, W, 3) float64 each
# Measured peaks beyond the frame's rays and channels (185 B/px), a 384x384 quad filling the
# image minus 128x128: shading and the PNG 345 B/px; the reference phase 137 + 154 B/px.
SHADE_SCRATCH_BYTES = 384
REFERENCE_SCRATCH_BYTES = 192

_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}
_SIZE = re.compile(r"([0-9]{1,15}(?:\.[0-9]{1,15})?)\s*([kmgt]?)(?:i?b)?", re.ASCII | re.IGNORECASE)


def channel_bytes() -> int:
    """Bytes a pixel of every kernel channel takes."""
    return sum(np.dtype(c.dtype).itemsize * math.prod(c.tail) for c in KERNEL_CHANNELS)


def render_bytes(width: int, height: int, *, reference: bool = False, frames: int = 1) -> int:
    """Estimated peak bytes of a width x height render: `frames` frames alive at once (each with
    its own rays), and the float64 reference of one of them if `reference`."""
    frame = RAY_BYTES + channel_bytes()
    peak = max(SHADE_SCRATCH_BYTES, channel_bytes() + REFERENCE_SCRATCH_BYTES if reference else 0)
    return width * height * (frames * frame + peak)


def parse_bytes(text: str) -> int:
    """'8G', '512M', '1.5GiB', '100000' -> bytes (binary units), at least 1."""
    m = _SIZE.fullmatch(text.strip())
    value = 0 if m is None else int(float(m.group(1)) * _UNITS[m.group(2).lower()])
    if value < 1:
        raise ValueError(f"expected a memory size such as 8G, 512M or 1000000 (bytes), got {quote(text)}")
    return value


def physical_memory() -> tuple[int, str]:
    """(bytes, what they are): the physical memory, or the cgroup's limit where that is lower."""
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    what = "physical memory"
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as f:
                text = f.read().strip()
        except OSError:
            continue
        if text.isdigit() and 0 < int(text) < total:
            total, what = int(text), "the cgroup's memory limit"
    return total, what


def memory_limit(limit: int | None = None) -> tuple[int, str]:
    """(bytes, where the limit comes from): `limit` if given, else $PSRT_MEMORY_LIMIT, else
    DEFAULT_FRACTION of physical_memory()."""
    if limit is not None:
        return limit, "--memory-limit"
    text = os.environ.get(ENV)
    if text:
        try:
            return parse_bytes(text), f"${ENV}"
        except ValueError as e:
            raise ValueError(f"${ENV}: {e}") from None
    total, what = physical_memory()
    return int(total * DEFAULT_FRACTION), f"{DEFAULT_FRACTION:.0%} of the {format_bytes(total)} of {what}"


def format_bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"


def check_render(width: int, height: int, *, reference: bool = False, frames: int = 1,
                 limit: int | None = None) -> int:
    """The estimate of render_bytes; ValueError with the figure and the limit if it is over."""
    need = render_bytes(width, height, reference=reference, frames=frames)
    allowed, source = memory_limit(limit)
    if need > allowed:
        per_pixel = need // (width * height)
        raise ValueError(f"a {width}x{height} render needs about {format_bytes(need)} ({per_pixel} bytes a pixel"
                         f"{', with the float64 reference' if reference else ''}), over the memory limit of "
                         f"{format_bytes(allowed)} ({source}); use a smaller --size, or set --memory-limit "
                         f"or ${ENV}")
    return need
