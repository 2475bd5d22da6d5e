"""The command line under failure: outputs that survive a failed run, outputs that would overwrite
an input, paths that are not regular files, the memory estimate, and a seeded fuzz of bad values
for every option (one line on stderr naming the option, exit 2, no traceback, nothing written).

Images are 8x8; nothing here depends on how fast the machine is.
"""
import errno
import json
import os
import random
import shutil
from pathlib import Path

import numpy as np
import pytest

import tracer.output_files
from psrt.cli import main
from tracer import memory
from tracer.camera import primary_rays, view_of
from tracer.options import option_fields
from tracer.scene import load_scene

REPO = Path(__file__).resolve().parents[1]
TEAPOT = REPO / "sample_models" / "teapot.json"


def run(*argv):
    return main([str(a) for a in argv])


def one_line_error(capsys, *needles):
    """stderr of the last run: exactly one line, no traceback, containing every needle."""
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, (needle, err)
    return err


def snapshot(folder: Path) -> dict:
    """Every file below folder (links not followed) and its bytes."""
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() and not p.is_symlink() else None)
            for p in sorted(folder.rglob("*"))}


@pytest.fixture
def outputs(tmp_path):
    """Pre-existing outputs of every kind, each holding bytes no render would write."""
    names = {"-o": "img.png", "--aov": "aov.npz", "--effort-map": "effort.png", "--error-map": "error.png",
             "--map": "nodes.png", "--stats": "stats.json"}
    paths = {flag: tmp_path / "out" / name for flag, name in names.items()}
    for flag, path in paths.items():
        path.parent.mkdir(exist_ok=True)
        path.write_bytes(f"old {flag}\n".encode())
    return paths


def failing_writes(monkeypatch, code, message, at=0):
    """Every output write from the at-th on fails as a device would (at its flush to disk)."""
    real_fsync, calls = os.fsync, []

    def fsync(fd):
        calls.append(fd)
        if len(calls) > at:
            raise OSError(code, message)
        real_fsync(fd)
    monkeypatch.setattr(tracer.output_files.os, "fsync", fsync)


def render_argv(paths, *extra):
    return ["render", TEAPOT, "--size", "8x8", "-q", "-o", paths["-o"], "--aov", paths["--aov"],
            "--effort-map", paths["--effort-map"], "--error-map", paths["--error-map"],
            "--map", f"nodes={paths['--map']}", "--stats", paths["--stats"], *extra]


# ---- outputs that survive failures ---------------------------------------------------------------

def test_all_outputs_commit_together(outputs, capsys):
    assert run(*render_argv(outputs)) == 0
    assert capsys.readouterr().err == ""
    for flag, path in outputs.items():
        assert not path.read_bytes().startswith(b"old"), flag
    assert sorted(p.name for p in outputs["-o"].parent.iterdir()) == sorted(p.name for p in outputs.values())
    with np.load(outputs["--aov"]) as z:  # the npz is where it was asked for, not at aov.npz.npz
        assert z["hit"].shape == (8, 8)


@pytest.mark.parametrize("failing", range(6))
def test_a_full_device_at_any_output_replaces_none(outputs, capsys, monkeypatch, failing):
    """The device fills up while the failing-th output is written (the image first, --stats last):
    every pre-existing output is byte-identical, no temporary is left, exit 1 with one line."""
    failing_writes(monkeypatch, errno.ENOSPC, "No space left on device", at=failing)
    before = snapshot(outputs["-o"].parent)
    assert run(*render_argv(outputs)) == 1
    one_line_error(capsys, "No space left on device")
    assert snapshot(outputs["-o"].parent) == before


def test_a_failure_after_some_outputs_are_written_replaces_none(outputs, capsys, monkeypatch):
    """The float64 reference fails (after the image, npz and effort map were written): none is
    replaced, and the outputs that did not exist before are not created."""
    import tracer.render

    def broken(*args, **kwargs):
        raise ValueError("reference exploded")
    monkeypatch.setattr(tracer.render, "reference_frame", broken)
    outputs["--aov"].unlink()
    outputs["--effort-map"].unlink()
    before = snapshot(outputs["-o"].parent)
    assert run(*render_argv(outputs)) == 2
    one_line_error(capsys, "reference exploded")
    assert snapshot(outputs["-o"].parent) == before


