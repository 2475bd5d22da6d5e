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
RUN_TIMEOUT = 90  # seconds per viewer run (a cold numba cache compiles the kernels first)


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


def run_view(xvfb, args, tmp_path, env=None, timeout=RUN_TIMEOUT):
    """Run `python -m viewer.cli_view ARGS --status S` under xvfb; returns (returncode, status, stderr)."""
    status = tmp_path / "status.json"
    cmd = [sys.executable, "-m", "viewer.cli_view", *map(str, args), "--status", str(status)]
    full_env = {**os.environ, "DISPLAY": xvfb.display,
                "PSRT_VIEWER_SETTINGS": str(tmp_path / "viewer-settings.json"), **(env or {})}
    full_env.setdefault("NUMBA_CACHE_DIR", str(REPO / ".numba_cache"))
    proc = subprocess.run(cmd, cwd=REPO, env=full_env, capture_output=True, text=True, timeout=timeout)
    data = json.loads(status.read_text()) if status.exists() else None
    if data is None:
        raise AssertionError(f"viewer wrote no status (exit {proc.returncode}):\n{proc.stderr[-4000:]}")
    return proc.returncode, data, proc.stderr
