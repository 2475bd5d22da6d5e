"""Shadow rays in bundles (bundle.py): a point's rays, and its neighbours', share their subdivisions.

The shadow rays of one point leave the same origin for points of one light: near the origin
they descend the same sub-patches of the point's own surface down to the rounding's scale (the
boxes there hold the origin until they are a few ulps wide), and further on they cross the same
boxes of an occluder until the light's extent sets them apart. A bundle halves each of those
sub-patches once for all its rays, where each ray alone would halve it again. Consecutive points
(neighbouring pixels, in a unit's order) are packed whole into bundles of up to MAX_RAYS rays:
they walk the same nodes and cross the same occluders, and the bundle walk drops a node all of
its rays miss in one test (frustum.py). Teapot 512^2, 16 samples: 2-4 % faster than a bundle per
point.

A ray in a bundle reports what it would report alone where the tree of sub-patches does not
depend on the ray (the `length` split under the float, fixed and mantissa criteria: bundle.py):
its occlusion is whether its search finds a hit box before t_max, which the bundle's closest-hit
search answers as the single ray's any-hit search does (each finds one exactly when a box of the
same tree is accepted before t_max). Elsewhere the rays go one by one (ray_batch's any kernel).

Reflected and refracted rays go the same way (PointBundles.closest): consecutive rays (neighbouring
pixels' hits) in bundles of MAX_RAYS, each reporting the single ray's hit box, patch, parameters
and normal; only the counters of a ray that hits follow the bundle's order of visits (teapot 512^2,
16 samples: its reflected rays 1.01 -> 0.89 s).
"""
from __future__ import annotations

import math
import threading

import numpy as np

from .bundle import MAX_RAYS, bundle_rays, make_bundle_search
from .bundle_steps import ONE, ZERO
from .bundle_walk import make_bvh_bundle_walk
from .jit import njit, specialise
from .kernel_channels import Outputs, allocate
from .ray import H_TIN, set_limit
from .ray_batch import RB_TMAX, start_ray
from .records import C_EFFORT, COUNTER_LEN
from .tile_kernel import working_slots, write_pixel
from .variants import compiled


@njit(cache=True, nogil=True, inline='always')
def load_bundle(rays, first, count, br):
    """Batch rays first .. first + count - 1 into the bundle's records, each with an empty hit
    before its t_max and zero counters; the bundle's mask of them."""
    active = ZERO
    for j in range(count):
        r = rays[first + j]
        start_ray(br.rays[j], r)
        set_limit(br.hits[j], r[RB_TMAX])
        for k in range(COUNTER_LEN):
            br.counts[j, k] = 0
        active |= ONE << np.uint64(j)
    return active


def _trace_bundles(rays, starts, scene, q, leaf_patch, channels, out, occluded, effort, sl, br, rs):
    """The kernel template (see make_point_bundle_kernel)."""
    lv, trims, agg = scene
    for g in range(starts.shape[0] - 1):
        first = starts[g]
        active = load_bundle(rays, first, starts[g + 1] - first, br)
        walk(agg, lv, trims, q, sl, br, active)  # noqa: F821
        for j in range(starts[g + 1] - first):
            r = rays[first + j]
            found = br.hits[j, H_TIN] < r[RB_TMAX]
            if not channels:
                occluded[first + j] = found
                effort[first + j] = br.counts[j, C_EFFORT]
                continue
            if not found:  # as ray_batch's closest kernel: a miss
                br.hits[j, H_TIN] = math.inf
            d = math.sqrt(r[3] * r[3] + r[4] * r[4] + r[5] * r[5])
            write_pixel(out, 0, first + j, br.rays[j], br.hits[j], br.counts[j], d, lv, trims, leaf_patch, rs)


