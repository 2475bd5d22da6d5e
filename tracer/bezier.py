"""Leaf kernels on tensor-product Bezier patches.

Control points of one patch live in a slot of a buffer `buf[slot, c, k]`
(slot, coordinate 0..2, point k = j*(m+1) + i for P[i][j], i along u). That is
structure of arrays per patch: each coordinate's points are contiguous.

Every split halves the parameter interval with de Casteljau's midpoints
`(a + b) * HALF` (HALF a float32 one half, so float32 stays float32): a convex combination, so boxes of the halves stay inside the
parent's (up to rounding) and the halving by 2 is exact. Arithmetic happens in
the buffer's dtype (float32 or float64): one source, two compilations.
"""
from __future__ import annotations

import math

import numpy as np
from .jit import njit

from . import simd

# float32 so float32 midpoints stay float32 (no widening round trip); exact in float64 too.
HALF = np.float32(0.5)


@njit(cache=True, nogil=True, inline='always')
def split_u(buf, src, dst, m, n, ncoord):
    """Halve the patch in slot `src` at u = 1/2: `src` keeps u in [0, 1/2], `dst` gets [1/2, 1].

    buf: (slots, 4, points) float32/float64; m, n: degrees along u and v; ncoord: 3 for
    integral patches, 4 for rational ones (homogeneous w x, w y, w z, w: the same midpoints in 4-D).
    """
    stride = m + 1
    for c in range(ncoord):
        a = buf[src, c]
        r = buf[dst, c]
        for j in range(n + 1):
            b = j * stride
            r[b + m] = a[b + m]
            for k in range(1, m + 1):
                # After pass k, a[b+i] (i >= k) holds level-k point i-k; a[b+k] is final.
                for i in range(m, k - 1, -1):
                    a[b + i] = (a[b + i - 1] + a[b + i]) * HALF
                r[b + m - k] = a[b + m]


@njit(cache=True, nogil=True, inline='always')
def split_v(buf, src, dst, m, n, ncoord):
    """Halve the patch in slot `src` at v = 1/2: `src` keeps v in [0, 1/2], `dst` gets [1/2, 1]."""
    stride = m + 1
    for c in range(ncoord):
        a = buf[src, c]
        r = buf[dst, c]
        for i in range(m + 1):
            r[n * stride + i] = a[n * stride + i]
            for k in range(1, n + 1):
                for j in range(n, k - 1, -1):
                    a[j * stride + i] = (a[(j - 1) * stride + i] + a[j * stride + i]) * HALF
                r[(n - k) * stride + i] = a[n * stride + i]


@njit(cache=True, nogil=True, inline='always')
def split_u_cubic(buf, src, dst, box):
    """split_u for bicubic patches, also writing both halves' control boxes into box[src], box[dst]
    (in 4-wide vectors: see simd)."""
    simd.split_u_cubic(buf, src, dst, box)


@njit(cache=True, nogil=True, inline='always')
def split_v_cubic(buf, src, dst, box):
    """split_v for bicubic patches, with both halves' boxes (see split_u_cubic)."""
    simd.split_v_cubic(buf, src, dst, box)


@njit(cache=True, nogil=True, inline='always')
def _split_linear(buf, src, dst, box, a0, a1, b0, b1):
    """Halve a bilinear patch between its point pairs (a0, a1) and (b0, b1): src keeps the a0, b0
    half, dst gets the other; both halves' boxes are written as they are formed."""
    for c in range(3):
        pa0 = buf[src, c, a0]
        pa1 = buf[src, c, a1]
        pb0 = buf[src, c, b0]
        pb1 = buf[src, c, b1]
        m0 = (pa0 + pa1) * HALF
        m1 = (pb0 + pb1) * HALF
        buf[src, c, a1] = m0
        buf[src, c, b1] = m1
        buf[dst, c, a0] = m0
        buf[dst, c, a1] = pa1
        buf[dst, c, b0] = m1
        buf[dst, c, b1] = pb1
        box[src, c] = min(pa0, m0, pb0, m1)
        box[src, 3 + c] = max(pa0, m0, pb0, m1)
        box[dst, c] = min(m0, pa1, m1, pb1)
        box[dst, 3 + c] = max(m0, pa1, m1, pb1)


@njit(cache=True, nogil=True, inline='always')
def split_u_linear(buf, src, dst, box):
    """split_u for bilinear patches (points P00 P10 P01 P11), with both halves' boxes."""
    _split_linear(buf, src, dst, box, 0, 1, 2, 3)


@njit(cache=True, nogil=True, inline='always')
def split_v_linear(buf, src, dst, box):
    """split_v for bilinear patches, with both halves' boxes."""
    _split_linear(buf, src, dst, box, 0, 2, 1, 3)


