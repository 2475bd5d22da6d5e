"""IGES import through pyiges: the impeller acceptance model, conversions checked against IGES."""
import math
import time
from pathlib import Path

import numpy as np
import pytest

pyiges = pytest.importorskip("pyiges")
from pyiges import examples  # noqa: E402

from tracer.errors import SceneError  # noqa: E402
from tracer.formats.iges import load_iges  # noqa: E402
from tracer.nurbs import bezier_surface_point  # noqa: E402
from tracer.revolution import CircleParam  # noqa: E402
from tracer.scene import load_scene  # noqa: E402
from tracer.trim import inside  # noqa: E402

IMPELLER = Path(examples.impeller)


@pytest.fixture(scope="module")
def impeller():
    t0 = time.perf_counter()
    model = load_iges(IMPELLER)
    print(f"\nimpeller.igs: load_iges {time.perf_counter() - t0:.2f} s")
    return model


@pytest.fixture(scope="module")
def doc():
    return {e.sequence_number: e for e in pyiges.read(str(IMPELLER))}


def test_impeller_counts(impeller):
    r = impeller.report
    assert r["entities"][128] == 247 and r["entities"][144] == 277 and r["entities"][120] == 30
    assert r["surfaces"] == 277 and len(impeller.surfaces) == 277
    assert r["counts"]["converted"] == {144: 277}
    assert r["counts"]["consumed"][128] == 247 and r["counts"]["consumed"][120] == 30
    assert r["counts"]["consumed"][142] == 279
    assert r["unsupported"] == {} and r["failed"] == []
    # every directory entry lands in exactly one bucket
    assert sum(sum(c.values()) for c in r["counts"].values()) == r["directory_entries"] == 4615
    assert r["tolerance"] == 1e-8 and r["units"] == "MM" and r["system"] == "SolidWorks 2010"
    kinds = {}
    for s in impeller.surfaces:
        kinds[s.info.entity["surface_type"]] = kinds.get(s.info.entity["surface_type"], 0) + 1
        assert s.info.entity["type"] == 144 and s.info.entity["de"] % 2 == 1
    assert kinds == {128: 247, 120: 30}
    # 87 outer boundaries are the parameter rectangle itself and are dropped as loops
    assert r["outer_loop_is_domain"] == 87 and r["trimmed"] == 190
    assert sum(len(s.loops) for s in impeller.surfaces) == 277 - 87 + 2


def test_impeller_scene(impeller):
    t0 = time.perf_counter()
    sc = load_scene(IMPELLER)
    print(f"\nimpeller.igs: load_scene {time.perf_counter() - t0:.2f} s, {sc.n_patches} patches, "
          f"{sc.trims.n_segments} trim segments")
    assert len(sc.surfaces) == 277 and sc.n_patches == sum(s.patch_count for s in sc.surfaces)
    assert np.all(np.diff(sc.patch_surface) >= 0) and sc.patch_surface.min() == 0
    assert sc.trims.has_trim.sum() == 190
    f = sc.surfaces[10]
    assert sc.patch_surface[f.first_patch] == 10 and f.entity["type"] == 144
    assert sc.import_report[str(IMPELLER)]["surfaces"] == 277
    # patch domains lie inside their surface's domain
    for p in range(0, sc.n_patches, 7):
        d, dom = sc.patch_domain[p], sc.surfaces[sc.patch_surface[p]].domain
        assert dom[0] <= d[0] < d[1] <= dom[1] and dom[2] <= d[2] < d[3] <= dom[3]


def test_bspline_surfaces_match_iges_data(impeller, doc):
    """Bezier patches of each 128 reproduce the B-spline defined by pyiges' knots/weights/points."""
    rng = np.random.default_rng(0)
    for fs in impeller.surfaces[::9]:
        if fs.info.entity["surface_type"] != 128:
            continue
        e = doc[fs.info.entity["surface_de"]]
        s = fs.surface
        assert np.array_equal(s.knots_u, e.knot1) and np.array_equal(s.knots_v, e.knot2)
        assert np.array_equal(s.points[..., :3].reshape(-1, 3), e._cp)
        assert np.array_equal(s.points[..., 3].ravel(), e.weights)
        net = s.bezier_patches()
        for pts, d in zip(net.points, net.domains):
            a, b = rng.uniform(size=2)
            got = bezier_surface_point(pts.reshape(s.degree_v + 1, s.degree_u + 1, 4), a, b)
            want = s.evaluate(d[0] + a * (d[1] - d[0]), d[2] + b * (d[3] - d[2]))
            assert np.allclose(got, want, 0, 1e-11)


