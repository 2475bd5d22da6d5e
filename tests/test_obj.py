"""OBJ free-form reader: round trips, Bezier and B-spline forms, trims, scenes, every error."""
import json
import random
import time
from pathlib import Path

import numpy as np
import pytest

from tracer.errors import SceneError
from tracer.formats.obj import dumps_obj, load_obj, parse_obj
from tracer.nurbs import NurbsCurve, NurbsSurface, bezier_surface_point
from tracer.revolution import circle_arc
from tracer.scene import load_scene, scene_from_dict
from tracer.trim import inside
from mutate import mutate

SAMPLES = Path(__file__).resolve().parents[1] / "sample_models"

QUAD = """v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
"""
BILINEAR = QUAD + "cstype bezier\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nend\n"
# a hole: a B-spline circle in parameter space (vp 5..13) on the bilinear patch
CIRCLE_VP = "".join(f"vp {float(u)!r} {float(v)!r} {float(w)!r}\n" for u, v, w in
                    circle_arc((0.5, 0.5), 0.25, 0, 2 * np.pi)[0].points)
HOLE = (QUAD + CIRCLE_VP + "cstype rat bspline\ndeg 2\ncurv2 1 2 3 4 5 6 7 8 9\n"
        "parm u 0 0 0 1 1 2 2 3 3 4 4 4\nend\n"
        "cstype bezier\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nhole 0 4 1\nend\n")


def random_model(rng, n=3, trims=True):
    out = []
    for k in range(n):
        p, q = int(rng.integers(1, 4)), int(rng.integers(1, 4))
        nu, nv = p + int(rng.integers(1, 4)), q + int(rng.integers(1, 4))
        ku = np.concatenate([[0] * (p + 1), np.sort(rng.uniform(0, 1, nu - p - 1)), [1] * (p + 1)])
        kv = np.concatenate([[0] * (q + 1), np.sort(rng.uniform(0, 1, nv - q - 1)), [1] * (q + 1)])
        rational = k % 2 == 0
        pts = np.concatenate([rng.normal(size=(nv, nu, 3)),
                              rng.uniform(0.2, 5, (nv, nu, 1)) if rational else np.ones((nv, nu, 1))],
                             2)
        s = NurbsSurface(p, q, ku, kv, pts, (0.0, 1.0, float(kv[q + 1] / 2 if nv > q + 1 else 0), 1.0))
        loops = []
        if trims:
            c, _ = circle_arc((0.5, 0.6), 0.2, 0, 2 * np.pi)
            tri = [NurbsCurve(1, [0, 0, 1, 1], [[0.1, 0.65, 1], [0.9, 0.65, 1]]),
                   NurbsCurve(1, [0, 0, 1, 1], [[0.9, 0.65, 1], [0.5, 0.95, 1]]),
                   NurbsCurve(1, [0, 0, 1, 1], [[0.5, 0.95, 1], [0.1, 0.65, 1]])]
            loops = [("trim", [(t, 0.0, 1.0) for t in tri]),
                     ("hole", [(NurbsCurve(2, c.knots, c.points), float(c.knots[0]),
                                float(c.knots[-1]))])][: 1 + k % 2]
        out.append((f"s{k}", s, loops))
    return out


def test_round_trip_is_exact():
    rng = np.random.default_rng(0)
    model = random_model(rng, 6)
    text = dumps_obj(model, "round trip")
    back = parse_obj(text, "rt.obj")
    assert len(back.surfaces) == 6
    for (name, s, loops), fs in zip(model, back.surfaces):
        t = fs.surface
        assert fs.info.name == name
        assert (t.degree_u, t.degree_v) == (s.degree_u, s.degree_v)
        for a, b in [(t.knots_u, s.knots_u), (t.knots_v, s.knots_v), (t.points, s.points)]:
            assert np.array_equal(a, b)
        assert t.domain == s.domain and t.rational == s.rational
        assert [k for k, _ in fs.curves] == [k for k, _ in loops]
        for (_, got), (_, want) in zip(fs.curves, loops):
            for (c1, a1, b1), (c2, a2, b2) in zip(got, want):
                assert np.array_equal(c1.points, c2.points) and np.array_equal(c1.knots, c2.knots)
                assert (a1, b1) == (a2, b2)
    assert dumps_obj([(f.info.name, f.surface, f.curves) for f in back.surfaces], "round trip") == text


