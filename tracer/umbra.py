"""Umbra detection (Lukaszewski 2001, 4.6) for free-form surfaces: a point whose every shadow ray
is proven to cross one patch is in the umbra, and none of its light samples is traced.

Lemma 4.3: p is in the umbra of an obstacle Q if the ray from p to the light's centre c meets Q
shrunk by L - c (a negative offset), for the light moved to that meeting point lies inside Q and
every ray from p to L passes through it. Patches are sheets without an inside: their negative
offset is empty. The lemma's conclusion, every segment from the shadow rays' origin o to a point
of L crosses the obstacle, is proven here for one patch P at a time instead:

1. depth: every control point of P lies in front of o (depth along o -> c above a margin) and
   before the light's nearest point, so every crossing lies inside the segment, t in (0, 1),
   where the any-hit search looks;
2. cover: P seen from o (its central projection onto the plane at depth 1) covers the light's
   projection K (a disc for a sphere, a segment, a quadrilateral). P's boundary, four Bezier
   curves (projected: rational curves with the projected control points and positive weights),
   winds around K without meeting it; a continuous map of the square whose boundary winds around
   a point has the point in its image (Brouwer's degree), so every ray from o through K meets P.

The winding number is summed piece by piece: each boundary curve is halved (de Casteljau in
homogeneous coordinates) until the convex hull of each piece's projected control points is
separated from K grown by a margin (separating axes: normals of point pairs within each set and
directions between the sets, complete for convex polygons in the plane); such a piece turns about
K's centre by less than half a turn, exactly the principal difference of its end angles.

The any-hit search never misses a crossing (its boxes hold the true surface: geometry.py), so a
proven point's sample rays would all have been found occluded: penumbra 'umbra' changes no bit of
the image or of the shadow channel (tests/test_umbra.py). Trimmed patches are not candidates (their
surface is not the whole square). Candidates are the scene patches of the leaves whose boxes the
segment o -> c meets, in the scene's BVH, at most MAX_CANDIDATES a point (Lukaszewski tests "only
one object which passed the penumbra detection test": the others rarely pay).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import njit
from .trim_kernel import halve_piece

MAX_CANDIDATES = 8  # scene patches tried per point
MAX_LEVEL = 12      # halvings of a boundary curve before the point is left to its samples
SPHERE, SEGMENT, RECT = 0, 1, 2
GROW = 1e-9         # relative growth of the light and of its projection (beyond rounding)
ROUNDING = 1e-14    # bound on float64 rounding relative to the coordinates' magnitude


@njit(cache=True, nogil=True, _nrt=False)
def _splits(ax, ay, px, py, n, kx, ky, nk, grow):
    """The axis (ax, ay) separates the points (px, py)[:n] from (kx, ky)[:nk] grown by `grow`."""
    length = math.sqrt(ax * ax + ay * ay)
    if not length > 0.0:
        return False
    ax /= length
    ay /= length
    p_lo, p_hi = math.inf, -math.inf
    for i in range(n):
        s = px[i] * ax + py[i] * ay
        p_lo, p_hi = min(p_lo, s), max(p_hi, s)
    k_lo, k_hi = math.inf, -math.inf
    for i in range(nk):
        s = kx[i] * ax + ky[i] * ay
        k_lo, k_hi = min(k_lo, s), max(k_hi, s)
    return p_lo > k_hi + grow or p_hi < k_lo - grow


@njit(cache=True, nogil=True, _nrt=False)
def _separated(px, py, n, kx, ky, nk, grow):
    """The convex hull of (px, py)[:n] is disjoint from that of (kx, ky)[:nk] grown by `grow`."""
    for i in range(n):
        for j in range(i + 1, n):
            if _splits(py[i] - py[j], px[j] - px[i], px, py, n, kx, ky, nk, grow):
                return True
    for i in range(nk):
        for j in range(i + 1, nk):
            if _splits(ky[i] - ky[j], kx[j] - kx[i], px, py, n, kx, ky, nk, grow):
                return True
    for i in range(n):
        for j in range(nk):
            if _splits(px[i] - kx[j], py[i] - ky[j], px, py, n, kx, ky, nk, grow):
                return True
    return False


@njit(cache=True, nogil=True, _nrt=False)
def _project(piece, n, px, py):
    for i in range(n):
        px[i] = piece[i, 0] / piece[i, 2]
        py[i] = piece[i, 1] / piece[i, 2]


@njit(cache=True, nogil=True, _nrt=False)
def _turn(curve, n, kx, ky, nk, grow, cx, cy, stack, level, px, py):
    """(proven, angle): the angle the curve (n homogeneous points X, Y, W) turns about (cx, cy),
    summed over pieces separated from K; not proven where a piece still meets K after MAX_LEVEL
    halvings or a point of the curve lies in K."""
    for i in range(n):
        for c in range(3):
            stack[0, i, c] = curve[i, c]
    level[0] = 0
    top = 1
    angle = 0.0
    while top > 0:
        top -= 1
        piece = stack[top]
        _project(piece, n, px, py)
        if _separated(px, py, n, kx, ky, nk, grow):
            ux, uy = px[0] - cx, py[0] - cy
            vx, vy = px[n - 1] - cx, py[n - 1] - cy
            angle += math.atan2(ux * vy - uy * vx, ux * vx + uy * vy)
            continue
        if level[top] == MAX_LEVEL:
            return False, 0.0
        halve_piece(stack, top, n)
        px[0] = stack[top + 1, 0, 0] / stack[top + 1, 0, 2]
        py[0] = stack[top + 1, 0, 1] / stack[top + 1, 0, 2]
        if not _separated(px, py, 1, kx, ky, nk, grow):
            return False, 0.0  # the curve meets K: this patch does not cover it
        # the left half (at top) is popped after the right one (at top + 1): the order is immaterial
        level[top + 1] = level[top] = level[top] + 1
        top += 2
    return True, angle


@njit(cache=True, nogil=True, _nrt=False)
def _load(points, first, du, dv, g):
    """g[k]: the patch's control points (Euclidean + weight) as homogeneous (w x, w y, w z, w)."""
    for k in range((du + 1) * (dv + 1)):
        w = points[first + k, 3]
        for c in range(3):
            g[k, c] = w * points[first + k, c]
        g[k, 3] = w


