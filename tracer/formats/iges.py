"""IGES import: NURBS (128), surfaces of revolution (120), trimmed surfaces (144).

tracer.formats.iges_sections reads the file as fixed-column ASCII (any line endings, stray
non-ASCII bytes) into directory entries and parameter records, pyiges' entity classes
decode the parameters of the types they know, and this module converts them.

Conversions, all exact unless said otherwise:
- 128 rational B-spline surface -> NurbsSurface on its [U0, U1] x [V0, V1].
- 120 surface of revolution -> rational NURBS (generatrix 110, 126 or 100 turned
  by rational quadratic arcs). u is the generatrix parameter and v the angle
  in IGES; in the NURBS, an angle becomes the rational circle parameter
  (equal at knots, see revolution.CircleParam), so trimming curves are pushed
  through that map: exactly for curves along a parameter line, by cubic
  pieces within 1e-11 of the parameter range elsewhere (counted in the report).
- 144 trimmed surface -> the base surface with a `trim` loop (outer boundary,
  unless it is the parameter rectangle itself) and `hole` loops, read from the
  parameter-space curves (BPTR) of the 142 boundaries: 126, 110, 100 and 102
  composites of them.
- 124 transformation matrices (chained) are applied to model-space geometry.

Every directory entry ends in one bucket of report['counts'] (converted,
consumed, failed, unsupported, unreadable, not_rendered, non_geometry, orphan), so
nothing is dropped silently; report['unsupported'] counts by type what could not be
turned into surfaces, and report['losses'] (tracer.formats.losses) groups every
entity that could have become a surface and did not (failed, unsupported,
unreadable, orphaned) by type and kind, with directory-entry numbers and a reason;
report['notes'] says when the file itself is cut short or inconsistent.
"""
from __future__ import annotations

import contextlib
import math
import time
from collections import Counter, defaultdict

import numpy as np

from tracer.errors import SceneError
from tracer.fixed_order import affine, matmul4
from tracer.formats.iges_sections import read_iges
from tracer.formats.losses import group_losses
from tracer.nurbs import FreeformModel, FreeformSurface, NurbsCurve, NurbsError, NurbsSurface, SurfaceInfo
from tracer.revolution import CircleParam, circle_arc, revolve
from tracer.trim import TrimError, curve_segments, make_loop, remap_segments

REMAP_TOL = 1e-11         # relative to the parameter range: trims through the angle map
SURFACE_TYPES = {108, 114, 118, 120, 122, 128, 140, 143, 144, 186, 190, 192, 194, 196, 198,
                 150, 152, 154, 156, 158, 160, 162, 164, 168, 180, 184, 430}
CURVE_TYPES = {100, 102, 104, 106, 110, 112, 116, 126, 130, 142, 146, 502, 504, 508, 510}
UNIT_NAMES = {1: "IN", 2: "MM", 4: "FT", 5: "MI", 6: "M", 7: "KM", 8: "MIL", 9: "UM",
              10: "CM", 11: "UIN"}


class _Unconvertible(Exception):
    """This entity cannot be converted; the message says why."""


def load_iges(path, measure_gaps: bool = False) -> FreeformModel:
    """Read an IGES file into free-form surfaces plus an import report; SceneError on failure.

    measure_gaps: also measure, for every trimming boundary with a model-space
    curve, the widest distance between the face's edge S(B(t)) and that curve
    (report['boundary_deviation_max'], model units). Two faces meeting at an
    edge can gap by at most the sum of their deviations. Costs about a second.
    """
    label = str(path)
    t_start = time.perf_counter()
    try:
        import pyiges  # noqa: F401  (its entity classes decode the parameters)
    except ImportError:
        raise SceneError("reading IGES needs the pyiges package (pip install pyiges)",
                         path=label) from None
    f = read_iges(path)
    conv = _Converter(f.entities.values(), f.glob, label, f.unreadable)
    conv.measure = measure_gaps
    model = conv.run(f.de_numbers)
    model.report.update(notes=f.notes, text=f.text)
    model.report["time_s"] = round(time.perf_counter() - t_start, 3)
    return model


