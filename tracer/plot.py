"""Plot of one pixel's subdivision trace: box L1 diameter over box index (Dammertz figs. 2.10-2.11).

Drawn with PIL only: log-scale y axis with decade ticks, the optimum
d(n) = s (1/2)^(n/2) of equation 2.7 (s = the first box's diameter), every box
coloured by what became of it, hit boxes circled in red (the reported one bold).
"""
from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw

from .colormap import font, format_value

EVENT_COLOURS = {"miss": (150, 150, 150), "pruned": (235, 150, 40), "split": (60, 120, 220),
                 "hit": (30, 170, 70)}
OPTIMUM_COLOUR = (150, 60, 200)
HIT_RING = (220, 20, 20)
AXIS = (40, 40, 40)
GRID = (228, 228, 228)
MARGIN = (78, 196, 44, 52)  # left, right, top, bottom


def _nice_step(span: float, max_ticks: int = 10) -> float:
    """A 1-2-5 step giving at most max_ticks ticks over span."""
    raw = max(span / max_ticks, 1e-12)
    mag = 10 ** math.floor(math.log10(raw))
    return next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)


def _decade_label(k: int) -> str:
    return f"1e{k}" if k not in (0, 1, 2) else format_value(10.0 ** k)


def trace_plot(trace, path=None, size=(960, 500)) -> Image.Image:
    """Draw `trace` (a trace_one.PixelTrace); save to `path` (PNG) if given; return the image."""
    width, height = size
    img = Image.new("RGB", (width, height), (255, 255, 255))
    d = ImageDraw.Draw(img)
    f, f_small = font(13), font(11)
    left, right, top, bottom = MARGIN
    x0, x1, y0, y1 = left, width - right, top, height - bottom  # plot area, y0 at the top
    diam = np.asarray(trace.diameters, np.float64)
    events = list(trace.events)
    n = len(diam)
    outcome = f"hit patch {trace.patch}" if trace.hit else "miss"
    title = (f"pixel ({trace.pixel[0]}, {trace.pixel[1]}): {n} boxes, {outcome}, effort {trace.effort}"
             + (" (trace truncated)" if getattr(trace, "truncated", False) else ""))
    d.text((x0, 10), title, font=f, fill=AXIS)

    positive = diam[diam > 0]
    lo = float(positive.min()) if positive.size else 1e-6
    hi = float(positive.max()) if positive.size else 1.0
    ky0, ky1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    if ky1 <= ky0:
        ky1 = ky0 + 1
    x_hi = max(n - 1, 1)

    def px(i):
        return x0 + (np.asarray(i, np.float64) / x_hi) * (x1 - x0)

    def py(v):
        lv = np.log10(np.maximum(np.asarray(v, np.float64), 10.0 ** ky0))
        return y1 - (lv - ky0) / (ky1 - ky0) * (y1 - y0)

    # grid, ticks and labels
    kstep = max(1, math.ceil((ky1 - ky0) / 12))
    for k in range(ky0, ky1 + 1, kstep):
        y = float(py(10.0 ** k))
        d.line([(x0, y), (x1, y)], fill=GRID)
        d.line([(x0 - 5, y), (x0, y)], fill=AXIS)
        d.text((x0 - 8, y), _decade_label(k), font=f_small, fill=AXIS, anchor="rm")
    step = _nice_step(x_hi)
    for i in np.arange(0, x_hi * (1 + 1e-9), step):
        x = float(px(i))
        d.line([(x, y1), (x, y1 + 5)], fill=AXIS)
        d.text((x, y1 + 8), format_value(float(i)), font=f_small, fill=AXIS, anchor="ma")
    d.rectangle([x0, y0, x1, y1], outline=AXIS)
    d.text(((x0 + x1) / 2, height - 18), "box index n", font=f, fill=AXIS, anchor="ma")
    label = Image.new("RGB", (200, 18), (255, 255, 255))
    ImageDraw.Draw(label).text((100, 9), "box L1 diameter", font=f, fill=AXIS, anchor="mm")
    img.paste(label.rotate(90, expand=True), (4, int((y0 + y1) / 2 - 100)))

    if n == 0:
        d.text(((x0 + x1) / 2, (y0 + y1) / 2), "no boxes: the ray missed every patch's bounds",
               font=f, fill=AXIS, anchor="mm")
    else:
        # optimum of Dammertz eq. 2.7, drawn while it is inside the plot
        idx = np.linspace(0, x_hi, 400)
        opt = diam[0] * 0.5 ** (idx / 2.0)
        keep = opt >= 10.0 ** ky0
        if keep.sum() >= 2:
            d.line(list(zip(px(idx[keep]).tolist(), py(opt[keep]).tolist())), fill=OPTIMUM_COLOUR, width=2)
        xs, ys = px(np.arange(n)).tolist(), py(diam).tolist()
        if n > 1:
            d.line(list(zip(xs, ys)), fill=(205, 205, 205), width=1)
        r = 2 if n < 3000 else 1
        for x, y, e in zip(xs, ys, events):
            d.ellipse([x - r, y - r, x + r, y + r], fill=EVENT_COLOURS[e])
        final = trace.hit_step()
        for i, e in enumerate(events):
            if e == "hit":
                ring, w = (8, 3) if i == final else (5, 1)
                d.ellipse([xs[i] - ring, ys[i] - ring, xs[i] + ring, ys[i] + ring], outline=HIT_RING, width=w)
        if final >= 0:
            side = -10 if xs[final] > x1 - 60 else 10  # keep the label inside the plot
            d.text((xs[final] + side, ys[final] - 10), f"n = {final}", font=f_small, fill=HIT_RING,
                   anchor="rb" if side < 0 else "lb")

    entries = [(EVENT_COLOURS[k], k, "dot") for k in ("split", "miss", "pruned", "hit")]
    entries += [(HIT_RING, "reported hit box", "ring"), (OPTIMUM_COLOUR, "optimum s(1/2)^(n/2)", "line")]
    lx, ly = x1 + 20, y0 + 8  # in the right margin, clear of the data
    for colour, text, kind in entries:
        if kind == "dot":
            d.ellipse([lx, ly + 3, lx + 7, ly + 10], fill=colour)
        elif kind == "ring":
            d.ellipse([lx - 1, ly + 1, lx + 9, ly + 11], outline=colour, width=2)
        else:
            d.line([(lx - 3, ly + 7), (lx + 11, ly + 7)], fill=colour, width=2)
        d.text((lx + 18, ly), text, font=f_small, fill=AXIS)
        ly += 16
    if path is not None:
        img.save(path, format="PNG")
    return img
