"""CPU side of the overlay: one tracer.stats channel's values per pixel, filled unit by unit.

Channels are elementwise, so a tile's values come from the channel evaluated on views of the
frame's arrays sliced to the tile, and a scattered unit's from copies of its pixels' values
laid out as one row. The GPU maps values to colours (shaders/image.frag).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from tracer import colormap
from tracer.render import AOV_NAMES
from tracer.stats import CHANNELS

from .display import MAX_SPECIALS
from .state import DEFAULT_CHANNEL


def sub_frame(frame, rect):
    """The frame restricted to rect (y0, y1, x0, x1): views, no copies."""
    y0, y1, x0, x1 = rect
    return replace(frame, **{n: getattr(frame, n)[y0:y1, x0:x1] for n in AOV_NAMES if getattr(frame, n) is not None})


def pixels_frame(frame, pixels):
    """The frame's values at pixels (k, 2) (row, column), as a frame of one row of k pixels."""
    rows, cols = pixels[:, 0], pixels[:, 1]
    return replace(frame, **{n: getattr(frame, n)[rows, cols][None] for n in AOV_NAMES
                             if getattr(frame, n) is not None})


class Overlay:
    """Values (H, W, 2 float32: value, special class) of the selected channel."""

    def __init__(self):
        self.name = "none"
        self.data = np.zeros((0, 0, 2), np.float32)
        self.specials = []   # [(rgb, text)] of the channel, class k + 1 each
        self.dirty_range = True

    @property
    def channel(self):
        return CHANNELS.get(self.name)

    def reset(self, name: str, size) -> None:
        w, h = size
        self.name = name
        self.data = np.zeros((h, w, 2), np.float32)
        self.data[..., 0] = np.nan
        self.specials = []
        self.dirty_range = True

    def fill(self, frame, ref, rect=None, pixels=None) -> bool:
        """Evaluate the channel on rect (default: the whole frame), or only at pixels (k, 2)
        (row, column); False if it cannot be yet."""
        ch = self.channel
        if ch is None or frame is None or (ch.needs_reference and ref is None):
            return False
        h, w = frame.hit.shape
        rect = rect or (0, h, 0, w)
        if self.data.shape[:2] != (h, w):
            self.reset(self.name, (w, h))
        if pixels is not None:
            f = pixels_frame(frame, pixels)
            r = pixels_frame(ref, pixels) if ref is not None else None
            block = np.empty((1, len(pixels), 2), np.float32)
        else:
            f = sub_frame(frame, rect)
            r = sub_frame(ref, rect) if ref is not None else None
            y0, y1, x0, x1 = rect
            block = self.data[y0:y1, x0:x1]
        block[..., 0] = ch.values(f, r)
        block[..., 1] = 0.0
        specials = ch.specials(f, r) if ch.specials else []
        for k, (mask, rgb, text) in enumerate(specials[:MAX_SPECIALS]):
            block[..., 1][mask] = k + 1  # later classes win, as in stats.channel_rgb
        if pixels is not None:
            self.data[pixels[:, 0], pixels[:, 1]] = block[0]
        self.specials = [(rgb, text) for _, rgb, text in specials[:MAX_SPECIALS]]
        self.dirty_range = True
        return True

    def fill_coarse(self, coarse, size, factor: int) -> bool:
        """Fill the whole image from a coarse preview frame, upscaled (nearest)."""
        ch = self.channel
        if ch is None or ch.needs_reference:
            return False
        w, h = size
        small = Overlay()
        small.name = self.name
        if not small.fill(coarse, None):
            return False
        self.data = np.repeat(np.repeat(small.data, factor, 0), factor, 1)[:h, :w].copy()
        self.specials = small.specials
        self.dirty_range = True
        return True

    def scale(self, settings) -> str:
        ch = self.channel
        return settings.scale if settings.scale != DEFAULT_CHANNEL else (ch.scale if ch else "linear")

    def colormap(self, settings) -> str:
        ch = self.channel
        if settings.colormap != DEFAULT_CHANNEL:
            return settings.colormap
        return ch.cmap if ch and ch.cmap else "viridis"

    def value_range(self, settings) -> tuple:
        """(lo, hi) per settings.range: min..max, min..mean+3 sigma, or manual."""
        if settings.range == "manual":
            return settings.range_lo, settings.range_hi
        scale = self.scale(settings)
        values = self.data[..., 0]
        values = values[self.data[..., 1] == 0]
        lo, hi = colormap.auto_range(values, scale)
        if settings.range == "3sigma":
            v = values[np.isfinite(values)]
            if scale == "log":
                v = v[v > 0]
            if v.size:
                hi = min(hi, float(v.mean() + 3.0 * v.std()))
                hi = max(hi, lo)
        return lo, hi
