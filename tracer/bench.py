"""Benchmark: every criterion x split heuristic x precision on one view, timed and checked
against the float64 reference of the same rays.

Per configuration: one warm-up render, then the median wall time of `runs`
renders (rays and tracing; the scene's kernel arrays are prepared once per
precision beforehand), rays/s, mean effort per hit, and the position error
statistics of stats.error_stats. The float32 and float64 configurations trace
different (rounded) rays, so each precision gets its own reference.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import asdict
from pathlib import Path

from .geometry import prepare
from .options import CRITERIA, PRECISIONS, SPLITS, Options
from .render import reference_frame, render
from .stats import error_stats, frame_stats

DEFAULT_SCENE = Path(__file__).resolve().parents[1] / "sample_models" / "teapot.json"
CRITERION_PARAM = {"float": None, "fixed": "fixed_size", "adaptive": "pixel_fraction",
                   "mantissa": "mantissa_ulps"}


def run_bench(scene, base: Options = Options(), *, size=(512, 512), runs: int = 5,
              criteria=CRITERIA, splits=SPLITS, precisions=PRECISIONS, log=None) -> dict:
    """Time and check each configuration; returns {'rows': [...], 'references': {...}, ...}.

    log(text) is called with one line per finished configuration.
    """
    if runs < 1:
        raise ValueError(f"--runs: expected at least 1, got {runs}")
    rows, refs = [], {}
    geom64 = prepare(scene, "f64")
    for precision in precisions:
        geom = geom64 if precision == "f64" else prepare(scene, precision)
        ref = None
        for criterion in criteria:
            for split in splits:
                opts = base.with_(criterion=criterion, split=split, precision=precision)
                frame = render(scene, opts, size=size, geometry=geom, lighting=False)  # warm-up, compile
                if ref is None:
                    ref = reference_frame(scene, frame, geometry=geom64)
                    refs[precision] = {"seconds": ref.seconds, "hits": int(ref.hit.sum())}
                times = []
                for _ in range(runs):
                    start = time.perf_counter()
                    frame = render(scene, opts, size=size, geometry=geom, lighting=False)
                    times.append(time.perf_counter() - start)
                row = _row(opts, frame, ref, times)
                rows.append(row)
                if log is not None:
                    log(f"{criterion:9s} {split:7s} {precision}  {row['time']:.3f} s  "
                        f"mean error {_fmt(row['error']['mean'])}")
    return {"size": list(size), "runs": runs, "threads": base.threads, "options": asdict(base),
            "references": refs, "rows": rows}


def _row(opts: Options, frame, ref, times) -> dict:
    median = statistics.median(times)
    fs = frame_stats(frame)
    param = CRITERION_PARAM[opts.criterion]
    return {"criterion": opts.criterion, "split": opts.split, "precision": opts.precision,
            "param": None if param is None else {param: getattr(opts, param)},
            "time": median, "times": times, "rays_per_s": fs["rays"] / median if median > 0 else None,
            "rays": fs["rays"], "hits": fs["hits"],
            "effort_mean": fs["effort"]["mean"],
            "effort_mean_hits": fs["effort_hits"]["mean"] if fs["effort_hits"] else None,
            "error": error_stats(frame, ref)}


def _fmt(x, spec=".2e") -> str:
    return "-" if x is None else format(x, spec)


COLUMNS = [("criterion", 9), ("split", 6), ("prec", 4), ("time s", 7), ("Mrays/s", 7),
           ("effort/hit", 10), ("mean err", 9), ("max err", 9), ("holes", 5), ("false", 5), ("unres", 5),
           ("err/floor", 9), ("in box %", 8), ("in 4ulp %", 9)]


def format_table(result: dict) -> str:
    """The benchmark rows as a fixed-width text table."""
    head = "  ".join(f"{name:>{w}}" if i > 2 else f"{name:<{w}}" for i, (name, w) in enumerate(COLUMNS))
    lines = [head, "-" * len(head)]
    for r in result["rows"]:
        e = r["error"]
        cells = [r["criterion"], r["split"], r["precision"], f"{r['time']:.3f}",
                 _fmt(r["rays_per_s"] and r["rays_per_s"] / 1e6, ".2f"), _fmt(r["effort_mean_hits"], ".1f"),
                 _fmt(e["mean"]), _fmt(e["max"]), str(e["holes"]), str(e["false_hits"]), str(e["unresolved"]),
                 _fmt(e["ratio"], ".2f"), _fmt(e["inside_box"] and 100 * e["inside_box"], ".2f"),
                 _fmt(e["inside_4ulp"] and 100 * e["inside_4ulp"], ".3f")]
        lines.append("  ".join(f"{c:>{w}}" if i > 2 else f"{c:<{w}}"
                               for i, (c, (_, w)) in enumerate(zip(cells, COLUMNS))))
    w, h = result["size"]
    lines.append(f"{w}x{h} primary rays, median of {result['runs']} run(s) after a warm-up; "
                 "errors are L1 against the float64 float-criterion render of the same rays (unres: pixels "
                 "where it ran out of its box budget, left out)")
    return "\n".join(lines)
