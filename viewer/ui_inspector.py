"""Inspector panel: the clicked pixel's hit, its surface (NURBS, trims) and its subdivision trace
(Dammertz figures 2.10-2.11)."""
from __future__ import annotations

import numpy as np
from imgui_bundle import imgui, implot

from tracer.options import bundled
from tracer.search_steps import EVENT_NAMES
from tracer.plot import EVENT_COLOURS, OPTIMUM_COLOUR

from .picking import inspection_surface, shown_trace
from .ui_ray_tree import ray_tree_section
from .ui_rows import clipped_rows
from .surface_info import summary_rows as surface_rows

PLOT_HEIGHT = 230
TABLE_HEIGHT = 200
TRIM_PLOT_SIZE = 330      # the (u, v) plot's side at most, pixels
TRIM_LEGEND_HEIGHT = 24   # its legend, below it
LOOP_RGBA = {"trim": (0.25, 0.8, 0.35, 1.0), "hole": (1.0, 0.45, 0.2, 1.0)}  # kept region / removed
SURFACE_DOMAIN_RGBA = (0.55, 0.55, 0.6, 1.0)
PATCH_DOMAIN_RGBA = (0.35, 0.6, 1.0, 0.9)
UV_HIT_RGBA = (1.0, 0.1, 0.1, 1.0)


def _rgba(rgb255, a=1.0):
    return (rgb255[0] / 255.0, rgb255[1] / 255.0, rgb255[2] / 255.0, a)


def _vec(v) -> str:
    return ", ".join(f"{x:.6g}" for x in v)


def summary_rows(ins) -> list:
    t = ins.trace
    rows = [("pixel", f"{t.pixel[0]}, {t.pixel[1]}"), ("hit", "yes" if t.hit else "miss")]
    if t.hit:
        rows += [("patch", str(t.patch)), ("t", f"{t.t:.9g}"), ("position", _vec(t.position)),
                 ("normal", _vec(t.normal)), ("uv", _vec(t.uv)),
                 ("box size", f"{float(np.sum(t.box_max - t.box_min)):.3g} (L1)")]
    # (a frame traced in bundles counts a pixel's boxes in its bundle's order of visits)
    alone = " (traced alone)" if ins.opts is not None and bundled(ins.opts) else ""
    rows.append(("effort", f"{t.effort} box tests{alone}"))
    if ins.error is not None:
        rows.append(("error", f"{ins.error:.3e} (L1 vs float64)"))
    elif ins.reference is not None and ins.reference.hit != t.hit:
        rows.append(("error", "hole (float64 hits)" if ins.reference.hit else "false hit (float64 misses)"))
    rows.append(("boxes", f"{len(t.steps_f)}" + (" (trace truncated)" if t.truncated else "")))
    return rows


def _table(table_id: str, rows) -> None:
    """(label, text) rows in two columns, the text wrapped."""
    if imgui.begin_table(table_id, 2, imgui.TableFlags_.sizing_stretch_prop):
        for label, text in rows:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.text(label)
            imgui.table_next_column()
            imgui.text_wrapped(text)
        imgui.end_table()


def _rect(label: str, d, rgba, weight: float = 1.0) -> None:
    """Rectangle u0 u1 v0 v1 as a closed line."""
    xs = np.array([d[0], d[1], d[1], d[0], d[0]], np.float64)
    ys = np.array([d[2], d[2], d[3], d[3], d[2]], np.float64)
    implot.plot_line(label, xs, ys, implot.Spec(line_color=rgba, line_weight=weight))


def trim_plot(info: dict, plot_id: str) -> None:
    """The surface's trim loops in its (u, v) domain (trim green, hole orange), the hit patch's
    domain and the hit's (u, v) as a red cross."""
    dom = info["surface_domain"]
    pad_u, pad_v = 0.04 * (dom[1] - dom[0]), 0.04 * (dom[3] - dom[2])
    # About square, the whole domain in view: u and v units are unrelated, so no equal aspect.
    side = min(imgui.get_content_region_avail().x, TRIM_PLOT_SIZE)
    if not implot.begin_plot(plot_id, (side, side + TRIM_LEGEND_HEIGHT)):
        return
    implot.setup_axes("u", "v")
    implot.setup_legend(implot.Location_.south, implot.LegendFlags_.outside | implot.LegendFlags_.horizontal)
    implot.setup_axes_limits(dom[0] - pad_u, dom[1] + pad_u, dom[2] - pad_v, dom[3] + pad_v)
    _rect("surface", dom, SURFACE_DOMAIN_RGBA)
    _rect("patch", info["patch_domain"], PATCH_DOMAIN_RGBA, 1.5)
    for loop in info["loops"]:
        pts = np.asarray(loop["points"], np.float64)
        implot.plot_line(loop["kind"], np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1]),
                         implot.Spec(line_color=LOOP_RGBA[loop["kind"]], line_weight=2.0))
    u, v = info["uv"]
    implot.plot_scatter("hit", np.array([u]), np.array([v]),
                        implot.Spec(marker=implot.Marker_.cross, marker_size=7, line_weight=2.0,
                                    marker_line_color=UV_HIT_RGBA, marker_fill_color=UV_HIT_RGBA))
    implot.end_plot()


