"""tests/float_levels.py (where a ray's subdivisions lie against a pixel) runs, and its classes
count every subdivision of the block it traces."""
import os
import re
import subprocess
import sys

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "float_levels.py")


def test_float_levels_counts_every_subdivision():
    out = subprocess.run([sys.executable, SCRIPT, "--size", "64", "--block", "6"], capture_output=True,
                         text=True, check=True, timeout=300).stdout
    total = int(re.search(r"([\d,]+) subdivisions", out).group(1).replace(",", ""))
    parts = [int(m.replace(",", "")) for m in re.findall(r"pixels?\s+([\d,]+)", out)]
    assert len(parts) == 3 and total > 0 and sum(parts) == total, out
    assert "36 hits" in out, out  # the centre of the teapot: every ray hits
