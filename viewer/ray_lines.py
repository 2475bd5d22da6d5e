"""The inspected pixel's secondary rays over the image: line segments in world space, drawn with
the box outlines (display.Display.set_boxes), coloured by what the ray is and what became of it.

Shadow rays run from their origin to the light sample (lit) or to the box that occluded them
(when their trace found it; else to the sample); reflected and refracted rays to their hit, with
the hit box and a cross there, or on past the scene when they miss; penumbra tests to the
light's centre, faint. The chosen row's ray is drawn white, on top.
"""
from __future__ import annotations

import numpy as np

from .picking import box_lines, hit_marker

RAY_RGBA = {"lit": (1.0, 0.85, 0.25, 0.9), "occluded": (0.75, 0.3, 1.0, 0.9), "reflected": (0.3, 0.75, 1.0, 0.95),
            "refracted": (0.25, 1.0, 0.55, 0.95), "penumbra_test": (1.0, 1.0, 1.0, 0.3),
            "umbra_test": (0.35, 0.35, 1.0, 0.5)}
CHOSEN_RGBA = (1.0, 1.0, 1.0, 1.0)
MISS_LENGTH = 0.5  # a missing ray is drawn this many eye distances long (it leaves the scene)


def ray_colour(ray) -> tuple:
    """RAY_RGBA's colour of a tracer.ray_tree.RayRecord."""
    if ray.kind == "shadow":
        return RAY_RGBA["occluded" if ray.hit else "lit"]
    return RAY_RGBA.get(ray.kind, CHOSEN_RGBA)


def ray_end(ray, view) -> np.ndarray:
    """Where the drawn segment of a ray ends (world coordinates)."""
    if ray.kind in ("shadow", "penumbra_test", "umbra_test"):
        return ray.position if ray.hit and ray.position is not None else ray.target
    if ray.hit:
        return ray.position
    d = ray.direction / max(float(np.linalg.norm(ray.direction)), 1e-300)
    reach = MISS_LENGTH * float(np.linalg.norm(np.asarray(view.look_at, float) - np.asarray(view.eye, float)))
    return ray.origin + reach * d


def ray_tree_vertices(tree, view, chosen: int = -1) -> np.ndarray:
    """Line vertices (rows x y z r g b a, two a segment) of the tree's rays but the primary (the
    box outlines show it), their hit boxes and crosses at their hits; the chosen row last."""
    parts = []
    order = [i for i in range(1, len(tree.rays)) if i != chosen] + ([chosen] if chosen > 0 else [])
    for i in order:
        ray = tree.rays[i]
        rgba = CHOSEN_RGBA if i == chosen else ray_colour(ray)
        seg = np.array([ray.origin, ray_end(ray, view)], np.float64)
        parts.append(np.concatenate([seg, np.tile(rgba, (2, 1))], axis=1))
        if ray.hit and ray.box_min is not None:
            edges = box_lines(np.asarray([ray.box_min]), np.asarray([ray.box_max])).reshape(-1, 3)
            parts.append(np.concatenate([edges, np.tile(rgba, (len(edges), 1))], axis=1))
            parts.append(hit_marker(ray.position, view, 0.008, rgba))
    if not parts:
        return np.zeros((0, 7), np.float32)
    return np.concatenate(parts).astype(np.float32)
