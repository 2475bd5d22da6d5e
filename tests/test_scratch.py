"""A ray's answer depends on nothing an earlier ray left in the kernel's scratch.

Each tile kernel call reuses one sub-patch stack for all its rays, so a field a search reads
before writing would make results depend on the tile size and on which rays ran before (the
right half of a float64 rational split once kept its error bound from whatever used the slot
last, zero in a fresh scratch: unwidened boxes). Here every float of the scratch starts as NaN
and the tiles change size: every contract channel must come out bit for bit the same.
"""
import numpy as np
import pytest

import digests as D
import tracer.render
from tracer.geometry import prepare
from tracer.options import Options
from tracer.render import render
from tracer.tile_kernel import tile_scratch

SCENES = ["teapot", "sphere", "plate", "random rational", "stress/degree 9x7"]


def _arrays(record):
    for item in record:
        if isinstance(item, np.ndarray):
            yield item
        else:  # a nested record (the cache's)
            yield from _arrays(item)


def _poisoned(inputs, thread_cache=None):
    scratch = tile_scratch(inputs, thread_cache)
    for array in _arrays(scratch):
        if array.dtype.kind == "f":
            array[...] = np.nan
    return scratch


@pytest.mark.parametrize("precision", ["f32", "f64"])
@pytest.mark.parametrize("name", SCENES)
def test_results_do_not_depend_on_what_the_scratch_held(name, precision, monkeypatch):
    scene, view = D.catalogue()[name][0]()
    geom = prepare(scene, precision)
    opts = Options(precision=precision, tile_size=16)
    clean = render(scene, opts, size=(16, 16), view=view, geometry=geom)
    monkeypatch.setattr(tracer.render, "tile_scratch", _poisoned)
    dirty = render(scene, opts.with_(tile_size=4), size=(16, 16), view=view, geometry=geom)
    moved = [c for c in D.CHANNELS if not np.array_equal(getattr(clean, c), getattr(dirty, c), equal_nan=True)]
    assert not moved
    assert clean.hit.any()