def test_ctrl_c_replaces_none(outputs, monkeypatch):
    import tracer.stats

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(tracer.stats, "error_stats", interrupted)
    before = snapshot(outputs["-o"].parent)
    assert run(*render_argv(outputs)) == 130
    assert snapshot(outputs["-o"].parent) == before


def test_trace_plot_failure_keeps_the_trace_and_stdout(tmp_path, capsys, monkeypatch):
    import tracer.plot
    out = tmp_path / "t.json"
    out.write_text("old trace")

    def unwritable(trace, path=None, size=None):
        raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "t.png"))
    monkeypatch.setattr(tracer.plot, "trace_plot", unwritable)
    assert run("trace", TEAPOT, "--pixel", "4,4", "--size", "8x8", "-q", "-o", out, "--plot", tmp_path / "t.png") == 1
    one_line_error(capsys, "Permission denied")
    assert out.read_text() == "old trace" and sorted(p.name for p in tmp_path.iterdir()) == ["t.json"]
    # the same run writing its trace to stdout prints nothing when the plot fails
    assert run("trace", TEAPOT, "--pixel", "4,4", "--size", "8x8", "-q", "--plot", tmp_path / "t.png") == 1
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1


def test_bench_json_is_atomic_too(tmp_path, capsys, monkeypatch):
    out = tmp_path / "b.json"
    out.write_text("old")
    failing_writes(monkeypatch, errno.EIO, "I/O error")
    assert run("bench", "--scene", TEAPOT, "--size", "8x8", "--runs", "1", "--criteria", "fixed", "--splits",
               "length", "--precisions", "f32", "-q", "--json", out) == 1
    one_line_error(capsys, "I/O error")
    assert out.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["b.json"]


def test_replaced_outputs_keep_their_mode_and_new_ones_follow_the_umask(tmp_path):
    kept = tmp_path / "kept.png"
    kept.write_bytes(b"old")
    kept.chmod(0o640)
    fresh = tmp_path / "fresh.json"
    assert run("render", TEAPOT, "--size", "8x8", "-q", "-o", kept, "--stats", fresh) == 0
    umask = os.umask(0)
    os.umask(umask)
    assert kept.stat().st_mode & 0o777 == 0o640 and fresh.stat().st_mode & 0o777 == 0o666 & ~umask


def test_an_output_through_a_symlink_replaces_the_target_and_keeps_the_link(tmp_path):
    target = tmp_path / "real.png"
    target.write_bytes(b"old")
    link = tmp_path / "link.png"
    link.symlink_to(target)
    assert run("render", TEAPOT, "--size", "8x8", "-q", "-o", link) == 0
    assert link.is_symlink() and target.read_bytes()[:4] == b"\x89PNG"


# ---- outputs refused before any work ----------------------------------------------------------

@pytest.fixture
def scene_dir(tmp_path):
    """The teapot scene and its .bpt, copied."""
    folder = tmp_path / "scene"
    folder.mkdir()
    shutil.copy(TEAPOT, folder / "teapot.json")
    for obj in json.loads(TEAPOT.read_text())["objects"]:
        if "file" in obj:
            (folder / obj["file"]).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(TEAPOT.parent / obj["file"], folder / obj["file"])
    return folder


def bpt_of(scene_dir: Path) -> Path:
    (bpt,) = scene_dir.rglob("*.bpt")
    return bpt


@pytest.fixture
def no_render(monkeypatch):
    """Fail the test if a render starts: refusals come before any work."""
    import tracer.render

    def render(*args, **kwargs):
        raise AssertionError("rendered although an output was refused")
    monkeypatch.setattr(tracer.render, "render", render)
    monkeypatch.setattr(tracer.render, "reference_frame", render)


@pytest.mark.parametrize("how", ["same path", "relative path", "symlink", "hard link"])
def test_an_output_that_is_the_scene_is_refused(scene_dir, capsys, monkeypatch, no_render, how):
    bpt = bpt_of(scene_dir)
    monkeypatch.chdir(scene_dir)
    out = {"same path": bpt, "relative path": os.path.relpath(bpt), "symlink": scene_dir / "link.bpt",
           "hard link": scene_dir / "hard.bpt"}[how]
    if how == "symlink":
        os.symlink(bpt, out)
    elif how == "hard link":
        os.link(bpt, out)
    before = snapshot(scene_dir)
    assert run("render", bpt, "-o", out, "-q") == 2
    one_line_error(capsys, "-o", "the scene file")
    assert snapshot(scene_dir) == before


