"""Files the viewer writes: screenshots (PNG), the render's AOVs (npz), the inspected trace (JSON).

Each is written as the CLI writes its outputs (tracer.output_files.write_atomic): to a temporary
file beside the target, renamed onto it once complete, so a failed export leaves the old file
as it was; a directory, FIFO or device at the path is refused.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from tracer.output_files import write_atomic
from tracer.stats import json_safe

from .picking import inspection_json


def _target(path) -> Path:
    """path as a Path, its folder created."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def write_png(rgb: np.ndarray, path) -> Path:
    """(H, W, 3) uint8, row 0 at the top."""
    path = _target(path)
    image = Image.fromarray(rgb, "RGB")
    write_atomic(path, lambda f: image.save(f, format="PNG"))
    return path


def write_aovs(frame, path) -> Path:
    """The contract's per-pixel arrays of a finished frame (tracer.render.Frame.save_npz)."""
    if frame is None:
        raise ValueError("no finished render to export yet")
    path = _target(path)
    write_atomic(path, frame.save_npz)
    return path


def write_trace(inspection, path) -> Path:
    """The contract's trace JSON of the inspected pixel."""
    if inspection is None:
        raise ValueError("no pixel inspected yet: click the image first")
    path = _target(path)
    text = json.dumps(json_safe(inspection_json(inspection)), indent=1)
    write_atomic(path, lambda f: f.write(text.encode("utf-8")))
    return path
