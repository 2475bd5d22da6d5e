"""Regenerate the free-form sample models: exact NURBS sphere and torus, a trimmed plate.

    .venv/bin/python sample_models/make_samples.py

Writes sphere.obj/.json, torus.obj/.json, plate.obj/.json next to this file.
The sphere and torus are rational quadratic in both directions (the standard
9-point circle turned about z); the plate is a bicubic B-spline with a
rounded-rectangle `trim` loop and two circular `hole`s. `plate_region` is the
analytic description of the plate's kept region, for tests.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from tracer.formats.obj import dumps_obj  # noqa: E402
from tracer.nurbs import NurbsCurve, NurbsSurface  # noqa: E402
from tracer.revolution import circle_arc, revolve  # noqa: E402

SPHERE_RADIUS = 1.0
TORUS_R, TORUS_r = 1.0, 0.35
# plate trim, in the plate's (u, v) parameters on [0, 1]^2
PLATE_OUTER = (0.05, 0.95, 0.05, 0.95, 0.12)        # u0 u1 v0 v1 corner radius
PLATE_HOLES = ((0.32, 0.36, 0.13), (0.66, 0.62, 0.17))  # centre u, v, radius


def unit_knots(s: NurbsSurface) -> NurbsSurface:
    """The same surface with both knot vectors scaled to [0, 1] (nicer numbers in the file)."""
    def scale(k):
        return (k - k[0]) / (k[-1] - k[0])
    return NurbsSurface(s.degree_u, s.degree_v, scale(s.knots_u), scale(s.knots_v), s.points)


def sphere() -> NurbsSurface:
    """Radius SPHERE_RADIUS about the origin: a half circle from the south pole, turned about z."""
    half, _ = circle_arc((0, 0, 0), SPHERE_RADIUS, -math.pi / 2, math.pi / 2,
                         (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    surf, _ = revolve(half, (0, 0, 0), (0, 0, 1), 0.0, 2 * math.pi)
    return unit_knots(surf)


def torus() -> NurbsSurface:
    """Tube radius TORUS_r around the circle of radius TORUS_R in the plane z = 0."""
    tube, _ = circle_arc((TORUS_R, 0, 0), TORUS_r, -math.pi, math.pi,
                         (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    surf, _ = revolve(tube, (0, 0, 0), (0, 0, 1), 0.0, 2 * math.pi)
    return unit_knots(surf)


def plate() -> NurbsSurface:
    """A gently curved bicubic plate over [-1.5, 1.5]^2, 5 x 5 control points."""
    n = 5
    x = np.linspace(-1.5, 1.5, n)
    grid = np.zeros((n, n, 4))
    for j in range(n):
        for i in range(n):
            grid[j, i] = (x[i], x[j], 0.25 * math.cos(1.1 * x[i]) * math.cos(0.9 * x[j]), 1.0)
    knots = np.array([0, 0, 0, 0, 0.5, 1, 1, 1, 1], dtype=np.float64)
    return NurbsSurface(3, 3, knots, knots, grid)


def _line(a, b) -> NurbsCurve:
    return NurbsCurve(1, [0.0, 0.0, 1.0, 1.0], [[a[0], a[1], 1.0], [b[0], b[1], 1.0]])


def _arc2d(cu, cv, r, a0, a1) -> NurbsCurve:
    c, _ = circle_arc((cu, cv), r, a0, a1)
    k = c.knots
    return NurbsCurve(2, (k - k[0]) / (k[-1] - k[0]), c.points)


def plate_loops():
    """[(kind, [(NurbsCurve, t0, t1), ...])]: the rounded outer trim, then the two holes."""
    u0, u1, v0, v1, r = PLATE_OUTER
    h = math.pi / 2
    arcs = [_arc2d(u1 - r, v0 + r, r, -h, 0), _arc2d(u1 - r, v1 - r, r, 0, h),
            _arc2d(u0 + r, v1 - r, r, h, 2 * h), _arc2d(u0 + r, v0 + r, r, 2 * h, 3 * h)]
    pieces = []
    for k, arc in enumerate(arcs):  # straight sides join the arcs' exact end points
        pieces += [_line(arcs[k - 1].points[-1], arc.points[0]), arc]
    loops = [("trim", [(c, 0.0, 1.0) for c in pieces])]
    for cu, cv, rad in PLATE_HOLES:
        loops.append(("hole", [(_arc2d(cu, cv, rad, 0.0, 2 * math.pi), 0.0, 1.0)]))
    return loops


def plate_region(u, v):
    """Analytic kept region of the plate (vectorised): inside the rounded rectangle, outside holes."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    u0, u1, v0, v1, r = PLATE_OUTER
    # rounded rectangle = points within r of the inner rectangle
    du = np.maximum(np.maximum(u0 + r - u, u - (u1 - r)), 0)
    dv = np.maximum(np.maximum(v0 + r - v, v - (v1 - r)), 0)
    keep = (du * du + dv * dv <= r * r) & (u >= u0) & (u <= u1) & (v >= v0) & (v <= v1)
    for cu, cv, rad in PLATE_HOLES:
        keep &= (u - cu) ** 2 + (v - cv) ** 2 > rad * rad
    return keep


