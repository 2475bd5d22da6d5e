"""Tests for the channel registry and statistics, colour maps, display modes and the trace plot.

All on small synthetic frames (no kernel), each checked against a naive
per-pixel reference written out longhand.
"""
import math
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from tracer import colormap, shade, stats
from tracer.plot import trace_plot
from tracer.render import AOV_NAMES, Frame


def synthetic_frame(h=6, w=5, seed=0):
    """A frame of rays from (0, -5, 0) with hits on a wavy surface in the lower rows."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:h, 0:w]
    dirs = np.stack([(xs - w / 2) * 0.1, np.ones((h, w)), -(ys - h / 2) * 0.1], axis=-1)
    origins = np.broadcast_to(np.array([0.0, -5.0, 0.0]), (h, w, 3)).copy()
    f = Frame.empty(origins, dirs)
    f.hit[:] = ys >= 2
    t = 5.0 + rng.random((h, w))
    f.t[f.hit] = t[f.hit]
    f.position[f.hit] = (origins + t[..., None] * dirs)[f.hit]
    half = 1e-6
    f.box_min[f.hit] = f.position[f.hit] - half
    f.box_max[f.hit] = f.position[f.hit] + half
    n = rng.normal(size=(h, w, 3))
    f.normal[f.hit] = (n / np.linalg.norm(n, axis=-1, keepdims=True))[f.hit]
    f.uv[f.hit] = rng.random((h, w, 2))[f.hit]
    f.patch[f.hit] = rng.integers(0, 4, (h, w))[f.hit].astype(np.int32)
    f.effort[:] = rng.integers(0, 500, (h, w)).astype(np.int32)
    f.nodes[:] = rng.integers(0, 60, (h, w)).astype(np.int32)
    f.patches_tested[:] = rng.integers(0, 8, (h, w)).astype(np.int32)
    f.add_lighting(shadows=True)
    f.radiance = None  # shaded from the channels (shade.py's fallback), as a frame traced without lighting
    f.shadow[f.hit] = rng.random((h, w))[f.hit]
    f.shadow_rays[f.hit] = rng.integers(0, 40, (h, w))[f.hit]
    f.penumbra[f.hit] = rng.integers(-1, 2, (h, w))[f.hit]
    f.seconds = 0.25
    return f


def copy_frame(f):
    return Frame(*(None if getattr(f, k) is None else getattr(f, k).copy() for k in AOV_NAMES), seconds=f.seconds)


def scene_stub(lights=()):
    mat = SimpleNamespace(color=np.array([0.8, 0.7, 0.6]), specular=0.3, shininess=40.0)
    return SimpleNamespace(materials=[mat, mat], patch_material=np.array([0, 1, 0, 1], np.int32),
                           lights=list(lights),
                           bounds=lambda: (np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])))


# ---- error statistics -------------------------------------------------------------

def naive_error_stats(frame, ref):
    errs, floors, inside, in_box = [], [], [], []
    holes = false_hits = unresolved = 0
    h, w = frame.hit.shape
    for y in range(h):
        for x in range(w):
            if ref.unresolved[y, x]:  # the reference does not know: nothing to score
                unresolved += 1
                continue
            a, b = frame.hit[y, x], ref.hit[y, x]
            holes += bool(b and not a)
            false_hits += bool(a and not b)
            if a and b:
                p, r = frame.position[y, x], ref.position[y, x]
                errs.append(sum(abs(float(p[i]) - float(r[i])) for i in range(3)))
                floors.append(sum(abs(float(np.float32(r[i])) - float(r[i])) for i in range(3)))
                ok = True
                in_box.append(all(frame.box_min[y, x, i] <= r[i] <= frame.box_max[y, x, i] for i in range(3)))
                for i in range(3):
                    lo, hi = frame.box_min[y, x, i], frame.box_max[y, x, i]
                    ulp_lo = float(np.spacing(np.float32(abs(lo))))
                    ulp_hi = float(np.spacing(np.float32(abs(hi))))
                    ok &= lo - 4 * ulp_lo <= r[i] <= hi + 4 * ulp_hi
                inside.append(ok)
    mean = sum(errs) / len(errs)
    return {"holes": holes, "false_hits": false_hits, "max": max(errs), "min": min(errs), "mean": mean,
            "variance": sum((e - mean) ** 2 for e in errs) / len(errs), "floor": sum(floors) / len(floors),
            "inside_box": sum(in_box) / len(in_box), "inside_4ulp": sum(inside) / len(inside),
            "compared": len(errs), "unresolved": unresolved}


def test_error_stats_matches_naive_reference():
    ref = synthetic_frame()
    frame = copy_frame(ref)
    rng = np.random.default_rng(1)
    frame.position[frame.hit] += rng.normal(scale=1e-7, size=(int(frame.hit.sum()), 3))
    frame.hit[5, 0] = False          # a hole
    frame.hit[0, 0] = True           # a false hit
    frame.box_min[4, 4] = frame.box_max[4, 4] = ref.position[4, 4] + 1e-3  # box misses the reference
    frame.hit[3, 1] = False
    frame.position[2, 2] += 5.0
    ref.unresolved[3, 1] = ref.unresolved[2, 2] = ref.unresolved[1, 3] = True  # out of budget: not scored
    got = stats.error_stats(frame, ref)
    want = naive_error_stats(frame, ref)
    assert got["holes"] == 1 and got["false_hits"] == 1 and got["unresolved"] == 3 and got["max"] < 1e-5
    for key, value in want.items():
        assert got[key] == pytest.approx(value, rel=1e-12, abs=0), key  # same sums, float64 rounding only
    assert got["ratio"] == pytest.approx(want["mean"] / want["floor"], rel=1e-12)
    assert got["inside_4ulp"] < 1.0 and got["inside_box"] <= got["inside_4ulp"]


def test_error_stats_identical_frames_and_no_hits():
    ref = synthetic_frame()
    s = stats.error_stats(copy_frame(ref), ref)
    assert s["max"] == 0 and s["mean"] == 0 and s["ratio"] == 0 and s["inside_4ulp"] == s["inside_box"] == 1.0
    empty = copy_frame(ref)
    empty.hit[:] = False
    s = stats.error_stats(empty, empty)
    assert s["compared"] == 0 and s["mean"] is None and s["holes"] == 0
    with pytest.raises(ValueError, match="not the same rays"):
        stats.error_stats(ref, synthetic_frame(4, 4))


def test_frame_stats():
    f = synthetic_frame()
    s = stats.frame_stats(f)
    assert s["rays"] == 30 and s["hits"] == int(f.hit.sum()) and s["time"] == 0.25
    assert s["effort"] == {"min": f.effort.min(), "mean": pytest.approx(f.effort.mean()), "max": f.effort.max()}
    assert s["effort_hits"]["max"] == f.effort[f.hit].max()


def test_ulp32_and_json_safe():
    x = np.array([0.0, 1.0, -3.5, 1e6])
    assert np.array_equal(stats.ulp32(x), [np.spacing(np.float32(abs(v))) for v in x])
    assert stats.json_safe({"a": [math.inf, np.float64(2.0)], "b": np.int32(3), "c": math.nan}) == \
        {"a": [None, 2.0], "b": 3, "c": None}


# ---- channels ---------------------------------------------------------------------

def test_channel_registry_is_complete():
    for name in ("effort", "error", "depth", "patch", "box_size"):
        ch = stats.channel(name)
        assert ch.name == name and ch.units and ch.help
        assert ch.scale in ("linear", "log", "categorical")
    with pytest.raises(ValueError, match="unknown channel"):
        stats.channel("nope")


@pytest.mark.parametrize("name", list(stats.CHANNELS))
def test_channel_tiles_agree_with_whole_image(name):
    ref = synthetic_frame()
    frame = copy_frame(ref)
    frame.position[frame.hit] += 1e-7
    frame.hit[5, 0] = False
    whole, rng = stats.channel_rgb(name, frame, ref)
    tile, _ = stats.channel_rgb(name, frame, ref, rect=(2, 5, 1, 4), vrange=rng)
    assert whole.dtype == np.float32 and whole.shape == (6, 5, 3)
    assert np.array_equal(tile, whole[2:5, 1:4])


def test_error_channel_marks_holes_and_false_hits():
    ref = synthetic_frame()
    frame = copy_frame(ref)
    frame.hit[5, 0] = False
    frame.hit[0, 0] = True
    frame.hit[4, 1] = False
    ref.unresolved[4, 1] = True
    rgb, _ = stats.channel_rgb("error", frame, ref)
    assert tuple(rgb[5, 0]) == stats.HOLE_RGB and tuple(rgb[0, 0]) == stats.FALSE_HIT_RGB
    assert tuple(rgb[4, 1]) == stats.UNRESOLVED_RGB  # not a hole: the reference ran out of budget there
    with pytest.raises(ValueError, match="reference"):
        stats.channel_rgb("error", frame)
    img = stats.channel_image("error", frame, ref, legend_width=300)
    assert img.width == 300 and img.height > 6


# ---- colour maps ------------------------------------------------------------------

def test_colormap_tables_and_scaling():
    for name in colormap.MAPS:
        t = colormap.table(name)
        assert t.shape == (colormap.TABLE_SIZE, 3) and t.dtype == np.float32
        luma = t @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        assert np.all(np.diff(luma) > -1e-3), name  # perceptually ordered: brightness never drops
    assert np.allclose(colormap.table("viridis")[0], np.array([68, 1, 84]) / 255)
    assert colormap.normalise([1, 10, 100], 1, 100, "log") == pytest.approx([0, 0.5, 1])
    assert colormap.normalise([0, 5, 20], 0, 10) == pytest.approx([0, 0.5, 1])
    assert colormap.normalise([-1.0], 1, 100, "log")[0] == 0  # non-positive clamps to lo
    rgb = colormap.colorize(np.array([np.nan, 0.0, 1.0]), 0, 1, nan_rgb=(0.5, 0.5, 0.5))
    assert tuple(rgb[0]) == (0.5, 0.5, 0.5) and np.allclose(rgb[2], colormap.table()[-1])
    assert colormap.auto_range([0, 2, 5, np.inf], "log") == (2, 5)
    with pytest.raises(ValueError):
        colormap.table("jet")


def test_legend_image_has_bar_and_text():
    img = colormap.legend_image(320, 1e-9, 1e-5, label="error", units="m", scale="log",
                                specials=[((1, 0, 0), "hole")])
    a = np.asarray(img)
    assert img.size[0] == 320
    assert np.any(np.all(a == (255, 0, 0), axis=-1))  # the hole swatch
    assert np.any(np.all(a == (253, 231, 37), axis=-1))  # the top of viridis in the bar
    assert colormap.format_value(1234.0) == "1234" and colormap.format_value(1.5e-7) == "1.50e-07"


# ---- display modes ------------------------------------------------------------------

@pytest.mark.parametrize("mode", shade.MODES)
def test_shade_modes(mode):
    f = synthetic_frame()
    scene = scene_stub([SimpleNamespace(intensity=1.0, color=np.ones(3), centre=lambda: np.array([0, -5.0, 5]))])
    rgb = shade.shade(f, scene, mode)
    assert rgb.shape == (6, 5, 3) and rgb.dtype == np.float32
    assert rgb.min() >= 0 and rgb.max() <= 1
    assert np.array_equal(rgb[~f.hit], shade.background(6, 0, 6, 5)[~f.hit])
    rng = shade.depth_limits(f, scene, rect=(0, 6, 0, 5))
    whole = shade.shade(f, scene, mode, depth_range=rng)
    tile = shade.shade(f, scene, mode, rect=(1, 4, 2, 5), depth_range=rng)
    assert np.array_equal(tile, whole[1:4, 2:5])


def test_shaded_headlight_and_facing():
    f = synthetic_frame()
    f.normal[f.hit] = -_unit(f.ray_dir[f.hit])  # facing the eye
    lit = shade.shade(f, scene_stub(), "shaded")
    f.normal[f.hit] *= -1  # facing away: lit from the eye's side all the same (two-sided)
    assert np.allclose(shade.shade(f, scene_stub(), "shaded"), lit)
    assert lit[f.hit].mean() > 0.5


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_patch_colours_distinct_and_to_png(tmp_path):
    c = shade.patch_colours(np.arange(64))
    dist = np.abs(c[:, None] - c[None]).sum(-1) + np.eye(64) * 9
    assert dist.min() > 0.02
    img = shade.to_png(np.full((3, 4, 3), 0.5, np.float32), tmp_path / "x.png")
    with Image.open(tmp_path / "x.png") as back:
        assert back.size == (4, 3) and back.getpixel((0, 0)) == (128, 128, 128)
    assert img.size == (4, 3)


def test_srgb_encode():
    assert shade.srgb_encode(np.array([0.0, 1.0, 0.001]))[:2] == pytest.approx([0, 1])
    assert shade.srgb_encode(np.array([0.18]))[0] == pytest.approx(0.4614, abs=1e-3)


# ---- trace plot -------------------------------------------------------------------

def fake_trace(n=60, hit_at=45):
    diam = 4.0 * 0.5 ** (np.arange(n) / 4.0)
    events = ["split" if i % 2 else "miss" for i in range(n)]
    events[10] = "pruned"
    events[hit_at] = "hit"
    return SimpleNamespace(diameters=diam, events=events, hit_step=lambda: hit_at, pixel=(3, 4), hit=True,
                           patch=7, effort=n, truncated=False)


def test_trace_plot(tmp_path):
    img = trace_plot(fake_trace(), tmp_path / "p.png")
    assert img.size == (960, 500)
    a = np.asarray(img)
    assert np.any(np.all(a == (220, 20, 20), axis=-1))  # the red ring of the reported hit box
    assert np.any(np.all(a == (150, 60, 200), axis=-1))  # the optimum curve
    with Image.open(tmp_path / "p.png") as back:
        assert back.size == (960, 500)
    empty = SimpleNamespace(diameters=np.zeros(0), events=[], hit_step=lambda: -1, pixel=(0, 0), hit=False,
                            patch=-1, effort=0, truncated=False)
    assert trace_plot(empty).size == (960, 500)