@pytest.mark.parametrize("flag", ["-o", "--aov", "--stats", "--map"])
def test_an_output_that_is_a_file_the_scene_refers_to_is_refused(scene_dir, tmp_path, capsys, no_render, flag):
    bpt = bpt_of(scene_dir)
    before = snapshot(scene_dir)
    outs = {"-o": tmp_path / "i.png"}
    outs[flag] = bpt
    argv = ["render", scene_dir / "teapot.json", "-q", "-o", outs["-o"]]
    argv += [] if flag == "-o" else ["--map", f"nodes={bpt}"] if flag == "--map" else [flag, bpt]
    assert run(*argv) == 2
    one_line_error(capsys, flag, "a file the scene refers to")
    assert snapshot(scene_dir) == before and not (tmp_path / "i.png").exists()


def test_trace_and_bench_refuse_their_scene_as_output(scene_dir, capsys, no_render):
    scene = scene_dir / "teapot.json"
    before = snapshot(scene_dir)
    assert run("trace", scene, "--pixel", "1,1", "-o", scene) == 2
    one_line_error(capsys, "the scene file")
    assert run("trace", scene, "--pixel", "1,1", "--plot", bpt_of(scene_dir)) == 2
    one_line_error(capsys, "--plot", "a file the scene refers to")
    assert run("bench", "--scene", scene, "--json", scene) == 2
    one_line_error(capsys, "--json", "the scene file")
    assert snapshot(scene_dir) == before


@pytest.mark.parametrize("second", ["same", "relative", "hard link"])
def test_two_outputs_naming_one_file_are_refused(tmp_path, capsys, monkeypatch, no_render, second):
    first = tmp_path / "a.png"
    first.write_bytes(b"old")
    monkeypatch.chdir(tmp_path)
    other = {"same": first, "relative": "./a.png", "hard link": tmp_path / "b.png"}[second]
    if second == "hard link":
        os.link(first, other)
    before = snapshot(tmp_path)
    assert run("render", TEAPOT, "-q", "-o", first, "--effort-map", other) == 2
    one_line_error(capsys, "--effort-map", "the same file as -o")
    assert snapshot(tmp_path) == before


def test_two_outputs_to_stdout_are_refused(capsys, no_render):
    assert run("render", TEAPOT, "-q", "-o", "x.png", "--stats", "-", "--aov", "-") == 2
    one_line_error(capsys, "--aov", "standard output")


@pytest.mark.parametrize("kind", ["fifo", "dev/null", "symlink to dev/null", "directory", "missing directory"])
def test_outputs_that_are_not_regular_files_are_refused(tmp_path, capsys, no_render, kind):
    path = {"fifo": tmp_path / "fifo.png", "dev/null": Path(os.devnull), "symlink to dev/null": tmp_path / "l.png",
            "directory": tmp_path / "d.png", "missing directory": tmp_path / "nowhere" / "x.png"}[kind]
    if kind == "fifo":
        os.mkfifo(path)  # opening it for writing would block forever: it must never be opened
    elif kind == "symlink to dev/null":
        path.symlink_to(os.devnull)
    elif kind == "directory":
        path.mkdir()
    expected = {"fifo": "is a FIFO", "dev/null": "is a device", "symlink to dev/null": "is a device",
                "directory": "is a directory", "missing directory": "does not exist"}[kind]
    before = snapshot(tmp_path)
    for argv in (["render", TEAPOT, "-q", "-o", tmp_path / "i.png", "--aov", path],
                 ["trace", TEAPOT, "--pixel", "1,1", "-q", "-o", path],
                 ["trace", TEAPOT, "--pixel", "1,1", "-q", "--plot", path]):
        assert run(*argv) == 2
        one_line_error(capsys, str(path), expected)
    assert snapshot(tmp_path) == before


