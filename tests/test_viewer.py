"""The viewer: pure parts without a display, and the real window under Xvfb (scripted runs).

Window runs are small (128x128 image) and each runs in its own subprocess (viewer_util).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tracer.camera import View, primary_rays, view_of
from tracer.colormap import to_uint8
from tracer.geometry import prepare
from tracer.options import Options
from tracer.pixel_order import fills_rect
from tracer.render import render, work_units
from tracer.shade import shade
from tracer.trace_one import trace_pixel
from images import compare_images, read_png
from viewer_util import (RUN_TIMEOUT, SCREENSHOT_TOLERANCE, SIZE, TEAPOT, headless, run_view, teapot,  # noqa: F401
                         warm_kernels, xvfb)

TEAPOT_PIXEL = (64, 72)      # on the teapot's body
BACKGROUND_PIXEL = (4, 2)    # above the horizon: misses everything
NEAR_MISS_PIXEL = (70, 35)   # passes through patch boxes beside the lid and misses the surface


# ---- no display needed --------------------------------------------------------------------

def test_the_inspector_says_a_bundled_frame_s_ray_was_traced_alone():
    """A frame traced in bundles counts each pixel's boxes in its bundle's order of visits; the
    inspector's trace is of the ray alone, and its summary says so."""
    from types import SimpleNamespace
    from viewer.state import Inspection
    from viewer.ui_inspector import summary_rows
    trace = SimpleNamespace(pixel=(1, 2), hit=False, effort=42, steps_f=[0, 0, 0], truncated=False)
    for opts, note in ((Options(bundle="8x8"), " (traced alone)"), (Options(bundle="1x1"), ""),
                       (Options(bundle="8x8", accel="kdtree"), ""), (None, "")):  # (bundles go through the BVH)
        assert dict(summary_rows(Inspection((1, 2), trace, opts=opts)))["effort"] == "42 box tests" + note


def test_camera_controls_keep_their_invariants():
    from viewer import camera_control as cc
    v = View((6.0, -9.0, 5.0), (0.0, 0.0, 1.5), (0.0, 0.0, 1.0), 35.0)
    dist = np.linalg.norm(np.subtract(v.eye, v.look_at))
    o = cc.orbit(v, 40, -25)
    assert o.look_at == v.look_at and math.isclose(np.linalg.norm(np.subtract(o.eye, o.look_at)), dist)
    p = cc.pan(v, 10, 5, 128)
    assert np.allclose(np.subtract(p.eye, v.eye), np.subtract(p.look_at, v.look_at))
    z = cc.zoom(v, 2)
    assert math.isclose(np.linalg.norm(np.subtract(z.eye, z.look_at)), dist * cc.ZOOM_PER_NOTCH ** 2)
    for _ in range(200):  # orbiting over the pole stops short of it
        v = cc.orbit(v, 0, 50)
    v.basis()


def test_projection_matches_primary_rays():
    """A point along pixel (x, y)'s ray projects to that pixel's centre with the GL matrix."""
    from viewer.display import view_projection
    view = View((6.0, -9.0, 5.0), (0.0, 0.0, 1.5), (0.0, 0.0, 1.0), 35.0)
    w, h = 160, 96
    origins, dirs = primary_rays(view, w, h, "f64")
    m = view_projection(view, w, h)
    for x, y in ((0, 0), (159, 95), (80, 10), (3, 77)):
        p = m @ np.append(origins[y, x] + 7.0 * dirs[y, x], 1.0)
        ndc = p[:2] / p[3]
        col, row_from_bottom = (ndc[0] + 1) / 2 * w, (ndc[1] + 1) / 2 * h
        assert abs(col - (x + 0.5)) < 1e-6 and abs((h - row_from_bottom) - (y + 0.5)) < 1e-6


def test_pixel_window_mapping_round_trips():
    from viewer.picking import pixel_to_window, window_to_pixel
    for region, size in (((0, 0, 128, 128), (128, 128)), ((10, 20, 300, 150), (600, 300))):
        for px, py in ((0, 0), (size[0] - 1, size[1] - 1), (37, 41)):
            assert window_to_pixel(region, size, *pixel_to_window(region, size, px, py)) == (px, py)
    assert window_to_pixel((0, 0, 128, 128), (128, 128), 128.0, 5.0) is None


