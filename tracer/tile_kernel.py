"""The per-tile kernel: the primary rays of one work unit (a list of pixels, a tile in some pixel
order), writing the kernel channels.

Called from worker threads (it releases the GIL), one call per unit, each with scratch of its
own (tile_scratch), so threads share nothing but the output arrays, of which each unit writes
only its own pixels. Built per kernel variant (variants.py).
"""
from __future__ import annotations

import math

import numpy as np

from .aggregate import WALKS, walk_scratch
from .bundle import WAITING, bundle_rays, make_bundle_search
from .lanes_split import LANES
from .bundle_steps import ONE, ZERO
from .bundle_walk import make_bvh_bundle_walk
from .drivers import make_search
from .jit import njit, specialise
from .ray import H_HI, H_LO, H_PATCH, H_TIN, H_TOUT, H_U, H_V, R_BUDGET, make_ray
from .records import (BUDGET_FLOOR, C_BOX_TESTS, C_CACHE_HITS, C_CACHE_MISSES, C_EFFORT, C_NODES, C_PATCHES,
                      C_SURFACES, C_UNRESOLVED, COUNTER_LEN, RAY_LEN, Slots, TileScratch, ray_scratch)
from .subpatch import MF_LEN, MI_LEN
from .hit_normal import hit_normal
from .trim_kernel import MAX_SPLIT_DEPTH
from .surface_cache import S_HITS, S_MISSES, no_cache

NO_CACHE = no_cache()


def working_slots(inputs) -> int:
    """Slots a search works in: a stack as deep as the subdivision, two for making halves, one
    for each ray of a bundle that may wait to go on alone (bundle.WAITING), and a stack for each
    lane the rays alone go on in (bundle_alone)."""
    return inputs.query.max_depth + 4 + WAITING + LANES * (inputs.query.max_depth + 2)


def tile_scratch(inputs, thread_cache=None) -> TileScratch:
    """A thread's scratch for one kernel call (kernel_inputs' records): the sub-patch stack in the
    working dtype, the aggregate's walk scratch (its stack and mailbox) and the per-ray records. Made
    here, in numpy, so the kernels allocate nothing (no reference counting, and no allocating kernel
    to compile). thread_cache: the thread's surface_cache.ThreadCache, whose arrays hold the slots."""
    lv = inputs.scene[0]
    _, max_points, stack_nodes, trim_points, bundle = inputs.sizes
    slots = working_slots(inputs)
    if thread_cache is not None:
        c = thread_cache
        buf, box, mf, mi, buf64, cache = c.buf, c.box, c.mf, c.mi, c.buf64, c.record
    else:
        buf = np.zeros((slots, 4, max_points), lv.ctrl.dtype)
        if buf.dtype == np.float64:
            buf64 = buf
        else:  # rational patches are searched in float64 slots (drivers.make_search)
            buf64 = np.zeros((slots, 4, max_points) if np.any(lv.rational) else (1, 4, 1))
        box, mf, mi = np.zeros((slots, 6)), np.zeros((slots, MF_LEN)), np.zeros((slots, MI_LEN), np.int32)
        cache = NO_CACHE
    sl = Slots(buf, box, mf, mi,
               np.arange(slots).astype(np.uint32),  # unsigned slot indices: no negative-index fix-ups
               np.zeros(RAY_LEN), np.zeros((4, max_points)),
               np.zeros((MAX_SPLIT_DEPTH + 4, trim_points, 3)), np.zeros((MAX_SPLIT_DEPTH + 4, 6)), buf64, cache)
    return TileScratch(sl, walk_scratch(inputs.scene[2], stack_nodes), ray_scratch(max_points),
                       bundle_rays(bundle, slots, stack_nodes, buf.dtype))


