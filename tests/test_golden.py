"""Stored golden images (tests/golden.py): what `psrt render` writes must not change unnoticed.

On failure the actual, expected and difference images are written into the test's tmp_path and
named in the message. Regenerate on purpose only: `python tests/golden.py --write`.
"""
import pytest

import golden as G
from images import compare_images, read_png

# Per-pixel tolerance in 8-bit levels, per image:
TOLERANCE = {
    # float64 shading (power, sqrt, the sRGB curve) of bit-identical hit channels: another numpy
    # or libm may round a value across a quantisation boundary, one level at most.
    "teapot-shaded": 1,
    # (n + 1) / 2 of the kernel's normals, quantised: the same one level.
    "teapot-normal": 1,
    # integer counts through a colour table interpolated in float32, and Pillow's text: one
    # level for the table's rounding; a moved glyph or table entry is a change to look at.
    "teapot-effort": 1,
}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    return G.render_all(tmp_path_factory.mktemp("golden-render"))


@pytest.mark.parametrize("name", G.NAMES)
def test_render_matches_golden_image(name, rendered, tmp_path):
    stored = G.STORE / f"{name}.png"
    assert stored.is_file(), f"{stored} missing: generate it on purpose with `python tests/golden.py --write`"
    compare_images(read_png(rendered[name]), read_png(stored), tmp_path, name, TOLERANCE[name])
