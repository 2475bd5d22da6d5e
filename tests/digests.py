"""Digests of the contract channels over a catalogue of scenes and every option variant.

A redesign of the kernel must not move a single bit of what it reports: this module renders
the teapot (with its floor), the stress scenes, the rational samples, the trimmed plate, a
random rational patch and the IGES impeller, each at every criterion x split x precision, and
hashes each contract channel. `tests/test_digests.py` compares them with the stored digests
(tests/data/channel_digests.json); regenerate those only on purpose, when a change is meant to
move results:

    python tests/digests.py --write

NaNs are hashed as one canonical NaN (their payload carries no meaning).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import scenes as S  # noqa: E402
from tracer.camera import view_of  # noqa: E402
from tracer.geometry import prepare  # noqa: E402
from tracer.options import CRITERIA, PLAIN, PRECISIONS, SPLITS, Options  # noqa: E402
from tracer.render import render  # noqa: E402
from tracer.scene import load_scene, scene_from_dict  # noqa: E402

STORE = Path(__file__).resolve().parent / "data" / "channel_digests.json"
CHANNELS = ("hit", "t", "position", "box_min", "box_max", "normal", "uv", "patch", "effort")
STRESS_SIZE = (20, 20)
SAMPLE_SIZE = (28, 28)


def _random_rational():
    import test_rational_trim as rt
    rng = np.random.default_rng(1)
    return scene_from_dict({"objects": [{"patches": [rt.random_rational_patch(rng)]}],
                            "camera": {"eye": [0.3, -0.4, 4.0], "look_at": [0, 0, 0], "up": [0, 1, 0],
                                       "fov_deg": 40}}, "random rational", ".")


def _impeller():
    try:
        import pyiges
    except ImportError:
        return None
    path = Path(pyiges.__file__).resolve().parent / "examples" / "impeller.igs"
    return load_scene(path) if path.is_file() else None


def catalogue() -> dict:
    """name -> (build, size, view or None): view None means the scene's own camera."""
    cases = {f"stress/{c.name}": (c.scene_and_view, STRESS_SIZE) for c in S.stress_cases()}

    def own(build):
        def scene_and_view():
            scene = build()
            return (None, None) if scene is None else (scene, view_of(scene))
        return scene_and_view

    samples = {name: own(lambda name=name: load_scene(S.SAMPLES / f"{name}.json"))
               for name in ("teapot", "sphere", "torus", "plate")}
    samples["random rational"] = own(_random_rational)
    samples["impeller"] = own(_impeller)
    out = {name: (f, SAMPLE_SIZE) for name, f in samples.items()}
    out.update(cases)
    return out


def variants():
    """Every criterion x split x precision, as (key, Options), in the plain setting (single rays:
    test_coherence_exact holds every other setting to its bits)."""
    for precision in PRECISIONS:
        for criterion in CRITERIA:
            for split in SPLITS:
                yield f"{criterion}/{split}/{precision}", Options(criterion=criterion, split=split,
                                                                  precision=precision, **PLAIN)


def channel_digest(array: np.ndarray) -> str:
    a = np.ascontiguousarray(array)
    if a.dtype.kind == "f":
        a = np.where(np.isnan(a), np.nan, a)
    h = hashlib.sha256(str(a.dtype).encode() + str(a.shape).encode())
    h.update(a.tobytes())
    return h.hexdigest()[:16]


@lru_cache(maxsize=None)
def _scene(name):
    build, size = catalogue()[name]
    scene, view = build()
    return scene, view, size


@lru_cache(maxsize=4)
def _geometry(name, precision):
    return prepare(_scene(name)[0], precision)


def scene_digests(name: str) -> dict | None:
    """variant key -> channel -> digest for one catalogue scene (None if it is not available)."""
    if _scene(name)[0] is None:
        return None
    return {key: variant_digests(name, opts) for key, opts in variants()}


def variant_digests(name: str, opts: Options) -> dict:
    """channel -> digest for one catalogue scene (it must be available) rendered with opts."""
    scene, view, size = _scene(name)
    frame = render(scene, opts, size=size, view=view, geometry=_geometry(name, opts.precision))
    return {c: channel_digest(getattr(frame, c)) for c in CHANNELS}


def compute_all(progress=True) -> dict:
    out = {}
    for name in catalogue():
        d = scene_digests(name)
        if d is not None:
            out[name] = d
        if progress:
            print(f"{name}: {'done' if d is not None else 'not available'}", file=sys.stderr)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", action="store_true", help=f"store the digests in {STORE}")
    args = ap.parse_args(argv)
    digests = compute_all()
    if args.write:
        STORE.parent.mkdir(parents=True, exist_ok=True)
        STORE.write_text(json.dumps(digests, indent=1, sort_keys=True) + "\n")
        print(f"wrote {STORE}")
    else:
        stored = json.loads(STORE.read_text())
        moved = [(n, k, c) for n, d in digests.items() for k, ch in d.items() for c, v in ch.items()
                 if stored.get(n, {}).get(k, {}).get(c) != v]
        print(f"{len(moved)} channels moved" + "".join(f"\n  {n} {k} {c}" for n, k, c in moved[:40]))


if __name__ == "__main__":
    main()
