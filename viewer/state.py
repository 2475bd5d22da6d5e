"""The viewer's state: the only mutable UI state, owned by the UI thread.

`ViewSettings` holds the viewer-only display settings (tone mapping, overlay), a
tracer.record.Record like tracer.options.Options, so one widget builder, one validation
and one `--set name=value` parser serve both records.
"""
from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from tracer import record
from tracer.camera import View
from tracer.options import Options

DEFAULT_CHANNEL = "default"

_setting = partial(record.described, group="Display")


def overlay_names() -> tuple:
    """'none' and every non-categorical channel of tracer.stats (the viewer is generic over them)."""
    from tracer.stats import CHANNELS
    return ("none",) + tuple(n for n, ch in CHANNELS.items() if ch.scale != "categorical")


def colormap_names() -> tuple:
    from tracer.colormap import MAPS
    return (DEFAULT_CHANNEL,) + tuple(MAPS)


@dataclass(frozen=True)
class ViewSettings(record.Record):
    """How the traced image is shown; never changes what is traced."""

    NOUN = "setting"

    exposure: float = _setting(0.0, "exposure in stops applied to the shaded colour", lo=-8.0, hi=8.0)
    gamma: float = _setting(1.0, "extra display gamma on top of the sRGB colours (1: none)", lo=0.2, hi=5.0)
    tone: str = _setting("clamp", "tone curve: clamp to [0, 1], or Reinhard c/(1+c)", choices=("clamp", "reinhard"))
    overlay: str = _setting("none", "per-pixel channel drawn over the image", choices=overlay_names(),
                            group="Overlays")
    opacity: float = _setting(0.85, "overlay opacity", lo=0.0, hi=1.0, group="Overlays")
    colormap: str = _setting(DEFAULT_CHANNEL, "overlay colour map (default: the channel's own)",
                             choices=colormap_names(), group="Overlays")
    scale: str = _setting(DEFAULT_CHANNEL, "overlay value scale (default: the channel's own)",
                          choices=(DEFAULT_CHANNEL, "linear", "log"), group="Overlays")
    range: str = _setting("auto", "overlay range: min..max, mean + 3 sigma clamp (Dammertz 2.13), or manual",
                          choices=("auto", "3sigma", "manual"), group="Overlays")
    range_lo: float = _setting(0.0, "manual overlay range: low end", lo=-1e30, hi=1e30, group="Overlays",
                               when={"range": "manual"})
    range_hi: float = _setting(1.0, "manual overlay range: high end", lo=-1e30, hi=1e30, group="Overlays",
                               when={"range": "manual"})
    reference: bool = _setting(True, "trace the float64 reference after each frame (error statistics)",
                               group="Overlays")


def assign(opts: Options, settings: ViewSettings, text: str):
    """Apply `name=value` to the tracer options or, failing that, the view settings."""
    return record.assign((opts, settings), text)


@dataclass
class RenderState:
    """What the UI knows of the current render job (fed by worker events)."""

    job: int = 0
    phase: str = "idle"          # idle | preparing | coarse | full | reference | done | error | cancelled
    submitted: float = 0.0       # perf_counter when the job was requested
    started: float | None = None  # when its first tile finished (restart latency)
    key: tuple | None = None     # what was traced: (scene id, trace options, view, size)
    frame: object = None         # tracer.render.Frame being filled
    reference: object = None     # its float64 reference, once started
    colour: np.ndarray | None = None  # (H, W, 3) float32 shaded colours
    tiles_done: int = 0
    tiles_total: int = 0
    ref_done: int = 0
    ref_total: int = 0
    seconds: float = 0.0
    ref_seconds: float = 0.0
    stats: dict | None = None
    error_stats: dict | None = None


@dataclass
class Inspection:
    """The pixel under the inspector."""

    pixel: tuple
    trace: object                # tracer.trace_one.PixelTrace
    reference: object = None     # the float64 trace of the same ray
    step: int = -1               # chosen step for the box outlines (-1: the last)
    error: float | None = None   # L1 distance to the float64 hit
    view: View | None = None     # the view it was traced in
    opts: Options | None = None
    surface: dict | None = None  # the hit's NURBS surface, parameters and trim loops (surface_info)
    tree: object = None          # tracer.ray_tree.RayTree, traced after the pixel (None meanwhile)
    tree_error: str | None = None  # why the ray tree could not be traced
    ray: int = 0                 # the ray tree's row whose subdivision trace is shown (0: the primary)
    rows_drawn: int = 0          # ray tree rows the panel listed in its last frame (the scripted status)


