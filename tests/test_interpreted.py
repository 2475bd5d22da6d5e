"""The kernels run as plain Python too: the tests marked `interpreted` again, with NUMBA_DISABLE_JIT=1.

Interpreted, the kernels' lines are visible to debuggers and coverage tools, and the run
proves the numba-only parts (the SIMD split's intrinsic) have plain-Python fallbacks. It is
about a thousand times slower than compiled code, so the marked tests are small ones (about a
minute in all on a 2-core machine).
"""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from numba import config as numba_config

REPO = Path(__file__).resolve().parents[1]
TIMEOUT = 600  # seconds; a run that long means the marked tests grew too big to stay interpreted
MIN_PASSED = 58  # the marked tests, less any skipped on this machine: fewer means they ran compiled or not at all


@pytest.mark.skipif(numba_config.DISABLE_JIT, reason="already interpreted")
def test_marked_kernel_tests_pass_interpreted():
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, "-m", "pytest", "-m", "interpreted", "-o", "addopts=", "-q",
                           "-p", "no:cacheprovider", "-W", "error::pytest.PytestUnknownMarkWarning", str(REPO / "tests")],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=TIMEOUT)
    summary = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else proc.stderr[-2000:]
    assert proc.returncode == 0, f"interpreted run failed: {summary}\n{proc.stdout[-6000:]}{proc.stderr[-2000:]}"
    passed = int(re.search(r"(\d+) passed", summary).group(1))
    assert passed >= MIN_PASSED, f"only {passed} interpreted tests passed: {summary}"
