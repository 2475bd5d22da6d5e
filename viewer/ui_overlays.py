"""Overlays panel: which channel, how it is mapped, and its legend (min, max, units, special colours)."""
from __future__ import annotations

from imgui_bundle import imgui

from tracer.colormap import format_value

from .ui_fields import record_widgets

BAR_HEIGHT = 14


def legend(info: dict) -> None:
    """Colour bar drawn from the GPU colour-map texture, with the range and special classes."""
    imgui.text(f"{info['label']} [{info['units']}, {info['scale']}]")
    width = imgui.get_content_region_avail().x
    if info.get("lut"):
        imgui.image(imgui.ImTextureRef(info["lut"]), (width, BAR_HEIGHT))
    lo, hi = format_value(info["lo"]), format_value(info["hi"])
    imgui.text(f"min {lo}")
    imgui.same_line(max(width - imgui.calc_text_size(f"max {hi}").x, 0.0))
    imgui.text(f"max {hi}")
    for k, (rgb, text) in enumerate(info.get("specials", [])):
        imgui.color_button(f"##special{k}", (*rgb, 1.0), imgui.ColorEditFlags_.no_tooltip, (12, 12))
        imgui.same_line()
        imgui.text(text)


def ui_overlays(state) -> bool:
    """Returns True when an overlay setting changed."""
    if not imgui.collapsing_header("Overlays", imgui.TreeNodeFlags_.default_open):
        return False
    changed, state.settings, error = record_widgets(state.settings, groups=("Overlays",))
    if error:
        state.log(error, "error")
    r = state.render
    if r.ref_total and r.phase == "reference":
        imgui.progress_bar(r.ref_done / r.ref_total, (-1, 0), f"float64 reference {r.ref_done}/{r.ref_total}")
    info = state.overlay_info
    if state.settings.overlay != "none" and info:
        if info.get("note"):
            imgui.text_disabled(info["note"])
        else:
            legend(info)
    return changed
