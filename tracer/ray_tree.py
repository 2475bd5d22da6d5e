"""One pixel's ray tree: every ray the renderer traced for it, and what became of each.

The pixel inspector's view of lighting.py. The pixel's primary ray is traced with the rest of its
ray bundle, as the render traced it, and shaded again by a Lighting whose recorder sees every
batch of secondary rays as the kernels got them: shadow rays (light, sample point, occluded),
penumbra tests (the ray to the light's centre, proven lit or not), reflected and refracted rays
(their hits), each with the box and the side its origin left from. Light samples are seeded by
the pixel's number in the whole image, so the records are the render's own: the tree's shadow,
shadow rays and radiance are the full render's at that pixel (tests/test_ray_tree.py). With the
surface-tree cache under the adaptive criterion or the cross split, a primary hit depends on the
rays traced before it and may differ.

On request each ray gets its subdivision trace (trace_one.trace_ray_steps: the same walk with
step recording, over the BVH as secondary rays are traced; shadow rays with the any-hit driver
up to the light sample, t_max = 1). Penumbra tests have none (their kernel walks grown boxes).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .camera import View, primary_rays, view_of
from .geometry import Geometry, prepare
from .options import Options
from .origins import box_corner
from .ray_batch import RB_D, RB_DT, RB_LEN, RB_O, RB_SIDE, RB_T0, RB_TMAX, RB_TMIN
from .render import bundle_shape, frame_lighting, kernel_inputs, trace_rays
from .trace_one import PixelTrace, trace_pixel, trace_ray_steps

KINDS = ("primary", "penumbra_test", "umbra_test", "shadow", "reflected", "refracted")
TESTS = ("penumbra_test", "umbra_test")  # rays asked of the fast penumbra, not traced by the search


def _vec(a) -> list | None:
    return None if a is None else [float(x) for x in a]


@dataclass
class RayRecord:
    """One ray of the tree. code: the path code of the ray's own vertex (1 primary; 2c reflected,
    2c + 1 refracted from c); shadow rays and penumbra tests carry the code of the vertex they
    leave. ray: the batch ray as traced (ray_batch.RB_*; t_max 1 at the light sample); hit: a
    hit found (shadow rays: occluded; penumbra tests: not proven lit); box_min, box_max, patch,
    t, position: the hit's (shadow rays: from their trace, when traced); corner: the box corner
    the origin was moved from (origin box_corner), from_box: (lo, hi) of the vertex it leaves."""

    kind: str
    code: int
    ray: np.ndarray
    hit: bool
    light: int = -1
    target: np.ndarray | None = None
    corner: np.ndarray | None = None
    from_box: tuple | None = None
    patch: int = -1
    t: float = float("inf")
    position: np.ndarray | None = None
    box_min: np.ndarray | None = None
    box_max: np.ndarray | None = None
    effort: int = 0
    steps: PixelTrace | None = None

    @property
    def origin(self) -> np.ndarray:
        return self.ray[RB_O:RB_O + 3]

    @property
    def direction(self) -> np.ndarray:
        return self.ray[RB_D:RB_D + 3]

    @property
    def depth(self) -> int:
        """Reflections and refractions before this ray's vertex (the primary ray's is 0)."""
        return int(self.code).bit_length() - 1

    @property
    def parent(self) -> int:
        """The code of the vertex the ray leaves (0: the eye)."""
        return self.code // 2 if self.kind in ("primary", "reflected", "refracted") else self.code

    def outcome(self) -> str:
        if self.kind == "shadow":
            return "occluded" if self.hit else "lit"
        if self.kind == "penumbra_test":
            return "not proven lit" if self.hit else "proven lit"
        if self.kind == "umbra_test":
            return f"proven umbra: every shadow ray crosses patch {self.patch}" if self.hit else "not proven umbra"
        return f"patch {self.patch}" if self.hit else "miss"

    def to_json(self, steps: bool = False) -> dict:
        out = {"kind": self.kind, "code": int(self.code), "depth": self.depth, "parent": int(self.parent),
               "light": int(self.light), "origin": _vec(self.origin), "direction": _vec(self.direction),
               "t_min": float(self.ray[RB_TMIN]), "t_max": float(self.ray[RB_TMAX]),
               "threshold": [float(self.ray[RB_T0]), float(self.ray[RB_DT])],
               "target": _vec(self.target), "corner": _vec(self.corner),
               "from_box": {"min": _vec(self.from_box[0]), "max": _vec(self.from_box[1])} if self.from_box else None,
               "outcome": self.outcome(), "hit": bool(self.hit), "patch": int(self.patch),
               "t": float(self.t) if self.hit and np.isfinite(self.t) else None, "position": _vec(self.position),
               "box_min": _vec(self.box_min), "box_max": _vec(self.box_max), "effort": int(self.effort)}
        if self.steps is not None:
            trace = self.steps.to_json()
            out["trace"] = trace if steps else {k: trace[k] for k in ("hit_step", "summary", "effort")}
        return out


@dataclass
class RayTree:
    """A pixel's rays (primary first, then level by level: penumbra tests, shadow rays, the next
    level's reflected and refracted rays), its light samples per vertex and light (code, light,
    samples, visible, proven_lit), and the pixel's shading: shadow (None without shadows or on a
    miss), shadow rays traced, penumbra class, radiance (linear RGB)."""

    pixel: tuple
    origin_method: str
    rays: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    shadow: float | None = None
    shadow_rays: int = 0
    penumbra: int = -1
    radiance: np.ndarray | None = None

    def census(self) -> str:
        """How many rays of each kind, e.g. '1 primary, 1 penumbra test, 16 shadow, 1 reflected'."""
        kinds = [r.kind for r in self.rays]
        return ", ".join(f"{kinds.count(k)} {k.replace('_', ' ')}" for k in KINDS if k in kinds)

    def to_json(self, steps: bool = False) -> dict:
        return {"pixel": [int(v) for v in self.pixel], "origin_method": self.origin_method,
                "shadow": self.shadow, "shadow_rays": int(self.shadow_rays), "penumbra": int(self.penumbra),
                "radiance": _vec(self.radiance), "lights": self.lights,
                "rays": [r.to_json(steps) for r in self.rays]}


class _Recorder:
    """lighting.Lighting.recorder: keeps every batch, in the order the lighting made them."""

    def __init__(self):
        self.batches = []

    def __call__(self, kind, **rays):
        self.batches.append((kind, rays))


def ray_tree(scene, opts: Options, x: int, y: int, *, size=None, view: View | None = None,
             geometry: Geometry | None = None, steps: bool = False) -> RayTree:
    """The ray tree of pixel (x = column, y = row from the top) of the scene's view, as `render`
    traced and shaded it; steps: each ray's subdivision trace too (RayRecord.steps)."""
    width, height = size or scene.image_size or (512, 512)
    if not (0 <= x < width and 0 <= y < height):
        raise ValueError(f"pixel {x},{y} is outside the {width}x{height} image")
    view = view or view_of(scene)
    geom = geometry if geometry is not None else prepare(scene, opts.precision)
    # the bundle holding the pixel (bundles are aligned to the image grid): a ray in a bundle may
    # report other bits than alone (tests/test_bundles.py)
    cols, rows = bundle_shape(opts)
    y0, x0 = y - y % rows, x - x % cols
    rect = (y0, min(y0 + rows, height), x0, min(x0 + cols, width))
    origins, dirs = primary_rays(view, width, height, opts.precision, rect=rect)
    angle = view.pixel_angle(height)
    frame = trace_rays(geom, opts.with_(order="scanline", threads=1), origins, dirs, angle)
    lighting = frame_lighting(scene, geom, opts, kernel_inputs(geom, opts, angle), angle, view.eye)
    recorder = lighting.recorder = _Recorder()
    frame.add_lighting(opts.shadows)
    local = (y - y0, x - x0)
    lighting.shade_unit(frame, np.array([local], np.int32), ids=[y * width + x])

    tree = RayTree((x, y), opts.origin)
    ray = np.zeros(RB_LEN)
    ray[RB_O:RB_O + 3], ray[RB_D:RB_D + 3], ray[RB_TMAX] = origins[local], dirs[local], np.inf
    hit = bool(frame.hit[local])
    tree.rays.append(RayRecord("primary", 1, ray, hit, patch=int(frame.patch[local]), t=float(frame.t[local]),
                               position=frame.position[local] if hit else None,
                               box_min=frame.box_min[local] if hit else None,
                               box_max=frame.box_max[local] if hit else None, effort=int(frame.effort[local])))
    corner = opts.origin == "box_corner"
    for kind, b in recorder.batches:
        if kind == "samples":
            tree.lights += [{"code": int(c), "light": int(b["light"]), "samples": int(vis.size),
                             "visible": int(vis.sum()), "proven_lit": None, "proven_umbra": None}
                            for c, vis in zip(b["code"], b["visible"])]
        else:
            tree.rays += _records(kind, b, corner)
    for entry in tree.lights:  # the fast penumbra's answers beside the samples they spared
        for r in tree.rays:
            if (r.code, r.light) != (entry["code"], entry["light"]):
                continue
            if r.kind == "penumbra_test":
                entry["proven_lit"] = not r.hit
            elif r.kind == "umbra_test":
                entry["proven_umbra"] = r.hit
    if hit:
        tree.shadow_rays = int(frame.shadow_rays[local])
        tree.radiance = frame.radiance[local].astype(np.float64)
        if opts.shadows:
            tree.penumbra = int(frame.penumbra[local])
            tree.shadow = float(sum(lighting.share[e["light"]] * e["visible"] / e["samples"]
                                    for e in tree.lights if e["code"] == 1))
    if steps:
        trace_steps(tree, scene, geom, opts, view, (width, height))
    return tree


