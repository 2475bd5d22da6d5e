"""Tests for the .bpt reader and the scene loader."""
import json
import pickle
import random
from pathlib import Path

import numpy as np
import pytest

from tracer.errors import SceneError
from tracer.formats.bpt import MAX_DEGREE, load_bpt, parse_bpt
from tracer.scene import load_scene, scene_from_dict
from mutate import mutate

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "sample_models"
SHARED_MODELS = REPO.parent / "shared" / "models"

BILINEAR = "1\n1 1\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n"
FLOOR = {"patches": [{"degree": [1, 1], "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]}]}


def bpt_error(tmp_path, text, name="m.bpt") -> str:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_bpt(path)
    return str(info.value)


def scene_error(tmp_path, data, name="s.json") -> SceneError:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    return info.value


# ---- .bpt -----------------------------------------------------------------------

def test_sample_teapot_loads():
    patches = load_bpt(SAMPLES / "teapot.bpt")
    assert len(patches) == 32
    assert all((p.degree_u, p.degree_v) == (3, 3) and p.points.shape == (16, 4) for p in patches)
    assert all(not p.rational and np.all(p.points[:, 3] == 1.0) for p in patches)
    assert patches[0].line == 2 and patches[1].line == 19


@pytest.mark.skipif(not SHARED_MODELS.is_dir(), reason="../shared/models absent")
@pytest.mark.parametrize("name,count", [("teapot", 32), ("teacup", 26),
                                        ("teaspoon", 16), ("teapot-original", 28)])
def test_shared_models_load(name, count):
    patches = load_bpt(SHARED_MODELS / f"{name}.bpt")
    assert len(patches) == count


def test_point_order_and_comments():
    # degree 2 x 1: line k = j*3 + i holds P[i][j] = (i, j, 10i + j)
    lines = [f"{i} {j} {10 * i + j}  # P[{i}][{j}]" for j in range(2) for i in range(3)]
    text = "# header\n1\n\n2 1\n" + "\n".join(lines) + "\n"
    (p,) = parse_bpt(text, "x.bpt")
    assert (p.degree_u, p.degree_v, p.line) == (2, 1, 4)
    grid = p.points.reshape(2, 3, 4)  # [j, i]
    for i in range(3):
        for j in range(2):
            assert grid[j, i].tolist() == [i, j, 10 * i + j, 1.0]


def test_rational_points_keep_weights():
    (p,) = parse_bpt("1\n1 1\n0 0 0 1\n1 0 0 2\n0 1 0 0.5\n1 1 0 1\n", "r.bpt")
    assert p.rational and p.points[:, 3].tolist() == [1, 2, 0.5, 1]
    assert p.points.dtype == np.float64


def test_bpt_missing_file(tmp_path):
    with pytest.raises(SceneError, match="nope.bpt: file not found"):
        load_bpt(tmp_path / "nope.bpt")


@pytest.mark.parametrize("text,line,words", [
    ("", 1, "empty file"),
    ("# only a comment\n\n", 2, "empty file"),
    ("0\n", 1, "positive integer"),
    ("-2\n", 1, "positive integer"),
    ("2.5\n", 1, "positive integer"),
    ("1\n1\n0 0 0\n", 2, "two integers"),
    ("1\n1 x\n", 2, "two integers"),
    ("1\n0 1\n", 2, "degree 0 out of range"),
    (f"1\n1 {MAX_DEGREE + 1}\n", 2, f"degree {MAX_DEGREE + 1} out of range"),
    ("1\n1 1\n0 0\n", 3, "expected 3 or 4 numbers per control point, got 2"),
    ("1\n1 1\n0 0 0\n1 0 0 1\n", 4, "expected 3 numbers per control point"),
    ("1\n1 1\n0 0 0\n1 0 zero\n", 4, "'zero' is not a number"),
    ("1\n1 1\n0 0 0\n1 nan 0\n", 4, "not finite"),
    ("1\n1 1\n0 0 0\n1 0 inf\n", 4, "not finite"),
    ("1\n1 1\n0 0 0 1\n1 0 0 0\n", 4, "weight must be > 0, got 0"),
    ("1\n1 1\n0 0 0 1\n1 0 0 -1\n", 4, "weight must be > 0, got -1"),
    ("1\n1 1\n0 0 0\n1 0 0\n", 4, "unexpected end of file in patch 1 of 1"),
    ("2\n" + BILINEAR[2:] + "# end\n", 7, "patch 2 of 2 is missing"),
    (BILINEAR + "\n7 7 7\n", 8, "extra content after the last patch"),
])
def test_bpt_errors(tmp_path, text, line, words):
    msg = bpt_error(tmp_path, text)
    assert msg.startswith(f"{tmp_path / 'm.bpt'}:{line}: "), msg
    assert words in msg


def test_bpt_error_attributes():
    with pytest.raises(SceneError) as info:
        parse_bpt("1\n1 1\n0 0\n", "t.bpt")
    err = info.value
    assert isinstance(err, ValueError)
    assert (err.path, err.line, err.key) == ("t.bpt", 3, None)
    assert str(err) == "t.bpt:3: expected 3 or 4 numbers per control point, got 2"
    again = pickle.loads(pickle.dumps(err))
    assert (str(again), again.line) == (str(err), 3)


# ---- scenes ---------------------------------------------------------------------

def test_sample_scene():
    s = load_scene(SAMPLES / "teapot.json")
    assert s.n_patches == 33 and [o.name for o in s.objects] == ["teapot", "floor"]
    assert s.objects[0].source == "teapot.bpt" and s.objects[1].source == "inline"
    assert [m.name for m in s.materials] == ["porcelain", "floor"]
    assert s.patch_material.tolist() == [0] * 32 + [1]
    assert s.patch_line[0] == 2 and s.patch_line[-1] == -1
    assert s.image_size == (512, 512) and s.camera.fov_deg == 35
    assert [(l.type, l.radius, l.samples) for l in s.lights] == [("sphere", 0.5, 16)]
    assert [(m.reflect, m.transmit, m.ior) for m in s.materials] == [(0.1, 0.0, 1.5), (0.15, 0.0, 1.5)]
    lo, hi = s.bounds()
    assert lo[2] == 0 and hi[2] == pytest.approx(3.15)  # teapot stands on the floor at z = 0


def test_bare_bpt_scene():
    s = load_scene(SAMPLES / "teapot.bpt")
    assert s.n_patches == 32 and s.points.shape == (512, 4)
    assert [m.name for m in s.materials] == ["default"]
    assert s.objects[0].name == "teapot"
    assert s.camera is None and s.image_size is None and s.lights == []


def test_patch_order_and_arrays(tmp_path):
    (tmp_path / "two.bpt").write_text("2\n" + BILINEAR[2:] + "2 1\n" + "0 0 0\n" * 6)
    quad = {"degree": [1, 1], "points": [[0, 0, 5, 1], [1, 0, 5, 1], [0, 1, 5, 1], [1, 1, 5, 2]]}
    data = {"objects": [FLOOR, {"file": "two.bpt", "material": "red"},
                        {"patches": [quad], "name": "q"}],
            "materials": {"red": {"color": [1, 0, 0]}}}
    s = scene_from_dict(data, "s.json", str(tmp_path))
    assert s.n_patches == 4
    assert s.point_start.tolist() == [0, 4, 8, 14, 18] and s.point_start.dtype == np.int64
    assert s.degree_u.tolist() == [1, 1, 2, 1] and s.degree_v.tolist() == [1, 1, 1, 1]
    assert s.degree_u.dtype == np.int32
    assert s.rational.tolist() == [False, False, False, True]
    assert s.patch_object.tolist() == [0, 1, 1, 2]
    assert [m.name for m in s.materials] == ["red", "default"]
    assert s.patch_material.tolist() == [1, 0, 0, 1]
    assert s.patch_line.tolist() == [-1, 2, 7, -1]
    assert [(o.first_patch, o.patch_count) for o in s.objects] == [(0, 1), (1, 2), (3, 1)]
    assert [o.name for o in s.objects] == ["object0", "two", "q"]
    assert s.points[17].tolist() == [1, 1, 5, 2]


def test_transform_translation_and_scale():
    quad = {"degree": [1, 1], "points": [[0, 0, 0, 1], [1, 0, 0, 1], [0, 1, 0, 1], [1, 1, 0, 4]]}
    m = [2, 0, 0, 10,  0, 3, 0, 20,  0, 0, 4, 30,  0, 0, 0, 1]
    s = scene_from_dict({"objects": [{"patches": [quad], "transform": m}]}, "s.json", ".")
    assert s.points.tolist() == [[10, 20, 30, 1], [12, 20, 30, 1], [10, 23, 30, 1], [12, 23, 30, 4]]
    assert s.bounds()[0].tolist() == [10, 20, 30] and s.bounds()[1].tolist() == [12, 23, 30]


def test_light_centres():
    lights = [{"type": "point", "position": [1, 2, 3]},
              {"type": "sphere", "center": [4, 5, 6], "radius": 1},
              {"type": "segment", "a": [0, 0, 0], "b": [2, 4, 6]},
              {"type": "rect", "corner": [1, 1, 1], "edge1": [2, 0, 0], "edge2": [0, 4, 0],
               "intensity": 2, "color": [1, 0.5, 0]}]
    s = scene_from_dict({"objects": [FLOOR], "lights": lights}, "s.json", ".")
    assert [l.centre().tolist() for l in s.lights] == [[1, 2, 3], [4, 5, 6], [1, 2, 3], [2, 3, 1]]
    assert s.lights[0].radius is None and s.lights[1].radius == 1.0
    assert s.lights[3].intensity == 2.0 and s.lights[0].color.tolist() == [1, 1, 1]


def with_(**top):
    return {"objects": [FLOOR], **top}


def obj(**keys):
    return {"objects": [{**FLOOR, **keys}]}


@pytest.mark.parametrize("data,key,words", [
    ({"objects": [FLOOR], "camra": {}}, "camra", "unknown key (expected one of: camera, image"),
    (with_(camera={"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 30,
                   "fov": 3}), "camera.fov", "unknown key"),
    (with_(image={"width": 4, "height": 4, "depth": 1}), "image.depth", "unknown key"),
    ({"objects": [FLOOR, {**FLOOR, "tranform": []}]}, "objects[1].tranform",
     "unknown key (expected one of: file, patches, transform, material, name)"),
    (with_(materials={"m": {"colour": [1, 1, 1]}}), "materials.m.colour", "unknown key"),
    (with_(lights=[{"type": "point", "position": [0, 0, 0], "radius": 1}]), "lights[0].radius",
     "unknown key (expected one of: type, intensity, color, position)"),
    (obj(patches=[{"degree": [1, 1], "points": [[0, 0, 0]] * 4, "w": 1}]),
     "objects[0].patches[0].w", "unknown key"),
    ({"camera": {}}, None, "missing required key 'objects'"),
    ({"objects": []}, "objects", "at least one object"),
    ({"objects": [{}]}, "objects[0]", "exactly one of 'file' or 'patches'"),
    ({"objects": [{**FLOOR, "file": "a.bpt"}]}, "objects[0]", "exactly one of"),
    (with_(camera={"eye": [1, 2], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 30}),
     "camera.eye", "expected a list of 3 finite numbers, got [1, 2]"),
    (with_(camera={"eye": [0, 0, 1], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 30}),
     "camera.up", "parallel"),
    (with_(camera={"eye": [0, 0, 1], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 180}),
     "camera.fov_deg", "expected a number in (0, 180)"),
    (with_(camera={"eye": [0, 0, 1]}), "camera", "missing required key 'look_at'"),
    (with_(image={"width": 0, "height": 4}), "image.width", "integer in 1..16384"),
    (with_(image={"width": 4, "height": 16385}), "image.height", "integer in 1..16384"),
    (with_(image={"width": 4.0, "height": 4}), "image.width", "integer"),
    (with_(materials={"m": {"color": [1, 2, 0]}}), "materials.m.color[1]", "in [0, 1]"),
    (with_(materials=[]), "materials", "expected an object, got a list"),
    (with_(lights=[{"type": "spot"}]), "lights[0].type", "expected one of: point, sphere"),
    (with_(lights=[{"position": [0, 0, 0]}]), "lights[0]", "missing required key 'type'"),
    (with_(lights=[{"type": "sphere", "center": [0, 0, 0]}]), "lights[0]",
     "missing required key 'radius'"),
    (with_(lights=[{"type": "sphere", "center": [0, 0, 0], "radius": 0}]), "lights[0].radius",
     "expected a number > 0, got 0"),
    (with_(lights=[{"type": "point", "position": [0, 0, 0], "intensity": True}]),
     "lights[0].intensity", "expected a finite number, got true"),
    (with_(lights=[{"type": "rect", "corner": [0, 0, 0], "edge1": [1, 0, 0],
                    "edge2": [2, 0, 0]}]), "lights[0]", "zero area"),
    (obj(material="gold"), "objects[0].material", "undefined material 'gold' (defined: none)"),
    (obj(material=3), "objects[0].material", "expected a non-empty string"),
    (obj(transform=[1, 0, 0]), "objects[0].transform", "expected a list of 16 finite numbers"),
    (obj(transform=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1]), "objects[0].transform",
     "not affine"),
    (obj(transform=[1, 2, 3, 0, 4, 5, 6, 0, 7, 8, 9, 0, 0, 0, 0, 1]), "objects[0].transform",
     "singular"),
    ({"objects": [{"file": "teapot.stl"}]}, "objects[0].file",
     "unsupported file type '.stl' (supported: .bpt, .obj, .igs, .iges)"),
    (obj(patches=[{"degree": [2, 1], "points": [[0, 0, 0]] * 4}]),
     "objects[0].patches[0].points", "degree [2, 1] needs 6 points, got 4"),
    (obj(patches=[{"degree": [0, 1], "points": []}]), "objects[0].patches[0].degree",
     "two integers in 1..20"),
    (obj(patches=[{"degree": [1, 1], "points": [[0, 0, 0, 1]] * 3 + [[0, 0, 0]]}]),
     "objects[0].patches[0].points[3]", "expected a list of 4 finite numbers"),
    (obj(patches=[{"degree": [1, 1], "points": [[0, 0, 0, 1]] * 3 + [[0, 0, 0, -1]]}]),
     "objects[0].patches[0].points[3]", "weight must be > 0"),
    (obj(patches=[{"degree": [1, 1]}]), "objects[0].patches[0]", "missing required key 'points'"),
    (obj(patches=[]), "objects[0].patches", "at least one patch"),
    ([1, 2], None, "expected an object, got a list"),
])
def test_scene_errors(tmp_path, data, key, words):
    err = scene_error(tmp_path, data)
    assert err.path == str(tmp_path / "s.json") and err.key == key, str(err)
    assert words in str(err)
    assert str(err).startswith(f"{err.path}: {key + ': ' if key else ''}")


def test_nan_in_json_is_an_error(tmp_path):
    text = '{"objects": [{"patches": [{"degree": [1, 1], ' \
           '"points": [[0, 0, 0], [1, 0, NaN], [0, 1, 0], [1, 1, 0]]}]}]}'
    err = scene_error(tmp_path, text)
    assert err.key == "objects[0].patches[0].points[1]" and "NaN" in str(err)
    camera = {"eye": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 1}
    err = scene_error(tmp_path, json.dumps(with_(camera=camera)).replace('"fov_deg": 1', '"fov_deg": Infinity'))
    assert err.key == "camera.fov_deg"


def test_invalid_json_names_line_and_column(tmp_path):
    err = scene_error(tmp_path, '{\n  "objects": [\n    1,,\n]}')
    assert err.line == 3 and "column 7" in str(err)
    assert str(err).startswith(f"{tmp_path / 's.json'}:3: invalid JSON")


def test_duplicate_json_key(tmp_path):
    err = scene_error(tmp_path, '{"objects": [], "objects": []}')
    assert err.path == str(tmp_path / "s.json") and "duplicate key 'objects'" in str(err)


def test_missing_referenced_file(tmp_path):
    (tmp_path / "sub").mkdir()
    data = {"objects": [FLOOR, FLOOR, {"file": "sub/missing.bpt"}]}
    err = scene_error(tmp_path, data)
    assert err.key == "objects[2].file"
    assert str(tmp_path / "sub" / "missing.bpt") in str(err) and "file not found" in str(err)


def test_error_inside_referenced_bpt_names_bpt(tmp_path):
    (tmp_path / "bad.bpt").write_text("1\n1 1\n0 0 0\n1 0 0\n0 1\n1 1 0\n")
    err = scene_error(tmp_path, {"objects": [{"file": "bad.bpt"}]})
    assert (err.path, err.line) == (str(tmp_path / "bad.bpt"), 5)


def test_unsupported_scene_extension(tmp_path):
    with pytest.raises(SceneError, match=r"unsupported scene file type '\.stl'"):
        load_scene(tmp_path / "x.stl")
    with pytest.raises(SceneError, match="file not found"):
        load_scene(tmp_path / "x.json")


def test_mutations_raise_only_scene_errors(tmp_path):
    """Random damage to valid inputs must end in a Scene or a SceneError, nothing else."""
    rng = random.Random(1234)
    bpt_text = "1\n2 1\n" + "0 1 2\n" * 5 + "1 1 1 2\n"
    scene_text = (SAMPLES / "teapot.json").read_text().replace("teapot.bpt", "small.bpt")
    (tmp_path / "small.bpt").write_text(BILINEAR)
    alphabet = "0123456789 -.,:[]{}\"\n#eEaNnx"
    for trial in range(300):
        base = scene_text if trial % 2 else bpt_text
        text = mutate(base, rng, alphabet)
        path = tmp_path / ("m.json" if trial % 2 else "m.bpt")
        path.write_text(text)
        try:
            load_scene(path)
        except SceneError:
            pass


def test_bpt_layouts_read_alike():
    """A point a line, everything on one line, a number a line: the same patches (the contract
    says whitespace separated)."""
    rng = np.random.default_rng(5)
    patches = []
    for _ in range(30):
        m, n = (int(d) for d in rng.integers(1, 4, 2))
        pts = rng.normal(size=((m + 1) * (n + 1), 4)).round(6)
        pts[:, 3] = rng.uniform(0.5, 2.0, len(pts)).round(6) if rng.random() < 0.4 else 1.0
        patches.append((m, n, pts, bool((pts[:, 3] != 1).any())))
    lines = [str(len(patches))]
    for m, n, pts, rat in patches:
        lines += [f"{m} {n}"] + [" ".join(repr(float(x)) for x in p[:4 if rat else 3]) for p in pts]
    text = "\n".join(lines) + "\n"
    want = parse_bpt(text, "lines.bpt")
    assert [(p.degree_u, p.degree_v, p.rational) for p in want] == [(m, n, r) for m, n, _, r in patches]
    for p, (_, _, pts, _) in zip(want, patches):
        assert np.array_equal(p.points, pts)
    words = text.split()
    for layout in (" ".join(words), "\n".join(words), "\t".join(words) + "  # the end\n"):
        got = parse_bpt(layout, "other.bpt")
        assert len(got) == len(want)
        assert all(np.array_equal(a.points, b.points) and a.rational == b.rational for a, b in zip(got, want))


def test_bpt_run_together_points_can_be_ambiguous():
    # all ones: 3 then 4 numbers a point read to the end just as well as 4 then 3
    text = "2 1 1 " + "1 " * 30
    with pytest.raises(SceneError, match=r"x.bpt:1: patch 1: cannot tell whether its control points have 3 or 4"):
        parse_bpt(text, "x.bpt")