def test_revolutions_match_iges_definition(impeller, doc):
    """S(u, theta) = generatrix point turned right-handed about the axis line by theta."""
    rng = np.random.default_rng(1)
    n = 0
    for fs in impeller.surfaces:
        if fs.info.entity["surface_type"] != 120:
            continue
        p = doc[fs.info.entity["surface_de"]].parameters[0]
        axis, gen = doc[int(p[1])].coordinates, doc[int(p[2])].coordinates
        a0, a1 = float(p[3]), float(p[4])
        assert fs.info.entity["angle_v"] == [a0, a1] and "angle_u" not in fs.info.entity
        d = (axis[1] - axis[0]) / np.linalg.norm(axis[1] - axis[0])
        circ = CircleParam.for_sweep(a0, a1)
        for u, th in rng.uniform([0, a0], [1, a1], (10, 2)):
            c = gen[0] + u * (gen[1] - gen[0]) - axis[0]
            x = c - d * (d @ c)
            want = axis[0] + d * (d @ c) + x * math.cos(th) + np.cross(d, x) * math.sin(th)
            got = fs.surface.evaluate(u, float(circ.param(th)))
            assert np.allclose(got, want, 0, 1e-10 * max(1.0, np.abs(want).max()))
        n += 1
    assert n == 30


def test_revolution_trims_follow_the_angle_map(impeller, doc):
    """Points just either side of an IGES p-curve (in angle space) classify differently."""
    from tracer.formats.iges import _Converter  # the converter's own curve reading
    rng = np.random.default_rng(2)
    checked = 0
    trimmed = [fs for fs in impeller.surfaces
               if fs.info.entity["surface_type"] == 120 and fs.loops]
    assert trimmed
    for fs in trimmed[:6]:
        tri = __import__("tracer.trim", fromlist=["build_trimset"]).build_trimset([fs.loops])
        p = doc[fs.info.entity["de"]].parameters[0]
        conv = _Converter(doc.values(), {}, "x")
        circ = CircleParam.for_sweep(*fs.surface.domain[2:])
        bptr = int(doc[int(p[4])].parameters[0][3])
        for seg in conv.param_curve(bptr):
            if np.all(seg[:, 0] == seg[0, 0]) or np.all(seg[:, 1] == seg[0, 1]):
                continue  # lines map exactly; test the curved ones
            from tracer.trim import evaluate_segment
            s = rng.uniform(0.05, 0.95, 3)
            xy, dxy = evaluate_segment(seg, s, derivative=True)
            for (u, th), (du, dth) in zip(xy, dxy):
                # normal in (u, t) space of the mapped curve, step 1e-8
                tu, tt = du, circ.dparam(th) * dth
                nrm = np.array([-tt, tu]) / math.hypot(tu, tt) * 1e-8
                t = float(circ.param(th))
                sides = {inside(tri, 0, u + k * nrm[0], t + k * nrm[1]) for k in (-1, 1)}
                assert sides == {True, False}
                checked += 1
    assert checked > 20


def test_boundary_deviation_is_measured():
    t0 = time.perf_counter()
    model = load_iges(IMPELLER, measure_gaps=True)
    r = model.report
    print(f"\nimpeller.igs: widest distance between a face edge S(B(t)) and its model-space "
          f"curve {r['boundary_deviation_max']:.3g} {r['units']} (boundary DE "
          f"{r['boundary_deviation_de']}); modelling tolerance {r['tolerance']:g}; "
          f"widest p-curve gap closed {r['trim_widest_gap_rel']:.2g} of the parameter range; "
          f"{time.perf_counter() - t0:.1f} s")
    assert r["boundaries_measured"] == 279
    assert 0 < r["boundary_deviation_max"] < 0.05   # the file's p-curves are this loose


def test_unsupported_entities_are_reported(tmp_path):
    """A trimmed surface relabelled as 143 is counted as unsupported, its parts as orphans."""
    lines = IMPELLER.read_text(encoding="latin-1").splitlines()
    de = next(i for i, l in enumerate(lines) if l[72] == "D" and l[:8].strip() == "144")
    for i in (de, de + 1):
        lines[i] = "     143" + lines[i][8:]
    seq = int(lines[de][73:80])
    first_p = next(i for i, l in enumerate(lines) if l[72] == "P")
    p = first_p + int(lines[de][8:16]) - 1  # its parameter data names the type too
    assert lines[p].startswith("144,") and int(lines[p][64:72]) == seq
    lines[p] = "143," + lines[p][4:]
    path = tmp_path / "edited.igs"
    path.write_text("\n".join(lines) + "\n", encoding="latin-1")
    r = load_iges(path).report
    assert r["surfaces"] == 276 and r["unsupported"] == {143: 1}
    assert r["counts"]["orphan"][128] == 1 and r["counts"]["orphan"][142] == 1
    assert sum(sum(c.values()) for c in r["counts"].values()) == 4615
    base = int(lines[p][4:].split(",")[0])  # the 143's surface, now drawn by nobody
    assert r["lost"] == 2 and [(g["type"], g["kind"], g["de"]) for g in r["losses"]] == [
        (128, "orphan", [base]), (143, "unsupported entity type", [seq])]


