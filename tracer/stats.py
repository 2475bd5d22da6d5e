"""Per-pixel channels (one registry for the CLI's maps and the viewer's overlays) and
the statistics of a render, alone and against its float64 reference.

A channel turns a Frame (and, for error channels, the reference Frame of the
same rays) into one float64 value per pixel, NaN where it is undefined, and
says how to show it: units, linear or log scale, colour map, and special
pixel classes drawn in fixed colours (documented in the legend).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import colormap
from .colormap import BACKGROUND, colorize, legend_image, with_legend
from .kernel_channels import COUNTERS
from .shade import patch_colours

HOLE_RGB = (1.0, 0.0, 0.0)
FALSE_HIT_RGB = (1.0, 0.0, 1.0)
UNRESOLVED_RGB = (1.0, 0.6, 0.0)
ULP_SLACK = 4


@dataclass(frozen=True)
class Channel:
    """One per-pixel quantity and how to display it."""

    name: str
    label: str
    units: str
    scale: str  # 'linear' | 'log' | 'categorical'
    cmap: str
    help: str
    values: Callable  # (frame, ref) -> (H, W) float64, NaN where undefined
    needs_reference: bool = False
    specials: Callable | None = None  # (frame, ref) -> [(mask (H, W) bool, rgb, legend text)]


CHANNELS: dict[str, Channel] = {}


def register(ch: Channel) -> Channel:
    CHANNELS[ch.name] = ch
    return ch


def channel(name: str) -> Channel:
    if name not in CHANNELS:
        raise ValueError(f"unknown channel {name!r} (known: {', '.join(CHANNELS)})")
    return CHANNELS[name]


# ---- per-pixel quantities -------------------------------------------------------

def distance(frame) -> np.ndarray:
    """Distance from the eye to the hit along the ray, NaN on a miss."""
    d = frame.t * np.linalg.norm(frame.ray_dir, axis=-1)
    return np.where(frame.hit, d, np.nan)


def resolved(ref) -> np.ndarray:
    """Where the reference's answer is known to be the closest (its box budget did not run out)."""
    return ~ref.unresolved if ref.unresolved is not None else np.ones(ref.hit.shape, bool)


def position_error(frame, ref) -> np.ndarray:
    """L1 distance |frame.position - ref.position| where both hit and the reference is resolved,
    NaN elsewhere."""
    both = frame.hit & ref.hit & resolved(ref)
    err = np.full(frame.hit.shape, np.nan)
    err[both] = np.sum(np.abs(frame.position[both] - ref.position[both]), axis=-1)
    return err


def _counter_values(name):
    def values(frame, ref=None):
        counts = getattr(frame, name)
        if counts is None:
            raise ValueError(f"channel {name!r}: this frame did not compute it")
        e = counts.astype(np.float64)
        return np.where(e > 0, e, np.nan)  # 0: the ray met nothing of this kind
    return values


def _counter_specials(name, nothing):
    def specials(frame, ref=None):
        return [(getattr(frame, name) <= 0, BACKGROUND, nothing)]
    return specials


def _error_specials(frame, ref):
    ok = resolved(ref)
    return [(ref.hit & ~frame.hit & ok, HOLE_RGB, "hole: reference hit, this render missed"),
            (frame.hit & ~ref.hit & ok, FALSE_HIT_RGB, "false hit: this render hit, reference missed"),
            (~ok, UNRESOLVED_RGB, "unresolved: the reference ran out of its box budget"),
            (~frame.hit & ~ref.hit & ok, BACKGROUND, "both missed")]


def _box_size(frame, ref=None):
    return np.where(frame.hit, np.sum(frame.box_max - frame.box_min, axis=-1), np.nan)


_NOTHING = {"effort": "no patch box tested", "nodes": "the ray missed the scene's bounds",
            "patches_tested": "no patch searched"}
for _kc in COUNTERS:  # the kernel's counters (kernel_channels), each a map of its own
    register(Channel(_kc.name, _kc.label, _kc.units, "log", "inferno", _kc.help, _counter_values(_kc.name),
                     specials=_counter_specials(_kc.name, _NOTHING.get(_kc.name, "zero"))))
register(Channel("error", "position error", "world units, L1", "log", "viridis",
                 "L1 distance of the hit point from the float64 reference hit of the same ray",
                 position_error, needs_reference=True, specials=_error_specials))
register(Channel("depth", "distance", "world units", "linear", "viridis",
                 "distance from the eye to the hit along the ray", lambda f, r=None: distance(f)))
register(Channel("box_size", "final box size", "world units, L1", "log", "viridis",
                 "L1 diameter of the final hit box", _box_size))


def _lighting_values(name, transform):
    def values(frame, ref=None):
        v = getattr(frame, name)
        if v is None:
            raise ValueError(f"channel {name!r}: this frame was traced without "
                             + ("shadows" if name != "shadow_rays" else "lighting"))
        return np.where(frame.hit, transform(v.astype(np.float64)), np.nan)
    return values


