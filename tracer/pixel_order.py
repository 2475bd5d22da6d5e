"""Pixel orders (Lischinski & Gonczarowski 1990, section 5): a frame's work units, and the sequence
in which their pixels are traced.

Pixels are traced in ray bundles: blocks of cols x rows pixels aligned to the image grid (cut at
its right and bottom edges), pixels within a block row by row. Every order is a sequence of
blocks cut into units; a unit's pixel list is its blocks' pixels, block by block:

- scanline: tiles of (tile_size // cols) x (tile_size // rows) blocks, row by row, blocks row by
  row within a tile (with 1x1 bundles, render.tiles);
- peano: the Hilbert curve (the continuous Peano-type curve of their figure 5) over the smallest
  power-of-two square of blocks covering the image, blocks outside the image skipped. Units are
  the curve's aligned squares of S x S blocks, S the largest power of two with S blocks within
  tile_size pixels both ways: every quadrant, at every level, is finished before the next;
- itembuffer: a 64 x 64 item buffer holds, per cell, the nearest scene patch whose projected box
  overlaps it (item_buffer). Blocks are grouped by the patch of the cell under their centre, groups
  in the order the cells' own Hilbert curve first meets them (cells holding none last), blocks in
  Peano order within a group; the sequence is cut into units of a full scanline tile's blocks.
  Units are then scattered: their rects are bounding rectangles. The item buffer only orders
  pixels; what is traced never depends on it.

Everything here is numpy on whole arrays (2048 x 2048 in a fraction of a frame's time).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from .fixed_order import dot
from .options import ORDERS

ITEM_CELLS = 64         # item buffer entries per image edge (the paper's 64 x 64)
PAIR_CHUNK = 1 << 22    # (patch, cell) overlaps expanded at once while building the item buffer


def _ceil_div(a: int, b: int) -> int:
    return -(-a // b)


def tile_blocks(tile_size: int, bundle) -> tuple:
    """(columns, rows) of blocks in a scanline tile (and an item-buffer unit): as many as fit in
    tile_size pixels each way, at least one."""
    cols, rows = bundle
    return max(1, tile_size // cols), max(1, tile_size // rows)


def peano_side(tile_size: int, bundle) -> int:
    """Blocks per edge of a Peano unit: the largest power of two fitting in tile_size pixels both ways."""
    fit = min(tile_blocks(tile_size, bundle))
    return 1 << (fit.bit_length() - 1)


def hilbert(x, y, levels: int):
    """Cells (x, y) (x right, y down) on the Hilbert curve of the 2^levels square: (position
    along the curve int64, swap, mirror bool). The curve starts at (0, 0) and visits the
    quadrants top-left, bottom-left, bottom-right, top-right, each of them (recursively) whole
    before the next. swap and mirror say how the curve is turned at the cell: the sub-curve of a
    square there visits (u, v) where the unturned curve visits (u, v) mirrored (u -> s-1-u,
    v -> s-1-v) if mirror, then swapped (u <-> v) if swap."""
    x = np.array(x, np.int64)
    y = np.array(y, np.int64)
    d = np.zeros(np.broadcast(x, y).shape, np.int64)
    swap = np.zeros(d.shape, bool)
    mirror = np.zeros(d.shape, bool)
    for level in range(levels - 1, -1, -1):
        s = 1 << level
        rx = (x >> level) & 1
        ry = (y >> level) & 1
        d += (s * s) * ((3 * rx) ^ ry)
        x &= s - 1
        y &= s - 1
        # the quadrant's curve is the whole curve turned: mirrored across a diagonal
        flip = (ry == 0) & (rx == 1)
        x = np.where(flip, s - 1 - x, x)
        y = np.where(flip, s - 1 - y, y)
        x, y = np.where(ry == 0, y, x), np.where(ry == 0, x, y)
        # mirroring and swapping commute, so each turn toggles its own flag
        swap ^= ry == 0
        mirror ^= flip
    return d, swap, mirror


def hilbert_index(x, y, levels: int) -> np.ndarray:
    """Position of cells (x, y) along the Hilbert curve of the 2^levels square (see hilbert)."""
    return hilbert(x, y, levels)[0]


def _levels(n: int) -> int:
    """Levels of the smallest power-of-two square with at least n cells per edge."""
    return max(0, (n - 1).bit_length())


def peano_sequence(ncols: int, nrows: int, side: int):
    """Blocks of an ncols x nrows grid along the Hilbert curve: (block ids r * ncols + c int64,
    starts of the side x side units in that sequence int64, ending with its length).

    Built square by square: the squares in curve order, and within each the curve's visiting
    order of a side x side square turned as that square's piece of the curve is (four ways)."""
    nsc, nsr = _ceil_div(ncols, side), _ceil_div(nrows, side)
    sx, sy = np.meshgrid(np.arange(nsc), np.arange(nsr))
    sx, sy = sx.ravel(), sy.ravel()
    square_levels = _levels(max(nsc, nsr))
    d, swap, mirror = hilbert(sx, sy, square_levels)
    along = np.argsort(d)
    sx, sy, swap, mirror = sx[along], sy[along], swap[along], mirror[along]
    turn = swap.astype(np.int64) * 2 + mirror
    u, v = np.meshgrid(np.arange(side), np.arange(side))
    u, v = u.ravel(), v.ravel()
    visits = []  # per turn: the (u, v) offsets of a square's blocks in visiting order
    for t in range(4):
        tu, tv = (side - 1 - u, side - 1 - v) if t & 1 else (u, v)
        tu, tv = (tv, tu) if t & 2 else (tu, tv)
        visits.append(np.argsort(hilbert_index(tu, tv, _levels(side))))
    visits = np.stack(visits)
    order = visits[turn]                                  # (squares, side * side)
    cols = sx[:, None] * side + u[order]
    rows = sy[:, None] * side + v[order]
    inside = (cols < ncols) & (rows < nrows)
    starts = np.concatenate([[0], np.cumsum(inside.sum(axis=1))])
    return (rows * ncols + cols)[inside], starts


