"""Trimming in the kernel: is a surface parameter point in the kept region?

Ray parity against the surface's loops of (rational) Bezier segments, with
curve subdivision where the answer is not yet clear (Dammertz 2.6): a piece
left of the point, wholly above or wholly below it crosses nothing; a piece
wholly right of it crosses the ray as often as its ends lie on different sides;
otherwise it is halved, until its box stops shrinking. This mirrors the
reference `tracer.trim.segment_parity` step for step, in float64.

Trim arrays (tracer.trim.TrimSet): seg_points (S, 3) u v w (Euclidean + weight),
seg_start (n_segs + 1,), surf_seg_start (n_surfaces + 1,), start_inside (n_surfaces,) int8,
and seg_box (n_segs, 4): u0 u1 v0 v1 of each segment's control points (its curve lies inside).
Scratch: stack_h (D, P, 3) homogeneous pieces, stack_m (D, 6) per piece: end a (u, v),
end b (u, v), parent diameter, depth; D >= MAX_SPLIT_DEPTH + 2, P >= max segment points.
"""
from __future__ import annotations

import math

import numpy as np
from .jit import njit

MAX_SPLIT_DEPTH = 96  # as tracer.trim: float64 boxes stop shrinking long before this


@njit(cache=True, nogil=True, inline='always')
def halve_piece(stack_h, top, n):
    """de Casteljau at t = 1/2 of the curve stack_h[top, :n] (homogeneous points, 3 coordinates):
    its left half stays in `top`, the right one goes to `top + 1`."""
    right = top + 1
    for c in range(3):
        stack_h[right, n - 1, c] = stack_h[top, n - 1, c]
    for k in range(1, n):
        for i in range(n - 1, k - 1, -1):
            for c in range(3):
                stack_h[top, i, c] = 0.5 * stack_h[top, i - 1, c] + 0.5 * stack_h[top, i, c]
        for c in range(3):
            stack_h[right, n - 1 - k, c] = stack_h[top, n - 1, c]


@njit(cache=True, nogil=True, inline='always')
def _halve(stack_h, stack_m, top, n, diam):
    """Halve the piece at `top` at t = 1/2 (halve_piece); both halves remember `diam` as their
    parent's diameter and one more level of depth."""
    bu = stack_m[top, 2]
    bv = stack_m[top, 3]
    right = top + 1
    halve_piece(stack_h, top, n)
    mu = stack_h[top, n - 1, 0] / stack_h[top, n - 1, 2]
    mv = stack_h[top, n - 1, 1] / stack_h[top, n - 1, 2]
    depth = stack_m[top, 5] + 1.0
    stack_m[right, 0] = mu
    stack_m[right, 1] = mv
    stack_m[right, 2] = bu
    stack_m[right, 3] = bv
    stack_m[right, 4] = diam
    stack_m[right, 5] = depth
    stack_m[top, 2] = mu
    stack_m[top, 3] = mv
    stack_m[top, 4] = diam
    stack_m[top, 5] = depth


@njit(cache=True, nogil=True, inline='always')
def _load_segment(seg_points, first, last, stack_h, stack_m):
    """The segment as the first piece of the stack: homogeneous points, ends exactly as stored
    (shared by neighbours), no parent diameter yet, depth 0. Returns its point count."""
    n = last - first
    for k in range(n):
        w = seg_points[first + k, 2]
        stack_h[0, k, 0] = seg_points[first + k, 0] * w
        stack_h[0, k, 1] = seg_points[first + k, 1] * w
        stack_h[0, k, 2] = w
    stack_m[0, 0] = seg_points[first, 0]
    stack_m[0, 1] = seg_points[first, 1]
    stack_m[0, 2] = seg_points[last - 1, 0]
    stack_m[0, 3] = seg_points[last - 1, 1]
    stack_m[0, 4] = math.inf
    stack_m[0, 5] = 0.0
    return n


@njit(cache=True, nogil=True, inline='always')
def _piece_box(stack_h, stack_m, top, n):
    """u0, u1, v0, v1 of the piece's control points (its curve lies inside: positive weights)."""
    au, av, bu, bv = stack_m[top, 0], stack_m[top, 1], stack_m[top, 2], stack_m[top, 3]
    umin = min(au, bu)
    umax = max(au, bu)
    vmin = min(av, bv)
    vmax = max(av, bv)
    for k in range(1, n - 1):
        pu = stack_h[top, k, 0] / stack_h[top, k, 2]
        pv = stack_h[top, k, 1] / stack_h[top, k, 2]
        umin = min(umin, pu)
        umax = max(umax, pu)
        vmin = min(vmin, pv)
        vmax = max(vmax, pv)
    return umin, umax, vmin, vmax


