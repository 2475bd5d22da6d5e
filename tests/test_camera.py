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
