"""Pixel orders (tracer/pixel_order.py): every order traces every pixel once, in whole bundles
aligned to the image grid; the Peano order finishes every quadrant before the next; the item
buffer holds the nearest overlapping patch box and groups pixels patch by patch; and the frame
does not depend on the order (tracing is per pixel)."""
from __future__ import annotations

import numpy as np
import pytest

from tracer.camera import View, view_of
from tracer.geometry import prepare
from tracer.options import Options
from tracer.pixel_order import ITEM_CELLS, item_buffer, order_units, unit_count
from tracer.render import AOV_NAMES, rect_blocks, reference_frame, render, tiles, work_units
from tracer.shade import MODES, shade
from viewer_util import teapot  # noqa: F401

ORDERS = ("scanline", "peano", "itembuffer")
BUNDLES = ((1, 1), (2, 2), (4, 2), (2, 4), (8, 8))
SIZES = ((40, 32), (37, 23), (5, 3), (64, 64))
VIEW = View((0.0, -10.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 40.0)


def random_boxes(n: int, seed: int) -> np.ndarray:
    """n boxes around the origin, seen by VIEW (some partly outside the image)."""
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-4.0, 4.0, (n, 3))
    half = rng.uniform(0.1, 1.5, (n, 3))
    return np.concatenate([centre - half, centre + half], axis=1)


def units_of(order, size, tile_size, bundle, boxes=None):
    w, h = size
    return order_units(w, h, order, tile_size, bundle, random_boxes(12, 1) if boxes is None else boxes, VIEW)


def block_sequence(units, bundle):
    """(column, row) of every block of the units in sequence, from its first pixel."""
    firsts = np.concatenate([u[0][u[1][:-1]] for u in units])
    return firsts[:, 1] // bundle[0], firsts[:, 0] // bundle[1]


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("bundle", BUNDLES, ids=lambda b: f"{b[0]}x{b[1]}")
def test_every_pixel_once_in_whole_aligned_blocks(order, bundle):
    cols, rows = bundle
    for w, h in SIZES:
        for tile_size in (4, 16, 20):
            units = units_of(order, (w, h), tile_size, bundle)
            assert len(units) == unit_count(w, h, order, tile_size, bundle)
            seen = np.zeros((h, w), int)
            for pixels, blocks, rect in units:
                assert pixels.dtype == np.int32 and pixels.flags.c_contiguous and blocks.dtype == np.int32
                assert blocks[0] == 0 and blocks[-1] == len(pixels) and np.all(np.diff(blocks) > 0)
                assert len(pixels) <= max(tile_size, cols, rows) ** 2  # about a tile's pixels at most
                np.add.at(seen, (pixels[:, 0], pixels[:, 1]), 1)
                y0, y1, x0, x1 = rect
                assert (pixels[:, 0].min(), pixels[:, 0].max() + 1, pixels[:, 1].min(), pixels[:, 1].max() + 1) \
                    == (y0, y1, x0, x1)
                for a, b in zip(blocks[:-1], blocks[1:]):
                    by, bx = pixels[a, 0] // rows * rows, pixels[a, 1] // cols * cols
                    ys, xs = np.mgrid[by:min(by + rows, h), bx:min(bx + cols, w)]  # cut at the image's edges
                    assert np.array_equal(pixels[a:b], np.stack([ys.ravel(), xs.ravel()], axis=1))
            assert np.all(seen == 1), (w, h, tile_size)


@pytest.mark.parametrize("bundle", ((1, 1), (2, 2), (4, 2), (8, 8)), ids=lambda b: f"{b[0]}x{b[1]}")
def test_scanline_units_are_the_tiles_row_by_row(bundle):
    for w, h in SIZES:
        units = work_units(w, h, Options(tile_size=16, bundle=f"{bundle[0]}x{bundle[1]}"))
        assert [u.rect for u in units] == tiles(w, h, 16)
        for u in units:
            pixels, blocks = rect_blocks(u.rect, *bundle)
            assert np.array_equal(u.pixels, pixels) and np.array_equal(u.blocks, blocks)


