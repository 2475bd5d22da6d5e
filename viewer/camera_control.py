"""Camera manipulation as pure functions of tracer.camera.View (no GL, no UI): testable."""
from __future__ import annotations

import math

import numpy as np

from tracer.camera import View, framing_view

ORBIT_RADIANS_PER_PIXEL = 0.008
ZOOM_PER_NOTCH = 0.85
MIN_PITCH_COS = 0.999  # keep the view direction off the up axis (the basis needs them apart)


def _vec(v) -> np.ndarray:
    return np.asarray(v, float)


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' rotation of v about a unit axis."""
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * float(axis @ v) * (1.0 - c)


def _make(view: View, eye, look_at) -> View:
    return View(tuple(map(float, eye)), tuple(map(float, look_at)), view.up, view.fov_deg)


def orbit(view: View, dx: float, dy: float, speed: float = ORBIT_RADIANS_PER_PIXEL) -> View:
    """Turn the eye around look_at: dx pixels about the up axis, dy pixels about the right axis.

    Dragging right moves the scene right (the eye goes left); the pitch stops short of the poles.
    """
    eye, target = _vec(view.eye), _vec(view.look_at)
    up = _vec(view.up) / np.linalg.norm(view.up)
    offset = _rotate(eye - target, up, -dx * speed)
    _, right, _ = view.basis()
    pitched = _rotate(offset, right, -dy * speed)
    if abs(float(pitched @ up)) / np.linalg.norm(pitched) < MIN_PITCH_COS:
        offset = pitched
    return _make(view, target + offset, target)


def pan(view: View, dx: float, dy: float, height: int) -> View:
    """Slide eye and look_at so the point at look_at follows the cursor by (dx, dy) pixels."""
    _, right, up = view.basis()
    dist = float(np.linalg.norm(_vec(view.look_at) - _vec(view.eye)))
    scale = dist * view.pixel_angle(max(height, 1))
    shift = (-dx * right + dy * up) * scale
    return _make(view, _vec(view.eye) + shift, _vec(view.look_at) + shift)


def zoom(view: View, notches: float) -> View:
    """Move the eye towards look_at (positive notches) or away, geometrically."""
    eye, target = _vec(view.eye), _vec(view.look_at)
    factor = ZOOM_PER_NOTCH ** notches
    return _make(view, target + (eye - target) * factor, target)


def frame_scene(view: View, lo, hi) -> View:
    """Fit the box [lo, hi] in view, looking from the current direction."""
    direction = _vec(view.eye) - _vec(view.look_at)
    fitted = framing_view(lo, hi, fov_deg=view.fov_deg, direction=direction, up=view.up)
    return fitted


def same_view(a: View | None, b: View | None, tol: float = 0.0) -> bool:
    if a is None or b is None:
        return a is b
    pa = np.concatenate([a.eye, a.look_at, a.up, [a.fov_deg]])
    pb = np.concatenate([b.eye, b.look_at, b.up, [b.fov_deg]])
    return bool(np.all(np.abs(pa - pb) <= tol))
