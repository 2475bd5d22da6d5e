"""Seeded fuzz of every loader (.bpt, .json, .obj, .igs) and of paths that are no regular files.

Every damaged input must end in a loaded scene or a SceneError whose message is one line,
names the file and (unless it is about the file as a whole) the line or key, and quotes at
most 80 characters of any token; never another exception. An IGES file that loads with
fewer surfaces must say so in its import report. The CLI cases: exit status 2, one line on
stderr, no traceback, no output file created or changed. Everything is tiny and fast.
"""
import json
import os
import random
import re
import signal
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import pytest

from iges_writer import tiny_iges
from mutate import KINDS, damage
from psrt.cli import main
from tracer.errors import SceneError
from tracer.formats import source
from tracer.formats.losses import has_losses
from tracer.scene import load_scene

REPO = Path(__file__).resolve().parents[1]
BPT = "2\n1 1\n0 0 0\n1 0 0\n0 1 0\n1 1 0.5\n2 1\n" + "0 1 2 1\n" * 5 + "1 1 1 2\n"
SCENE = {"camera": {"eye": [3, -4, 2], "look_at": [0.5, 0.5, 0], "up": [0, 0, 1], "fov_deg": 40},
         "image": {"width": 8, "height": 8},
         "objects": [{"file": "small.bpt", "transform": [2, 0, 0, 1, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1]},
                     {"patches": [{"degree": [1, 1], "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.25]]}],
                      "material": "m"}],
         "materials": {"m": {"color": [0.5, 0.5, 0.5]}},
         "lights": [{"type": "point", "position": [5, -5, 10]}]}
OBJ = (REPO / "sample_models" / "plate.obj").read_text()
IGES = tiny_iges()
# messages about a file as a whole, which have no line or key to name
WHOLE_FILE = re.compile(r"file not found|not a regular file|input limit|no directory entries|"
                        r"no free-form surfaces|binary IGES|unsupported (scene )?file type|"
                        r"expected an object, got|missing required key 'objects'")
TRIALS = 60  # per kind of damage and loader


@contextmanager
def deadline(seconds=20):
    """A loader that blocks (a FIFO) fails the test instead of hanging it."""
    def stop(*_):
        raise TimeoutError(f"still loading after {seconds} s")
    old = signal.signal(signal.SIGALRM, stop)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def check_error(err: SceneError, files) -> str:
    """The error's message is one line, names one of `files`, its line or key, quotes briefly."""
    msg = str(err)
    assert "\n" not in msg and "\r" not in msg, msg[:300]
    assert err.path in {str(f) for f in files}, msg[:300]
    assert msg.startswith(err.path)
    assert err.line is not None or err.key is not None or WHOLE_FILE.search(err.message), msg
    assert len(err.message) < 400, msg[:500]  # a bad token is quoted to 80 characters
    return msg


def load(path, files):
    """load_scene: the scene, or None after checking its SceneError."""
    try:
        with deadline():
            return load_scene(path)
    except SceneError as err:
        check_error(err, files)
        return None


@pytest.fixture
def scene_dir(tmp_path):
    (tmp_path / "small.bpt").write_text(BPT)
    (tmp_path / "scene.json").write_text(json.dumps(SCENE, indent=1))
    return tmp_path


def test_the_bases_load(scene_dir):
    assert load_scene(scene_dir / "scene.json").n_patches == 3
    (scene_dir / "plate.obj").write_text(OBJ)
    (scene_dir / "tiny.igs").write_text(IGES)
    assert len(load_scene(scene_dir / "plate.obj").surfaces) == 1
    assert len(load_scene(scene_dir / "tiny.igs").surfaces) == 2


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("ext", [".bpt", ".json", ".obj"])
def test_damaged_text_files(scene_dir, ext, kind):
    base = {".bpt": BPT, ".json": json.dumps(SCENE, indent=1), ".obj": OBJ}[ext]
    rng = random.Random(f"{ext}{kind}")
    path = scene_dir / f"damaged{ext}"
    files = (path, scene_dir / "small.bpt")
    for _ in range(TRIALS):
        path.write_bytes(damage(base, rng, kind))
        load(path, files)


@pytest.mark.parametrize("kind", KINDS)
def test_damaged_bpt_inside_a_scene(scene_dir, kind):
    rng = random.Random(f"inside{kind}")
    for _ in range(TRIALS // 2):
        (scene_dir / "small.bpt").write_bytes(damage(BPT, rng, kind))
        load(scene_dir / "scene.json", (scene_dir / "scene.json", scene_dir / "small.bpt"))


@pytest.mark.parametrize("kind", KINDS)
def test_damaged_iges_loses_nothing_silently(tmp_path, kind):
    rng = random.Random(f"igs{kind}")
    path = tmp_path / "damaged.igs"
    for _ in range(TRIALS // 2):
        path.write_bytes(damage(IGES, rng, kind))
        scene = load(path, (path,))
        if scene is None:
            continue
        report = scene.import_report[str(path)]
        assert sum(sum(c.values()) for c in report["counts"].values()) == report["directory_entries"]
        if report["surfaces"] < 2:
            assert has_losses(report), report


@pytest.mark.parametrize("ext", [".bpt", ".json", ".obj", ".igs"])
def test_line_endings_load_alike(tmp_path, ext):
    """CRLF (and CR, and none at all, for IGES) load as LF does."""
    base = {".bpt": BPT, ".json": json.dumps(SCENE, indent=1), ".obj": OBJ, ".igs": IGES}[ext]
    (tmp_path / "small.bpt").write_text(BPT)
    path = tmp_path / f"x{ext}"
    path.write_bytes(base.encode())
    want = load_scene(path)
    variants = [base.replace("\n", "\r\n")]
    if ext == ".igs":
        variants += [base.replace("\n", "\r"), base.replace("\n", "")]
    for text in variants:
        path.write_bytes(text.encode())
        got = load_scene(path)
        assert (got.points == want.points).all() and got.n_patches == want.n_patches


@pytest.mark.parametrize("ext", [".bpt", ".json", ".obj"])
def test_form_feed_and_vertical_tab_keep_line_numbers(tmp_path, ext):
    """Inside a line they are spaces (JSON: an error there), never line breaks."""
    base = {".bpt": BPT, ".json": json.dumps(SCENE, indent=1), ".obj": OBJ}[ext]
    (tmp_path / "small.bpt").write_text(BPT)
    lines = base.split("\n")
    k = next(i for i, l in enumerate(lines) if " " in l.strip())
    lines[k] = lines[k].replace(" ", " \x0c\x0b", 1)
    if ext == ".json":
        bad = k + 1  # JSON has no form feed: the error is on that very line
    else:
        lines.insert(len(lines) - 1, "bogus 1 2")
        bad = len(lines) - 1
    path = tmp_path / f"x{ext}"
    path.write_text("\n".join(lines))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.line == bad, str(info.value)


def test_bpt_all_on_one_line_and_early_junk(tmp_path):
    path = tmp_path / "one.bpt"
    path.write_text(" ".join(BPT.split()))
    assert load_scene(path).n_patches == 2 and load_scene(path).rational.tolist() == [False, True]
    path.write_text(BPT + "junk " * 2_000_000)  # 10 MB of junk after the last patch
    with pytest.raises(SceneError, match=r"one.bpt:14: extra content after the last patch.*'junk"):
        load_scene(path)


def test_long_tokens_are_quoted_briefly(tmp_path):
    token = "z" * 1_000_000
    cases = {"a.bpt": BPT.replace("0.5", token), "a.obj": OBJ.replace("v ", "v " + token + " ", 1),
             "a.json": json.dumps(SCENE).replace('"camera"', f'"{token}"'),
             "b.json": json.dumps(SCENE).replace("40", "4" * 100_000)}
    (tmp_path / "small.bpt").write_text(BPT)
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(SceneError) as info:
            load_scene(tmp_path / name)
        msg = check_error(info.value, (tmp_path / name,))
        assert "z" * 81 not in msg and "4" * 401 not in msg and len(msg) < 500, (name, msg[:300])


@pytest.mark.parametrize("ext", [".json", ".bpt", ".obj", ".igs"])
def test_paths_that_are_not_regular_files(tmp_path, ext):
    fifo, folder, zero = tmp_path / f"fifo{ext}", tmp_path / f"folder{ext}", tmp_path / f"zero{ext}"
    os.mkfifo(fifo)
    folder.mkdir()
    zero.symlink_to("/dev/zero")
    for path, kind in ((fifo, "FIFO"), (folder, "directory"), (zero, "character device")):
        with deadline(), pytest.raises(SceneError) as info:
            load_scene(path)
        assert str(info.value) == f"{path}: is a {kind}{' (named pipe)' if kind == 'FIFO' else ''}, " \
                                  f"not a regular file"
        if ext == ".json":
            continue
        scene = tmp_path / "refers.json"
        scene.write_text(json.dumps({"objects": [{"file": path.name}]}))
        with deadline(), pytest.raises(SceneError) as info:
            load_scene(scene)
        assert info.value.key == "objects[0].file" and "not a regular file" in str(info.value)


def test_size_is_checked_before_reading(tmp_path, monkeypatch):
    path = tmp_path / "big.bpt"
    path.write_text(BPT * 3)
    monkeypatch.setattr(source, "MAX_INPUT_BYTES", 64)
    with pytest.raises(SceneError, match=r"big.bpt: file is 252 bytes, more than the input limit of 64 "):
        load_scene(path)


# ---- the CLI ---------------------------------------------------------------------------------

BAD = {"nan.bpt": BPT.replace("0.5", "nan"), "digit.obj": OBJ.replace("0.5", "0.\u0665", 1),
       "long.json": json.dumps(SCENE).replace("40", "1" * 5000),
       "camera.json": json.dumps({**SCENE, "camera": {**SCENE["camera"], "up": [0, 1e-300, 1e-300]}}),
       "seq.igs": IGES.replace("D      3", "D      4", 1)}


def run_cli(argv, capsys):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    return code, err


@pytest.mark.parametrize("name", sorted(BAD))
@pytest.mark.parametrize("command", ["render", "trace"])
def test_cli_bad_input_leaves_outputs_alone(tmp_path, capsys, name, command):
    (tmp_path / "small.bpt").write_text(BPT)
    path = tmp_path / name
    path.write_text(BAD[name])
    old, new = tmp_path / "old.out", tmp_path / "new.out"
    old.write_bytes(b"keep me")
    outs = ["-o", old, "--stats", new] if command == "render" else ["-o", old, "--plot", new]
    argv = [command, path, *outs, "--size", "8x8"] + (["--pixel", "1,1"] if command == "trace" else [])
    code, err = run_cli(argv, capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith(f"psrt {command}: error: {path}"), err
    assert "Traceback" not in err and old.read_bytes() == b"keep me" and not new.exists()


@pytest.mark.parametrize("command", ["render", "trace"])
def test_cli_strict_damaged_iges(tmp_path, capsys, command):
    path = tmp_path / "cut.igs"
    path.write_text(IGES[:len(IGES) * 2 // 3])
    out = tmp_path / "out.png"
    argv = [command, path, "-o", out, "--size", "8x8", "--strict"] + (["--pixel", "1,1"] if command == "trace" else [])
    code, err = run_cli(argv, capsys)
    assert code == 2 and err.count("\n") == 1 and not out.exists(), err
    assert err.startswith(f"psrt {command}: error: {path}: --strict: ") and "cut short" in err


def test_cli_fifo_does_not_hang(tmp_path):
    fifo = tmp_path / "scene.json"
    os.mkfifo(fifo)
    out = tmp_path / "x.png"
    proc = subprocess.run([sys.executable, "-m", "psrt", "render", str(fifo), "-o", str(out)],
                          capture_output=True, text=True, timeout=120, cwd=REPO,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert proc.returncode == 2 and not out.exists()
    assert proc.stderr == f"psrt render: error: {fifo}: is a FIFO (named pipe), not a regular file\n"
