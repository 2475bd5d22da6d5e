"""What the Scene panel and the inspector say about surfaces: pure functions of a loaded Scene.

No window needed: the panels draw what these return, the tests check it directly.
"""
from __future__ import annotations

import os
from collections import Counter

import numpy as np

from tracer.formats.losses import group_line
from tracer.trim import inside, loops_for_plot

LOOP_SAMPLES = 24  # points per curved trim segment in the parameter-space plot
RATIONAL_KINDS = ("nurbs", "rational bspline", "rational bezier")  # kinds that say so already


def scene_counts(scene) -> dict:
    """Patch and surface counts by type.

    integral / rational: Bezier patches by weights (all patches, whatever they came from);
    trimmed: patches whose NURBS surface has trimming loops; plain: patches given as Bezier
    patches (.bpt, inline), not expanded from a NURBS surface; kinds: per SurfaceInfo.kind,
    [surfaces, Bezier patches they expanded to].
    """
    rational = np.asarray(scene.rational, bool)
    kinds: dict = {}
    for info in scene.surfaces:
        k = kinds.setdefault(info.kind, [0, 0])
        k[0] += 1
        k[1] += int(info.patch_count)
    return {"patches": int(scene.n_patches), "integral": int(np.sum(~rational)),
            "rational": int(np.sum(rational)), "trimmed": int(np.sum(scene.patch_has_trim)),
            "plain": int(np.sum(np.asarray(scene.patch_surface) < 0)),
            "surfaces": len(scene.surfaces), "surface_patches": int(np.sum(np.asarray(scene.patch_surface) >= 0)),
            "trimmed_surfaces": int(np.sum(scene.trims.has_trim)), "kinds": kinds}


def _n(count: int, what: str) -> str:
    """'1 rational patch', '2 rational patches'."""
    if count == 1:
        return f"1 {what}"
    return f"{count} {what[:-1] + 'ies' if what.endswith('y') else what + ('es' if what.endswith('ch') else 's')}"


def count_lines(counts: dict) -> list:
    """The Scene panel's lines for scene_counts(...)."""
    lines = [_n(counts["integral"], "integral Bezier patch"), _n(counts["rational"], "rational patch"),
             _n(counts["trimmed"], "trimmed patch")]
    if counts["surfaces"]:
        kinds = ", ".join(f"{n} {kind}" for kind, (n, _) in sorted(counts["kinds"].items()))
        lines.append(f"{_n(counts['surfaces'], 'NURBS surface')} ({kinds}; {counts['trimmed_surfaces']} trimmed) "
                     f"-> {_n(counts['surface_patches'], 'Bezier patch')}")
    if counts["plain"] and counts["surfaces"]:
        lines.append(f"{_n(counts['plain'], 'patch')} given directly as Bezier patches")
    return lines


def _by_type(counter) -> str:
    """{144: 277, 128: 3} -> '277 x 144, 3 x 128' (most first)."""
    items = sorted(counter.items(), key=lambda kv: (-kv[1], str(kv[0])))
    return ", ".join(f"{n} x {t}" for t, n in items) or "none"


def import_rows(report: dict) -> list:
    """(label, text) rows of one free-form file's import report (IGES or OBJ)."""
    if report.get("format") == "iges":
        counts = report.get("counts", {})
        rows = [("format", f"IGES from {report.get('system') or 'unknown system'}"),
                ("units", str(report.get("units") or "?")),
                ("tolerance", f"{report['tolerance']:g} (modelling, global section)"
                 if report.get("tolerance") is not None else "not given"),
                ("surfaces", f"{report.get('surfaces', 0)} ({report.get('trimmed', 0)} with trimming loops)"),
                ("converted", _by_type(counts.get("converted", {}))),
                ("consumed", _by_type(counts.get("consumed", {}))),
                ("unsupported", _by_type(report.get("unsupported", {})))]
        if report.get("failed"):
            first = report["failed"][0]
            rows.append(("failed", (f"{len(report['failed'])}, e.g. DE {first['de']} (type {first['type']}): "
                                    f"{first['reason']}")))
        if report.get("lost") or report.get("notes"):
            rows.append(("not converted", f"{report.get('lost', 0)} entities, "
                                          f"{report.get('lost_surfaces', 0)} of them surfaces"))
            rows += [("damage", note) for note in report.get("notes", [])]
            rows += [("lost", group_line(g)) for g in report.get("losses", [])]
        for bucket in ("not_rendered", "non_geometry", "orphan"):
            if counts.get(bucket):
                rows.append((bucket.replace("_", " "), _by_type(counts[bucket])))
        if report.get("trim_widest_gap_rel"):
            gap = f"{report['trim_widest_gap_rel']:.3g} of the parameter range (DE {report.get('trim_widest_gap_de')})"
            rows.append(("widest trim gap", gap))
        if report.get("boundary_deviation_max") is not None:  # measured only on request (load_iges)
            dev = (f"{report['boundary_deviation_max']:.3g} {report.get('units') or ''} widest, face edge vs "
                   f"model curve (DE {report.get('boundary_deviation_de')})")
            rows.append(("edge deviation", dev))
        text = report.get("text") or {}
        if text.get("non_ascii_bytes"):
            rows.append(("non-ASCII", f"{text['non_ascii_bytes']} bytes read as '?' (first on line "
                                      f"{text.get('non_ascii_first_line')})"))
        if report.get("time_s") is not None:
            rows.append(("import time", f"{report['time_s']:g} s"))
        return rows
    rows = [("format", str(report.get("format", "?")).upper()),
            ("surfaces", f"{report.get('surfaces', 0)} ({report.get('trimmed', 0)} trimmed)")]
    if "curv2" in report:
        rows.append(("trim curves", str(report["curv2"])))
    if report.get("ignored"):
        rows.append(("ignored", ", ".join(f"{n} x {k}" for k, n in Counter(report["ignored"]).most_common())))
    if report.get("bridged_gaps"):
        rows.append(("bridged gaps", str(report["bridged_gaps"])))
    return rows


