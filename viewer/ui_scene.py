"""Scene panel: open a file (path, recent list, drag-and-drop), what the scene holds."""
from __future__ import annotations

import os
from collections import Counter

import numpy as np
from imgui_bundle import imgui

DEGREE_NAMES = {(1, 1): "bilinear", (2, 2): "biquadratic", (3, 3): "bicubic"}


def patch_types(scene) -> list:
    """["32 bicubic", "1 bilinear", ...]: patch counts by degree (and rationality)."""
    kinds = Counter()
    for m, n, r in zip(scene.degree_u, scene.degree_v, scene.rational):
        name = DEGREE_NAMES.get((int(m), int(n)), f"degree {m}x{n}")
        kinds["rational " + name if r else name] += 1
    return [f"{count} {name}" for name, count in kinds.most_common()]


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
    imgui.set_item_tooltip("open a .json scene or .bpt patch file (or drop one on the window)")
    if state.recent and imgui.tree_node("Recent files"):
        for path in state.recent:
            clicked, _ = imgui.selectable(path, path == state.scene_path)
            if clicked:
                state.pending_open, asked = path, True
        imgui.tree_pop()
    scene = state.scene
    if scene is None:
        imgui.text_disabled("no scene loaded")
        return asked
    imgui.text_wrapped(f"{state.scene_path}")
    imgui.text(f"{scene.n_patches} patches: {', '.join(patch_types(scene))}")
    lo, hi = scene.bounds()
    imgui.text(f"bounds {np.array2string(lo, precision=3)} .. {np.array2string(hi, precision=3)}")
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
