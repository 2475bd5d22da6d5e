"""Points on the lights for shadow rays: stratified, and seeded by pixel, so every render is
reproducible bit for bit whatever the threads, tiles, pixel order or penumbra method.

Random numbers come from a counter-based hash (splitmix64) of (pixel, ray-tree vertex, light,
sample, dimension), not from a stream, so a pixel's samples never depend on what was traced
before it. `count` samples of a 2D light fill a grid of ceil(sqrt(count)) columns row by row,
one jittered point per cell; a segment's fill `count` intervals.
"""
from __future__ import annotations

import math

import numpy as np

_M1, _M2, _GOLDEN = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB), np.uint64(0x9E3779B97F4A7C15)


def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser, elementwise on uint64."""
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


def seeds(pixel_ids, vertex, light: int) -> np.ndarray:
    """(k,) uint64 seeds of k pixels' shading points at their ray-tree vertices (path codes, (k,)
    or one for all) for light `light`."""
    with np.errstate(over="ignore"):
        key = np.asarray(pixel_ids, np.uint64) * _GOLDEN
        key = _mix(key + np.asarray(vertex, np.uint64) * _M2) + np.uint64(light + 1)
        return _mix(key)


def uniforms(seed: np.ndarray, count: int, dims: int) -> np.ndarray:
    """(k, count, dims) float64 in [0, 1) from seeds (k,): 53 bits of a hash per number."""
    j = np.arange(count * dims, dtype=np.uint64)
    with np.errstate(over="ignore"):
        bits = _mix(seed[:, None] + (j[None, :] + np.uint64(1)) * _GOLDEN)
    return ((bits >> np.uint64(11)).astype(np.float64) * 2.0 ** -53).reshape(len(seed), count, dims)


def stratified(seed: np.ndarray, count: int, dims: int) -> np.ndarray:
    """(k, count, dims) jittered stratified points in [0, 1)^dims (dims 1 or 2)."""
    u = uniforms(seed, count, dims)
    j = np.arange(count)
    if dims == 1:
        return (j[None, :, None] + u) / count
    cols = math.ceil(math.sqrt(count))
    rows = math.ceil(count / cols)
    cell = np.stack([j % cols, j // cols], axis=1).astype(np.float64)
    return (cell[None] + u) / np.array([cols, rows], np.float64)


def sample_count(light, light_samples: int) -> int:
    """Samples of `light` per shading point: 1 for a point light, else the option, else the light's own."""
    if light.type == "point":
        return 1
    return light_samples if light_samples > 0 else light.samples


def points(light, shading: np.ndarray, seed: np.ndarray, count: int) -> np.ndarray:
    """(k, count, 3) points on `light` (scene.Light) for k shading points (k, 3) with seeds (k,)."""
    k = len(shading)
    if light.type == "point":
        return np.broadcast_to(light.position, (k, count, 3)).copy()
    if light.type == "segment":
        s = stratified(seed, count, 1)
        return light.a + s * (light.b - light.a)
    st = stratified(seed, count, 2)
    if light.type == "rect":
        return light.corner + st[..., :1] * light.edge1 + st[..., 1:] * light.edge2
    # sphere: a disc through the centre facing the shading point (the ball's points it sees)
    w = light.center - shading
    w /= np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300)
    e1, e2 = _basis(w)
    r = light.radius * np.sqrt(st[..., 0])
    phi = 2.0 * math.pi * st[..., 1]
    return light.center + (r * np.cos(phi))[..., None] * e1[:, None] + (r * np.sin(phi))[..., None] * e2[:, None]


def _basis(w: np.ndarray):
    """Two unit vectors (k, 3) orthogonal to the unit vectors w and to each other."""
    helper = np.where(np.abs(w[:, :1]) < 0.6, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(w, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(w, e1)


def half_extent(light) -> np.ndarray:
    """(3,) half sizes of the box of light - centre (symmetric: every light shape is centrally
    symmetric), the expansion of penumbra.py's boxes (Lukaszewski Example 4.1: a segment grows
    them only along its own axes)."""
    if light.type == "point":
        return np.zeros(3)
    if light.type == "sphere":
        return np.full(3, float(light.radius))
    if light.type == "segment":
        return np.abs(light.b - light.a) / 2
    return (np.abs(light.edge1) + np.abs(light.edge2)) / 2
