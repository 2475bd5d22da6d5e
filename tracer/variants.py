"""Kernel variants: the compile-time key of the tile and ray kernels, and their compilation.

A variant fixes what a scene needs: precision, which patch kinds occur (rational; integral
bicubic, bilinear or other degrees), trims present, tracing on or off, the query driver
(closest or any hit), the aggregate kind and ray bundles (primary rays through the BVH: bundle.py;
elsewhere each ray goes alone). Its flags are constants of the kernels' closures,
so an integral bicubic scene never compiles or branches through rational or trimming code.
Kernels are built once per variant in a process and compiled (or loaded from numba's disk
cache) explicitly before the first tile, so compiling is its own, timed step: COMPILED
records how long each variant took and whether it came from the cache.
"""
from __future__ import annotations

import threading
import time
from collections import namedtuple

import numba
import numpy as np

from .jit import load_callees_first
from .options import bundled

Variant = namedtuple("Variant", "precision rational cubic linear general trims trace driver accel bundle cache")

COMPILED: dict = {}  # (kernel kind, Variant) -> {"seconds": s, "cached": bool}
_BUILT: dict = {}
_LOCK = threading.Lock()


def variant_for(geom, opts, *, trace: bool = False, driver: str = "closest") -> Variant:
    """The variant a render of `geom` with `opts` needs (the aggregate kind is opts.accel)."""
    m = np.asarray(geom.deg_u)
    n = np.asarray(geom.deg_v)
    rational = np.asarray(geom.rational) != 0
    integral = ~rational
    cubic = integral & (m == 3) & (n == 3)
    linear = integral & (m == 1) & (n == 1)
    trimmed = bool(opts.trims) and bool(np.any(np.asarray(geom.patch_trim) >= 0))
    # The bicubic and bilinear splits are small: a scene with integral patches compiles both,
    # so the teapot, the teapot on its floor and a floor alone share one variant (fewer
    # compiles); other degrees (the generic split) and rational patches stay flags of their own.
    fast = bool((cubic | linear).any())
    return Variant(geom.precision, bool(rational.any()), fast, fast,
                   bool((integral & ~cubic & ~linear).any()), trimmed, bool(trace), driver, opts.accel,
                   bundled(opts) and not trace and driver == "closest",
                   opts.cache and not trace)


def label(variant: Variant) -> str:
    """A short readable name, e.g. 'f32 bicubic+bilinear closest bvh'."""
    kinds = [k for k, on in (("rational", variant.rational), ("bicubic", variant.cubic),
                             ("bilinear", variant.linear), ("general", variant.general)) if on]
    extras = [k for k, on in (("trims", variant.trims), ("trace", variant.trace), ("bundles", variant.bundle),
                              ("cache", variant.cache)) if on]
    return " ".join([variant.precision, "+".join(kinds) or "empty"] + extras + [variant.driver, variant.accel])


def _kernel(kind: str, variant: Variant):
    from .ray_batch import make_batch_kernel, make_penumbra_kernel
    from .shadow_bundles import make_point_bundle_kernel
    from .tile_kernel import make_ray_kernel, make_tile_kernel
    factory = {"tile": make_tile_kernel, "ray": make_ray_kernel, "batch": make_batch_kernel,
               "penumbra": make_penumbra_kernel, "point_bundles": make_point_bundle_kernel}[kind]
    key = (kind, variant._replace(precision=""))  # one dispatcher serves both precisions
    with _LOCK:
        if key not in _BUILT:
            _BUILT[key] = factory(variant)
        return _BUILT[key]


def compiled(kind: str, variant: Variant, args: tuple, on_compile=None):
    """The kernel `kind` ('tile', 'ray', ray_batch's 'batch' and 'penumbra', or shadow_bundles'
    'point_bundles') of `variant`,
    compiled for the types of `args`.

    The first request for a variant in a process compiles it or loads it from the disk cache;
    on_compile(variant) is called before that work starts and on_compile(variant, seconds)
    when it is done (progress messages)."""
    kernel = _kernel(kind, variant)
    record_key = (kind, variant)
    if numba.config.DISABLE_JIT or record_key in COMPILED:
        return kernel
    signature = tuple(numba.typeof(a) for a in args)
    with _LOCK:
        if record_key in COMPILED:
            return kernel
        if on_compile is not None:
            on_compile(variant)
        hits_before = sum(kernel.stats.cache_hits.values())
        start = time.perf_counter()
        load_callees_first(kernel)
        kernel.compile(signature)
        COMPILED[record_key] = {"seconds": time.perf_counter() - start,
                                "cached": sum(kernel.stats.cache_hits.values()) > hits_before}
        if on_compile is not None:
            on_compile(variant, COMPILED[record_key]["seconds"])
    return kernel


def bound(kernel, args: tuple):
    """A caller of `kernel` for arguments of exactly the types of `args`: the entry point of the
    overload compiled for them, which skips the dispatcher's typing of every argument (about 11 us
    a call for the tile kernel's nested records, against 1 us); `kernel` itself where no overload
    takes these types yet, or where it is not a dispatcher (NUMBA_DISABLE_JIT, a wrapper). Only
    arguments of the same types may be passed to what it returns: the entry point does not check
    them."""
    overloads = getattr(kernel, "overloads", None)
    if overloads is None:
        return kernel
    overload = overloads.get(tuple(numba.typeof(a) for a in args))
    return kernel if overload is None else overload.entry_point


def type_key(value):
    """A hashable key of `value`'s numba type, in microseconds: values numba types differently have
    different keys (arrays by class, dtype, rank and the flags their layout, mutability and
    alignment come from; tuples and records by class and fields; ints by whether int64 holds
    them), where numba.typeof takes about 0.6 ms for the tile kernel's 94 arrays."""
    if isinstance(value, np.ndarray):
        f = value.flags
        return (type(value), value.dtype, value.ndim, f.c_contiguous, f.f_contiguous, f.writeable, f.aligned)
    if isinstance(value, tuple):
        return (type(value),) + tuple(type_key(v) for v in value)
    if value is None or isinstance(value, (bool, float)):
        return type(value)
    if isinstance(value, int) and -2 ** 63 <= value < 2 ** 63:
        return int
    if isinstance(value, np.generic):
        return (type(value), value.dtype)
    return numba.typeof(value)


_ENTRIES: dict = {}  # (kernel, type_key of its arguments) -> the overload's entry point


def entry_point(kernel, args: tuple):
    """bound(kernel, args), remembered by the arguments' type_key: a render's first call in each
    thread finds its entry point without numba's typing (0.6 ms a time, holding the interpreter
    lock the other threads' calls wait on)."""
    if getattr(kernel, "overloads", None) is None:
        return kernel
    key = (kernel, type_key(args))
    entry = _ENTRIES.get(key)
    if entry is None:
        entry = bound(kernel, args)
        if entry is not kernel:
            _ENTRIES[key] = entry
    return entry


def compile_report() -> list:
    """[{kernel, variant, seconds, cached}] for every variant compiled in this process."""
    return [{"kernel": kind, "variant": label(v), "seconds": round(r["seconds"], 3), "cached": r["cached"]}
            for (kind, v), r in COMPILED.items()]
