"""Reading input files: regular files only, a size limit, lines at "\\n", plain ASCII numbers.

Every loader (scene `.json`, `.bpt`, `.obj`, `.igs`) reads through `read_bytes` / `read_text`,
so a FIFO cannot hang a load, `/dev/zero` cannot eat memory, and every file is checked
against the one limit `MAX_INPUT_BYTES` before it is read.

Numbers in the files are the plain decimals a CAD or export tool writes
(`NUMBER`: optional sign, ASCII digits, optional point, optional exponent). Python's
float() also takes `1_0`, Arabic-Indic digits, `infinity` and surrounding Unicode
spaces; no file means those, so the loaders check the grammar first.
"""
from __future__ import annotations

import math
import os
import re
import stat

from tracer.errors import SceneError

MAX_INPUT_BYTES = 256 * 2 ** 20   # the largest input file any loader reads (256 MiB)
QUOTE_LIMIT = 80                  # characters of a bad token an error message quotes

NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
INTEGER = re.compile(r"[+-]?[0-9]+\Z")
_ASCII_SPACE = re.compile(r"[ \t\n\r\x0b\x0c]+")
_NON_FINITE = re.compile(r"[+-]?(?:nan|inf|infinity)\Z", re.IGNORECASE)
_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def quote(token: str, limit: int = QUOTE_LIMIT) -> str:
    """repr of a token for an error message, cut to `limit` characters (saying how long it was)."""
    token = str(token)
    if len(token) <= limit:
        return repr(token)
    return f"{token[:limit]!r}... ({len(token)} characters)"


def shown(token: str, limit: int = QUOTE_LIMIT) -> str:
    """The token as it is when short, else quote(token): for messages that show it bare."""
    token = str(token)
    return token if len(token) <= limit else quote(token, limit)


def not_a_number(token: str) -> str:
    """Why `token` is not a number of the file grammar (for 'X: ...' messages)."""
    if _NON_FINITE.match(token.strip()):
        return f"{quote(token)} is not finite (numbers must be finite plain decimals)"
    return f"{quote(token)} is not a number (expected a plain ASCII decimal such as -1.25e3)"


def parse_number(token: str) -> float | None:
    """The value of a plain ASCII decimal, or None if `token` is not one (or overflows)."""
    if not NUMBER.match(token):
        return None
    value = float(token)
    return value if math.isfinite(value) else None  # 1e999 overflows to inf


def parse_int(token: str, limit: int = 18) -> int | None:
    """The value of a plain ASCII integer of at most `limit` digits, or None."""
    if not INTEGER.match(token) or len(token.lstrip("+-")) > limit:
        return None
    return int(token)


def check_file(path, key: str | None = None) -> int:
    """The size of `path` if it is a regular file within MAX_INPUT_BYTES; else a SceneError."""
    label = str(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise SceneError(f"file not found: {label}" if key else "file not found",
                         path=None if key else label, key=key) from None
    except OSError as e:
        raise SceneError(f"cannot read file: {e.strerror}", path=label, key=key) from None
    _check_stat(st, label, key)
    return st.st_size


def _check_stat(st, label, key=None) -> None:
    where = {"path": None, "key": key} if key else {"path": label}
    prefix = f"{label}: " if key else ""
    if not stat.S_ISREG(st.st_mode):
        kind = next((name for test, name in _KINDS if test(st.st_mode)), "not a regular file")
        raise SceneError(f"{prefix}is {kind}, not a regular file", **where)
    if st.st_size > MAX_INPUT_BYTES:
        raise SceneError(f"{prefix}file is {st.st_size:,} bytes, more than the input limit of "
                         f"{MAX_INPUT_BYTES:,} (tracer.formats.source.MAX_INPUT_BYTES)", **where)


def read_bytes(path) -> bytes:
    """A regular file's bytes, at most MAX_INPUT_BYTES; anything else is a SceneError.

    Opened without blocking and checked on the open descriptor, so a path that becomes a
    FIFO between a check and the open cannot hang the read either.
    """
    label = str(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise SceneError("file not found", path=label) from None
    except OSError as e:
        raise SceneError(f"cannot read file: {e.strerror}", path=label) from None
    try:
        _check_stat(os.fstat(fd), label)
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, 1 << 24)
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > MAX_INPUT_BYTES:  # the file grew while we read it
                raise SceneError(f"file is more than the input limit of {MAX_INPUT_BYTES:,} bytes",
                                 path=label)
        return b"".join(chunks)
    except OSError as e:
        raise SceneError(f"cannot read file: {e.strerror}", path=label) from None
    finally:
        os.close(fd)


def read_text(path) -> str:
    """A source file's text (UTF-8, BOM tolerated); undecodable bytes are named by line."""
    data = read_bytes(path)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise SceneError(f"not UTF-8 text: byte 0x{data[e.start]:02x} cannot be decoded",
                         path=str(path), line=line) from None


def split_words(line: str) -> list[str]:
    """The words of a line between ASCII whitespace (str.split() also splits at no-break and
    other Unicode spaces, so '1\u00a02' would read as two numbers)."""
    return [w for w in _ASCII_SPACE.split(line) if w]


def split_lines(text: str) -> list[str]:
    """Lines at "\\n" only (a "\\r" before it dropped): form feed, vertical tab and the other
    characters str.splitlines() breaks at stay inside their line, so line numbers match
    what editors and `wc -l` count."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [l[:-1] if l.endswith("\r") else l for l in lines]
