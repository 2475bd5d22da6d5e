"""`psrt study SCENE`: run time against error on the same primary rays (issue 14 item 1; Dammertz
table 2.9). psrt's criteria each with a sweep of their parameter, in both precisions, and the
fastest coherence setting beside the plain one (measured per criterion and precision on the study's
rays: study_coherence.py); the tessellation peer (study_peers.py: N x N per
patch, Embree through trimesh) as a first image and per frame; every point scored against a truth
independent of the search (study_truth.py); POV-Ray's bicubic_patch at a sweep of flatness where
povray is installed and the scene is integral bicubic (study_povray.py).

Every series traces the rays of the float32 frame (float64 series: the same rays widened exactly).
Times are the process's CPU time over the trace with one render thread (as psrt bench --coherence),
after one untimed warm-up of each configuration (compiles, builds). Every coherence trial, psrt
point and peer point is a work unit: run here, or on Dask workers (study_distributed.py).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from .camera import primary_rays, view_of
from .geometry import prepare
from .options import PLAIN, Options
from .render import reference_frame, trace_rays
from .study_coherence import CANDIDATES, ROUNDS, Trial, run_trial, settings, trials
from .study_truth import box_slack, polished_truth

# The parameter sweeps of the issue: fixed sizes as fractions of the scene's size, adaptive pixel
# fractions, mantissa ulps; `float` has no parameter.
FIXED_FRACTIONS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
PIXEL_FRACTIONS = (2.0, 1.0, 0.5, 0.25, 0.125)
MANTISSA_ULPS = (4, 16, 64, 256, 1024, 4096)
SWEEPS = {"float": (None,), "fixed": FIXED_FRACTIONS, "adaptive": PIXEL_FRACTIONS, "mantissa": MANTISSA_ULPS}
PRECISIONS = ("f32", "f64")


@dataclass(frozen=True)
class Point:
    """One configuration of the study: its series' name, its parameter and the options traced."""

    series: str
    parameter: float | None
    opts: Options

    @property
    def label(self) -> str:
        return self.series if self.parameter is None else f"{self.series} {self.parameter:g}"


@dataclass(frozen=True)
class Peer:
    """One point of a peer: 'embree' at N x N quads per patch, or 'povray' at a flatness."""

    kind: str
    parameter: float

    @property
    def label(self) -> str:
        return f"{self.kind} {self.parameter:g}"


def scene_size(scene) -> float:
    """The longest side of the scene's control-point box: errors are reported relative to it."""
    lo, hi = scene.bounds()
    return float(np.max(hi - lo))


def sweep_options(size: float) -> dict:
    """{criterion: the option fields at a parameter of its sweep}, for a scene of `size`."""
    return {"float": lambda p: {}, "fixed": lambda f: {"fixed_size": f * size},
            "adaptive": lambda f: {"pixel_fraction": f}, "mantissa": lambda k: {"mantissa_ulps": k}}


def points(size: float, base: Options = Options(), precisions=PRECISIONS, chosen: dict | None = None) -> list:
    """Every psrt configuration of the study, series by series: per precision the plain series, then
    (chosen: {(criterion, precision): coherence setting}, study_coherence.py) the coherence series,
    named by their setting."""
    base = base.with_(threads=1, **PLAIN)  # the plain series; a coherence series sets its own
    fields = sweep_options(size)
    out = []
    for precision in precisions:
        for coherent in (False, True) if chosen is not None else (False,):
            for criterion, sweep in SWEEPS.items():
                spec = chosen[(criterion, precision)] if coherent else None
                name = f"psrt {criterion} {precision}" + (f" {spec}" if spec else "")
                extra = settings(spec) if spec else {}
                out += [Point(name, p, base.with_(criterion=criterion, precision=precision, **extra,
                                                  **fields[criterion](p))) for p in sweep]
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
    size: tuple


def prepare_study(scene, size, view=None) -> Study:
    """Trace the float32 rays once (float criterion) and build the truth from their float64 reference."""
    view = view or view_of(scene)
    width, height = size
    origins, dirs = primary_rays(view, width, height, "f32")
    geoms = {p: prepare(scene, p) for p in PRECISIONS}
    pixel_angle = view.pixel_angle(height)
    frame = trace_rays(geoms["f32"], Options(threads=1, **PLAIN), origins, dirs, pixel_angle)
    ref = reference_frame(scene, frame, geoms["f64"])
    extent = scene_size(scene)
    position, accepted = polished_truth(scene, geoms["f64"], ref, extent)
    return Study(scene, origins, dirs, pixel_angle, Truth(ref, position, accepted, extent), view, geoms,
                 tuple(size))


def _trace(study: Study, opts: Options):
    """A trace of the study's rays (in opts' precision) with opts."""
    dtype = np.float32 if opts.precision == "f32" else np.float64
    return trace_rays(study.geometries[opts.precision], opts, study.origins.astype(dtype),
                      study.dirs.astype(dtype), study.pixel_angle)


def run_point(study: Study, point: Point, runs: int = 1) -> Score:
    """Warm up, then time `runs` traces of the point (median CPU time) and score the last."""
    _trace(study, point.opts)
    timed = [cpu_timed(lambda: _trace(study, point.opts)) for _ in range(runs)]
    frame = timed[-1][0]
    s = score(frame.hit, frame.position, frame.patch, frame.box_min, frame.box_max, study.truth)
    s.seconds = float(np.median([t for _, t in timed]))
    return s


