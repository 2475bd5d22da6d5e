"""Reader for `.bpt` Bezier patch files (see /work/shared/scene-format.md).

Whitespace separated, as the contract says: the patch count, then for each patch a header
`m n` (two integers on one line, or n alone on its line: an n that shares the line of the
points is a header missing its n) and (m+1)*(n+1) control points of 3 numbers (x y z) or
4 (x y z w). `#` starts a comment that runs to the end of its line; lines are counted at
"\\n" only, so a form feed or vertical tab inside a line is just a space. Numbers are plain
ASCII decimals (tracer.formats.source.NUMBER).

A patch's points have 3 or 4 numbers. When its first point starts a line of 3 or 4 numbers
(the usual layout, a point a line), that count holds and every point of the patch must fill
a line of its own. Otherwise (points run together, everything on one line, ...) it is the
count after which the next patch headers (LOOKAHEAD of them), or the end of the file,
follow; if both counts fit, an error says the file is ambiguous.

Vectorised: numpy tokenises and converts the text a block at a time as the parser reaches
it, and a run of patches with the same header and layout as the one before is checked and
cut out as one array (points run together are then read with that patch's count). Junk
after the last patch is reported as soon as it is reached.
"""
import re
from dataclasses import dataclass

import numpy as np

from tracer.errors import SceneError
from tracer.formats.source import not_a_number, quote, read_text, shown

MAX_DEGREE = 20
FIRST_BLOCK = 1 << 20     # characters tokenised first; each further block is twice the last
FIRST_RUN = 1024          # patches checked at once in a run; doubles while the run goes on
LOOKAHEAD = 3             # patches read ahead to tell 3 from 4 numbers a point in a stream

_SPACE = np.zeros(256, bool)
_SPACE[list(b" \t\n\r\x0b\x0c")] = True
_NOT_INTEGER = np.zeros(256, bool)
_NOT_INTEGER[list(b".eE")] = True
_BAD_CHAR = re.compile(r"[^0-9eE+\-. \t\n\r\x0b\x0c]")
_COMMENT = re.compile(r"#[^\n]*")
_WORD = re.compile(r"[^ \t\n\r\x0b\x0c]+")


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


@dataclass(frozen=True)
class PatchArrays:
    """Patches as flat arrays in file order: what loaders hand the scene (no object a patch).

    points (total, 4) float64 as in PatchData, patch k's rows start[k]:start[k+1];
    start (n+1,) int64; degree_u, degree_v (n,) int32; rational (n,) bool; line (n,) int32
    (the header's line, -1 where there is none).
    """
    points: np.ndarray
    start: np.ndarray
    degree_u: np.ndarray
    degree_v: np.ndarray
    rational: np.ndarray
    line: np.ndarray

    def __len__(self) -> int:
        return len(self.degree_u)

    def patches(self) -> list[PatchData]:
        s = self.start.tolist()
        return [PatchData(int(m), int(n), self.points[s[k]:s[k + 1]], bool(r), int(line))
                for k, (m, n, r, line) in enumerate(zip(self.degree_u, self.degree_v,
                                                        self.rational, self.line))]

    @classmethod
    def of(cls, patches: list[PatchData]) -> "PatchArrays":
        return cls.join([cls(p.points, np.array([0, len(p.points)]), np.array([p.degree_u]),
                             np.array([p.degree_v]), np.array([p.rational]), np.array([p.line]))
                         for p in patches])

    @classmethod
    def join(cls, parts: list["PatchArrays"]) -> "PatchArrays":
        if not parts:
            return cls(np.empty((0, 4)), np.zeros(1, np.int64), *(np.empty(0, t) for t in (
                np.int32, np.int32, bool, np.int32)))
        sizes = np.cumsum([0] + [len(p.points) for p in parts])
        start = np.concatenate([[0]] + [p.start[1:] + o for p, o in zip(parts, sizes)])
        return cls(np.concatenate([p.points for p in parts]).astype(np.float64),
                   start.astype(np.int64),
                   *(np.concatenate([getattr(p, f) for p in parts]).astype(t) for f, t in (
                       ("degree_u", np.int32), ("degree_v", np.int32), ("rational", bool),
                       ("line", np.int32))))


def load_bpt(path) -> list[PatchData]:
    """Read and parse a `.bpt` file; every failure is a SceneError."""
    return load_bpt_arrays(path).patches()


def load_bpt_arrays(path) -> PatchArrays:
    """load_bpt as flat arrays (the scene's way: 100,000 patches take no object each)."""
    label = str(path)
    text = read_text(path)
    return _Parser(text, label).run()


