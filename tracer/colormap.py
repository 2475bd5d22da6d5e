"""Perceptual colour maps, value scaling and colour-bar legends drawn with PIL.

The maps are a few control points of matplotlib's viridis and inferno
(sRGB, evenly spaced) interpolated linearly: close enough to stay perceptually
ordered, and no matplotlib dependency. Output colours are display-ready sRGB
floats in [0, 1].
"""
from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw, ImageFont

_CONTROL = {
    "viridis": [(68, 1, 84), (72, 40, 120), (62, 73, 137), (49, 104, 142), (38, 130, 142),
                (31, 158, 137), (53, 183, 121), (110, 206, 88), (253, 231, 37)],
    "inferno": [(0, 0, 4), (31, 12, 72), (85, 15, 109), (136, 34, 106), (186, 54, 85),
                (227, 89, 51), (249, 142, 9), (249, 203, 53), (252, 255, 164)],
    "grey": [(0, 0, 0), (255, 255, 255)],
}
MAPS = tuple(_CONTROL)
SCALES = ("linear", "log")
TABLE_SIZE = 256

BACKGROUND = (0.11, 0.11, 0.12)  # legend strip and canvas behind small maps
TEXT = (230, 230, 230)


def table(name: str = "viridis", n: int = TABLE_SIZE) -> np.ndarray:
    """(n, 3) float32 colours of map `name` from 0 to 1."""
    if name not in _CONTROL:
        raise ValueError(f"unknown colour map {name!r} (known: {', '.join(MAPS)})")
    ctrl = np.asarray(_CONTROL[name], np.float64) / 255.0
    x = np.linspace(0.0, 1.0, len(ctrl))
    s = np.linspace(0.0, 1.0, n)
    return np.stack([np.interp(s, x, ctrl[:, c]) for c in range(3)], axis=1).astype(np.float32)


def to_uint8(rgb: np.ndarray) -> np.ndarray:
    """Display floats in [0, 1] quantised to uint8 (values are already sRGB-encoded)."""
    return (np.clip(np.nan_to_num(rgb, nan=0.0), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def auto_range(values, scale: str = "linear"):
    """(lo, hi) over the finite values (positive ones for log); (0, 1) or (1, 10) if there are none."""
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v)]
    if scale == "log":
        v = v[v > 0]
    if v.size == 0:
        return (1.0, 10.0) if scale == "log" else (0.0, 1.0)
    return float(v.min()), float(v.max())


def normalise(values, lo: float, hi: float, scale: str = "linear") -> np.ndarray:
    """Values mapped to [0, 1] (clamped); NaN stays NaN. Log scale clamps values <= 0 to lo."""
    if scale not in SCALES:
        raise ValueError(f"unknown scale {scale!r} (known: {', '.join(SCALES)})")
    v = np.asarray(values, np.float64)
    if scale == "log":
        lo = lo if lo > 0 else 1e-300
        hi = max(hi, lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.log10(np.maximum(v, lo))
        lo, hi = math.log10(lo), math.log10(hi)
    span = hi - lo
    with np.errstate(invalid="ignore"):
        out = (v - lo) / span if span > 0 else np.where(np.isnan(v), np.nan, 0.5)
        return np.clip(out, 0.0, 1.0)


def colorize(values, lo: float, hi: float, scale: str = "linear", cmap: str = "viridis",
             nan_rgb=BACKGROUND) -> np.ndarray:
    """(..., 3) float32 colours of `values` on map `cmap` over [lo, hi]; NaN pixels get nan_rgb."""
    s = normalise(values, lo, hi, scale)
    lut = table(cmap)
    bad = np.isnan(s)
    idx = np.rint(np.where(bad, 0.0, s) * (len(lut) - 1)).astype(np.intp)
    rgb = lut[idx]
    rgb[bad] = nan_rgb
    return rgb


def format_value(x: float) -> str:
    """Short label for a tick value: integers plain, others in 3 significant digits."""
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    if float(x).is_integer() and abs(x) < 1e7:
        return f"{int(x)}"
    return f"{x:.3g}" if 1e-3 <= abs(x) < 1e5 else f"{x:.2e}"


def font(size: int = 12):
    """PIL's default font at a pixel size (FreeType build), else its bitmap font."""
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, ImportError, OSError):  # Pillow without FreeType
        return ImageFont.load_default()


def legend_image(width: int, lo: float, hi: float, *, label: str = "", units: str = "",
                 scale: str = "linear", cmap: str = "viridis", specials=(), bar: bool = True,
                 height: int | None = None) -> Image.Image:
    """A colour bar strip `width` pixels wide: the map from lo to hi with min/max (and middle)
    numbers, a title "label [units, scale]", and swatches for special colours.

    specials: (rgb, text) pairs, e.g. ((1, 0, 0), "hole: reference hit, this render missed").
    """
    f = font(12)
    pad, bar_h, line = 8, 14, 16
    h = height or (pad + line + (bar_h + 4 + line if bar else 0) + len(specials) * line + pad)
    img = Image.new("RGB", (width, h), tuple(int(255 * c) for c in BACKGROUND))
    d = ImageDraw.Draw(img)
    unit_txt = ", ".join(p for p in (units, "log scale" if scale == "log" else "") if p)
    d.text((pad, pad), f"{label} [{unit_txt}]" if unit_txt else label, font=f, fill=TEXT)
    y = pad + line
    if bar:
        y = _draw_bar(img, d, f, y, pad, width, lo, hi, scale, cmap)
    for rgb, text in specials:
        d.rectangle([pad, y + 2, pad + 10, y + 12], fill=tuple(int(255 * c) for c in rgb),
                    outline=TEXT)
        d.text((pad + 16, y), text, font=f, fill=TEXT)
        y += line
    return img


def _draw_bar(img, d, f, y_bar, pad, width, lo, hi, scale, cmap) -> int:
    """The colour ramp at row y_bar with ticks and numbers under it; returns the next free row."""
    bar_h, line = 14, 16
    x0, x1 = pad, max(width - pad, pad + 2)
    ramp = table(cmap)[np.linspace(0, TABLE_SIZE - 1, x1 - x0).astype(int)]
    bar = np.repeat((ramp[None] * 255 + 0.5).astype(np.uint8), bar_h, axis=0)
    img.paste(Image.fromarray(bar, "RGB"), (x0, y_bar))
    y_num = y_bar + bar_h + 4
    mid = math.sqrt(lo * hi) if scale == "log" and lo > 0 else 0.5 * (lo + hi)
    for value, anchor, x in ((lo, "la", x0), (mid, "ma", (x0 + x1) // 2), (hi, "ra", x1)):
        if anchor == "ma" and width < 200:
            continue  # no room for three numbers
        d.line([(x, y_bar + bar_h), (x, y_bar + bar_h + 3)], fill=TEXT)
        d.text((x, y_num), format_value(value), font=f, fill=TEXT, anchor=anchor)
    return y_num + line


def with_legend(rgb: np.ndarray, legend: Image.Image) -> Image.Image:
    """The map image (H, W, 3 floats) above its legend, on a canvas as wide as the wider one."""
    top = Image.fromarray(to_uint8(rgb), "RGB")
    w = max(top.width, legend.width)
    out = Image.new("RGB", (w, top.height + legend.height), tuple(int(255 * c) for c in BACKGROUND))
    out.paste(top, (0, 0))
    out.paste(legend, (0, top.height))
    return out
