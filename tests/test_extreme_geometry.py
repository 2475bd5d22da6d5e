"""Finite but extreme geometry through the command line (issue 11, item 3): coordinates near
1e300 or 1e308, weights of 1e-300 or 1e300, transforms scaling by 1e300, a unit quad at 1e8.

Each case renders a correct image, or fails with one line naming the file and the extent (exit
2), or, where the working precision cannot place the rays finely enough, warns in one line with
the remedy and renders. Never a traceback, never a silently empty image. The rules are
tracer/limits.py's; images are 8x8.
"""
import json

import numpy as np
import pytest
from PIL import Image

from psrt.cli import main
from tracer import limits
from tracer.errors import SceneError
from tracer.geometry import prepare
from tracer.scene import load_scene

from test_cli_hardening import REPO, one_line_error

TEAPOT = REPO / "sample_models" / "teapot.bpt"
UNIT = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)]


def quad(path, corners, weights=None):
    """A one-patch bilinear .bpt (rational with weights); the patch header is line 2."""
    rows = [" ".join(repr(float(c)) for c in p) + ("" if weights is None else f" {weights[k]!r}")
            for k, p in enumerate(corners)]
    path.write_text("1\n1 1\n" + "\n".join(rows) + "\n")
    return path


def moved(corners, by=(0, 0, 0), scale=1.0):
    return [tuple(scale * c + b for c, b in zip(p, by)) for p in corners]


def scaled_scene(path, source, s):
    """A scene of one object, `source` under a transform scaling by s."""
    path.write_text(json.dumps({"objects": [{"file": str(source), "transform":
                                             [s, 0, 0, 0, 0, s, 0, 0, 0, 0, s, 0, 0, 0, 0, 1]}]}))
    return path


def render(tmp_path, scene, precision, *extra):
    aov = tmp_path / "aov.npz"
    code = main(["render", str(scene), "-o", str(tmp_path / "img.png"), "--size", "8x8", "--precision",
                 precision, "--aov", str(aov), "-q", *extra])
    hits = int(np.load(aov)["hit"].sum()) if code == 0 else None
    return code, hits


def trace(scene, precision):
    return main(["trace", str(scene), "--pixel", "4,4", "--size", "8x8", "--precision", precision, "-q",
                 "-o", "-"])


# ---- what cannot be bounded or resolved: one line naming the file and the extent ----------

def _span_1e308(d):
    return quad(d / "span.bpt", [(-1e308, -1e308, 0), (1e308, -1e308, 0), (-1e308, 1e308, 0), (1e308, 1e308, 5e307)])


