"""The subdivision search: against exact planes, known surface points, an independent float64
intersection, the documented termination criteria, the pixel trace, and float32 against
float64 on small teapot images."""
import functools
import math
from fractions import Fraction

import numpy as np
import pytest

import reference as ref
import scenes as S
from tracer.camera import View
from tracer.geometry import prepare
from tracer.options import Options
from tracer.camera import primary_rays
from tracer.render import reference_frame, render, trace_rays
from tracer.trace_one import trace_pixel

PRECISIONS = ("f32", "f64")
BITS = {"f32": 24, "f64": 53}


def affine_patch(corner, e1, e2, m=3, n=3):
    """P[i, j] = corner + (i/m) e1 + (j/n) e2: a flat patch parametrised linearly."""
    i = np.arange(m + 1)[:, None, None] / m
    j = np.arange(n + 1)[None, :, None] / n
    return np.asarray(corner, float) + i * np.asarray(e1, float) + j * np.asarray(e2, float)


def random_directions(rng, count):
    d = rng.normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def exact_plane_hit(o, d, corner, e1, e2):
    """(t, a, b) with o + t d = corner + a e1 + b e2, in exact rational arithmetic (Cramer)."""
    cols = [[Fraction(x) for x in e1], [Fraction(x) for x in e2], [-Fraction(x) for x in d]]
    rhs = [Fraction(o[k]) - Fraction(corner[k]) for k in range(3)]

    def det(c0, c1, c2):
        return (c0[0] * (c1[1] * c2[2] - c1[2] * c2[1]) - c1[0] * (c0[1] * c2[2] - c0[2] * c2[1])
                + c2[0] * (c0[1] * c1[2] - c0[2] * c1[1]))

    full = det(*cols)
    a = det(rhs, cols[1], cols[2]) / full
    b = det(cols[0], rhs, cols[2]) / full
    t = det(cols[0], cols[1], rhs) / full
    return t, a, b


# ---- flat patches against the exact plane ------------------------------------------------

# Dyadic corners and edges (thirds of the edges dyadic too): every control point, the frame
# origin and the local coordinates are exact in float32, so both precisions trace the same plane.
FLAT = {
    "z-plane": ((-1.0, -1.0, 0.75), (3 * 0.6875, 0.0, 0.0), (0.0, 3 * 0.625, 0.0)),
    "x-plane offset": ((2.5, 1.0, 2.0), (0.0, 3 * 0.5, 0.0), (0.0, 0.0, 3 * 0.75)),
    "tilted": ((-0.5, 0.25, 1.0), (3 * 0.5, 3 * 0.125, 3 * 0.25), (3 * -0.125, 3 * 0.5, 3 * 0.1875)),
    "tilted far": ((1000.5, -2000.25, 500.0), (3 * 0.5, 3 * 0.125, 3 * 0.25), (3 * -0.125, 3 * 0.5, 3 * 0.375)),
}