def test_set_reaches_options_and_view_settings():
    from viewer.state import ViewSettings, assign
    opts, settings = assign(Options(), ViewSettings(), "criterion=adaptive")
    opts, settings = assign(opts, settings, "overlay=error")
    assert opts.criterion == "adaptive" and settings.overlay == "error"
    with pytest.raises(ValueError, match="unknown option"):
        assign(opts, settings, "nonsense=1")
    with pytest.raises(ValueError, match="overlay"):
        assign(opts, settings, "overlay=rainbow")


def test_script_triggers_parse():
    from viewer.script import parse_at
    assert parse_at("12:mode=normal") == (12, "mode=normal")
    assert parse_at("mid-render:criterion=fixed") == ("mid-render", "criterion=fixed")
    assert parse_at("after-render:mode=uv") == ("after-render", "mode=uv")
    with pytest.raises(ValueError, match="after-render"):
        parse_at("later:mode=uv")


def test_option_widgets_know_which_fields_apply():
    from dataclasses import fields

    from viewer.state import ViewSettings
    from viewer.ui_fields import applies
    by_name = {f.name: f for f in fields(Options)}
    assert applies(Options(criterion="fixed"), by_name["fixed_size"])
    assert not applies(Options(criterion="float"), by_name["fixed_size"])
    assert applies(Options(criterion="adaptive"), by_name["pixel_fraction"])
    assert applies(Options(), by_name["split"])
    assert applies(Options(), by_name["bundle"]) and not applies(Options(accel="grid"), by_name["bundle"])
    range_lo = {f.name: f for f in fields(ViewSettings)}["range_lo"]
    assert not applies(ViewSettings(), range_lo) and applies(ViewSettings(range="manual"), range_lo)


def run_worker(scene, opts, on_first_tile=None):
    """One job of the viewer's render worker at SIZE, no window: [(event, payload)] up to the
    frame. on_first_tile(events), if given, runs while the render is held after its first
    full-resolution unit."""
    from viewer.worker import GeometryCache, Job, RenderWorker
    worker = RenderWorker(GeometryCache())
    hold = worker.hold_mid_render() if on_first_tile is not None else None
    events = []
    try:
        worker.submit(Job(1, scene, opts, view_of(scene), SIZE, reference=False))
        while not events or events[-1][0] not in ("frame", "error", "cancelled"):
            kind, _, payload = worker.events.get(timeout=RUN_TIMEOUT)
            events.append((kind, payload))
            if kind == "tile" and hold is not None and not hold.is_set():
                on_first_tile(events)
                hold.set()
    finally:
        worker.stop()
    assert events[-1][0] == "frame", events[-1]
    return events


@pytest.mark.parametrize("order", ["scanline", "peano", "itembuffer"])
def test_the_worker_hands_out_units_in_the_order_s_sequence(warm_kernels, teapot, order):
    """One render thread: units are reported in the order they are handed out, which is the
    order's own sequence (Peano: the top-left quadrant first), or for scanline the same tiles
    from the centre out."""
    opts = Options(order=order, tile_size=16, threads=1)
    events = run_worker(teapot, opts)
    rects = [unit.rect for kind, unit in events if kind == "tile"]
    units = work_units(*SIZE, opts, prepare(teapot, "f32"), view_of(teapot))
    assert len(rects) == len(units) == 64
    if order == "scanline":
        assert sorted(rects) == sorted(u.rect for u in units)
        y0, y1, x0, x1 = rects[0]
        assert y0 <= 64 <= y1 and x0 <= 64 <= x1  # centre out
    else:
        assert rects == [u.rect for u in units]
    if order == "peano":
        assert all(y1 <= 64 and x1 <= 64 for y0, y1, x0, x1 in rects[:16])


