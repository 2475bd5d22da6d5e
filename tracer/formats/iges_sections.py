"""IGES as fixed-column ASCII: lines, sections, directory entries and parameter records.

Read as bytes whatever the line endings (LF, CRLF, CR, or none at all: 80-byte records) and
whatever stray bytes >= 0x80 a CAD tool wrote (an accented author name in the start or
global section): each non-ASCII character becomes one '?', so every field stays in the
columns the format puts it in (a UTF-8 line is decoded first when that makes it 80 columns).

Damage to the file's structure (a line that is no IGES line, sections out of order, a
sequence number out of step) is a SceneError naming the section, its sequence number and
the file line. Damage inside one entity (a directory field or a parameter that is no plain
ASCII number, a pointer past the parameter section, a record without its ';') makes that
entity unreadable: it is kept aside with the reason, so the converter reports it by
directory-entry number instead of losing it. A file cut short loses the entities whose data
is missing, and says so in `notes`. pyiges' entity classes decode the parameters of the
types they know; every other type keeps its raw parameter list.
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field

from tracer.errors import SceneError
from tracer.formats.source import not_a_number, parse_int, quote, read_bytes

SECTIONS = {"S": "start", "G": "global", "D": "directory", "P": "parameter", "T": "terminate"}
RECORD = 80
# directory entry fields: (name, first line?, first column (0-based)); each 8 columns wide
_D_FIELDS = (("entity_type_number", 0, 0), ("parameter_pointer", 0, 8), ("structure", 0, 16),
             ("line_font_pattern", 0, 24), ("level", 0, 32), ("view", 0, 40),
             ("transform", 0, 48), ("label_assoc", 0, 56), ("line_weight_number", 1, 8),
             ("color_number", 1, 16), ("param_line_count", 1, 24), ("form_number", 1, 32),
             ("entity_subs_num", 1, 64))
_NUMBER = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[EeDd][+-]?[0-9]+)?"  # D: Fortran exponents
_IGES_NUMBER = re.compile(_NUMBER + r"\Z")
_HOLLERITH = re.compile(r" *([0-9]+)H")


class _NonAscii(dict):
    """str.translate table: every non-ASCII character becomes '?'."""

    def __missing__(self, code):
        if code < 128:
            raise LookupError(code)
        return "?"


_HIGH = _NonAscii()
_BLANK = " \t\x1a"  # a line of only these (\x1a: DOS end of file) is skipped
_ORDER = re.compile("S*G*D*P*T?")
_FIELD = rf" *(?:{_NUMBER})? *"
_BIG = re.compile(r"[EeDd][+-]?0*[1-9][0-9]{2}|[0-9]{300}")  # a number that may overflow


class Unreadable(Exception):
    """This entity's directory entry or parameter data cannot be read; says where and why."""

    def __init__(self, kind: str, reason: str):
        super().__init__(reason)
        self.kind = kind


@dataclass
class IgesFile:
    """The sections of an IGES file, read; entities still as pyiges objects."""
    label: str
    start: str                       # the start section's text
    glob: dict                       # global parameters by 1-based index (tracer.formats.iges)
    de_numbers: list[int]            # every directory entry's sequence number, in file order
    entities: dict                   # readable entries: DE number -> pyiges entity
    unreadable: dict                 # DE number -> (entity type or None, kind, reason)
    notes: list[str] = field(default_factory=list)  # whole-file findings (cut short, ...)
    text: dict = field(default_factory=dict)        # line endings, non-ASCII bytes replaced


def read_iges(path) -> IgesFile:
    """Read an IGES file's sections and entities; SceneError for a file that is no IGES."""
    label = str(path)
    lines, text, partial = _lines(read_bytes(path), label)
    notes = []
    sections = _sections(lines, label, partial, notes)
    if not sections["D"]:
        raise SceneError("no directory entries: not an IGES file", path=label)
    glob = global_section("".join(t[:72] for _, t in sections["G"]))
    delim, end = glob.get(1) or ",", glob.get(2) or ";"
    if not (isinstance(delim, str) and isinstance(end, str) and len(delim) == len(end) == 1):
        no = sections["G"][0][0] if sections["G"] else None
        raise SceneError("global section G 1: cannot read the parameter and record "
                         "delimiters", path=label, line=no)
    f = IgesFile(label, " ".join(t[:72].strip() for _, t in sections["S"]), glob, [], {}, {},
                 notes, text)
    _entries(f, sections["D"], sections["P"], delim, end)
    return f


# ---- lines ----------------------------------------------------------------------------