def scanline_sequence(ncols: int, nrows: int, tcols: int, trows: int):
    """Blocks in tiles of tcols x trows blocks, tiles row by row and blocks row by row within a
    tile: (block ids, unit starts) as peano_sequence."""
    ntc, ntr = _ceil_div(ncols, tcols), _ceil_div(nrows, trows)
    rows = np.arange(ntr * trows).reshape(ntr, 1, trows, 1)
    cols = np.arange(ntc * tcols).reshape(1, ntc, 1, tcols)
    rows, cols = np.broadcast_arrays(rows, cols)          # (tile row, tile column, row, column)
    inside = ((rows < nrows) & (cols < ncols)).reshape(ntr * ntc, -1)
    ids = (rows * ncols + cols).reshape(ntr * ntc, -1)
    starts = np.concatenate([[0], np.cumsum(inside.sum(axis=1))])
    return ids[inside], starts


def _block_extent(n: int, size: int, nblocks: int):
    """First pixel and pixel count of each block along one image axis (the last one cut)."""
    first = np.arange(nblocks) * size
    return first, np.minimum(first + size, n) - first


def item_buffer(boxes: np.ndarray, view, width: int, height: int, cells: int = ITEM_CELLS) -> np.ndarray:
    """(cells, cells) int32, row 0 at the top: per entry the patch whose box, projected through
    `view` onto a width x height image, overlaps the entry and lies nearest (the least distance
    of a box corner along the view direction; ties to the lower index), -1 where none does.

    boxes: (n, 6) float64 world boxes (lo, hi). Entry (i, j) covers the image region
    [j, j + 1] x [i, i + 1] in cell units (closed). A box wholly behind the eye is never seen;
    one reaching behind it projects without bound, so it covers every entry, at distance 0."""
    forward, right, up = view.basis()
    half = math.tan(math.radians(view.fov_deg) / 2.0)
    boxes = np.asarray(boxes, np.float64).reshape(-1, 6)
    corner = np.array([[(k >> a) & 1 for a in range(3)] for k in range(8)], bool)
    corners = np.where(corner[None], boxes[:, None, 3:], boxes[:, None, :3]) - np.asarray(view.eye, float)
    z, across, upward = dot(corners, forward), dot(corners, right), dot(corners, up)
    near, far = z.min(axis=1), z.max(axis=1)
    seen = np.isfinite(boxes).all(axis=1) & (far > 0)
    behind = near <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (across / z / (half * width / height) + 1.0) * cells / 2.0   # cell units, right
        v = (1.0 - upward / z / half) * cells / 2.0                      # cell units, down
    jlo = np.where(behind, 0, np.ceil(np.nan_to_num(u.min(axis=1))) - 1).clip(0, cells)
    jhi = np.where(behind, cells - 1, np.floor(np.nan_to_num(u.max(axis=1)))).clip(-1, cells - 1)
    ilo = np.where(behind, 0, np.ceil(np.nan_to_num(v.min(axis=1))) - 1).clip(0, cells)
    ihi = np.where(behind, cells - 1, np.floor(np.nan_to_num(v.max(axis=1)))).clip(-1, cells - 1)
    wide, tall = (jhi - jlo + 1).astype(np.int64), (ihi - ilo + 1).astype(np.int64)
    ids = np.flatnonzero(seen & (wide > 0) & (tall > 0))
    # nearest first, ties to the lower index: a cell keeps the least rank of the boxes over it
    rank_order = ids[np.lexsort((ids, np.maximum(near[ids], 0.0)))]
    nearest = np.full(cells * cells, len(rank_order), np.int64)
    count = wide[rank_order] * tall[rank_order]
    total = np.concatenate([[0], np.cumsum(count)])
    begin = 0
    while begin < len(rank_order):  # in chunks of about PAIR_CHUNK overlaps, to bound the memory
        end = max(begin + 1, int(np.searchsorted(total, total[begin] + PAIR_CHUNK, side="right")) - 1)
        rank = np.repeat(np.arange(begin, end), count[begin:end])
        p = rank_order[rank]
        k = np.arange(len(rank)) + total[begin] - total[rank]   # the overlap's index within its box
        cell = (ilo[p].astype(np.int64) + k // wide[p]) * cells + jlo[p].astype(np.int64) + k % wide[p]
        np.minimum.at(nearest, cell, rank)
        begin = end
    out = np.full(cells * cells, -1, np.int32)
    held = nearest < len(rank_order)
    out[held] = rank_order[nearest[held]]
    return out.reshape(cells, cells)


def itembuffer_sequence(ncols: int, nrows: int, width: int, height: int, bundle, per_unit: int, items,
                        side: int):
    """Blocks patch by patch after the item buffer `items` (item_buffer), Peano order within a
    patch (peano_sequence with squares of side blocks): (block ids, unit starts: every per_unit
    blocks)."""
    cells = items.shape[0]
    # the groups' order: where the cells' Hilbert curve first meets each patch; no patch last
    along = np.argsort(hilbert_index(*np.meshgrid(np.arange(cells), np.arange(cells)), _levels(cells)).ravel())
    met = items.ravel()[along]
    patches, first = np.unique(met, return_index=True)
    first = np.where(patches < 0, cells * cells, first)
    group = np.empty(len(patches), np.int16)   # at most cells^2 + 1 groups: int16 sorts by radix
    group[np.argsort(first, kind="stable")] = np.arange(len(patches))
    group_of_cell = group[np.searchsorted(patches, items)]
    # the cell under each block's centre
    centres = []
    for n, size, nb in ((height, bundle[1], nrows), (width, bundle[0], ncols)):
        first_px, extent = _block_extent(n, size, nb)
        centres.append(np.minimum(((2 * first_px + extent) * cells) // (2 * n), cells - 1))
    block_group = group_of_cell[centres[0][:, None], centres[1][None, :]].ravel()
    peano, _ = peano_sequence(ncols, nrows, side)
    ids = peano[np.argsort(block_group[peano], kind="stable")]
    return ids, np.append(np.arange(0, len(ids), per_unit), len(ids))


def block_units(width: int, height: int, bundle, ids: np.ndarray, starts: np.ndarray) -> list:
    """Units from a block sequence: [(pixels (k, 2) int32 (row, column), blocks (nb + 1,) int32
    offsets into pixels, rect (y0, y1, x0, x1) bounding the pixels)], one per run
    ids[starts[i]:starts[i + 1]]; a block's pixels row by row."""
    cols, rows = bundle
    ncols = _ceil_div(width, cols)
    brow = ids // ncols
    bcol = ids - brow * ncols
    if cols == rows == 1:  # a block is a pixel
        ys, xs, offsets = brow, bcol, np.arange(len(ids) + 1)
    else:
        y0, bh = _block_extent(height, rows, _ceil_div(height, rows))
        x0, bw = _block_extent(width, cols, ncols)
        bh, bw, y0, x0 = bh[brow], bw[bcol], y0[brow], x0[bcol]
        size = bh * bw
        offsets = np.concatenate([[0], np.cumsum(size)])
        block = np.repeat(np.arange(len(ids)), size)
        k = np.arange(offsets[-1]) - offsets[block]
        ys, xs = y0[block] + k // bw[block], x0[block] + k % bw[block]
    pixels = np.empty((len(ys), 2), np.int32)
    pixels[:, 0], pixels[:, 1] = ys, xs
    first = offsets[starts[:-1]]
    top, bottom = np.minimum.reduceat(ys, first), np.maximum.reduceat(ys, first) + 1
    left, right = np.minimum.reduceat(xs, first), np.maximum.reduceat(xs, first) + 1
    units = []
    for i in range(len(starts) - 1):
        a, b = starts[i], starts[i + 1]
        units.append((pixels[offsets[a]:offsets[b]], (offsets[a:b + 1] - offsets[a]).astype(np.int32),
                      (int(top[i]), int(bottom[i]), int(left[i]), int(right[i]))))
    return units


def order_units(width: int, height: int, order: str, tile_size: int, bundle=(1, 1), boxes=None, view=None) -> list:
    """The frame's work units in the order they are handed out (see the module docstring), as
    (pixels, blocks, rect) triples. itembuffer needs the scene's patch boxes (n, 6) and the view."""
    if order not in ORDERS:
        raise ValueError(f"order: expected one of {', '.join(ORDERS)}, got {order!r}")
    if width <= 0 or height <= 0:
        return []
    if order != "itembuffer":
        return list(_image_units(width, height, order, tile_size, tuple(bundle)))
    if boxes is None or view is None:
        raise ValueError("order itembuffer: needs the scene's patch boxes and the view")
    cols, rows = bundle
    ncols, nrows = _ceil_div(width, cols), _ceil_div(height, rows)
    tcols, trows = tile_blocks(tile_size, bundle)
    items = item_buffer(boxes, view, width, height)
    ids, starts = itembuffer_sequence(ncols, nrows, width, height, bundle, tcols * trows, items,
                                      peano_side(tile_size, bundle))
    return block_units(width, height, bundle, ids, starts)


@lru_cache(maxsize=8)
def _image_units(width: int, height: int, order: str, tile_size: int, bundle: tuple) -> tuple:
    """order_units of the orders that depend on the image alone, made once per image and kept: a
    steady frame (the viewer's, a benchmark's) spends no time on them. The kernels only read them."""
    cols, rows = bundle
    ncols, nrows = _ceil_div(width, cols), _ceil_div(height, rows)
    tcols, trows = tile_blocks(tile_size, bundle)
    if order == "scanline":
        ids, starts = scanline_sequence(ncols, nrows, tcols, trows)
    else:
        ids, starts = peano_sequence(ncols, nrows, peano_side(tile_size, bundle))
    return tuple(block_units(width, height, bundle, ids, starts))


def unit_count(width: int, height: int, order: str, tile_size: int, bundle=(1, 1)) -> int:
    """How many units order_units makes (without the scene: a progress bar's length)."""
    if width <= 0 or height <= 0:
        return 0
    cols, rows = bundle
    ncols, nrows = _ceil_div(width, cols), _ceil_div(height, rows)
    tcols, trows = tile_blocks(tile_size, bundle)
    if order == "scanline":
        return _ceil_div(ncols, tcols) * _ceil_div(nrows, trows)
    if order == "peano":
        side = peano_side(tile_size, bundle)
        return _ceil_div(ncols, side) * _ceil_div(nrows, side)
    return _ceil_div(ncols * nrows, tcols * trows)


def fills_rect(pixels: np.ndarray, rect) -> bool:
    """Whether a unit's pixels are all of its rect (a tile), not scattered in it."""
    y0, y1, x0, x1 = rect
    return len(pixels) == (y1 - y0) * (x1 - x0)
