"""The kernels' named records: what each kernel takes, defined in this one place.

Numba named tuples of arrays and scalars: they cost nothing at run time (their fields are
passed as one struct and read by offset), and they keep every kernel under a dozen
parameters. Python builds them once per frame (render.kernel_inputs) or per thread
(scratch_for); kernels read fields by name, so the order of the arrays is written only here.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .ray import HIT_LEN, RAY_LEN

# The patches the kernels search (geometry's leaves): control points in the working dtype
# (ctrl, (4, points), local to frame[p]; row 3 weights, rows 0-2 premultiplied for rational
# patches), point offsets pstart, degrees, rational flags, frames (n, 3), the float grid
# (n, 3), the stored points' error bound eps (n, 3), and the same points in float64 with
# their bound (ctrl64, eps64) for re-deriving small sub-patches.
Leaves = namedtuple("Leaves", "ctrl pstart deg_u deg_v rational frame grid eps ctrl64 eps64")

# Trimming (trim_kernel): the trimmed surface of each leaf (-1: none), each leaf's domain in
# its surface's parameters (n, 4), and the loops' flat arrays.
Trims = namedtuple("Trims", "patch_trim domain seg_points seg_start surf_seg_start start_inside seg_box")

# One patch as a search sees it: index, degrees, point count and first point; rational, bicubic
# or bilinear (integral) split; and its slots' arithmetic: mantissa bits, whether slots carry their
# subdivision rounding (cumulative, below float64), the per-level bound relative to the magnitude
# otherwise (sub_scale), a rounding's relative size (round_unit) and what counts as a real
# decrease of a box (shrink_factor).
PatchInfo = namedtuple("PatchInfo", "p m n count start rational cubic linear bits cumulative "
                       "sub_scale round_unit shrink_factor")

# What a search is asked: the criterion code and its parameter, split heuristic, depth cap,
# mantissa bits of the working dtype; and a box budget per ray (the float64 reference's
# bound): budget_factor times max(budget_base[y, x], BUDGET_FLOOR) boxes, none if the factor is 0.
Query = namedtuple("Query", "criterion param split_mode max_depth bits budget_factor budget_base")
BUDGET_FLOOR = 256

# The sub-patch stack of one thread, S = max depth + 2 slots (see subpatch.py for columns):
# buf (S, 4, P) working dtype, box (S, 6), mf (S, MF_LEN), mi (S, MI_LEN) int32,
# order (S,) uint32 stack position -> slot; lray: the ray moved into the patch's frame;
# w64 (4, P) float64 for re-derivation; trim_h, trim_m: the trim parity's curve stack;
# buf64 (S, 4, P) float64, the points of rational patches, which are searched in float64 whatever
# the working precision (buf itself in float64; a (1, 4, 1) stand-in where no patch is rational);
# cache: the thread's surface-tree cache (surface_cache.CacheRecord), whose nodes are the slots
# past the first S of buf, box, mf, mi and buf64 (a stand-in where the cache is off).
Slots = namedtuple("Slots", "buf box mf mi order lray w64 trim_h trim_m buf64 cache")

# Per ray counters the drivers and aggregates add to (int64 array of COUNTER_LEN): sub-patch boxes
# computed (effort), aggregate nodes (or voxels) visited, patches searched, 1 where the ray's box
# budget ran out (its hit, if any, need not be the closest), patches whose outermost box was
# tested (Lischinski's "surfaces tested"), the aggregate's own ray-box tests, and patch searches
# that found (or missed) a cached surface tree.
C_EFFORT, C_NODES, C_PATCHES, C_UNRESOLVED, C_SURFACES, C_BOX_TESTS, C_CACHE_HITS, C_CACHE_MISSES = range(8)
COUNTER_LEN = 8

# The subdivision trace of one ray: steps (k, TRACE_F) float64, (k, TRACE_I) int32, and
# state [steps used, truncated, reported step]. Kernels built without tracing ignore it.
Trace = namedtuple("Trace", "steps_f steps_i state")
TRACE_F, TRACE_I = 11, 3

# Per-ray scratch of the tile kernel: ray and hit records, counters, normal evaluation.
RayScratch = namedtuple("RayScratch", "ray hit counts pts scratch work normal")

# A kernel call's scratch: Slots, the aggregate's walk stack (aggregate.WalkStack), RayScratch,
# and the ray bundle's records (bundle.BundleRays; one ray's worth where rays go alone).
TileScratch = namedtuple("TileScratch", "slots stack ray bundle")


def no_trace() -> Trace:
    """The Trace record for kernels built without tracing (never written)."""
    return Trace(np.zeros((1, TRACE_F)), np.zeros((1, TRACE_I), np.int32), np.zeros(3, np.int64))


def new_trace(capacity: int) -> Trace:
    return Trace(np.zeros((capacity, TRACE_F)), np.zeros((capacity, TRACE_I), np.int32),
                 np.array([0, 0, -1], np.int64))


def ray_scratch(max_points: int) -> RayScratch:
    return RayScratch(np.zeros(RAY_LEN), np.zeros(HIT_LEN), np.zeros(COUNTER_LEN, np.int64),
                      np.zeros((4, max_points)), np.zeros((4, max_points)), np.zeros((6, 4)), np.zeros(3))
