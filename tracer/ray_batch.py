"""Secondary rays in batches: any N rays, each with its own interval and threshold of detail.

The primary tile kernel traces one ray per pixel from a camera; shadow, reflected and refracted
rays start anywhere. Their kernel takes a flat (N, RB_LEN) float64 array of rays, each with
origin, direction, t_min, t_max and the threshold of detail T(t) = T0 + dT * t, and walks them
through the same aggregate and patch search as the primary rays (tile_kernel._walk_of):
  closest  the nearest hit in (t_min, t_max): the kernel channels of a (1, N) image;
  any      occlusion: the first hit box in (t_min, t_max) ends the ray (shadow rays);
  penumbra a point's ray to a light's centre through penumbra.py's expanded data set, with its
           sample rays' own searches where a grown box holds the origin: proven lit or not.
Calls come from the render threads, each with scratch of its own (BatchTracer.scratch).
"""
from __future__ import annotations

import math
import threading
from collections import namedtuple

import numpy as np

from .aggregate import WalkStack, make_bvh_walk
from .cone_search import make_cone_search
from .drivers import make_search
from .jit import njit, specialise
from .kernel_channels import Outputs, allocate
from .ray import H_TIN, R_TMIN, make_ray, set_limit, set_side
from .records import C_EFFORT, COUNTER_LEN, no_trace
from .tile_kernel import _walk_of, tile_scratch, write_pixel
from .variants import compiled, variant_for

# A batch ray: origin, direction, t_min, t_max, threshold of detail T0 and dT, and the normal of
# the side its origin left the surface on (ray.set_side; zero: none).
RB_O, RB_D, RB_TMIN, RB_TMAX, RB_T0, RB_DT, RB_SIDE = 0, 3, 6, 7, 8, 9, 10
RB_LEN = 13


@njit(cache=True, nogil=True, inline='always')
def start_ray(ray, r):
    """The ray record of batch ray r (RB_LEN,)."""
    make_ray(ray, r[0], r[1], r[2], r[3], r[4], r[5], r[RB_TMIN], r[RB_T0], r[RB_DT])
    set_side(ray, r[RB_SIDE], r[RB_SIDE + 1], r[RB_SIDE + 2])


def _trace_batch(rays, scene, q, leaf_patch, out, trace, scratch):
    """The batch kernel template (see make_batch_kernel)."""
    lv, trims, agg = scene
    sl, stack, rs, _ = scratch
    for i in range(rays.shape[0]):
        r = rays[i]
        start_ray(rs.ray, r)
        t_max = r[RB_TMAX]
        set_limit(rs.hit, t_max)
        for k in range(COUNTER_LEN):
            rs.counts[k] = 0
        walk(agg, lv, trims, rs.ray, rs.hit, q, sl, stack, trace, rs.counts)  # noqa: F821
        found = rs.hit[H_TIN] < t_max
        if ANY:  # noqa: F821
            out.hit[0, i] = found
            out.effort[0, i] = rs.counts[C_EFFORT]
        else:
            if not found:
                rs.hit[H_TIN] = math.inf
            d = math.sqrt(r[3] * r[3] + r[4] * r[4] + r[5] * r[5])
            write_pixel(out, 0, i, rs.ray, rs.hit, rs.counts, d, lv, trims, leaf_patch, rs)


def make_batch_kernel(variant):
    """trace_batch(rays, scene, q, leaf_patch, out, trace, scratch) for one variant: its driver
    'closest' writes every kernel channel of out (a (1, N) image), 'any' only hit and effort."""
    kernel = specialise(_trace_batch, walk=_walk_of(variant), ANY=variant.driver == "any")
    return njit(cache=True, nogil=True, _nrt=False)(kernel)


# What the penumbra kernel's leaf visits read (passed where the walk passes the leaves through):
# the scene's leaves and trims, the grown boxes (n_leaves, 6), the sample rays (m * S, RB_LEN) of
# the m points (S = count), the point being tested (state[0]) and the walk (state[1]: 0 boxes
# alone, 1 with the samples' searches; state[2] the grown boxes holding the origin met so far;
# state[3] 1 where one cone search may stand for the samples' searches: cone_search.py; state[4]
# the boxes the point's cone searches have computed; state[5], state[6]: the point's limits on
# leaves and boxes, MAX_NEAR and CONE_BOXES made smaller under wide cones),
# the sample's ray and hit records, and the light's half extents (3,).
PenumbraContext = namedtuple("PenumbraContext", "leaves trims grown samples count state ray hit counts half")


