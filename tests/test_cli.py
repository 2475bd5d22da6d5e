"""Tests for the `psrt` command line: every flag of every subcommand, output contracts, errors.

Images are tiny (at most 48x40) so the suite stays fast; the numba cache is shared.
"""
import importlib.machinery
import json
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from psrt.cli import main
from tracer.colormap import to_uint8
from tracer.options import Options
from tracer.render import render
from tracer.scene import load_scene
from tracer.shade import MODES, shade
from tracer.stats import HOLE_RGB
from tracer.trace_one import trace_pixel

REPO = Path(__file__).resolve().parents[1]
TEAPOT = str(REPO / "sample_models" / "teapot.json")

CONTRACT = {"ray_origin": ("float64", 3), "ray_dir": ("float64", 3), "hit": ("bool", 0), "t": ("float64", 0),
            "position": ("float64", 3), "box_min": ("float64", 3), "box_max": ("float64", 3),
            "normal": ("float64", 3), "uv": ("float64", 2), "patch": ("int32", 0), "effort": ("int32", 0)}
# The contract's further channels that the primary-ray kernel computes on every render.
FURTHER = {"nodes": ("int32", 0), "patches_tested": ("int32", 0), "surfaces_tested": ("int32", 0),
           "box_tests": ("int32", 0), "cache_hits": ("int32", 0), "cache_misses": ("int32", 0),
           "unresolved": ("bool", 0),
           # the lighting's (tracer/lighting.py), on by default
           "shadow": ("float32", 0), "shadow_rays": ("int32", 0), "penumbra": ("int8", 0)}
STAT_KEYS = {"rays", "hits", "time", "effort", "effort_hits", "error", "options", "size", "scene"}
ERROR_KEYS = {"max", "min", "mean", "variance", "holes", "false_hits", "unresolved", "floor", "ratio", "inside_box",
              "inside_4ulp"}


def run(*argv):
    return main([str(a) for a in argv])


def png_size(path):
    with Image.open(path) as im:
        return im.size


def load_npz(path):
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def check_contract(a, w, h):
    assert set(a) == set(CONTRACT) | set(FURTHER)
    for name, (dtype, last) in {**CONTRACT, **FURTHER}.items():
        assert a[name].dtype == np.dtype(dtype), name
        assert a[name].shape == ((h, w, last) if last else (h, w)), name
    hit = a["hit"]
    assert not a["unresolved"].any()  # only the float64 reference has a box budget
    assert np.array_equal(hit, a["patch"] >= 0)
    assert np.all(np.isinf(a["t"][~hit])) and np.all(np.isfinite(a["t"][hit]))
    assert np.all(a["box_min"][hit] <= a["position"][hit]) and np.all(a["position"][hit] <= a["box_max"][hit])
    assert np.allclose(np.linalg.norm(a["normal"][hit], axis=-1), 1.0, atol=1e-9)  # unit normals


@pytest.fixture(scope="module")
def horizon_scene(tmp_path_factory):
    """A floor seen level from just above it: only the lower half of the image has geometry."""
    path = tmp_path_factory.mktemp("scene") / "horizon.json"
    path.write_text(json.dumps({
        "camera": {"eye": [0, -3, 1], "look_at": [0, 0, 1], "up": [0, 0, 1], "fov_deg": 60},
        "objects": [{"patches": [{"degree": [1, 1],
                                  "points": [[-40, -5, 0], [40, -5, 0], [-40, 60, 0], [40, 60, 0]]}]}]}))
    return str(path)


# ---- render -------------------------------------------------------------------------

def test_render_all_outputs(tmp_path, capsys):
    out = {k: tmp_path / f"{k}" for k in ("img.png", "aov.npz", "effort.png", "error.png", "stats.json")}
    assert run("render", TEAPOT, "-o", out["img.png"], "--size", "48x40", "--aov", out["aov.npz"],
               "--effort-map", out["effort.png"], "--error-map", out["error.png"],
               "--stats", out["stats.json"]) == 0
    assert png_size(out["img.png"]) == (48, 40)
    a = load_npz(out["aov.npz"])
    check_contract(a, 48, 40)
    assert 0 < a["hit"].sum() < 48 * 40
    for key in ("effort.png", "error.png"):  # the map in the top-left 48x40, the legend below it
        w, h = png_size(out[key])
        assert w >= 48 and h > 40
    st = json.loads(out["stats.json"].read_text())
    assert STAT_KEYS <= set(st) and ERROR_KEYS <= set(st["error"])
    assert st["rays"] == 48 * 40 and st["hits"] == int(a["hit"].sum()) and st["size"] == [48, 40]
    assert set(st["effort"]) == {"min", "mean", "max"} and st["effort"]["max"] == int(a["effort"].max())
    assert st["error"]["holes"] == 0 and st["error"]["false_hits"] == 0  # the float criterion is exact
    assert st["error"]["max"] < 1e-4 and st["error"]["inside_4ulp"] > 0.5
    assert "48x40" in capsys.readouterr().err  # the summary line


