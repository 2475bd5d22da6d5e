"""psrt tracer: floating-point precision ray tracing of parametric surfaces."""
from __future__ import annotations

import hashlib
import os
import re
import shutil
from pathlib import Path


def _configure_numba_cache() -> None:
    """Key numba's on-disk cache by the kernel sources.

    numba checks only the decorated function's own file when it reuses cached
    machine code, so a kernel that inlines helpers from another module would
    keep running stale code after an edit. A directory per source hash avoids
    that; hash directories unused for a day are removed.
    """
    import time

    import numba

    base = Path(os.environ.get("NUMBA_CACHE_DIR") or Path.home() / ".cache" / "psrt" / "numba")
    digest = hashlib.sha1()
    for path in sorted(Path(__file__).parent.rglob("*.py")):
        source = path.read_bytes()
        if b"from numba" in source:  # only kernel modules decide what machine code is valid
            digest.update(path.name.encode())
            digest.update(source)
    key = "psrt-" + digest.hexdigest()[:12]
    numba.config.CACHE_DIR = str(base / key)
    try:
        for old in base.iterdir():
            stale = time.time() - old.stat().st_mtime > 86400
            if old.name != key and stale and re.fullmatch(r"psrt-[0-9a-f]{12}", old.name):
                shutil.rmtree(old, ignore_errors=True)
    except OSError:
        return  # a read-only or missing base: numba reports its own errors


_configure_numba_cache()
