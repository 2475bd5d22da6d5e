"""Wavefront OBJ free-form geometry: rational and integral Bezier / B-spline surfaces with trims.

Read: `v x y z [w]`, `vp u v [w]`, `cstype [rat] bezier|bspline`, `deg du [dv]`,
`surf s0 s1 t0 t1 v/vt/vn ...` and `curv2 vp ...` with their bodies (`parm u|v`,
`trim`, `hole`) closed by `end`; names from `o`/`g`. A trailing backslash
continues a line, `#` starts a comment. Indices are 1-based, negative ones
count back from the last element defined before the statement; positive ones
may point forward. Surface control points are listed with u varying fastest.

For `cstype bezier`, `parm` lists the global parameter breaks of the segments
(s segments of degree p take s*p + 1 control points); without `parm` a Bezier
element is one segment on [0, 1]. Non-rational types ignore vertex weights.

Display and grouping statements (`vt`, `vn`, `g`, `s`, `mg`, `usemtl`, ...)
are counted in the report and otherwise ignored; polygons and the free-form
statements this reader does not implement are errors naming the line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tracer.errors import SceneError
from tracer.formats.source import (INTEGER, not_a_number, parse_int, parse_number, quote, read_text,
                                   shown, split_lines, split_words)
from tracer.nurbs import (MAX_DEGREE, FreeformModel, FreeformSurface, NurbsCurve, NurbsError,
                          NurbsSurface, SurfaceInfo, bezier_knots)
from tracer.trim import TrimError, curve_segments, make_loop

POLYGON = ("f", "l", "p", "fo")
UNSUPPORTED = ("bmat", "step", "ctech", "stech", "scrv", "sp", "con", "curv", "call", "csh",
               "res")
IGNORED = ("vt", "vn", "g", "s", "mg", "usemtl", "mtllib", "lod", "shadow_obj", "trace_obj",
           "bevel", "c_interp", "d_interp", "maplib", "usemap")
CLOSE_TOL = 1e-6  # trim gaps up to this times the surface's parameter extent are bridged


@dataclass
class _Element:
    kind: str                   # 'surf' | 'curv2'
    line: int
    rational: bool
    basis: str                  # 'bezier' | 'bspline'
    deg: tuple
    refs: list                  # 0-based indices (may still be out of range: checked later)
    name: str = ""
    srange: tuple = ()
    parm: dict = field(default_factory=dict)     # 'u'/'v' -> (values, line)
    loops: list = field(default_factory=list)    # (kind, [(t0, t1, curve index)], line)


def load_obj(path) -> FreeformModel:
    """Read and parse an OBJ free-form file; every failure is a SceneError."""
    label = str(path)
    text = read_text(path)
    return parse_obj(text, label)


def _statements(text):
    """(line number, tokens) per statement: comments stripped, backslash continuations joined."""
    pending, start = [], 0
    for no, raw in enumerate(split_lines(text), start=1):
        body = raw.split("#", 1)[0].rstrip()
        if not pending:
            start = no
        if body.endswith("\\"):
            pending.append(body[:-1])
            continue
        pending.append(body)
        toks = split_words(" ".join(pending))
        pending = []
        if toks:
            yield start, toks
    if pending:
        toks = split_words(" ".join(pending))
        if toks:
            yield start, toks


def parse_obj(text: str, path_label: str) -> FreeformModel:
    """Parse OBJ free-form text; ``path_label`` names the source in error messages."""
    def fail(msg, line):
        raise SceneError(msg, path=path_label, line=line)

    def numbers(toks, lo, hi, what, line):
        if not lo <= len(toks) <= hi:
            want = f"{lo}" if lo == hi else f"{lo} to {hi}"
            fail(f"{what}: expected {want} numbers, got {len(toks)}", line)
        vals = []
        for t in toks:
            x = parse_number(t)
            if x is None:
                fail(f"{what}: {not_a_number(t)}", line)
            vals.append(x)
        return vals

    def index(tok, count, what, line):
        i = parse_int(tok)
        if i is None:
            fail(f"{what}: {quote(tok)} is not an integer index"
                 + (" (too many digits)" if INTEGER.match(tok) else ""), line)
        if i == 0:
            fail(f"{what}: index 0 is invalid (indices start at 1, negative count back)", line)
        if i < 0:
            if -i > count:
                fail(f"{what}: relative index {i} reaches before the first "
                     f"(only {count} defined so far)", line)
            return count + i
        return i - 1

    verts, vert_lines, vps, vp_lines = [], [], [], []
    elements, curves = [], []
    cstype, deg, cur = None, None, None
    names = {"o": "", "g": ""}  # a surface is named by the current object, else its group
    ignored = {}
    for line, toks in _statements(text):
        kw, args = toks[0], toks[1:]
        if kw == "v":
            x = numbers(args, 3, 4, "v", line)
            if len(x) == 4 and x[3] <= 0:
                fail(f"v: weight must be > 0, got {shown(args[3])}", line)
            verts.append(x + [1.0] * (4 - len(x)))
            vert_lines.append(line)
        elif kw == "vp":
            x = numbers(args, 1, 3, "vp", line)
            if len(x) == 3 and x[2] <= 0:
                fail(f"vp: weight must be > 0, got {shown(args[2])}", line)
            vps.append(x + [math.nan, 1.0][len(x) - 1:])  # v missing -> nan, w -> 1
            vp_lines.append(line)
        elif kw == "cstype":
            rat = bool(args) and args[0] == "rat"
            rest = args[1:] if rat else args
            if len(rest) != 1:
                fail("cstype: expected [rat] followed by one type", line)
            if rest[0] in ("bmatrix", "cardinal", "taylor"):
                fail(f"cstype {rest[0]} is not supported (supported: bezier, bspline, "
                     f"rat bezier, rat bspline)", line)
            if rest[0] not in ("bezier", "bspline"):
                fail(f"cstype: unknown type {quote(rest[0])} (expected bezier or bspline)", line)
            cstype = (rat, rest[0])
        elif kw == "deg":
            if len(args) not in (1, 2):
                fail(f"deg: expected 1 or 2 integers, got {len(args)}", line)
            d = []
            for a in args:
                k = parse_int(a)
                if k is None or not 1 <= k <= MAX_DEGREE:
                    fail(f"deg: {quote(a)} is not a degree in 1..{MAX_DEGREE}", line)
                d.append(k)
            deg = tuple(d)
        elif kw in ("surf", "curv2"):
            if cur is not None:
                fail(f"'{kw}' before the 'end' of the {cur.kind} at line {cur.line}", line)
            if cstype is None:
                fail(f"{kw}: no 'cstype' given before it", line)
            if deg is None:
                fail(f"{kw}: no 'deg' given before it", line)
            if kw == "surf":
                if len(deg) != 2:
                    fail("surf: needs two degrees ('deg du dv')", line)
                if len(args) < 5:
                    fail("surf: expected 's0 s1 t0 t1' and control point references", line)
                srange = tuple(numbers(args[:4], 4, 4, "surf", line))
                refs = [index(r.split("/")[0], len(verts), "surf", line) for r in args[4:]]
                for r in args[4:]:
                    if any(p and parse_int(p) is None for p in r.split("/")[1:]) \
                            or r.count("/") > 2:
                        fail(f"surf: bad reference {quote(r)} (expected v, v/vt, v/vt/vn or "
                             f"v//vn)", line)
                cur = _Element("surf", line, cstype[0], cstype[1], deg, refs,
                               names["o"] or names["g"], srange)
            else:
                if len(args) < 2:
                    fail("curv2: expected at least 2 parameter vertex references", line)
                refs = [index(r, len(vps), "curv2", line) for r in args]
                cur = _Element("curv2", line, cstype[0], cstype[1], deg[:1], refs)
        elif kw == "parm":
            if cur is None:
                fail("'parm' outside a surf or curv2 body", line)
            if not args or args[0] not in ("u", "v"):
                fail("parm: expected 'u' or 'v' followed by parameter values", line)
            if args[0] == "v" and cur.kind == "curv2":
                fail("parm v: a curv2 has only a u direction", line)
            cur.parm[args[0]] = (numbers(args[1:], 2, 10 ** 9, f"parm {args[0]}", line), line)
        elif kw in ("trim", "hole"):
            if cur is None or cur.kind != "surf":
                fail(f"'{kw}' outside a surf body", line)
            if not args or len(args) % 3:
                fail(f"{kw}: expected triples 'u0 u1 curv2' (got {len(args)} values)", line)
            triples = []
            for k in range(0, len(args), 3):
                t0, t1 = numbers(args[k:k + 2], 2, 2, kw, line)
                triples.append((t0, t1, index(args[k + 2], len(curves), kw, line)))
            cur.loops.append((kw, triples, line))
        elif kw == "end":
            if cur is None:
                fail("'end' without a surf or curv2 to close", line)
            (elements if cur.kind == "surf" else curves).append(cur)
            cur = None
        elif kw == "o":
            names["o"] = " ".join(args)
        elif kw in IGNORED:
            ignored[kw] = ignored.get(kw, 0) + 1
            if kw == "g":
                names["g"] = " ".join(args)
        elif kw in POLYGON:
            fail(f"polygon meshes are not supported yet (statement '{kw}'); this reader takes "
                 f"free-form surfaces (surf)", line)
        elif kw in UNSUPPORTED:
            fail(f"'{kw}' is not supported (free-form statements read: v, vp, cstype, deg, "
                 f"surf, curv2, parm, trim, hole, end)", line)
        else:
            fail(f"unknown statement {quote(kw)}", line)
    if cur is not None:
        fail(f"{cur.kind} at line {cur.line} has no 'end'", cur.line)

    verts = np.array(verts, dtype=np.float64).reshape(-1, 4)
    vps = np.array(vps, dtype=np.float64).reshape(-1, 3)
    built_curves = [None] * len(curves)

    def knots_for(el, axis, degree, count):
        """Knot vector and control count along one axis of an element."""
        if axis in el.parm:
            vals, pline = el.parm[axis]
            if el.basis == "bezier":
                return bezier_knots(vals, degree), degree * (len(vals) - 1) + 1, pline
            return np.array(vals), len(vals) - degree - 1, pline
        if el.basis == "bspline":
            fail(f"{el.kind}: B-spline needs 'parm {axis}' (its knot vector)", el.line)
        return bezier_knots([0.0, 1.0], degree), degree + 1, el.line

    def curve(ci, line):
        if ci >= len(curves):
            fail(f"curv2 {ci + 1} does not exist ({len(curves)} defined)", line)
        if built_curves[ci] is None:
            el = curves[ci]
            for r in el.refs:
                if r >= len(vps):
                    fail(f"curv2: vp {r + 1} does not exist ({len(vps)} defined)", el.line)
            pts = vps[el.refs].copy()
            if np.any(np.isnan(pts[:, 1])):
                k = int(np.argmax(np.isnan(pts[:, 1])))
                fail(f"curv2: control point {k + 1} (vp at line {vp_lines[el.refs[k]]}) has no "
                     f"v coordinate", el.line)
            if not el.rational:
                pts[:, 2] = 1.0
            knots, count, pline = knots_for(el, "u", el.deg[0], len(pts))
            if count != len(pts):
                fail(f"curv2: {len(pts)} control points, but degree {el.deg[0]} and the "
                     f"{len(el.parm['u'][0]) if 'u' in el.parm else 2} parm u values need "
                     f"{count}", el.line)
            try:
                built_curves[ci] = NurbsCurve(el.deg[0], knots, pts)
            except NurbsError as e:
                fail(f"curv2: {e}", pline)
        return built_curves[ci]

    surfaces = []
    for el in elements:
        for r in el.refs:
            if r >= len(verts):
                fail(f"surf: v {r + 1} does not exist ({len(verts)} defined)", el.line)
        du, dv = el.deg
        ku, nu, _ = knots_for(el, "u", du, None)
        kv, nv, _ = knots_for(el, "v", dv, None)
        if nu * nv != len(el.refs) or nu < 1 or nv < 1:
            fail(f"surf: {len(el.refs)} control points, but the degrees {du} {dv} and the parm "
                 f"values need {max(nu, 0)} x {max(nv, 0)} = {max(nu, 0) * max(nv, 0)}", el.line)
        pts = verts[el.refs].reshape(nv, nu, 4).copy()
        if not el.rational:
            pts[..., 3] = 1.0
        s0, s1, t0, t1 = el.srange
        try:
            surf = NurbsSurface(du, dv, ku, kv, pts, (s0, s1, t0, t1))
        except NurbsError as e:
            fail(f"surf: {e}", el.line)
        extent = max(s1 - s0, t1 - t0)
        loops, raw = [], []
        for kind, triples, line in el.loops:
            segs, pieces = [], []
            for a, b, ci in triples:
                c = curve(ci, line)
                if a == b:
                    fail(f"{kind}: empty parameter range {a:g} {b:g} for curv2 {ci + 1}", line)
                try:
                    part = curve_segments(c, min(a, b), max(a, b))
                except NurbsError as e:
                    fail(f"{kind}: curv2 {ci + 1}: {e}", line)
                if a > b:  # walk the curve backwards
                    part = [s[::-1].copy() for s in reversed(part)]
                segs += part
                pieces.append((c, a, b))
            try:
                loops.append(make_loop(kind, segs, CLOSE_TOL * extent))
            except TrimError as e:
                fail(f"{kind}: {e}", line)
            raw.append((kind, pieces))
        kind = ("rational " if surf.rational else "") + el.basis
        info = SurfaceInfo(el.name or f"surf@{el.line}", path_label, kind, surf.rational,
                           bool(loops), (du, dv), surf.domain, entity={"line": el.line})
        surfaces.append(FreeformSurface(surf, info, loops, raw))
    report = {"format": "obj", "file": path_label, "surfaces": len(surfaces),
              "curv2": len(curves), "trimmed": sum(1 for s in surfaces if s.loops),
              "ignored": ignored,
              "bridged_gaps": sum(1 for s in surfaces for l in s.loops if l.bridged_gap > 0)}
    return FreeformModel(surfaces, report)


# ---- writing ------------------------------------------------------------------------

def dumps_obj(surfaces, comment: str = "") -> str:
    """OBJ text for surfaces; round-trips exactly through parse_obj.

    surfaces: iterable of (name, NurbsSurface, loops) with loops a list of
    (kind, [(NurbsCurve, t0, t1), ...]) in the surface's parameter space.
    Floats are written with repr, so values come back bit for bit.
    """
    out = [f"# {line}" for line in comment.splitlines()]
    nv = nvp = ncurv = 0
    for name, s, loops in surfaces:
        rat = s.rational
        out.append(f"o {name}")
        net = s.points.reshape(-1, 4)
        for p in net:
            out.append("v " + " ".join(repr(float(x)) for x in (p if rat else p[:3])))
        curve_ids = []
        for kind, pieces in loops:
            ids = []
            for c, _, _ in pieces:
                crat = c.rational
                for p in c.points:
                    out.append("vp " + " ".join(repr(float(x)) for x in (p if crat else p[:2])))
                out.append(f"cstype {'rat ' if crat else ''}bspline")
                out.append(f"deg {c.degree}")
                out.append("curv2 " + " ".join(str(nvp + 1 + k) for k in range(len(c.points))))
                out.append("parm u " + " ".join(repr(float(k)) for k in c.knots))
                out.append("end")
                nvp += len(c.points)
                ncurv += 1
                ids.append(ncurv)
            curve_ids.append(ids)
        out.append(f"cstype {'rat ' if rat else ''}bspline")
        out.append(f"deg {s.degree_u} {s.degree_v}")
        refs = " ".join(str(nv + 1 + k) for k in range(len(net)))
        out.append("surf " + " ".join(repr(float(x)) for x in s.domain) + " " + refs)
        out.append("parm u " + " ".join(repr(float(k)) for k in s.knots_u))
        out.append("parm v " + " ".join(repr(float(k)) for k in s.knots_v))
        for (kind, pieces), ids in zip(loops, curve_ids):
            out.append(kind + " " + " ".join(f"{float(t0)!r} {float(t1)!r} {i}"
                                             for (_, t0, t1), i in zip(pieces, ids)))
        out.append("end")
        nv += len(net)
    return "\n".join(out) + "\n"
