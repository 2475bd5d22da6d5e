"""`psrt stress SCENE` (tracer/cli_stress.py, tracer/stress.py): the table, the JSON, the exit
codes (0 clean, 1 holes or false hits, 2 bad input) and refused variants. Images are 16x16."""
import json
from pathlib import Path

import numpy as np
import pytest

from psrt.cli import main
from tracer import stress
from tracer.scene import load_scene

TEAPOT = str(Path(__file__).resolve().parents[1] / "sample_models" / "teapot.json")
SUBSET = ["as-is", "scale-1e3", "grazing-90", "ulps-1"]


def stress_cli(*argv):
    return main(["stress", *map(str, argv)])


def table_rows(out: str) -> dict:
    """The table's rows by variant name (the header left out)."""
    lines = out.strip().splitlines()
    assert lines[0] == stress.HEADER
    return {line.split()[0]: line for line in lines[1:]}


def test_teapot_subset_table_and_json(tmp_path, capsys):
    out = tmp_path / "stress.json"
    assert stress_cli(TEAPOT, "--size", "16x16", "--variants", *SUBSET, "--json", out, "-q") == 0
    captured = capsys.readouterr()
    rows = table_rows(captured.out)
    assert list(rows) == SUBSET
    data = json.loads(out.read_text())
    assert [v["name"] for v in data["variants"]] == SUBSET and data["failed"] == []
    for v in data["variants"]:
        assert v["refused"] is None and v["hits"] > 0 and v["holes"] == 0 and v["false_hits"] == 0
        assert 0.0 <= v["inside"] <= 1.0 and v["ratio"] is not None
        assert rows[v["name"]].split()[1:4] == [str(v["hits"]), "0", "0"]
    assert data["size"] == [16, 16] and data["options"]["criterion"] == "float"
    grazing = data["variants"][SUBSET.index("grazing-90")]
    assert 0 < grazing["hits"] < 16 * 16  # the silhouette crosses the image


@pytest.mark.parametrize("azimuth", stress.AZIMUTHS)
def test_grazing_views_touch_the_teapot_not_the_floor_edge(azimuth):
    """The target is a point of a curved patch where the view is tangent to the surface: on the
    teapot, not on the edge of the sample scene's floor (a plane seen edge-on)."""
    scene = load_scene(TEAPOT)
    view = stress.grazing_view(scene, azimuth)
    points, normals, curved = stress.surface_samples(scene)
    i = int(np.argmin(np.abs(points - view.look_at).sum(axis=1)))
    along = np.subtract(view.look_at, view.eye) / np.linalg.norm(np.subtract(view.look_at, view.eye))
    assert curved[i] and abs(float(normals[i] @ along)) < stress.TANGENT_COS
    assert np.abs(view.look_at[:2]).max() < 4.0 and view.look_at[2] > 0.1  # the floor spans +-8 at z = 0


def test_a_kind_selects_its_variants(capsys):
    assert [v.name for v in stress.select(["scale", "as-is"])] == ["as-is", "scale-1e-6", "scale-1e-3",
                                                                  "scale-1e3", "scale-1e6"]


def test_a_forced_hole_exits_1(tmp_path, capsys, monkeypatch):
    """One pixel the reference hits is made a miss in the float32 frame: the real scoring must see
    a hole and the command exit 1, with the row and the JSON saying so."""
    real = stress.trace_variant

    def holed(*args, **kwargs):
        frame, ref = real(*args, **kwargs)
        y, x = np.argwhere(ref.hit & frame.hit)[0]
        frame.hit[y, x] = False
        return frame, ref
    monkeypatch.setattr(stress, "trace_variant", holed)
    out = tmp_path / "stress.json"
    # in this process: the patch does not reach a LocalCluster's workers
    assert stress_cli(TEAPOT, "--size", "16x16", "--variants", "as-is", "--json", out, "-q", "--scheduler", "none") == 1
    captured = capsys.readouterr()
    row = table_rows(captured.out)["as-is"]
    assert row.split()[2] == "1" and "HOLES/FALSE HITS" in row
    assert "holes or false hits in as-is" in captured.err
    data = json.loads(out.read_text())
    assert data["failed"] == ["as-is"] and data["variants"][0]["holes"] == 1


def test_a_refused_variant_is_a_row_not_a_failure(tmp_path, capsys):
    """A quad 1e-27 across scaled by 1e-6 is below what float32 resolves (limits.py)."""
    scene = tmp_path / "tiny.json"
    pts = [[0, 0, 0], [1e-27, 0, 0], [0, 1e-27, 0], [1e-27, 1e-27, 1e-28]]
    scene.write_text(json.dumps({"objects": [{"patches": [{"degree": [1, 1], "points": pts}]}]}))
    assert stress_cli(scene, "--size", "8x8", "--variants", "scale-1e-6", "-q") == 0
    row = table_rows(capsys.readouterr().out)["scale-1e-6"]
    assert "refused:" in row and "--precision f64" in row


def test_perturbation_is_seeded_and_within_k_ulps():
    scene = load_scene(TEAPOT)
    a, b = stress.perturbed(scene, 3, seed=3), stress.perturbed(scene, 3, seed=3)
    assert np.array_equal(a.points, b.points)
    xyz = scene.points[:, :3]
    steps = (a.points[:, :3] - xyz) / np.spacing(np.abs(xyz).astype(np.float32)).astype(np.float64)
    assert np.abs(steps).max() == 3 and np.array_equal(steps, np.round(steps))
    assert np.array_equal(a.points[:, 3], scene.points[:, 3])


@pytest.mark.parametrize("argv, needle", [
    (["missing.json"], "missing.json"),
    ([TEAPOT, "--variants", "bogus"], "unknown variant 'bogus'"),
    ([TEAPOT, "--size", "0x4"], "--size"),
])
def test_bad_input_exits_2(argv, needle, capsys):
    assert stress_cli(*argv) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1


def test_json_on_stdout_moves_the_table_to_stderr(capsys):
    assert stress_cli(TEAPOT, "--size", "8x8", "--variants", "as-is", "--json", "-", "-q") == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["variants"][0]["name"] == "as-is"
    assert list(table_rows(captured.err)) == ["as-is"]


def test_json_onto_the_scene_is_refused_before_any_work(tmp_path, capsys):
    scene = tmp_path / "teapot.json"
    scene.write_text(Path(TEAPOT).read_text().replace('"teapot.bpt"', json.dumps(str(Path(TEAPOT).parent / "teapot.bpt"))))
    before = scene.read_text()
    assert stress_cli(scene, "--json", scene, "-q") == 2
    assert scene.read_text() == before and "error" in capsys.readouterr().err