ERRORS = {  # name: (make(tmp_path) -> scene, precisions, text the line holds)
    "extent 2e308": (_span_1e308, ("f32", "f64"), ("span.bpt", "extent 2e+308", "too large for float64")),
    "a 1e295 quad at 1e300": (lambda d: quad(d / "far.bpt", moved(UNIT, (1e300, 0, 0), 1e295)),
                              ("f32", "f64"), ("far.bpt", "coordinates up to 1e+300", "extent 1e+295")),
    "a 1e300 quad": (lambda d: quad(d / "huge.bpt", moved(UNIT, scale=1e300)), ("f32", "f64"),
                     ("huge.bpt", "extent 1e+300", "2^240")),
    "transform by 1e300": (lambda d: scaled_scene(d / "s.json", quad(d / "unit.bpt", UNIT), 1e300), ("f32", "f64"),
                           ("s.json", "extent 1e+300", "too large for float64")),
    "transform past float64": (lambda d: scaled_scene(d / "s.json", TEAPOT, 1e308), ("f32", "f64"),
                               ("s.json", "objects[0].transform", "past float64's largest number")),
    "transform by 1e-300": (lambda d: scaled_scene(d / "s.json", quad(d / "unit.bpt", UNIT), 1e-300), ("f32", "f64"),
                            ("s.json", "extent 1e-300", "too small for float64")),
    "neighbouring floats at 1e16": (lambda d: quad(d / "n.bpt", moved(UNIT, (1e16, 0, 0), 2.0)), ("f32", "f64"),
                                    ("n.bpt", "extent 2", "2 apart", "no precision resolves")),
    "one point": (lambda d: quad(d / "p.bpt", [(1, 2, 3)] * 4), ("f32", "f64"), ("p.bpt", "extent 0", "same point")),
    "a 1e37 quad near 1e38 in float32": (lambda d: quad(d / "big.bpt", moved(UNIT, (1e38, 0, 0), 1e37)), ("f32",),
                                         ("big.bpt", "extent 1e+37", "float32's range", "--precision f64")),
    "a 1e-35 quad in float32": (lambda d: quad(d / "small.bpt", moved(UNIT, scale=1e-35)), ("f32",),
                                ("small.bpt", "extent 1e-35", "float32's range", "--precision f64")),
    "a weight of 1e-300": (lambda d: quad(d / "w.bpt", UNIT, [1e-300, 1.0, 1.0, 1.0]), ("f32", "f64"),
                           ("w.bpt:2: patch 0", "weights from 1e-300", "cannot add the smallest")),
    "a weight of 1e300": (lambda d: quad(d / "w.bpt", UNIT, [1e300, 1.0, 1.0, 1.0]), ("f32", "f64"),
                          ("w.bpt:2: patch 0", "to 1.25e+299", "cannot add the smallest")),
}


@pytest.mark.parametrize("command", ["render", "trace"])
@pytest.mark.parametrize("name", list(ERRORS))
def test_what_cannot_be_bounded_is_one_line_naming_the_file_and_the_extent(tmp_path, capsys, name, command):
    make, precisions, needles = ERRORS[name]
    scene = make(tmp_path)
    for precision in precisions:
        code = render(tmp_path, scene, precision)[0] if command == "render" else trace(scene, precision)
        assert code == 2, (name, precision)
        one_line_error(capsys, f"psrt {command}: error:", *needles)
        assert not (tmp_path / "img.png").exists()


def test_prepare_refuses_them_too(tmp_path):
    """The viewer and the Python API meet the same errors (prepare checks before any work)."""
    with pytest.raises(SceneError, match="too large for float64"):
        prepare(load_scene(_span_1e308(tmp_path)), "f64")


# ---- what renders: correctly, or with a warning and its remedy ------------------------------

def test_a_unit_quad_at_1e8_warns_in_float32_and_renders_in_float64(tmp_path, capsys):
    """float32 numbers near 1e8 are 8 apart: the eye rounds by up to 4, farther than the quad is
    wide, and the float32 image is empty. float64 renders it."""
    scene = quad(tmp_path / "far.bpt", moved(UNIT, (1e8, 0, 0)))
    code, hits = render(tmp_path, scene, "f32")
    assert code == 0
    line = one_line_error(capsys, "psrt render: warning:", "far.bpt", "coordinates up to 1e+08", "extent 1",
                          "8 apart", "--precision f64")
    assert "error" not in line
    assert trace(scene, "f32") == 0
    one_line_error(capsys, "psrt trace: warning:", "8 apart", "--precision f64")
    code, hits = render(tmp_path, scene, "f64")
    assert code == 0 and hits > 10 and capsys.readouterr().err == ""


def test_float64_warns_where_it_cannot_place_the_rays_finely(tmp_path, capsys):
    """A unit quad at 1e15: float64 numbers there are 0.125 apart, 1/8 of the quad."""
    scene = quad(tmp_path / "far.bpt", moved(UNIT, (1e15, 0, 0)))
    assert render(tmp_path, scene, "f64")[0] == 0
    one_line_error(capsys, "psrt render: warning:", "0.125 apart", "nearer the origin")