def _no_rays(frame, ref=None):
    return [(frame.hit & (frame.shadow_rays <= 0), BACKGROUND, "no shadow ray traced")]


def _penumbra_specials(frame, ref=None):
    return [(frame.hit & (frame.penumbra < 0), BACKGROUND, "not classified (penumbra off, or no area light)")]


register(Channel("shadow", "shadow", "fraction of light", "linear", "inferno",
                 "fraction of the lights' intensity reaching the hit point unoccluded (1 fully lit)",
                 _lighting_values("shadow", lambda v: v)))
register(Channel("shadow_rays", "shadow rays", "rays", "log", "inferno",
                 "shadow rays traced for the pixel (all lights, samples and ray-tree vertices)",
                 _lighting_values("shadow_rays", lambda v: np.where(v > 0, v, np.nan)), specials=_no_rays))
register(Channel("penumbra", "penumbra class", "0 lit, 1 penumbra, 2 umbra", "linear", "viridis",
                 "fast penumbra classification: 0 proven lit without samples, 1 sampled",
                 _lighting_values("penumbra", lambda v: np.where(v >= 0, v, np.nan)), specials=_penumbra_specials))
register(Channel("patch", "patch id", "index", "categorical", "",
                 "global index of the hit patch (hashed colours)",
                 lambda f, r=None: np.where(f.hit, f.patch.astype(np.float64), np.nan)))


def channel_rgb(name: str, frame, ref=None, rect=None, vrange=None):
    """Colours of a channel, (h, w, 3) float32 for the image or a tile rect (y0, y1, x0, x1),
    and the (lo, hi) value range used (from the whole frame unless vrange is given)."""
    ch = channel(name)
    if ch.needs_reference and ref is None:
        raise ValueError(f"channel {name!r} needs the float64 reference frame")
    values = ch.values(frame, ref)
    h, w = values.shape
    y0, y1, x0, x1 = rect if rect is not None else (0, h, 0, w)
    sl = (slice(y0, y1), slice(x0, x1))
    if ch.scale == "categorical":
        v = values[sl]
        rgb = np.empty(v.shape + (3,), np.float32)
        rgb[:] = BACKGROUND
        ok = np.isfinite(v)
        rgb[ok] = patch_colours(v[ok].astype(np.int64))
        lo, hi = colormap.auto_range(values)
    else:
        lo, hi = vrange if vrange is not None else colormap.auto_range(values, ch.scale)
        rgb = colorize(values[sl], lo, hi, ch.scale, ch.cmap)
    for mask, colour, _ in (ch.specials(frame, ref) if ch.specials else []):
        rgb[mask[sl]] = colour
    return rgb, (lo, hi)


def channel_image(name: str, frame, ref=None, vrange=None, legend_width: int = 360):
    """The channel's map above a colour-bar legend (min/max, units, special colours): a PIL image
    max(W, legend_width) wide and H + legend height tall, the map in the top-left W x H."""
    ch = channel(name)
    rgb, (lo, hi) = channel_rgb(name, frame, ref, vrange=vrange)
    specials = [(c, text) for _, c, text in (ch.specials(frame, ref) if ch.specials else [])]
    if not specials:
        specials.append((BACKGROUND, "ray missed"))
    legend = legend_image(max(frame.hit.shape[1], legend_width), lo, hi, label=ch.label, units=ch.units,
                          scale="linear" if ch.scale == "categorical" else ch.scale,
                          cmap=ch.cmap or "grey", specials=specials, bar=ch.scale != "categorical")
    return with_legend(rgb, legend)


# ---- statistics -------------------------------------------------------------------

def _summary(values) -> dict | None:
    v = np.asarray(values, np.float64)
    if v.size == 0:
        return None
    return {"min": float(v.min()), "mean": float(v.mean()), "max": float(v.max())}


def coherence_stats(frame) -> dict:
    """Lischinski and Gonczarowski's counters of a render (1990, section 5), per ray over all rays:
    surfaces (patches) whose box was tested, surfaces searched, ray-box tests; and with the
    surface-tree cache (None without): the cache hit ratio, searches of the rays that started from
    a cached tree over all their searches, and the cache misses per surface, the trees the frame
    made over the surfaces it searched (render._frame_cache; per render thread: 1 when each
    searched surface's tree was made once, more when a bounded cache released and remade trees,
    less when trees were kept from an earlier frame); `cache`: the frame's cache figures."""
    rays = max(frame.hit.size, 1)
    out = {"surfaces_tested_per_ray": float(frame.surfaces_tested.sum()) / rays,
           "surfaces_searched_per_ray": float(frame.patches_tested.sum()) / rays,
           "box_tests_per_ray": float(frame.box_tests.sum()) / rays,
           "cache_hit_ratio": None, "cache_misses_per_surface": None, "cache": frame.extras.get("cache")}
    if out["cache"] is not None:
        hits, misses = int(frame.cache_hits.sum()), int(frame.cache_misses.sum())
        out["cache_hit_ratio"] = hits / (hits + misses) if hits + misses else None
        c = out["cache"]
        out["cache_misses_per_surface"] = c["misses"] / c["surfaces"] if c["surfaces"] else None
    return out