def _lines(data: bytes, label):
    """[(file line, 80-column text, columns it had)], what was normalised, the line number of
    a last line the file ends inside (or None); blank lines dropped."""
    info = {}
    if b"\x00" in data[:RECORD]:
        raise SceneError("binary IGES is not supported (ASCII IGES only)", path=label)
    if b"\n" not in data and b"\r" not in data:
        raw = [data[i:i + RECORD] for i in range(0, len(data), RECORD)]
        info["line_endings"] = "none (80-byte records)"
        ends_inside = True
    else:
        crlf = data.count(b"\r\n")
        counts = {"LF": data.count(b"\n") - crlf, "CRLF": crlf, "CR": data.count(b"\r") - crlf}
        info["line_endings"] = "+".join(k for k, v in counts.items() if v)
        raw = re.split(rb"\r\n|\r|\n", data)
        ends_inside = raw[-1] != b""  # no line ending after the last line
        if not ends_inside:
            raw.pop()
    out, high, first_high = [], 0, None
    for no, line in enumerate(raw, start=1):
        if line.isascii():
            text = line.decode("ascii")
        else:
            high += sum(b >= 0x80 for b in line)
            first_high = first_high or no
            text = None
            if len(line) > RECORD:  # UTF-8 from a tool that counted characters, not bytes
                try:
                    text = line.decode("utf-8").translate(_HIGH)
                except UnicodeDecodeError:
                    pass
                if text is not None and len(text) > RECORD:
                    text = None
            if text is None:
                text = line.decode("latin-1").translate(_HIGH)
        if not text.strip(_BLANK):
            continue
        if len(text) > RECORD and text[RECORD:].strip(_BLANK):
            raise SceneError(f"not an IGES line: {len(text)} columns, expected 80", path=label,
                             line=no)
        out.append((no, text[:RECORD].ljust(RECORD), min(len(text), RECORD)))
    if high:
        info["non_ascii_bytes"] = high
        info["non_ascii_first_line"] = first_high
    partial = (out[-1][0] if out and ends_inside and out[-1][0] == len(raw)
               and out[-1][2] < RECORD else None)
    return out, info, partial


def _sections(lines, label, partial, notes) -> dict:
    """Lines (file line, text) by section letter, in order and numbered 1, 2, ... (checked).

    `partial`: the file line the file ends inside; where it fails a check, the file was cut
    there, and the line is dropped with a note instead of an error."""
    sections = _sections_at_once(lines)
    at = 0
    for no, text, width in lines if sections is None else ():
        sections = sections or {c: [] for c in SECTIONS}
        try:
            at = _check_line(sections, no, text, width, at, lines[0][0], label)
        except SceneError:
            if no != partial:
                raise
            notes.append(f"the file ends inside line {no}, which is dropped (cut short?)")
            continue
        sections[text[72]].append((no, text))
    sections = sections or {c: [] for c in SECTIONS}
    if not sections["T"]:
        last = lines[-1][0] if lines else 0
        notes.append(f"no terminate section: the file ends at line {last} (cut short?)")
    else:
        t = sections["T"][0][1]
        for k, c in enumerate("SGDP"):
            said = parse_int(t[8 * k + 1:8 * k + 8].strip()) if t[8 * k] == c else None
            if said is not None and said != len(sections[c]):
                notes.append(f"the terminate section counts {said} {SECTIONS[c]} lines, "
                             f"the file has {len(sections[c])}")
    return sections


def _sections_at_once(lines) -> dict | None:
    """The sections of a sound file in one go (what _check_line checks line by line), or None
    if anything is off: then the line by line check says what and where."""
    if not lines or min(w for _, _, w in lines) < 73:
        return None
    if not _ORDER.fullmatch("".join(t[72] for _, t, _ in lines)):
        return None
    sections = {c: [] for c in SECTIONS}
    for no, text, _ in lines:
        sections[text[72]].append((no, text))
    for c, part in sections.items():
        seq = [t[73:80] for _, t in part]
        if any("_" in x for x in seq):  # int() takes 1_0
            return None
        try:
            if list(map(int, seq)) != list(range(1, len(seq) + 1)):
                return None
        except ValueError:
            return None
    return sections