def test_not_iges(tmp_path):
    bad = tmp_path / "x.igs"
    bad.write_text("hello\n")
    with pytest.raises(SceneError, match=r"x.igs:1: not an IGES line"):
        load_iges(bad)
    with pytest.raises(SceneError, match="file not found"):
        load_iges(tmp_path / "missing.igs")


# ---- IGES as written by real CAD tools, and damaged ----------------------------------------

from iges_writer import tiny_iges  # noqa: E402
from tracer.formats.losses import strict_check  # noqa: E402


def tiny_file(tmp_path, data, name="tiny.igs") -> Path:
    path = tmp_path / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode("ascii"))
    return path


def replace_in_line(text: str, section_seq: str, old: str, new: str) -> str:
    """text with `old` replaced by `new` (same width) in the line ending in section_seq ('P      9')."""
    assert len(old) == len(new)
    lines = text.split("\n")
    k = next(i for i, l in enumerate(lines) if l.endswith(section_seq))
    assert old in lines[k][:72], (lines[k], old)
    lines[k] = lines[k].replace(old, new, 1)
    return "\n".join(lines)


@pytest.mark.parametrize("variant", ["lf", "crlf", "cr", "80-byte records", "latin-1", "utf-8 by bytes",
                                     "utf-8 by characters"])
def test_iges_text_is_read_as_fixed_columns(tmp_path, variant):
    """Line endings and stray bytes >= 0x80 (an accented author) change nothing but the report."""
    accented = {"start": "Exportaci\u00f3n de Jos\u00e9", "author": "Jos\u00e9 M\u00fcller"}
    if variant == "utf-8 by characters":  # columns counted in characters: lines of 81, 82 bytes
        data = tiny_iges(**accented).encode("utf-8")
    elif variant == "utf-8 by bytes":  # columns counted in bytes (the same bytes, as Latin-1 text)
        data = tiny_iges(**{k: v.encode("utf-8").decode("latin-1") for k, v in accented.items()}).encode("latin-1")
    elif variant == "latin-1":
        data = tiny_iges(**accented).encode("latin-1")
    else:
        text = tiny_iges()
        data = {"lf": text, "crlf": text.replace("\n", "\r\n"), "cr": text.replace("\n", "\r"),
                "80-byte records": text.replace("\n", "")}[variant].encode("ascii")
    r = load_iges(tiny_file(tmp_path, data)).report
    assert r["surfaces"] == 2 and r["trimmed"] == 1 and r["lost"] == 0 and r["notes"] == []
    assert r["units"] == "MM" and r["tolerance"] == 1e-8
    if variant.startswith(("latin", "utf")):
        assert r["text"]["non_ascii_bytes"] in (4, 8) and r["text"]["non_ascii_first_line"] == 1
    else:
        assert r["text"] == {"line_endings": {"lf": "LF", "crlf": "CRLF", "cr": "CR",
                                              "80-byte records": "none (80-byte records)"}[variant]}


@pytest.mark.parametrize("edit, line, words", [
    (lambda t: t.replace("D      3", "D      4", 1), 7, "directory section D 3: sequence number '4', expected 3"),
    (lambda t: t.replace("     1P      2", "     1P      x", 1), 18,
     "parameter section P 2: sequence number 'x', expected 2"),
    (lambda t: t.replace("D      5", "X      5", 1), 9, "column 73 holds 'X'"),
    (lambda t: (lambda ls: "\n".join(ls[:10] + ["short line"] + ls[10:]))(t.split("\n")), 11,
     "not an IGES line: 10 columns"),
    (lambda t: (lambda ls: "\n".join(ls[:3] + ls[4:5] + ls[3:4] + ls[5:]))(t.split("\n")), 5,
     "a global section line after the directory section"),
    (lambda t: t.replace(t.split("\n")[3], t.split("\n")[3] + "extra columns"), 4, "93 columns, expected 80"),
])
def test_iges_structure_errors_name_section_and_line(tmp_path, edit, line, words):
    path = tiny_file(tmp_path, edit(tiny_iges()))
    with pytest.raises(SceneError) as info:
        load_iges(path)
    assert info.value.line == line and words in str(info.value), str(info.value)
    assert str(info.value).startswith(f"{path}:{line}: ") and "\n" not in str(info.value)


def groups(report):
    return {(g["type"], g["kind"]): g["de"] for g in report["losses"]}


