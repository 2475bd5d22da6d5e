"""`psrt study SCENE`: run time against error on the same primary rays (issue 14 item 1; Dammertz
table 2.9). psrt's criteria each with a sweep of their parameter, in both precisions, and the
fastest coherence setting beside the plain one; the tessellation peer (study_peers.py: N x N per
patch, Embree through trimesh) as a first image and per frame; every point scored against a truth
independent of the search (study_truth.py); POV-Ray's bicubic_patch at a sweep of flatness where
povray is installed and the scene is integral bicubic (study_povray.py).

Every series traces the rays of the float32 frame (float64 series: the same rays widened exactly).
Times are the process's CPU time over the trace with one render thread (as psrt bench --coherence),
after one untimed warm-up of each configuration (compiles, builds).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from .camera import primary_rays, view_of
from .geometry import prepare
from .options import Options
from .render import reference_frame, trace_rays
from .study_truth import box_slack, polished_truth

# The parameter sweeps of the issue: fixed sizes as fractions of the scene's size, adaptive pixel
# fractions, mantissa ulps; `float` has no parameter.
FIXED_FRACTIONS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
PIXEL_FRACTIONS = (2.0, 1.0, 0.5, 0.25, 0.125)
MANTISSA_ULPS = (4, 16, 64, 256, 1024, 4096)
PRECISIONS = ("f32", "f64")
# The fastest coherence setting of `psrt bench --coherence` on the teapot (README, "Coherence"):
# 8x8 bundles with the surface-tree cache.
COHERENT = {"bundle": "8x8", "cache": True}


@dataclass(frozen=True)
class Point:
    """One configuration of the study: its series' name, its parameter and the options traced."""

    series: str
    parameter: float | None
    opts: Options


def scene_size(scene) -> float:
    """The longest side of the scene's control-point box: errors are reported relative to it."""
    lo, hi = scene.bounds()
    return float(np.max(hi - lo))


def points(size: float, base: Options = Options(), precisions=PRECISIONS, coherence: bool = True) -> list:
    """Every configuration of the study, series by series."""
    base = base.with_(threads=1)
    sweeps = [("float", [(None, {})]),
              ("fixed", [(f, {"fixed_size": f * size}) for f in FIXED_FRACTIONS]),
              ("adaptive", [(f, {"pixel_fraction": f}) for f in PIXEL_FRACTIONS]),
              ("mantissa", [(k, {"mantissa_ulps": k}) for k in MANTISSA_ULPS])]
    out = []
    for precision in precisions:
        for settings, suffix in [({}, "")] + [(COHERENT, " 8x8+cache")] * coherence:
            for criterion, sweep in sweeps:
                name = f"psrt {criterion} {precision}{suffix}"
                out += [Point(name, p, base.with_(criterion=criterion, precision=precision, **settings, **extra))
                        for p, extra in sweep]
    return out


@dataclass
class Score:
    """One point against the truth, errors relative to the scene's size."""

    seconds: float
    mean_error: float | None   # mean L1 position error over rays both hit (truth accepted)
    max_error: float | None
    compared: int              # rays both hit, where the truth was accepted
    holes: int                 # the reference hit, the point missed
    false_hits: int            # the point hit, the reference missed
    wrong_surface: int         # both hit, on different patches
    inside: float | None       # share of hit boxes (both hit, truth accepted) containing the truth
                               # (boxes widened by study_truth.box_slack, the truth's own uncertainty)


def score(hit, position, patch, box_min, box_max, truth) -> Score:
    """Score a point's per-ray hits (H, W), positions (H, W, 3), patches (H, W) and hit boxes (None for
    a peer without boxes) against the truth (Truth); seconds filled in by the caller."""
    ref_hit, ok = truth.ref.hit, truth.accepted
    both = hit & ref_hit
    same = both & (patch == truth.ref.patch)
    compared = both & ok
    err = np.sum(np.abs(position[compared].astype(np.float64) - truth.position[compared]), axis=-1) / truth.size
    inside = None
    if box_min is not None and compared.any():
        p, ref = truth.position[compared], truth.ref
        slack = box_slack(ref.ray_origin[compared].astype(np.float64), ref.ray_dir[compared].astype(np.float64),
                          ref.t[compared].astype(np.float64))  # the truth is known only to this
        inside = float(np.all((p >= box_min[compared] - slack) & (p <= box_max[compared] + slack), axis=-1).mean())
    return Score(0.0, float(err.mean()) if err.size else None, float(err.max()) if err.size else None,
                 int(compared.sum()), int((ref_hit & ~hit).sum()), int((hit & ~ref_hit).sum()),
                 int((both & ~same).sum()), inside)


@dataclass
class Truth:
    """The truth of the study's rays: the float64 reference, polished positions and where accepted."""

    ref: object
    position: np.ndarray
    accepted: np.ndarray
    size: float

    @property
    def floor(self) -> float:
        """Mean L1 error of merely rounding the truth to float32, relative to the scene's size."""
        p = self.position[self.accepted]
        if not p.size:
            return 0.0
        return float(np.mean(np.sum(np.abs(p.astype(np.float32).astype(np.float64) - p), axis=-1))) / self.size


def cpu_timed(trace):
    """(result, CPU seconds of the process) of trace()."""
    start = time.process_time()
    out = trace()
    return out, time.process_time() - start


@dataclass
class Study:
    """The rays, the truth and the rays' geometries, shared by every point."""

    scene: object
    origins: np.ndarray
    dirs: np.ndarray
    pixel_angle: float
    truth: Truth
    view: object
    geometries: dict


