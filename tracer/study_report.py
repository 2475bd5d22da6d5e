"""The study's outputs (tracer/study.py): a Markdown table and a log-log chart of time against error,
in the form of Dammertz's table 2.9, with the float32 rounding floor drawn as a vertical line."""
from __future__ import annotations

import io


def _fmt(x, spec=".3g") -> str:
    return "—" if x is None else format(x, spec)


def _parameter(row) -> str:
    p = row["parameter"]
    if p is None:
        return ""
    kind = row["series"].split()[0 if row["series"].startswith(("embree", "povray")) else 1]
    return {"fixed": f"{p:g} of size", "adaptive": f"{p:g} px", "mantissa": f"{int(p)} ulps",
            "embree": f"{int(p)}x{int(p)} per patch", "povray": f"flatness {p:g}"}.get(kind, f"{p:g}")


def markdown(result: dict) -> str:
    """The study as a Markdown table, one row per point, series in order; a header of the run's figures."""
    lines = [f"Rays {result['rays']} ({result['size'][0]}x{result['size'][1]}), reference hits "
             f"{result['reference_hits']}, truth accepted at {result['truth_accepted']}; errors are L1 / scene "
             f"size ({result['scene_size']:.4g}); float32 floor {result['float32_floor']:.3g}; time: "
             f"{result['timing']}, median of {result['runs']}."
             + (f" Tessellations left out (too many vertices): {result['tessellations_left_out']}."
                if result.get("tessellations_left_out") else "")
             + (f" POV-Ray left out: {result['povray_left_out']}." if result.get("povray_left_out") else ""), "",
             "| series | parameter | time s | mean error | max error | holes | false hits | wrong surface "
             "| truth in box |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in result["points"]:
        inside = "—" if r["inside"] is None else f"{100 * r['inside']:.2f}%"
        flag = " *" if r.get("contended") else ""
        lines.append(f"| {r['series']} | {_parameter(r)} | {r['seconds']:.4f}{flag} | {_fmt(r['mean_error'])} | "
                     f"{_fmt(r['max_error'])} | {r['holes']} | {r['false_hits']} | {r['wrong_surface']} | {inside} |")
    if any(r.get("contended") for r in result["points"]):
        lines += ["", "\\* contended: the point's Dask worker got under 0.8 of the wall time on its core (another "
                  "process had it); its time is suspect."]
    trials = coherence_table(result)
    return ("\n".join(lines) + "\n" + ("\n" + trials if trials else "")
            + ("\n" + format_targets(result) if targets(result) else ""))


def _trial_parameter(t) -> str:
    return _parameter({"series": f"psrt {t['criterion']}", "parameter": t["parameter"]}) or "—"


def coherence_table(result: dict) -> str:
    """The coherence trials (study_coherence.py) as a Markdown table; '' without them."""
    c = result.get("coherence")
    if not c:
        return ""
    labels = ["plain"] + list(c["candidates"])
    lines = [f"Coherence trials: CPU s of a frame of the study's rays at each criterion's trial parameter, "
             f"median of {c['rounds']} rounds, the settings taking turns; the fastest candidate gives the "
             "criterion's coherence series.", "",
             "| criterion | parameter | " + " | ".join(labels) + " | chosen | plain / chosen |",
             "|---|---|" + "---:|" * len(labels) + "---|---:|"]
    for t in c["trials"]:
        flag = " (contended)" if t.get("contended") else ""
        lines.append(f"| {t['criterion']} {t['precision']} | {_trial_parameter(t)} | "
                     + " | ".join(f"{t['seconds'][k]:.4f}" for k in labels)
                     + f" | {t['chosen']}{flag} | {t['speedup']:.2f} |")
    return "\n".join(lines) + "\n"


def _point(result: dict, series: str, parameter=None):
    return next((r for r in result["points"] if r["series"] == series and r["parameter"] == parameter), None)


def targets(result: dict) -> list:
    """Issue 14's targets read off the study: (target, met, the figures); met None for a check that
    is no target (the figures tell)."""
    out = []
    best = _point(result, "psrt float f32")
    if best is None or best["mean_error"] is None:
        return out
    floor = result["float32_floor"]
    out.append(("psrt float f32 within 2x of the float32 floor", best["mean_error"] <= 2 * floor,
                f"{best['mean_error']:.3g} = {best['mean_error'] / floor:.2f} x floor {floor:.3g}"))
    peers = [r for r in result["points"] if r["series"].endswith("first image") and r["mean_error"]]
    if peers:
        peer = min(peers, key=lambda r: r["mean_error"])
        name = f"{peer['series']} {_parameter(peer)}"
        # no float32 position is nearer the truth than the truth rounded to float32: the floor bounds
        # the ratio any float32 result can reach
        bound = peer["mean_error"] / floor if floor > 0 else float("inf")
        out.append(("psrt float f32 >= 100x below the most accurate peer point",
                    peer["mean_error"] >= 100 * best["mean_error"],
                    f"{name}: {peer['mean_error']:.3g} = {peer['mean_error'] / best['mean_error']:.0f} x; bound: "
                    f"the float32 floor {floor:.3g} is {bound:.0f} x below that peer point, "
                    + ("so 100 x is out of any float32 result's reach" if bound < 100 else "room for 100 x")))
        out.append(("psrt float f32 faster than that peer's first image", best["seconds"] < peer["seconds"],
                    f"{best['seconds']:.3f} s against {peer['seconds']:.3f} s"))
    finest = sorted((r for r in result["points"] if r["series"] == "embree first image" and r["mean_error"]),
                    key=lambda r: r["parameter"])[-2:]
    if len(finest) == 2:  # a tessellation's error is the chord's sag, ~1/N^2 once no ray hits the wrong surface
        (a, b) = finest
        out.append(("the tessellation peer's error falls as 1/N^2 between its two finest points", None,
                    f"N = {a['parameter']}: {a['mean_error']:.3g}, N = {b['parameter']}: {b['mean_error']:.3g}, "
                    f"{a['mean_error'] / b['mean_error']:.2f} x where 1/N^2 gives "
                    f"{(b['parameter'] / a['parameter']) ** 2:.2f} x"))
    pov = _point(result, "povray first image", 0.01)
    if pov is not None and pov["mean_error"] is not None:
        what = ("psrt adaptive faster than POV-Ray at flatness 0.01, fewer holes (the fastest psrt adaptive "
                "point, plain or coherence series, whose mean error is at most POV-Ray's)")
        fair = [r for r in result["points"] if r["series"].startswith("psrt adaptive")
                and r["mean_error"] is not None and r["mean_error"] <= pov["mean_error"]]
        if not fair:
            out.append((what, False, f"no psrt adaptive point has a mean error at most {pov['mean_error']:.3g}"))
        else:
            a = min(fair, key=lambda r: r["seconds"])
            out.append((what, a["seconds"] < pov["seconds"] and a["holes"] < pov["holes"],
                        f"{a['series']} at {_parameter(a)}, mean error {a['mean_error']:.3g}: {a['seconds']:.3f} s, "
                        f"{a['holes']} holes against {pov['seconds']:.3f} s, {pov['holes']} holes, mean error "
                        f"{pov['mean_error']:.3g}"))
    return out


def format_targets(result: dict) -> str:
    """The targets as a Markdown list."""
    rows = targets(result)
    status = {True: "met", False: "NOT met", None: "check"}
    return "\n".join(["Targets (issue 14):", ""] + [f"- {status[ok]}: {what} ({figures})"
                                                       for what, ok, figures in rows]) + "\n" if rows else ""


def series_points(result: dict) -> dict:
    """{series: [(mean error, seconds), ...]} in sweep order, points without an error left out."""
    out = {}
    for r in result["points"]:
        if r["mean_error"] is not None and r["mean_error"] > 0:
            out.setdefault(r["series"], []).append((r["mean_error"], r["seconds"]))
    return out


def chart_png(result: dict) -> bytes:
    """The log-log chart of time against mean error, one labelled line per series, as PNG bytes."""
    import matplotlib
    matplotlib.use("Agg")  # no display needed
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9, 6), dpi=100)
    colours = plt.cm.tab20.colors  # 20 distinct colours: the default cycle of 10 repeats
    for k, (name, pts) in enumerate(series_points(result).items()):
        err, sec = zip(*pts)
        coherent = name.startswith("psrt") and len(name.split()) > 3   # 'psrt adaptive f32 8x8'
        style = "--" if coherent or "per frame" in name else "-"
        marker = "^" if not name.startswith("psrt") else ("s" if " f64" in name else "o")
        ax.plot(err, [max(s, 1e-6) for s in sec], style, color=colours[k % len(colours)], marker=marker,
                markersize=4 if len(pts) > 1 else 11, label=name)
    floor = result["float32_floor"]
    if floor > 0:
        ax.axvline(floor, color="black", linestyle=":", label=f"float32 floor {floor:.2g}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("mean L1 position error / scene size")
    ax.set_ylabel("time, s")
    ax.set_title(f"Run time against error, {result['size'][0]}x{result['size'][1]} (Dammertz table 2.9)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()