@njit(cache=True, nogil=True, inline='always')
def _write_channels(out, y, x, ray, hit, counts, length, trims, leaf_patch):
    """Pixel (y, x)'s kernel channels but its normal, from its ray's hit record and counters
    (length: |direction|); a miss's normal too."""
    out.effort[y, x] = counts[C_EFFORT]
    out.nodes[y, x] = counts[C_NODES]
    out.patches_tested[y, x] = counts[C_PATCHES]
    out.surfaces_tested[y, x] = counts[C_SURFACES]
    out.box_tests[y, x] = counts[C_BOX_TESTS] + counts[C_EFFORT]
    out.cache_hits[y, x] = counts[C_CACHE_HITS]
    out.cache_misses[y, x] = counts[C_CACHE_MISSES]
    out.unresolved[y, x] = counts[C_UNRESOLVED] != 0
    if hit[H_TIN] == math.inf:
        out.hit[y, x] = False
        out.t[y, x] = math.inf
        out.patch[y, x] = -1
        for c in range(3):
            out.position[y, x, c] = math.nan
            out.box_min[y, x, c] = math.nan
            out.box_max[y, x, c] = math.nan
            out.normal[y, x, c] = 0.0
        out.uv[y, x, 0] = math.nan
        out.uv[y, x, 1] = math.nan
        return
    out.hit[y, x] = True
    out.patch[y, x] = leaf_patch[int(hit[H_PATCH])]
    along = 0.0
    for c in range(3):
        lo = hit[H_LO + c]
        hi = hit[H_HI + c]
        centre = 0.5 * (lo + hi)
        out.box_min[y, x, c] = lo
        out.box_max[y, x, c] = hi
        out.position[y, x, c] = centre
        along += (centre - ray[c]) * ray[3 + c]
    # t of the ray point nearest the box centre, kept inside the box's slab interval.
    out.t[y, x] = min(max(along / (length * length), hit[H_TIN]), hit[H_TOUT])
    p = int(hit[H_PATCH])
    domain = trims.domain
    out.uv[y, x, 0] = domain[p, 0] + hit[H_U] * (domain[p, 1] - domain[p, 0])
    out.uv[y, x, 1] = domain[p, 2] + hit[H_V] * (domain[p, 3] - domain[p, 2])


@njit(cache=True, nogil=True, inline='always')
def _write_normal(out, y, x, ray, hit, lv, rs):
    """A hit pixel's normal channel (rs: records.RayScratch for the normal's evaluation)."""
    hit_normal(hit, lv.ctrl, lv.pstart, lv.deg_u, lv.deg_v, lv.rational, ray, rs.pts, rs.scratch, rs.work,
               rs.normal)
    for c in range(3):
        out.normal[y, x, c] = rs.normal[c]


@njit(cache=True, nogil=True, _nrt=False)
def write_pixel(out, y, x, ray, hit, counts, length, lv, trims, leaf_patch, rs):
    """Pixel (y, x)'s kernel channels from its ray's hit record and counters (length: |direction|;
    rs: records.RayScratch for the normal's evaluation)."""
    _write_channels(out, y, x, ray, hit, counts, length, trims, leaf_patch)
    if hit[H_TIN] != math.inf:
        _write_normal(out, y, x, ray, hit, lv, rs)


@njit(cache=True, nogil=True, _nrt=False)
def write_rays(out, pixels, first, count, rays, hits, counts, lengths, lv, trims, leaf_patch, rs):
    """write_pixel for rays[:count] (hits, counts and lengths likewise) into pixels[first:first +
    count]: every pixel's channels but the normal, then the hits' normals in a loop of their own
    (measured: 12-14 % of a 512x512 teapot frame without subdivision faster than pixel by pixel, as
    the two loops keep their code and registers apart)."""
    for j in range(count):
        _write_channels(out, pixels[first + j, 0], pixels[first + j, 1], rays[j], hits[j], counts[j], lengths[j],
                        trims, leaf_patch)
    for j in range(count):
        if hits[j, H_TIN] != math.inf:
            _write_normal(out, pixels[first + j, 0], pixels[first + j, 1], rays[j], hits[j], lv, rs)