def _records(kind: str, b: dict, corner: bool) -> list:
    """The RayRecords of one recorded batch (lighting.Lighting.recorder)."""
    n = len(b["code"])
    corners = box_corner(b["box_min"], b["box_max"], b["side"]) if corner else [None] * n
    boxes = list(zip(b["box_min"], b["box_max"]))
    if kind == "shadow":
        return [RayRecord("shadow", int(b["code"][i]), b["rays"][i], bool(b["occluded"][i]), int(b["light"]),
                          b["target"][i], corners[i], boxes[i], effort=int(b["effort"][i])) for i in range(n)]
    if kind == "proven_lit":
        return [RayRecord("penumbra_test", int(b["code"][i]), _centre_ray(b["origin"][i], b["centre"]),
                          not bool(b["lit"][i]), int(b["light"]), b["centre"], corners[i], boxes[i])
                for i in range(n)]
    if kind == "proven_umbra":
        return [RayRecord("umbra_test", int(b["code"][i]), _centre_ray(b["origin"][i], b["centre"]),
                          bool(b["patch"][i] >= 0), int(b["light"]), b["centre"], corners[i], boxes[i],
                          patch=int(b["patch"][i])) for i in range(n)]
    out = b["hit"]
    records = []
    for i in range(n):
        code, found = int(b["code"][i]), bool(out.hit[0, i])
        records.append(RayRecord("reflected" if code % 2 == 0 else "refracted", code, b["rays"][i], found,
                                 corner=corners[i], from_box=boxes[i], patch=int(out.patch[0, i]),
                                 t=float(out.t[0, i]), position=out.position[0, i] if found else None,
                                 box_min=out.box_min[0, i] if found else None,
                                 box_max=out.box_max[0, i] if found else None, effort=int(out.effort[0, i])))
    return records


