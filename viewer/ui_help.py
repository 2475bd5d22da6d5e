"""Help window: the keyboard and mouse shortcuts (H or F1)."""
from __future__ import annotations

from imgui_bundle import imgui

SHORTCUTS = (
    ("left drag", "orbit around the look-at point"),
    ("middle drag, shift + left drag", "pan"),
    ("mouse wheel", "zoom"),
    ("left click", "inspect the pixel (trace, boxes, plot, ray tree with its shadow and secondary rays)"),
    ("F", "frame the scene"),
    ("R", "reset the camera to the scene's"),
    ("B", "save a camera bookmark"),
    ("1 .. 9", "restore bookmark 1 .. 9"),
    ("O", "toggle the overlay (none / last one)"),
    ("Esc", "clear the inspector"),
    ("Ctrl+S", "screenshot of the view (PNG, output directory)"),
    ("H, F1", "this help"),
    ("drop a file", "open a .json scene or .bpt patch file"),
)


def ui_help(state) -> bool:
    if not state.show_help:
        return False
    _, state.show_help = imgui.begin("Help", state.show_help, imgui.WindowFlags_.always_auto_resize)
    if imgui.begin_table("keys", 2, imgui.TableFlags_.borders_inner_h):
        for keys, what in SHORTCUTS:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.text(keys)
            imgui.table_next_column()
            imgui.text(what)
        imgui.end_table()
    imgui.text_disabled("Options in the panels are tracer.options.Options, as on the command line.")
    imgui.end()
    return False