MAX_NEAR = 512  # leaves a point's walk may visit before it is sampled instead
MIN_NEAR = 8  # the fewest leaves a walk may visit (under the widest cones)
WIDE = 0.1  # angular size (light's half extent over its distance) up to which the limits hold whole
CONE_BOXES = 2048  # the boxes a point's cone searches may compute in all (a cone that meets a surface
# explores the whole patch of surface it meets: such points are cheaper sampled)


def _penumbra_visit(p, ctx, trims, ray, hit, q, sl, trace):
    """The centre ray of a point met leaf p's grown box.

    With a cone search (state[3] = 1) the leaf's surface itself is tested against the cone of the
    point's shadow rays (cone_search.py, Lukaszewski 4.3: the expanded object by its own geometry):
    a box reaching the criterion means "not proven lit", and so does a walk past MAX_NEAR leaves.
    Without it, a grown box that does not hold the ray's origin means "not proven lit"; one that
    does (the point's own surface, its neighbours) is passed by in the first walk (state[1] = 0)
    and settled in the second by the samples' own searches of that leaf."""
    ctx.state[2] += 1
    if ctx.state[2] > ctx.state[5]:  # too many boxes on the way to the light: sample the point
        hit[H_TIN] = ray[R_TMIN]
        return 1
    if CONE and ctx.state[3] == 1:  # noqa: F821
        maybe, spent = cone(p, ctx.leaves, ctx.trims, ray, ctx.half, q, sl, ctx.state[6] - ctx.state[4])  # noqa: F821
        ctx.state[4] += spent
        if maybe:
            hit[H_TIN] = ray[R_TMIN]
        return spent
    g = ctx.grown
    holds = True
    for c in range(3):
        if not g[p, c] <= ray[c] <= g[p, 3 + c]:
            holds = False
    if not holds:
        hit[H_TIN] = ray[R_TMIN]
        return 1
    if ctx.state[1] == 0:
        return 1
    first = ctx.state[0] * ctx.count
    spent = 0
    for j in range(first, first + ctx.count):
        r = ctx.samples[j]
        start_ray(ctx.ray, r)
        set_limit(ctx.hit, r[RB_TMAX])
        spent += search(p, ctx.leaves, ctx.trims, ctx.ray, ctx.hit, q, sl, trace)  # noqa: F821
        if ctx.hit[H_TIN] < r[RB_TMAX]:
            hit[H_TIN] = ray[R_TMIN]
            break
    return spent


def _trace_penumbra(rays, ctx, agg, q, lit, effort, trace, scratch):
    """The penumbra kernel template (see make_penumbra_kernel): per point, a walk over the grown
    boxes alone, then, if it met only boxes holding the origin, a walk with the samples' searches."""
    sl, stack, rs, _ = scratch
    for i in range(rays.shape[0]):
        r = rays[i]
        ctx.state[0] = i
        effort[i] = 0
        # the limits shrink as the light looks bigger (wider cones meet more surface): a third
        # power of its angular size beyond WIDE (measured: tests of wide cones mostly fail, dearly)
        size = 0.0
        for c in range(3):
            size = max(size, ctx.half[c])
        wide = size / max(math.sqrt(r[3] * r[3] + r[4] * r[4] + r[5] * r[5]), 1e-300)
        scale = min(1.0, (WIDE / wide) ** 3) if wide > 0.0 else 1.0
        ctx.state[5] = max(MIN_NEAR, int(MAX_NEAR * scale))
        ctx.state[6] = ctx.state[5] * CONE_BOXES // MAX_NEAR
        for second in range(1 if ctx.state[3] == 1 else 2):
            start_ray(rs.ray, r)
            set_limit(rs.hit, r[RB_TMAX])
            for k in range(COUNTER_LEN):
                rs.counts[k] = 0
            ctx.state[1] = second
            ctx.state[2] = 0
            ctx.state[4] = 0
            walk(agg, ctx, ctx.trims, rs.ray, rs.hit, q, sl, stack, trace, rs.counts)  # noqa: F821
            effort[i] += rs.counts[C_EFFORT]
            lit[i] = rs.hit[H_TIN] >= r[RB_TMAX]
            if not lit[i]:
                break


def make_penumbra_kernel(variant):
    """trace_penumbra(rays, ctx, agg, q, lit, effort, trace, scratch): per point, its centre ray
    (rays (m, RB_LEN), to the light's centre) through the BVH of grown boxes `agg`; lit[i] where
    no grown box but those holding the origin is met and no sample ray hits those (penumbra.py)."""
    cone = None if variant.rational else make_cone_search(variant)
    visit = njit(cache=True, nogil=True, _nrt=False)(specialise(_penumbra_visit, search=make_search(variant, True),
                                                                cone=cone, CONE=cone is not None))
    kernel = specialise(_trace_penumbra, walk=make_bvh_walk(visit, True))
    return njit(cache=True, nogil=True, _nrt=False)(kernel)


