"""The tables of `psrt bench --coherence` (bench_coherence.run_coherence's result) as text, and the
checks of issue 12's targets read off them."""
from __future__ import annotations

import statistics

from .bench_coherence import BOUNDED_CACHE_MB, SMALL_CACHE_MB, TABLES

TITLES = {"bundles": "ray bundles (Dammertz table 2.5): speed-up against 1x1 of the same criterion",
          "accel": "acceleration structures (Dammertz table 3.1): speed-up against the BVH",
          "order": "pixel order and surface-tree cache (Lischinski and Gonczarowski, section 5): "
                   "speed-up against scanline without the cache"}


# Issue 12: the cost of traversal, ray set-up and the tile loop, a frame of the teapot at 512x512.
FLAT_FRAME_SECONDS = 0.04


def _f(x, spec=".2f") -> str:
    return "-" if x is None else format(x, spec)


def _coh(row, key):
    c = row["stats"].get("coherence") or {}
    return c.get(key)


def _cache(row, key):
    c = _coh(row, "cache") or {}
    return c.get(key)


def _remade(row):
    """Trees the frame made again after releasing them: its cache misses beyond one per surface
    searched (0 when the bound held every tree the frame needed; None without the cache)."""
    c = _coh(row, "cache")
    return None if not c or "surfaces" not in c else c["misses"] - c["surfaces"]


def _per_leaf(a: dict):
    return a.get("mean_items_per_full_leaf", a.get("mean_items_per_full_cell", a.get("mean_items_per_leaf")))


# Per table: (heading, width, cell of a row).
COLUMNS = {
    "bundles": [("time s", 8, lambda r: _f(r["time"], ".3f")), ("speed-up", 8, lambda r: _f(r["speedup"])),
                ("effort/ray", 10, lambda r: _f(r["stats"]["effort"]["mean"], ".1f")),
                ("box tests/ray", 13, lambda r: _f(_coh(r, "box_tests_per_ray"), ".1f")),
                ("hit ratio", 9, lambda r: _f(_coh(r, "cache_hit_ratio"), ".3f"))],
    "accel": [("build s", 8, lambda r: _f(r["build_seconds"], ".3f") if r["build_seconds"] is not None else "shared"),
              ("MiB", 7, lambda r: _f(r["stats"]["accel"]["bytes"] / 2 ** 20)),
              ("nodes/cells", 11, lambda r: str(r["stats"]["accel"].get("cells") or r["stats"]["accel"]["nodes"])),
              ("per leaf", 8, lambda r: _f(_per_leaf(r["stats"]["accel"]))),
              ("time s", 8, lambda r: _f(r["time"], ".3f")), ("speed-up", 8, lambda r: _f(r["speedup"])),
              ("nodes/ray", 9, lambda r: _f(r["stats"]["nodes"]["mean"], ".1f")),
              ("tested/ray", 10, lambda r: _f(_coh(r, "surfaces_tested_per_ray"))),
              ("searched/ray", 12, lambda r: _f(_coh(r, "surfaces_searched_per_ray"))),
              ("box tests/ray", 13, lambda r: _f(_coh(r, "box_tests_per_ray"), ".1f"))],
    "order": [("time s", 8, lambda r: _f(r["time"], ".3f")), ("speed-up", 8, lambda r: _f(r["speedup"])),
              ("tested/ray", 10, lambda r: _f(_coh(r, "surfaces_tested_per_ray"))),
              ("searched/ray", 12, lambda r: _f(_coh(r, "surfaces_searched_per_ray"))),
              ("box tests/ray", 13, lambda r: _f(_coh(r, "box_tests_per_ray"), ".1f")),
              ("misses/surface", 14, lambda r: _f(_coh(r, "cache_misses_per_surface"))),
              ("re-made", 7, lambda r: _f(_remade(r), "d")),
              ("hit ratio", 9, lambda r: _f(_coh(r, "cache_hit_ratio"), ".4f")),
              ("released", 8, lambda r: _f(_cache(r, "released"), "d"))],
}


def format_table(table: str, label: str, scene: dict) -> str:
    rows = [r for r in scene["rows"] if r["table"] == table]
    first = max(len(r["label"]) for r in rows)
    cols = COLUMNS[table]
    head = f"{'':<{first}}  " + "  ".join(f"{name:>{w}}" for name, w, _ in cols)
    lines = [f"{label} ({scene['patches']:,} patches, {scene['leaves']:,} leaves): {TITLES[table]}", head,
             "-" * len(head)]
    for r in rows:
        lines.append(f"{r['label']:<{first}}  " + "  ".join(f"{cell(r):>{w}}" for _, w, cell in cols))
    return "\n".join(lines)