def test_a_scattered_unit_paints_only_its_own_pixels(warm_kernels, teapot):
    """Item buffer: held after its first unit, the worker's colours are that unit's shaded
    pixels over the coarse preview, although its rect holds many pixels it does not trace."""
    from viewer.worker import COARSE, upscale
    want = shade(render(teapot, Options(), size=SIZE), teapot)
    seen = {}

    def first_tile(events):
        (_, (coarse, rgb, _, _)), = [e for e in events if e[0] == "coarse"]
        (_, (_, colour)), = [e for e in events if e[0] == "frame_start"]
        seen.update(unit=events[-1][1], colour=colour.copy(), preview=upscale(rgb, COARSE, SIZE))

    events = run_worker(teapot, Options(order="itembuffer", tile_size=16, threads=1, bundle="1x1"), first_tile)
    unit, colour, preview = seen["unit"], seen["colour"], seen["preview"]
    assert not fills_rect(unit.pixels, unit.rect)
    mine = np.zeros(colour.shape[:2], bool)
    mine[unit.pixels[:, 0], unit.pixels[:, 1]] = True
    y0, y1, x0, x1 = unit.rect
    others = ~mine
    others[:y0], others[y1:], others[:, :x0], others[:, x1:] = False, False, False, False
    assert np.any(np.abs(preview - want)[others].max(axis=-1) > 0.1), "the check could not fail"
    assert np.array_equal(colour[mine], want[mine]) and np.array_equal(colour[~mine], preview[~mine])
    (_, (_, final)), = [e for e in events if e[0] == "frame_start"]
    assert np.array_equal(final, want)


def test_box_outlines_end_with_the_hit_box(teapot):
    from viewer.picking import outline_vertices
    from viewer.state import Inspection
    trace = trace_pixel(teapot, Options(), *TEAPOT_PIXEL, size=SIZE)
    verts = outline_vertices(Inspection(TEAPOT_PIXEL, trace, step=-1))
    assert verts.shape[1] == 7 and len(verts) % 24 == 0
    hit = trace.hit_step()
    last = verts[-24:, :3]
    assert np.allclose(last.min(axis=0), trace.steps_f[hit, 4:7], rtol=1e-6, atol=1e-6)
    assert np.allclose(last.max(axis=0), trace.steps_f[hit, 7:10], rtol=1e-6, atol=1e-6)


# ---- the window under Xvfb ----------------------------------------------------------------

def test_first_frame_matches_headless_render(xvfb, warm_kernels, tmp_path, teapot):
    shot = tmp_path / "view.png"
    # --wait-reference: the float64 kernel's note ("compiling ...") would otherwise be over the image
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--screenshot", shot, "--wait-reference",
                                        "--window-screenshot", tmp_path / "window.png"], tmp_path)
    assert code == 0, err
    assert status["render"]["phase"] in ("reference", "done") and status["renders"]["finished"] >= 1
    assert status["render"]["tiles_done"] == status["render"]["tiles_total"] > 0
    actual = read_png(shot)
    assert actual.shape == (128, 128, 3) and actual.std() > 20, "screenshot is blank"
    compare_images(actual, headless(teapot), tmp_path, "first-frame", SCREENSHOT_TOLERANCE)
    window = read_png(tmp_path / "window.png")
    assert window.shape[1] > 128 and np.array_equal(window[:128, :128], actual)  # the view at 1:1, top-left


def click_and_dump(xvfb, tmp_path, x, y):
    """Run the viewer, click pixel (x, y), and return (inspector dump, status)."""
    dump = tmp_path / "trace.json"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--click", f"{x},{y}",
                                        "--dump-inspector", dump], tmp_path)
    assert code == 0, err
    return json.loads(dump.read_text()), status


def test_click_on_teapot_dumps_the_pixel_trace(xvfb, warm_kernels, tmp_path, teapot):
    x, y = TEAPOT_PIXEL
    got, _ = click_and_dump(xvfb, tmp_path, x, y)
    want = trace_pixel(teapot, Options(), x, y, size=SIZE)
    assert got["pixel"] == [x, y] and got["hit"] is True and want.hit
    assert got["patch"] == want.patch
    assert np.array_equal(np.array(got["position"]), want.position)  # same kernel, same ray: bit-identical
    steps = got["steps"]
    assert [s["event"] for s in steps] == want.events
    assert np.array_equal([s["box_min"] + s["box_max"] for s in steps], want.steps_f[:, 4:10])
    reported = steps[got["hit_step"]]  # the step whose box the inspector reports as the hit box
    assert got["hit_step"] == want.hit_step() and reported["event"] == "hit"
    assert reported["box_min"] == got["box_min"] and reported["box_max"] == got["box_max"]
    assert got["summary"]["events"]["hit"] == want.events.count("hit") >= 1
    assert got["reference"]["hit"] is True and got["error"] is not None  # the float64 trace of the same ray