@njit(cache=True, nogil=True, _nrt=False)
def _part(work, n, t, left):
    """work[:n] (a Bezier curve's points, 4 coordinates) becomes its part on [0, t] (left) or on
    [t, 1], by de Casteljau in place."""
    for r in range(1, n):
        if left:
            for i in range(n - 1, r - 1, -1):
                for c in range(4):
                    work[i, c] = (1.0 - t) * work[i - 1, c] + t * work[i, c]
        else:
            for i in range(n - r):
                for c in range(4):
                    work[i, c] = (1.0 - t) * work[i, c] + t * work[i + 1, c]


@njit(cache=True, nogil=True, _nrt=False)
def _restrict(g, du, dv, u0, u1, v0, v1, work):
    """The patch g ((dv + 1) rows of du + 1 homogeneous points) restricted to [u0, u1] x [v0, v1]."""
    for line in range(dv + 1 + du + 1):
        along_u = line <= dv
        start, step, n = (line * (du + 1), 1, du + 1) if along_u else (line - dv - 1, du + 1, dv + 1)
        a, b = (u0, u1) if along_u else (v0, v1)
        if a == 0.0 and b == 1.0:
            continue
        for i in range(n):
            for c in range(4):
                work[i, c] = g[start + i * step, c]
        if b < 1.0:
            _part(work, n, b, True)
        if a > 0.0:
            _part(work, n, a / b, False)
        for i in range(n):
            for c in range(4):
                g[start + i * step, c] = work[i, c]


