"""Image comparison for the image tests (STYLE rule 7): a per-pixel tolerance in 8-bit levels
that the caller states, and actual, expected and difference PNGs written where the failure
message says."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image


def read_png(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


def compare_images(actual: np.ndarray, expected: np.ndarray, out_dir: Path, name: str, tol: int):
    """Assert |actual - expected| <= tol (8-bit levels) everywhere; on failure write
    NAME-actual.png, NAME-expected.png and NAME-diff.png (the difference amplified 16x) into
    out_dir and name them in the message."""
    out_dir = Path(out_dir)
    paths = [out_dir / f"{name}-{tag}.png" for tag in ("actual", "expected", "diff")]
    if actual.shape != expected.shape:
        _write(out_dir, paths[:2], actual, expected)
        raise AssertionError(f"{name}: size {actual.shape} != expected {expected.shape}; "
                             f"written: {', '.join(map(str, paths[:2]))}")
    diff = np.abs(actual.astype(int) - expected.astype(int))
    if diff.max() > tol:
        _write(out_dir, paths, actual, expected, np.clip(diff * 16, 0, 255).astype(np.uint8))
        bad = int(np.sum(diff.max(axis=-1) > tol))
        raise AssertionError(f"{name}: {bad} pixels differ by more than {tol} levels (max {diff.max()}); "
                             f"written: {', '.join(map(str, paths))}")


def _write(out_dir: Path, paths, *images):
    out_dir.mkdir(parents=True, exist_ok=True)
    for path, img in zip(paths, images):
        Image.fromarray(img).save(path)