def _status(e) -> tuple[int, int, int, int]:
    """(blank, subordinate, use, hierarchy) from pyiges' integer status field."""
    s = int(e.d.get("status_number") or 0)
    return s // 1000000 % 100, s // 10000 % 100, s // 100 % 100, s % 100


class _Converter:
    def __init__(self, entities, glob, label, unreadable=None):
        self.ents = {e.sequence_number: e for e in entities}
        self.glob, self.label = glob, label
        self.unreadable = unreadable or {}  # DE -> (type, kind, reason)
        self.used: set[int] = set()
        self.approximated = 0
        self.gaps: list[float] = []
        self.domain_outer = 0
        self.measure = False
        self.deviations: list[tuple[float, int]] = []

    # ---- entity access -------------------------------------------------------------

    def ent(self, seq, expect=None):
        e = self.ents.get(int(seq))
        if e is None:
            if int(seq) in self.unreadable:
                raise _Unconvertible(f"points to DE {seq}, which is unreadable "
                                     f"({self.unreadable[int(seq)][2]})")
            raise _Unconvertible(f"points to DE {seq}, which does not exist")
        t = e.d["entity_type_number"]
        if expect is not None and t not in expect:
            raise _Unconvertible(f"DE {seq} is type {t}, expected {'/'.join(map(str, expect))}")
        self.used.add(int(seq))
        return e

    def params(self, e) -> list[str]:
        if e.parameters and isinstance(e.parameters[0], list):
            return e.parameters[0]
        raise _Unconvertible(f"DE {e.sequence_number} has no parameter list")

    def matrix(self, e, depth=0) -> np.ndarray:
        """4x4 of the entity's DE transform (chained 124s), identity if none."""
        ptr = e.d.get("transform")
        if not ptr or depth > 32:
            return np.eye(4)
        t = self.ent(ptr, (124,))
        return matmul4(self.matrix(t, depth + 1), t.to_affine())

    # ---- curves --------------------------------------------------------------------

    def model_curve(self, seq) -> tuple[NurbsCurve, CircleParam | None]:
        """A model-space curve (110, 126, 100) as a 3-D NURBS; the angle map for an arc."""
        e = self.ent(seq)
        t = e.d["entity_type_number"]
        m = self.matrix(e)
        circ = None
        if t == 110:
            pts = e.coordinates
            curve = NurbsCurve(1, [0, 0, 1, 1], np.column_stack([pts, np.ones(2)]))
        elif t == 126:
            curve = self._bspline_curve(e, 3)
        elif t == 100:
            curve, circ = self._arc(e)
        else:
            raise _Unconvertible(f"generatrix of type {t} is not supported (110, 126, 100 are)")
        pts = curve.points.copy()
        pts[:, :3] = affine(pts[:, :3], m)
        return NurbsCurve(curve.degree, curve.knots, pts, curve.domain), circ

    def _bspline_curve(self, e, dim) -> NurbsCurve:
        cp = np.asarray(e.control_points, dtype=np.float64)[:, :dim]
        w = np.asarray(e.W, dtype=np.float64)
        knots = np.asarray(e.T, dtype=np.float64)
        lo, hi = e.V0, e.V1
        d0, d1 = knots[e.M], knots[len(cp)]
        eps = 1e-12 * max(1.0, abs(d0), abs(d1))
        lo, hi = (max(lo, d0) if lo > d0 - eps else lo), (min(hi, d1) if hi < d1 + eps else hi)
        return NurbsCurve(e.M, knots, np.column_stack([cp, w]), (lo, hi))

    def _arc(self, e):
        c = np.array([e.x, e.y])
        a0 = math.atan2(e.y1 - e.y, e.x1 - e.x)
        a1 = math.atan2(e.y2 - e.y, e.x2 - e.x)
        r = math.hypot(e.x1 - e.x, e.y1 - e.y)
        if (e.x1, e.y1) == (e.x2, e.y2):
            a1 = a0 + 2 * math.pi
        elif a1 <= a0:
            a1 += 2 * math.pi
        return circle_arc(np.array([c[0], c[1], e.z]), r, a0, a1,
                          (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))

    def curve_segments(self, seq, parent=None, depth=0) -> list[np.ndarray]:
        """Bezier segments (k, 4) x y z w of a 126, 110, 100 or a 102 of them, transforms applied."""
        e = self.ent(seq)
        t = e.d["entity_type_number"]
        m = self.matrix(e) if parent is None else matmul4(parent, self.matrix(e))
        if t == 102:
            if depth > 8:
                raise _Unconvertible("composite curves nested too deeply")
            p = self.params(e)
            return [s for ptr in p[2:2 + int(p[1])]
                    for s in self.curve_segments(int(ptr), m, depth + 1)]
        if t == 110:
            segs = [np.column_stack([e.coordinates, np.ones(2)])]
        elif t == 126:
            segs = curve_segments(self._bspline_curve(e, 3))
        elif t == 100:
            segs = curve_segments(self._arc(e)[0])
        else:
            raise _Unconvertible(f"curve of type {t} is not supported (126, 110, 100, 102 are)")
        if np.array_equal(m, np.eye(4)):
            return segs
        return [np.column_stack([affine(s[:, :3], m), s[:, 3]]) for s in segs]

    def param_curve(self, seq) -> list[np.ndarray]:
        """Bezier segments (u, v, w) of a parameter-space curve (x, y of the IGES curve)."""
        return [s[:, [0, 1, 3]] for s in self.curve_segments(seq)]

    # ---- surfaces ------------------------------------------------------------------

    def surface(self, seq):
        """(NurbsSurface in model space, (map_u, map_v), type) of a 128 or 120."""
        e = self.ent(seq)
        t = e.d["entity_type_number"]
        if t == 128:
            surf, maps = self._bspline_surface(e), (None, None)
        elif t == 120:
            p = self.params(e)
            axis = self.ent(int(p[1]), (110,))
            am = self.matrix(axis)
            a = affine(axis.coordinates, am)
            gen, gcirc = self.model_curve(int(p[2]))
            try:
                surf, circ = revolve(gen, a[0], a[1] - a[0], _float(p[3]), _float(p[4]))
            except NurbsError as err:
                raise _Unconvertible(f"surface of revolution: {err}") from None
            maps = (gcirc, circ)
        else:
            raise _Unconvertible(f"surface of type {t} is not supported (128, 120 are)")
        return _transformed(surf, self.matrix(e)), maps, t

    def _bspline_surface(self, e) -> NurbsSurface:
        k1, k2, m1, m2 = e._k1, e._k2, e._m1, e._m2
        p = self.params(e)
        at = 14 + k1 + m1 + k2 + m2 + 4 * (k1 + 1) * (k2 + 1)
        try:
            dom = [_float(x) for x in p[at:at + 4]]
        except ValueError:
            dom = []
        ku, kv = np.asarray(e.knot1, float), np.asarray(e.knot2, float)
        if len(dom) != 4:
            raise _Unconvertible("128: cannot read the parameter range U0 U1 V0 V1")
        for i, (k, n, d) in enumerate(((ku, k1 + 1, m1), (ku, k1 + 1, m1), (kv, k2 + 1, m2),
                                       (kv, k2 + 1, m2))):
            lo, hi = k[d], k[n]
            eps = 1e-12 * max(1.0, abs(lo), abs(hi))
            dom[i] = min(max(dom[i], lo), hi) if lo - eps <= dom[i] <= hi + eps else dom[i]
        pts = np.concatenate([np.asarray(e._cp, float).reshape(k2 + 1, k1 + 1, 3),
                              np.asarray(e.weights, float).reshape(k2 + 1, k1 + 1, 1)], axis=2)
        return NurbsSurface(m1, m2, ku, kv, pts, tuple(dom))

    def boundary(self, seq, kind, surf, maps) -> list:
        """One 142 boundary as a TrimLoop in the NURBS parameters, or None if it is the domain."""
        e = self.ent(seq, (142,))
        p = self.params(e)
        bptr, cptr = int(p[3]), int(p[4])
        if cptr:
            with contextlib.suppress(_Unconvertible):
                self.mark(cptr)
        if not bptr:
            raise _Unconvertible("boundary 142 has no parameter-space curve (BPTR = 0); "
                                 "projecting model-space curves is not supported")
        segs = self.param_curve(bptr)
        if self.measure and cptr:
            with contextlib.suppress(_Unconvertible, NurbsError, ValueError):
                d = _deviation(surf, maps, segs, self.curve_segments(cptr))
                self.deviations.append((d, int(seq)))
        u0, u1, v0, v1 = surf.domain
        extent = max(u1 - u0, v1 - v0)
        if any(maps):
            segs, n = remap_segments(segs, maps, REMAP_TOL * extent)
            self.approximated += n
        if kind == "trim" and _on_domain_boundary(segs, surf.domain):
            self.domain_outer += 1
            return None
        try:
            loop = make_loop(kind, segs, math.inf)
        except TrimError as err:
            raise _Unconvertible(f"boundary 142 DE {seq}: {err}") from None
        self.gaps.append((loop.bridged_gap / extent, int(seq)))
        return loop

    def mark(self, seq, depth=0):
        """Mark an entity and everything it points to as used (model-space edge curves)."""
        e = self.ent(seq)
        t = e.d["entity_type_number"]
        if t == 102 and depth < 8:
            p = self.params(e)
            for ptr in p[2:2 + int(p[1])]:
                self.mark(int(ptr), depth + 1)
        self.matrix(e)

    def trimmed(self, e) -> FreeformSurface:
        p = self.params(e)
        pts, n1, n2 = int(p[1]), int(p[2]), int(p[3])
        surf, maps, stype = self.surface(pts)
        loops = []
        if n1:
            loops.append(self.boundary(int(p[4]), "trim", surf, maps))
        for ptr in p[5:5 + n2]:
            loops.append(self.boundary(int(ptr), "hole", surf, maps))
        surf = _transformed(surf, self.matrix(e))
        loops = [l for l in loops if l is not None]
        base = self.ents[pts]
        return self._record(surf, e, loops, {"type": 144, "de": e.sequence_number,
                                             "surface_type": stype, "surface_de": pts,
                                             "label": base.d.get("entity_label") or "",
                                             **_angle_info(maps)})

    def _record(self, surf, e, loops, entity) -> FreeformSurface:
        t = entity["surface_type"]
        kind = "revolution" if t == 120 else ("nurbs" if surf.rational else "bspline")
        name = e.d.get("entity_label") or f"{entity['type']}@{entity['de']}"
        info = SurfaceInfo(name, self.label, kind, surf.rational, bool(loops),
                           (surf.degree_u, surf.degree_v), surf.domain, entity=entity)
        return FreeformSurface(surf, info, loops)

    # ---- driver --------------------------------------------------------------------

    def run(self, de_numbers) -> FreeformModel:
        surfaces, failed, converted = [], [], set()
        order = sorted(self.ents)
        attempts = [s for s in order if self.ents[s].d["entity_type_number"] == 144
                    and _status(self.ents[s])[1] == 0]
        referenced = set()
        for s in attempts:
            with contextlib.suppress(Exception):
                referenced.add(int(self.params(self.ents[s])[1]))
        attempts += [s for s in order if self.ents[s].d["entity_type_number"] in (128, 120)
                     and _status(self.ents[s])[1] == 0 and s not in referenced]
        attempts.sort()
        for seq in attempts:
            e = self.ents[seq]
            before = set(self.used)
            try:
                if e.d["entity_type_number"] == 144:
                    surfaces.append(self.trimmed(e))
                else:
                    self.used.add(seq)
                    surf, maps, t = self.surface(seq)
                    surfaces.append(self._record(surf, e, [], {
                        "type": t, "de": seq, "surface_type": t, "surface_de": seq,
                        "label": e.d.get("entity_label") or "", **_angle_info(maps)}))
                converted.add(seq)
            except (_Unconvertible, NurbsError, TrimError, ValueError, IndexError,
                    AttributeError, TypeError) as err:
                self.used = before
                failed.append({"de": seq, "type": e.d["entity_type_number"],
                               "reason": str(err) or type(err).__name__})
        failed_de = {f["de"] for f in failed}
        counts: dict[str, Counter] = defaultdict(Counter)
        lost = [{"de": f["de"], "type": f["type"], "kind": "conversion failed",
                 "reason": f["reason"]} for f in failed]
        for seq in de_numbers:
            e = self.ents.get(seq)
            if e is None:
                t, kind, reason = self.unreadable[seq]
                counts["unreadable"][t if t is not None else "?"] += 1
                lost.append({"de": seq, "type": t, "kind": kind, "reason": reason})
                continue
            t = e.d["entity_type_number"]
            sub = _status(e)[1]
            if seq in converted:
                bucket = "converted"
            elif seq in failed_de:
                bucket = "failed"
            elif seq in self.used:
                bucket = "consumed"
            elif sub != 0:
                bucket = "orphan"
                if t in SURFACE_TYPES:  # a surface only its parent would have drawn
                    lost.append({"de": seq, "type": t, "kind": "orphan",
                                 "reason": "a subordinate surface whose parent was not "
                                           "converted"})
            elif t in SURFACE_TYPES:
                bucket = "unsupported"
                lost.append({"de": seq, "type": t, "kind": "unsupported entity type",
                             "reason": f"type {t} is not converted (128, 120, 144 are)"})
            elif t in CURVE_TYPES or 200 <= t < 300 or t == 116:
                bucket = "not_rendered"
            else:
                bucket = "non_geometry"
            counts[bucket][t] += 1
        unsupported = Counter()
        for b in ("failed", "unsupported"):
            unsupported.update(counts.get(b, {}))
        tol = self.glob.get(19)
        report = {
            "format": "iges", "file": self.label,
            "system": self.glob.get(5, ""), "units": self.glob.get(15) or
            UNIT_NAMES.get(int(self.glob.get(14, 0) or 0), ""),
            "tolerance": float(tol) if isinstance(tol, float) else None,
            "max_coordinate": self.glob.get(20),
            "entities": dict(sorted(Counter(self.ents[s].d["entity_type_number"]
                                            for s in self.ents).items())),
            "directory_entries": len(de_numbers),
            "counts": {b: dict(sorted(c.items(), key=lambda kv: str(kv[0])))
                       for b, c in sorted(counts.items())},
            "unsupported": dict(sorted(unsupported.items())),
            "failed": failed,
            "losses": group_losses(lost, SURFACE_TYPES),
            "lost": len(lost),
            "lost_surfaces": sum(1 for x in lost if x["type"] in SURFACE_TYPES),
            "surfaces": len(surfaces),
            "trimmed": sum(1 for s in surfaces if s.loops),
            "outer_loop_is_domain": self.domain_outer,
            "trim_segments_approximated": self.approximated,
            "trim_approx_tol_rel": REMAP_TOL,
            "trim_widest_gap_rel": max(self.gaps, default=(0.0, None))[0],
            "trim_widest_gap_de": max(self.gaps, default=(0.0, None))[1],
        }
        if self.measure:
            worst = max(self.deviations, default=(0.0, None))
            report["boundary_deviation_max"] = worst[0]
            report["boundary_deviation_de"] = worst[1]
            report["boundaries_measured"] = len(self.deviations)
        return FreeformModel(surfaces, report)