@njit(cache=True, nogil=True, _nrt=False)
def _covers(g, du, dv, o, frame, near, far, kx, ky, nk, grow, cx, cy, reach, s):
    """The patch g ((dv + 1) rows of du + 1 homogeneous world points) lies at depths in (near, far)
    from o and covers K (kx, ky)[:nk] grown by `grow` seen from o: every segment from o to a point
    of K's cone crosses it. frame: rows e1, e2, axis; reach: the coordinates' magnitude (rounding
    margins); s: scratch (_scratch)."""
    grid, curve, stack, level, px, py = s[0], s[1], s[2], s[3], s[4], s[5]
    closest = math.inf
    for k in range((du + 1) * (dv + 1)):
        w = g[k, 3]
        if not w > 0.0:
            return False
        rx, ry, rz = g[k, 0] - w * o[0], g[k, 1] - w * o[1], g[k, 2] - w * o[2]
        z = (rx * frame[2, 0] + ry * frame[2, 1] + rz * frame[2, 2]) / w
        if not near < z < far:
            return False
        closest = min(closest, z)
        grid[k, 0] = rx * frame[0, 0] + ry * frame[0, 1] + rz * frame[0, 2]
        grid[k, 1] = rx * frame[1, 0] + ry * frame[1, 1] + rz * frame[1, 2]
        grid[k, 2] = w * z
    grow = grow + ROUNDING * reach / closest  # the projection's rounding
    total = 0.0
    for side in range(4):  # the boundary loop: v = 0, u = 1, v = 1 backwards, u = 0 backwards
        n = du + 1 if side % 2 == 0 else dv + 1
        for i in range(n):
            if side == 0:
                k = i
            elif side == 1:
                k = i * (du + 1) + du
            elif side == 2:
                k = dv * (du + 1) + du - i
            else:
                k = (dv - i) * (du + 1)
            for c in range(3):
                curve[i, c] = grid[k, c]
        proven, angle = _turn(curve, n, kx, ky, nk, grow, cx, cy, stack, level, px, py)
        if not proven:
            return False
        total += angle
    winding = round(total / (2.0 * math.pi))
    return winding != 0 and abs(total - 2.0 * math.pi * winding) < 0.5


@njit(cache=True, nogil=True, _nrt=False)
def _light_view(o, centre, kind, radius, corners, frame, kx, ky, reach):
    """Seen from o: (usable, nk, grow, far, cx, cy, d): K's points (kx, ky)[:nk] grown by `grow` (a
    disc: its centre and radius; a segment or rectangle: its corners), the light's nearest depth
    (less a margin), K's centre and the distance to the light's centre; frame gets e1, e2 and the
    axis o -> centre."""
    ax, ay, az = centre[0] - o[0], centre[1] - o[1], centre[2] - o[2]
    d = math.sqrt(ax * ax + ay * ay + az * az)
    if not d > 0.0:
        return False, 0, 0.0, 0.0, 0.0, 0.0, 0.0
    ax, ay, az = ax / d, ay / d, az / d
    hx, hy, hz = (1.0, 0.0, 0.0) if abs(ax) < 0.6 else (0.0, 1.0, 0.0)
    ux, uy, uz = ay * hz - az * hy, az * hx - ax * hz, ax * hy - ay * hx
    length = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / length, uy / length, uz / length
    frame[0, 0], frame[0, 1], frame[0, 2] = ux, uy, uz
    frame[1, 0], frame[1, 1], frame[1, 2] = ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux
    frame[2, 0], frame[2, 1], frame[2, 2] = ax, ay, az
    slack = ROUNDING * reach
    if kind == SPHERE:
        r = radius * (1.0 + GROW) + slack
        if not d > r * (1.0 + GROW):
            return False, 0, 0.0, 0.0, 0.0, 0.0, 0.0
        kx[0], ky[0] = 0.0, 0.0
        return True, 1, r / math.sqrt(d * d - r * r), d - r, 0.0, 0.0, d
    nk = 2 if kind == SEGMENT else 4
    far = math.inf
    cx = cy = extent = 0.0
    for j in range(nk):
        rx, ry, rz = corners[j, 0] - o[0], corners[j, 1] - o[1], corners[j, 2] - o[2]
        z = rx * ax + ry * ay + rz * az
        if not z > slack:
            return False, 0, 0.0, 0.0, 0.0, 0.0, 0.0
        far = min(far, z - slack)
        kx[j] = (rx * frame[0, 0] + ry * frame[0, 1] + rz * frame[0, 2]) / z
        ky[j] = (rx * frame[1, 0] + ry * frame[1, 1] + rz * frame[1, 2]) / z
        cx += kx[j] / nk
        cy += ky[j] / nk
    for j in range(nk):
        extent = max(extent, abs(kx[j] - cx) + abs(ky[j] - cy))
    return True, nk, GROW * (1.0 + extent) + slack / far, far, cx, cy, d


