"""Pinhole camera and primary rays."""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from .fixed_order import norm
from .geometry import PRECISION_DTYPE


@dataclass(frozen=True)
class View:
    """A pinhole camera: eye, target, up vector and vertical field of view in degrees."""

    eye: tuple
    look_at: tuple
    up: tuple = (0.0, 0.0, 1.0)
    fov_deg: float = 35.0

    def basis(self):
        """Unit forward, right and up vectors (right-handed, image rows run down)."""
        eye = np.asarray(self.eye, float)
        forward = np.asarray(self.look_at, float) - eye
        if not norm(forward) > 0:
            raise ValueError("camera: eye and look_at coincide")
        forward /= norm(forward)
        right = np.cross(forward, np.asarray(self.up, float))
        if not norm(right) > 1e-12:
            raise ValueError("camera: up is parallel to the viewing direction")
        right /= norm(right)
        up = np.cross(right, forward)
        return forward, right, up

    def pixel_angle(self, height: int) -> float:
        """Size of one pixel at unit distance along the view direction."""
        return 2.0 * math.tan(math.radians(self.fov_deg) / 2.0) / height


def view_of(scene) -> View:
    """The scene's camera, or one framing the scene's control points from the front-right."""
    if scene.camera is not None:
        c = scene.camera
        return View(tuple(map(float, c.eye)), tuple(map(float, c.look_at)), tuple(map(float, c.up)),
                    float(c.fov_deg))
    return framing_view(*scene.bounds())


def framing_view(lo, hi, fov_deg: float = 35.0, direction=(0.55, -0.8, 0.45), up=(0.0, 0.0, 1.0)) -> View:
    """A view of the box [lo, hi] that fits its bounding sphere in the field of view."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * norm(hi - lo)
    radius = radius if radius > 0 else 1e-9  # a point; a floor for small scenes would lose them (limits.py)
    distance = radius / math.sin(math.radians(fov_deg) / 2.0)
    d = np.asarray(direction, float)
    eye = centre + d / norm(d) * distance
    return View(tuple(eye), tuple(centre), tuple(up), fov_deg)


def primary_rays(view: View, width: int, height: int, precision: str = "f32", rect=None, threads: int = 1):
    """Origins and directions (height, width, 3) through pixel centres, row 0 at the top.

    Computed in float64, rounded to the working precision and widened again, so the
    arrays hold exactly the rays the kernel traces. Directions are not unit length.
    rect: (y0, y1, x0, x1) for only those pixels' rays, (y1 - y0, x1 - x0, 3), bit for bit
    the whole image's (one pixel's trace need not hold a whole image of rays).
    threads: bands of rows made at once (numpy lets go of the interpreter while it fills them),
    for an image large enough to repay a thread.
    """
    y0, y1, x0, x1 = rect if rect is not None else (0, height, 0, width)
    origins = np.empty((y1 - y0, x1 - x0, 3))
    dirs = np.empty_like(origins)
    bands = max(1, min(threads, origins.size // _BAND_VALUES))
    cuts = [y0 + (y1 - y0) * k // bands for k in range(bands + 1)]
    jobs = [(a, b) for a, b in zip(cuts, cuts[1:]) if b > a]

    failed = []  # a helper's exception, raised on the calling thread

    def band(a, b):
        try:
            _rays_into(view, width, height, PRECISION_DTYPE[precision], (a, b, x0, x1),
                       origins[a - y0:b - y0], dirs[a - y0:b - y0])
        except BaseException as exc:
            failed.append(exc)

    helpers = [threading.Thread(target=band, args=job) for job in jobs[1:]]
    for t in helpers:
        t.start()
    try:
        if jobs:
            band(*jobs[0])
    finally:
        for t in helpers:
            t.join()
    if failed:
        raise failed[0]
    return origins, dirs


_BAND_VALUES = 3 * 128 * 128  # an image smaller than two such bands is made on the calling thread


def _rays_into(view: View, width: int, height: int, dtype, rect, origins, dirs) -> None:
    """primary_rays' rays of the pixels in rect, written into origins and dirs (float64 views)."""
    forward, right, up = view.basis()
    half = math.tan(math.radians(view.fov_deg) / 2.0)
    y0, y1, x0, x1 = rect
    xs = ((np.arange(x0, x1) + 0.5) * 2.0 / width - 1.0) * half * width / height
    ys = (1.0 - (np.arange(y0, y1) + 0.5) * 2.0 / height) * half
    # forward + x right + y up, added in that order, the last sum rounded straight into the working
    # precision, then widened into place
    across = forward + xs[:, None] * right
    rounded = np.empty(dirs.shape, dtype)
    np.add(across[None, :, :], ys[:, None, None] * up, out=rounded, casting="same_kind")
    dirs[...] = rounded
    origins[...] = np.asarray(view.eye, float).astype(dtype)