def run_tessellation(study: Study, n: int, runs: int = 1) -> list:
    """The tessellation peer at n x n per patch: rows of its first-image and per-frame series."""
    from .study_peers import embree_scene, embree_trace, warm_up_embree
    warm_up_embree()
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
            "seconds": float(np.median([t for _, t, _ in timed])), "povray_wall_cpu": timed[-1][2]}


def run_unit(study: Study, unit, runs: int = 1):
    """One work unit of the study, on whichever process runs it: a psrt Point or a Peer point (its
    rows), or a coherence Trial (its figures, study_coherence.run_trial)."""
    if isinstance(unit, Trial):
        return run_trial(lambda opts: cpu_timed(lambda: _trace(study, opts))[1], unit)
    if isinstance(unit, Peer):
        if unit.kind == "embree":
            return run_tessellation(study, int(unit.parameter), runs)
        return [run_povray(study, unit.parameter, runs)]
    return [{"series": unit.series, "parameter": unit.parameter, **asdict(run_point(study, unit, runs))}]


def povray_left_out(scene, flatnesses) -> str | None:
    """Why the POV-Ray peer cannot run on the scene, or None."""
    from .study_povray import available, bicubic_nets
    if not flatnesses:
        return None
    if not available():
        return "povray is not installed (scripts/setup --povray)"
    return bicubic_nets(scene)[1]


def _peers(scene, tessellations, flatnesses) -> list:
    """The peers' points that can run on the scene."""
    from .study_peers import fits
    pov = povray_left_out(scene, flatnesses) is None
    return [Peer("embree", n) for n in tessellations if fits(scene, n)] + [Peer("povray", f) for f in flatnesses if pov]


def unit_count(scene, precisions=PRECISIONS, coherence=True, tessellations=(), flatnesses=()) -> int:
    """How many work units run() reports to progress, the truth's preparation included."""
    plain = len(points(scene_size(scene), precisions=precisions))
    trial_units = len(precisions) * len(SWEEPS)
    return 1 + plain + (trial_units + plain) * coherence + len(_peers(scene, tessellations, flatnesses))


def _execute(study: Study, units: list, runs: int, client, progress) -> list:
    """[(result, contended or None)] of the units in their order: here, or on the client's workers
    (study_distributed.py: timed, one at a time per worker, `contended` from the worker's times)."""
    if client is not None:
        from .study_distributed import run_units
        return run_units(study.scene, study.size, units, runs, client, progress)
    out = []
    for unit in units:
        out.append((run_unit(study, unit, runs), None))
        if progress is not None:
            progress(unit.label)
    return out


def _flagged(row: dict, contended: bool) -> dict:
    """The row of a unit run on a worker with its contention flag: the worker's (distributed.Timed),
    or for POV-Ray the flag of povray's own phases (it idles outside them)."""
    if row.get("povray_wall_cpu"):
        from .distributed import Timed
        contended = Timed(None, *row["povray_wall_cpu"]).contended
    return {**row, "contended": contended}


def run(scene, size, base: Options = Options(), *, precisions=PRECISIONS, coherence=True, runs=1,
        tessellations=(), flatnesses=(), progress=None, client=None, candidates=CANDIDATES,
        rounds=ROUNDS) -> dict:
    """The study as a JSON-ready dict: the truth's figures, the coherence trials (study_coherence.py;
    None without coherence) and every point's score, series by series; progress(label) after each work
    unit (and once, with None, after the truth); tessellations: the peer's N.
    A peer point's row has the same fields; its `inside` is None (a triangle hit has no box).
    client: a dask.distributed Client whose workers run every work unit (study_distributed.py; each
    row and trial then says whether its worker's core was contended)."""
    study = prepare_study(scene, size)
    if progress is not None:
        progress(None)
    truth = study.truth
    chosen, tried = None, None
    if coherence:
        done = _execute(study, trials(sweep_options(truth.size), precisions, base, candidates, rounds), 1,
                        client, progress)
        tried = [t if contended is None else {**t, "contended": contended} for t, contended in done]
        chosen = {(t["criterion"], t["precision"]): t["chosen"] for t in tried}
    rows = []
    for out, contended in _execute(study, points(truth.size, base, precisions, chosen)
                                   + _peers(scene, tessellations, flatnesses), runs, client, progress):
        rows += out if contended is None else [_flagged(row, contended) for row in out]
    from .study_peers import fits
    return {"size": list(size), "scene_size": truth.size, "rays": int(truth.ref.hit.size),
            "reference_hits": int(truth.ref.hit.sum()), "truth_accepted": int(truth.accepted.sum()),
            "float32_floor": truth.floor, "runs": runs,
            "coherence": None if tried is None else {"candidates": list(candidates), "rounds": rounds,
                                                     "trials": tried},
            "tessellations_left_out": [n for n in tessellations if not fits(scene, n)],
            "povray_left_out": povray_left_out(scene, flatnesses), "timing": "cpu, one render thread",
            "points": rows}