@njit(cache=True, nogil=True, _nrt=False)
def _candidate(points, first, du, dv, param, o, frame, near, far, kx, ky, nk, grow, cx, cy, reach, s, whole):
    """Whether the patch (if whole) or one of the parameter squares of half width 1/4, 1/8, 1/16
    about the leaf's centre (param: its u0 u1 v0 v1) covers the light seen from o."""
    g = s[7]
    for half in (0.0, 0.25, 0.125, 0.0625):
        if half == 0.0 and not whole:
            continue
        _load(points, first, du, dv, g)
        if half > 0.0:
            uc, vc = 0.5 * (param[0] + param[1]), 0.5 * (param[2] + param[3])
            _restrict(g, du, dv, max(0.0, uc - half), min(1.0, uc + half), max(0.0, vc - half),
                      min(1.0, vc + half), s[6])
        if _covers(g, du, dv, o, frame, near, far, kx, ky, nk, grow, cx, cy, reach, s):
            return True
    return False


@njit(cache=True, nogil=True, _nrt=False)
def proven_umbra(origins, ask, centre, kind, radius, corners, node_box, node_child, node_leaf, leaf_patch,
                 leaf_param, candidate, points, point_start, deg_u, deg_v, out, nodes, tried, frame, kx, ky, s):
    """out[i]: a scene patch that every shadow ray from origins[i] to the light crosses (see the
    module docstring), -1 where none is found or not ask[i]. The light: kind (SPHERE: centre and
    radius; SEGMENT, RECT: corners (2 or 4, 3) in order around it). Candidates: the leaves (BVH
    nodes node_box, node_child, node_leaf) whose boxes the segment from the origin to the centre
    meets, but those holding the origin, of untrimmed scene patches (leaf_patch, candidate): the
    whole patch once, and squares about the leaf (leaf_param). nodes, tried, frame, kx, ky, s: scratch."""
    for i in range(origins.shape[0]):
        out[i] = -1
        if not ask[i]:
            continue
        o = origins[i]
        reach = 0.0
        for c in range(3):
            reach = max(reach, abs(o[c]), abs(centre[c]) + radius)
            for j in range(corners.shape[0]):
                reach = max(reach, abs(corners[j, c]))
        usable, nk, grow, far, cx, cy, d = _light_view(o, centre, kind, radius, corners, frame, kx, ky, reach)
        if not usable:
            continue
        near = GROW * d + ROUNDING * reach
        far = far - GROW * d - ROUNDING * reach
        n_patches = n_leaves = 0
        top = 1
        nodes[0] = 0
        while top > 0 and out[i] < 0 and n_leaves < MAX_CANDIDATES:
            top -= 1
            node = nodes[top]
            t_in, t_out = 0.0, 1.0
            for c in range(3):
                dc = centre[c] - o[c]
                lo, hi = node_box[node, c] - o[c], node_box[node, 3 + c] - o[c]
                if dc == 0.0:
                    if lo > 0.0 or hi < 0.0:
                        t_in = 2.0
                    continue
                a, b = lo / dc, hi / dc
                if a > b:
                    a, b = b, a
                t_in, t_out = max(t_in, a), min(t_out, b)
            if t_in > t_out:
                continue
            if node_child[node, 0] >= 0:
                nodes[top] = node_child[node, 0]
                nodes[top + 1] = node_child[node, 1]
                top += 2
                continue
            leaf = node_leaf[node]
            p = leaf_patch[leaf]
            holds = True  # a leaf around the origin (its own surface) cannot lie wholly before it
            for c in range(3):
                holds = holds and node_box[node, c] <= o[c] <= node_box[node, 3 + c]
            if holds or not candidate[p]:
                continue
            whole = True  # the whole patch is tried with its first leaf, squares about each leaf
            for k in range(n_patches):
                whole = whole and tried[k] != p
            if whole:
                tried[n_patches] = p
                n_patches += 1
            n_leaves += 1
            if _candidate(points, point_start[p], deg_u[p], deg_v[p], leaf_param[leaf], o, frame, near, far, kx, ky, nk,
                          grow, cx, cy, reach, s, whole):
                out[i] = p


