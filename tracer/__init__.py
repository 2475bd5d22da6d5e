"""psrt tracer: floating-point precision ray tracing of parametric surfaces."""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path


CACHE_LAYOUT = "psrt-deps"  # jit.py keys every cached kernel by the modules it depends on


def _configure_numba_cache() -> None:
    """Put numba's on-disk cache under NUMBA_CACHE_DIR (or ~/.cache/psrt/numba)/psrt-deps.

    Cached kernels are keyed by their own sources and those of the modules they depend on
    (tracer.jit), so an edit recompiles only what depends on it. Directories of the old
    layout (one per hash of all kernel sources) unused for a day are removed.
    """
    import time

    import numba

    base = Path(os.environ.get("NUMBA_CACHE_DIR") or Path.home() / ".cache" / "psrt" / "numba")
    numba.config.CACHE_DIR = str(base / CACHE_LAYOUT)
    try:
        for old in base.iterdir():
            stale = time.time() - old.stat().st_mtime > 86400
            if stale and re.fullmatch(r"psrt-[0-9a-f]{12}", old.name):
                shutil.rmtree(old, ignore_errors=True)
    except OSError:
        return  # a read-only or missing base: numba reports its own errors


_configure_numba_cache()
