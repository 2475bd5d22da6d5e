"""The one options record, shared by the command line and the viewer.

Each field carries its default, help text, choices or range and a UI hint in
its metadata (tracer/record.py), so `cli.py` builds its arguments and the viewer
its widgets from this single description. Kernels receive plain scalars derived
from it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial

from .record import Record, assign, described

CRITERIA = ("float", "fixed", "adaptive", "mantissa")
SPLITS = ("length", "cross")
PRECISIONS = ("f32", "f64")
MODES = ("shaded", "normal", "uv", "depth", "patch")
BUNDLES = ("1x1", "2x2", "4x2", "2x4", "4x4", "8x8")  # columns x rows of pixels traced together
ACCELS = ("bvh", "kdtree", "grid")
KD_SPLITS = ("sah", "middle")
ORDERS = ("scanline", "peano", "itembuffer")
ORIGINS = ("box_corner", "shift", "fixed_epsilon")  # where a secondary ray starts (lighting.py)
PENUMBRAS = ("off", "expanded", "tmax", "umbra")  # fast penumbra (penumbra.py)

# The plain setting, which every coherence option is checked and measured against: single rays
# through the BVH, no cache, scanline order (the default bundle is 8x8, the fastest: README).
PLAIN = {"bundle": "1x1", "accel": "bvh", "mailbox": False, "cache": False, "order": "scanline"}

# Kernel codes: small ints so the numba kernels take scalars, not strings.
CRITERION_CODE = {name: i for i, name in enumerate(CRITERIA)}
SPLIT_CODE = {name: i for i, name in enumerate(SPLITS)}

_opt = partial(described, group="Tracer")
_coh = partial(described, group="Coherence")
_lit = partial(described, group="Lighting")


@dataclass(frozen=True)
class Options(Record):
    """Everything that changes what the tracer computes or shows."""

    NOUN = "option"

    criterion: str = _opt("float", "termination criterion of the subdivision", choices=CRITERIA)
    fixed_size: float = _opt(1e-3, "fixed: stop when the box's L1 diameter is at most this (world units)",
                             lo=1e-9, hi=10.0, log=True, when={"criterion": "fixed"})
    pixel_fraction: float = _opt(0.5, "adaptive: stop when the box's L1 diameter is at most this fraction "
                                 "of the pixel footprint at its distance", lo=0.01, hi=8.0, log=True,
                                 when={"criterion": "adaptive"})
    mantissa_ulps: int = _opt(64, "mantissa: stop when box corners lie within this many ulps per coordinate "
                              "(of the patch-frame coordinates the arithmetic uses)",
                              lo=0, hi=1 << 20, log=True, when={"criterion": "mantissa"})
    split: str = _opt("length", "split heuristic: longer parameter direction, or cross product with the ray",
                      choices=SPLITS)
    precision: str = _opt("f32", "working precision of the subdivision", choices=PRECISIONS)
    trims: bool = _opt(True, "apply trimming curves (off: show trimmed surfaces whole)")
    bundle: str = _coh("8x8", "ray bundle: columns x rows of pixels whose rays share one subdivision stack "
                       "(Dammertz 2.5.1; through the BVH only). With the length split every bundle reports the "
                       "single ray's hits bit for bit; 8x8 measures fastest", choices=BUNDLES,
                       when={"accel": "bvh"})
    accel: str = _coh("bvh", "acceleration structure: bounding volume hierarchy, kd-tree, or uniform grid",
                      choices=ACCELS)
    kd_depth: int = _coh(20, "kd-tree: maximum depth", lo=1, hi=40, when={"accel": "kdtree"})
    kd_split: str = _coh("sah", "kd-tree: split planes by the surface area heuristic, or at the patch-box side "
                         "nearest the voxel's middle (Dammertz 3.2)", choices=KD_SPLITS, when={"accel": "kdtree"})
    grid_scale: float = _coh(1.0, "grid: voxels per axis relative to Lischinski's rule (voxel side a quarter of "
                             "the mean patch box side)", lo=0.0625, hi=8.0, log=True, when={"accel": "grid"})
    mailbox: bool = _coh(False, "kd-tree and grid: search each patch once per ray along the whole ray "
                         "(off: each voxel searches its patches with the ray clamped to the voxel)")
    cache: bool = _coh(False, "keep the upper levels of each patch's subdivision tree across rays "
                       "(Lischinski's surface trees, least recently used released first)")
    cache_mb: float = _coh(64.0, "surface-tree cache: memory bound per render thread, MiB", lo=1.0, hi=65536.0,
                           log=True, when={"cache": True})
    cache_depth: int = _coh(4, "surface-tree cache: levels of each patch's tree kept", lo=1, hi=40,
                            when={"cache": True})
    order: str = _coh("scanline", "pixel order: rows, the Peano curve (every quadrant finished before the next), "
                      "or patch by patch from a 64x64 item buffer", choices=ORDERS)
    shadows: bool = _lit(True, "trace shadow rays to the lights (off: every light reaches every point facing it)")
    reflections: bool = _lit(True, "trace mirror reflections of materials with `reflect`")
    refractions: bool = _lit(True, "trace refractions of materials with `transmit`")
    max_depth: int = _lit(3, "longest chain of reflected and refracted rays after the primary one", lo=0, hi=16)
    light_samples: int = _lit(0, "samples per area light and shading point (0: each light's own `samples`)",
                              lo=0, hi=4096, log=True)
    origin: str = _lit("box_corner", "where secondary rays start: the hit box's corner on the side they leave, "
                       "widened by origin_ulps (Dammertz 2.4); the hit point moved along the normal by the "
                       "threshold of detail or the box size (Lempitsky's O+-); or moved by origin_epsilon "
                       "world units", choices=ORIGINS)
    origin_ulps: int = _lit(7, "box_corner: ulps of the working precision the corner is moved outwards",
                            lo=0, hi=1 << 20, log=True, when={"origin": "box_corner"})
    origin_epsilon: float = _lit(1e-4, "fixed_epsilon: world units the origin is moved along the normal",
                                 lo=0.0, hi=1e6, when={"origin": "fixed_epsilon"})
    penumbra: str = _lit("umbra", "fast penumbra (Lukaszewski): off traces every light sample; expanded first "
                         "walks the point's ray to the light's centre through the patch boxes grown by the "
                         "light (Lemma 3.1) and tests the surfaces in the grown boxes it meets against the "
                         "cone of the shadow rays, and a point it proves lit traces no samples; tmax grows "
                         "each box only by its own shrink factor (Lemma 4.2); umbra adds umbra detection (Lemma "
                         "4.3): a point whose every shadow ray is proven to cross one patch traces no samples "
                         "either, and it runs the lit test only where that costs less than the point's samples "
                         "traced in bundles. The image is the same",
                         choices=PENUMBRAS)
    trivial_tests: bool = _lit(True, "decide shadow rays without tracing where the surface faces away from the "
                               "light sample (Lischinski 6); the image is the same")
    mode: str = _opt("shaded", "what the image shows", choices=MODES, group="Display")
    tile_size: int = _opt(32, "tile edge in pixels (tiles render in parallel)", lo=4, hi=256, group="Render")
    threads: int = _opt(0, "render threads (0: one per core)", lo=0, hi=256, group="Render")


def bundled(opts: Options) -> bool:
    """Does a render with opts trace its primary rays in bundles? (They go through the BVH only.)"""
    return opts.bundle != "1x1" and opts.accel == "bvh"


def option_fields():
    """The dataclass fields of Options, in declaration order."""
    return dataclasses.fields(Options)


def parse_assignment(opts: Options, text: str) -> Options:
    """Apply one `name=value` assignment (as given to `--set`) to an options record."""
    return assign((opts,), text)[0]