def surface_location(info) -> str:
    """Where a surface came from: 'sphere.obj line 51' or 'IGES 144 DE 123, surface 128 DE 121'."""
    e = info.entity or {}
    if "de" in e:
        text = f"IGES {e.get('type')} DE {e['de']}"
        if e.get("surface_de") not in (None, e["de"]):
            text += f", surface {e.get('surface_type')} DE {e['surface_de']}"
        return text + (f" '{e['label']}'" if e.get("label") else "")
    where = os.path.basename(info.source)
    return f"{where} line {e['line']}" if e.get("line", -1) >= 0 else where


def _iges_angles(entity: dict, u: float, v: float) -> dict:
    """For IGES surfaces of revolution: the IGES angle of a NURBS circle parameter (per axis)."""
    from tracer.revolution import CircleParam
    out = {}
    for axis, x in (("u", u), ("v", v)):
        rng = entity.get(f"angle_{axis}")
        if rng:
            out[axis] = float(CircleParam.for_sweep(*rng).angle(x))
    return out


def hit_surface(scene, patch: int, uv, samples: int = LOOP_SAMPLES) -> dict | None:
    """What the inspector shows about the surface of a hit on `patch` at `uv`, or None (no hit).

    uv is the hit's parameter pair as the renderer reports it: the NURBS surface's (u, v)
    for patches expanded from a surface, the patch's own (s, t) in [0, 1]^2 otherwise.
    Keys: patch, object, object_source, surface (-1: a plain Bezier patch), uv, patch_uv
    (s, t inside the patch), patch_domain [u0, u1, v0, v1]; for NURBS patches also name,
    kind, rational, degree, source, location, entity, surface_domain, surface_patches
    [first, count], trimmed, and for trimmed ones inside (tracer.trim.inside, the reference
    test) and loops [{'kind': 'trim'|'hole', 'points': (N, 2)}].
    """
    if patch is None or patch < 0 or patch >= scene.n_patches:
        return None
    u, v = (float(x) for x in uv)
    dom = [float(x) for x in scene.patch_domain[patch]]
    su, sv = dom[1] - dom[0], dom[3] - dom[2]
    obj = scene.objects[int(scene.patch_object[patch])]
    out = {"patch": int(patch), "object": obj.name, "object_source": obj.source, "uv": [u, v],
           "patch_uv": [(u - dom[0]) / su if su else 0.0, (v - dom[2]) / sv if sv else 0.0],
           "patch_domain": dom, "surface": int(scene.patch_surface[patch])}
    s = out["surface"]
    if s < 0:
        out["line"] = int(scene.patch_line[patch])
        return out
    info = scene.surfaces[s]
    trimmed = bool(scene.trims.has_trim[s])
    out.update(name=info.name, kind=info.kind, rational=bool(info.rational), degree=list(info.degree),
               source=info.source, location=surface_location(info), entity=dict(info.entity),
               surface_domain=[float(x) for x in info.domain],
               surface_patches=[int(info.first_patch), int(info.patch_count)], trimmed=trimmed)
    angles = _iges_angles(info.entity or {}, u, v)
    if angles:
        out["iges_angles"] = angles
    if trimmed:
        out["inside"] = bool(inside(scene.trims, s, u, v))
        out["loops"] = loops_for_plot(scene.trims, s, samples)
    return out


def summary_rows(info: dict) -> list:
    """(label, text) rows of hit_surface(...) for the inspector table."""
    def vec(xs):
        return ", ".join(f"{x:.6g}" for x in xs)

    d = info["patch_domain"]
    if info["surface"] < 0:
        line = f" line {info['line']}" if info.get("line", -1) >= 0 else ""
        return [("surface", f"Bezier patch of {info['object']} ({info['object_source']}{line})"),
                ("patch uv", vec(info["uv"]))]
    first, count = info["surface_patches"]
    kind = info["kind"] + (" (rational)" if info["rational"] and info["kind"] not in RATIONAL_KINDS else "")
    rows = [("surface", f"{info['surface']}: {info['name']}"),
            ("from", info["location"]),
            ("kind", f"{kind}, degree {info['degree'][0]}x{info['degree'][1]}, patches {first}..{first + count - 1}"),
            ("u, v", vec(info["uv"])),
            ("patch domain", f"u {d[0]:.6g}..{d[1]:.6g}, v {d[2]:.6g}..{d[3]:.6g}"),
            ("in patch", vec(info["patch_uv"]))]
    if "iges_angles" in info:
        rows.append(("IGES angle", ", ".join(f"{k} {np.degrees(a):.6g} deg" for k, a in info["iges_angles"].items())))
    if info["trimmed"]:
        kinds = Counter(loop["kind"] for loop in info["loops"])
        rows.append(("trims", f"{kinds.get('trim', 0)} trim, {kinds.get('hole', 0)} hole loops; hit "
                              + ("inside the kept region" if info["inside"] else "trimmed away (trims off?)")))
    else:
        rows.append(("trims", "none"))
    return rows


def info_json(info: dict | None) -> dict | None:
    """hit_surface(...) with arrays as lists (for the inspector's JSON dump)."""
    if info is None:
        return None
    out = dict(info)
    if "loops" in out:
        out["loops"] = [{"kind": loop["kind"], "points": np.asarray(loop["points"]).tolist()}
                        for loop in out["loops"]]
    return out