@dataclass
class AppState:
    opts: Options = field(default_factory=Options)
    settings: ViewSettings = field(default_factory=ViewSettings)
    scene: object = None
    scene_path: str | None = None
    view: View | None = None
    home_view: View | None = None
    image_size: tuple = (0, 0)
    fixed_size: tuple | None = None
    render: RenderState = field(default_factory=RenderState)
    inspector: Inspection | None = None
    show_rays: bool = True               # draw the inspected pixel's secondary rays over the image
    hover: tuple | None = None           # image pixel under the cursor
    messages: list = field(default_factory=list)  # (time, level, text), newest last
    error: str | None = None             # the latest error, shown until dismissed
    bookmarks: list = field(default_factory=list)  # (name, View)
    recent: list = field(default_factory=list)
    show_help: bool = False
    open_path: str = ""
    pending_open: str | None = None      # set by drag-and-drop, the Scene panel or the script
    loading: tuple | None = None         # (file name, perf_counter since) while a load runs
    compiling: tuple | None = None       # (kernel variant label, perf_counter since) while one compiles
    inspecting: tuple | None = None      # (pixel, since, [variant labels it compiles]) while one is traced
    cancel_load: bool = False            # the Cancel button was pressed
    failed_loads: list = field(default_factory=list)  # one line per load that failed or was cancelled
    notes: list = field(default_factory=list)  # the status lines drawn over the image this frame
    pending_screenshot: str | None = None  # taken by the loop after drawing the view
    last_overlay: str = "effort"         # what the O key toggles back to
    output_dir: str = "."
    overlay_info: dict = field(default_factory=dict)  # legend: label, units, lo, hi, scale, specials, lut
    fps: float = 0.0
    frame_count: int = 0
    renders_started: int = 0
    renders_finished: int = 0
    renders_cancelled: int = 0
    latencies: list = field(default_factory=list)  # seconds from request to the worker starting it
    busy_frame_times: list = field(default_factory=list)  # UI frame times while a render runs

    def log(self, text: str, level: str = "info") -> None:
        self.messages.append((time.time(), level, text))
        del self.messages[:-200]
        if level == "error":
            self.error = text.split("\nTraceback")[0]  # the traceback stays in the message log

    def add_recent(self, path: str) -> None:
        path = os.path.abspath(path)
        self.recent = [path] + [p for p in self.recent if p != path][:9]


# --- persistence of recent files and camera bookmarks ------------------------------------

def settings_path() -> Path:
    return Path(os.environ.get("PSRT_VIEWER_SETTINGS", Path.home() / ".config" / "psrt" / "viewer.json"))


def view_to_json(view: View) -> dict:
    return {"eye": list(map(float, view.eye)), "look_at": list(map(float, view.look_at)),
            "up": list(map(float, view.up)), "fov_deg": float(view.fov_deg)}


def view_from_json(d: dict) -> View:
    return View(tuple(d["eye"]), tuple(d["look_at"]), tuple(d["up"]), float(d["fov_deg"]))


def load_persistent(state: AppState, path: Path | None = None) -> None:
    """Recent files and bookmarks from the settings file; a bad file is logged, not fatal."""
    path = path or settings_path()
    if not path.exists():
        return
    try:
        data = json.loads(path.read_text())
        state.recent = [str(p) for p in data.get("recent", [])][:10]
        state.bookmarks = [(b["name"], view_from_json(b["view"])) for b in data.get("bookmarks", [])]
    except (OSError, ValueError, KeyError, TypeError) as e:
        state.log(f"{path}: ignoring unreadable viewer settings ({e})", "warning")


def save_persistent(state: AppState, path: Path | None = None) -> None:
    path = path or settings_path()
    data = {"recent": state.recent,
            "bookmarks": [{"name": n, "view": view_to_json(v)} for n, v in state.bookmarks]}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=1))
    except OSError as e:
        state.log(f"{path}: cannot save viewer settings ({e.strerror or e})", "warning")