def _scratch(max_points: int, max_degree: int):
    """proven_umbra's scratch s: the projected patch, a boundary curve, the halving stack and its
    levels, projected points (x, y), de Casteljau's work row, the patch."""
    n = max_degree + 1
    return (np.zeros((max_points, 3)), np.zeros((n, 3)), np.zeros((MAX_LEVEL + 2, n, 3)),
            np.zeros(MAX_LEVEL + 2, np.int64), np.zeros(n), np.zeros(n), np.zeros((n, 4)), np.zeros((max_points, 4)))


def light_shape(light):
    """(kind, centre (3,), radius, corners (k, 3)) of an area light for proven_umbra."""
    centre = np.asarray(light.centre(), np.float64)
    if light.type == "sphere":
        return SPHERE, centre, float(light.radius), np.zeros((1, 3))
    if light.type == "segment":
        return SEGMENT, centre, 0.0, np.array([light.a, light.b], np.float64)
    c, e1, e2 = (np.asarray(v, np.float64) for v in (light.corner, light.edge1, light.edge2))
    return RECT, centre, 0.0, np.array([c, c + e1, c + e1 + e2, c + e2])


class UmbraTest:
    """Umbra detection over one scene and its geometry's BVH: candidates are the untrimmed scene
    patches with positive weights."""

    def __init__(self, scene, geom):
        self.points = np.ascontiguousarray(scene.points, np.float64)
        self.start = np.asarray(scene.point_start, np.int64)
        self.deg_u = np.asarray(scene.degree_u, np.int64)
        self.deg_v = np.asarray(scene.degree_v, np.int64)
        n = len(self.deg_u)
        trimmed = np.zeros(n, bool)
        trimmed[np.asarray(geom.leaf_patch)[np.asarray(geom.patch_trim) >= 0]] = True
        positive = np.minimum.reduceat(self.points[:, 3], self.start[:-1]) > 0.0
        self.candidate = ~trimmed & positive
        bvh = geom.bvh
        self.bvh = (np.ascontiguousarray(bvh.node_box), np.ascontiguousarray(bvh.node_child),
                    np.asarray(bvh.node_patch, np.int64), np.asarray(geom.leaf_patch, np.int64))
        self.param = np.ascontiguousarray(geom.leaf_param, np.float64)
        self.stack = bvh.depth + 2
        self.sizes = (int(np.max(np.diff(self.start))), int(max(self.deg_u.max(), self.deg_v.max())))

    def __call__(self, light, origins: np.ndarray, ask: np.ndarray) -> np.ndarray:
        """(m,) int64: per origin (m, 3) a scene patch proven to occlude all of `light`, -1: none."""
        kind, centre, radius, corners = light_shape(light)
        out = np.full(len(origins), -1, np.int64)
        if ask.any():
            node_box, node_child, node_leaf, leaf_patch = self.bvh
            proven_umbra(np.ascontiguousarray(origins, np.float64), np.ascontiguousarray(ask), centre, kind,
                         radius, corners, node_box, node_child, node_leaf, leaf_patch, self.param, self.candidate,
                         self.points, self.start, self.deg_u, self.deg_v, out, np.zeros(2 * self.stack, np.int64),
                         np.zeros(MAX_CANDIDATES, np.int64), np.zeros((3, 3)), np.zeros(4), np.zeros(4),
                         _scratch(*self.sizes))
        return out