@pytest.mark.parametrize("bundle", ((1, 1), (2, 2), (4, 2), (2, 4)), ids=lambda b: f"{b[0]}x{b[1]}")
def test_peano_finishes_every_quadrant_before_the_next(bundle):
    for w, h in ((64, 64), (40, 32), (100, 37), (37, 100)):
        for tile_size in (8, 32):
            units = units_of("peano", (w, h), tile_size, bundle)
            bx, by = block_sequence(units, bundle)
            span = 1 << int(np.ceil(np.log2(max(bx.max(), by.max()) + 1)))
            runs = 0
            side = span
            while side >= 2:
                for qy in range(0, span, side):
                    for qx in range(0, span, side):
                        at = np.flatnonzero((bx >= qx) & (bx < qx + side) & (by >= qy) & (by < qy + side))
                        assert len(at) == 0 or at[-1] - at[0] + 1 == len(at), (w, h, side, qx, qy)
                        runs += len(at) > 0
                side //= 2
            assert runs > 4
            # a unit is one of the curve's aligned squares (cut by the image)
            firsts = np.cumsum([0] + [len(u[1]) - 1 for u in units])
            sq = max(b - a for a, b in zip(firsts[:-1], firsts[1:])) ** 0.5
            for a, b in zip(firsts[:-1], firsts[1:]):
                assert len({(x // sq, y // sq) for x, y in zip(bx[a:b], by[a:b])}) == 1
            if bx.max() == by.max() == span - 1:  # blocks fill the square: a continuous curve, each next to the last
                assert np.all(np.abs(np.diff(bx)) + np.abs(np.diff(by)) == 1)


def test_peano_units_cut_one_curve():
    """The curve does not depend on the unit size (squares of 4, 8 or 32 blocks): it is the
    Hilbert curve of the whole power-of-two square, cut."""
    for w, h in ((64, 64), (100, 37)):
        sequences = [np.concatenate([u[0] for u in units_of("peano", (w, h), t, (1, 1))]) for t in (4, 8, 32)]
        assert all(np.array_equal(sequences[0], other) for other in sequences[1:])


def test_peano_starts_in_the_top_left_quadrant():
    units = work_units(128, 128, Options(order="peano", tile_size=16, bundle="1x1"))
    assert len(units) == 64 and all(u.rect[1] <= 64 and u.rect[3] <= 64 for u in units[:16])
    assert not any(u.rect[1] <= 64 and u.rect[3] <= 64 for u in units[16:])


def project_cells(box, view, size):
    """Brute force: the box's corners through the GL matrix of the viewer (a separate derivation
    of the camera): (cell x min, max, cell y min, max, distance along the view) or None when the
    box lies behind the eye; 'all' when it reaches behind the eye."""
    from viewer.display import view_projection
    m = view_projection(view, *size)
    corners = [[box[3 * (k >> a & 1) + a] for a in range(3)] for k in range(8)]
    clip = [m @ np.append(c, 1.0) for c in corners]
    w = [c[3] for c in clip]  # distance in front of the eye along the view direction
    if max(w) <= 0:
        return None
    if min(w) <= 0:
        return "all"
    xs = [(c[0] / c[3] + 1) / 2 * ITEM_CELLS for c in clip]
    ys = [(1 - c[1] / c[3]) / 2 * ITEM_CELLS for c in clip]
    return min(xs), max(xs), min(ys), max(ys), min(w)


@pytest.mark.parametrize("size", [(48, 48), (80, 40), (30, 50)])
def test_item_buffer_holds_the_nearest_overlapping_box(size):
    boxes = random_boxes(14, 7)
    boxes[3] = [-0.5, 20.0, -0.5, 0.5, 21.0, 0.5]   # behind the eye: never seen
    got = item_buffer(boxes, VIEW, *size)
    projected = [project_cells(b, VIEW, size) for b in boxes]
    want = np.full((ITEM_CELLS, ITEM_CELLS), -1)
    for i in range(ITEM_CELLS):
        for j in range(ITEM_CELLS):
            best = None
            for p, pr in enumerate(projected):
                if pr is None or not (pr[0] <= j + 1 and pr[1] >= j and pr[2] <= i + 1 and pr[3] >= i):
                    continue
                if best is None or pr[4] < best[0]:
                    best = (pr[4], p)
            want[i, j] = -1 if best is None else best[1]
    assert np.array_equal(got, want)
    assert len(set(got.ravel()) - {-1}) >= 5 and (got == -1).any()


def test_a_box_reaching_behind_the_eye_covers_the_item_buffer():
    boxes = np.array([[-1.0, -5.0, -1.0, 1.0, -4.0, 1.0], [-0.5, -11.0, -0.5, 0.5, 3.0, 0.5]])
    assert project_cells(boxes[1], VIEW, (32, 32)) == "all"
    assert np.all(item_buffer(boxes, VIEW, 32, 32) == 1)
    assert np.all(item_buffer(boxes[:1] - [0, 20, 0, 0, 20, 0], VIEW, 32, 32) == -1)


@pytest.mark.parametrize("bundle", ((1, 1), (2, 2), (4, 2)), ids=lambda b: f"{b[0]}x{b[1]}")
@pytest.mark.parametrize("size", [(96, 80), (50, 130)])
def test_itembuffer_traces_patch_by_patch_in_peano_order(bundle, size):
    w, h = size
    boxes = random_boxes(14, 7)
    items = item_buffer(boxes, VIEW, w, h)
    units = units_of("itembuffer", size, 16, bundle, boxes)
    bx, by = block_sequence(units, bundle)
    centre_x = bx * bundle[0] + np.minimum(bundle[0], w - bx * bundle[0]) / 2   # blocks are cut at the edges
    centre_y = by * bundle[1] + np.minimum(bundle[1], h - by * bundle[1]) / 2
    patch = items[(centre_y * ITEM_CELLS / h).astype(int), (centre_x * ITEM_CELLS / w).astype(int)]
    changes = np.flatnonzero(np.diff(patch)) + 1
    runs = np.split(patch, changes)
    assert len(runs) == len(set(patch)) >= 4, "a patch's blocks are not contiguous"
    assert patch[-1] == -1  # the blocks under no patch come last
    peano = units_of("peano", size, 16, bundle)
    px, py = block_sequence(peano, bundle)
    place = {(x, y): k for k, (x, y) in enumerate(zip(px, py))}
    for a, b in zip(np.concatenate([[0], changes]), np.concatenate([changes, [len(patch)]])):
        where = [place[(x, y)] for x, y in zip(bx[a:b], by[a:b])]
        assert where == sorted(where), "blocks of a patch out of Peano order"
    sizes = [len(u[1]) - 1 for u in units]
    assert sizes[:-1] == [sizes[0]] * (len(sizes) - 1) and sizes[0] == (16 // bundle[0]) * (16 // bundle[1])


def test_bad_orders_are_refused_in_one_line():
    with pytest.raises(ValueError, match="order: expected one of scanline, peano, itembuffer, got 'zorder'"):
        order_units(8, 8, "zorder", 4)
    with pytest.raises(ValueError, match="order itembuffer: needs the scene's patch boxes and the view"):
        work_units(8, 8, Options(order="itembuffer"))
    with pytest.raises(ValueError, match="option order"):
        Options().with_(order="zorder")


@pytest.fixture(scope="module")
def scanline_frame(teapot):
    frame = render(teapot, Options(tile_size=8, bundle="1x1"), size=(40, 32))
    return frame, reference_frame(teapot, frame)


def identical(a, b) -> bool:
    if a is None or b is None:  # a channel the frame did not compute (the reference has no lighting)
        return a is b
    return a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


@pytest.mark.parametrize("order", ("peano", "itembuffer"))
@pytest.mark.parametrize("tile_size", (8, 16))
def test_frame_channels_do_not_depend_on_the_order(teapot, scanline_frame, order, tile_size):
    """Every channel of the frame and of its float64 reference, bit for bit (bundle 1x1: the only
    one traced in this build); the reference is traced in the frame's order and units."""
    want, want_ref = scanline_frame
    opts = Options(order=order, tile_size=tile_size, threads=1, bundle="1x1")
    seen = []
    frame = render(teapot, opts, size=(40, 32), on_tile=lambda f, u: seen.append(u.rect))
    expected = work_units(40, 32, opts, prepare(teapot, "f32"), view_of(teapot))
    assert seen == [u.rect for u in expected]  # one thread: traced in the order's sequence
    ref_seen = []
    ref = reference_frame(teapot, frame, on_tile=lambda f, u: ref_seen.append(u.pixels))
    ref_units = work_units(40, 32, opts, prepare(teapot, "f64"), view_of(teapot))
    assert sorted(map(bytes, ref_seen)) == sorted(bytes(u.pixels) for u in ref_units)
    assert frame.hit.sum() > 100
    for name in AOV_NAMES:
        assert identical(getattr(frame, name), getattr(want, name)), name
        assert identical(getattr(ref, name), getattr(want_ref, name)), name


def test_scattered_pixels_shade_as_the_whole_image(teapot, scanline_frame):
    frame, _ = scanline_frame
    pixels = work_units(40, 32, Options(order="itembuffer", tile_size=8, bundle="1x1"), prepare(teapot, "f32"),
                        view_of(teapot))[1].pixels
    for mode in MODES:
        whole = shade(frame, teapot, mode, rect=(0, 32, 0, 40))
        assert np.array_equal(shade(frame, teapot, mode, pixels=pixels), whole[pixels[:, 0], pixels[:, 1]]), mode


def test_peano_meets_its_first_quadrant_again_only_at_the_end():
    """The seam that costs the Peano order re-made trees under some cache bounds (README,
    "Coherence"): the first and the last top-level quadrants of the curve (top left, top right)
    share an edge, and the pixels on either side of it are traced at the start and at the end of
    the frame; a scanline tile's neighbour below comes one row of tiles later."""
    n = 64
    place = np.empty((n, n), int)
    pixels = np.concatenate([u[0] for u in units_of("peano", (n, n), 16, (1, 1))])
    place[pixels[:, 0], pixels[:, 1]] = np.arange(n * n)
    left, right = place[:n // 2, n // 2 - 1], place[:n // 2, n // 2]
    assert left.max() < n * n // 4 and right.min() >= 3 * n * n // 4
    scan = np.concatenate([u[0] for u in units_of("scanline", (n, n), 16, (1, 1))])
    place[scan[:, 0], scan[:, 1]] = np.arange(n * n)
    assert np.all(np.abs(place[1:] - place[:-1]) <= 16 * n)  # vertical neighbours a row of tiles apart at most


@pytest.mark.parametrize("order", ORDERS)
def test_orders_make_the_same_searches_with_a_bounded_cache(teapot, scanline_frame, order):
    """With a cache too small for the frame (trees released and re-made), each order is scanline's
    frame without the cache bit for bit, each pixel makes the same searches (a hit or a miss each),
    and only the count of re-made trees can differ: every order misses each surface once first."""
    want, _ = scanline_frame
    geom = prepare(teapot, "f32")
    frames = {}
    for mb, depth in ((1.0, 30), (4096.0, 4)):
        opts = Options(order=order, tile_size=8, threads=1, cache=True, cache_mb=mb, cache_depth=depth,
                       bundle="1x1")
        frames[mb] = render(teapot, opts, size=(40, 32), geometry=geom)
        for name in AOV_NAMES:
            if name not in ("cache_hits", "cache_misses"):
                assert identical(getattr(frames[mb], name), getattr(want, name)), (name, mb)
        f = frames[mb]
        assert np.array_equal(f.cache_hits + f.cache_misses, want.patches_tested)
    small, every = frames[1.0].extras["cache"], frames[4096.0].extras["cache"]
    assert every["released"] == 0 and every["misses"] == every["surfaces"] == small["surfaces"]
    assert small["released"] > 0 and small["misses"] > small["surfaces"]
