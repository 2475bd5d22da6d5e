"""The numerical stability suite on any loaded scene (`psrt stress`; issue 14 item 2).

Each variant is the scene moved, scaled, perturbed or seen otherwise; it is traced in the working
precision (primary rays only: the suite measures intersection, not shading) and scored against
the float64 reference of the same rays (render.reference_frame, stats.error_stats): holes, false
hits, mean error over the float32 rounding floor, and containment of the reference points in the
hit boxes widened by 4 float32 ulps. tests/scenes.py scores its stress catalogue with `score`.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .camera import View, primary_rays, view_of
from .errors import SceneError
from .fixed_order import dot, norm
from .options import Options
from .trim import bernstein

# Scales apply about the origin, like the view's: a factor about the scene's centre would also
# move a scene that lies off the origin relative to its size, which is what `move` measures.
SCALES = (1e-6, 1e-3, 1e3, 1e6)
MOVES = (1e2, 1e4, 1e6)          # offsets in every coordinate, in units of the scene's extent
AZIMUTHS = (0.0, 90.0, 180.0, 270.0)
PERTURB_ULPS = (1, 2, 3, 4)
MAX_SAMPLES = 1_000_000          # surface points sampled to find a silhouette
TANGENT_COS = 0.02               # |cos| between normal and view below which a sample is on the silhouette


@dataclass(frozen=True)
class Variant:
    """One way to stress a scene: kind 'as-is', 'scale', 'move', 'grazing' or 'ulps', and its amount
    (the factor, the offset in extents, the azimuth in degrees, or the ulps)."""

    kind: str
    amount: float = 0.0

    @property
    def name(self) -> str:
        if self.kind in ("scale", "move"):  # powers of ten: scale-1e-6, move-1e4
            return f"{self.kind}-1e{round(math.log10(self.amount))}"
        return self.kind if self.kind == "as-is" else f"{self.kind}-{self.amount:g}"


def variants() -> list:
    """Every variant of the suite, in table order."""
    return ([Variant("as-is")] + [Variant("scale", s) for s in SCALES] + [Variant("move", m) for m in MOVES]
            + [Variant("grazing", a) for a in AZIMUTHS] + [Variant("ulps", k) for k in PERTURB_ULPS])


def select(names) -> list:
    """The variants named (or of the kinds named), in table order; ValueError naming an unknown one."""
    every = variants()
    known = {v.name for v in every} | {v.kind for v in every}
    for name in names:
        if name not in known:
            raise ValueError(f"--variants: unknown variant {name!r} (known: {', '.join(v.name for v in every)}, "
                             f"or a kind: scale, move, grazing, ulps)")
    return [v for v in every if v.name in names or v.kind in names]


# ---- the variant's scene and view ---------------------------------------------------------

def extent(scene) -> float:
    """The longest side of the box of the scene's control points."""
    lo, hi = scene.bounds()
    return float(np.max(hi - lo))


def with_points(scene, xyz):
    """The scene with its control points' Euclidean coordinates replaced (weights kept)."""
    return dataclasses.replace(scene, points=np.column_stack([xyz, scene.points[:, 3]]))


def perturbed(scene, ulps: int, seed: int):
    """Every control coordinate moved by a seeded whole number of float32 ulps in -ulps..ulps."""
    xyz = scene.points[:, :3]
    steps = np.random.default_rng(seed).integers(-ulps, ulps + 1, xyz.shape)
    ulp = np.spacing(np.abs(xyz).astype(np.float32)).astype(np.float64)
    return with_points(scene, xyz + steps * ulp)


def moved_view(view: View, scale=1.0, offset=(0.0, 0.0, 0.0)) -> View:
    """The view of the scene scaled about the origin by `scale`, then translated by `offset`."""
    off = np.asarray(offset, float)
    return View(tuple(map(float, np.asarray(view.eye) * scale + off)),
                tuple(map(float, np.asarray(view.look_at) * scale + off)), view.up, view.fov_deg)


def grid_points(scene, ts):
    """Yields (patches, points [v, u, patch, xyz]) per degree pair of the scene: its patches (indices)
    evaluated in float64 on the parameter grid ts x ts (trims ignored)."""
    for m, d in sorted(set(zip(scene.degree_u.tolist(), scene.degree_v.tolist()))):
        patches = np.flatnonzero((scene.degree_u == m) & (scene.degree_v == d))
        rows = scene.point_start[patches][:, None] + np.arange((m + 1) * (d + 1))
        pts = scene.points[rows]                                      # (P, count, 4): x y z w
        homog = np.concatenate([pts[..., :3] * pts[..., 3:], pts[..., 3:]], axis=-1)
        nets = homog.reshape(len(patches), d + 1, m + 1, 4)           # [patch, j (v), i (u), xyzw]
        bu, bv = bernstein(m, ts), bernstein(d, ts)
        s = dot(bv, dot(bu, nets.transpose(2, 0, 1, 3)).transpose(2, 0, 1, 3))  # [v, u, patch, xyzw]
        yield patches, s[..., :3] / s[..., 3:]


