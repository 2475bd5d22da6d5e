"""Where a secondary ray starts: robust origins from a hit box (options.origin).

A hit is a box that contains the true intersection, not a point. A ray leaving the surface
from a point inside that box can meet the same surface again at once (acne, false shadows);
an origin pushed far away passes thin obstacles (light leaks). Three ways, as switches so the
debugger can show the difference:

  box_corner     Dammertz 2.4: the corner of the hit box on the side the new ray leaves (by the
                 octant of the normal on that side), then moved outwards by origin_ulps units in
                 the last place of the working precision, an integer number of steps on the grid
                 the tracer's own boxes are rounded onto (the patch's local frame: geometry.grid).
                 No scene-size parameter: the step scales with the arithmetic.
  shift          Lempitsky's O+-: the hit point moved along the normal by the threshold of
                 detail at the hit, or by the hit box's diagonal where that is larger (the
                 float, fixed and mantissa criteria have no threshold), so it clears the box.
  fixed_epsilon  the hit point moved along the normal by origin_epsilon world units: the usual
                 scene-scale offset, to show its acne and leaks at other scales.
"""
from __future__ import annotations

import numpy as np


def patch_ulps(geom) -> np.ndarray:
    """(n_scene_patches, 3) float64: each patch's unit in the last place per axis, the largest over
    its leaves: the float32 grid step of its leaves' local coordinates, or in float64 the spacing
    at their magnitude."""
    if geom.precision == "f32":
        unit = np.asarray(geom.grid, np.float64)
    else:
        box = np.asarray(geom.leaf_box)
        reach = np.maximum(np.abs(box[:, :3] - geom.frame), np.abs(box[:, 3:] - geom.frame))
        unit = np.spacing(reach)
    n = int(geom.leaf_patch.max()) + 1
    out = np.zeros((n, 3))
    np.maximum.at(out, geom.leaf_patch, unit)
    return out


def box_corner(lo, hi, normal) -> np.ndarray:
    """(k, 3) the corners of boxes (lo, hi) on the side of `normal` (by its octant): where
    box_corner origins start before they are moved outwards."""
    return np.where(np.asarray(normal) >= 0.0, hi, lo)


def robust_origins(method: str, *, lo, hi, position, normal, ulp=None, ulps: int = 7, threshold=None,
                   epsilon: float = 1e-4) -> np.ndarray:
    """(k, 3) float64 origins for rays leaving k hit boxes (lo, hi) on the side of `normal` (unit,
    pointing where the rays go). box_corner needs ulp (k, 3) (patch_ulps of the hit patches) and
    ulps; shift the threshold of detail at the hits (k,) or None."""
    normal = np.asarray(normal, np.float64)
    if method == "box_corner":
        up = normal >= 0.0
        corner = box_corner(lo, hi, normal)
        step = ulps * np.asarray(ulp, np.float64)
        moved = np.where(up, corner + step, corner - step)
        # at least `ulps` float64 steps: a step below the world coordinate's spacing would vanish
        least = ulps * np.spacing(np.abs(corner))
        return np.where(up, np.maximum(moved, corner + least), np.minimum(moved, corner - least))
    if method == "shift":
        diagonal = np.linalg.norm(np.asarray(hi) - np.asarray(lo), axis=-1)
        size = diagonal if threshold is None else np.maximum(threshold, diagonal)
        return position + size[:, None] * normal
    if method == "fixed_epsilon":
        return position + epsilon * normal
    raise ValueError(f"option origin: unknown method {method!r}")