def batch_variant(geom, opts, driver: str):
    """The kernel variant of secondary rays: the scene's, rays alone and without the surface cache
    (its trees belong to the primary rays' thread units); render.trace_rays gives them the BVH."""
    return variant_for(geom, opts, driver=driver)._replace(bundle=False, cache=False)


class BatchTracer:
    """Secondary rays of one frame: the frame's kernel inputs (render.kernel_inputs), compiled
    batch kernels, and per-thread scratch."""

    def __init__(self, geom, opts, inputs, on_compile=None):
        self.inputs = inputs
        self.trace = no_trace()
        self._local = threading.local()
        self._geom, self._opts, self.on_compile = geom, opts, on_compile
        self._kernels = {}

    def variant(self, driver: str):
        """The batch kernels' variant for `driver` (batch_variant)."""
        return batch_variant(self._geom, self._opts, driver)

    def scratch(self):
        s = getattr(self._local, "scratch", None)
        if s is None:
            s = self._local.scratch = tile_scratch(self.inputs)
        return s

    def _kernel(self, driver: str, rays, out):
        if driver not in self._kernels:
            inp = self.inputs
            args = (rays, inp.scene, inp.query, inp.leaf_patch, out, self.trace, self.scratch())
            self._kernels[driver] = compiled("batch", self.variant(driver), args, self.on_compile)
        return self._kernels[driver]

    def occluded(self, rays: np.ndarray):
        """(occluded (N,) bool, boxes computed (N,) int32) of rays (N, RB_LEN)."""
        out = _outputs(len(rays))
        if len(rays):
            inp = self.inputs
            self._kernel("any", rays, out)(rays, inp.scene, inp.query, inp.leaf_patch, out, self.trace,
                                           self.scratch())
        return out.hit[0], out.effort[0]

    def closest(self, rays: np.ndarray) -> Outputs:
        """The kernel channels of rays (N, RB_LEN) as a (1, N) image."""
        out = _outputs(len(rays))
        if len(rays):
            inp = self.inputs
            self._kernel("closest", rays, out)(rays, inp.scene, inp.query, inp.leaf_patch, out, self.trace,
                                               self.scratch())
        return out

    def proven_lit(self, record, stack: int, grown, centre_rays, samples, count: int, half, cone: bool):
        """(lit (m,) bool, boxes (m,) int32): the penumbra kernel on m points' centre rays
        (m, RB_LEN) with their sample rays (m * count, RB_LEN), over the BVH `record` of `grown`;
        half: the light's half extents; cone: one cone search may stand for the samples'."""
        m = len(centre_rays)
        lit, effort = np.zeros(m, bool), np.zeros(m, np.int32)
        if m:
            inp = self.inputs
            ctx = PenumbraContext(inp.scene[0], inp.scene[1], grown, samples, count,
                                  np.array([0, 0, 0, int(cone), 0, 0, 0], np.int64), np.zeros(len(self.scratch().ray.ray)),
                                  np.zeros(len(self.scratch().ray.hit)), np.zeros(COUNTER_LEN, np.int64),
                                  np.ascontiguousarray(half, np.float64))
            scratch = self.scratch()._replace(stack=WalkStack(np.zeros(stack, np.int32), np.zeros(stack)))
            args = (centre_rays, ctx, record, inp.query, lit, effort, self.trace, scratch)
            compiled("penumbra", self.variant("any"), args, self.on_compile)(*args)
        return lit, effort


def _outputs(n: int) -> Outputs:
    return Outputs(**allocate(1, n))


def batch_rays(origins, dirs, t_min=0.0, t_max=math.inf, t0=0.0, dt=0.0, side=None) -> np.ndarray:
    """(N, RB_LEN) rays from origins and directions (N, 3) and scalars or (N,) arrays; side (N, 3):
    the normals of the sides the rays leave their surfaces on (None: not known)."""
    n = len(origins)
    rays = np.empty((n, RB_LEN))
    rays[:, RB_O:RB_O + 3] = origins
    rays[:, RB_D:RB_D + 3] = dirs
    rays[:, RB_TMIN] = t_min
    rays[:, RB_TMAX] = t_max
    rays[:, RB_T0] = t0
    rays[:, RB_DT] = dt
    rays[:, RB_SIDE:RB_SIDE + 3] = 0.0 if side is None else side
    return rays
