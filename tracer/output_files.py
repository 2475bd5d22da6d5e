"""Output files that survive failures: written beside their targets under temporary names and
renamed into place only once the whole run has succeeded.

`OutputFiles` is one run's outputs. `add` checks a path before any work: its directory exists
and can be written, nothing but a regular file is there (a directory, FIFO or device is
refused), it is not another output of the run (real paths, hard links), and `refuse_inputs`
checks it is none of the run's inputs. `write` writes an output to a temporary file in the
target's directory (flushed to disk); `commit` renames them all into place at the end, and on
any failure (an exception, Ctrl-C) the temporaries are removed and no existing file is
touched. "-" stands for standard output where a command allows it, written at commit too.
`write_atomic` does the same for one file (the viewer's exports).
"""
from __future__ import annotations

import io
import os
import stat
import sys
import tempfile

STDOUT = "-"

_UMASK = os.umask(0)  # read once: the mode a plainly created file would get
os.umask(_UMASK)


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a device"),
                       (stat.S_ISBLK, "a device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def check_target(path) -> str:
    """The real path an output to `path` replaces; ValueError if it cannot be a regular file
    written there (no such directory, not writable, or a directory, FIFO or device)."""
    text = os.fspath(path)
    if not text:
        raise ValueError("empty output path")
    real = os.path.realpath(text)
    try:
        st = os.stat(real)
    except FileNotFoundError:
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise ValueError(f"{text}: is {_kind(st.st_mode)}, not a regular file")
    parent = os.path.dirname(real)
    if not os.path.isdir(parent):
        raise ValueError(f"{text}: output directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{text}: cannot write in directory {parent}")
    return real


def same_file(a: str, b: str) -> bool:
    """Whether two real paths are one file: equal, or hard links of one inode."""
    if a == b:
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet)
        return False


def _temporary(real: str, write) -> str:
    """Call write(binary file) on a new temporary file beside `real`, flushed to disk; its path."""
    folder, name = os.path.split(real)
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".part", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        try:  # a replaced file keeps its mode; a new one gets the umask's
            mode = stat.S_IMODE(os.stat(real).st_mode)
        except FileNotFoundError:
            mode = 0o666 & ~_UMASK
        os.chmod(tmp, mode)
    except BaseException:
        _remove(tmp)
        raise
    return tmp


def _remove(path: str) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


def write_atomic(path, write) -> str:
    """Write one file: write(binary file) to a temporary beside `path`, renamed onto it once
    complete (a failed write leaves the old file as it was); returns the real path."""
    real = check_target(path)
    os.replace(_temporary(real, write), real)
    return real


class OutputFiles:
    """The outputs of one run, checked up front and committed together (see the module doc).

    Use as a context manager: leaving the block normally commits, an exception discards.
    """

    def __init__(self):
        self._planned = []   # (real path or STDOUT, flag)
        self._pending = []   # (temporary, real path)
        self._stdout = []    # bytes for standard output

    def add(self, flag: str, path, stdout: bool = False):
        """Plan the output of `flag` at `path` ("-": standard output, if `stdout`); None: none.
        Refuses, with a message naming the flag, a path that cannot be written (check_target)
        or that another output of the run already names."""
        if path is None:
            return
        if os.fspath(path) == STDOUT:
            if not stdout:
                raise ValueError(f"{flag}: cannot write this output to standard output ('-'); give a file")
            real = STDOUT
        else:
            try:
                real = check_target(path)
            except ValueError as e:
                raise ValueError(f"{flag} {e}") from None
        for other, other_flag in self._planned:
            if real == other or (real != STDOUT and other != STDOUT and same_file(real, other)):
                raise ValueError(f"{flag} {path}: the same file as {other_flag}; give each output its own path")
        self._planned.append((real, flag))

    def refuse_inputs(self, inputs, what="an input") -> None:
        """Refuse any planned output that is one of the input files (real paths, hard links);
        `what` says which input, e.g. "the scene file"."""
        for source in inputs:
            if source is None:
                continue
            real = os.path.realpath(os.fspath(source))
            for output, flag in self._planned:
                if output != STDOUT and same_file(output, real):
                    raise ValueError(f"{flag} {source}: is {what}; an output may not overwrite an input")

    def write(self, path, write) -> None:
        """Write the output planned at `path` (write(binary file)); it replaces the target at commit."""
        if os.fspath(path) == STDOUT:
            buffer = io.BytesIO()
            write(buffer)
            self._stdout.append(buffer.getvalue().decode("utf-8"))
            return
        real = os.path.realpath(os.fspath(path))
        if not any(real == p for p, _ in self._planned):
            raise ValueError(f"{path}: not a planned output of this run")
        self._pending.append((_temporary(real, write), real))

    def write_text(self, path, text: str) -> None:
        self.write(path, lambda f: f.write(text.encode("utf-8")))

    def commit(self) -> None:
        """Rename every written output into place, then write standard output."""
        try:
            while self._pending:
                tmp, real = self._pending[0]
                os.replace(tmp, real)
                self._pending.pop(0)
        except BaseException:
            self.discard()
            raise
        for text in self._stdout:
            sys.stdout.write(text)
        sys.stdout.flush()
        self._stdout = []

    def discard(self) -> None:
        """Remove every temporary written so far; no target is touched."""
        for tmp, _ in self._pending:
            _remove(tmp)
        self._pending, self._stdout = [], []

    def __enter__(self):
        return self

    def __exit__(self, kind, error, tb):
        if kind is None:
            self.commit()
        else:
            self.discard()
        return False
