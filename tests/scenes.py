"""Test scenes built in code, and the float32-against-float64 comparison the image tests share.

Scenes are built as contract dicts and loaded by `scene_from_dict`, so every test
goes through the same loader as a user's file. Grids are P[i, j, xyz] as in
`reference.py`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import reference as ref
from tracer import stress
from tracer.camera import View, view_of
from tracer.options import Options
from tracer.geometry import Geometry, prepare
from tracer.nurbs import split_bezier
from tracer.render import Frame, trace_rays
from tracer.scene import Scene, scene_from_dict

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "sample_models"
TEAPOT_BPT = "teapot.bpt"
FLOOR = [[-8, -8, 0], [8, -8, 0], [-8, 8, 0], [8, 8, 0]]


# ---- scene builders ---------------------------------------------------------------------

def load(data: dict, label: str = "test-scene") -> Scene:
    """A Scene from a contract dict; `file` entries resolve against sample_models/."""
    return scene_from_dict(data, label, str(SAMPLES))


def patch_entry(P) -> dict:
    """The contract's inline patch for a grid P[i, j, :]."""
    P = np.asarray(P, np.float64)
    return {"degree": [P.shape[0] - 1, P.shape[1] - 1], "points": ref.flat(P).tolist()}


def patches_scene(grids, label="patches", separate=False) -> Scene:
    """One object holding all grids (they share a frame), or one object each if `separate`."""
    objects = ([{"patches": [patch_entry(P)]} for P in grids] if separate
               else [{"patches": [patch_entry(P) for P in grids]}])
    return load({"objects": objects}, label)


def teapot(scale=1.0, offset=(0.0, 0.0, 0.0), floor=False) -> Scene:
    """The sample teapot, scaled about the origin then translated; optionally on the floor patch."""
    s = float(scale)
    ox, oy, oz = map(float, offset)
    transform = [s, 0, 0, ox, 0, s, 0, oy, 0, 0, s, oz, 0, 0, 0, 1]
    objects = [{"file": TEAPOT_BPT, "transform": transform}]
    if floor:
        pts = [[s * x + ox, s * y + oy, s * z + oz] for x, y, z in FLOOR]
        objects.append({"patches": [{"degree": [1, 1], "points": pts}]})
    return load({"objects": objects}, f"teapot x{scale:g} +{offset}")


def grids_of(scene: Scene) -> list:
    """World control grids P[i, j, :] (float64, as loaded) of every patch of a scene."""
    out = []
    for p in range(scene.n_patches):
        pts = scene.points[scene.point_start[p]:scene.point_start[p + 1], :3]
        out.append(ref.grid(pts, int(scene.degree_u[p]), int(scene.degree_v[p])))
    return out


def smooth_patch(rng, m, n, size=2.0, height=0.6, jitter=0.15) -> np.ndarray:
    """A random but smooth height-field-like patch of degree m x n over [0, size]^2.

    The control net is a jittered regular grid lifted by a few low-frequency waves, so the
    surface has bumps and folds of moderate curvature but no cusps."""
    i = np.arange(m + 1)[:, None] / m
    j = np.arange(n + 1)[None, :] / n
    x = size * (i + jitter * rng.uniform(-1, 1, (m + 1, n + 1)) / m) + 0 * j
    y = size * (j + jitter * rng.uniform(-1, 1, (m + 1, n + 1)) / n) + 0 * i
    z = np.zeros((m + 1, n + 1))
    for _ in range(3):
        fu, fv, ph = rng.uniform(0.5, 2.0), rng.uniform(0.5, 2.0), rng.uniform(0, 2 * np.pi)
        z += height / 3 * np.sin(np.pi * (fu * i + fv * j) + ph)
    return np.stack([x, y, z], axis=-1)