def _angle_info(maps) -> dict:
    """For axes that are angles in IGES: {'angle_u'/'angle_v': [a0, a1]}.

    CircleParam.for_sweep(a0, a1).angle(x) turns the NURBS parameter x back into
    the IGES angle (they agree at the knots, every 90 degrees at most).
    """
    return {f"angle_{k}": [m.a0, m.a1] for k, m in zip("uv", maps) if m is not None}


def _transformed(surf: NurbsSurface, m: np.ndarray) -> NurbsSurface:
    if np.array_equal(m, np.eye(4)):
        return surf
    pts = surf.points.copy()
    pts[..., :3] = affine(pts[..., :3], m)
    return NurbsSurface(surf.degree_u, surf.degree_v, surf.knots_u, surf.knots_v, pts, surf.domain)


def _deviation(surf, maps, pcurve, model_segs, per_segment: int = 6) -> float:
    """Widest distance from S(B(t)) (sampled) to the model-space curve C (its Bezier segments)."""
    from tracer.trim import evaluate_segment
    t = np.linspace(0.0, 1.0, per_segment)
    uv = np.concatenate([evaluate_segment(s, t) for s in pcurve])
    uv = np.column_stack([m.param(uv[:, k]) if m else uv[:, k] for k, m in enumerate(maps)])
    lo = np.array(surf.domain[0::2])
    hi = np.array(surf.domain[1::2])
    pts = surf.evaluate_many(*np.clip(uv, lo, hi).T)
    # the model curve's segments, degree-elevated to one degree, homogeneous: (S, n+1, 4)
    n = max(len(seg) for seg in model_segs) - 1
    hs = []
    for seg in model_segs:
        h = np.column_stack([seg[:, :3] * seg[:, 3:], seg[:, 3]])
        while len(h) <= n:  # exact degree elevation
            k = len(h)
            a_ = (np.arange(1, k) / k)[:, None]
            h = np.vstack([h[:1], a_ * h[:-1] + (1 - a_) * h[1:], h[-1:]])
        hs.append(h)
    hs = np.array(hs)
    binom = np.array([math.comb(n, i) for i in range(n + 1)], dtype=np.float64)

    def at(k, x):
        """Points of model segments k at parameters x (same shapes)."""
        b = binom * x[..., None] ** np.arange(n + 1) * (1 - x[..., None]) ** (n - np.arange(n + 1))
        p = np.einsum("...i,...ic->...c", b, hs[k])
        return p[..., :3] / p[..., 3:]

    m = 65
    coarse = np.linspace(0.0, 1.0, m)
    samples = at(np.repeat(np.arange(len(hs)), m), np.tile(coarse, len(hs)))
    d = np.einsum("nsc,nsc->ns", diff := pts[:, None, :] - samples[None], diff)
    cand = np.argpartition(d, 2, axis=1)[:, :3]  # refine around the three nearest samples
    k, i = cand // m, cand % m
    a, b = coarse[np.maximum(i - 1, 0)], coarse[np.minimum(i + 1, m - 1)]
    q = pts[:, None, :]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(45):
        c1, c2 = b - g * (b - a), a + g * (b - a)
        closer = np.linalg.norm(at(k, c1) - q, axis=2) < np.linalg.norm(at(k, c2) - q, axis=2)
        a, b = np.where(closer, a, c1), np.where(closer, c2, b)
    best = np.minimum(np.linalg.norm(at(k, (a + b) / 2) - q, axis=2).min(axis=1),
                      np.sqrt(d.min(axis=1)))
    return float(best.max())


def _float(text: str) -> float:
    """An IGES real: Fortran D exponents allowed."""
    return float(text.strip().replace("D", "E").replace("d", "e"))


def _on_domain_boundary(segs, domain) -> bool:
    """Do all segments run along the edges of the parameter rectangle (so the loop is it)?"""
    u0, u1, v0, v1 = domain
    eps = 1e-9 * max(u1 - u0, v1 - v0)
    for s in segs:
        u, v = s[:, 0], s[:, 1]
        if not (np.all(np.abs(u - u0) <= eps) or np.all(np.abs(u - u1) <= eps)
                or np.all(np.abs(v - v0) <= eps) or np.all(np.abs(v - v1) <= eps)):
            return False
    return True