@functools.lru_cache(maxsize=None)
def flat_rays(name, precision):
    """Random rays at the flat patch FLAT[name]: 3/4 aimed inside, 1/4 beyond an edge. Returns
    per-ray arrays: exact (a, b) and point (rational plane hit, rounded), |cos| to the normal, and
    the kernel's hit, box and position."""
    corner, e1, e2 = (np.array(x) for x in FLAT[name])
    P = affine_patch(corner, e1, e2)
    assert np.array_equal(P, ref.round32(P))
    scene = S.patches_scene([P])
    rng = np.random.default_rng(sum(map(ord, name)))
    count = 400
    ab = rng.uniform(0.01, 0.99, (count, 2))
    outside = rng.uniform(size=count) < 0.25
    k = int(outside.sum())
    ab[outside] = (rng.uniform(0.01, 0.5, (k, 2)) * np.where(rng.uniform(size=(k, 2)) < 0.5, -1, 1)
                   + (rng.uniform(size=(k, 2)) < 0.5))  # some beyond an edge by 0.01 .. 0.5
    targets = corner + ab[:, :1] * e1 + ab[:, 1:] * e2
    normal = np.cross(e1, e2)
    normal /= np.linalg.norm(normal)
    dirs = random_directions(rng, count)
    dirs[np.abs(dirs @ normal) < 0.1] = normal  # keep away from rays inside the plane
    origins = targets - 3.0 * dirs * rng.uniform(0.5, 3.0, (count, 1))
    d = targets - origins
    frame = S.trace(scene, origins, d, Options(precision=precision))
    exact_ab, points, ts = np.zeros((count, 2)), np.zeros((count, 3)), np.zeros(count)
    for k in range(count):
        t, a, b = exact_plane_hit(origins[k], d[k], corner, e1, e2)
        exact_ab[k] = float(a), float(b)
        ts[k] = float(t)
        points[k] = [float(Fraction(origins[k, c]) + t * Fraction(d[k, c])) for c in range(3)]
    centre = 0.5 * (P.reshape(-1, 3).min(0) + P.reshape(-1, 3).max(0))
    return dict(ab=exact_ab, t=ts, point=points, origin=origins, dir=d, cos=np.abs(d @ normal) / np.linalg.norm(d, axis=1),
                hit=frame.hit[0], lo=frame.box_min[0], hi=frame.box_max[0], pos=frame.position[0],
                local_size=np.abs(P - centre).max())


def _inner(r):
    return np.all((r["ab"] >= 0) & (r["ab"] <= 1), axis=1) & (r["t"] >= 0)


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("name", list(FLAT))
def test_flat_patch_hits_and_misses(name, precision):
    """Rays at points of a flat patch hit it; rays at points clearly beyond an edge miss."""
    r = flat_rays(name, precision)
    inner = _inner(r)
    margin = np.minimum(r["ab"], 1 - r["ab"]).min(axis=1)
    assert inner.sum() > 250
    assert np.all(r["hit"][inner]), f"missed at (a, b) = {r['ab'][inner & ~r['hit']].tolist()}"
    clearly_out = ~inner & (margin < -1e-3)
    assert np.all(~r["hit"][clearly_out]), f"hit outside at (a, b) = {r['ab'][clearly_out & r['hit']].tolist()}"


def outside_by(r, bits):
    """Per ray: how far the exact point lies outside the hit box, in ulps of the box corners
    (the kernel's measure, per coordinate, maximum over coordinates)."""
    lo, hi, p = r["lo"], r["hi"], r["point"]
    out = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    unit = ref.ulp(np.maximum(np.abs(lo), np.abs(hi)), bits)
    return np.where(out > 0, out / np.where(unit > 0, unit, np.inf), 0.0).max(axis=1)


@pytest.mark.parametrize("name", list(FLAT))
def test_flat_patch_box_contains_plane_point_f32(name):
    """Float32: the exact rational plane intersection lies inside the hit box widened by
    4 float32 ulps per coordinate (ulp of max(|lo|, |hi|), the kernel's mantissa measure)."""
    r = flat_rays(name, "f32")
    inner = _inner(r)
    out = outside_by(r, 24)[inner]
    worst = int(np.argmax(out))
    assert out.max() <= 4.0, (f"{np.mean(out > 4):.1%} of the rays outside by more than 4 ulps; worst "
                              f"{out[worst]:.1f} ulps: point {r['point'][inner][worst].tolist()}, box "
                              f"{r['lo'][inner][worst].tolist()} .. {r['hi'][inner][worst].tolist()}")


@pytest.mark.parametrize("name", list(FLAT))
def test_flat_patch_box_near_plane_point_f32(name):
    """What the float32 search guarantees today, in the object's terms: the exact point is within
    2 ulps of the object's local size, times 1 + 1/cos(angle to the normal), of the hit box (the
    box is about an ulp wide and the ray may cross it that far from the surface)."""
    r = flat_rays(name, "f32")
    inner = _inner(r)
    lo, hi, p = r["lo"][inner], r["hi"][inner], r["point"][inner]
    out = np.maximum(np.maximum(lo - p, p - hi), 0.0).max(axis=1)
    allowed = 2 * ref.ulp(r["local_size"]) * (1 + 1 / r["cos"][inner])
    assert np.all(out <= allowed), f"worst {np.max(out / allowed):.2f} x allowed"