def test_samples_load():
    for name, rat, trims in [("sphere", True, 0), ("torus", True, 0), ("plate", False, 3)]:
        m = load_obj(SAMPLES / f"{name}.obj")
        (fs,) = m.surfaces
        assert fs.surface.rational == rat and len(fs.loops) == trims
        assert fs.info.entity == {"line": fs.info.entity["line"]} and fs.info.entity["line"] > 0
        sc = load_scene(SAMPLES / f"{name}.json")
        assert sc.objects[0].name == name and sc.objects[1].name == "floor"


def test_bezier_forms():
    # single patch, control points u fastest
    m = parse_obj(BILINEAR, "b.obj")
    s = m.surfaces[0].surface
    assert s.points[0, 1, :3].tolist() == [1, 0, 0] and s.points[1, 0, :3].tolist() == [0, 1, 0]
    # two quadratic segments in u with global breaks 0 1 3, continuation lines and comments
    text = "".join(f"v {i} {j} {i * j}\n" for j in range(2) for i in range(5))
    text += ("cstype bezier  # piecewise\ndeg 2 1\nsurf 0 3 0 1 \\\n 1 2 3 4 5 \\\n"
             " 6 7 8 9 10\nparm u 0 1 3\nparm v 0 1\nend\n")
    m = parse_obj(text, "b2.obj")
    net = m.surfaces[0].surface.bezier_patches()
    assert net.domains.tolist() == [[0, 1, 0, 1], [1, 3, 0, 1]]
    assert m.surfaces[0].info.entity["line"] == 13
    g = net.points[1].reshape(2, 3, 4)
    assert np.array_equal(g[0, :, 0], [2, 3, 4])


def test_indices_negative_and_forward():
    text = ("cstype bezier\ndeg 1 1\n" + QUAD + "surf 0 1 0 1 -4 -3 -2 -1\nend\n")
    m = parse_obj(text, "n.obj")
    assert m.surfaces[0].surface.points[1, 1, :3].tolist() == [1, 1, 0]
    # a trim may name a curv2 defined later in the file
    tail = HOLE.split("cstype bezier\n")
    fwd = QUAD + CIRCLE_VP + "cstype bezier\n" + tail[1] + \
        "cstype rat bspline\ndeg 2\ncurv2 1 2 3 4 5 6 7 8 9\nparm u 0 0 0 1 1 2 2 3 3 4 4 4\nend\n"
    m = parse_obj(fwd, "f.obj")
    assert [l.kind for l in m.surfaces[0].loops] == ["hole"]


def test_weights_ignored_for_non_rational_types():
    text = "v 0 0 0 2\nv 1 0 0\nv 0 1 0\nv 1 1 0 3\ncstype bezier\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nend\n"
    s = parse_obj(text, "w.obj").surfaces[0].surface
    assert not s.rational
    s = parse_obj(text.replace("cstype bezier", "cstype rat bezier"), "w.obj").surfaces[0].surface
    assert s.rational and s.points[0, 0, 3] == 2 and s.points[1, 1, 3] == 3


def test_hole_loop_and_scene_arrays(tmp_path):
    (tmp_path / "h.obj").write_text(HOLE + "o second\n" + BILINEAR)
    data = {"objects": [{"patches": [{"degree": [1, 1], "points": [[0, 0, 0]] * 4}]},
                        {"file": "h.obj", "transform": [2, 0, 0, 1, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]}]}
    sc = scene_from_dict(data, "s.json", str(tmp_path))
    assert sc.n_patches == 3 and sc.patch_surface.tolist() == [-1, 0, 1]
    assert sc.patch_surface.dtype == np.int32 and sc.patch_domain.dtype == np.float64
    assert sc.patch_domain.tolist() == [[0, 1, 0, 1]] * 3
    assert [s.name for s in sc.surfaces] == ["surf@21", "second"]
    assert [(s.first_patch, s.patch_count, s.object) for s in sc.surfaces] == [(1, 1, 1), (2, 1, 1)]
    assert sc.surfaces[0].trimmed and not sc.surfaces[1].trimmed
    assert sc.trims.has_trim.tolist() == [True, False] and sc.trims.start_inside.tolist() == [True, False]
    assert not inside(sc.trims, 0, 0.5, 0.5) and inside(sc.trims, 0, 0.1, 0.1)
    assert sc.points[4].tolist() == [1, 0, 0, 1]   # transformed, weight kept
    assert sc.patch_line.tolist() == [-1, 21, 31]
    assert sc.import_report["h.obj"]["surfaces"] == 2
    bare = load_scene(tmp_path / "h.obj")
    assert bare.n_patches == 2 and bare.objects[0].name == "h" and bare.trims.n_surfaces == 2


