"""Scripted viewer runs that keep their promises under failure and load: failed steps exit
non-zero with one line, waits are bounded by --timeout (not frames), loads and compiles never
stop the window drawing, Ctrl-C ends a long render at once.

Slow things are made to happen on cue by tests/view_hooks.py (a hold that ends only once the
window has drawn frames showing it), so no test depends on how fast the machine is.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pytest

from images import compare_images, read_png
from tracer.variants import label, variant_for
from viewer_util import (REPO, SCREENSHOT_TOLERANCE, TEAPOT, headless, read_status, run_view,  # noqa: F401
                         teapot, view_command, warm_kernels, xvfb)
from view_hooks import HOLD_FRAMES

F32_VARIANT = "f32 bicubic+bilinear bundles closest bvh"  # the teapot's (tracer.variants.label; 8x8 bundles)
INTERRUPT_BOUND = 5.0  # seconds from SIGINT to exit allowed here; about 0.3-0.6 s measured (README)


def one_line(err: str) -> str:
    """The run's stderr must be exactly one line (the failure), whatever else it says."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    return lines[0]


def test_the_teapot_variant_label():
    from tracer.geometry import prepare
    from tracer.options import Options
    from tracer.scene import load_scene
    assert label(variant_for(prepare(load_scene(TEAPOT), "f32"), Options())) == F32_VARIANT


def test_a_scene_that_fails_to_load_fails_the_run(xvfb, tmp_path):
    bad = tmp_path / "broken.json"
    bad.write_text('{"objects": [{"file": "teapot.bpt", "tranform": [1, 0]}]}')
    shot = tmp_path / "view.png"
    code, status, err = run_view(xvfb, [bad, "--size", "64x64", "--screenshot", shot], tmp_path)
    assert code == 5 and "broken.json" in one_line(err) and "tranform" in err
    assert status["scene"] is None and status["failure"] == one_line(err).removeprefix("psrt view: error: ")
    assert shot.exists()  # the outputs show what the window showed


def test_frames_do_not_bound_the_wait_for_the_render(xvfb, warm_kernels, tmp_path):
    """--frames 2 with a click: the render, the click and the inspector take many more frames,
    none of them spent waiting for nothing."""
    dump = tmp_path / "trace.json"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--frames", 2, "--click", "64,72",
                                        "--dump-inspector", dump], tmp_path)
    assert code == 0, err
    assert status["frames"] > 2 and dump.exists() and status["inspector"]["hit"]


def test_timeout_bounds_a_render_that_does_not_finish(xvfb, warm_kernels, tmp_path):
    """The render is held after its first tile: --frames does not end the wait, --timeout does."""
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--frames", 5, "--timeout", 8,
                                        "--screenshot", tmp_path / "view.png"], tmp_path, hooks="hold-render")
    line = one_line(err)
    assert code == 3 and "timed out after" in line and "(--timeout 8) waiting for" in line
    assert status["exit_code"] == 3 and status["seconds"] >= 8 and status["frames"] > 5
    # what it waited for: the load (a very slow machine), a compile, or the held render
    waited = "loading" if status["loading"] else "compiling" if "compiling" in line else "the render"
    assert f"waiting for {waited}" in line, line
    assert (tmp_path / "view.png").exists()


def test_the_window_draws_while_the_scene_loads(xvfb, warm_kernels, tmp_path, teapot):
    """The load holds until the window has drawn HOLD_FRAMES frames saying "loading teapot.json"."""
    shot = tmp_path / "view.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--screenshot", shot], tmp_path,
                                 hooks="hold-load")
    assert code == 0, err
    assert status["frames"] > HOLD_FRAMES and status["scene"] == str(TEAPOT) and status["loading"] is None
    compare_images(read_png(shot), headless(teapot), tmp_path, "after-slow-load", SCREENSHOT_TOLERANCE)


def test_cancel_leaves_the_previous_scene(xvfb, warm_kernels, tmp_path, teapot):
    """--load of a file whose load never ends: Cancel (pressed through ImGui) keeps the teapot; the
    thread still blocked in the load does not keep the process alive."""
    other = REPO / "sample_models" / "sphere.json"
    shot = tmp_path / "view.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--load", other, "--screenshot", shot],
                                 tmp_path, env={"PSRT_HOOK_FILE": other.name}, hooks="block-load,cancel-load")
    assert code == 5 and "sphere.json cancelled" in one_line(err)
    assert status["scene"] == str(TEAPOT) and status["loading"] is None
    assert any("cancelled loading" in m["text"] for m in status["messages"])
    compare_images(read_png(shot), headless(teapot), tmp_path, "after-cancel", SCREENSHOT_TOLERANCE)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_never_freezes_the_window(xvfb, warm_kernels, tmp_path, teapot):
    """A FIFO nobody writes: its load blocks until cancelled (or the loader refuses it at once);
    either way the window keeps drawing, the teapot stays, and the run fails saying why."""
    fifo = tmp_path / "scene.bpt"
    os.mkfifo(fifo)
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--load", fifo,
                                        "--screenshot", tmp_path / "view.png"], tmp_path,
                                 env={"PSRT_HOOK_FILE": fifo.name}, hooks="cancel-load")
    line = one_line(err)
    assert code == 5 and "scene.bpt" in line, err
    assert status["scene"] == str(TEAPOT) and status["render"]["phase"] in ("reference", "done")


