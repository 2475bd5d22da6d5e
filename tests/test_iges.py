"""IGES import through pyiges: the impeller acceptance model, conversions checked against IGES."""
import math
import time
from pathlib import Path

import numpy as np
import pytest

pyiges = pytest.importorskip("pyiges")
from pyiges import examples  # noqa: E402

from tracer.errors import SceneError  # noqa: E402
from tracer.formats.iges import load_iges  # noqa: E402
from tracer.nurbs import CircleParam, bezier_surface_point  # noqa: E402
from tracer.scene import load_scene  # noqa: E402
from tracer.trim import inside  # noqa: E402

IMPELLER = Path(examples.impeller)


@pytest.fixture(scope="module")
def impeller():
    t0 = time.perf_counter()
    model = load_iges(IMPELLER)
    print(f"\nimpeller.igs: load_iges {time.perf_counter() - t0:.2f} s")
    return model


@pytest.fixture(scope="module")
def doc():
    return {e.sequence_number: e for e in pyiges.read(str(IMPELLER))}


def test_impeller_counts(impeller):
    r = impeller.report
    assert r["entities"][128] == 247 and r["entities"][144] == 277 and r["entities"][120] == 30
    assert r["surfaces"] == 277 and len(impeller.surfaces) == 277
    assert r["counts"]["converted"] == {144: 277}
    assert r["counts"]["consumed"][128] == 247 and r["counts"]["consumed"][120] == 30
    assert r["counts"]["consumed"][142] == 279
    assert r["unsupported"] == {} and r["failed"] == []
    # every directory entry lands in exactly one bucket
    assert sum(sum(c.values()) for c in r["counts"].values()) == r["directory_entries"] == 4615
    assert r["tolerance"] == 1e-8 and r["units"] == "MM" and r["system"] == "SolidWorks 2010"
    kinds = {}
    for s in impeller.surfaces:
        kinds[s.info.entity["surface_type"]] = kinds.get(s.info.entity["surface_type"], 0) + 1
        assert s.info.entity["type"] == 144 and s.info.entity["de"] % 2 == 1
    assert kinds == {128: 247, 120: 30}
    # 87 outer boundaries are the parameter rectangle itself and are dropped as loops
    assert r["outer_loop_is_domain"] == 87 and r["trimmed"] == 190
    assert sum(len(s.loops) for s in impeller.surfaces) == 277 - 87 + 2


def test_impeller_scene(impeller):
    t0 = time.perf_counter()
    sc = load_scene(IMPELLER)
    print(f"\nimpeller.igs: load_scene {time.perf_counter() - t0:.2f} s, {sc.n_patches} patches, "
          f"{sc.trims.n_segments} trim segments")
    assert len(sc.surfaces) == 277 and sc.n_patches == sum(s.patch_count for s in sc.surfaces)
    assert np.all(np.diff(sc.patch_surface) >= 0) and sc.patch_surface.min() == 0
    assert sc.trims.has_trim.sum() == 190
    f = sc.surfaces[10]
    assert sc.patch_surface[f.first_patch] == 10 and f.entity["type"] == 144
    assert sc.import_report[str(IMPELLER)]["surfaces"] == 277
    # patch domains lie inside their surface's domain
    for p in range(0, sc.n_patches, 7):
        d, dom = sc.patch_domain[p], sc.surfaces[sc.patch_surface[p]].domain
        assert dom[0] <= d[0] < d[1] <= dom[1] and dom[2] <= d[2] < d[3] <= dom[3]


def test_bspline_surfaces_match_iges_data(impeller, doc):
    """Bezier patches of each 128 reproduce the B-spline defined by pyiges' knots/weights/points."""
    rng = np.random.default_rng(0)
    for fs in impeller.surfaces[::9]:
        if fs.info.entity["surface_type"] != 128:
            continue
        e = doc[fs.info.entity["surface_de"]]
        s = fs.surface
        assert np.array_equal(s.knots_u, e.knot1) and np.array_equal(s.knots_v, e.knot2)
        assert np.array_equal(s.points[..., :3].reshape(-1, 3), e._cp)
        assert np.array_equal(s.points[..., 3].ravel(), e.weights)
        net = s.bezier_patches()
        for pts, d in zip(net.points, net.domains):
            a, b = rng.uniform(size=2)
            got = bezier_surface_point(pts.reshape(s.degree_v + 1, s.degree_u + 1, 4), a, b)
            want = s.evaluate(d[0] + a * (d[1] - d[0]), d[2] + b * (d[3] - d[2]))
            assert np.allclose(got, want, 0, 1e-11)