@pytest.mark.parametrize("name", list(FLAT))
def test_flat_patch_box_contains_plane_point_f64(name):
    """Float64: boxes are a few tens of float64 ulps of the patch wide at most, and the exact point is within
    box width / cos(angle to the normal) of the box (the ray may cross the box that far from the
    plane) plus 16 ulps of the ray's scale |origin| + t |d| (the slab test's resolution)."""
    r = flat_rays(name, "f64")
    inner = _inner(r)
    lo, hi, p = r["lo"][inner], r["hi"][inner], r["point"][inner]
    width = (hi - lo).max(axis=1)
    size_ulp = ref.ulp(r["local_size"], 53) + ref.ulp(np.abs(p).max(axis=1), 53)  # local, and world rounding
    assert np.all(width <= 64 * size_ulp), f"widest {np.max(width / size_ulp):.1f} ulps"
    out = np.maximum(np.maximum(lo - p, p - hi), 0.0).max(axis=1)
    scale = np.abs(r["origin"][inner]).max(axis=1) + r["t"][inner] * np.linalg.norm(r["dir"][inner], axis=1)
    allowed = width / r["cos"][inner] + 16 * ref.ulp(scale, 53)
    assert np.all(out <= allowed), f"worst {np.max(out / allowed):.2f} x allowed"


@pytest.mark.parametrize("name", list(FLAT))
def test_flat_patch_position_f32(name):
    """Float32: the reported position (box centre) is within 4 ulps of the exact point's largest
    coordinate (the float criterion stops when the L1 size stalls, so that is its scale) times
    1 + 1/cos(angle to the normal)."""
    r = flat_rays(name, "f32")
    inner = _inner(r)
    err = np.abs(r["pos"] - r["point"])[inner].max(axis=1)
    unit = ref.ulp(np.abs(r["point"][inner]).max(axis=1))
    allowed = 4 * unit * (1 + 1 / r["cos"][inner])
    assert np.all(err <= allowed), f"worst {np.max(err / unit):.1f} ulps"


# ---- rays aimed at known surface points -------------------------------------------------------

def known_point_patches():
    rng = np.random.default_rng(7)
    out = [("smooth 3x3", S.smooth_patch(rng, 3, 3)), ("smooth 5x4", S.smooth_patch(rng, 5, 4)),
           ("smooth 9x7", S.smooth_patch(rng, 9, 7)), ("loop 3x3", S.loop_patch(rng)),
           ("far 3x3", S.smooth_patch(rng, 3, 3) + 1e4)]
    return out


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("case", range(len(known_point_patches())))
def test_rays_at_known_points_hit_no_farther(case, precision):
    """A ray from `origin` to a surface point S(u, v) (of the patch as stored in the working
    precision, so the target lies on the surface the kernel sees) reports a hit at t <= 1 up to
    the box size; a clearly nearer hit must be a real intersection (checked with the reference)."""
    name, P = known_point_patches()[case]
    scene = S.patches_scene([P])
    geom = prepare(scene, precision, presplit=0)  # one leaf: the patch exactly as stored
    Ps = ref.grid(geom.patch_points(0), P.shape[0] - 1, P.shape[1] - 1)
    rng = np.random.default_rng(100 + case)
    count = 120
    uv = rng.uniform(0.02, 0.98, (count, 2))
    targets = np.array([ref.evaluate(Ps, u, v) for u, v in uv])
    normals = np.array([ref.normal(Ps, u, v) for u, v in uv])
    dirs = random_directions(rng, count)
    steep = np.abs((dirs * normals).sum(1)) >= 0.2  # not grazing: t is well conditioned
    origins = targets - 4.0 * dirs
    d = targets - origins
    frame = S.trace(geom, origins, d, Options(precision=precision))
    scale = np.abs(Ps - Ps.mean(axis=(0, 1))).max()
    # in t (|d| = 4): a few ulps of the patch in the working precision, and of the world
    # coordinates in float64 (the target and the ray are formed there)
    tol = 64 * (ref.ulp(scale, BITS[precision]) + ref.ulp(np.abs(Ps).max(), 53)) / 4.0
    nearer = 0
    for k in np.nonzero(steep)[0]:
        assert frame.hit[0, k], f"{name} ray {k} aimed at S{tuple(uv[k])} missed"
        t = frame.t[0, k]
        assert t <= 1 + tol, f"{name} ray {k}: hit at t = {t!r} beyond the target (t = 1, tol {tol:.2e})"
        if t < 1 - tol:
            nearer += 1
            r = ref.intersect_patch(Ps, origins[k], d[k])
            assert r.hit and r.t < 1 - tol / 2, f"{name} ray {k}: hit at t = {t} but nothing nearer than 1"
            assert abs(r.t - t) <= 2 * tol or not r.certain, f"{name} ray {k}: t = {t}, reference {r.t}"
    assert steep.sum() > 50


