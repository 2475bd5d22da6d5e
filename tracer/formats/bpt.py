"""Reader for `.bpt` Bezier patch files (see /work/shared/scene-format.md).

Line-oriented: the patch count, each patch header ``m n`` and each control
point (``x y z`` or ``x y z w``) stand on their own line; ``#`` starts a
comment anywhere on a line.
"""
import math
import re
from dataclasses import dataclass

import numpy as np

from tracer.errors import SceneError, read_text

MAX_DEGREE = 20

_INT = re.compile(r"[+-]?\d+\Z")


@dataclass(frozen=True)
class PatchData:
    """One Bezier patch as read from a file.

    ``points`` is float64 (``(m+1)*(n+1)``, 4): Euclidean x, y, z and the
    weight w (1.0 for integral points), not premultiplied. Row
    ``k = j*(m+1) + i`` is ``P[i][j]`` with ``i`` the u index.
    """
    degree_u: int
    degree_v: int
    points: np.ndarray
    rational: bool
    line: int  # line of the patch header "m n"


def load_bpt(path) -> list[PatchData]:
    """Read and parse a `.bpt` file; every failure is a SceneError."""
    label = str(path)
    text = read_text(path)
    return parse_bpt(text, label)


def parse_bpt(text: str, path_label: str) -> list[PatchData]:
    """Parse `.bpt` text; ``path_label`` names the source in error messages."""
    lines = [(no, raw.split("#", 1)[0].split())
             for no, raw in enumerate(text.splitlines(), start=1)]
    lines = [(no, toks) for no, toks in lines if toks]
    eof_line = max(1, len(text.splitlines()))

    def fail(msg, line):
        raise SceneError(msg, path=path_label, line=line)

    if not lines:
        fail("empty file (expected the number of patches)", eof_line)
    no, toks = lines[0]
    if len(toks) != 1 or not _INT.match(toks[0]) or int(toks[0]) < 1:
        fail(f"expected the number of patches (a positive integer) alone on the line, "
             f"got {' '.join(toks)!r}", no)
    n_patches = int(toks[0])

    patches, pos = [], 1
    for p in range(1, n_patches + 1):
        if pos >= len(lines):
            fail(f"unexpected end of file: patch {p} of {n_patches} is missing "
                 f"(expected its header 'm n')", eof_line)
        head_no, toks = lines[pos]
        pos += 1
        if len(toks) != 2 or not all(_INT.match(t) for t in toks):
            fail(f"patch {p}: expected a header 'm n' (two integers), got {' '.join(toks)!r}",
                 head_no)
        m, n = int(toks[0]), int(toks[1])
        for d in (m, n):
            if not 1 <= d <= MAX_DEGREE:
                fail(f"patch {p}: degree {d} out of range (allowed 1..{MAX_DEGREE})", head_no)
        count = (m + 1) * (n + 1)
        rows, width = [], None
        for k in range(count):
            if pos >= len(lines):
                fail(f"unexpected end of file in patch {p} of {n_patches}: "
                     f"expected {count} control points, got {k}", eof_line)
            no, toks = lines[pos]
            pos += 1
            rows.append(_point(toks, width, fail, no))
            width = len(toks)
        pts = np.ones((count, 4), dtype=np.float64)
        pts[:, :width] = rows
        patches.append(PatchData(m, n, pts, width == 4, head_no))

    if pos < len(lines):
        no, toks = lines[pos]
        fail(f"extra content after the last patch ({n_patches} patches announced): "
             f"{' '.join(toks)!r}", no)
    return patches


def _point(toks, width, fail, no):
    """Validate one control point line and return its numbers."""
    vals = []
    for t in toks:
        try:
            vals.append(float(t))
        except ValueError:
            fail(f"{t!r} is not a number", no)
    if width is None and len(vals) not in (3, 4):
        fail(f"expected 3 or 4 numbers per control point, got {len(vals)}", no)
    if width is not None and len(vals) != width:
        fail(f"expected {width} numbers per control point (as in the patch's first point), "
             f"got {len(vals)}", no)
    if not all(math.isfinite(v) for v in vals):
        fail(f"control point is not finite: {' '.join(toks)}", no)
    if len(vals) == 4 and vals[3] <= 0:
        fail(f"weight must be > 0, got {toks[3]}", no)
    return vals