def test_kernel_channels_reach_npz_maps_and_stats(tmp_path):
    """nodes and patches_tested (declared once in kernel_channels) are in the .npz, drawable with
    --map, summarised in --stats; --stats lists the kernel variants compiled and their times."""
    aov, stats = tmp_path / "a.npz", tmp_path / "s.json"
    maps = {name: tmp_path / f"{name}.png" for name in ("nodes", "patches_tested", "box_size")}
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--size", "24x20", "--aov", aov, "--stats", stats,
               *[a for name, path in maps.items() for a in ("--map", f"{name}={path}")]) == 0
    a = load_npz(aov)
    for name in ("nodes", "patches_tested"):
        assert a[name].dtype == np.int32 and a[name].shape == (20, 24)
    assert np.all(a["patches_tested"] <= a["nodes"]) and a["nodes"].max() > 1
    for path in maps.values():
        w, h = png_size(path)
        assert w >= 24 and h > 20
    st = json.loads(stats.read_text())
    assert st["nodes"]["max"] == int(a["nodes"].max())
    assert st["patches_tested_hits"]["min"] >= 1
    assert st["variant"] == "f32 bicubic+bilinear bundles closest bvh"  # 8x8 bundles by default
    kernels = {(k["kernel"], k["variant"]) for k in st["kernels"]}
    assert ("tile", "f32 bicubic+bilinear bundles closest bvh") in kernels
    assert ("tile", "f64 bicubic+bilinear closest bvh") in kernels  # the float64 reference: single rays
    assert all(k["seconds"] >= 0 for k in st["kernels"])


def test_unknown_map_channel_exits_2(tmp_path, capsys):
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--map", "bogus=x.png") == 2
    assert "unknown channel 'bogus'" in capsys.readouterr().err


def test_compile_note_is_a_step_of_its_own():
    from tracer.cli import _compile_note
    from tracer.variants import Variant

    class Bar:
        desc = "render"
        lines = []

        def set_description_str(self, text):
            self.desc = text

        def write(self, text, file=None):
            self.lines.append(text)

    bar, args = Bar(), type("Args", (), {"quiet": False})()
    note = _compile_note(args, bar)
    v = Variant("f32", False, True, False, False, False, False, "closest", "bvh", False, False)
    note(v)
    assert bar.desc == "compiling the f32 bicubic closest bvh kernel"
    note(v, 12.5)
    assert bar.desc == "render" and bar.lines == ["compiled the f32 bicubic closest bvh kernel in 12.5 s"]
    assert _compile_note(type("Args", (), {"quiet": True})(), bar) is None