@njit(cache=True, nogil=True, inline='always')
def start_ray(ray, hit, counts, origins, dirs, y, x, slope, q):
    """Pixel (y, x)'s primary ray into `ray` (threshold of detail slope * |direction|, the query's
    box budget), an empty hit before t = inf and zero counters; returns |direction|."""
    dx = dirs[y, x, 0]
    dy = dirs[y, x, 1]
    dz = dirs[y, x, 2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    make_ray(ray, origins[y, x, 0], origins[y, x, 1], origins[y, x, 2], dx, dy, dz, 0.0, 0.0, slope * length)
    if q.budget_factor > 0.0:
        ray[R_BUDGET] = q.budget_factor * max(q.budget_base[y, x], BUDGET_FLOOR)
    hit[H_TIN] = math.inf
    for k in range(COUNTER_LEN):
        counts[k] = 0
    return length


def _render_tile(pixels, blocks, origins, dirs, scene, q, slope, leaf_patch, out, trace, scratch):
    """The tile kernel template (see make_tile_kernel)."""
    lv, trims, agg = scene
    sl, stack, rs, _ = scratch
    for i in range(pixels.shape[0]):
        y = pixels[i, 0]
        x = pixels[i, 1]
        length = start_ray(rs.ray, rs.hit, rs.counts, origins, dirs, y, x, slope, q)
        hits = sl.cache.state[S_HITS]
        misses = sl.cache.state[S_MISSES]
        walk(agg, lv, trims, rs.ray, rs.hit, q, sl, stack, trace, rs.counts)  # noqa: F821
        rs.counts[C_CACHE_HITS] = sl.cache.state[S_HITS] - hits
        rs.counts[C_CACHE_MISSES] = sl.cache.state[S_MISSES] - misses
        write_pixel(out, y, x, rs.ray, rs.hit, rs.counts, length, lv, trims, leaf_patch, rs)


def _render_bundles(pixels, blocks, origins, dirs, scene, q, slope, leaf_patch, out, trace, scratch):
    """The tile kernel template for ray bundles (see make_tile_kernel): each block of pixels is one
    bundle through the aggregate and the patch searches (bundle.py)."""
    lv, trims, agg = scene
    sl, _, rs, br = scratch
    for b in range(blocks.shape[0] - 1):
        first = blocks[b]
        active = ZERO
        for j in range(blocks[b + 1] - first):
            y = pixels[first + j, 0]
            x = pixels[first + j, 1]
            br.lengths[j] = start_ray(br.rays[j], br.hits[j], br.counts[j], origins, dirs, y, x, slope, q)
            active |= ONE << np.uint64(j)
        walk(agg, lv, trims, q, sl, br, active)  # noqa: F821
        write_rays(out, pixels, first, blocks[b + 1] - first, br.rays, br.hits, br.counts, br.lengths, lv, trims,
                   leaf_patch, rs)


def _walk_of(variant):
    any_hit = variant.driver == "any"
    return WALKS[variant.accel](make_search(variant, any_hit), any_hit)


def make_tile_kernel(variant):
    """render_tile(pixels, blocks, origins, dirs, scene, q, slope, leaf_patch, out, trace, scratch)
    for one variant.

    pixels: (k, 2) int32 (row, column) of the unit's pixels, in the order they are traced; blocks:
    the bundles' offsets into them (render.Unit; bundle variants trace each block as one bundle);
    origins/dirs: (H, W, 3) float64 rays as traced. scene: (lv, trims,
    agg) records; q: records.Query; slope: the threshold of detail per unit distance (adaptive
    criterion; 0 otherwise); q's budget fields bound each ray's boxes (the float64 reference).
    The kernel's patches are leaves, and leaf_patch maps them to scene
    patches for the output. out: kernel_channels.Outputs; uv is in the parameters of the patch's
    surface (NURBS). scratch: the calling thread's TileScratch (tile_scratch).
    """
    # The pixel loop allocates nothing: no reference counts (see drivers).
    if variant.bundle:
        walk = make_bvh_bundle_walk(make_bundle_search(variant, sided=False))  # primary rays: no side planes
        return njit(cache=True, nogil=True, _nrt=False)(specialise(_render_bundles, walk=walk))
    return njit(cache=True, nogil=True, _nrt=False)(specialise(_render_tile, walk=_walk_of(variant)))


def _trace_one_ray(ray, hit, scene, q, trace, counts, scratch):
    """The one-ray kernel template (see make_ray_kernel)."""
    lv, trims, agg = scene
    sl, stack, _, _ = scratch
    walk(agg, lv, trims, ray, hit, q, sl, stack, trace, counts)  # noqa: F821


def make_ray_kernel(variant):
    """trace_one_ray(ray, hit, scene, q, trace, counts, scratch): one ray through the variant's
    walk (the pixel inspector: `trace` records every box). hit[H_TIN] holds the initial t_max."""
    return njit(cache=True, nogil=True, _nrt=False)(specialise(_trace_one_ray, walk=_walk_of(variant)))
