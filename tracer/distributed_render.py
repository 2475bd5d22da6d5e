"""A render whose work units run on Dask workers (`psrt render --scheduler`; issue 14 item 3).

The units (render.work_units, in the options' pixel order) are cut into groups; a task is the
scene's path, the options, the image size and a group's unit indices. Each worker loads the scene
and prepares its geometry once (cached per process), traces its units with render.trace_rays (the
`order` argument picks them out) including their lighting, and returns the channels of their
pixels; the client writes them into one Frame. Every pixel is traced by the same kernel with the
same inputs and its secondary rays are seeded per pixel, so the frame is bit-identical to a local
render (tests/test_distributed.py).
"""
from __future__ import annotations

import os
import time

import numpy as np

from .camera import primary_rays, view_of
from .distributed import loaded_scene, map_items, worker_threads
from .options import Options
from .render import LIGHTING_CHANNELS, Frame, trace_rays, unit_count, work_units
from .kernel_channels import CHANNEL_NAMES

UNITS_PER_TASK_SHARE = 4   # groups per worker thread: enough to balance, few enough to amortise a task

_GEOMETRY: dict = {}


def prepared(scene, precision: str):
    """The scene's Geometry in `precision`, prepared once per process while the scene is the same."""
    from .geometry import prepare
    key = (id(scene), precision)
    if key not in _GEOMETRY or _GEOMETRY[key][0] is not scene:
        _GEOMETRY.clear()
        _GEOMETRY[key] = (scene, prepare(scene, precision))
    return _GEOMETRY[key][1]


def trace_group(item):
    """One task: ((scene's absolute path, its path as given), options, (width, height), unit indices) -> (pixels (k, 2) int32,
    {channel: values at those pixels}, the frame's kernel variant and aggregate report)."""
    where, opts, (width, height), indices = item
    scene = loaded_scene(*where)
    geom = prepared(scene, opts.precision)
    view = view_of(scene)
    opts = opts.with_(threads=worker_threads(opts.threads))
    origins, dirs = primary_rays(view, width, height, opts.precision)
    frame = trace_rays(geom, opts, origins, dirs, view.pixel_angle(height), view=view, scene=scene,
                       order=list(indices))
    units = work_units(width, height, opts, geom, view)
    pixels = np.concatenate([units[i].pixels for i in indices])
    rows, cols = pixels[:, 0], pixels[:, 1]
    channels = {name: getattr(frame, name)[rows, cols] for name in CHANNEL_NAMES + tuple(LIGHTING_CHANNELS)
                if getattr(frame, name) is not None}
    return pixels, channels, {k: frame.extras[k] for k in ("variant", "accel", "lighting") if k in frame.extras}


def merged_lighting(reports: list) -> dict:
    """The tasks' lighting reports (lighting.Lighting.report) as one: seconds and counts summed over
    the tasks, the expanded data sets' builds of the first (each worker builds the same ones)."""
    seconds = {}
    for r in reports:
        for k, v in r["seconds"].items():
            seconds[k] = round(seconds.get(k, 0.0) + v, 4)
    return {"seconds": seconds, "centre_rays": sum(r["centre_rays"] for r in reports),
            "umbra_tests": sum(r["umbra_tests"] for r in reports),
            "trivially_decided": sum(r["trivially_decided"] for r in reports),
            "expanded_sets": reports[0]["expanded_sets"]}


def groups(count: int, parts: int) -> list:
    """0..count-1 in `parts` runs of consecutive indices (fewer if count is smaller)."""
    parts = max(1, min(parts, count))
    cuts = np.linspace(0, count, parts + 1).round().astype(int)
    return [tuple(range(a, b)) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def render_distributed(client, scene, opts: Options = Options(), *, size=None, progress=None) -> Frame:
    """render.render(scene, opts, size=size) with its units traced on the client's workers;
    progress(n) as n units finish."""
    width, height = size or scene.image_size or (512, 512)
    view = view_of(scene)
    origins, dirs = primary_rays(view, width, height, opts.precision)
    threads = sum(client.nthreads().values()) or 1
    units = unit_count(width, height, opts)
    items = [((os.path.abspath(scene.path), str(scene.path)), opts, (width, height), g)
             for g in groups(units, UNITS_PER_TASK_SHARE * threads)]
    frame = Frame.empty(origins, dirs)
    frame.add_lighting(opts.shadows)

    def step(i, result):
        if progress is not None:
            progress(len(items[i][3]))

    start = time.perf_counter()
    results = map_items(trace_group, items, client, progress=step)
    frame.seconds = time.perf_counter() - start
    for pixels, channels, extras in results:
        for name, values in channels.items():
            getattr(frame, name)[pixels[:, 0], pixels[:, 1]] = values
        frame.extras.update(extras)
    lighting = [extras["lighting"] for _, _, extras in results if "lighting" in extras]
    if lighting:
        frame.extras["lighting"] = merged_lighting(lighting)
    frame.tiles_done = frame.tiles_total = units
    frame.extras.update(order=opts.order, tile_size=opts.tile_size, view=view)
    return frame
