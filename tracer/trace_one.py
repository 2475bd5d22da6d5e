"""One pixel's subdivision trace: every box the search computed, with what became of it.

The same kernel as the renderer runs with trace arrays attached (numba
compiles that variant separately, so the renderer pays nothing for it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .camera import View, primary_rays, view_of
from .fixed_order import dot
from .geometry import Geometry, prepare
from .options import Options
from .ray import H_HI, H_LO, H_PATCH, H_TIN, H_TOUT, H_U, H_V, HIT_LEN, RAY_LEN, make_ray, set_side
from .records import C_EFFORT, COUNTER_LEN, new_trace
from .render import kernel_inputs
from .tile_kernel import tile_scratch
from .search_steps import EVENT_NAMES
from .hit_normal import hit_normal
from .variants import compiled, variant_for

TRACE_CAPACITY = 1 << 20


@dataclass
class PixelTrace:
    """A traced pixel: the hit (if any) and the steps of the subdivision search."""

    pixel: tuple
    hit: bool
    patch: int
    t: float
    position: np.ndarray
    box_min: np.ndarray
    box_max: np.ndarray
    normal: np.ndarray
    uv: np.ndarray
    effort: int
    steps_f: np.ndarray  # (k, 11): u0 u1 v0 v1, box lo xyz, box hi xyz, L1 diameter
    steps_i: np.ndarray  # (k, 3): patch, depth, event code
    truncated: bool = False
    reported_step: int = -1  # the step whose box is the reported hit box

    @property
    def diameters(self) -> np.ndarray:
        return self.steps_f[:, 10]

    @property
    def events(self) -> list:
        return [EVENT_NAMES[e] for e in self.steps_i[:, 2]]

    def hit_step(self) -> int:
        """Index of the step that produced the reported hit box, or -1. Steps are listed in the
        order their boxes were computed; a hit found later in a box computed earlier (the far
        half of an ancestor, closer along the ray) replaces earlier hits, so this need not be
        the last 'hit' step."""
        return self.reported_step if self.hit else -1

    def to_json(self) -> dict:
        """The contract's trace object (scene-format.md), with a summary added."""
        def vec(a):
            return [float(x) for x in a]

        steps = [{"patch": int(i[0]), "depth": int(i[1]), "u": vec(f[0:2]), "v": vec(f[2:4]),
                  "box_min": vec(f[4:7]), "box_max": vec(f[7:10]), "diameter": float(f[10]),
                  "event": EVENT_NAMES[i[2]]} for f, i in zip(self.steps_f, self.steps_i)]
        counts = {name: int(np.sum(self.steps_i[:, 2] == k)) for k, name in enumerate(EVENT_NAMES)}
        out = {"pixel": [int(self.pixel[0]), int(self.pixel[1])], "hit": bool(self.hit),
               "patch": int(self.patch), "t": float(self.t) if self.hit else None,
               "position": vec(self.position) if self.hit else None,
               "box_min": vec(self.box_min) if self.hit else None,
               "box_max": vec(self.box_max) if self.hit else None,
               "normal": vec(self.normal) if self.hit else None,
               "uv": vec(self.uv) if self.hit else None,
               "effort": int(self.effort), "hit_step": self.hit_step(),
               "summary": {"boxes": len(steps), "events": counts,
                           "max_depth": int(self.steps_i[:, 1].max()) if len(steps) else 0,
                           "truncated": bool(self.truncated)},
               "steps": steps}
        return out