def loop_patch(rng) -> np.ndarray:
    """A random self-intersecting bicubic: a looping cubic profile (control polygon
    0, 3, -2, 1 crosses itself) swept along v with a random twist and bend."""
    prof = np.array([[0.0, 0.0], [3.0, 1.6], [-2.0, 1.6], [1.0, 0.0]])
    prof += rng.uniform(-0.25, 0.25, prof.shape)
    P = np.zeros((4, 4, 3))
    for j in range(4):
        angle = rng.uniform(-0.3, 0.3) * j
        c, s = math.cos(angle), math.sin(angle)
        for i in range(4):
            x, z = prof[i]
            P[i, j] = [c * x - s * z, 1.2 * j + rng.uniform(-0.2, 0.2), s * x + c * z + rng.uniform(-0.3, 0.3)]
    return P


def random_patch(rng, m=3, n=3, size=2.0) -> np.ndarray:
    """Control points uniform in a cube: usually folds over itself."""
    return rng.uniform(-size / 2, size / 2, (m + 1, n + 1, 3))


def split_pair(P, axis: int, t: float):
    """The two patches of P split at parameter t along u (axis 0) or v (axis 1), in float64.

    A scene builder, not a reference: de Casteljau (tracer.nurbs) gives both halves the same
    boundary points bit for bit, and keeps the seam scenes' stored digests where they are."""
    lower, upper = split_bezier(np.moveaxis(np.asarray(P, np.float64), axis, 0), t)
    return np.moveaxis(lower, 0, axis), np.moveaxis(upper, 0, axis)


# ---- views -----------------------------------------------------------------------------

def aim(target, direction, distance, fov_deg, up=(0.0, 0.0, 1.0)) -> View:
    """A view looking at `target` from `distance` along `direction` (pointing from target to eye)."""
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    eye = np.asarray(target, float) + distance * d
    if abs(float(np.dot(d, np.asarray(up, float) / np.linalg.norm(up)))) > 0.99:
        up = (0.0, 1.0, 0.0)
    return View(tuple(map(float, eye)), tuple(map(float, target)), tuple(map(float, up)), float(fov_deg))


transformed = stress.moved_view  # the same view of a scene scaled about the origin and translated