# ---- float64 kernel against the independent reference ---------------------------------------

def reference_patches():
    rng = np.random.default_rng(11)
    return [S.smooth_patch(rng, 3, 3), S.loop_patch(rng), S.random_patch(rng),
            S.smooth_patch(rng, 9, 7), S.random_patch(rng, 4, 2)]


@pytest.mark.parametrize("case", range(5))
def test_float64_kernel_matches_independent_reference(case):
    """Random rays through the patch's box: hit or miss and the hit distance agree with the
    Newton/subdivision reference wherever that reference is certain of its answer."""
    P = reference_patches()[case]
    scene = S.patches_scene([P])
    rng = np.random.default_rng(200 + case)
    lo, hi = P.reshape(-1, 3).min(0), P.reshape(-1, 3).max(0)
    count = 60
    targets = rng.uniform(lo, hi, (count, 3))
    origins = targets - 2.5 * np.linalg.norm(hi - lo) * random_directions(rng, count)
    d = targets - origins
    frame = S.trace(scene, origins, d, Options(precision="f64"))
    checked = 0
    for k in range(count):
        r = ref.intersect_patch(P, origins[k], d[k])
        if not r.certain:
            continue
        checked += 1
        assert frame.hit[0, k] == r.hit, f"ray {k}: kernel hit={frame.hit[0, k]}, reference hit={r.hit}"
        if r.hit:
            assert frame.t[0, k] == pytest.approx(r.t, rel=1e-9, abs=1e-9), f"ray {k}"
            assert np.abs(frame.position[0, k] - r.point).max() <= 1e-9 * (1 + np.abs(r.point).max())
    assert checked >= count * 0.8


def test_reference_frame_matches_independent_reference_on_teapot():
    """The float64 reference every image test trusts, checked on every pixel of a small side
    view of the teapot (silhouettes included) against the independent intersection."""
    scene = S.teapot()
    grids = S.grids_of(scene)
    frame = render(scene, Options(precision="f64"), size=(24, 24), view=S.SIDE_VIEW)
    pixels = np.argwhere(np.ones(frame.hit.shape, bool))
    checked = 0
    for y, x in pixels:
        o, d = frame.ray_origin[y, x], frame.ray_dir[y, x]
        near = [P for P in grids if ref.slab_exact(ref.box(P), o, d)[0]]  # control boxes the ray meets
        r = ref.intersect_scene(near, o, d)
        if not r.certain:
            continue
        checked += 1
        assert frame.hit[y, x] == r.hit, (x, y)
        if r.hit:
            assert frame.t[y, x] == pytest.approx(r.t, rel=1e-9), (x, y)
            assert np.abs(frame.position[y, x] - r.point).max() <= 1e-9
    assert checked >= 0.9 * len(pixels)