def test_the_viewer_exports_write_atomically(tmp_path, monkeypatch):
    from viewer import outputs as viewer_outputs
    png = tmp_path / "shot.png"
    png.write_bytes(b"old")
    rgb = np.zeros((4, 4, 3), np.uint8)
    failing_writes(monkeypatch, errno.ENOSPC, "No space left on device")
    with pytest.raises(OSError):
        viewer_outputs.write_png(rgb, png)
    assert png.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["shot.png"]
    monkeypatch.undo()
    viewer_outputs.write_png(rgb, png)
    assert png.read_bytes()[:4] == b"\x89PNG"
    os.mkfifo(tmp_path / "fifo.png")
    with pytest.raises(ValueError, match="is a FIFO"):
        viewer_outputs.write_png(rgb, tmp_path / "fifo.png")


# ---- the memory estimate ------------------------------------------------------------------------

def test_a_huge_size_is_refused_with_the_figure_before_rendering(tmp_path, capsys, no_render):
    need = memory.render_bytes(16384, 16384, reference=True)
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--size", "16384x16384", "--stats", tmp_path / "s.json") == 2
    err = one_line_error(capsys, "16384x16384", f"needs about {memory.format_bytes(need)}", "memory limit",
                         "--memory-limit", memory.ENV)
    assert "with the float64 reference" in err
    assert list(tmp_path.iterdir()) == []


def test_the_memory_limit_can_be_set_by_flag_and_environment(tmp_path, capsys, monkeypatch, no_render):
    out = tmp_path / "i.png"
    assert run("render", TEAPOT, "-o", out, "--size", "64x64", "--memory-limit", "1M") == 2
    one_line_error(capsys, "64x64", "needs about", "over the memory limit of 1.0 MiB (--memory-limit)")
    monkeypatch.setenv(memory.ENV, "100K")
    assert run("render", TEAPOT, "-o", out, "--size", "64x64") == 2
    one_line_error(capsys, f"over the memory limit of 100.0 KiB (${memory.ENV})")
    assert run("bench", "--scene", TEAPOT, "--size", "64x64", "--runs", "1") == 2
    one_line_error(capsys, f"${memory.ENV}")
    monkeypatch.setenv(memory.ENV, "lots")
    assert run("render", TEAPOT, "-o", out, "--size", "64x64") == 2
    one_line_error(capsys, f"${memory.ENV}", "'lots'")
    assert not out.exists()


def test_the_memory_limit_lets_a_small_render_through(tmp_path, monkeypatch):
    monkeypatch.setenv(memory.ENV, "1G")
    assert run("render", TEAPOT, "-o", tmp_path / "i.png", "--size", "8x8", "-q", "--memory-limit", "1M") == 0


def test_the_estimate_counts_every_kernel_channel_and_the_reference():
    one = memory.render_bytes(1, 1)
    assert one >= memory.RAY_BYTES + memory.channel_bytes() + memory.SHADE_SCRATCH_BYTES
    assert memory.render_bytes(10, 20, reference=True, frames=2) == 200 * memory.render_bytes(1, 1, reference=True,
                                                                                              frames=2)
    assert memory.render_bytes(1, 1, frames=2) - one == memory.RAY_BYTES + memory.channel_bytes()
    assert memory.parse_bytes("1.5G") == 3 << 29 and memory.parse_bytes("512m") == 512 << 20


def test_a_trace_of_one_pixel_holds_one_ray_whatever_the_size(capsys):
    """`trace --size 16384x16384` traces its pixel without a whole image of rays."""
    assert run("trace", TEAPOT, "--pixel", "8191,8191", "--size", "16384x16384", "-q") == 0
    assert json.loads(capsys.readouterr().out)["pixel"] == [8191, 8191]
    view = view_of(load_scene(TEAPOT))
    full = primary_rays(view, 24, 16, "f32")
    for rect in ((0, 16, 0, 24), (3, 4, 17, 18), (15, 16, 0, 24)):
        part = primary_rays(view, 24, 16, "f32", rect=rect)
        y0, y1, x0, x1 = rect
        assert all(np.array_equal(p, f[y0:y1, x0:x1]) for p, f in zip(part, full))  # bit for bit


# ---- a fuzz of bad values -------------------------------------------------------------------------

JUNK = ["", " ", "inf", "-inf", "nan", "NaN", "1e400", "-1e400", "1_0", "\u0661\u0662", "\uff18", "0x10", "1e",
        "--1", "1,5", "½", "true", "None", "[]", "1 2", "\n", "\x00", "é" * 2000, "9" * 5000]


