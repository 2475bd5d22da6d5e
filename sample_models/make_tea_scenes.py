"""Write the tea set and the flying tea set: the scenes `psrt bench --coherence` compares structures on.

    .venv/bin/python sample_models/make_tea_scenes.py [--out DIR]

tea_set.json: Newell's teapot, teacup and teaspoon (copies of ../shared/models/, in this folder)
on a floor. flying.json: at least FLYING_PATCHES patches as copies of the three, scattered through a
box, each turned at random (uniform rotations), scaled 0.35-2.5 (log-uniform) and seeded, so the
file is the same on every run (tests/test_sample_scenes.py checks the committed one against it).
The objects refer to the three .bpt files with a transform each, so the scene stays small.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FLYING_PATCHES = 25_000
SEED = 2024
HALF = (60.0, 60.0, 30.0)  # the box the flying copies' origins lie in, half sides
# Each model's turn onto z up and its size beside the teapot (the teacup and teaspoon files have y up).
MODELS = {  # name: (file, patches, 3x3 turn to z up, scale, lift onto z = 0)
    "teapot": ("teapot.bpt", 32, ((1, 0, 0), (0, 1, 0), (0, 0, 1)), 1.0, 0.0),
    "teacup": ("teacup.bpt", 26, ((1, 0, 0), (0, 0, -1), (0, 1, 0)), 1.6, 0.0),
    "teaspoon": ("teaspoon.bpt", 16, ((0, 1, 0), (-1, 0, 0), (0, 0, 1)), 2.0, 0.107143),
}
MATERIALS = {"porcelain": {"color": [0.9, 0.9, 0.85], "reflect": 0.1},
             "blue": {"color": [0.35, 0.5, 0.85], "specular": 0.4, "shininess": 60},
             "silver": {"color": [0.75, 0.75, 0.78], "reflect": 0.3},
             "floor": {"color": [0.5, 0.5, 0.5]}}
MATERIAL_OF = {"teapot": "porcelain", "teacup": "blue", "teaspoon": "silver"}
LIGHTS = [{"type": "point", "position": [5, -5, 10], "intensity": 1.0}]


def transform(turn, scale, shift) -> list:
    """The row-major 4x4 list of the contract, numbers rounded to 5 decimals (a stable file)."""
    m = np.asarray(turn, np.float64) * scale
    rows = [[*m[i], shift[i]] for i in range(3)] + [[0, 0, 0, 1]]
    return [round(float(v), 5) + 0.0 for row in rows for v in row]  # + 0.0: no "-0.0" in the file


def placed(name, turn, scale, shift) -> dict:
    """An object: model `name` turned to z up, then by `turn`, scaled and moved to `shift`."""
    file, _, up, size, lift = MODELS[name]
    base = np.asarray(up, np.float64)
    lifted = np.asarray(turn, np.float64) @ np.array([0.0, 0.0, lift * size])
    return {"file": file, "material": MATERIAL_OF[name],
            "transform": transform(np.asarray(turn) @ base * size, scale, np.asarray(shift) + scale * lifted)}


def turn_about_z(angle) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def tea_set() -> dict:
    floor = {"name": "floor", "material": "floor",
             "patches": [{"degree": [1, 1], "points": [[-8, -8, 0], [10, -8, 0], [-8, 8, 0], [10, 8, 0]]}]}
    return {"camera": {"eye": [9.5, -13, 7], "look_at": [1.8, -0.8, 0.9], "up": [0, 0, 1], "fov_deg": 35},
            "image": {"width": 512, "height": 512},
            "objects": [placed("teapot", turn_about_z(0.0), 1.0, (0.0, 0.0, 0.0)),
                        placed("teacup", turn_about_z(0.5), 1.0, (5.2, -1.2, 0.0)),
                        placed("teaspoon", turn_about_z(-0.4), 1.0, (4.6, -3.6, 0.0)), floor],
            "materials": MATERIALS, "lights": LIGHTS}


def random_turn(rng) -> np.ndarray:
    """A uniformly distributed rotation (a unit quaternion from four normal numbers)."""
    w, x, y, z = (q := rng.normal(size=4)) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def flying(patches: int = FLYING_PATCHES, seed: int = SEED) -> dict:
    rng = np.random.default_rng(seed)
    names = list(MODELS)
    objects, count = [], 0
    while count < patches:
        name = names[int(rng.integers(len(names)))]
        turn = random_turn(rng)
        scale = math.exp(rng.uniform(math.log(0.35), math.log(2.5)))
        shift = rng.uniform(-1.0, 1.0, 3) * HALF
        objects.append(placed(name, turn, scale, shift))
        count += MODELS[name][1]
    return {"camera": {"eye": [80, -105, 60], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 40},
            "image": {"width": 512, "height": 512},
            "objects": objects, "materials": {k: v for k, v in MATERIALS.items() if k != "floor"},
            "lights": [{"type": "point", "position": [120, -160, 200], "intensity": 1.0}]}


def scene_text(scene: dict) -> str:
    """The JSON of a scene, an object per line (readable, and diffs stay small)."""
    head = [f" {json.dumps(k)}: {json.dumps(v)}" for k, v in scene.items() if k != "objects"]
    body = ",\n".join("  " + json.dumps(o, separators=(",", ":")) for o in scene["objects"])
    return "{\n" + ",\n".join(head) + ',\n "objects": [\n' + body + "\n ]\n}\n"


SCENES = {"tea_set.json": tea_set, "flying.json": flying}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE, help="folder to write to (default: this one)")
    args = parser.parse_args(argv)
    for name, make in SCENES.items():
        text = scene_text(make())
        (args.out / name).write_text(text)
        print(f"wrote {args.out / name} ({len(text):,} bytes)")


if __name__ == "__main__":
    main()