SEAM_PLANE_VIEWS = [View((10.0, 0.0, 1.5), (0.0, 0.0, 1.5), (0.0, 0.0, 1.0), 40.0),
                    View((0.0, -10.0, 1.5), (0.0, 0.0, 1.5), (0.0, 0.0, 1.0), 40.0),
                    View((0.0, 0.0, 10.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 40.0),
                    View((0.0, 0.0, -10.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), 40.0)]


@pytest.mark.parametrize("view", SEAM_PLANE_VIEWS, ids=["+x", "-y", "top", "bottom"])
def test_rays_in_seam_planes(view):
    """Axis-aligned views with an odd image width: the middle column's rays have a zero
    direction component (the middle ray two) and run exactly in the planes x = 0 or y = 0 where
    the teapot's patches meet (and through the lid and bottom apexes). Both precisions agree with the independent
    reference there, and float32 with float64 everywhere."""
    scene = S.teapot()
    grids = S.grids_of(scene)
    frame = render(scene, Options(), size=(33, 33), view=view)
    refr = reference_frame(scene, frame)
    assert np.all((frame.ray_dir[:, 16] == 0).any(axis=1))
    assert np.array_equal(frame.hit, refr.hit)
    for y in range(33):
        o, d = frame.ray_origin[y, 16], frame.ray_dir[y, 16]
        r = ref.intersect_scene([P for P in grids if ref.slab_exact(ref.box(P), o, d)[0]], o, d)
        if r.certain:
            assert frame.hit[y, 16] == r.hit, y
            if r.hit:
                assert refr.t[y, 16] == pytest.approx(r.t, rel=1e-9), y


# ---- termination criteria ---------------------------------------------------------------

SMALL = (40, 40)


def teapot_render(opts, offset=(0.0, 0.0, 0.0), size=SMALL, view=S.TEAPOT_VIEW):
    scene = S.teapot(offset=offset)
    return scene, render(scene, opts, size=size, view=S.transformed(view, 1.0, offset))


def l1(frame):
    return (frame.box_max - frame.box_min).sum(axis=-1)


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("size", [0.3, 1e-2, 1e-4])
def test_fixed_criterion_box_size(size, precision):
    """`fixed`: every hit box has an L1 diameter of at most the size, and no ray the float64
    reference hits is lost (coarse boxes may add hits at silhouettes, never remove them)."""
    scene, frame = teapot_render(Options(criterion="fixed", fixed_size=size, precision=precision))
    assert frame.hit.sum() > 300
    assert np.all(l1(frame)[frame.hit] <= size)
    assert np.median(l1(frame)[frame.hit]) > size / 8  # it stopped early, not at the float limit
    refr = reference_frame(scene, frame)
    assert not np.any(refr.hit & ~frame.hit)


def test_unreachable_fixed_size_falls_back_to_float():
    """A size below what float32 can resolve: every box stops at the float limit instead, so the
    render equals the `float` criterion's exactly."""
    _, fixed = teapot_render(Options(criterion="fixed", fixed_size=1e-9))
    _, flt = teapot_render(Options(criterion="float"))
    assert np.array_equal(fixed.hit, flt.hit)
    assert np.array_equal(fixed.box_min[fixed.hit], flt.box_min[flt.hit])
    assert np.array_equal(fixed.box_max[fixed.hit], flt.box_max[flt.hit])


def within_ulps(frame, ulps, bits=24):
    """The kernel's mantissa measure per pixel: (hi - lo) <= ulps * ulp(max(|lo|, |hi|)) per axis."""
    lo, hi = frame.box_min, frame.box_max
    return np.all(hi - lo <= ulps * ref.ulp(np.maximum(np.abs(lo), np.abs(hi)), bits), axis=-1)


@pytest.mark.parametrize("ulps", [2, 64, 4096])
def test_mantissa_criterion_box_within_ulps(ulps):
    """`mantissa`: box corners within N float32 ulps per coordinate. The teapot is moved to
    (10, 10, 10) so every world coordinate is far from zero and N ulps are reachable."""
    offset = (10.0, 10.0, 10.0)
    scene, frame = teapot_render(Options(criterion="mantissa", mantissa_ulps=ulps), offset=offset)
    hits = frame.hit
    assert hits.sum() > 300
    ok = within_ulps(frame, ulps)
    assert np.all(ok[hits]), f"{np.sum(~ok & hits)} boxes wider than {ulps} ulps"
    if ulps >= 64:  # it stopped early: boxes clearly larger than the float criterion's
        _, flt = teapot_render(Options(criterion="float"), offset=offset)
        assert np.median(l1(frame)[hits]) > 4 * np.median(l1(flt)[flt.hit])
    refr = reference_frame(scene, frame)
    assert not np.any(refr.hit & ~frame.hit)


def test_mantissa_criterion_near_origin_stops_at_float_limit():
    """Coordinates near zero have ulps far below what float32 subdivision of the whole teapot
    can resolve; the search must still terminate there (float limit), with no holes."""
    scene, frame = teapot_render(Options(criterion="mantissa", mantissa_ulps=0))
    _, flt = teapot_render(Options(criterion="float"))
    assert np.array_equal(frame.hit, flt.hit)
    refr = reference_frame(scene, frame)
    assert not np.any(refr.hit != frame.hit)


@pytest.mark.parametrize("fraction", [0.05, 0.5, 2.0])
def test_adaptive_criterion_box_within_pixel_footprint(fraction):
    """`adaptive`: box L1 diameter <= fraction x pixel footprint at the box's distance
    (T(t) = fraction * pixel angle * |d| * t_in, and t_in <= the reported t)."""
    view = S.TEAPOT_VIEW
    scene, frame = teapot_render(Options(criterion="adaptive", pixel_fraction=fraction), view=view)
    hits = frame.hit
    angle = view.pixel_angle(SMALL[1])
    footprint = fraction * angle * np.linalg.norm(frame.ray_dir, axis=-1) * frame.t
    assert np.all(l1(frame)[hits] <= footprint[hits] * (1 + 1e-9))
    assert np.median((l1(frame) / footprint)[hits]) > 0.1  # stops near the threshold, not below
    refr = reference_frame(scene, frame)
    assert not np.any(refr.hit & ~frame.hit)


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (1e4, 1e4, 1e4)])
def test_float_criterion_boxes_are_a_few_ulps(offset):
    """`float`: boxes are as small as float32 arithmetic on the object allows: a few float32
    ulps of the object's size per coordinate (its coordinates are stored relative to its centre)."""
    scene, frame = teapot_render(Options(criterion="float"), offset=offset)
    lo, hi = scene.bounds()
    size_ulp = ref.ulp(0.5 * np.max(hi - lo))
    widths = (frame.box_max - frame.box_min)[frame.hit]
    assert widths.max() <= 4 * size_ulp, f"widest box {widths.max() / size_ulp:.1f} ulps"