def test_rational_transform_keeps_weights(tmp_path):
    (tmp_path / "sphere.obj").write_text((SAMPLES / "sphere.obj").read_text())
    m = [1, 0, 0, 5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    sc = scene_from_dict({"objects": [{"file": "sphere.obj", "transform": m}]}, "s.json", str(tmp_path))
    rng = np.random.default_rng(1)
    for p in range(sc.n_patches):
        grid = sc.points[sc.point_start[p]:sc.point_start[p + 1]].reshape(3, 3, 4)
        for st in rng.uniform(size=(10, 2)):
            q = bezier_surface_point(grid, *st) - [5, 0, 0]
            assert abs(np.linalg.norm(q) - 1) < 4e-15
    assert sc.rational.all() and sc.surfaces[0].kind == "rational bspline"


def test_thousand_surfaces_load_time(tmp_path):
    """1,000 bicubic B-spline surfaces (9 patches each, a third trimmed): measure the load."""
    rng = np.random.default_rng(2)
    knots = np.array([0, 0, 0, 0, 1 / 3, 2 / 3, 1, 1, 1, 1])
    c, _ = circle_arc((0.5, 0.5), 0.2, 0, 2 * np.pi)
    hole = [("hole", [(NurbsCurve(2, c.knots, c.points), float(c.knots[0]), float(c.knots[-1]))])]
    model = []
    for k in range(1000):
        pts = np.concatenate([rng.normal(size=(6, 6, 3)) + [k % 40 * 3, k // 40 * 3, 0],
                              np.ones((6, 6, 1))], 2)
        model.append((f"s{k}", NurbsSurface(3, 3, knots, knots, pts), hole if k % 3 == 0 else []))
    path = tmp_path / "many.obj"
    path.write_text(dumps_obj(model))
    t0 = time.perf_counter()
    sc = load_scene(path)
    elapsed = time.perf_counter() - t0
    print(f"\n1,000-surface OBJ ({path.stat().st_size / 1e6:.1f} MB, {sc.n_patches} patches): "
          f"load_scene {elapsed:.2f} s (target < 2 s)")
    assert sc.n_patches == 9000 and len(sc.surfaces) == 1000 and sc.trims.has_trim.sum() == 334


BASE = QUAD + "cstype bezier\ndeg 1 1\n"


@pytest.mark.parametrize("text,line,words", [
    ("v 0 0\n", 1, "v: expected 3 to 4 numbers, got 2"),
    ("v 0 0 x\n", 1, "v: 'x' is not a number"),
    ("v 0 0 nan\n", 1, "v: 'nan' is not finite"),
    ("v 0 0 0 0\n", 1, "v: weight must be > 0, got 0"),
    ("vp 0 0 -1\n", 1, "vp: weight must be > 0, got -1"),
    ("vp 0 0 1 1\n", 1, "vp: expected 1 to 3 numbers, got 4"),
    (BASE + "surf 0 1 0 1 1 2 3 a\n", 7, "surf: 'a' is not an integer index"),
    (BASE + "surf 0 1 0 1 0 1 2 3\n", 7, "index 0 is invalid"),
    (BASE + "surf 0 1 0 1 -5 1 2 3\n", 7, "relative index -5 reaches before the first (only 4"),
    (BASE + "surf 0 1 0 1 1 2 3 4/1/2/3\n", 7, "bad reference '4/1/2/3'"),
    (BASE + "surf 0 1 0 1 1 2 3 4/x\n", 7, "bad reference '4/x'"),
    ("cstype rat\n", 1, "cstype: expected [rat] followed by one type"),
    ("cstype bmatrix\n", 1, "cstype bmatrix is not supported"),
    ("cstype rat taylor\n", 1, "cstype taylor is not supported"),
    ("cstype nurbs\n", 1, "cstype: unknown type 'nurbs'"),
    ("deg 1 2 3\n", 1, "deg: expected 1 or 2 integers, got 3"),
    ("deg 0\n", 1, "deg: '0' is not a degree in 1..20"),
    ("deg 21 1\n", 1, "deg: '21' is not a degree"),
    (QUAD + "deg 1 1\nsurf 0 1 0 1 1 2 3 4\n", 6, "surf: no 'cstype' given before it"),
    (QUAD + "cstype bezier\nsurf 0 1 0 1 1 2 3 4\n", 6, "surf: no 'deg' given before it"),
    (QUAD + "cstype bezier\ndeg 1\nsurf 0 1 0 1 1 2 3 4\n", 7, "surf: needs two degrees"),
    (BASE + "surf 0 1 0 1\n", 7, "expected 's0 s1 t0 t1' and control point references"),
    (BASE + "surf 0 1 0 1 1 2 3 4\nsurf 0 1 0 1 1 2 3 4\n", 8,
     "'surf' before the 'end' of the surf at line 7"),
    (BASE + "surf 0 1 0 1 1 2 3 4\n", 7, "surf at line 7 has no 'end'"),
    ("vp 0 0\ncstype bezier\ndeg 1\ncurv2 1\n", 4, "curv2: expected at least 2 parameter vertex"),
    ("parm u 0 1\n", 1, "'parm' outside a surf or curv2 body"),
    (BASE + "surf 0 1 0 1 1 2 3 4\nparm w 0 1\n", 8, "parm: expected 'u' or 'v'"),
    (BASE + "surf 0 1 0 1 1 2 3 4\nparm u 0\n", 8, "parm u: expected 2 to"),
    ("vp 0 0\nvp 1 1\ncstype bezier\ndeg 1\ncurv2 1 2\nparm v 0 1\n", 6,
     "parm v: a curv2 has only a u direction"),
    ("trim 0 1 1\n", 1, "'trim' outside a surf body"),
    (BASE + "surf 0 1 0 1 1 2 3 4\nhole 0 1\n", 8, "hole: expected triples 'u0 u1 curv2'"),
    ("end\n", 1, "'end' without a surf or curv2 to close"),
    (QUAD + "f 1 2 3\n", 5, "polygon meshes are not supported yet (statement 'f')"),
    ("l 1 2\n", 1, "polygon meshes are not supported yet (statement 'l')"),
    ("p 1\n", 1, "polygon meshes are not supported yet"),
    ("fo 1 2 3\n", 1, "polygon meshes are not supported yet"),
    ("bmat u 1 0 0 1\n", 1, "'bmat' is not supported"),
    ("step 1 1\n", 1, "'step' is not supported"),
    ("ctech cparm 1\n", 1, "'ctech' is not supported"),
    ("stech cparma 1 1\n", 1, "'stech' is not supported"),
    (BASE + "surf 0 1 0 1 1 2 3 4\nscrv 0 1 1\n", 8, "'scrv' is not supported"),
    (BASE + "surf 0 1 0 1 1 2 3 4\nsp 1\n", 8, "'sp' is not supported"),
    ("con 1 0 1 1 2 0 1 1\n", 1, "'con' is not supported"),
    ("curv 0 1 1 2\n", 1, "'curv' is not supported"),
    ("frobnicate\n", 1, "unknown statement 'frobnicate'"),
    (QUAD + "cstype bspline\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nend\n", 7,
     "surf: B-spline needs 'parm u'"),
    (BASE + "surf 0 1 0 1 1 2 3 9\nend\n", 7, "surf: v 9 does not exist (4 defined)"),
    (BASE + "surf 0 1 0 1 1 2 3\nend\n", 7, "surf: 3 control points, but the degrees 1 1"),
    (BASE + "surf 0 2 0 1 1 2 3 4\nend\n", 7, "parameter range [0, 2] leaves the knot domain"),
    (QUAD + "cstype bspline\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nparm u 0 0 1 1\nparm v 0 1 0 1\nend\n",
     7, "v knot vector: knots must not decrease"),
    (BASE + "surf 0 1 0 1 1 2 3 4\ntrim 0 1 1\nend\n", 8, "curv2 1 does not exist (0 defined)"),
    ("vp 0 0\nvp 1 1\ncstype bezier\ndeg 1\ncurv2 1 5\nend\n" + BASE.replace("cstype bezier\ndeg 1 1\n", "")
     + "deg 1 1\nsurf 0 1 0 1 1 2 3 4\ntrim 0 1 1\nend\n", 5, "curv2: vp 5 does not exist"),
    ("vp 0\nvp 1 1\ncstype bezier\ndeg 1\ncurv2 1 2\nend\n" + QUAD +
     "deg 1 1\nsurf 0 1 0 1 1 2 3 4\ntrim 0 1 1\nend\n", 5,
     "curv2: control point 1 (vp at line 1) has no v coordinate"),
    ("vp 0 0\nvp 1 1\nvp 1 0\ncstype bezier\ndeg 1\ncurv2 1 2 3\nend\n" + QUAD +
     "deg 1 1\nsurf 0 1 0 1 1 2 3 4\ntrim 0 1 1\nend\n", 6, "curv2: 3 control points, but degree 1"),
    ("vp 0 0\nvp 1 1\ncstype bspline\ndeg 1\ncurv2 1 2\nparm u 0 1 0 1\nend\n" + QUAD +
     "cstype bezier\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\ntrim 0 1 1\nend\n", 6,
     "curv2: knot vector: knots must not decrease"),
    ("vp 0 0\nvp 1 1\ncstype bezier\ndeg 1\ncurv2 1 2\nend\n" + QUAD +
     "deg 1 1\nsurf 0 1 0 1 1 2 3 4\ntrim 0.5 0.5 1\nend\n", 13, "trim: empty parameter range 0.5 0.5"),
    ("vp 0 0\nvp 1 1\ncstype bezier\ndeg 1\ncurv2 1 2\nend\n" + QUAD +
     "deg 1 1\nsurf 0 1 0 1 1 2 3 4\ntrim 0 2 1\nend\n", 13, "trim: curv2 1: curve: parameter range"),
    ("vp 0.1 0.1\nvp 0.9 0.9\ncstype bezier\ndeg 1\ncurv2 1 2\nend\n" + QUAD +
     "deg 1 1\nsurf 0 1 0 1 1 2 3 4\ntrim 0 1 1\nend\n", 13, "trim: trimming loop is not closed"),
])
def test_errors_name_file_and_line(tmp_path, text, line, words):
    path = tmp_path / "e.obj"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_obj(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}:{line}: "), msg
    assert words in msg, msg


def test_error_in_referenced_obj_names_obj(tmp_path):
    (tmp_path / "bad.obj").write_text(QUAD + "f 1 2 3\n")
    with pytest.raises(SceneError) as info:
        scene_from_dict({"objects": [{"file": "bad.obj"}]}, "s.json", str(tmp_path))
    assert (info.value.path, info.value.line) == (str(tmp_path / "bad.obj"), 5)
    (tmp_path / "empty.obj").write_text("# nothing\nv 0 0 0\n")
    with pytest.raises(SceneError, match="no free-form surfaces in the file"):
        load_scene(tmp_path / "empty.obj")


def test_ignored_statements_are_counted():
    text = "mtllib a.mtl\ng grp\nusemtl red\ns 1\nvt 0 0\nvn 0 0 1\n" + BILINEAR
    m = parse_obj(text, "i.obj")
    assert m.report["ignored"] == {"mtllib": 1, "g": 1, "usemtl": 1, "s": 1, "vt": 1, "vn": 1}
    assert m.surfaces[0].info.name == "grp"


def test_mutations_raise_only_scene_errors(tmp_path):
    """Random damage to a valid OBJ must end in a model or a SceneError, nothing else."""
    rng = random.Random(99)
    base = HOLE
    alphabet = "0123456789 -./\n#\\abceghimnoprstuvx"
    for trial in range(300):
        text = mutate(base, rng, alphabet)
        try:
            parse_obj(text, "m.obj")
        except SceneError:
            pass


def test_scene_json_accepts_obj(tmp_path):
    (tmp_path / "p.obj").write_text(BILINEAR)
    (tmp_path / "s.json").write_text(json.dumps({"objects": [{"file": "p.obj", "name": "plate"}]}))
    sc = load_scene(tmp_path / "s.json")
    assert sc.objects[0].name == "plate" and sc.objects[0].source == "p.obj"
    assert sc.surfaces[0].source == str(tmp_path / "p.obj")
