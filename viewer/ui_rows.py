"""A scrolling table of many rows, with a frozen header row, that lays out only the rows in view
(the inspector's subdivision steps, the ray tree's rays)."""
from __future__ import annotations

from imgui_bundle import imgui

FLAGS = (imgui.TableFlags_.scroll_y | imgui.TableFlags_.scroll_x | imgui.TableFlags_.row_bg
         | imgui.TableFlags_.borders_inner_v | imgui.TableFlags_.sizing_fixed_fit)


def clipped_rows(table_id: str, columns, count: int, height: float):
    """Yields the indices of the rows in view, each after starting its table row: the caller
    fills the row's cells (imgui.table_next_column, then the widgets)."""
    if not imgui.begin_table(table_id, len(columns), FLAGS, (0, height)):
        return
    try:
        for name in columns:
            imgui.table_setup_column(name)
        imgui.table_setup_scroll_freeze(0, 1)
        imgui.table_headers_row()
        clipper = imgui.ListClipper()
        clipper.begin(count)
        while clipper.step():
            for i in range(clipper.display_start, clipper.display_end):
                imgui.table_next_row()
                yield i
    finally:
        imgui.end_table()
