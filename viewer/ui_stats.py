"""Stats panel: timing, progress, effort, coherence counters (Lischinski) and accuracy against float64
(Dammertz table 2.1)."""
from __future__ import annotations

import time

from imgui_bundle import imgui

from tracer.variants import compile_report

ERROR_ROWS = (("max", "max error"), ("min", "min error"), ("mean", "mean error"), ("variance", "variance"),
              ("floor", "float32 floor"), ("ratio", "mean / floor"), ("inside_box", "ref in box"),
              ("inside_4ulp", "ref in box (4 ulp)"))


def _fmt(v) -> str:
    if v is None:
        return "-"
    return f"{v:d}" if isinstance(v, int) else f"{v:.6e}" if abs(v) < 1e-3 or abs(v) >= 1e5 else f"{v:.6g}"


def ui_stats(state) -> bool:
    if not imgui.collapsing_header("Stats", imgui.TreeNodeFlags_.default_open):
        return False
    r = state.render
    imgui.text(f"UI {state.fps:.0f} frames/s   render: {r.phase}")
    if state.compiling is not None:
        name, since = state.compiling
        imgui.text_colored((1.0, 0.8, 0.3, 1.0), f"compiling the {name} kernel: {time.perf_counter() - since:.0f} s")
    if r.tiles_total:
        imgui.progress_bar(r.tiles_done / r.tiles_total, (-1, 0), f"tiles {r.tiles_done}/{r.tiles_total}")
    if state.latencies:
        imgui.text(f"restart latency {1000 * state.latencies[-1]:.0f} ms (option change to the new render starting)")
    s = r.stats
    if s:
        rate = s["rays"] / s["time"] if s["time"] > 0 else 0.0
        imgui.text(f"frame {s['time']:.3f} s, {rate / 1e3:.1f} k rays/s, {s['hits']}/{s['rays']} hits")
        for key, label in (("effort", "effort (all rays)"), ("effort_hits", "effort (hits)"),
                           ("nodes", "nodes visited"), ("patches_tested", "patches tested")):
            e = s.get(key)
            if e:
                imgui.text(f"{label}: min {e['min']:.0f}  mean {e['mean']:.1f}  max {e['max']:.0f}")
        _accel(s.get("accel"))
        for line in coherence_lines(s.get("coherence")):
            imgui.text(line)
    e = r.error_stats
    if e:
        imgui.separator_text(f"vs float64 reference ({r.ref_seconds:.2f} s)")
        imgui.text(f"{e['compared']} hits compared, {e['holes']} holes, {e['false_hits']} false hits")
        if e.get("unresolved"):
            imgui.text_colored((1.0, 0.6, 0.0, 1.0), f"{e['unresolved']} pixels unresolved: the reference ran "
                               "out of its box budget there (orange in the error overlay)")
        if imgui.begin_table("errors", 2, imgui.TableFlags_.borders_inner_h):
            for key, label in ERROR_ROWS:
                imgui.table_next_row()
                imgui.table_next_column()
                imgui.text(label)
                imgui.table_next_column()
                imgui.text(_fmt(e.get(key)))
            imgui.end_table()
        imgui.text_disabled("position error: L1 norm, world units, over pixels both hit")
    _kernels()
    return False


def accel_lines(a: dict) -> list:
    """The acceleration structure's figures (frame_stats' "accel"), a few lines of text."""
    if not a:
        return []
    from tracer.accel import KIND_NAMES
    params = ", ".join(f"{k} {v}" for k, v in a.get("parameters", {}).items())
    head = KIND_NAMES[a["kind"]] + (f" ({params})" if params else "")
    if a["kind"] == "bvh":
        return [f"{head}: {a['nodes']} nodes, depth {a['depth']}, {a['bytes'] / 2**20:.2f} MiB (built with the scene)"]
    built = f"built in {a['build_seconds']:.3f} s" + ("" if a["built_now"] else " (reused)")
    lines = [f"{head}, mailbox {'on' if a['mailbox'] else 'off'}: {built}, {a['bytes'] / 2**20:.2f} MiB"]
    if a["kind"] == "kdtree":
        lines.append(f"{a['nodes']} nodes, {a['leaves']} leaves ({a['empty_leaves']} empty), depth {a['depth']}, "
                     f"{a['items']} items, {a['mean_items_per_full_leaf']:.2f} per non-empty leaf")
    else:
        nx, ny, nz = a["dims"]
        lines.append(f"{nx}x{ny}x{nz} cells ({a['empty_cells']} empty), {a['items']} items, "
                     f"{a['mean_items_per_full_cell']:.2f} per non-empty cell"
                     + (f", coarsened {a['coarsened']:.2f}x to fit" if a["coarsened"] > 1.0 else ""))
    return lines


def coherence_lines(c: dict | None) -> list:
    """Lischinski's counters of the frame (frame_stats' "coherence"), a few lines of text."""
    if not c:
        return []
    lines = [f"per ray: {c['surfaces_tested_per_ray']:.2f} surfaces box-tested, "
             f"{c['surfaces_searched_per_ray']:.2f} searched, {c['box_tests_per_ray']:.1f} ray-box tests"]
    cache = c.get("cache")
    if cache:
        ratio = c["cache_hit_ratio"]
        per = c["cache_misses_per_surface"]
        lines.append(f"surface-tree cache: hit ratio {'-' if ratio is None else f'{ratio:.3f}'}, "
                     f"{'-' if per is None else f'{per:.2f}'} misses per surface searched "
                     f"({cache['misses']} trees made for {cache['surfaces']} surfaces, {cache['released']} released)")
        lines.append(f"  {cache['nodes']} nodes of {cache['capacity']} held, {cache['bytes'] / 2**20:.1f} MiB "
                     f"in {cache['threads']} thread cache(s)")
    return lines


def _accel(a):
    for line in accel_lines(a):
        imgui.text(line)


def _kernels():
    """The kernel variants this process compiled (or loaded from the cache), with their times."""
    report = compile_report()
    if report and imgui.tree_node("kernel variants"):
        for k in report:
            how = "from the cache" if k["cached"] else "compiled"
            imgui.text(f"{k['kernel']} {k['variant']}: {how} in {k['seconds']:.2f} s")
        imgui.tree_pop()
