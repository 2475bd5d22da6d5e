"""Display modes: a render.Frame's per-pixel channels turned into display-ready RGB.

Every mode returns float32 (h, w, 3) sRGB-encoded values in [0, 1], for the
whole image or one tile rectangle (y0, y1, x0, x1), so the viewer can upload a
tile as it finishes and the CLI can write the same pixels to a PNG unchanged;
or (k, 3) for a list of pixels (a work unit scattered over the image).

- shaded: the frame's radiance (lighting.py: shadows, area lights, reflection and
  refraction) through the sRGB transfer curve; a frame traced without lighting
  gets Lambert + Phong with every light a point at its centre, unshadowed. No
  distance falloff; the sum of light intensities is normalised to at most 1 so
  a second light does not blow out the image. No lights: a headlight at the eye.
- normal: (n + 1) / 2; uv: (u, v, 0); depth: distance along the ray on viridis,
  near = bright; patch: a colour hashed from the patch id.
Misses show a dark grey vertical gradient in every mode.
"""
from __future__ import annotations

import numpy as np
from PIL import Image

from .colormap import colorize, to_uint8
from .fixed_order import dot3, norm

MODES = ("shaded", "normal", "uv", "depth", "patch")
AMBIENT = 0.06
BG_TOP, BG_BOTTOM = 0.22, 0.07


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve applied to linear values in [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """Linear values of sRGB-encoded ones in [0, 1]."""
    x = np.clip(encoded, 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def background(height: int, y0: int, y1: int, width: int) -> np.ndarray:
    """Rows y0..y1 of a full-height dark grey gradient (top lighter), (y1-y0, width, 3) float32."""
    rows = (np.arange(y0, y1) + 0.5) / max(height, 1)
    g = (BG_TOP + (BG_BOTTOM - BG_TOP) * rows).astype(np.float32)
    return np.repeat(np.repeat(g[:, None, None], width, axis=1), 3, axis=2)


def unit(v: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) scaled to length 1 (zero ones left as they are)."""
    n = np.sqrt(dot3(v, v))[..., None]
    return v / np.where(n > 0, n, 1.0)


def _material_tables(scene):
    mats = scene.materials
    colour = np.array([m.color for m in mats], np.float64).reshape(-1, 3)
    spec = np.array([m.specular for m in mats], np.float64)
    shin = np.array([m.shininess for m in mats], np.float64)
    return colour, spec, shin


def _lights(scene):
    """[(position (3,), rgb (3,))]; empty list means headlight."""
    lights = list(scene.lights or [])
    total = sum(float(li.intensity) for li in lights)
    norm = 1.0 / max(total, 1.0)
    return [(np.asarray(li.centre(), np.float64), np.asarray(li.color, np.float64) * li.intensity * norm)
            for li in lights]


def _shaded(scene, pos, n, d, eye, patch) -> np.ndarray:
    """Linear radiance (k, 3) of k hit pixels."""
    colour, spec, shin = _material_tables(scene)
    mat = np.asarray(scene.patch_material, np.int64)[patch]
    kd, ks, ns = colour[mat], spec[mat][:, None], shin[mat][:, None]
    v = unit(-d)
    # patches have no consistent orientation: light the side facing the eye
    facing = np.sum(n * v, axis=1, keepdims=True)
    n = np.where(facing < 0, -n, n)
    out = AMBIENT * kd
    lights = _lights(scene) or [(eye, np.ones(3))]
    for centre, rgb in lights:
        l_dir = unit(centre - pos)
        ndl = np.sum(n * l_dir, axis=1, keepdims=True)
        lit = ndl > 0
        r = 2.0 * ndl * n - l_dir
        rdv = np.clip(np.sum(r * v, axis=1, keepdims=True), 0.0, 1.0)
        out = out + np.where(lit, kd * ndl + ks * rdv ** ns, 0.0) * rgb
    return out


def patch_colours(ids: np.ndarray) -> np.ndarray:
    """Distinct-looking colours (k, 3) from integer ids: hue, saturation and value from a hash."""
    h = (ids.astype(np.uint64) * np.uint64(2654435761) + np.uint64(0x9E3779B9)) & np.uint64(0xFFFFFFFF)
    h ^= h >> np.uint64(15)
    h = (h * np.uint64(0x2C1B3C6D)) & np.uint64(0xFFFFFFFF)
    hue = (h & np.uint64(0xFFFF)).astype(np.float64) / 65536.0
    sat = 0.45 + 0.45 * ((h >> np.uint64(16)) & np.uint64(0xFF)).astype(np.float64) / 255.0
    val = 0.60 + 0.40 * ((h >> np.uint64(24)) & np.uint64(0xFF)).astype(np.float64) / 255.0
    k = np.stack([(5 + hue * 6) % 6, (3 + hue * 6) % 6, (1 + hue * 6) % 6], axis=1)
    return val[:, None] - val[:, None] * sat[:, None] * np.clip(np.minimum(k, 4 - k), 0.0, 1.0)


def depth_limits(frame, scene=None, rect=None):
    """(near, far) distances for the depth mode.

    Whole image (rect None) or no scene: the range of the hits' distances. A tile:
    eye-to-scene-box distances, the same for every tile so tiles agree.
    """
    if rect is not None and scene is not None:
        eye = frame.ray_origin[0, 0]
        lo, hi = scene.bounds()
        near = norm(np.maximum(np.maximum(lo - eye, 0.0), eye - hi))
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        far = float(np.max(np.linalg.norm(corners - eye, axis=1)))
        return near, max(far, near * (1 + 1e-9) + 1e-12)
    dist = frame.t[frame.hit] * np.linalg.norm(frame.ray_dir[frame.hit], axis=-1)
    if dist.size == 0:
        return 0.0, 1.0
    return float(dist.min()), float(dist.max())


def shade(frame, scene, mode: str = "shaded", rect=None, *, pixels=None, depth_range=None) -> np.ndarray:
    """Display colours of `frame` in `mode`, (h, w, 3) float32 sRGB in [0, 1].

    rect: (y0, y1, x0, x1) to shade one tile; default the whole image.
    pixels: (k, 2) (row, column) to shade only those, (k, 3), as the tiles holding them have them.
    depth_range: (near, far) distances for mode 'depth' (default: see depth_limits).
    """
    if mode not in MODES:
        raise ValueError(f"unknown display mode {mode!r} (known: {', '.join(MODES)})")
    height, width = frame.hit.shape
    if pixels is not None:
        sl = (pixels[:, 0], pixels[:, 1])
        out = background(height, 0, height, 1)[pixels[:, 0], 0]
        rect = (0, height, 0, width)  # a part of the image: the depth limits every tile has
    else:
        y0, y1, x0, x1 = rect if rect is not None else (0, height, 0, width)
        sl = (slice(y0, y1), slice(x0, x1))
        out = background(height, y0, y1, x1 - x0)
    hit = frame.hit[sl]
    if not hit.any():
        return out
    if mode == "shaded" and frame.radiance is not None:
        out[hit] = srgb_encode(frame.radiance[sl][hit])
    elif mode == "shaded":
        lin = _shaded(scene, frame.position[sl][hit], frame.normal[sl][hit], frame.ray_dir[sl][hit],
                      frame.ray_origin[sl][hit], frame.patch[sl][hit])
        out[hit] = srgb_encode(lin)
    elif mode == "normal":
        out[hit] = np.clip((frame.normal[sl][hit] + 1.0) / 2.0, 0.0, 1.0)
    elif mode == "uv":
        uv = np.clip(frame.uv[sl][hit], 0.0, 1.0)
        out[hit] = np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)
    elif mode == "depth":
        near, far = depth_range or depth_limits(frame, scene, rect)
        dist = frame.t[sl][hit] * np.linalg.norm(frame.ray_dir[sl][hit], axis=-1)
        out[hit] = colorize(-dist, -far, -near, cmap="viridis")  # negated: near is bright
    else:
        out[hit] = patch_colours(frame.patch[sl][hit])
    return out


def to_png(rgb: np.ndarray, path) -> Image.Image:
    """Write display colours (h, w, 3) as an 8-bit RGB PNG; no further gamma is applied."""
    img = Image.fromarray(to_uint8(rgb), "RGB")
    img.save(path, format="PNG")
    return img