def test_grid_steps_are_float32_spacing_at_the_leaf_capped_by_the_scene():
    """The float criterion's grid: per leaf and axis, the float32 spacing at the leaf's largest
    world coordinate; moved far from the origin, the spacing at the scene's half-extent instead
    (the same for every leaf, so the render does not coarsen); no grid in float64."""
    def spacings(geom):
        box = geom.leaf_box
        magnitude = np.maximum(np.abs(box[:, :3]), np.abs(box[:, 3:]))
        half = 0.5 * np.max(box[:, 3:].max(axis=0) - box[:, :3].min(axis=0))
        return ref.ulp(magnitude), ref.ulp(half)

    at_origin = prepare(S.teapot(), "f32")
    world, scene = spacings(at_origin)
    assert np.array_equal(at_origin.grid, np.minimum(world, scene))
    assert np.mean(at_origin.grid < scene) > 0.5  # near the origin, mostly the world's spacing
    far = prepare(S.teapot(offset=(1e4, 1e4, 1e4)), "f32")
    assert np.all(far.grid == spacings(far)[1]) and spacings(far)[1] == scene
    assert not np.any(prepare(S.teapot(), "f64").grid)


@pytest.mark.parametrize("split", ["length", "cross"])
def test_every_criterion_and_split_keeps_the_hits(split):
    scene = S.teapot()
    for opts in (Options(split=split), Options(split=split, criterion="adaptive"),
                 Options(split=split, criterion="mantissa"), Options(split=split, criterion="fixed")):
        frame = render(scene, opts, size=(32, 32), view=S.SIDE_VIEW)
        refr = reference_frame(scene, frame)
        assert not np.any(refr.hit & ~frame.hit), opts


