"""psrt's study points on Dask workers (`psrt study --scheduler`, tracer/distributed.py).

A point's item is small: the scene's path, the image size, the point and the runs. Each worker
process loads the scene and prepares the study (the float32 rays, their float64 reference and the
Newton-polished truth) once, then runs its points one at a time (timed items: one per worker, so
timed work never shares a core) and returns each point's score. The truth is a deterministic
function of the scene and the size, so every worker scores against the same bits as the client.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from .study import Point, prepare_study, run_point

_STUDIES: dict = {}


@dataclass(frozen=True)
class PointItem:
    """One study point as a task: where the scene is (absolute path, and the path as the user gave
    it), the image size, the point and its timed runs."""

    path: str
    label: str
    size: tuple
    point: Point
    runs: int


def study_here(path: str, label: str, size: tuple):
    """The study of the scene at `path` and `size`, prepared once per process while the file is unchanged."""
    from .distributed import loaded_scene
    scene = loaded_scene(path, label)
    key = (path, label, tuple(size))
    held = _STUDIES.get(key)
    if held is None or held.scene is not scene:
        _STUDIES.clear()  # one study at a time on a long-lived worker
        _STUDIES[key] = held = prepare_study(scene, size)
    return held


def run_point_item(item: PointItem):
    """The score of one point, on whichever process runs it."""
    return run_point(study_here(item.path, item.label, item.size), item.point, item.runs)


def run_points(scene, size, chosen: list, runs: int, client, progress=None) -> list:
    """[(Score, contended)] of the chosen points on the client's workers, in their order;
    progress(point) as each finishes."""
    from .distributed import map_items
    items = [PointItem(os.path.abspath(scene.path), str(scene.path), tuple(size), p, runs) for p in chosen]
    step = None if progress is None else (lambda i, timed: progress(chosen[i]))
    return [(t.value, t.contended) for t in map_items(run_point_item, items, client, progress=step, timed=True)]
