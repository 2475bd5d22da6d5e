"""Primary rays made in bands of rows on several threads (camera.primary_rays threads=) are byte
for byte the rays made on one."""
from __future__ import annotations

import numpy as np
import pytest

from tracer.camera import View, primary_rays

VIEW = View((1.5, -9.0, 2.25), (0.1, 0.2, -0.3), (0.0, 0.0, 1.0), 37.0)


@pytest.mark.parametrize("precision", ("f32", "f64"))
@pytest.mark.parametrize("size, rect", [((512, 512), None), ((300, 700), None), ((640, 480), (5, 470, 3, 600)),
                                         ((7, 3), None)])
def test_rays_in_bands_are_the_rays_in_one(precision, size, rect):
    one = primary_rays(VIEW, *size, precision, rect=rect)
    for threads in (2, 3, 8):
        many = primary_rays(VIEW, *size, precision, rect=rect, threads=threads)
        for a, b in zip(one, many):
            assert a.shape == b.shape and a.dtype == b.dtype == np.float64 and b.flags.c_contiguous
            assert a.tobytes() == b.tobytes()
    dirs = one[1].reshape(-1, 3)
    assert len(np.unique(dirs, axis=0)) == len(dirs)  # every pixel its own ray


def test_a_band_that_fails_fails_the_rays(monkeypatch):
    import tracer.camera as camera
    real = camera._rays_into

    def fails_below_the_middle(view, width, height, dtype, rect, origins, dirs):
        if rect[0] > 0:
            raise MemoryError("no room for the lower band")
        real(view, width, height, dtype, rect, origins, dirs)

    monkeypatch.setattr(camera, "_rays_into", fails_below_the_middle)
    with pytest.raises(MemoryError, match="lower band"):
        primary_rays(VIEW, 512, 512, "f32", threads=2)
    assert primary_rays(VIEW, 512, 512, "f32", threads=1)[1].shape == (512, 512, 3)  # one band: the top
