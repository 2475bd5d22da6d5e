"""Scene panel: open a file (path, samples, recent list, drag-and-drop), what the scene holds."""
from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

import numpy as np
from imgui_bundle import imgui

from .surface_info import count_lines, import_rows, scene_counts

DEGREE_NAMES = {(1, 1): "bilinear", (2, 2): "biquadratic", (3, 3): "bicubic"}
SAMPLES_DIR = Path(__file__).resolve().parents[1] / "sample_models"


def patch_types(scene) -> list:
    """["32 bicubic", "1 bilinear", ...]: patch counts by degree (and rationality), most first
    (ties in order of first appearance)."""
    kinds = Counter()
    triples = np.column_stack([scene.degree_u, scene.degree_v, scene.rational]).astype(np.int64)
    found, first, counts = np.unique(triples, axis=0, return_index=True, return_counts=True)
    for i in np.argsort(first, kind="stable"):  # one entry per kind, not per patch
        m, n, r = (int(x) for x in found[i])
        name = DEGREE_NAMES.get((m, n), f"degree {m}x{n}")
        kinds["rational " + name if r else name] += int(counts[i])
    return [f"{count} {name}" for name, count in kinds.most_common()]


_SUMMARY = [None, None]  # the last scene drawn and its summary


def scene_summary(scene) -> dict:
    """What the panel shows about a scene that takes work over all its patches (types, counts,
    bounds): computed once per scene, not every frame (a scene is not changed once loaded)."""
    if _SUMMARY[0] is not scene:
        lo, hi = scene.bounds()
        _SUMMARY[:] = scene, {"types": f"{scene.n_patches} patches: {', '.join(patch_types(scene))}",
                              "counts": count_lines(scene_counts(scene)),
                              "bounds": f"bounds {np.array2string(lo, precision=3)} .. {np.array2string(hi, precision=3)}"}
    return _SUMMARY[1]


def sample_files(directory: Path = SAMPLES_DIR) -> list:
    """The sample scenes (sample_models/*.json), sorted by name; [] without the folder."""
    return sorted(str(p) for p in Path(directory).glob("*.json")) if Path(directory).is_dir() else []


def _file_list(label: str, paths, current, tooltip: str = "") -> str | None:
    """A tree of selectable file names (full path as tooltip); the clicked path, or None."""
    chosen = None
    if paths and imgui.tree_node_ex(label, imgui.TreeNodeFlags_.default_open if label == "Samples" else 0):
        for path in paths:
            clicked, _ = imgui.selectable(f"{os.path.basename(path)}##{path}", path == current)
            imgui.set_item_tooltip(f"{path}{tooltip}")
            if clicked:
                chosen = path
        imgui.tree_pop()
    return chosen


def _rows(rows) -> None:
    if imgui.begin_table("##rows", 2, imgui.TableFlags_.sizing_stretch_prop):
        for label, text in rows:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.text_disabled(label)
            imgui.table_next_column()
            imgui.text_wrapped(text)
        imgui.end_table()


def ui_surfaces(scene) -> None:
    """Surface types with counts, and each free-form file's import report."""
    for line in scene_summary(scene)["counts"]:
        imgui.bullet()  # then the text on the same line, wrapped at the panel's edge
        imgui.text_wrapped(line)
    for source, report in scene.import_report.items():
        if imgui.tree_node_ex(f"import of {os.path.basename(source)}##{source}",
                              imgui.TreeNodeFlags_.default_open if report.get("format") == "iges" else 0):
            _rows(import_rows(report))
            imgui.tree_pop()


def ui_scene(state) -> bool:
    """Returns True when a file was asked for (state.pending_open is set)."""
    if not imgui.collapsing_header("Scene", imgui.TreeNodeFlags_.default_open):
        return False
    asked = False
    imgui.set_next_item_width(-70)
    entered, state.open_path = imgui.input_text("##path", state.open_path,
                                                imgui.InputTextFlags_.enter_returns_true)
    imgui.same_line()
    if (imgui.button("Open") or entered) and state.open_path.strip():
        state.pending_open, asked = os.path.expanduser(state.open_path.strip()), True
    imgui.set_item_tooltip("open a .json scene, or a .bpt, .obj or .igs file (or drop one on the window)")
    for label, paths in (("Samples", sample_files()), ("Recent files", state.recent)):
        chosen = _file_list(label, paths, state.scene_path)
        if chosen:
            state.pending_open, asked = chosen, True
    scene = state.scene
    if scene is None:
        imgui.text_disabled("no scene loaded")
        return asked
    imgui.text_wrapped(f"{state.scene_path}")
    imgui.text_wrapped(scene_summary(scene)["types"])
    ui_surfaces(scene)
    imgui.text(scene_summary(scene)["bounds"])
    if imgui.tree_node(f"{len(scene.objects)} objects, {len(scene.lights)} lights"):
        for obj in scene.objects:
            mat = scene.materials[obj.material].name if obj.material < len(scene.materials) else "?"
            imgui.bullet_text(f"{obj.name}: {obj.patch_count} patches from {obj.first_patch}, "
                              f"{obj.source}, material {mat}")
        for light in scene.lights:
            imgui.bullet_text(f"{light.type} light at {np.array2string(light.centre(), precision=2)}, "
                              f"intensity {light.intensity:g}")
        imgui.tree_pop()
    return asked