def test_hits_lie_in_their_patch_boxes():
    """Every reported position lies in the tight (padded) box of its patch that the BVH uses."""
    scene = S.teapot(floor=True)
    geom = prepare(scene, "f32")
    frame = render(scene, Options(), size=(48, 48), view=S.TEAPOT_VIEW, geometry=geom)
    boxes = geom.patch_box[frame.patch[frame.hit]]
    pos = frame.position[frame.hit]
    assert np.all((pos >= boxes[:, :3]) & (pos <= boxes[:, 3:]))


# ---- the pixel trace -----------------------------------------------------------------------

TRACE_OPTS = [pytest.param(Options(), marks=pytest.mark.interpreted), Options(precision="f64"),
              Options(criterion="adaptive"), Options(criterion="fixed", fixed_size=1e-3),
              Options(criterion="mantissa", split="cross")]


class _PixelView:
    """One pixel's channels of a Frame, as attributes."""

    def __init__(self, frame, col, row):
        for name in ("hit", "box_min", "box_max", "effort", "ray_origin", "ray_dir"):
            setattr(self, name, getattr(frame, name)[row, col])


def halves(step):
    """The four parameter intervals (u0, u1, v0, v1) a split of `step` can produce."""
    u0, u1, v0, v1 = step[:4]
    mu, mv = 0.5 * (u0 + u1), 0.5 * (v0 + v1)
    return [(u0, mu, v0, v1), (mu, u1, v0, v1), (u0, u1, v0, mv), (u0, u1, mv, v1)]