def test_revolutions_match_iges_definition(impeller, doc):
    """S(u, theta) = generatrix point turned right-handed about the axis line by theta."""
    rng = np.random.default_rng(1)
    n = 0
    for fs in impeller.surfaces:
        if fs.info.entity["surface_type"] != 120:
            continue
        p = doc[fs.info.entity["surface_de"]].parameters[0]
        axis, gen = doc[int(p[1])].coordinates, doc[int(p[2])].coordinates
        a0, a1 = float(p[3]), float(p[4])
        assert fs.info.entity["angle_v"] == [a0, a1] and "angle_u" not in fs.info.entity
        d = (axis[1] - axis[0]) / np.linalg.norm(axis[1] - axis[0])
        circ = CircleParam.for_sweep(a0, a1)
        for u, th in rng.uniform([0, a0], [1, a1], (10, 2)):
            c = gen[0] + u * (gen[1] - gen[0]) - axis[0]
            x = c - d * (d @ c)
            want = axis[0] + d * (d @ c) + x * math.cos(th) + np.cross(d, x) * math.sin(th)
            got = fs.surface.evaluate(u, float(circ.param(th)))
            assert np.allclose(got, want, 0, 1e-10 * max(1.0, np.abs(want).max()))
        n += 1
    assert n == 30


def test_revolution_trims_follow_the_angle_map(impeller, doc):
    """Points just either side of an IGES p-curve (in angle space) classify differently."""
    from tracer.formats.iges import _Converter  # the converter's own curve reading
    rng = np.random.default_rng(2)
    checked = 0
    trimmed = [fs for fs in impeller.surfaces
               if fs.info.entity["surface_type"] == 120 and fs.loops]
    assert trimmed
    for fs in trimmed[:6]:
        tri = __import__("tracer.trim", fromlist=["build_trimset"]).build_trimset([fs.loops])
        p = doc[fs.info.entity["de"]].parameters[0]
        conv = _Converter(doc.values(), {}, ",", {}, "x")
        circ = CircleParam.for_sweep(*fs.surface.domain[2:])
        bptr = int(doc[int(p[4])].parameters[0][3])
        for seg in conv.param_curve(bptr):
            if np.all(seg[:, 0] == seg[0, 0]) or np.all(seg[:, 1] == seg[0, 1]):
                continue  # lines map exactly; test the curved ones
            from tracer.trim import evaluate_segment
            s = rng.uniform(0.05, 0.95, 3)
            xy, dxy = evaluate_segment(seg, s, derivative=True)
            for (u, th), (du, dth) in zip(xy, dxy):
                # normal in (u, t) space of the mapped curve, step 1e-8
                tu, tt = du, circ.dparam(th) * dth
                nrm = np.array([-tt, tu]) / math.hypot(tu, tt) * 1e-8
                t = float(circ.param(th))
                sides = {inside(tri, 0, u + k * nrm[0], t + k * nrm[1]) for k in (-1, 1)}
                assert sides == {True, False}
                checked += 1
    assert checked > 20


def test_boundary_deviation_is_measured():
    t0 = time.perf_counter()
    model = load_iges(IMPELLER, measure_gaps=True)
    r = model.report
    print(f"\nimpeller.igs: widest distance between a face edge S(B(t)) and its model-space "
          f"curve {r['boundary_deviation_max']:.3g} {r['units']} (boundary DE "
          f"{r['boundary_deviation_de']}); modelling tolerance {r['tolerance']:g}; "
          f"widest p-curve gap closed {r['trim_widest_gap_rel']:.2g} of the parameter range; "
          f"{time.perf_counter() - t0:.1f} s")
    assert r["boundaries_measured"] == 279
    assert 0 < r["boundary_deviation_max"] < 0.05   # the file's p-curves are this loose


def test_unsupported_entities_are_reported(tmp_path):
    """A trimmed surface relabelled as 143 is counted as unsupported, its parts as orphans."""
    lines = IMPELLER.read_text(encoding="latin-1").splitlines()
    de = next(i for i, l in enumerate(lines) if l[72] == "D" and l[:8].strip() == "144")
    for i in (de, de + 1):
        lines[i] = "     143" + lines[i][8:]
    path = tmp_path / "edited.igs"
    path.write_text("\n".join(lines) + "\n", encoding="latin-1")
    r = load_iges(path).report
    assert r["surfaces"] == 276 and r["unsupported"] == {143: 1}
    assert r["counts"]["orphan"][128] == 1 and r["counts"]["orphan"][142] == 1
    assert sum(sum(c.values()) for c in r["counts"].values()) == 4615


def test_not_iges(tmp_path):
    bad = tmp_path / "x.igs"
    bad.write_text("hello\n")
    with pytest.raises(SceneError, match=r"x.igs:1: not an IGES line"):
        load_iges(bad)
    with pytest.raises(SceneError, match="file not found"):
        load_iges(tmp_path / "missing.igs")