@pytest.mark.parametrize("pixel, boxes_met", [(BACKGROUND_PIXEL, False), (NEAR_MISS_PIXEL, True)],
                         ids=["background", "near-miss"])
def test_click_off_the_surface_reports_a_miss(xvfb, warm_kernels, tmp_path, teapot, pixel, boxes_met):
    x, y = pixel
    got, status = click_and_dump(xvfb, tmp_path, x, y)
    assert got["pixel"] == [x, y] and got["hit"] is False and got["patch"] == -1
    assert status["inspector"]["hit"] is False
    want = trace_pixel(teapot, Options(), x, y, size=SIZE)
    assert [s["event"] for s in got["steps"]] == want.events and (len(want.events) > 0) == boxes_met
    assert got["hit_step"] == -1 and got["summary"]["events"]["hit"] == 0 and "hit" not in want.events
    assert got["reference"]["hit"] is False and got["error"] is None


@pytest.mark.parametrize("name, value", [("criterion", "adaptive"), ("order", "peano")])
def test_changing_a_traced_option_mid_render_re_renders(xvfb, warm_kernels, tmp_path, teapot, name, value):
    """The criterion changes the image; the pixel order (a Coherence option) only how it is
    traced, and restarts the render all the same."""
    shot = tmp_path / "view.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--set", "tile_size=16",
                                        "--at", f"mid-render:{name}={value}", "--screenshot", shot], tmp_path)
    assert code == 0, err
    applied = status["applied"][0]
    assert applied["phase"] == "full" and 0 < applied["tiles_done"] < applied["tiles_total"], applied
    assert status["renders"]["started"] == 2 and status["renders"]["cancelled"] >= 1
    assert status["render"]["traced_options"][name] == value
    compare_images(read_png(shot), headless(teapot, Options(tile_size=16).with_(**{name: value})), tmp_path,
                   value, SCREENSHOT_TOLERANCE)


@pytest.mark.parametrize("when, order", [("mid-render", "scanline"), ("after-render", "scanline"),
                                         ("mid-render", "itembuffer")])
def test_display_mode_change_re_shades_without_re_tracing(xvfb, warm_kernels, tmp_path, teapot, when, order):
    """The display mode is not traced: changed while tiles arrive (the script holds the render
    after its first tile until the change is made) or after the frame, it never restarts it.
    Item buffer: the pixels traced so far, scattered, are re-shaded."""
    shot = tmp_path / "view.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--set", "tile_size=16", "--set", f"order={order}",
                                        "--at", f"{when}:mode=normal", "--screenshot", shot], tmp_path)
    assert code == 0, err
    applied = status["applied"][0]
    if when == "mid-render":
        assert applied["phase"] == "full" and 0 < applied["tiles_done"] < applied["tiles_total"], applied
    else:
        assert applied["phase"] in ("reference", "done"), applied
    assert status["renders"]["started"] == 1 and status["renders"]["cancelled"] == 0
    assert status["render"]["shaded_mode"] == "normal"
    compare_images(read_png(shot), headless(teapot, Options(mode="normal", tile_size=16)), tmp_path, "normal",
                   SCREENSHOT_TOLERANCE)