def test_error_map_marks_holes(tmp_path, monkeypatch):
    """A reference that hits where the render missed (holes made on purpose: a correct render has
    none): the CLI's error map paints exactly those pixels in the documented hole colour, its
    legend shows that colour's swatch, and --stats counts them."""
    import tracer.render
    real_reference = tracer.render.reference_frame
    holes = []

    def reference_with_holes(scene, frame, **kwargs):
        ref = real_reference(scene, frame, **kwargs)
        missed = np.argwhere(~frame.hit)
        for y, x in missed[[0, len(missed) // 2, -1]]:
            holes.append((int(y), int(x)))
            ref.hit[y, x], ref.patch[y, x], ref.t[y, x] = True, 0, 1.0
            ref.position[y, x] = ref.box_min[y, x] = ref.box_max[y, x] = ref.ray_origin[y, x] + ref.ray_dir[y, x]
        return ref

    monkeypatch.setattr(tracer.render, "reference_frame", reference_with_holes)
    error_map, stats = tmp_path / "e.png", tmp_path / "s.json"
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--size", "32x32", "--error-map", error_map,
               "--stats", stats, "-q") == 0
    img = np.asarray(Image.open(error_map).convert("RGB"))
    is_hole = np.all(img == to_uint8(np.asarray(HOLE_RGB)), axis=-1)
    assert sorted(map(tuple, np.argwhere(is_hole[:32, :32]))) == sorted(holes)  # the map: top-left 32x32
    assert is_hole[32:].any(), "the legend shows no hole swatch"
    assert json.loads(stats.read_text())["error"]["holes"] == len(holes) == 3


@pytest.mark.parametrize("mode", Options.__dataclass_fields__["mode"].metadata["choices"])
def test_render_modes(tmp_path, mode):
    path = tmp_path / f"{mode}.png"
    assert run("render", TEAPOT, "-o", path, "--size", "32x24", "--mode", mode, "-q") == 0
    assert png_size(path) == (32, 24)
    via_set = tmp_path / f"{mode}-set.png"
    assert run("render", TEAPOT, "-o", via_set, "--size", "32x24", "--set", f"mode={mode}", "-q") == 0
    assert np.array_equal(np.asarray(Image.open(path)), np.asarray(Image.open(via_set)))
    # the mode reaches the image: it is shade() of that mode, not of another
    scene = load_scene(TEAPOT)
    frame = render(scene, Options(), size=(32, 24))
    expected = {m: to_uint8(shade(frame, scene, m)) for m in MODES}
    assert [m for m in MODES if np.array_equal(np.asarray(Image.open(path).convert("RGB")), expected[m])] == [mode]


@pytest.mark.parametrize("flags", [
    ["--criterion", "fixed", "--fixed-size", "0.01"],
    ["--criterion", "adaptive", "--pixel-fraction", "1.5"],
    ["--criterion", "mantissa", "--mantissa-ulps", "1000"],
    ["--split", "cross", "--tile-size", "8", "--threads", "1"],
    ["--precision", "f64"],
])
def test_render_tracer_flags(tmp_path, flags):
    npz, js = tmp_path / "a.npz", tmp_path / "s.json"
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--size", "32x32", "--aov", npz, "--stats", js,
               "-q", *flags) == 0
    a = load_npz(npz)
    check_contract(a, 32, 32)
    opts = json.loads(js.read_text())["options"]
    for name, value in zip(flags[::2], flags[1::2]):
        key = name[2:].replace("-", "_")
        assert str(opts[key]) == value or float(opts[key]) == float(value), name
    hit = a["hit"]
    assert hit.any()
    if "fixed" in flags:  # every reported box is no larger than the fixed size
        assert np.all(np.sum(a["box_max"][hit] - a["box_min"][hit], axis=-1) <= 0.01)
    if "f64" in flags:  # rays are not rounded to float32
        assert np.any(a["ray_dir"].astype(np.float32).astype(np.float64) != a["ray_dir"])
    else:
        assert np.array_equal(a["ray_dir"].astype(np.float32).astype(np.float64), a["ray_dir"])


def test_set_is_applied_after_flags(tmp_path):
    js = tmp_path / "s.json"
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--size", "16x16", "--criterion", "fixed",
               "--set", "criterion=adaptive", "--set", "pixel_fraction=2", "--stats", js, "-q") == 0
    opts = json.loads(js.read_text())["options"]
    assert opts["criterion"] == "adaptive" and opts["pixel_fraction"] == 2.0


def test_row_zero_is_the_top(tmp_path, horizon_scene):
    npz = tmp_path / "h.npz"
    assert run("render", horizon_scene, "-o", tmp_path / "h.png", "--size", "24x32", "--aov", npz, "-q") == 0
    hit = load_npz(npz)["hit"]
    assert not hit[:16].any() and hit[-10:].all()