def test_ctrl_c_during_a_long_render_exits_at_once(xvfb, warm_kernels, tmp_path):
    """SIGINT once full-resolution tiles arrive (big f64 tiles on one thread: the render has far
    to go, and a tile is being traced when the signal comes): exit 130 within INTERRUPT_BOUND."""
    cmd, env = view_command(xvfb, [TEAPOT, "--size", "512x512", "--precision", "f64", "--set", "tile_size=256",
                                   "--set", "threads=1", "--wait-reference", "--screenshot", tmp_path / "v.png"],
                            tmp_path, hooks="announce-render")
    proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()  # blocks until the first full-resolution tile is shown
        assert line.strip() == "RENDERING", proc.stderr.read()
        sent = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(60)
        took = time.perf_counter() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
    err = proc.stderr.read()
    print(f"SIGINT to exit: {took:.3f} s")
    assert code == 130 and one_line(err) == "psrt view: error: interrupted", err
    status = read_status(tmp_path, code, err)
    assert status["exit_code"] == 130 and status["render"]["phase"] in ("full", "reference")
    assert not (tmp_path / "v.png").exists()  # an interrupted run writes only its status
    assert took < INTERRUPT_BOUND, f"{took:.2f} s from SIGINT to exit"


def _check_compile_shown(status, variant=F32_VARIANT, min_frames=HOLD_FRAMES):
    """The window drew frames while `variant` compiled, its note counting the seconds up."""
    seen = status["compiles"].get(variant)
    assert seen is not None, status["compiles"]
    assert seen["frames"] >= min_frames, seen
    seconds = [int(n.rsplit("... ", 1)[1].split()[0]) for n in seen["notes"]]
    assert all(n.startswith(f"compiling {variant}... ") for n in seen["notes"]), seen["notes"]
    assert seconds == sorted(seconds) and seconds[-1] >= 1, seen["notes"]
    return seen


def test_the_window_shows_the_compile_and_then_the_image(xvfb, warm_kernels, tmp_path, teapot):
    """The compile step holds until the window has drawn HOLD_FRAMES frames saying "compiling
    <variant>... N s" over the image, for at least two seconds of Python work (the GIL changes
    hands as in numba's compiler); then the image arrives."""
    shot, during = tmp_path / "view.png", tmp_path / "compiling.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--set", "reference=false", "--screenshot",
                                        shot], tmp_path, env={"PSRT_HOOK_SHOT": str(during)}, hooks="hold-compile")
    assert code == 0, err
    _check_compile_shown(status)
    compare_images(read_png(shot), headless(teapot), tmp_path, "after-compile", SCREENSHOT_TOLERANCE)
    window = read_png(during)
    note = window[8:40, 8:300].astype(int)  # the notes window at the image's top-left corner
    warm = (note[..., 0] > 180) & (note[..., 1] > 140) & (note[..., 2] < 120)  # its amber text
    assert warm.sum() > 50, "no compiling note over the image in the window grabbed mid-compile"


def test_the_window_draws_while_the_inspector_compiles(xvfb, warm_kernels, tmp_path, teapot):
    """A click's first trace compiles the step-recording kernels: on its own thread, the window
    drawing HOLD_FRAMES frames saying so meanwhile; then the dump is the headless trace."""
    from tracer.options import Options
    from tracer.trace_one import trace_pixel
    dump = tmp_path / "trace.json"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--click", "64,72", "--dump-inspector", dump],
                                 tmp_path, hooks="hold-trace")
    assert code == 0, err
    got, want = json.loads(dump.read_text()), trace_pixel(teapot, Options(), 64, 72, size=(128, 128))
    assert got["hit"] and got["patch"] == want.patch and len(got["steps"]) == len(want.events)
    assert any("pixel 64,72: hit patch" in m["text"] for m in status["messages"])


@pytest.mark.skipif(not os.environ.get("PSRT_COLD_COMPILE_TEST"),
                    reason="compiles the teapot's kernel from an empty cache (1-3 min); set PSRT_COLD_COMPILE_TEST=1")
def test_cold_start_shows_the_real_compile(xvfb, tmp_path, teapot):
    """An empty numba cache: the real compile, with the window drawing throughout (no gap of
    more than half of it), then the image."""
    shot = tmp_path / "view.png"
    code, status, err = run_view(xvfb, [TEAPOT, "--size", "128x128", "--set", "reference=false", "--screenshot",
                                        shot], tmp_path, env={"NUMBA_CACHE_DIR": str(tmp_path / "numba")},
                                 timeout=900)
    assert code == 0, err
    kernels = {k["variant"]: k for k in status["kernels"]}
    assert kernels[F32_VARIANT]["cached"] is False
    seen = _check_compile_shown(status, min_frames=10)
    assert seen["max_gap_ms"] < 500 * kernels[F32_VARIANT]["seconds"], seen
    compare_images(read_png(shot), headless(teapot), tmp_path, "after-cold-compile", SCREENSHOT_TOLERANCE)
    print(f"cold compile {kernels[F32_VARIANT]['seconds']:.1f} s, {seen['frames']} frames drawn meanwhile, "
          f"longest frame {seen['max_gap_ms']:.0f} ms")