def _check_line(sections, no, text, width, at, first, label) -> int:
    """Check one line's section letter, order and sequence number; the section index now."""
    order = "SGDPT"
    c = text[72]
    if width < 73:
        raise SceneError(f"not an IGES line: {width} columns (expected 80, with S, G, D, P or "
                         f"T in column 73)", path=label, line=no)
    if c not in SECTIONS:
        if c in "BC" and no == first:
            raise SceneError(f"{'binary' if c == 'B' else 'compressed'} IGES (column 73 of "
                             f"the first line is {c}) is not supported", path=label, line=no)
        raise SceneError(f"not an IGES line: column 73 holds {quote(c)}, expected S, G, D, P "
                         f"or T", path=label, line=no)
    k = order.index(c)
    if k < at or sections["T"]:
        last = "terminate" if sections["T"] else SECTIONS[order[at]]
        raise SceneError(f"a {SECTIONS[c]} section line after the {last} section (the "
                         f"sections run S, G, D, P, T)", path=label, line=no)
    seq = text[73:80].strip()
    expect = len(sections[c]) + 1
    if parse_int(seq) != expect:
        raise SceneError(f"{SECTIONS[c]} section {c} {expect}: sequence number {quote(seq)}, "
                         f"expected {expect} (a line missing, doubled or damaged)", path=label,
                         line=no)
    return k


def global_section(text: str) -> dict:
    """Global parameters by 1-based index; strings (Hollerith nH...) decoded, numbers as float."""
    delim, end = ",", ";"
    if text.startswith("1H"):
        delim = text[2]
    elif text[:1] not in (",", ""):
        return {}
    out, i, idx = {}, 0, 1
    # the first two fields name the delimiters themselves
    while i < len(text) and idx < 40:
        j = i
        while j < len(text) and text[j] == " ":
            j += 1
        k = j
        while k < len(text) and text[k].isascii() and text[k].isdigit():
            k += 1
        if k > j and k < len(text) and text[k] == "H" and k - j < 6:
            n = int(text[j:k])
            value = text[k + 1:k + 1 + n]
            i = k + 1 + n
        else:
            stop = i
            while stop < len(text) and text[stop] not in (delim, end):
                stop += 1
            value = text[i:stop].strip()
            i = stop
            if _IGES_NUMBER.match(value):
                number = float(value.replace("D", "E").replace("d", "e"))
                value = number if math.isfinite(number) else value
        if idx == 2 and isinstance(value, str) and value:
            end = value
        if value != "":
            out[idx] = value
        if i >= len(text) or text[i] == end:
            break
        i += 1  # skip the delimiter
        idx += 1
    return out


# ---- entities -------------------------------------------------------------------------

def _entries(f: IgesFile, dlines, plines, delim, end) -> None:
    """Fill f.de_numbers, f.entities and f.unreadable from the D and P sections."""
    from pyiges.entity import Entity
    back = [t[64:72] for _, t in plines]  # each line's DE number
    try:
        back = list(map(int, back)) if not any("_" in b for b in back) else None
    except ValueError:
        back = None
    back = back or [parse_int(t[64:72].strip()) for _, t in plines]
    for k in range(0, len(dlines), 2):
        de = k + 1
        f.de_numbers.append(de)
        kind = "unreadable directory entry"
        etype = parse_int(dlines[k][1][:8].strip())
        try:
            if k + 1 >= len(dlines):
                raise Unreadable(kind, f"D {de}: the entry's second line is missing "
                                       f"(the directory section is cut short)")
            d = _directory_fields(dlines[k][1], dlines[k + 1][1], de)
            tokens = _parameters(d, de, plines, back, delim, end)
            e = _CLASSES().get(d["entity_type_number"], Entity)(None)
            e.d, e.sequence_number = d, de
            try:
                e._add_parameters(tokens)
            except Exception as err:  # pyiges indexes and converts as it goes
                raise Unreadable("unreadable parameter data",
                                 f"P {d['parameter_pointer']}: the {d['entity_type_number']} "
                                 f"entity's parameters do not decode "
                                 f"({type(err).__name__}: {quote(str(err))})") from None
            e.parameters = [tokens]
            f.entities[de] = e
        except Unreadable as err:
            f.unreadable[de] = (etype, err.kind, str(err))


def _directory_fields(first: str, second: str, de: int) -> dict:
    lines = (first, second)
    d = {}
    plain = "_" not in first and "_" not in second  # then int() reads only ASCII integers
    for name, which, col in _D_FIELDS:
        text = lines[which][col:col + 8].strip()
        try:
            value = (int(text) if plain else parse_int(text)) if text else 0
        except ValueError:
            value = None
        if value is None:
            raise Unreadable("unreadable directory entry",
                             f"D {de + which}: columns {col + 1}-{col + 8} ({name}) hold "
                             f"{quote(text)}, not an integer")
        d[name] = value
    status = first[64:72].replace(" ", "0")
    if parse_int(status) is None:
        raise Unreadable("unreadable directory entry",
                         f"D {de}: columns 65-72 (status) hold {quote(first[64:72])}, "
                         f"not four 2-digit numbers")
    d["status_number"] = int(status)
    d["entity_label"] = second[56:64].strip()
    if parse_int(second[:8].strip()) != d["entity_type_number"]:
        raise Unreadable("unreadable directory entry",
                         f"D {de + 1}: entity type {quote(second[:8].strip())}, but "
                         f"{d['entity_type_number']} on D {de}")
    return d


