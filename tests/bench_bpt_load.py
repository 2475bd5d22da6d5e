"""How long a large .bpt takes to load: 100,000 bilinear patches (a 4.3 MB file).

    .venv/bin/python tests/bench_bpt_load.py [PATCHES]

Prints the file size and the best of three runs of load_bpt (PatchData objects) and of
load_scene (the arrays the renderer takes). The BVH build is not part of it.
"""
import os
import sys
import tempfile
import time

from tracer.formats.bpt import load_bpt
from tracer.scene import load_scene


def write(path, n):
    """n unit quads on a grid, one point a line (the usual layout), one corner lifted."""
    side = int(n ** 0.5 + 0.999)
    lines = [str(n)]
    for k in range(n):
        i, j = k % side, k // side
        lines += ["1 1", f"{i} {j} 0", f"{i + 1} {j} 0", f"{i} {j + 1} 0", f"{i + 1} {j + 1} 0.5"]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def best(f, path, runs=3):
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        f(path)
        times.append(time.perf_counter() - t)
    return min(times)


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "big.bpt")
        write(path, n)
        print(f"{n} bilinear patches, {os.path.getsize(path) / 1e6:.1f} MB")
        for f in (load_bpt, load_scene):
            print(f"{f.__name__}: {best(f, path):.2f} s (best of 3)")