def prepare_study(scene, size, view=None) -> Study:
    """Trace the float32 rays once (float criterion) and build the truth from their float64 reference."""
    view = view or view_of(scene)
    width, height = size
    origins, dirs = primary_rays(view, width, height, "f32")
    geoms = {p: prepare(scene, p) for p in PRECISIONS}
    pixel_angle = view.pixel_angle(height)
    frame = trace_rays(geoms["f32"], Options(threads=1), origins, dirs, pixel_angle)
    ref = reference_frame(scene, frame, geoms["f64"])
    extent = scene_size(scene)
    position, accepted = polished_truth(scene, geoms["f64"], ref, extent)
    return Study(scene, origins, dirs, pixel_angle, Truth(ref, position, accepted, extent), view, geoms)


def run_point(study: Study, point: Point, runs: int = 1) -> Score:
    """Warm up, then time `runs` traces of the point (median CPU time) and score the last."""
    opts = point.opts
    dtype = np.float32 if opts.precision == "f32" else np.float64
    origins, dirs = study.origins.astype(dtype), study.dirs.astype(dtype)

    def trace():
        return trace_rays(study.geometries[opts.precision], opts, origins, dirs, study.pixel_angle)
    trace()
    timed = [cpu_timed(trace) for _ in range(runs)]
    frame = timed[-1][0]
    s = score(frame.hit, frame.position, frame.patch, frame.box_min, frame.box_max, study.truth)
    s.seconds = float(np.median([t for _, t in timed]))
    return s


def run_tessellation(study: Study, n: int, runs: int = 1) -> list:
    """The tessellation peer at n x n per patch: rows of its first-image and per-frame series."""
    from .study_peers import embree_scene, embree_trace
    firsts, frames = [], []
    for _ in range(runs):
        def first_image():
            intersector, face_patch = embree_scene(study.scene, n)
            return intersector, face_patch, embree_trace(intersector, study.origins, study.dirs, face_patch)
        (intersector, face_patch, hits), seconds = cpu_timed(first_image)
        firsts.append(seconds)
        hits, seconds = cpu_timed(lambda: embree_trace(intersector, study.origins, study.dirs, face_patch))
        frames.append(seconds)
    s = score(*hits, None, None, study.truth)
    return [{"series": name, "parameter": n, **asdict(s), "seconds": float(np.median(times))}
            for name, times in (("embree first image", firsts), ("embree per frame", frames))]


def run_povray(study: Study, flatness: float, runs: int = 1) -> dict:
    """The POV-Ray peer at `flatness`: its row (first image only: povray keeps nothing across runs)."""
    from .study_povray import trace
    timed = [trace(study.scene, study.view, study.origins, study.dirs, flatness) for _ in range(runs)]
    s = score(*timed[-1][0], None, None, study.truth)
    return {"series": "povray first image", "parameter": flatness, **asdict(s),
            "seconds": float(np.median([t for _, t in timed]))}


def povray_left_out(scene, flatnesses) -> str | None:
    """Why the POV-Ray peer cannot run on the scene, or None."""
    from .study_povray import available, bicubic_nets
    if not flatnesses:
        return None
    if not available():
        return "povray is not installed (scripts/setup --povray)"
    return bicubic_nets(scene)[1]


def run(scene, size, base: Options = Options(), *, precisions=PRECISIONS, coherence=True, runs=1,
        tessellations=(), flatnesses=(), progress=None, client=None) -> dict:
    """The study as a JSON-ready dict: the truth's figures and every point's score, series by series;
    progress(point) after each point (and once, with None, after the truth); tessellations: the peer's N.
    A peer point's row has the same fields; its `inside` is None (a triangle hit has no box).
    client: a dask.distributed Client whose workers run psrt's points (study_distributed.py; each
    row then says whether its worker's core was contended); the peers run here."""
    study = prepare_study(scene, size)
    if progress is not None:
        progress(None)
    truth = study.truth
    rows = []
    chosen = points(truth.size, base, precisions, coherence)
    if client is None:
        scores = []
        for point in chosen:
            scores.append((run_point(study, point, runs), None))
            if progress is not None:
                progress(point)
    else:
        from .study_distributed import run_points
        scores = run_points(scene, size, chosen, runs, client, progress)
    for point, (s, contended) in zip(chosen, scores):
        row = {"series": point.series, "parameter": point.parameter, **asdict(s)}
        rows.append(row if contended is None else {**row, "contended": contended})
    from .study_peers import fits, warm_up_embree
    if tessellations:
        warm_up_embree()
    for n in tessellations:
        if fits(scene, n):
            rows += run_tessellation(study, n, runs)
        if progress is not None:
            progress(Point("embree", n, base))
    povray_why = povray_left_out(scene, flatnesses)
    for flatness in flatnesses:
        if povray_why is None:
            rows.append(run_povray(study, flatness, runs))
        if progress is not None:
            progress(Point("povray", flatness, base))
    return {"size": list(size), "scene_size": truth.size, "rays": int(truth.ref.hit.size),
            "reference_hits": int(truth.ref.hit.sum()), "truth_accepted": int(truth.accepted.sum()),
            "float32_floor": truth.floor, "runs": runs,
            "tessellations_left_out": [n for n in tessellations if not fits(scene, n)], "povray_left_out": povray_why, "timing": "cpu, one render thread", "points": rows}