@pytest.mark.parametrize("weight", [1e-300, 1e300])
@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_uniform_extreme_weights_render_as_weight_one(tmp_path, capsys, weight, precision):
    """Scaling all of a patch's weights alike leaves it unchanged (limits.weight_scale)."""
    _, plain = render(tmp_path, quad(tmp_path / "unit.bpt", UNIT), precision)
    code, hits = render(tmp_path, quad(tmp_path / "w.bpt", UNIT, [weight] * 4), precision)
    assert code == 0 and hits == plain > 10 and capsys.readouterr().err == ""


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_weights_float32_cannot_add_render_in_float64(tmp_path, capsys, precision):
    """A corner weight of 1e10: float32 could not add the smallest weight to the largest (it once
    reported hits 5e11 off); rational patches are searched in float64 at either precision, and
    the hits lie on the plane of the quad, inside it."""
    code, hits = render(tmp_path, quad(tmp_path / "w.bpt", UNIT, [1e10, 1.0, 1.0, 1.0]), precision)
    assert code == 0 and hits > 10 and capsys.readouterr().err == ""
    aov = np.load(tmp_path / "aov.npz")
    p = aov["position"][aov["hit"]]
    assert np.all(p[:, 2] == 0) and np.all((p[:, :2] >= 0) & (p[:, :2] <= 1))


def _image(path):
    return np.asarray(Image.open(path))


@pytest.mark.parametrize("precision, power", [("f64", 230), ("f64", -230), ("f32", 100), ("f32", -90)])
def test_the_teapot_scaled_far_within_the_limits_renders_the_same_image(tmp_path, capsys, precision, power):
    """A power-of-two scale is exact, and so, within the limits, is every step of a render: the
    image (and every hit) is the unscaled one's."""
    assert render(tmp_path, scaled_scene(tmp_path / "one.json", TEAPOT, 1.0), precision)[0] == 0
    unscaled, hits = _image(tmp_path / "img.png"), np.load(tmp_path / "aov.npz")["hit"]
    assert render(tmp_path, scaled_scene(tmp_path / "far.json", TEAPOT, 2.0 ** power), precision)[0] == 0
    assert capsys.readouterr().err == ""
    assert np.array_equal(np.load(tmp_path / "aov.npz")["hit"], hits) and hits.sum() > 5
    assert np.array_equal(_image(tmp_path / "img.png"), unscaled)


# ---- the rules at their edges ---------------------------------------------------------------

class _Scene:
    """What check_extent reads of a scene: its path and the box of its control points."""

    def __init__(self, lo, hi, path="edge.bpt"):
        self.path, self._box = path, (np.asarray(lo, float), np.asarray(hi, float))

    def bounds(self):
        return self._box


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_extent_limits_hold_at_their_edges(precision):
    big = limits.FLOAT32_LARGEST if precision == "f32" else limits.FLOAT64_LARGEST
    small = limits.FLOAT32_SMALLEST if precision == "f32" else limits.FLOAT64_SMALLEST
    for extent in (small, big / 2):  # f32's largest bounds coordinates: a box [0, E] reaches E
        assert limits.check_extent(_Scene([0, 0, 0], [extent, extent, 0]), precision) == []
    for extent in (small / 2, big * 2):
        with pytest.raises(SceneError, match="edge.bpt: coordinates up to"):
            limits.check_extent(_Scene([0, 0, 0], [extent, extent, 0]), precision)


@pytest.mark.parametrize("precision, bits", [("f32", 24), ("f64", 53)])
def test_resolution_warning_starts_past_a_64th_of_the_extent(precision, bits):
    """At 2^k the spacing is 2^(k + 1 - bits); a box of extent 64 spacings is the last without
    a warning."""
    at = 2.0 ** 40
    step = 2.0 ** (41 - bits)
    edge = _Scene([at, 0, 0], [at, 64 * step, 0])
    assert limits.check_extent(edge, precision) == []
    (line,) = limits.check_extent(_Scene([at, 0, 0], [at, 32 * step, 0]), precision)
    assert line.startswith("edge.bpt: coordinates up to") and "1/64 of the extent" in line