def bad_values(f, rng: random.Random) -> list:
    """Texts no field f accepts: junk, and for numbers the values just outside the range and
    non-integers for int fields; a few random strings of printable and other characters."""
    meta, kind = f.metadata, type(f.default)
    values = list(JUNK)
    if kind in (int, float):
        lo, hi = meta["lo"], meta["hi"]
        values += [repr(lo - 1), repr(hi + 1), repr(-abs(hi) - 1), repr(hi * 10)]
        if lo > 0:
            values.append(repr(lo / 2))
        if kind is int:
            values += [repr(lo + 0.5), f"{hi}.1", repr((lo + hi) / 2 + 0.25)]
    elif meta["choices"]:
        values += [c.upper() for c in meta["choices"]] + [c + " " for c in meta["choices"]]
    alphabet = "0123456789.eE+-_x ,;=/\\\"'\t\u0663\u00e9\u4e2d"
    values += ["".join(rng.choice(alphabet) for _ in range(rng.randint(1, 12))) for _ in range(8)]
    return [v for v in values if not accepted(f, v)]


def accepted(f, text) -> bool:
    from tracer.record import read_value
    try:
        read_value(f, text.strip())
        return True
    except ValueError:
        return False


def fuzz_cases(seed=11):
    rng = random.Random(seed)
    cases = []
    for f in option_fields():
        flag = "--" + (f.metadata.get("cli") or f.name.replace("_", "-"))
        for value in bad_values(f, rng):
            cases.append((["--set", f"{f.name}={value}"], f"option {f.name}"))
            if not isinstance(f.default, bool):
                cases.append(([f"{flag}={value}"], flag))
        if isinstance(f.default, bool):
            cases.append(([f"{flag}=maybe"], flag))
    for value in ["0x8", "8x0", "8", "8x8x8", "16385x8", "1_0x8", "\u0668x8", "-8x8", "8.5x8", "", "9" * 5000 + "x8"]:
        cases.append(([f"--size={value}"], "--size"))
    for value in ["bogus=x.png", "nodes=", "nodes", "=x.png", "\u00e9" * 3000]:
        cases.append(([f"--map={value}"], "--map"))
    for value in ["0", "-1", "1.5", "1e3", "inf", "", "\u0661"]:
        cases.append(([f"--memory-limit={value}"], "--memory-limit"))
    trace = [(["--pixel=" + v], "--pixel") for v in ["5", "1,2,3", "-1,2", "1.5,2", "\u0661,2", "", "a,b"]]
    bench = [(["--runs=" + v], "--runs") for v in ["0", "-1", "1.5", "1_0", "inf", "", "\u0663"]]
    return [("render", argv, needle) for argv, needle in cases] + [("trace", a, n) for a, n in trace] + \
        [("bench", a, n) for a, n in bench]


def test_fuzz_cases_cover_every_option():
    names = {needle.split()[-1] for _, _, needle in fuzz_cases()}
    assert {f.name for f in option_fields()} <= names
    assert len(fuzz_cases()) > 400


def test_fuzz_bad_cli_values(tmp_path, capsys, monkeypatch, no_render):
    """Every bad value: exit 2, exactly one line on stderr naming the option, no traceback, and
    no output file changed or created."""
    out = tmp_path / "out"
    out.mkdir()
    for name in ("i.png", "a.npz", "s.json", "t.json"):
        (out / name).write_bytes(b"old " + name.encode())
    before = snapshot(tmp_path)
    monkeypatch.chdir(tmp_path)
    for command, argv, needle in fuzz_cases():
        full = {"render": ["render", TEAPOT, "-o", out / "i.png", "--aov", out / "a.npz", "--stats", out / "s.json"],
                "trace": ["trace", TEAPOT, "--pixel", "1,1", "-o", out / "t.json"],
                "bench": ["bench", "--scene", TEAPOT, "--json", out / "s.json"]}[command]
        if command == "trace" and argv[0].startswith("--pixel"):
            full = full[:2] + full[4:]
        code = run(*full, *argv)
        captured = capsys.readouterr()
        assert code == 2, (command, argv, captured.err)
        err = captured.err
        assert err.count("\n") == 1 and err.endswith("\n"), (argv, err)
        assert needle in err and "Traceback" not in err, (argv, err)
        assert len(err) < 600, (argv, len(err))  # bad values are quoted in part, not echoed whole
        assert captured.out == ""
    assert snapshot(tmp_path) == before