@pytest.mark.parametrize("opts", TRACE_OPTS, ids=lambda o: f"{o.criterion}-{o.split}-{o.precision}")
def test_trace_events_are_consistent(opts):
    """trace_one: every step is miss/pruned/split/hit; the reported box is a hit step's box, the
    nearest of them along the ray (the last hit, since only nearer hits replace the current one);
    effort counts the steps; depths and parameter intervals nest; and it agrees with render."""
    scene = S.teapot()
    size = (24, 24)
    opts = opts.with_(bundle="1x1")  # rays traced alone, as trace_one traces one
    geom = prepare(scene, opts.precision)
    # the renderer's kernel on every third pixel (the rays render() would trace there)
    origins, dirs = primary_rays(S.LID_VIEW, *size, opts.precision)
    sub = (slice(0, 24, 3), slice(0, 24, 3))
    sampled = trace_rays(geom, opts, np.ascontiguousarray(origins[sub]), np.ascontiguousarray(dirs[sub]),
                         S.LID_VIEW.pixel_angle(size[1]))
    pixels = [(x, y) for y in range(0, 24, 3) for x in range(0, 24, 3)]
    hits = 0
    for x, y in pixels:
        frame = _PixelView(sampled, x // 3, y // 3)
        tr = trace_pixel(scene, opts, x, y, size=size, view=S.LID_VIEW, geometry=geom)
        assert not tr.truncated
        events = tr.events
        assert set(events) <= {"miss", "pruned", "split", "hit"}
        assert tr.effort == len(events), (x, y)
        assert tr.hit == frame.hit
        f, i = tr.steps_f, tr.steps_i
        # the diameter is measured on the local box, the recorded box is in world coordinates
        np.testing.assert_allclose(f[:, 10], (f[:, 7:10] - f[:, 4:7]).sum(axis=1), rtol=1e-12,
                                   atol=8 * ref.ulp(np.abs(f[:, 4:10]).max(initial=0.0), BITS[opts.precision]))
        children = {}  # (patch, depth, interval) of a possible child -> earliest split step
        root = 2 * geom.presplit  # scene patches are pre-split 4^presplit ways into leaves
        cell = 0.5 ** geom.presplit
        for k in range(len(events)):
            if i[k, 1] == root:  # a leaf's root box covers its cell of the patch's parameter square
                u0, u1, v0, v1 = f[k, :4]
                assert u1 - u0 == cell and v1 - v0 == cell and (u0 / cell) % 1 == 0 and (v0 / cell) % 1 == 0
            else:  # a child: one half, in u or v, of an earlier split step one level up
                # (midpoints rounded as the kernel rounds them: near a collapsed edge float64
                # intervals can shrink below the resolution of u itself)
                assert (i[k, 0], i[k, 1], tuple(f[k, :4])) in children, (x, y, k)
            if i[k, 2] == 2:
                for h in halves(f[k]):
                    children.setdefault((i[k, 0], i[k, 1] + 1, h), k)
        if tr.hit:
            hits += 1
            k = tr.hit_step()  # the reported step: not always the last 'hit' in list order, since a
            assert events[k] == "hit"  # box computed early (an ancestor's far half) may be hit last
            assert np.array_equal(tr.box_min, f[k, 4:7]) and np.array_equal(tr.box_max, f[k, 7:10])
            assert tr.patch == i[k, 0]
            assert np.array_equal(tr.box_min, frame.box_min)
            assert np.array_equal(tr.box_max, frame.box_max)
            assert tr.effort == frame.effort
            o, d = frame.ray_origin, frame.ray_dir
            entry = {q: float(ref.slab_exact(f[q, 4:10], o, d)[1] or math.inf) for q in np.nonzero(i[:, 2] == 3)[0]}
            # hits are ordered by the entry of the box the kernel tests, which the reported (grid,
            # widened) box contains: equal up to the box's size along the ray
            slack = f[k, 10] / np.linalg.norm(d) + 1e-12
            assert entry[k] <= min(entry.values()) + slack, (x, y, entry)
        else:
            assert "hit" not in events and tr.hit_step() == -1
    assert 10 < hits < len(pixels)


# ---- effort stays bounded ---------------------------------------------------------------------

# Pixel (22, 17) of LID_VIEW at 24 x 24 (float64 primary rays): the lid knob, patch 20.
KNOB_RAY = ((0.55, -0.8, 3.75), (-0.21259009004896104, 0.7230676952310235, -0.7085409452357097))


@pytest.mark.interpreted
@pytest.mark.parametrize("precision", ["f64", "f32"])
def test_effort_bounded_on_the_lid_knob(precision):
    """One ray at the lid knob: the search finds the hit with a sane number of boxes."""
    origin, direction = KNOB_RAY
    frame = S.trace(S.teapot(), np.array(origin), np.array([direction]), Options(precision=precision))
    assert frame.hit[0, 0] and frame.patch[0, 0] == 20
    assert frame.effort[0, 0] <= 20000, f"{frame.effort[0, 0]} boxes"


# ---- float32 against float64: no holes on the teapot -------------------------------------------

NO_HOLE_VIEWS = {
    "standard": (S.TEAPOT_VIEW, (96, 96)),
    "lid knob": (S.LID_VIEW, (64, 64)),
    "silhouettes": (S.SIDE_VIEW, (96, 64)),
}


@pytest.mark.parametrize("split", ["length", "cross"])
@pytest.mark.parametrize("view", list(NO_HOLE_VIEWS))
def test_teapot_no_holes_no_false_hits(view, split, tmp_path):
    """The sample scene (teapot on its floor) in float32 against the float64 reference of the
    same rays: zero holes and zero false hits."""
    v, size = NO_HOLE_VIEWS[view]
    scene = S.teapot(floor=True)
    cmp = S.compare(scene, size, v, Options(split=split), name=f"teapot {view} {split}")
    assert cmp.hits > size[0] * size[1] // 4
    if cmp.holes or cmp.false_hits:
        paths = S.write_failure_images(cmp, tmp_path)
        pytest.fail(f"{cmp.holes} holes, {cmp.false_hits} false hits; images {paths}")