def test_iges_nan_parameter_is_reported_by_entry_and_line(tmp_path):
    path = tiny_file(tmp_path, replace_in_line(tiny_iges(), "P      9", "2.00", "nan "))
    r = load_iges(path).report
    assert r["surfaces"] == 1 and r["lost"] == 2 and r["lost_surfaces"] == 2
    assert groups(r) == {(144, "conversion failed"): [9], (128, "unreadable parameter data"): [3]}
    reason = {g["type"]: g["reason"] for g in r["losses"]}
    assert reason[128].startswith("P 9: 'nan' is not finite")
    assert reason[144] == f"points to DE 3, which is unreadable ({reason[128]})"
    with pytest.raises(SceneError) as info:
        strict_check({str(path): r})
    assert str(info.value) == (f"{path}: --strict: 2 entities not converted (1 x 128 unreadable parameter "
                               f"data; 1 x 144 conversion failed); first: DE 3: {reason[128]}")


def test_iges_cut_short_is_reported(tmp_path):
    text = tiny_iges()
    cut = text.index("P     13")  # inside line P 13: the 126 p-curve, and everything after it, are gone
    r = load_iges(tiny_file(tmp_path, text[:cut - 30])).report
    assert r["surfaces"] == 1 and r["notes"][0].startswith("the file ends inside line 29")
    assert "no terminate section" in r["notes"][1]
    assert groups(r) == {(144, "unreadable parameter data"): [9], (128, "orphan"): [3],
                         (126, "unreadable parameter data"): [5], (142, "unreadable parameter data"): [7],
                         (314, "unreadable parameter data"): [11]}
    assert sum(sum(c.values()) for c in r["counts"].values()) == r["directory_entries"] == 6


def test_iges_flipped_status_is_not_silent(tmp_path):
    """A flipped bit that makes the independent surface subordinate leaves it an orphan, reported."""
    path = tiny_file(tmp_path, replace_in_line(tiny_iges(), "D      1", "       000000000", "       000010000"))
    r = load_iges(path).report
    assert r["surfaces"] == 1 and groups(r) == {(128, "orphan"): [1]}


def test_impeller_cut_in_half_reports_its_161_surfaces(tmp_path):
    data = IMPELLER.read_bytes()
    r = load_iges(tiny_file(tmp_path, data[:len(data) // 2], "half.igs")).report
    assert r["surfaces"] == 277 - 161 and groups(r)[(144, "unreadable parameter data")][:2] == [4253, 4307]
    assert len(groups(r)[(144, "unreadable parameter data")]) == 161 and r["text"]["line_endings"] == "CRLF"
    assert sum(sum(c.values()) for c in r["counts"].values()) == r["directory_entries"] == 4615


def test_cli_reports_iges_losses_on_stderr_in_stats_and_viewer(tmp_path, capsys):
    """render and trace say what was lost (even with -q), --stats holds it, the Scene panel shows
    it, --strict refuses the file in one line and leaves the outputs alone."""
    import json

    from psrt.cli import main
    from viewer.surface_info import import_rows
    path = tiny_file(tmp_path, replace_in_line(tiny_iges(), "P      9", "2.00", "nan "), "nan.igs")
    png, stats, tr = tmp_path / "x.png", tmp_path / "s.json", tmp_path / "t.json"
    want = [f"psrt render: warning: {path}: 2 IGES entities not converted (2 of them surfaces) "
            f"(--strict makes this an error):",
            "  1 x 128 (unreadable parameter data): DE 3; first: DE 3: P 9: 'nan' is not finite",
            "  1 x 144 (conversion failed): DE 9; first: DE 9: points to DE 3, which is unreadable (P 9: 'nan'"]
    assert main(["render", str(path), "-o", str(png), "--size", "8x8", "--stats", str(stats), "-q"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and err[0] == want[0] and all(e.startswith(w) for e, w in zip(err[1:], want[1:])), err
    imports = json.loads(stats.read_text())["imports"][str(path)]
    assert imports["lost"] == 2 and imports["lost_surfaces"] == 2 and imports["surfaces"] == 1
    assert [(g["type"], g["kind"], g["de"]) for g in imports["losses"]] == [
        (128, "unreadable parameter data", [3]), (144, "conversion failed", [9])]
    assert main(["trace", str(path), "--pixel", "4,4", "--size", "8x8", "-o", str(tr), "-q"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == want[0].replace("render", "trace") and len(err) == 3
    rows = import_rows(load_scene(path).import_report[str(path)])
    assert ("not converted", "2 entities, 2 of them surfaces") in rows
    assert [t for label, t in rows if label == "lost"][1].startswith("1 x 144 (conversion failed): DE 9")
    before = {p: p.read_bytes() for p in (png, stats, tr)}
    for argv in (["render", str(path), "-o", str(png), "--stats", str(stats)],
                 ["trace", str(path), "--pixel", "1,1", "-o", str(tr)]):
        assert main(argv + ["--size", "8x8", "--strict"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"psrt {argv[0]}: error: {path}: --strict: 2 entities")
    assert {p: p.read_bytes() for p in before} == before
