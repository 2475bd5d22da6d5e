"""The study's work units on Dask workers (`psrt study --scheduler`, tracer/distributed.py).

A unit's item is small: the scene's path, the image size, the unit (a coherence trial, a psrt point
or a peer's point: study.run_unit) and the runs. Each worker process loads the scene and prepares
the study (the float32 rays, their float64 reference and the Newton-polished truth) once, then runs
its units one at a time (timed items: one per worker, so timed work never shares a core) and
returns each unit's result. The truth is a deterministic function of the scene and the size, so
every worker scores against the same bits as the client.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from .study import prepare_study, run_unit

_STUDIES: dict = {}


@dataclass(frozen=True)
class UnitItem:
    """One study unit as a task: where the scene is (absolute path, and the path as the user gave
    it), the image size, the unit and its timed runs."""

    path: str
    label: str
    size: tuple
    unit: object
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


def run_unit_item(item: UnitItem):
    """The result of one unit, on whichever process runs it."""
    return run_unit(study_here(item.path, item.label, item.size), item.unit, item.runs)


def run_units(scene, size, units: list, runs: int, client, progress=None) -> list:
    """[(result, contended)] of the units on the client's workers, in their order; progress(label) as
    each finishes."""
    from .distributed import map_items
    items = [UnitItem(os.path.abspath(scene.path), str(scene.path), tuple(size), u, runs) for u in units]
    step = None if progress is None else (lambda i, timed: progress(units[i].label))
    return [(t.value, t.contended) for t in map_items(run_unit_item, items, client, progress=step, timed=True)]
