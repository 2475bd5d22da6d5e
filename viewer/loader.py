"""Opening scene files off the UI thread, with a cancel; a file that fails leaves the previous scene.

A load (parse, prepare the geometry, the scene's camera) runs on a daemon thread: a FIFO, a
slow disk or a huge file cannot freeze the window, and the UI shows "loading NAME..." with a
Cancel button meanwhile. A cancelled or superseded load is abandoned (a thread blocked in the
kernel cannot be interrupted; being a daemon, it cannot keep the process alive either) and its
result, whenever it comes, is dropped. Only the UI thread touches the viewer state.
"""
from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field

from tracer.camera import view_of
from tracer.errors import SceneError
from tracer.geometry import prepare
from tracer.scene import load_scene


def read_scene(path: str, precision: str):
    """(scene, prepared geometry, home view) of `path`, or raise with a message naming the file."""
    scene = load_scene(path)
    geom = prepare(scene, precision)  # fails early on what the kernel cannot trace
    home = view_of(scene)
    home.basis()  # a degenerate camera is an error now, not in the worker
    return scene, geom, home


def failure_message(path: str, e: BaseException) -> str:
    """One line: what went wrong opening `path` (SceneError already names the file)."""
    if isinstance(e, (SceneError, ValueError, OSError)):
        where = "" if path in str(e) else f"{path}: "
        return f"cannot open {where}{e}"
    return f"cannot open {path}: {type(e).__name__}: {e}"  # a loader bug must not take the window down


@dataclass
class Load:
    """One requested load; `result` is set (once) by its thread: (scene, geom, home) or an exception."""

    path: str
    precision: str
    number: int
    started: float = field(default_factory=time.perf_counter)
    result: object = None
    seconds: float = 0.0
    done: threading.Event = field(default_factory=threading.Event)

    @property
    def name(self) -> str:
        return os.path.basename(self.path) or self.path

    def run(self) -> None:
        try:
            self.result = read_scene(self.path, self.precision)
        except BaseException as e:  # reported on the UI thread
            self.result = e
        self.seconds = time.perf_counter() - self.started
        self.done.set()


class SceneLoader:
    """At most one load in flight; the newest request wins."""

    def __init__(self):
        self.current: Load | None = None
        self.count = 0

    def start(self, path, precision: str) -> Load:
        """Start loading `path` (abandoning a load in flight)."""
        self.count += 1
        load = Load(os.fspath(path), precision, self.count)
        self.current = load
        threading.Thread(target=load.run, name=f"psrt-load-{load.number}", daemon=True).start()
        return load

    def cancel(self) -> Load | None:
        """Abandon the load in flight; returns it (None if there was none)."""
        load, self.current = self.current, None
        return load

    def poll(self) -> Load | None:
        """The load in flight once it has finished (it is then no longer current), else None."""
        load = self.current
        if load is None or not load.done.is_set():
            return None
        self.current = None
        return load


def adopt(state, geometry, load: Load) -> bool:
    """Make a finished load the current scene; on failure log it and keep the current scene."""
    result = load.result
    if isinstance(result, BaseException):
        message = failure_message(load.path, result)
        state.failed_loads.append(message)
        state.log(message + ("; keeping the current scene" if state.scene else ""), "error")
        return False
    scene, geom, home = result
    geometry.adopt(scene, load.precision, geom)
    state.scene, state.scene_path = scene, os.path.abspath(load.path)
    state.home_view = state.view = home
    state.inspector = None
    state.render.key = None
    state.error = None
    state.add_recent(load.path)
    state.log(f"opened {load.path}: {scene.n_patches} patches ({load.seconds:.1f} s)")
    return True

