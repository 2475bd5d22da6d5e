"""What the working precision can bound and resolve: finite but extreme scenes, checked before
any work (geometry.prepare; the CLI prints the warnings, `check_extent`).

The rules follow from the arithmetic. M is the scene's largest |coordinate| and E its extent (the
longest side of the box of all control points), both in float64.

Errors (a one-line SceneError naming the file and the extent):

- E = 0: every control point is one point; there is nothing to see.
- (scene.py) A transform that takes control points past float64's largest number, naming the
  object's transform key.
- The float64 spacing at M is at least E: float64 numbers there cannot tell the scene's points
  apart (a quad whose corners are neighbouring float64 numbers, 2 apart at 1e16). No precision
  resolves it.
- E > 2^240 (1.8e72): the surface normal at a hit is a cross product of two derivatives (each
  up to 20 lengths for degree 20) normalised by its length, a sum of products of four lengths,
  which overflows float64 (2^1024) past about 2^251: the teapot scaled by 2^260 gets zero
  normals. Squared lengths elsewhere (the camera's framing and basis, shading, the kernels' box
  and hull tests; the BVH scales its own costs) stay far from overflow. Every scene is bounded
  in float64 (boxes, BVH, camera, normals, the reference), so this holds at f32 too.
- E < 2^-240 (5.7e-73): those products of four lengths underflow (below 2^-1022, normals lose
  digits at 2^-255 and turn to a fallback at 2^-300).
- f32 only: M > 2^124 (2.1e37): the camera a few extents away (the default framing stands 3 E
  back) and the float32 rays from it would pass float32's largest number, 2^128. E < 2^-100
  (7.9e-31): float32 coordinates inside the leaves, and their ulps, would be subnormal. The
  remedy `--precision f64` is named.
- A leaf whose weights differ by a ratio of 2^53 (9e15) or more: float64, in which rational
  patches are searched at either precision, cannot add its smallest weight to its largest, so
  de Casteljau's sums drop it and the boxes grow to the whole leaf. `check_weights`, per leaf (a
  pre-split leaf spans a smaller ratio than its patch).

Warnings (a line for the CLI to print; the render goes on):

- The working precision's spacing at M is more than E / 64: the rays' origins (the eye, a working
  precision number) round by up to half of it, 1/128 of the scene or about two pixels of a
  512-pixel view from 2.5 E away; the image is shifted, and once the spacing nears E, empty (a
  unit quad at 1e8 in float32, where float32 numbers are 8 apart). In float32 the remedy
  `--precision f64` is named (float64 resolves such a scene 2^29 times finer).

Extreme but uniform weights (1e-300 or 1e300 on every point of a patch) are harmless: a rational
patch is unchanged when all its weights are scaled alike, and `weight_scale` brings them near 1.
"""
from __future__ import annotations

import os
from decimal import Decimal

import numpy as np

from .errors import SceneError

PRECISION_BITS = {"f32": 24, "f64": 53}
PRECISION_NAME = {"f32": "float32", "f64": "float64"}

FLOAT64_LARGEST = 2.0 ** 240    # extents beyond: products of four lengths (normals) overflow float64
FLOAT64_SMALLEST = 2.0 ** -240  # extents below: they underflow
FLOAT32_LARGEST = 2.0 ** 124    # coordinates beyond: float32 rays from a camera a few extents away overflow
FLOAT32_SMALLEST = 2.0 ** -100  # extents below: float32 coordinates within a leaf are subnormal
RESOLVE = 1.0 / 64              # spacing at the scene's coordinates, as a fraction of its extent, above
                                # which the rays' origins are placed too coarsely
WEIGHTS_NEAR_ONE = 2.0 ** 64    # a leaf's largest weight outside 1/this..this is scaled to [0.5, 1)
REMEDY = "; use --precision f64"


def spacing(x, bits: int):
    """Spacing of `bits`-bit floats at x > 0 (a power of two)."""
    return np.ldexp(1.0, np.frexp(x)[1] - bits)


def _g(x) -> str:
    """x (a float or a Decimal) to 3 significant digits, even past float64's range (an extent of
    2e308, a Decimal)."""
    if np.isfinite(float(x)):
        return f"{float(x):.3g}"
    power = Decimal(x).adjusted()
    return f"{float(Decimal(x).scaleb(-power)):.3g}e+{power}"