def surface_section(ins) -> None:
    """The hit's surface: where it came from, its (u, v) and domain; trim loops when trimmed."""
    info = inspection_surface(ins)
    if info is None:
        return
    imgui.separator_text("Surface")
    _table("surface", surface_rows(info))
    if info.get("trimmed"):
        # the id changes with the surface and pixel, so a new inspection frames its own domain
        trim_plot(info, f"##trims-{info['surface']}-{ins.pixel[0]}-{ins.pixel[1]}")


def diameter_plot(ins) -> bool:
    """Box L1 diameter over box index, the optimum d(n) = s 2^(-n/2), hits marked; drag the step."""
    t = shown_trace(ins)
    k = len(t.steps_f)
    # the id changes with the pixel and ray, so a new trace frames its own axes
    plot_id = f"##diameters-{ins.pixel[0]}-{ins.pixel[1]}-{ins.ray}"
    if k == 0 or not implot.begin_plot(plot_id, (-1, PLOT_HEIGHT)):
        return False
    xs = np.arange(k, dtype=np.float64)
    ys = t.diameters.astype(np.float64)
    positive = ys[ys > 0]
    ys = np.maximum(ys, positive.min() if positive.size else 1e-30)  # log axis: no zeros
    implot.setup_axes("box index", "L1 diameter")
    implot.setup_axis_scale(implot.ImAxis_.y1, implot.Scale_.log10)
    implot.plot_line("diameter", xs, ys, implot.Spec(line_color=(0.6, 0.6, 0.6, 1.0)))
    implot.plot_line("optimum", xs, ys[0] * 0.5 ** (xs / 2.0), implot.Spec(line_color=_rgba(OPTIMUM_COLOUR)))
    events = t.steps_i[:, 2]
    for code, name in enumerate(EVENT_NAMES):
        sel = events == code
        if sel.any():
            implot.plot_scatter(name, xs[sel], ys[sel],
                                implot.Spec(marker=implot.Marker_.circle, marker_size=2.5,
                                            marker_fill_color=_rgba(EVENT_COLOURS[name]),
                                            marker_line_color=_rgba(EVENT_COLOURS[name])))
    h = t.hit_step()
    if h >= 0:
        implot.plot_scatter("reported hit", xs[[h]], ys[[h]],
                            implot.Spec(marker=implot.Marker_.circle, marker_size=7, fill_alpha=0.0,
                                        marker_line_color=(1.0, 0.1, 0.1, 1.0), line_weight=2.0))
    step = k - 1 if ins.step < 0 else ins.step
    moved, x, *_ = implot.drag_line_x(1, float(step), (1.0, 1.0, 1.0, 0.8))
    implot.end_plot()
    if moved:
        ins.step = int(min(max(round(x), 0), k - 1))
    return moved


def steps_table(ins) -> bool:
    t = shown_trace(ins)
    changed = False
    columns = ("#", "patch", "depth", "u", "v", "diameter", "event")
    for i in clipped_rows("steps", columns, len(t.steps_f), TABLE_HEIGHT):
        f, n = t.steps_f[i], t.steps_i[i]
        imgui.table_next_column()
        clicked, _ = imgui.selectable(f"{i}", i == ins.step, imgui.SelectableFlags_.span_all_columns)
        if clicked:
            ins.step, changed = i, True
        for text in (f"{n[0]}", f"{n[1]}", f"{f[0]:.4g}..{f[1]:.4g}", f"{f[2]:.4g}..{f[3]:.4g}",
                     f"{f[10]:.3e}", EVENT_NAMES[n[2]]):
            imgui.table_next_column()
            imgui.text(text)
    return changed


def ui_inspector(state) -> bool:
    """Returns True when the chosen step or ray, or the drawing of the rays, changed (the box
    outlines follow)."""
    if not imgui.collapsing_header("Inspector", imgui.TreeNodeFlags_.default_open):
        return False
    ins = state.inspector
    if ins is None:
        imgui.text_disabled("click a pixel of the image to inspect its ray")
        return False
    _table("summary", summary_rows(ins))
    surface_section(ins)
    changed = ray_tree_section(state)
    trace = shown_trace(ins)
    k = len(trace.steps_f)
    which = "the primary ray" if trace is ins.trace else f"ray {ins.ray} ({ins.tree.rays[ins.ray].kind})"
    imgui.separator_text(f"Subdivision of {which}")
    if k == 0:
        imgui.text_disabled("the ray met no patch box")
        return changed
    changed |= diameter_plot(ins)
    if ins.step >= k:
        ins.step = k - 1
    moved, step = imgui.slider_int("step", ins.step if ins.step >= 0 else k - 1, 0, k - 1)
    if moved:
        ins.step, changed = step, True
    f, n = trace.steps_f[ins.step], trace.steps_i[ins.step]
    imgui.text(f"box {ins.step}: patch {n[0]}, depth {n[1]}, {EVENT_NAMES[n[2]]}, diameter {f[10]:.3e}")
    changed |= steps_table(ins)
    return changed