TEAPOT_VIEW = View((6.0, -9.0, 5.0), (0.0, 0.0, 1.5), (0.0, 0.0, 1.0), 35.0)
SIDE_VIEW = View((0.3, -12.0, 1.6), (0.3, 0.0, 1.6), (0.0, 0.0, 1.0), 32.0)   # silhouettes everywhere
LID_VIEW = View((0.55, -0.8, 3.75), (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 30.0)  # knob and its apex
BOTTOM_VIEW = View((0.7, -1.0, -1.4), (0.0, 0.0, 0.05), (0.0, 0.0, 1.0), 35.0)  # collapsed bottom


def surface_samples(P, k=65) -> np.ndarray:
    """S on a k x k parameter grid, (k, k, 3)."""
    ts = np.linspace(0.0, 1.0, k)
    return np.array([[ref.evaluate(P, u, v) for v in ts] for u in ts])


def silhouette_view(scene: Scene, axis=1, along=0, half_width=0.05, distance=30.0) -> View:
    """A grazing close-up of the silhouette at the extreme point of the surface in +`axis`,
    seen along the world axis `along`: the rays there are tangent to the surface. `psrt stress`'s
    choice of view (tracer.stress), on samples evaluated by the reference."""
    pts = np.concatenate([surface_samples(P, 33).reshape(-1, 3) for P in grids_of(scene)])
    return stress.silhouette_view(pts, np.eye(3)[axis], np.eye(3)[along], half_width, distance)


# ---- tracing given rays ------------------------------------------------------------------

def trace(scene_or_geom, origins, dirs, opts: Options = Options(), pixel_angle: float = 0.0) -> Frame:
    """Trace N given rays (origins (N, 3) or (3,), dirs (N, 3), float64, used as given) through the
    renderer's kernel; the Frame's channels are (1, N, ...)."""
    geom = scene_or_geom if isinstance(scene_or_geom, Geometry) else prepare(scene_or_geom, opts.precision)
    d = np.ascontiguousarray(np.asarray(dirs, np.float64).reshape(1, -1, 3))
    o = np.ascontiguousarray(np.broadcast_to(np.asarray(origins, np.float64), d.shape[1:])[None])
    return trace_rays(geom, opts, o, d, pixel_angle)


# ---- float32 against float64 -----------------------------------------------------------

@dataclass
class Comparison:
    """A float32 render against the float64 `float`-criterion render of the same rays, scored as
    `psrt stress` scores its variants (tracer.stress.Score: hits, holes, false_hits, unresolved,
    mean_error, max_error, floor, inside, ratio are read through to it)."""

    name: str
    score: stress.Score
    frame: Frame = field(repr=False)
    reference: Frame = field(repr=False)

    def __getattr__(self, attr):
        if attr == "score":  # not set yet (copy, pickle): no recursion
            raise AttributeError(attr)
        return getattr(self.score, attr)

    def row(self) -> str:
        return (f"{self.name:<28} {self.hits:6d} {self.holes:5d} {self.false_hits:5d} "
                f"{self.mean_error:10.3e} {self.floor:10.3e} {self.ratio:7.2f} {100 * self.inside:8.4f}%")


def compare(scene: Scene, size=(64, 64), view: View | None = None, opts: Options = Options(),
            name: str = "") -> Comparison:
    """Trace `scene`'s primary rays with `opts` (float32) and the float64 reference of the same
    rays (tracer.stress, as `psrt stress` does); score holes, false hits, errors against the
    rounding floor and reference-in-box containment."""
    frame, refr = stress.trace_variant(scene, view or view_of(scene), size, opts)
    return Comparison(name or str(scene.path), stress.score(frame, refr), frame, refr)


TABLE_HEADER = (f"{'scene':<28} {'hits':>6} {'holes':>5} {'false':>5} {'mean err':>10} {'floor':>10} "
                f"{'ratio':>7} {'inside':>9}")


def write_failure_images(cmp: Comparison, directory) -> list:
    """Actual, expected and difference hit masks as PNGs (red: hole, blue: false hit)."""
    from PIL import Image
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    stem = "".join(ch if ch.isalnum() else "_" for ch in cmp.name)
    a, e = cmp.frame.hit, cmp.reference.hit
    diff = np.zeros(a.shape + (3,), np.uint8)
    diff[e & a] = 80
    diff[e & ~a] = (255, 0, 0)
    diff[a & ~e] = (0, 0, 255)
    out = []
    for tag, img in (("actual", a.astype(np.uint8) * 255), ("expected", e.astype(np.uint8) * 255),
                     ("diff", diff)):
        path = directory / f"{stem}-{tag}.png"
        Image.fromarray(img).save(path)
        out.append(path)
    return out


def check(cmp: Comparison, directory, max_ratio=10.0, min_inside=0.9999) -> None:
    """Assert the stress targets; on failure write the hit-mask images and say where."""
    problems = []
    if cmp.unresolved:  # the scoring leaves them out: they must not hide a hole
        problems.append(f"{cmp.unresolved} pixels the reference could not resolve")
    if cmp.holes:
        problems.append(f"{cmp.holes} holes")
    if cmp.false_hits:
        problems.append(f"{cmp.false_hits} false hits")
    if cmp.ratio > max_ratio:
        problems.append(f"mean error {cmp.mean_error:.3e} is {cmp.ratio:.2f}x the float32 floor "
                        f"{cmp.floor:.3e} (allowed {max_ratio}x)")
    if cmp.inside < min_inside:
        problems.append(f"only {100 * cmp.inside:.4f}% of reference points inside the widened box "
                        f"(need {100 * min_inside:.2f}%)")
    if problems:
        paths = write_failure_images(cmp, directory)
        raise AssertionError(f"{cmp.name}: " + "; ".join(problems) + f"\n{TABLE_HEADER}\n{cmp.row()}\n"
                             f"images: {', '.join(map(str, paths))}")


# ---- the stress catalogue ---------------------------------------------------------------

@dataclass(frozen=True)
class Case:
    """One stress scene: a builder (scenes are rebuilt per use, they are cheap), size and view."""

    name: str
    build: object
    size: tuple
    view: object  # a View, or a function of the built scene returning one

    def scene_and_view(self):
        scene = self.build()
        view = self.view(scene) if callable(self.view) else self.view
        return scene, view


def seam_case(name, axis, t, seed, oblique=False) -> Case:
    """A random smooth bicubic split in float64 at the non-dyadic parameter t along `axis`:
    two patches meeting in a seam; the view is centred on the seam's midpoint."""
    P = smooth_patch(np.random.default_rng(seed), 3, 3)
    halves = split_pair(P, axis, t)
    uv = (t, 0.5) if axis == 0 else (0.5, t)
    target = ref.evaluate(P, *uv)
    n = ref.normal(P, *uv)
    along = ref.derivatives(P, *uv)[1 + axis]  # across the seam
    direction = n + (1.5 * along / np.linalg.norm(along) if oblique else 0.25 * along / np.linalg.norm(along))
    return Case(name, lambda: patches_scene(list(halves), name), (64, 64), aim(target, direction, 3.0, 12.0))


def _framing(direction=(0.55, -0.8, 0.45), zoom=2.0):
    """framing_view of the control points, zoomed in: the surface fills less than their box."""
    from tracer.camera import framing_view

    def view(scene):
        v = framing_view(*scene.bounds(), direction=direction)
        return View(v.eye, v.look_at, v.up, v.fov_deg / zoom)
    return view


def stress_cases() -> list:
    """The numerical stress scenes (each <= 64 x 64)."""
    far = (1e4, 1e4, 1e4)
    rng_seeds = {"loop a": 3, "loop b": 4, "folded cube": 5, "deg 9x7": 6, "deg 15x15": 7}
    return [
        Case("teapot x1e-4", lambda: teapot(1e-4), (64, 64), transformed(TEAPOT_VIEW, 1e-4)),
        Case("teapot x1e4", lambda: teapot(1e4), (64, 64), transformed(TEAPOT_VIEW, 1e4)),
        Case("teapot +1e4", lambda: teapot(1.0, far), (64, 64), transformed(TEAPOT_VIEW, 1.0, far)),
        Case("grazing silhouette body", teapot, (64, 64), lambda s: silhouette_view(s, axis=1, along=0)),
        Case("grazing silhouette knob", teapot, (64, 64), lambda s: silhouette_view(s, axis=2, along=0)),
        Case("grazing floor", lambda: teapot(floor=True), (64, 48),
             View((-7.9, -7.9, 0.03), (8.0, 8.0, 0.0), (0.0, 0.0, 1.0), 30.0)),
        Case("lid apex", teapot, (64, 64), LID_VIEW),
        Case("lid apex zoom", teapot, (48, 48), aim((0.0, 0.0, 3.15), (0.6, -0.8, 1.0), 1.0, 1.0)),
        Case("bottom apex", teapot, (64, 64), BOTTOM_VIEW),
        Case("self-intersecting loop a", lambda: patches_scene([loop_patch(np.random.default_rng(rng_seeds["loop a"]))]),
             (64, 64), _framing((0.2, -1.0, 0.3))),
        Case("self-intersecting loop b", lambda: patches_scene([loop_patch(np.random.default_rng(rng_seeds["loop b"]))]),
             (64, 64), _framing((-0.4, -1.0, 0.6))),
        Case("folded random cube", lambda: patches_scene([random_patch(np.random.default_rng(rng_seeds["folded cube"]))]),
             (64, 64), _framing()),
        seam_case("seam u=0.3718", 0, 0.3718, 8),
        seam_case("seam v=0.6183 oblique", 1, 0.6183, 9, oblique=True),
        Case("degree 9x7", lambda: patches_scene([smooth_patch(np.random.default_rng(rng_seeds["deg 9x7"]), 9, 7)]),
             (64, 64), _framing()),
        Case("degree 15x15", lambda: patches_scene([smooth_patch(np.random.default_rng(rng_seeds["deg 15x15"]), 15, 15)]),
             (48, 48), _framing()),
    ]


def run_case(case: Case, opts: Options = Options()) -> Comparison:
    scene, view = case.scene_and_view()
    return compare(scene, case.size, view, opts, name=case.name)


def accuracy_table(opts: Options = Options()) -> str:
    """The per-scene float32-against-float64 table of the stress catalogue."""
    rows = [TABLE_HEADER] + [run_case(c, opts).row() for c in stress_cases()]
    return "\n".join(rows)


if __name__ == "__main__":
    print(accuracy_table())
