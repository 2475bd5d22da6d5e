"""The inspector's Ray tree section: the clicked pixel's rays (tracer.ray_tree), one row each; a
chosen row's subdivision trace goes to the Subdivision plot and table, and the rays are drawn
over the image (viewer.ray_lines) while the checkbox is on."""
from __future__ import annotations

from imgui_bundle import imgui

from tracer.ray_tree import TESTS

from .ray_lines import ray_colour
from .ui_rows import clipped_rows

TABLE_HEIGHT = 180
COLUMNS = ("#", "kind", "code", "depth", "light", "outcome", "effort", "origin", "corner")
PENUMBRA_CLASS = {-1: "not classified", 0: "lit", 1: "penumbra", 2: "umbra"}


def _vec(v) -> str:
    return "-" if v is None else ", ".join(f"{x:.6g}" for x in v)


def _cells(ray) -> tuple:
    return (str(ray.code), str(ray.depth), str(ray.light) if ray.light >= 0 else "-", ray.outcome(),
            str(ray.effort) if ray.kind not in TESTS else "-", _vec(ray.origin), _vec(ray.corner))


def _summary(tree) -> None:
    imgui.text(tree.census())
    if tree.radiance is None:
        return
    shadow = "-" if tree.shadow is None else f"{tree.shadow:.4g}"
    imgui.text(f"shadow {shadow}, {tree.shadow_rays} shadow rays, {PENUMBRA_CLASS.get(tree.penumbra, '?')}")
    for e in tree.lights:
        proven = {True: ", proven lit", False: ", not proven lit", None: ""}[e["proven_lit"]]
        proven += {True: ", proven umbra", False: ", not proven umbra", None: ""}[e.get("proven_umbra")]
        imgui.text_disabled(f"vertex {e['code']}, light {e['light']}: {e['visible']}/{e['samples']} samples "
                            f"visible{proven}")


def _rows(ins) -> bool:
    """The table of rays; True when another row was chosen."""
    tree, changed = ins.tree, False
    ins.rows_drawn = 0
    # as tall as the rows need (with the header and the horizontal scroll bar), at most TABLE_HEIGHT
    height = min(TABLE_HEIGHT, (len(tree.rays) + 1) * imgui.get_frame_height() + 2 * imgui.get_style().scrollbar_size)
    for i in clipped_rows("rays", COLUMNS, len(tree.rays), height):
        ray = tree.rays[i]
        imgui.table_next_column()
        clicked, _ = imgui.selectable(f"{i}##ray", i == ins.ray, imgui.SelectableFlags_.span_all_columns)
        if clicked and i != ins.ray:
            ins.ray, ins.step, changed = i, -1, True
        imgui.table_next_column()
        imgui.text_colored((*ray_colour(ray)[:3], 1.0) if i else (1.0, 1.0, 1.0, 1.0), ray.kind.replace("_", " "))
        for text in _cells(ray):
            imgui.table_next_column()
            imgui.text(text)
        ins.rows_drawn += 1
    return changed


def ray_tree_section(state) -> bool:
    """Returns True when the chosen ray or the drawing of the rays changed (the outlines follow)."""
    ins = state.inspector
    imgui.separator_text("Ray tree")
    toggled, state.show_rays = imgui.checkbox("draw the rays on the image", state.show_rays)
    if ins.tree_error is not None:
        imgui.text_colored((1.0, 0.35, 0.3, 1.0), "the ray tree could not be traced:")
        imgui.text_wrapped(ins.tree_error.split("\n")[0])
        return toggled
    if ins.tree is None:
        imgui.text_disabled("tracing the ray tree...")
        return toggled
    _summary(ins.tree)
    changed = _rows(ins)
    chosen = ins.tree.rays[ins.ray] if 0 <= ins.ray < len(ins.tree.rays) else None
    if chosen is not None and chosen.steps is None and ins.ray > 0:
        why = {"penumbra_test": " (a penumbra test walks grown boxes)",
               "umbra_test": " (an umbra test proves a patch covers the light)"}.get(chosen.kind, "")
        imgui.text_disabled("no subdivision trace for this ray" + why)
    return toggled or changed