def _centre_ray(origin, centre) -> np.ndarray:
    ray = np.zeros(RB_LEN)
    ray[RB_O:RB_O + 3], ray[RB_D:RB_D + 3], ray[RB_TMAX] = origin, np.asarray(centre) - origin, 1.0
    return ray


def trace_steps(tree: RayTree, scene, geom: Geometry, opts: Options, view: View, size, limit: int | None = None) -> None:
    """Give the tree's rays (the first `limit`, or all) their subdivision traces: the primary ray
    as trace_one.trace_pixel traces it, secondary rays over the BVH as lighting.py traces them."""
    width, height = size
    angle = view.pixel_angle(height)
    secondary = opts.with_(accel="bvh")
    for r in tree.rays[:limit]:
        if r.kind == "primary":
            r.steps = trace_pixel(scene, opts, *tree.pixel, size=size, view=view, geometry=geom)
        elif r.kind not in TESTS:
            q = r.ray
            r.steps = trace_ray_steps(geom, secondary, q[RB_O:RB_O + 3], q[RB_D:RB_D + 3], angle, tree.pixel,
                                      t_min=q[RB_TMIN], t_max=q[RB_TMAX], t0=q[RB_T0], dt=q[RB_DT],
                                      driver="any" if r.kind == "shadow" else "closest",
                                      side=q[RB_SIDE:RB_SIDE + 3])
            if r.kind == "shadow" and r.steps.hit:  # the box that occluded it
                r.box_min, r.box_max, r.patch, r.t = r.steps.box_min, r.steps.box_max, r.steps.patch, r.steps.t
                r.position = r.steps.position