class _Tokens:
    """The numbers of a text, tokenised as far as the parser has asked.

    Parallel arrays by token index: value (float64), line (int64, 1-based), integral (no
    '.', 'e' or 'E' in the token), start/end (offsets in the text). Tokenising stops at the
    first token that is not a number (`bad`: its text and line).
    """

    def __init__(self, text: str):
        self.text = text
        self.done, self.at_line, self.block = 0, 1, FIRST_BLOCK
        self.value = np.empty(0)
        self.line = np.empty(0, np.int64)
        self.integral = np.empty(0, bool)
        self.start = np.empty(0, np.int64)
        self.end = np.empty(0, np.int64)
        self.bad = None
        self.last_line = max(1, text.count("\n") + (0 if text.endswith("\n") else 1))

    @property
    def n(self) -> int:
        return len(self.value)

    def need(self, k: int) -> bool:
        """Tokenise until k tokens are known (or the text or its numbers end); are there k?"""
        while self.n < k and self.bad is None and self.done < len(self.text):
            self._more()
        return self.n >= k

    def _more(self) -> None:
        text = self.text
        stop = text.find("\n", self.done + self.block)
        stop = len(text) if stop < 0 else stop + 1
        self.block *= 2
        chunk = text[self.done:stop]
        if "#" in chunk:  # blank comments out, keeping offsets
            chunk = _COMMENT.sub(lambda m: " " * len(m.group()), chunk)
        cut = len(chunk)
        m = _BAD_CHAR.search(chunk)
        if m:
            cut = max(chunk.rfind(c, 0, m.start()) for c in " \t\n\r\x0b\x0c") + 1
        data = chunk[:cut].encode("ascii")
        a = np.frombuffer(data, np.uint8)
        space = _SPACE[a]
        word = ~space
        start = np.flatnonzero(word & np.concatenate(([True], space[:-1])))
        end = np.flatnonzero(word & np.concatenate((space[1:], [True]))) + 1
        words = data.split()
        try:
            value = np.array(words, dtype=np.float64)
        except ValueError:  # a token of digits and signs that is no number ("1e", "--2")
            first = next(i for i, w in enumerate(words) if not _is_float(w))
            value = np.array(words[:first], dtype=np.float64)
            cut = int(start[first])
            start, end = start[:first], end[:first]
        line = self.at_line + np.searchsorted(np.flatnonzero(a == 10), start)
        marks = np.concatenate(([0], np.cumsum(_NOT_INTEGER[a])))
        self._append(value, line, marks[end] == marks[start], start + self.done,
                     end + self.done)
        if cut < len(chunk):
            token = _WORD.match(chunk, cut).group()
            self.bad = (token, self.at_line + chunk.count("\n", 0, cut))
            return
        self.at_line += chunk.count("\n")
        self.done = stop

    def _append(self, value, line, integral, start, end):
        self.value = np.concatenate((self.value, value))
        self.line = np.concatenate((self.line, line))
        self.integral = np.concatenate((self.integral, integral))
        self.start = np.concatenate((self.start, start))
        self.end = np.concatenate((self.end, end))

    def word(self, i: int) -> str:
        return self.text[self.start[i]:self.end[i]]

    def rest_of_line(self, i: int) -> str:
        """Token i and what follows it on its line, comment dropped."""
        if i >= self.n:
            return self.bad[0] if self.bad else ""
        stop = self.text.find("\n", self.start[i])
        return self.text[self.start[i]:None if stop < 0 else stop].split("#", 1)[0].strip()

    def on_line(self, line: int) -> int:
        """How many numbers line `line` holds (it is tokenised, the arrays are by line)."""
        return int(np.searchsorted(self.line, line, "right") - np.searchsorted(self.line, line))


def _is_float(word: bytes) -> bool:
    try:
        float(word)
        return True
    except ValueError:
        return False


def parse_bpt(text: str, path_label: str) -> list[PatchData]:
    """Parse `.bpt` text; ``path_label`` names the source in error messages."""
    return _Parser(text, path_label).run().patches()


