"""Tiny stored golden images of the teapot exactly as `psrt render` writes them: shaded, in
normal mode, and the effort map with its legend (--effort-map), at 32x32.

`tests/test_golden.py` compares fresh renders with the PNGs in tests/data/golden/. Regenerate
them only on purpose, when a change is meant to alter what the images show (the legend's text
is drawn by Pillow's bundled font, so a Pillow upgrade that moves glyphs is such a change):

    python tests/golden.py --write
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS.parent))

from psrt.cli import main as psrt  # noqa: E402

STORE = TESTS / "data" / "golden"
TEAPOT = TESTS.parent / "sample_models" / "teapot.json"
SIZE = "32x32"
NAMES = ("teapot-shaded", "teapot-normal", "teapot-effort")


def render_all(directory) -> dict:
    """Run the CLI twice (the shaded image and its effort map come from one render) into
    `directory`; returns name -> PNG path for every name in NAMES."""
    d = Path(directory)
    paths = {name: d / f"{name}.png" for name in NAMES}
    runs = [["-o", paths["teapot-shaded"], "--effort-map", paths["teapot-effort"]],
            ["-o", paths["teapot-normal"], "--mode", "normal"]]
    for flags in runs:
        status = psrt(["render", str(TEAPOT), "--size", SIZE, "-q", *map(str, flags)])
        if status != 0:
            raise RuntimeError(f"psrt render {' '.join(map(str, flags))} exited with {status}")
    return paths


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", action="store_true", help=f"store the images in {STORE}")
    args = ap.parse_args(argv)
    if not args.write:
        ap.error("nothing to do: --write regenerates the stored images (the test compares them)")
    STORE.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name, path in render_all(tmp).items():
            (STORE / path.name).write_bytes(path.read_bytes())
            print(f"wrote {STORE / path.name}")


if __name__ == "__main__":
    main()
