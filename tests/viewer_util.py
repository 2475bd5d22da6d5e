"""Xvfb for the viewer tests, and running `psrt view` scripted in a subprocess.

The window runs in a subprocess so an X error or a GL crash fails one test, not the run.
Without Xvfb the window tests skip with the reason, except in CI (CI=true), where they fail:
scripts/setup installs Xvfb and Mesa.
"""
from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TEAPOT = REPO / "sample_models" / "teapot.json"
SIZE = (128, 128)  # the window tests' image
# GL converts the same float colours to 8 bits (round to nearest) as tracer.colormap.to_uint8;
# one level allows for the driver's float rounding at exact .5 boundaries.
SCREENSHOT_TOLERANCE = 1
RUN_TIMEOUT = 300  # seconds per viewer run: a bound for a hung run, far above a run on a busy machine


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() in ("1", "true", "yes")


class Xvfb:
    """An Xvfb server on a free display number (it picks it and tells us through a pipe)."""

    def __init__(self, screen: str = "1280x800x24"):
        read_fd, write_fd = os.pipe()
        self.proc = subprocess.Popen(["Xvfb", "-displayfd", str(write_fd), "-screen", "0", screen,
                                      "-nolisten", "tcp"], pass_fds=(write_fd,),
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        os.close(write_fd)
        number = b""
        try:
            while not number.endswith(b"\n"):
                ready, _, _ = select.select([read_fd], [], [], 10.0)
                chunk = os.read(read_fd, 64) if ready else b""
                if not chunk:
                    err = self.proc.stderr.read().decode(errors="replace") if self.proc.poll() is not None else ""
                    self.stop()
                    raise RuntimeError(f"Xvfb did not report a display number within 10 s. {err}")
                number += chunk
        finally:
            os.close(read_fd)
        self.display = f":{int(number.strip())}"

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()


@pytest.fixture(scope="session")
def xvfb():
    if shutil.which("Xvfb") is None:
        reason = "Xvfb is not installed (scripts/setup installs it: apt-get install xvfb)"
        if in_ci():
            pytest.fail(reason + "; in CI the viewer tests must run")
        pytest.skip(reason)
    server = Xvfb()
    yield server
    server.stop()


def view_command(xvfb, args, tmp_path, env=None, hooks=None, timeout=RUN_TIMEOUT):
    """(command, environment) of `psrt view ARGS --status S` under xvfb, through tests/view_hooks.py
    when `hooks` are given. Without a --timeout in ARGS the run gets one a little shorter than
    `timeout`, so a run that cannot finish still says what it was waiting for."""
    args = [str(a) for a in args]
    if "--timeout" not in args:
        args += ["--timeout", str(timeout - 15)]  # the run gives up and writes its status first
    args += ["--status", str(tmp_path / "status.json")]
    head = [sys.executable, str(REPO / "tests" / "view_hooks.py"), hooks, "--"] if hooks else \
        [sys.executable, "-m", "viewer.cli_view"]
    full_env = {**os.environ, "DISPLAY": xvfb.display,
                "PSRT_VIEWER_SETTINGS": str(tmp_path / "viewer-settings.json"), **(env or {})}
    full_env.setdefault("NUMBA_CACHE_DIR", str(REPO / ".numba_cache"))
    return head + args, full_env


def read_status(tmp_path, returncode, stderr):
    status = tmp_path / "status.json"
    data = json.loads(status.read_text()) if status.exists() else None
    if data is None:
        raise AssertionError(f"viewer wrote no status (exit {returncode}):\n{stderr[-4000:]}")
    return data


def run_view(xvfb, args, tmp_path, env=None, timeout=RUN_TIMEOUT, hooks=None):
    """Run `psrt view ARGS --status S` under xvfb (view_command); returns (returncode, status, stderr)."""
    cmd, full_env = view_command(xvfb, args, tmp_path, env, hooks, timeout)
    proc = subprocess.run(cmd, cwd=REPO, env=full_env, capture_output=True, text=True, timeout=timeout)
    return proc.returncode, read_status(tmp_path, proc.returncode, proc.stderr), proc.stderr


@pytest.fixture(scope="module")
def teapot():
    from tracer.scene import load_scene
    return load_scene(TEAPOT)


@pytest.fixture(scope="module")
def warm_kernels(teapot):
    """Compile (or load) the kernels the viewer uses once, here, so that a cold numba cache
    costs the first window test a compile it cannot finish within its time limit."""
    from tracer.options import Options
    from tracer.render import reference_frame, render
    from tracer.trace_one import trace_pixel
    frame = render(teapot, Options(), size=(4, 4))
    reference_frame(teapot, frame)
    render(teapot, Options(bundle="1x1"), size=(4, 4))  # (single rays: the itembuffer tests' scattered units)
    trace_pixel(teapot, Options(), 2, 2, size=(4, 4))
    trace_pixel(teapot, Options(precision="f64", criterion="float"), 2, 2, size=(4, 4))


def headless(scene, opts=None, size=SIZE):
    """What the view must show: tracer.render + tracer.shade, quantised as the CLI writes PNGs."""
    from tracer.colormap import to_uint8
    from tracer.options import Options
    from tracer.render import render
    from tracer.shade import shade
    opts = opts or Options()
    return to_uint8(shade(render(scene, opts, size=size), scene, opts.mode))