@njit(cache=True, nogil=True, _nrt=False)
def _segment_parity(seg_points, first, last, u, v, stack_h, stack_m):
    """0 or 1: parity of the crossings of the ray from (u, v) towards +u with one segment."""
    n = _load_segment(seg_points, first, last, stack_h, stack_m)
    odd = 0
    top = 1
    while top > 0:
        top -= 1
        umin, umax, vmin, vmax = _piece_box(stack_h, stack_m, top, n)
        if umax < u or vmin >= v or vmax < v:  # left of the point, wholly above, wholly below
            continue
        flip = 1 if (stack_m[top, 1] >= v) != (stack_m[top, 3] >= v) else 0
        diam = (umax - umin) + (vmax - vmin)
        if umin > u or diam >= stack_m[top, 4] or stack_m[top, 5] >= MAX_SPLIT_DEPTH:
            odd ^= flip  # wholly right of the point, or the precision is spent
            continue
        _halve(stack_h, stack_m, top, n, diam)
        top += 2
    return odd


@njit(cache=True, nogil=True, _nrt=False)
def trim_inside(surface, u, v, seg_points, seg_start, surf_seg_start, start_inside, stack_h, stack_m):
    """Is (u, v) (surface parameters) in the kept region of `surface`'s trimming loops?"""
    odd = int(start_inside[surface])
    for s in range(surf_seg_start[surface], surf_seg_start[surface + 1]):
        odd ^= _segment_parity(seg_points, seg_start[s], seg_start[s + 1], u, v, stack_h, stack_m)
    return odd != 0


@njit(cache=True, nogil=True, _nrt=False)
def _segment_meets_rect(seg_points, first, last, u0, u1, v0, v1, stack_h, stack_m):
    """Could one segment pass through the rectangle? A piece whose control box misses it is
    dropped, one whose box lies inside it says yes; the others are halved until they are no
    larger than the rectangle or stop shrinking (then: perhaps, so yes)."""
    n = _load_segment(seg_points, first, last, stack_h, stack_m)
    size = (u1 - u0) + (v1 - v0)
    top = 1
    while top > 0:
        top -= 1
        umin, umax, vmin, vmax = _piece_box(stack_h, stack_m, top, n)
        if umax < u0 or umin > u1 or vmax < v0 or vmin > v1:
            continue
        diam = (umax - umin) + (vmax - vmin)
        inside = umin >= u0 and umax <= u1 and vmin >= v0 and vmax <= v1
        if inside or diam <= size or diam >= stack_m[top, 4] or stack_m[top, 5] >= MAX_SPLIT_DEPTH:
            return True
        _halve(stack_h, stack_m, top, n, diam)
        top += 2
    return False


@njit(cache=True, nogil=True, _nrt=False)
def rect_meets_loops(surface, u0, u1, v0, v1, seg_points, seg_start, surf_seg_start, seg_box, stack_h, stack_m):
    """Could a trimming curve of `surface` pass through the parameter rectangle? If not, the whole
    rectangle is on one side of every loop: one parity test at any point classifies all of it.

    Segments whose control box meets the rectangle are halved until their pieces miss it: with
    the segments' boxes alone, a sub-patch near a long trimming curve stayed undecided down to
    the precision limit, and every box it left was classified alone (the float64 reference spent
    millions of boxes on a ray through a trimmed-away part of the IGES impeller)."""
    pad = (max(abs(u0), abs(u1)) + max(abs(v0), abs(v1))) * 2.0 ** -48  # the halving's rounding
    u0 -= pad
    u1 += pad
    v0 -= pad
    v1 += pad
    for s in range(surf_seg_start[surface], surf_seg_start[surface + 1]):
        if seg_box[s, 1] >= u0 and seg_box[s, 0] <= u1 and seg_box[s, 3] >= v0 and seg_box[s, 2] <= v1:
            if _segment_meets_rect(seg_points, seg_start[s], seg_start[s + 1], u0, u1, v0, v1, stack_h, stack_m):
                return True
    return False


def segment_boxes(seg_points: np.ndarray, seg_start: np.ndarray) -> np.ndarray:
    """(n_segs, 4) u0 u1 v0 v1 of each segment's control points."""
    n = len(seg_start) - 1
    box = np.zeros((n, 4))
    for s in range(n):
        pts = seg_points[seg_start[s]:seg_start[s + 1], :2]
        box[s] = (pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max())
    return box


def trim_scratch(max_points: int):
    """Scratch for trim_inside."""
    return np.zeros((MAX_SPLIT_DEPTH + 4, max(max_points, 2), 3)), np.zeros((MAX_SPLIT_DEPTH + 4, 6))