def check_extent(scene, precision: str) -> list:
    """The warnings for a scene at a working precision (see the module docstring); raises
    SceneError, naming the scene file and its extent, for what it cannot bound or resolve."""
    lo, hi = scene.bounds()
    magnitude = float(np.max(np.maximum(np.abs(lo), np.abs(hi))))
    extent = 2 * Decimal(float(np.max(0.5 * hi - 0.5 * lo)))  # hi - lo can overflow
    extent_f = float(extent)  # inf past float64's range
    what = f"coordinates up to {_g(magnitude)}, extent {_g(extent)}"

    def error(text):
        return SceneError(f"{what}: {text}", path=scene.path)

    if extent == 0:
        raise error("every control point is the same point; there is nothing to render")
    s64 = spacing(magnitude, PRECISION_BITS["f64"])
    if s64 >= extent_f:
        raise error(f"float64 numbers there are {_g(s64)} apart, more than the extent: no precision "
                    f"resolves the scene (move it nearer the origin)")
    if extent_f > FLOAT64_LARGEST:
        raise error(f"too large for float64: surface normals (products of four lengths) overflow beyond "
                    f"an extent of 2^240 = {_g(FLOAT64_LARGEST)}")
    if extent_f < FLOAT64_SMALLEST:
        raise error(f"too small for float64: surface normals (products of four lengths) underflow below "
                    f"an extent of 2^-240 = {_g(FLOAT64_SMALLEST)}")
    if precision == "f32" and magnitude > FLOAT32_LARGEST:
        raise error(f"beyond float32's range: rays from a camera a few extents away would overflow past "
                    f"coordinates of 2^124 = {_g(FLOAT32_LARGEST)}{REMEDY}")
    if precision == "f32" and extent_f < FLOAT32_SMALLEST:
        raise error(f"below float32's range: coordinates within the patches would be subnormal below an "
                    f"extent of 2^-100 = {_g(FLOAT32_SMALLEST)}{REMEDY}")
    step = spacing(magnitude, PRECISION_BITS[precision])
    if step > extent_f * RESOLVE:
        name = PRECISION_NAME[precision]
        fix = REMEDY if precision == "f32" else " (move the scene nearer the origin)"
        return [f"{scene.path}: {what}: {name} numbers there are {_g(step)} apart, more than 1/64 of the "
                f"extent: too coarse for the rays' origins, the image may be misplaced or empty{fix}"]
    return []


def check_weights(scene, wmin, wmax, leaf_patch) -> None:
    """SceneError naming the first patch with a leaf whose weights differ by 2^53 or more (rational
    patches are searched in float64 whatever the working precision: drivers.make_search).

    wmin, wmax: (n_leaves,) each leaf's smallest and largest weight; leaf_patch: its scene patch."""
    bits = PRECISION_BITS["f64"]
    with np.errstate(over="ignore", divide="ignore"):
        ratio = wmax / wmin  # weights are > 0 (the loaders check); a 0 would be an infinite ratio
    bad = np.flatnonzero(ratio >= 2.0 ** bits)
    if not len(bad):
        return
    leaf = bad[0]
    patch = int(leaf_patch[leaf])
    path, line = _patch_source(scene, patch)
    raise SceneError(f"patch {patch}: weights from {_g(wmin[leaf])} to {_g(wmax[leaf])} within one of its "
                     f"pre-split pieces: float64 cannot add the smallest to the largest beyond a ratio of "
                     f"2^{bits} = {_g(2.0 ** bits)}", path=path, line=line)


def weight_scale(wmax) -> np.ndarray:
    """Per leaf, the power of two its weights are multiplied by: 1, unless the largest lies outside
    1/WEIGHTS_NEAR_ONE..WEIGHTS_NEAR_ONE (then one that brings it into [0.5, 1))."""
    far = (wmax > WEIGHTS_NEAR_ONE) | (wmax < 1.0 / WEIGHTS_NEAR_ONE)
    return np.where(far, np.ldexp(1.0, -np.frexp(wmax)[1]), 1.0)


def _patch_source(scene, patch: int):
    """(file, line) a scene patch was read from: its object's file (relative to the scene file's
    folder, as written in a scene) and the patch's line there; inline patches: the scene, no line."""
    source = scene.objects[int(scene.patch_object[patch])].source
    line = int(scene.patch_line[patch])
    if source == "inline":
        return scene.path, None
    if source != scene.path and scene.path:
        source = os.path.join(os.path.dirname(scene.path), source)
    return source, (line if line >= 0 else None)