def frame_stats(frame) -> dict:
    """Rays, hits, trace time, and each kernel counter's min/mean/max over all rays and over hits
    (effort, effort_hits, nodes, nodes_hits, ...); the kernel variant, the acceleration
    structure's build figures (accel.aggregate_for), and the coherence counters (coherence_stats)."""
    out = {"rays": int(frame.hit.size), "hits": int(frame.hit.sum()), "time": float(frame.seconds)}
    for kc in COUNTERS:
        counts = getattr(frame, kc.name)
        if counts is not None:
            out[kc.name] = _summary(counts)
            out[f"{kc.name}_hits"] = _summary(counts[frame.hit])
    for key in ("variant", "accel"):
        if key in frame.extras:
            out[key] = frame.extras[key]
    if all(getattr(frame, name) is not None for name in ("surfaces_tested", "patches_tested", "box_tests")):
        out["coherence"] = coherence_stats(frame)
    if "lighting" in frame.extras:
        out["lighting"] = lighting_stats(frame)
    return out


def lighting_stats(frame) -> dict:
    """Shadow rays per hit pixel, the shares of hit pixels the fast penumbra proved lit and in umbra, time per
    phase (lighting.py, summed over threads) and the expanded data sets' builds."""
    hit = frame.hit
    n = max(int(hit.sum()), 1)
    out = dict(frame.extras["lighting"])
    out["shadow_rays_per_hit"] = float(frame.shadow_rays[hit].sum()) / n if frame.shadow_rays is not None else 0.0
    if frame.penumbra is not None:
        klass = frame.penumbra[hit]
        out["proven_lit_share"] = float((klass == 0).sum()) / n
        out["sampled_share"] = float((klass == 1).sum()) / n
        out["proven_umbra_share"] = float((klass == 2).sum()) / n
    if frame.shadow is not None:
        out["shadow"] = _summary(frame.shadow[hit])
    return out


def ulp32(x) -> np.ndarray:
    """Spacing of float32 numbers at the magnitude of x, as float64."""
    return np.spacing(np.abs(np.asarray(x)).astype(np.float32)).astype(np.float64)


def error_stats(frame, ref) -> dict:
    """Position accuracy of `frame` against `ref`, the float64 render of the same rays.

    holes: ref hit, frame missed; false_hits: frame hit, ref missed; unresolved: pixels where the
    reference's box budget ran out, left out of everything else. Over pixels both hit:
    the L1 position error's max/min/mean/variance (Dammertz table 2.1), the float32 floor
    (mean L1 error of merely rounding ref.position to float32), ratio = mean / floor, and
    inside_box: the fraction of those hits whose ref.position lies in the final box;
    inside_4ulp: the same with the box widened by 4 float32 ulps per coordinate.
    """
    if frame.hit.shape != ref.hit.shape:
        raise ValueError(f"frame is {frame.hit.shape}, reference {ref.hit.shape}: not the same rays")
    ok = resolved(ref)
    both = frame.hit & ref.hit & ok
    out = {"compared": int(both.sum()), "holes": int(np.sum(ref.hit & ~frame.hit & ok)),
           "false_hits": int(np.sum(frame.hit & ~ref.hit & ok)), "unresolved": int(np.sum(~ok))}
    if not both.any():
        return {**out, "max": None, "min": None, "mean": None, "variance": None, "floor": None,
                "ratio": None, "inside_box": None, "inside_4ulp": None}
    p, r = frame.position[both], ref.position[both]
    err = np.sum(np.abs(p - r), axis=-1)
    floor = float(np.mean(np.sum(np.abs(r.astype(np.float32).astype(np.float64) - r), axis=-1)))
    lo, hi = frame.box_min[both], frame.box_max[both]
    in_box = np.all((r >= lo) & (r <= hi), axis=-1)
    inside = np.all((r >= lo - ULP_SLACK * ulp32(lo)) & (r <= hi + ULP_SLACK * ulp32(hi)), axis=-1)
    mean = float(err.mean())
    return {**out, "max": float(err.max()), "min": float(err.min()), "mean": mean,
            "variance": float(err.var()), "floor": floor,
            "ratio": mean / floor if floor > 0 else (1.0 if mean == 0 else math.inf),
            "inside_box": float(in_box.mean()), "inside_4ulp": float(inside.mean())}


def json_safe(value):
    """Replace non-finite floats with None (recursively) so json.dump writes strict JSON."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value