@njit(cache=True, nogil=True, inline='always')
def control_box(buf, slot, count, box):
    """Write the axis-aligned box of the first `count` control points of `slot` into box[slot].

    box: (slots, 6) float64 as lo x, y, z, hi x, y, z; exact (min and max do not round).
    """
    for c in range(3):
        a = buf[slot, c]
        lo = a[0]
        hi = a[0]
        for k in range(1, count):
            v = a[k]
            lo = min(lo, v)
            hi = max(hi, v)
        box[slot, c] = lo
        box[slot, 3 + c] = hi


@njit(cache=True, nogil=True, inline='always')
def control_box_rational(buf, slot, count, box):
    """Box of the homogenised control points (x/w, y/w, z/w) of a rational patch in `slot`.

    Quotients are formed in float64 (one rounding, at most half an ulp) and each bound is moved
    outward by |bound| * 2^-52 (at least one ulp after its own rounding), so the box contains every
    exact quotient of the stored points; numba has no rounding modes to do it with. With positive
    weights the sub-patch lies in the hull of these points.
    """
    for c in range(3):
        lo = math.inf
        hi = -math.inf
        for k in range(count):
            q = np.float64(buf[slot, c, k]) / np.float64(buf[slot, 3, k])  # numba: float(float32) stays float32
            lo = min(lo, q)
            hi = max(hi, q)
        box[slot, c] = lo - abs(lo) * 2.220446049250313e-16
        box[slot, 3 + c] = hi + abs(hi) * 2.220446049250313e-16


@njit(cache=True, nogil=True, inline='always')
def _restrict_line(pts, c, first, step, deg, t0, t1):
    """The control points of one Bezier curve (pts[c, first + i * step], i = 0..deg) restricted to
    its parameter interval [t0, t1], in place: de Casteljau at t0 keeping the right part, then
    at (t1 - t0) / (1 - t0) keeping the left part."""
    if t0 > 0.0:
        for k in range(1, deg + 1):
            for i in range(deg - k + 1):
                a = pts[c, first + i * step]
                pts[c, first + i * step] = a + t0 * (pts[c, first + (i + 1) * step] - a)
    if t1 < 1.0:
        t = (t1 - t0) / (1.0 - t0)
        for k in range(1, deg + 1):
            for i in range(deg, k - 1, -1):
                a = pts[c, first + (i - 1) * step]
                pts[c, first + i * step] = a + t * (pts[c, first + i * step] - a)


@njit(cache=True, nogil=True, inline='always')
def restrict(pts, m, n, ncoord, u0, u1, v0, v1):
    """Control points of the sub-patch [u0, u1] x [v0, v1] of the patch in pts (ncoord, points),
    in place (float64: a handful of roundings per point, see restrict_err)."""
    stride = m + 1
    if m == 3 and n == 3:  # _restrict_line's lerps, four lines at a time (simd.restrict_cubic)
        for c in range(ncoord):
            simd.restrict_cubic(pts, c, u0, u1, v0, v1)
        return
    if m == 1 and n == 1:  # the lines below with their degree a constant: unrolled (a floor's leaves)
        for c in range(ncoord):
            for j in range(2):
                _restrict_line(pts, c, 2 * j, 1, 1, u0, u1)
            for i in range(2):
                _restrict_line(pts, c, i, 2, 1, v0, v1)
        return
    for c in range(ncoord):
        for j in range(n + 1):
            _restrict_line(pts, c, j * stride, 1, m, u0, u1)
        for i in range(m + 1):
            _restrict_line(pts, c, i, stride, n, v0, v1)


@njit(cache=True, nogil=True, inline='always')
def restrict_err(m, n):
    """Bound on restrict's error relative to the largest |control point|: 2 (m + n) lerps of
    three roundings each, and the rounded t (the interval moves by a few ulps of the parameter;
    derivatives are at most 2 m (2 n) times the largest point)."""
    return (16.0 * (m + n) + 8.0) * 2.0 ** -53


@njit(cache=True, nogil=True, _nrt=False)
def _bernstein_row(deg, t, out):
    """Bernstein polynomials B_i^deg(t), i = 0..deg, by the stable triangular recurrence."""
    out[0] = 1.0
    s = 1.0 - t
    for k in range(1, deg + 1):
        saved = 0.0
        for i in range(k):
            tmp = out[i]
            out[i] = saved + s * tmp
            saved = t * tmp
        out[k] = saved