def plate_distance(u, v):
    """Distance (in parameters) from (u, v) to the nearest trimming curve of the plate."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    u0, u1, v0, v1, r = PLATE_OUTER
    qu = np.abs(u - (u0 + u1) / 2) - ((u1 - u0) / 2 - r)
    qv = np.abs(v - (v0 + v1) / 2) - ((v1 - v0) / 2 - r)
    outer = np.hypot(np.maximum(qu, 0), np.maximum(qv, 0)) + np.minimum(np.maximum(qu, qv), 0) - r
    d = np.abs(outer)
    for cu, cv, rad in PLATE_HOLES:
        d = np.minimum(d, np.abs(np.hypot(u - cu, v - cv) - rad))
    return d


def floor(z: float, half: float = 6.0) -> dict:
    return {"name": "floor", "material": "floor",
            "patches": [{"degree": [1, 1], "points": [[-half, -half, z], [half, -half, z],
                                                      [-half, half, z], [half, half, z]]}]}


def scene(obj_file, name, material, colour, eye, look_at, floor_z) -> dict:
    return {
        "camera": {"eye": eye, "look_at": look_at, "up": [0, 0, 1], "fov_deg": 35},
        "image": {"width": 512, "height": 512},
        "objects": [{"name": name, "file": obj_file, "material": material}, floor(floor_z)],
        "materials": {material: {"color": colour, "specular": 0.4, "shininess": 60},
                      "floor": {"color": [0.5, 0.5, 0.5]}},
        "lights": [{"type": "point", "position": [4, -5, 8], "intensity": 1.0}],
    }


def main():
    models = {
        "sphere": ([("sphere", sphere(), [])],
                   "exact NURBS sphere, radius 1 about the origin: rational quadratic 5 x 9 net",
                   scene("sphere.obj", "sphere", "blue", [0.3, 0.45, 0.85],
                         [3.5, -5.0, 2.5], [0, 0, 0], -SPHERE_RADIUS)),
        "torus": ([("torus", torus(), [])],
                  "exact NURBS torus, R = 1, r = 0.35 about the z axis: rational quadratic 9 x 9",
                  scene("torus.obj", "torus", "gold", [0.85, 0.65, 0.25],
                        [2.8, -4.0, 3.2], [0, 0, 0], -TORUS_r)),
        "plate": ([("plate", plate(), plate_loops())],
                  "bicubic plate with a rounded-rectangle trim and two circular holes",
                  scene("plate.obj", "plate", "green", [0.35, 0.7, 0.4],
                        [1.2, -3.6, 3.4], [0, 0, 0], -0.6)),
    }
    for name, (surfaces, comment, sc) in models.items():
        text = dumps_obj(surfaces, comment + "\nwritten by sample_models/make_samples.py")
        (HERE / f"{name}.obj").write_text(text)
        (HERE / f"{name}.json").write_text(json.dumps(sc, indent=2) + "\n")
        print(f"wrote {name}.obj ({len(text.splitlines())} lines) and {name}.json")


if __name__ == "__main__":
    main()