class _Parser:
    def __init__(self, text, label):
        self.tk = _Tokens(text)
        self.label = label

    def fail(self, msg, line):
        raise SceneError(msg, path=self.label, line=line)

    def fail_bad(self):
        word, line = self.tk.bad
        self.fail(not_a_number(word), line)

    def fail_short(self, what):
        """Token needed but missing: the token that is not a number, else the end of the file."""
        if self.tk.bad:
            self.fail_bad()
        self.fail(f"unexpected end of file{what}", self.tk.last_line)

    def run(self) -> PatchArrays:
        tk = self.tk
        if not tk.need(1):
            if tk.bad:
                self.fail(f"expected the number of patches (a positive integer), got "
                          f"{quote(tk.bad[0])}", tk.bad[1])
            self.fail("empty file (expected the number of patches)", tk.last_line)
        if not (tk.integral[0] and 1 <= tk.value[0] < 2 ** 53):
            self.fail(f"expected the number of patches (a positive integer), got "
                      f"{quote(tk.word(0))}", int(tk.line[0]))
        self.count = int(tk.value[0])
        parts, done, pos = [], 0, 1
        while done < self.count:
            m, n, w, lines, end = self.patch(pos, done + 1)
            runs = self.run_length(end, m, n, w, self.count - done - 1, lines)
            parts.append(self.cut(pos, m, n, w, 1 + runs))
            done += 1 + runs
            pos = end + runs * (2 + (m + 1) * (n + 1) * w)
        if tk.need(pos + 1) or tk.bad:
            line = int(tk.line[pos]) if pos < tk.n else tk.bad[1]
            self.fail(f"extra content after the last patch ({self.count} patches announced): "
                      f"{quote(tk.rest_of_line(pos))}", line)
        return PatchArrays.join(parts)

    # ---- one patch, checked token by token where it matters ------------------------

    def patch(self, pos, p):
        """(m, n, width, one point a line?, end) of patch p whose header is token pos."""
        tk, total = self.tk, self.count
        if not tk.need(pos + 2):
            if tk.n <= pos and not tk.bad:
                self.fail(f"unexpected end of file: patch {p} of {total} is missing "
                          f"(expected its header 'm n')", tk.last_line)
        hline = int(tk.line[pos]) if pos < tk.n else tk.bad[1]
        if not self.header_at(pos):
            self.fail(f"patch {p}: expected a header 'm n' (two integers), "
                      f"got {quote(tk.rest_of_line(pos))}", hline)
        for k in (pos, pos + 1):
            if not 1 <= tk.value[k] <= MAX_DEGREE:
                self.fail(f"patch {p}: degree {shown(tk.word(k))} out of range "
                          f"(allowed 1..{MAX_DEGREE})", hline)
        m, n = int(tk.value[pos]), int(tk.value[pos + 1])
        count, first = (m + 1) * (n + 1), pos + 2
        where = f" in patch {p} of {total}: expected {count} control points"
        if not tk.need(first + 5) and tk.n <= first:
            self.fail_short(where + ", got 0")
        fline = int(tk.line[first])
        if tk.bad and tk.bad[1] == fline and tk.n < first + 5:
            self.fail_bad()
        on_line = int(np.count_nonzero(tk.line[first:first + 5] == fline))
        if tk.line[first - 1] < fline and on_line in (3, 4):
            self.check_lines(first, count, on_line, where)
            return m, n, on_line, True, first + count * on_line
        w = self.stream_width(first, count, p)
        if w is None and tk.line[first - 1] < fline and on_line < 3:  # a point a line, short
            self.fail(f"expected 3 or 4 numbers per control point, got {on_line}", fline)
        w = w or 3  # neither count reads on: the errors come as the tokens are read as 3s
        end = first + count * w
        if not tk.need(end):
            self.fail_short(where + f", got {(tk.n - first) // w}")
        self.check_values(first, count, w, end)
        return m, n, w, False, end

    def header_at(self, q) -> bool:
        """Are tokens q, q+1 two integers that read as a header: on one line, or n alone on
        its line (a number a line)? (n on the line of the points is a header missing its n.)"""
        tk = self.tk
        if not (tk.need(q + 3) or tk.n >= q + 2) or not (tk.integral[q] and tk.integral[q + 1]):
            return False
        line = tk.line[q + 1]
        return bool(tk.line[q] == line or (q + 2 >= tk.n and not tk.bad) or tk.line[q + 2] > line)

    def check_lines(self, first, count, w, where):
        """The points of a patch laid out a point a line: each fills its own line."""
        tk = self.tk
        end = first + count * w
        tk.need(end + 1)
        j = np.arange(first + 1, min(end + 1, tk.n))
        new_row = (j - first) % w == 0
        ok = np.where(new_row, tk.line[j] > tk.line[j - 1], tk.line[j] == tk.line[j - 1])
        layout = int(j[np.argmin(ok)]) if not ok.all() else None
        self.check_values(first, count, w, min(tk.n, end) if layout is None else layout)
        if layout is not None:
            line = int(tk.line[layout - 1])
            self.fail(f"expected {w} numbers per control point (as in the patch's first "
                      f"point), got {tk.on_line(line)}", line)
        if tk.n < end:
            self.fail_short(where + f", got {(tk.n - first) // w}")

    def check_values(self, first, count, w, before):
        """Finite coordinates and positive weights in the points that end before token `before`."""
        tk = self.tk
        rows = (min(before, first + count * w) - first) // w
        pts = tk.value[first:first + rows * w].reshape(rows, w)
        bad = ~np.isfinite(pts).all(axis=1)
        if w == 4:
            bad |= pts[:, 3] <= 0
        if not bad.any():
            return
        r = int(np.argmax(bad))
        k = first + r * w
        line = int(tk.line[k])
        words = [tk.word(i) for i in range(k, k + w)]
        if not np.isfinite(pts[r]).all():
            self.fail(f"control point is not finite: {shown(' '.join(words))}", line)
        self.fail(f"weight must be > 0, got {shown(words[3])}", line)

    def stream_width(self, first, count, p):
        """3 or 4: the count after which the following patches (LOOKAHEAD of them, or all
        that are left) read on, the last ending the file; None if neither does."""
        fits = [w for w in (3, 4) if self.fits(first + count * w, p, LOOKAHEAD)]
        if len(fits) == 2:
            self.fail(f"patch {p}: cannot tell whether its control points have 3 or 4 numbers "
                      f"(both fit); put each control point on a line of its own",
                      int(self.tk.line[first]))
        return fits[0] if fits else None

    def fits(self, q, p, depth) -> bool:
        """Can token q start patch p+1 (q the end of the file if p was the last), with
        `depth` patches more reading on after it?"""
        tk = self.tk
        if p == self.count:
            tk.need(q + 1)
            return tk.n == q and not tk.bad
        if not (self.header_at(q) and all(1 <= tk.value[k] <= MAX_DEGREE for k in (q, q + 1))):
            return False
        count = (int(tk.value[q]) + 1) * (int(tk.value[q + 1]) + 1)
        return depth == 0 or any(self.fits(q + 2 + count * w, p + 1, depth - 1) for w in (3, 4))

    # ---- runs of patches like the last, checked as arrays ----------------------------

    def run_length(self, pos, m, n, w, most, one_a_line):
        """How many patches from token pos on repeat header m n, laid out like the patch
        before them: a point a line of w (one_a_line), or run together (read w a point)."""
        tk = self.tk
        count = (m + 1) * (n + 1)
        stride = 2 + count * w
        done, batch = 0, FIRST_RUN
        while done < most:
            start = pos + done * stride
            r = min(batch, most - done)
            tk.need(start + r * stride + 1)
            r = min(r, (tk.n - start) // stride)
            if r <= 0:
                break
            block = slice(start, start + r * stride)
            lines = tk.line[block].reshape(r, stride)
            head = lines[:, :2]
            pts = lines[:, 2:].reshape(r, count, w)
            after = np.append(lines[1:, 0], tk.line[start + r * stride]
                              if tk.n > start + r * stride else np.iinfo(np.int64).max)
            value = tk.value[block].reshape(r, stride)
            coords = value[:, 2:].reshape(r, count, w)
            integral = tk.integral[block].reshape(r, stride)
            ok = (integral[:, 0] & integral[:, 1] & (value[:, 0] == m) & (value[:, 1] == n)
                  & (head[:, 0] == head[:, 1]) & np.isfinite(coords).all(axis=(1, 2)))
            if one_a_line:
                ok &= ((pts == pts[:, :, :1]).all(axis=(1, 2)) & (pts[:, 0, 0] > head[:, 1])
                       & (pts[:, 1:, 0] > pts[:, :-1, -1]).all(axis=1) & (after > pts[:, -1, -1]))
            else:  # as patch() decides: the first point does not start a line of 3 or 4,
                # and the count w reads on to a header (or to the end after the last patch)
                first = pts.reshape(r, -1)
                ok &= (first[:, 0] == head[:, 1]) | (first[:, 4] == first[:, 0])
                heads = (integral[:, 0] & integral[:, 1] & (head[:, 0] == head[:, 1])
                         & (value[:, :2] >= 1).all(axis=1) & (value[:, :2] <= MAX_DEGREE).all(axis=1))
                last = start + r * stride
                ok &= np.append(heads[1:], self.fits(last, self.count - most + done + r, 0))
            if w == 4:
                ok &= (coords[:, :, 3] > 0).all(axis=1)
            if not ok.all():
                return done + int(np.argmin(ok))
            done += r
            batch *= 2
        return done

    def cut(self, pos, m, n, w, runs) -> PatchArrays:
        """`runs` patches of header m n and width w from token pos on."""
        tk = self.tk
        count = (m + 1) * (n + 1)
        stride = 2 + count * w
        block = slice(pos, pos + runs * stride)
        pts = np.ones((runs * count, 4))
        pts[:, :w] = tk.value[block].reshape(runs, stride)[:, 2:].reshape(runs * count, w)
        return PatchArrays(pts, np.arange(runs + 1, dtype=np.int64) * count,
                           np.full(runs, m, np.int32), np.full(runs, n, np.int32),
                           np.full(runs, w == 4), tk.line[block][::stride].astype(np.int32))