def _parameters(d: dict, de: int, plines, back, delim, end) -> list[str]:
    """The entity's parameter record as a list of fields (Hollerith strings kept whole)."""
    kind = "unreadable parameter data"
    ptr, n = d["parameter_pointer"], len(plines)
    if not 1 <= ptr <= n:
        where = "is missing: the parameter section ends" if ptr > n else "is out of range:"
        raise Unreadable(kind, f"its parameter data at P {ptr} {where} at P {n}"
                               + (" (the file is cut short?)" if ptr > n else ""))
    if back[ptr - 1] != de:
        raise Unreadable(kind, f"P {ptr}: the line belongs to DE "
                               f"{quote(plines[ptr - 1][1][64:72].strip())}, not to DE {de}")
    stop = ptr
    while stop < n and back[stop] == de:
        stop += 1
    record = "".join(t[:64] for _, t in plines[ptr - 1:stop])
    tokens, offsets, strings, body = _split(record, delim, end, ptr, stop)
    if parse_int(tokens[0].strip()) != d["entity_type_number"]:
        raise Unreadable(kind, f"P {ptr}: the parameter data is of type {quote(tokens[0])}, "
                               f"the directory entry says {d['entity_type_number']}")
    if body is not None and _numbers(delim).match(body) and not _BIG.search(body):
        return tokens  # every field a plain number (or empty), none that overflows
    for k, t in enumerate(tokens):
        s = t.strip()
        if s and not _number_ok(s) and k not in strings:
            at = (offsets[k] if offsets else sum(len(x) + 1 for x in tokens[:k]))
            at += len(t) - len(t.lstrip())  # padding that ends the line before
            raise Unreadable(kind, f"P {ptr + at // 64}: {not_a_number(s)}")
    return tokens


def _number_ok(s: str) -> bool:
    if not _IGES_NUMBER.match(s):
        return False
    return math.isfinite(float(s.replace("D", "E").replace("d", "e")))


def _split(record: str, delim: str, end: str, ptr: int, stop: int):
    """(fields, their offsets in the record or None (they follow from the fields), the
    indices of Hollerith strings among them, the record's text if it has none, else None)
    up to the record delimiter."""
    kind = "unreadable parameter data"
    if "H" not in record:
        cut = record.find(end)
        if cut < 0:
            raise Unreadable(kind, f"P {ptr}-{stop}: the parameter data does not end with "
                                   f"{quote(end)} (cut short?)")
        return record[:cut].split(delim), None, (), record[:cut]
    tokens, offsets, strings, i = [], [], set(), 0
    while True:
        m = _HOLLERITH.match(record, i)
        if m and m.end(1) - m.start(1) < 6:
            j = m.end() + int(m.group(1))
            if j > len(record):
                raise Unreadable(kind, f"P {ptr + i // 64}: a Hollerith string runs past the "
                                       f"end of the parameter data")
            token = record[i:j]
            strings.add(len(tokens))
            while j < len(record) and record[j] == " ":
                j += 1
        else:
            j = i
            while j < len(record) and record[j] not in (delim, end):
                j += 1
            token = record[i:j]
        tokens.append(token)
        offsets.append(i)
        if j >= len(record):
            raise Unreadable(kind, f"P {ptr}-{stop}: the parameter data does not end with "
                                   f"{quote(end)} (cut short?)")
        if record[j] == end:
            return tokens, offsets, strings, None
        if record[j] != delim:
            raise Unreadable(kind, f"P {ptr + j // 64}: {quote(record[j])} after a Hollerith "
                                   f"string, expected {quote(delim)} or {quote(end)}")
        i = j + 1


@functools.cache
def _numbers(delim: str) -> re.Pattern:
    """A record's text (to its ';') whose every field is a plain number or empty."""
    return re.compile(f"{_FIELD}(?:{re.escape(delim)}{_FIELD})*\\Z")


@functools.cache
def _CLASSES() -> dict:
    """pyiges' entity classes by type (those its reader builds), for decoding parameters."""
    from pyiges import geometry as g
    return {100: g.CircularArc, 104: g.ConicArc, 110: g.Line, 116: g.Point,
            124: g.Transformation, 126: g.RationalBSplineCurve, 128: g.RationalBSplineSurface,
            502: g.VertexList, 504: g.EdgeList, 508: g.Loop, 510: g.Face}
