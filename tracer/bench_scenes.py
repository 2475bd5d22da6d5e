"""The scenes `psrt bench --coherence` runs on, by name: the teapot, the tea set, the IGES impeller
and the flying tea set of 25,000 patches (sample_models/make_tea_scenes.py), so that the
structures are compared on a small, a middling, a trimmed and a large scene. Any other name is
taken as the path of a scene file."""
from __future__ import annotations

from pathlib import Path

SAMPLES = Path(__file__).resolve().parents[1] / "sample_models"
NAMES = ("teapot", "tea_set", "impeller", "flying")


def impeller_path() -> Path:
    """The IGES impeller among pyiges' examples (as tests/digests.py uses it)."""
    try:
        import pyiges
    except ImportError:
        raise ValueError("scene 'impeller': the pyiges package is not installed") from None
    path = Path(pyiges.__file__).resolve().parent / "examples" / "impeller.igs"
    if not path.is_file():
        raise ValueError(f"scene 'impeller': {path} is missing from the pyiges package")
    return path


def scene_path(name: str) -> Path:
    """The file of a named scene (NAMES), or `name` itself as a path."""
    if name == "impeller":
        return impeller_path()
    if name in NAMES:
        return SAMPLES / f"{name}.json"
    return Path(name)


def scene_label(name: str) -> str:
    """A short name for tables: the name, or a path's file name without its suffix."""
    return name if name in NAMES else Path(name).stem