@njit(cache=True, nogil=True, _nrt=False)
def evaluate(pts, m, n, u, v, ncoord, scratch, out):
    """Point and derivatives of one patch at (u, v), in float64.

    pts: (>= ncoord, points) control points (any float dtype); scratch: (4, >= max degree + 1)
    float64; out: (4, >= ncoord) float64 receives S, dS/du, dS/dv and d2S/dudv per coordinate.
    """
    bu = scratch[0]
    bv = scratch[1]
    du = scratch[2]
    dv = scratch[3]
    m = np.int64(m)  # one compiled _bernstein_row for deg and deg - 1
    n = np.int64(n)
    _bernstein_row(m, u, bu)
    _bernstein_row(n, v, bv)
    if m > 0:
        _bernstein_row(m - 1, u, du)
    if n > 0:
        _bernstein_row(n - 1, v, dv)
    for c in range(ncoord):
        a = pts[c]
        s = 0.0
        for j in range(n + 1):
            for i in range(m + 1):
                s += bu[i] * bv[j] * a[j * (m + 1) + i]
        out[0, c] = s
        tangents(a, m, n, bu, bv, du, dv, c, out)


@njit(cache=True, nogil=True, inline='always')
def tangents(a, m, n, bu, bv, du, dv, c, out):
    """dS/du, dS/dv and d2S/dudv of coordinate c (points a) into out[1:4, c], from the Bernstein
    rows of degrees m, n (bu, bv) and m - 1, n - 1 (du, dv); see evaluate."""
    stride = m + 1
    su = 0.0
    for j in range(n + 1):
        for i in range(m):
            su += du[i] * bv[j] * (a[j * stride + i + 1] - a[j * stride + i])
    out[1, c] = m * su
    sv = 0.0
    for j in range(n):
        for i in range(m + 1):
            sv += bu[i] * dv[j] * (a[(j + 1) * stride + i] - a[j * stride + i])
    out[2, c] = n * sv
    suv = 0.0
    for j in range(n):
        for i in range(m):
            diff = (a[(j + 1) * stride + i + 1] - a[(j + 1) * stride + i]
                    - a[j * stride + i + 1] + a[j * stride + i])
            suv += du[i] * dv[j] * diff
    out[3, c] = m * n * suv


@njit(cache=True, nogil=True, _nrt=False)
def normal_at(pts, m, n, u, v, rational, scratch, d, out):
    """Unit normal dS/du x dS/dv at (u, v) into out (3,), float64.

    Where a derivative vanishes (a patch edge collapsed to a point, as on the
    teapot's lid and bottom) the normal is the limit from inside the patch: the
    vanishing dS/du is replaced by the mixed derivative, signed toward the
    interior. Rational patches (pts rows w x, w y, w z, w) get their Euclidean derivatives
    by the quotient rule. scratch: as for `evaluate`; d: (6, 4) float64 work space.
    Returns False if no normal could be found (a fully degenerate patch).
    """
    evaluate(pts, m, n, u, v, 4 if rational else 3, scratch, d)
    return normal_from(d, u, v, rational, out)


@njit(cache=True, nogil=True, inline='always')
def normal_from(d, u, v, rational, out):
    """normal_at's normal from the derivatives evaluate wrote into d (see normal_at)."""
    if rational:
        # P = S W  =>  S_u = (P_u - S W_u) / W,  S_uv = (P_uv - S_u W_v - S_v W_u - S W_uv) / W
        w = d[0, 3]
        for c in range(3):
            s0 = d[0, c] / w
            s_u = (d[1, c] - s0 * d[1, 3]) / w
            s_v = (d[2, c] - s0 * d[2, 3]) / w
            d[3, c] = (d[3, c] - s_u * d[2, 3] - s_v * d[1, 3] - s0 * d[3, 3]) / w
            d[0, c] = s0
            d[1, c] = s_u
            d[2, c] = s_v
    su = d[4]
    sv = d[5]
    for c in range(3):
        su[c] = d[1, c]
        sv[c] = d[2, c]
    nu = np.sqrt(su[0] * su[0] + su[1] * su[1] + su[2] * su[2])
    nv = np.sqrt(sv[0] * sv[0] + sv[1] * sv[1] + sv[2] * sv[2])
    mixed = np.sqrt(d[3, 0] ** 2 + d[3, 1] ** 2 + d[3, 2] ** 2)
    scale = max(nu, nv, mixed)
    if scale == 0.0:
        return False
    tiny = 1e-7 * scale
    if nu < tiny:
        # S_u(u, v) ~ (v - v_edge) * S_uv near a collapsed v-edge.
        sign = 1.0 if v < 0.5 else -1.0
        for c in range(3):
            su[c] = sign * d[3, c]
    if nv < tiny:
        sign = 1.0 if u < 0.5 else -1.0
        for c in range(3):
            sv[c] = sign * d[3, c]
    cx = su[1] * sv[2] - su[2] * sv[1]
    cy = su[2] * sv[0] - su[0] * sv[2]
    cz = su[0] * sv[1] - su[1] * sv[0]
    length = np.sqrt(cx * cx + cy * cy + cz * cz)
    if not length > 0.0:
        return False
    out[0] = cx / length
    out[1] = cy / length
    out[2] = cz / length
    return True