def test_render_matches_trace_pixel(tmp_path):
    """The npz pixel [y, x] and `psrt trace --pixel x,y` are the same ray with the same result."""
    npz = tmp_path / "a.npz"
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--size", "40x32", "--aov", npz, "-q") == 0
    a = load_npz(npz)
    ys, xs = np.nonzero(a["hit"])
    for y, x in [(ys[0], xs[0]), (ys[len(ys) // 2], xs[len(ys) // 2]), (31, 0)]:
        out = tmp_path / f"t{x}_{y}.json"
        assert run("trace", TEAPOT, "--pixel", f"{x},{y}", "--size", "40x32", "-o", out, "-q") == 0
        tr = json.loads(out.read_text())
        assert tr["pixel"] == [x, y] and tr["hit"] == bool(a["hit"][y, x])
        assert tr["patch"] == a["patch"][y, x]
        if tr["hit"]:
            assert tr["position"] == a["position"][y, x].tolist()
            assert tr["box_min"] == a["box_min"][y, x].tolist()


# ---- trace --------------------------------------------------------------------------

def test_trace_json_and_plot(tmp_path, capsys):
    out, plot = tmp_path / "t.json", tmp_path / "t.png"
    assert run("trace", TEAPOT, "--pixel", "20,18", "--size", "40x32", "-o", out, "--plot", plot) == 0
    tr = json.loads(out.read_text())
    assert {"pixel", "hit", "patch", "t", "position", "box_min", "box_max", "steps"} <= set(tr)
    assert tr["hit"] and tr["patch"] >= 0 and tr["t"] > 0
    steps = tr["steps"]
    step_keys = {"patch", "depth", "u", "v", "box_min", "box_max", "diameter", "event"}
    assert all(step_keys <= set(s) for s in steps)
    # the steps of a direct trace of the same pixel (same kernel, same ray: bit for bit)
    want = trace_pixel(load_scene(TEAPOT), Options(), 20, 18, size=(40, 32))
    events = [s["event"] for s in steps]
    assert events == want.events and tr["hit_step"] == want.hit_step()
    assert np.array_equal([s["box_min"] + s["box_max"] for s in steps], want.steps_f[:, 4:10])
    assert [[s["patch"], s["depth"]] for s in steps] == want.steps_i[:, :2].tolist()
    # the summary counts what the steps say; effort is one box test per step
    summary = tr["summary"]
    assert summary["events"] == {k: events.count(k) for k in ("miss", "pruned", "split", "hit")}
    assert summary["boxes"] == len(steps) == tr["effort"] and summary["events"]["split"] > 0
    assert summary["max_depth"] == max(s["depth"] for s in steps) and summary["truncated"] is False
    last_hit = steps[tr["hit_step"]]  # the step that produced the reported box
    assert last_hit["event"] == "hit"
    assert last_hit["box_min"] == tr["box_min"] and last_hit["box_max"] == tr["box_max"]
    assert last_hit["patch"] == tr["patch"]
    centre = (np.array(tr["box_min"]) + np.array(tr["box_max"])) / 2
    assert np.allclose(centre, tr["position"], rtol=0, atol=1e-12)
    assert png_size(plot) == (960, 500)
    err = capsys.readouterr().err
    n = summary["events"]
    assert (f"pixel 20,18: hit patch {tr['patch']} at t=" in err and f"box {tr['hit_step']};" in err
            and f"{len(steps)} boxes ({n['split']} split, {n['miss']} miss, {n['pruned']} pruned, {n['hit']} hit), "
                f"effort {tr['effort']}" in err)


def test_trace_to_stdout_and_miss(capsys, horizon_scene):
    assert run("trace", horizon_scene, "--pixel", "2,1", "--size", "24x32", "--criterion", "mantissa",
               "--mantissa-ulps", "8", "--split", "cross", "--precision", "f64", "--tile-size", "8",
               "--threads", "1", "--fixed-size", "0.1", "--pixel-fraction", "1", "--mode", "uv",
               "--set", "threads=2") == 0
    captured = capsys.readouterr()
    tr = json.loads(captured.out)
    assert tr["pixel"] == [2, 1] and tr["hit"] is False and tr["patch"] == -1 and tr["position"] is None
    assert tr["hit_step"] == -1 and all(s["event"] != "hit" for s in tr["steps"])
    assert "miss" in captured.err


# ---- bench --------------------------------------------------------------------------

def test_bench(tmp_path, capsys):
    out = tmp_path / "b.json"
    assert run("bench", "--scene", TEAPOT, "--size", "16x16", "--runs", "1", "--criteria", "fixed",
               "--splits", "length", "--precisions", "f32", "--fixed-size", "0.01", "--pixel-fraction", "1",
               "--mantissa-ulps", "32", "--tile-size", "8", "--threads", "1", "--set", "tile_size=16",
               "--json", out) == 0
    captured = capsys.readouterr()
    assert "criterion" in captured.out and "err/floor" in captured.out and "fixed" in captured.out
    res = json.loads(out.read_text())
    assert res["size"] == [16, 16] and res["runs"] == 1 and res["options"]["tile_size"] == 16
    (row,) = res["rows"]
    assert (row["criterion"], row["split"], row["precision"]) == ("fixed", "length", "f32")
    assert row["param"] == {"fixed_size": 0.01} and row["rays"] == 256 and row["time"] > 0
    assert row["rays_per_s"] > 0 and row["effort_mean"] > 0
    assert ERROR_KEYS <= set(row["error"]) and row["error"]["holes"] == 0
    assert "f32" in res["references"]


def test_bench_quiet_defaults_scene(capsys):
    assert run("bench", "--size", "8x8", "--runs", "1", "--criteria", "float", "--splits", "cross",
               "--precisions", "f64", "-q") == 0
    captured = capsys.readouterr()
    assert "float" in captured.out and captured.err == ""


# ---- errors and the view hook -----------------------------------------------------------

@pytest.mark.parametrize("argv, needle", [
    (["render", "missing.json", "-o", "x.png"], "missing.json"),
    (["render", TEAPOT, "-o", "x.png", "--size", "12"], "--size"),
    (["render", TEAPOT, "-o", "x.png", "--size", "0x5"], "--size"),
    (["render", TEAPOT, "-o", "x.png", "--set", "nope=1"], "nope"),
    (["render", TEAPOT, "-o", "x.png", "--set", "criterion"], "option=value"),
    (["render", TEAPOT, "-o", "x.png", "--fixed-size", "50"], "--fixed-size: 50 is outside [1e-09, 10.0]"),
    (["render", TEAPOT, "-o", "x.png", "--criterion", "exact"], "--criterion"),
    (["render", TEAPOT, "-o", "/no/such/dir/x.png"], "/no/such/dir"),
    (["trace", TEAPOT, "--pixel", "5"], "--pixel"),
    (["trace", TEAPOT, "--pixel", "100,5", "--size", "32x32"], "outside"),
    (["bench", "--runs", "0", "--size", "8x8"], "--runs"),
    (["bench", "--scene", "missing.json"], "missing.json"),
    ([], "usage"),
])
def test_bad_input_exits_2(argv, needle, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert run(*argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_bad_scene_names_file_and_key(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"objects": [], "camra": {}}))
    assert run("render", bad, "-o", tmp_path / "x.png") == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "camra" in err


def test_help_exits_0(capsys):
    assert run("render", "--help") == 0
    out = capsys.readouterr().out
    for flag in ("--criterion", "--split", "--precision", "--mode", "--fixed-size", "--pixel-fraction",
                 "--mantissa-ulps", "--set", "--aov", "--effort-map", "--error-map", "--stats"):
        assert flag in out


def test_view_command_reaches_the_viewer_with_the_options(monkeypatch):
    calls = []
    fake = types.ModuleType("viewer.app")
    fake.__spec__ = importlib.machinery.ModuleSpec("viewer.app", None)
    fake.run = lambda scene, frames, size=None, script=None, opts=None, settings=None: \
        calls.append((scene, size, opts)) or 0
    import viewer
    monkeypatch.setitem(sys.modules, "viewer.app", fake)
    monkeypatch.setattr(viewer, "app", fake, raising=False)
    assert run("view", TEAPOT, "--size", "64x32", "--criterion", "fixed") == 0
    assert calls == [(TEAPOT, (64, 32), Options(criterion="fixed"))]


# ---- end to end -------------------------------------------------------------------------

def declared_entry_point() -> str:
    """The console script's target as pyproject.toml declares it, e.g. 'psrt.cli:main'."""
    import re
    return re.search(r'^psrt\s*=\s*"([^"]+)"', (REPO / "pyproject.toml").read_text(), re.M).group(1)


def test_console_script_end_to_end(tmp_path):
    exe = Path(sys.executable).parent / "psrt"
    if not exe.exists():
        pytest.skip("psrt console script not installed in this environment (pip install -e .)")
    module, function = declared_entry_point().split(":")
    if f"from {module} import {function}" not in exe.read_text():  # installed before the entry point moved
        reason = f"{exe} does not call {module}:{function} (reinstall: scripts/setup)"
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(reason)
        pytest.skip(reason)
    env = dict(os.environ, NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", str(REPO / ".numba_cache")))
    png, npz = tmp_path / "e2e.png", tmp_path / "e2e.npz"
    proc = subprocess.run([str(exe), "render", TEAPOT, "-o", str(png), "--size", "32x24", "--aov", str(npz)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert png_size(png) == (32, 24)
    check_contract(load_npz(npz), 32, 24)
    assert "32x24" in proc.stderr
    proc = subprocess.run([str(exe), "render", str(tmp_path / "none.json"), "-o", str(png)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 2 and "none.json" in proc.stderr and "Traceback" not in proc.stderr