@pytest.mark.parametrize("order", ["scanline", "itembuffer"])
@pytest.mark.parametrize("channel", ["error", "effort"])
def test_overlay_matches_the_cli_channel_map(xvfb, warm_kernels, tmp_path, teapot, channel, order):
    """At opacity 1 the GPU-mapped overlay is the CLI's map of the same frame and reference
    (filled unit by unit: with the item buffer, scattered pixels of the frame or the reference)."""
    from tracer.render import AOV_NAMES, reference_frame
    from tracer.stats import channel_rgb
    shot, aov = tmp_path / "view.png", tmp_path / "aov.npz"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--set", f"overlay={channel}",
                                        "--set", f"order={order}",
                                        "--set", "opacity=1", "--wait-reference", "--screenshot", shot, "--aov", aov], tmp_path)
    assert code == 0, err
    assert status["render"]["phase"] == "done" and status["render"]["error_stats"]["compared"] > 0
    assert sorted(np.load(aov).files) == sorted(AOV_NAMES)
    frame = render(teapot, Options(), size=SIZE)
    ref = reference_frame(teapot, frame)
    lo, hi = status["overlay"]["lo"], status["overlay"]["hi"]
    expected, _ = channel_rgb(channel, frame, ref, vrange=(lo, hi))
    # GPU log vs numpy log10 may pick the neighbouring entry of the 256-entry map: 3 levels.
    compare_images(read_png(shot), to_uint8(expected), tmp_path, f"{channel}-overlay", 3)


def test_itembuffer_units_appear_over_the_preview(xvfb, warm_kernels, tmp_path, teapot):
    """order=itembuffer in the window: grabbed while the render is held after its first unit,
    the view is the coarse preview with only that unit's scattered pixels traced; let go, the
    render completes and shows the scanline image."""
    from viewer.worker import COARSE, upscale
    shot, first = tmp_path / "view.png", tmp_path / "first.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--set", "order=itembuffer", "--set",
                                        "tile_size=16", "--set", "threads=1", "--set", "bundle=1x1", "--screenshot",
                                        shot], tmp_path,
                                 env={"PSRT_HOOK_SHOT": str(first)}, hooks="shot-first-tile")
    assert code == 0, err
    assert status["render"]["traced_options"]["order"] == "itembuffer" and status["renders"]["started"] == 1
    compare_images(read_png(shot), headless(teapot), tmp_path, "itembuffer", SCREENSHOT_TOLERANCE)
    opts = Options(order="itembuffer", tile_size=16, bundle="1x1")
    coarse = render(teapot, opts, size=(SIZE[0] // COARSE, SIZE[1] // COARSE))
    expected = upscale(shade(coarse, teapot), COARSE, SIZE)
    unit = work_units(*SIZE, opts, prepare(teapot, "f32"), view_of(teapot))[0]
    assert not fills_rect(unit.pixels, unit.rect)
    rows, cols = unit.pixels[:, 0], unit.pixels[:, 1]
    expected[rows, cols] = shade(render(teapot, Options(), size=SIZE), teapot)[rows, cols]
    compare_images(read_png(first), to_uint8(expected), tmp_path, "itembuffer-first-unit", SCREENSHOT_TOLERANCE)


def test_malformed_file_keeps_the_teapot_and_shows_the_error(xvfb, warm_kernels, tmp_path, teapot):
    bad = tmp_path / "broken.json"
    bad.write_text('{"objects": [{"file": "teapot.bpt", "tranform": [1, 0]}]}')
    shot = tmp_path / "view.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--load", bad,
                                        "--screenshot", shot], tmp_path)
    assert code == 5, err  # the scripted load failed: the run says so, in one line
    assert err.strip().count("\n") == 0 and "broken.json" in err and "tranform" in err, err
    assert status["scene"] == str(TEAPOT) and status["n_patches"] == teapot.n_patches
    assert status["error"] and "broken.json" in status["error"] and "tranform" in status["error"]
    compare_images(read_png(shot), headless(teapot), tmp_path, "after-bad-file", SCREENSHOT_TOLERANCE)


def test_broken_shader_is_reported_not_fatal(xvfb, warm_kernels, tmp_path):
    from viewer.display import PROGRAMS, SHADER_DIR
    shaders = tmp_path / "shaders"
    shaders.mkdir()
    for files in PROGRAMS.values():
        for f in files:
            (shaders / f).write_text((SHADER_DIR / f).read_text())
    (shaders / "image.frag").write_text("#version 330 core\nvoid main() { this is not glsl; }\n")
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "64x64"], tmp_path,
                                 env={"PSRT_SHADER_DIR": str(shaders)})
    assert code == 0, err
    assert status["shader_error"] and "image.frag" in status["shader_error"]
    assert status["render"]["phase"] in ("reference", "done")