def surface_samples(scene, k: int | None = None):
    """(points, normals, curved), (count, 3), (count, 3), (count,): every patch on a k x k parameter
    grid (trims ignored; k from the patch count so that at most MAX_SAMPLES points are made), in
    float64; unit normals from differences along the grid (NaN where the grid collapses, as at a
    pole); curved: the sample's patch is not a plane (its normals differ)."""
    n = scene.n_patches
    k = k or int(min(33, max(2, math.isqrt(MAX_SAMPLES // max(n, 1)))))
    ts = np.linspace(0.0, 1.0, k)
    points, normals, curved = [], [], []
    for patches, xyz in grid_points(scene, ts):
        n = np.cross(np.gradient(xyz, axis=1), np.gradient(xyz, axis=0))
        with np.errstate(invalid="ignore", divide="ignore"):
            n = n / np.sqrt(n[..., 0:1] ** 2 + n[..., 1:2] ** 2 + n[..., 2:3] ** 2)
        ok = ~np.isnan(n[..., :1])
        mean = np.where(ok, n, 0.0).sum(axis=(0, 1)) / np.maximum(ok.sum(axis=(0, 1)), 1)
        spread = np.where(ok, np.abs(n - mean), 0.0).max(axis=(0, 1, 3))  # per patch; 0: a plane
        points.append(xyz.reshape(-1, 3))
        normals.append(n.reshape(-1, 3))
        curved.append(np.broadcast_to(~(spread < 1e-9), (k, k, len(patches))).reshape(-1))
    return np.concatenate(points), np.concatenate(normals), np.concatenate(curved)


def silhouette_view(points, outward, along, half_width: float, distance: float) -> View:
    """A grazing close-up of the silhouette at the sample point farthest in `outward`, seen along
    `along` (perpendicular to it) from `distance`: the rays there are tangent to the surface."""
    target = points[int(np.argmax(dot(points, np.asarray(outward, float))))]
    a = np.asarray(along, float) / norm(np.asarray(along, float))
    up = (0.0, 1.0, 0.0) if abs(a[2]) > 0.99 else (0.0, 0.0, 1.0)
    fov = math.degrees(2 * math.atan(half_width / distance))
    return View(tuple(map(float, target - distance * a)), tuple(map(float, target)), up, fov)


def grazing_view(scene, azimuth_deg: float) -> View:
    """A horizontal view from `azimuth_deg` (about z), five extents away and 1/128 of the extent
    wide, of the rightmost silhouette point: a sample of a curved patch whose normal is within
    TANGENT_COS of perpendicular to the view (any sample if there is none). A plane seen edge-on
    (a floor) has edges there, not points where the rays touch the surface."""
    az = math.radians(azimuth_deg)
    along = np.array([-math.cos(az), -math.sin(az), 0.0])
    outward = np.array([-math.sin(az), math.cos(az), 0.0])   # the image's right
    points, normals, curved = surface_samples(scene)
    tangent = curved & (np.abs(dot(normals, along)) < TANGENT_COS)  # NaN normals compare False
    size = extent(scene)
    return silhouette_view(points[tangent] if tangent.any() else points, outward, along, size / 128, 5 * size)


def variant_scene(scene, variant: Variant, view: View):
    """(scene, view) of a variant of a loaded scene seen by `view`."""
    xyz = scene.points[:, :3]
    if variant.kind == "scale":
        return with_points(scene, xyz * variant.amount), moved_view(view, variant.amount)
    if variant.kind == "move":
        offset = np.full(3, variant.amount * extent(scene))
        return with_points(scene, xyz + offset), moved_view(view, 1.0, offset)
    if variant.kind == "grazing":
        return scene, grazing_view(scene, variant.amount)
    if variant.kind == "ulps":
        return perturbed(scene, int(variant.amount), seed=int(variant.amount)), view
    return scene, view


# ---- scoring ------------------------------------------------------------------------------

@dataclass
class Score:
    """A frame against its float64 reference (stats.error_stats; unresolved pixels left out)."""

    hits: int             # reference hits
    holes: int            # reference hit, frame missed
    false_hits: int       # frame hit, reference missed
    unresolved: int       # the reference's box budget ran out
    mean_error: float     # mean L1 distance to the reference positions
    max_error: float
    floor: float          # mean L1 error of merely rounding the reference positions to float32
    inside: float         # fraction of reference positions inside the box widened by 4 float32 ulps

    @property
    def ratio(self) -> float:
        return self.mean_error / self.floor if self.floor > 0 else (0.0 if self.mean_error == 0 else math.inf)


def score(frame, ref) -> Score:
    from .stats import error_stats
    e = error_stats(frame, ref)
    both = e["compared"] > 0
    return Score(int(ref.hit.sum()), e["holes"], e["false_hits"], e["unresolved"],
                 e["mean"] if both else 0.0, e["max"] if both else 0.0, e["floor"] if both else 0.0,
                 e["inside_4ulp"] if both else 1.0)


@dataclass
class Result:
    """One variant's run: its score, or why the tracer refused it; warnings; seconds."""

    variant: Variant
    score: Score | None = None
    refused: str | None = None
    warnings: tuple = ()
    seconds: float = 0.0            # the working precision's trace
    reference_seconds: float = 0.0

    @property
    def failed(self) -> bool:
        return self.score is not None and bool(self.score.holes or self.score.false_hits)

    def to_json(self) -> dict:
        out = {"name": self.variant.name, "kind": self.variant.kind, "amount": self.variant.amount,
               "refused": self.refused, "warnings": list(self.warnings), "seconds": self.seconds,
               "reference_seconds": self.reference_seconds}
        if self.score is not None:
            out.update(dataclasses.asdict(self.score), ratio=self.score.ratio)
        return out


def trace_variant(scene, view: View, size, opts: Options):
    """(frame, reference) of a scene's primary rays: opts' precision, then float64."""
    from .geometry import prepare
    from .render import reference_frame, trace_rays
    width, height = size
    origins, dirs = primary_rays(view, width, height, opts.precision)
    frame = trace_rays(prepare(scene, opts.precision), opts, origins, dirs, view.pixel_angle(height), view=view)
    return frame, reference_frame(scene, frame)


def run_variant(scene, variant: Variant, size, opts: Options = Options(), view: View | None = None) -> Result:
    """Trace and score one variant; a scene the tracer refuses (limits.py) is reported, not raised."""
    from .limits import check_extent
    try:
        vscene, vview = variant_scene(scene, variant, view or view_of(scene))
        warnings = tuple(check_extent(vscene, opts.precision))
        frame, ref = trace_variant(vscene, vview, size, opts)
    except SceneError as e:
        return Result(variant, refused=" ".join(str(e).split()))
    return Result(variant, score(frame, ref), None, warnings, frame.seconds, ref.seconds)


def run(scene, chosen, size, opts: Options = Options(), progress=None, client=None) -> list:
    """Results of the chosen variants, in their order; progress(result) after each. client: a
    dask.distributed Client (tracer/distributed.py) whose workers each load the scene from its
    path and run one variant per task; None: here, one after another."""
    from .distributed import map_items
    import os
    where = (os.path.abspath(scene.path), str(scene.path))
    items = [(where, variant, tuple(size), opts) for variant in chosen]
    if client is None:  # the scene is loaded already
        view = view_of(scene)
        items = [(scene, variant, size, opts, view) for _, variant, size, opts in items]
    step = None if progress is None else (lambda i, result: progress(result))
    return map_items(variant_item, items, client, progress=step)


def variant_item(item) -> Result:
    """One work item of `run`: (scene or (its absolute path, its path as given), variant, size,
    options[, view])."""
    from .distributed import loaded_scene
    from .distributed import worker_threads
    scene, variant, size, opts, *view = item
    opts = opts.with_(threads=worker_threads(opts.threads))
    return run_variant(loaded_scene(*scene) if isinstance(scene, tuple) else scene, variant, size, opts, *view)


# ---- the table ----------------------------------------------------------------------------

HEADER = (f"{'variant':<14} {'hits':>6} {'holes':>5} {'false':>5} {'unres':>5} {'err/floor':>9} "
          f"{'inside':>9} {'trace s':>7} {'f64 s':>7}  note")


def row(r: Result) -> str:
    if r.score is None:
        return f"{r.variant.name:<14} refused: {r.refused}"
    s = r.score
    # a warning reads "file: coordinates ...: what: remedy"; the table keeps the what
    note = "; ".join(("HOLES/FALSE HITS",) * r.failed + tuple((w.split(": ") + [w] * 3)[2] for w in r.warnings))
    return (f"{r.variant.name:<14} {s.hits:6d} {s.holes:5d} {s.false_hits:5d} {s.unresolved:5d} "
            f"{s.ratio:9.3g} {100 * s.inside:8.4f}% {r.seconds:7.3f} {r.reference_seconds:7.3f}  {note}").rstrip()


def table(results) -> str:
    return "\n".join([HEADER] + [row(r) for r in results])