def footer(result: dict) -> str:
    w, h = result["size"]
    clock = ("CPU time of the process over the render call, one render thread" if result["timing"] == "cpu"
             else f"wall time of the render call, {result['threads'] or 'all'} render threads")
    return (f"{w}x{h} primary rays; time: median of {result['runs']} run(s) after a warm-up, {clock}; configurations "
            "take turns within each run, and a speed-up is the median over runs of the plain row's time over the "
            "row's in the same run. Per ray (all rays): effort = patch boxes computed; tested = surfaces whose box "
            "was tested; searched = surfaces searched; box tests = nodes, patch boxes, cached and computed "
            "sub-patch boxes. Cache (empty at the start of every frame): hit ratio = searches that found the "
            "surface's tree / all searches; misses/surface = trees made / surfaces searched (1: each made once); "
            "re-made = trees made again after their release (misses beyond one per surface searched: every order "
            "makes the same searches, so these are where orders differ); released = trees released to make room. "
            "No subdivision: `fixed` at the largest leaf box's L1 diameter (at most 10, the option's range), so "
            "searches stop at the leaves' root boxes. Build: least "
            "time of the runs' builds, same clock; mailbox rows share the build of the row above them.")


def _best(scene, criterion):
    rows = [r for r in scene["rows"] if r["table"] == "bundles" and r["label"].startswith(criterion + " ")
            and r["label"] != f"{criterion} 1x1"]
    return max(rows, key=lambda r: r["speedup"]) if rows else None


def _row(scene, start, end=""):
    """The first row whose label starts with `start` and ends with `end`."""
    return next((r for r in scene["rows"] if r["label"].startswith(start) and r["label"].endswith(end)), None)


def _shown(x: float, digits: int, meets) -> str:
    """x with `digits` decimals, or as many more as it takes for the figure shown to meet the target
    (meets) exactly when x does: 1.1996x is shown as 1.1996x, not 1.20x, beside a 1.2x target."""
    for d in range(digits, 17):
        text = f"{x:.{d}f}"
        if meets(float(text)) == meets(x):
            return text
    return repr(x)


def checks(result: dict) -> list:
    """Issue 12's targets as measured: (what, figure, target, met: bool, or None where the target is
    about another scene or only asks for the figure)."""
    out = []
    full_size = result["size"] == [512, 512]
    for label, scene in result["scenes"].items():
        for criterion, target in (("adaptive", 1.5), ("float", 1.2)):
            best = _best(scene, criterion)
            if best is not None:
                figure = _shown(best["speedup"], 2, lambda x: x >= target)
                out.append((f"{label}: best {criterion} combination ({best['label']})", f"{figure}x",
                            f">= {target}x on the teapot at 512x512",
                            best["speedup"] >= target if label == "teapot" else None))
        bounded = _row(scene, f"scanline, cache {BOUNDED_CACHE_MB:g} MB")
        free = _row(scene, "scanline, cache unbounded")
        if bounded and free:
            kept = statistics.median(u / b for u, b in zip(free["times"], bounded["times"]))
            out.append((f"{label}: speed of the {BOUNDED_CACHE_MB:g} MB cache against the unbounded one (scanline)",
                        f"{100 * kept:.0f} %", ">= 90 % on the 25,000-patch scene (flying)",
                        kept >= 0.9 if label == "flying" else None))
        for bound in (f"{SMALL_CACHE_MB:g} MB", f"{BOUNDED_CACHE_MB:g} MB", "unbounded"):
            scan, peano = _row(scene, f"scanline, cache {bound}"), _row(scene, f"peano, cache {bound}")
            if scan and peano:
                a, b = _coh(peano, "cache_hit_ratio"), _coh(scan, "cache_hit_ratio")
                out.append((f"{label}: cache hit ratio, peano / scanline, cache {bound}",
                            f"{_f(a, '.4f')} / {_f(b, '.4f')} (trees re-made {_f(_remade(peano), 'd')} / "
                            f"{_f(_remade(scan), 'd')})", "peano >= scanline on every scene",
                            None if a is None or b is None else a >= b))
        flat = [r for r in scene["rows"] if r["label"].endswith("no subdivision")]
        if flat:
            best = min(flat, key=lambda r: r["time"])
            out.append((f"{label}: a frame without subdivision ({best['label']})",
                        f"{_shown(best['time'], 3, lambda t: t <= FLAT_FRAME_SECONDS)} s, "
                        f"{100 / best['speedup']:.0f} % of the float 1x1 frame",
                        f"<= {FLAT_FRAME_SECONDS} s on the teapot at 512x512",
                        best["time"] <= FLAT_FRAME_SECONDS if label == "teapot" and full_size else None))
    return out


def format_checks(result: dict) -> str:
    w, h = result["size"]
    lines = [f"targets (issue 12), as measured in this run ({w}x{h}); a verdict where the target is about the scene:"]
    for what, figure, target, met in checks(result):
        verdict = "" if met is None else ("  met" if met else "  NOT met")
        lines.append(f"  {what}: {figure}  [{target}]{verdict}")
    return "\n".join(lines)


def format_result(result: dict) -> str:
    """Every scene's three tables, the footer and the checks."""
    parts = [format_table(table, label, scene) for label, scene in result["scenes"].items()
             for table in TABLES if table in result["tables"]]
    return "\n\n".join(parts + [footer(result), format_checks(result)])

