"""The tea set and the flying tea set (sample_models/make_tea_scenes.py): the committed files are
the generator's, flying.json holds 25,000 patches of the three models that the camera mostly sees,
and both render."""
import importlib.util
import math

import numpy as np
import pytest

import scenes as S
from tracer.options import Options
from tracer.render import render
from tracer.scene import load_scene

MODELS = {"teapot.bpt", "teacup.bpt", "teaspoon.bpt"}


def _generator():
    spec = importlib.util.spec_from_file_location("make_tea_scenes", S.SAMPLES / "make_tea_scenes.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_committed_scenes_are_the_generators(tmp_path, capsys):
    _generator().main(["--out", str(tmp_path)])
    for name in ("tea_set.json", "flying.json"):
        assert (tmp_path / name).read_bytes() == (S.SAMPLES / name).read_bytes(), name


def test_the_shared_models_are_copied_unchanged():
    shared = S.REPO.parent / "shared" / "models"
    if not shared.is_dir():
        pytest.skip("../shared/models is not beside the repository")
    for name in MODELS:
        assert (S.SAMPLES / name).read_bytes() == (shared / name).read_bytes(), name


@pytest.fixture(scope="module")
def flying():
    return load_scene(S.SAMPLES / "flying.json")


def test_flying_has_25000_patches_of_the_three_models(flying):
    assert flying.n_patches >= 25_000
    assert {o.source for o in flying.objects} == MODELS
    counts = {name: sum(o.source == name for o in flying.objects) for name in MODELS}
    assert min(counts.values()) > 250  # a mix, not one model


def test_the_camera_sees_most_of_the_flying_copies(flying):
    eye, look = np.asarray(flying.camera.eye), np.asarray(flying.camera.look_at)
    axis = (look - eye) / np.linalg.norm(look - eye)
    start = flying.point_start
    centres = np.array([flying.points[start[o.first_patch]:start[o.first_patch + o.patch_count], :3].mean(axis=0)
                        for o in flying.objects])
    to = centres - eye
    angle = np.degrees(np.arccos(np.clip(to @ axis / np.linalg.norm(to, axis=1), -1, 1)))
    assert np.mean(angle < flying.camera.fov_deg / 2) > 0.7
    frame = render(flying, Options(), size=(32, 32))
    assert frame.hit.mean() > 0.3 and len(np.unique(frame.patch[frame.hit])) > 150


def test_the_tea_set_renders_with_all_its_pieces():
    scene = load_scene(S.SAMPLES / "tea_set.json")
    assert [o.source for o in scene.objects] == ["teapot.bpt", "teacup.bpt", "teaspoon.bpt", "inline"]
    frame = render(scene, Options(), size=(96, 96))
    seen = set(scene.patch_object[frame.patch[frame.hit]].tolist())
    assert seen == {0, 1, 2, 3}, seen  # teapot, teacup, teaspoon and floor each cover pixels
    start = scene.point_start
    for o in scene.objects:  # every piece stands on the floor (z = 0)
        z = scene.points[start[o.first_patch]:start[o.first_patch + o.patch_count], 2]
        assert math.isclose(z.min(), 0.0, abs_tol=1e-4), o.source
