"""IGES acceptance (issue 4b), headless: pyiges's impeller.igs renders with its trims.

One small render with trims and one without (default framing, 96x96). Trimming may only take
hits away: a hit kept by the trims is the untrimmed render's hit exactly, a hit the trims cut
leaves the pixel empty or shows something farther, and no hit of the trimmed render lies in a
trimmed-away region (tracer.trim.inside, the reference parity test, on the reported uv).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

pyiges = pytest.importorskip("pyiges")

from tracer.geometry import prepare  # noqa: E402
from tracer.options import Options  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import load_scene  # noqa: E402
from tracer.trim import inside  # noqa: E402
from viewer.surface_info import hit_surface, import_rows, scene_counts  # noqa: E402

IMPELLER = Path(pyiges.__file__).resolve().parent / "examples" / "impeller.igs"
SIZE = (96, 96)
LOAD_LIMIT_S = 10.0       # "loads in a few seconds"
ON_CURVE = 1e-9           # relative nudge: a uv this close to a trim curve may fall either way


@pytest.fixture(scope="module")
def impeller():
    """The scene, its trimmed and untrimmed frames, and how long each step took."""
    if not IMPELLER.is_file():
        pytest.skip(f"pyiges has no examples/impeller.igs ({IMPELLER})")
    times = {}
    t0 = time.perf_counter()
    scene = load_scene(IMPELLER)
    times["load_scene"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    geom = prepare(scene, "f32")
    times["prepare_f32"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    render(scene, Options(), size=(2, 2), geometry=geom)  # compile, or load from the numba cache
    times["kernel_warm_up"] = time.perf_counter() - t0
    frames = {}
    for trims in (True, False):
        t0 = time.perf_counter()
        frames[trims] = render(scene, Options(trims=trims), size=SIZE, geometry=geom)
        times[f"render_trims_{'on' if trims else 'off'}"] = time.perf_counter() - t0
    print(f"\nimpeller.igs {SIZE[0]}x{SIZE[1]}: " + ", ".join(f"{k} {v:.2f} s" for k, v in times.items())
          + f"; hits {int(frames[True].hit.sum())} trimmed, {int(frames[False].hit.sum())} untrimmed")
    return scene, frames, times


def _surface(scene, frame) -> np.ndarray:
    return np.where(frame.patch >= 0, scene.patch_surface[np.maximum(frame.patch, 0)], -1)


def _kept(scene, frame) -> np.ndarray:
    """(H, W) bool: the pixel's hit is in its surface's kept region (True for misses)."""
    out = np.ones(frame.hit.shape, bool)
    surf = _surface(scene, frame)
    for y, x in zip(*np.nonzero(frame.hit)):
        out[y, x] = inside(scene.trims, int(surf[y, x]), *frame.uv[y, x])
    return out


def _on_curve(scene, surface: int, u: float, v: float) -> bool:
    """Does a nudge of ON_CURVE (relative to the domain) change the inside test at (u, v)?"""
    d = scene.surfaces[surface].domain
    du, dv = ON_CURVE * (d[1] - d[0]), ON_CURVE * (d[3] - d[2])
    here = inside(scene.trims, surface, u, v)
    return any(inside(scene.trims, surface, u + a, v + b) != here for a, b in ((du, 0), (-du, 0), (0, dv), (0, -dv)))


def test_impeller_loads_with_its_import_report(impeller):
    scene, _, times = impeller
    assert times["load_scene"] < LOAD_LIMIT_S, f"loading took {times['load_scene']:.1f} s"
    counts = scene_counts(scene)
    assert counts["surfaces"] == 277 and counts["trimmed_surfaces"] == 190
    assert counts["surface_patches"] == counts["patches"] == scene.n_patches and counts["plain"] == 0
    assert counts["trimmed"] == int(scene.patch_has_trim.sum()) > 0
    rows = dict(import_rows(scene.import_report[str(IMPELLER)]))
    assert rows["converted"] == "277 x 144" and rows["unsupported"] == "none"
    assert rows["tolerance"].startswith("1e-08") and rows["units"] == "MM"


def test_trims_cut_away_surface(impeller):
    scene, frames, _ = impeller
    on, off = frames[True], frames[False]
    assert on.hit.sum() > 0, "the trimmed render shows nothing"
    assert on.hit.sum() < off.hit.sum(), "trimming took no pixel away"
    kept_on = _kept(scene, on)
    surf = _surface(scene, on)
    stray = [(int(x), int(y)) for y, x in zip(*np.nonzero(on.hit & ~kept_on))
             if not _on_curve(scene, int(surf[y, x]), *on.uv[y, x])]
    assert stray == [], f"trimmed-away surface left in the trimmed render at pixels {stray[:10]}"
    # Cut-outs: pixels whose untrimmed hit is trimmed away now show nothing or something farther.
    cut = off.hit & ~_kept(scene, off)
    assert cut.sum() > 0.1 * off.hit.sum(), "the untrimmed view shows hardly any trimmed-away surface"
    both = on.hit & off.hit
    # Closer by more than a hit box: where patches meet, either side's box may report the crossing.
    box_t = (off.box_max - off.box_min).sum(axis=-1) / np.linalg.norm(off.ray_dir, axis=-1)
    assert not np.any(both & (on.t < off.t - box_t)), "a trimmed hit is closer than the untrimmed one"
    emptied = cut & ~on.hit
    assert emptied.sum() > 0, "no cut-out: every trimmed-away hit has something behind it"


def test_hits_kept_by_the_trims_are_unchanged(impeller):
    """Where the untrimmed hit is in the kept region, it is the closest kept hit: same patch, and the
    same hit box or its neighbour on the grid. (Which of two boxes that both hold the crossing is
    accepted first depends on the hits other patches found before: trims change those.)"""
    scene, frames, _ = impeller
    on, off = frames[True], frames[False]
    keep = off.hit & _kept(scene, off)
    assert keep.sum() > 0
    assert np.array_equal(on.patch[keep], off.patch[keep])
    size = off.box_max[keep] - off.box_min[keep]
    assert np.all(np.abs(on.position[keep] - off.position[keep]) <= size)
    assert np.mean(np.all(on.box_min[keep] == off.box_min[keep], axis=-1)) > 0.99


def test_inspector_names_the_iges_entity_of_a_trimmed_face(impeller):
    scene, frames, _ = impeller
    on = frames[True]
    surf = _surface(scene, on)
    trimmed = on.hit & (surf >= 0) & scene.trims.has_trim[np.maximum(surf, 0)]
    assert trimmed.any(), "no pixel of the trimmed render shows a trimmed face"
    y, x = (int(a[len(a) // 2]) for a in np.nonzero(trimmed))
    info = hit_surface(scene, int(on.patch[y, x]), on.uv[y, x])
    e = info["entity"]
    assert e["type"] == 144 and e["surface_type"] in (128, 120)
    assert info["location"].startswith(f"IGES 144 DE {e['de']}, surface {e['surface_type']} DE {e['surface_de']}")
    assert info["trimmed"] and info["inside"] and info["loops"]
    d = info["surface_domain"]
    assert d[0] <= info["uv"][0] <= d[1] and d[2] <= info["uv"][1] <= d[3]


def test_the_float64_reference_costs_a_few_times_the_float32_render(impeller):
    """Its trimmed-away parts once cost the reference millions of boxes a ray (the search could
    not tell a sub-patch near a long trimming curve was clear of it): now about twice the float32
    render's boxes, and no pixel runs out of the reference's budget."""
    from tracer.render import reference_frame
    scene, frames, _ = impeller
    frame = frames[True]
    ref = reference_frame(scene, frame)
    assert ref.effort.sum() <= 4 * frame.effort.sum(), (ref.effort.sum(), frame.effort.sum())
    assert not ref.unresolved.any()
    assert np.array_equal(ref.hit, frame.hit)