def make_point_bundle_kernel(variant):
    """trace(rays, starts, scene, q, leaf_patch, channels, out, occluded, effort, sl, br, rs): batch
    rays (N, ray_batch.RB_LEN), grouped into bundles of at most MAX_RAYS at the offsets `starts`,
    through the BVH (closest hit); channels: every kernel channel of out (a (1, N) image) written
    as ray_batch's closest kernel writes it (rs: the thread's ray scratch), else occluded (N,) bool
    and effort (N,) int32. sl: the thread's slots, br its BundleRays of MAX_RAYS rays. One kernel
    for both: a second would be compiled again."""
    walk = make_bvh_bundle_walk(make_bundle_search(variant, alone=False))  # measured: no faster, 15 s to compile
    return njit(cache=True, nogil=True, _nrt=False)(specialise(_trace_bundles, walk=walk))


# What the kernel's `out` reads when it writes occlusion alone: empty, never written.
_NO_CHANNELS = Outputs(**allocate(1, 0))


def shares_tree(opts) -> bool:
    """Does every ray descend the same tree of sub-patches (so a bundle, or penumbra.py's cone search
    standing for a point's rays, changes no answer)?"""
    return opts.criterion != "adaptive" and opts.split == "length"


class PointBundles:
    """Shadow rays traced in bundles of consecutive points' rays, beside a ray_batch.BatchTracer
    (its inputs, its threads' slots)."""

    def __init__(self, tracer):
        self.tracer = tracer
        self._local = threading.local()
        self._variant = tracer.variant("closest")._replace(bundle=True)

    def _bundle(self):
        br = getattr(self._local, "bundle", None)
        if br is None:
            inp = self.tracer.inputs
            br = self._local.bundle = bundle_rays(MAX_RAYS, working_slots(inp), inp.sizes[2])
        return br

    def _trace(self, rays, starts, channels: bool, out, occluded, effort):
        inp = self.tracer.inputs
        scratch = self.tracer.scratch()
        args = (rays, starts, inp.scene, inp.query, inp.leaf_patch, channels, out, occluded, effort, scratch.slots,
                self._bundle(), scratch.ray)
        compiled("point_bundles", self._variant, args, self.tracer.on_compile)(*args)

    def occluded(self, rays: np.ndarray, point: np.ndarray):
        """(occluded (N,) bool, boxes computed (N,) int32) of rays (N, RB_LEN) sorted by their
        point (N,), as BatchTracer.occluded answers them."""
        n = len(rays)
        occluded, effort = np.zeros(n, bool), np.zeros(n, np.int32)
        if n:
            self._trace(rays, bundle_starts(point), False, _NO_CHANNELS, occluded, effort)
        return occluded, effort

    def closest(self, rays: np.ndarray) -> Outputs:
        """The kernel channels of rays (N, RB_LEN) as a (1, N) image, as BatchTracer.closest answers
        them (but the counters of a ray that hits, which follow the bundle's order of visits),
        consecutive rays in bundles of MAX_RAYS: reflected and refracted rays of neighbouring pixels."""
        n = len(rays)
        out = Outputs(**allocate(1, n))
        if n:
            starts = np.arange(0, n + MAX_RAYS, MAX_RAYS).clip(max=n)
            self._trace(rays, starts, True, out, np.zeros(0, bool), np.zeros(0, np.int32))
        return out


def bundle_starts(point: np.ndarray) -> np.ndarray:
    """Offsets of the bundles of rays sorted by their point (N,): consecutive points' rays packed
    whole into bundles of at most MAX_RAYS (neighbouring pixels' points share much of the walk and
    of the occluders' boxes), a point with more rays cut every MAX_RAYS."""
    n = len(point)
    if n == 0:
        return np.zeros(1, np.int64)
    first = np.flatnonzero(np.r_[True, point[1:] != point[:-1]])
    starts = [0]
    size = 0
    for a, b in zip(first.tolist(), np.r_[first[1:], n].tolist()):
        if size and size + b - a > MAX_RAYS:
            starts.append(a)
            size = 0
        while size + b - a > MAX_RAYS:  # a point with more rays than a bundle holds
            a += MAX_RAYS - size
            starts.append(a)
            size = 0
        size += b - a
    return np.array(starts + [n], np.int64)
