"""A tiny IGES writer for tests: fixed-column S, G, D, P and T sections from entity lists."""
from __future__ import annotations


def _line(data: str, section: str, seq: int) -> str:
    assert len(data) <= 72, data
    return f"{data:<72}{section}{seq:>7}"


def global_section(author: str = "psrt tests") -> str:
    fields = ["1H,", "1H;", "4Hpsrt", "8Htiny.igs", "4Hpsrt", "3H1.0", "32", "38", "6", "308",
              "15", "4Htiny", "1.", "2", "2HMM", "1", "0.1", "15H20250101.000000", "1E-08",
              "10.", f"{len(author)}H{author}", "4Htest", "11", "0", "15H20250101.000000"]
    return ",".join(fields) + ";"


def iges_text(entities, start: str = "psrt test file", author: str = "psrt tests") -> str:
    """IGES text (LF line endings) for entities: dicts with type, params (list of str, the type
    first), and optionally status (8 digits) and form. Entity k gets DE number 2k+1."""
    s_lines = [_line(start, "S", 1)]
    g_text = global_section(author)
    g_lines = [_line(g_text[i:i + 72], "G", k + 1) for k, i in enumerate(range(0, len(g_text), 72))]
    d_lines, p_lines = [], []
    for k, e in enumerate(entities):
        de = 2 * k + 1
        chunks, cur = [], ""
        fields = list(e["params"])
        for i, f in enumerate(fields):
            piece = f + (";" if i == len(fields) - 1 else ",")
            if len(cur) + len(piece) > 64:
                chunks.append(cur)
                cur = ""
            cur += piece
        chunks.append(cur)
        first = len(p_lines) + 1
        for c in chunks:
            p_lines.append(f"{c:<64}{de:>8}P{len(p_lines) + 1:>7}")
        t, status, form = e["type"], e.get("status", "00000000"), e.get("form", 0)
        d_lines.append(_line(f"{t:>8}{first:>8}{0:>8}{0:>8}{0:>8}{0:>8}{0:>8}{0:>8}{status:>8}",
                             "D", de))
        d_lines.append(_line(f"{t:>8}{0:>8}{0:>8}{len(chunks):>8}{form:>8}{'':>8}{'':>8}"
                             f"{e.get('label', ''):>8}{0:>8}", "D", de + 1))
    t_line = _line(f"S{len(s_lines):>7}G{len(g_lines):>7}D{len(d_lines):>7}P{len(p_lines):>7}",
                   "T", 1)
    return "\n".join(s_lines + g_lines + d_lines + p_lines + [t_line]) + "\n"


def _bicubic(z: float) -> list[str]:
    """A 128 bicubic Bezier patch over [0, 3]^2 at height z (a gentle bump), knots 0 0 0 0 1 1 1 1."""
    pts = []
    for j in range(4):
        for i in range(4):
            pts += [f"{i:.1f}", f"{j:.1f}", f"{z + (0.5 if 0 < i < 3 and 0 < j < 3 else 0):.2f}"]
    return (["128", "3", "3", "3", "3", "0", "0", "1", "0", "0"] + ["0.", "0.", "0.", "0.", "1.",
            "1.", "1.", "1."] * 2 + ["1."] * 16 + pts + ["0.", "1.", "0.", "1."])


def tiny_entities() -> list[dict]:
    """Two surfaces: an independent 128 (DE 1) and a 144 (DE 9) trimming a second 128 (DE 3)
    by a square p-curve 126 (DE 5) on a 142 (DE 7); and a colour 314 with a Hollerith name."""
    square = [(0.2, 0.2), (0.8, 0.2), (0.8, 0.8), (0.2, 0.8), (0.2, 0.2)]
    curve = (["126", "4", "1", "0", "0", "1", "0", "0.", "0.", "0.25", "0.5", "0.75", "1.", "1."]
             + ["1."] * 5 + [f"{c:.2f}" for u, v in square for c in (u, v, 0.0)]
             + ["0.", "1.", "0.", "0.", "1."])
    return [
        {"type": 128, "params": _bicubic(0.0)},
        {"type": 128, "params": _bicubic(2.0), "status": "00010000"},
        {"type": 126, "params": curve, "status": "00010500"},
        {"type": 142, "params": ["142", "1", "3", "5", "0", "1"], "status": "00010000"},
        {"type": 144, "params": ["144", "3", "1", "0", "7"]},
        {"type": 314, "params": ["314", "50.", "50.", "50.", "5HGREEN"], "status": "00000200"},
    ]


def tiny_iges(**kw) -> str:
    return iges_text(tiny_entities(), **kw)