def trace_ray_steps(geom: Geometry, opts: Options, origin, direction, pixel_angle: float,
                    pixel=(0, 0), capacity: int = TRACE_CAPACITY, *, t_min: float = 0.0, t_max: float = math.inf,
                    t0: float = 0.0, dt: float | None = None, driver: str = "closest", side=None) -> PixelTrace:
    """Trace one ray with step recording; same kernel and options as the renderer.

    A primary ray by default; a secondary ray (ray_batch's batch rays) gives its interval
    (t_min, t_max), its threshold of detail T0 + dT * t (dt None: the pixel angle's slope times
    the direction's length), its driver ('any' for shadow rays: the first hit box ends it) and the
    side it leaves its surface on (ray.set_side; None: none)."""
    inputs = kernel_inputs(geom, opts, pixel_angle)
    slope, max_points = inputs.sizes[:2]
    lv = inputs.scene[0]
    trace = new_trace(capacity)
    o = np.asarray(origin, np.float64)
    d = np.asarray(direction, np.float64)
    length = math.sqrt(float(dot(d, d)))
    ray = np.zeros(RAY_LEN)
    hit = np.zeros(HIT_LEN)
    counts = np.zeros(COUNTER_LEN, np.int64)
    make_ray(ray, o[0], o[1], o[2], d[0], d[1], d[2], t_min, t0, slope * length if dt is None else dt)
    if side is not None:
        set_side(ray, float(side[0]), float(side[1]), float(side[2]))
    hit[H_TIN] = t_max
    args = (ray, hit, inputs.scene, inputs.query, trace, counts, tile_scratch(inputs))
    compiled("ray", variant_for(geom, opts, trace=True, driver=driver), args)(*args)
    effort = int(counts[C_EFFORT])
    leaf_patch = inputs.leaf_patch
    ctrl, pstart, deg_u, deg_v, rational = lv.ctrl, lv.pstart, lv.deg_u, lv.deg_v, lv.rational
    trace = tuple(trace)
    k = int(trace[2][0])
    found = hit[H_TIN] < t_max
    lo = hit[H_LO:H_LO + 3].copy()
    hi = hit[H_HI:H_HI + 3].copy()
    centre = 0.5 * (lo + hi)
    normal = np.zeros(3)
    t = math.inf
    if found:
        pts = np.zeros((4, max_points))
        hit_normal(hit, ctrl, pstart, deg_u, deg_v, rational, ray, pts, np.zeros((4, max_points)),
                   np.zeros((6, 4)), normal)
        t = min(max(float(dot(centre - o, d)) / (length * length), hit[H_TIN]), hit[H_TOUT])
    uv = np.array([hit[H_U], hit[H_V]])
    if found:  # in the parameters of the patch's surface (NURBS), as the renderer reports them
        dom = geom.leaf_domain[int(hit[H_PATCH])]
        uv = np.array([dom[0] + uv[0] * (dom[1] - dom[0]), dom[2] + uv[1] * (dom[3] - dom[2])])
    steps_f, steps_i = _to_scene_patches(geom, trace[0][:k].copy(), trace[1][:k].copy())
    return PixelTrace(tuple(pixel), found, int(leaf_patch[int(hit[H_PATCH])]) if found else -1, t, centre,
                      lo, hi, normal, uv, int(effort), steps_f, steps_i,
                      bool(trace[2][1]), int(trace[2][2]))


def _to_scene_patches(geom: Geometry, steps_f: np.ndarray, steps_i: np.ndarray):
    """Steps of leaves as steps of scene patches: patch index, (u, v) within the scene patch, and
    depth counted from the scene patch (a leaf of a 4^k pre-split starts at depth 2k)."""
    leaf = steps_i[:, 0].copy()
    steps_i[:, 0] = geom.leaf_patch[leaf]
    steps_i[:, 1] += 2 * geom.presplit
    lp = geom.leaf_param[leaf]
    for lo, hi in ((0, 1), (2, 3)):
        a, b = steps_f[:, lo].copy(), steps_f[:, hi].copy()
        steps_f[:, lo] = lp[:, lo] + a * (lp[:, hi] - lp[:, lo])
        steps_f[:, hi] = lp[:, lo] + b * (lp[:, hi] - lp[:, lo])
    return steps_f, steps_i


def trace_pixel(scene, opts: Options, x: int, y: int, *, size=None, view: View | None = None,
                geometry: Geometry | None = None) -> PixelTrace:
    """Trace pixel (x = column, y = row from the top) of the scene's view, as `render` would."""
    width, height = size or scene.image_size or (512, 512)
    if not (0 <= x < width and 0 <= y < height):
        raise ValueError(f"pixel {x},{y} is outside the {width}x{height} image")
    view = view or view_of(scene)
    geom = geometry if geometry is not None else prepare(scene, opts.precision)
    origins, dirs = primary_rays(view, width, height, opts.precision, rect=(y, y + 1, x, x + 1))
    return trace_ray_steps(geom, opts, origins[0, 0], dirs[0, 0], view.pixel_angle(height), (x, y))
