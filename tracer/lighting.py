"""Shading with secondary rays: shadows, reflection and refraction, per work unit.

After the tile kernel has traced a unit's primary rays, the same render thread shades its hit
pixels here (render.trace_rays), so the viewer shows lit tiles as they finish. The ray tree is
walked breadth first in numpy ("wavefront"): every vertex (a hit) gets its direct light, then
spawns its reflected and refracted rays, traced together through ray_batch's closest-hit
kernel (in bundles of neighbouring pixels' rays where that changes no answer: shadow_bundles.py);
their hits are the next level's vertices, up to options.max_depth levels after the primary one.
Misses see the background's grey.

Direct light at a vertex: ambient plus Lambert + Phong per light sample (light_samples.py),
each sample weighted by its visibility: 0 where the sample lies behind the surface (decided
without a ray where options.trivial_tests, Lischinski 6) or the shadow ray from the robust
origin (origins.py) to it is occluded (neighbouring points' rays in bundles: shadow_bundles.py,
where that changes no answer; else ray_batch's any-hit kernel). Area lights first ask the
fast penumbra test (penumbra.py) and skip the samples of points it proves lit. Neither test
changes a bit of the image: they skip only rays whose answer is already known. A scene without
lights has a headlight at the eye, which casts no shadows (they would hide behind their casters).

Materials: `reflect` is the mirror fraction, `transmit` the refracted one; the refracted part
is split by Fresnel's reflectance (Schlick's approximation, total internal reflection included)
into more reflection and the refraction proper; what is left (1 - reflect - transmit) is the
surface's own Lambert + Phong colour. Patches have no consistent orientation, so a ray tree
tracks whether it is inside a refracting body by counting the refractions along it.

Threshold of detail (adaptive criterion): a secondary ray starts with the threshold its parent
had at the hit, T0' = T0 + dT * t, and keeps the parent's growth per unit length (Lempitsky 3.6);
a reflected or refracted one grows faster by 2 k T0', k the surface's largest curvature at the
hit (curvature.py), as a curved mirror spreads the beam: reflections of distant detail stop early.
"""
from __future__ import annotations

import threading
import time

import numpy as np

from .curvature import max_curvature, patch_parameters
from .fixed_order import dot3
from .light_samples import half_extent, points, sample_count, seeds
from .origins import patch_ulps, robust_origins
from .penumbra import LIT, PENUMBRA, UMBRA, UNCLASSIFIED, expanded_set, inside, scene_box
from .ray_batch import BatchTracer, batch_rays
from .scene import Light
from .shade import AMBIENT, unit
from .shadow_bundles import PointBundles, shares_tree
from .umbra import UmbraTest
from .vertices import Vertices, environment, facing, schlick

PHASES = ("shadow_rays", "penumbra_tests", "secondary_rays", "shading")

# Where the samples go in bundles (shadow_bundles.py), the lit test of `umbra` runs only
# if the light has at least this many samples per unit of its angular size (half extent over
# distance): a wider cone costs the test more, more samples cost the bundle more. Measured on the
# teapot (160^2, one thread, sphere lights of radius 0.005-0.05 of the diagonal, 8-64 samples), the
# test pays from 8 samples at radius 0.005, 10 at 0.01, 22 at 0.02 and 70 at 0.05: about 700.
WORTH_TESTING = 700.0


class Lighting:
    """What shading a frame's units needs, built once per frame (render.trace_rays)."""

    def __init__(self, scene, geom, opts, inputs, eye, on_compile=None):
        self.opts, self.scene, self.geom = opts, scene, geom
        self.tracer = BatchTracer(geom, opts, inputs, on_compile)
        self.bundles = PointBundles(self.tracer) if shares_tree(opts) else None
        # 'umbra' runs the lit test where it pays (WORTH_TESTING); 'expanded' and 'tmax' show it everywhere
        self.worth_testing = self.bundles is not None and opts.penumbra == "umbra"
        self.slope = float(inputs.sizes[0])  # threshold of detail per unit distance (adaptive)
        mats = scene.materials
        self.kd = np.array([m.color for m in mats], np.float64).reshape(-1, 3)
        self.ks, self.ns = (np.array([getattr(m, k) for m in mats], np.float64) for k in ("specular", "shininess"))
        self.reflect = np.array([m.reflect for m in mats]) if opts.reflections else np.zeros(len(mats))
        self.transmit = np.array([m.transmit for m in mats]) if opts.refractions else np.zeros(len(mats))
        self.ior = np.array([m.ior for m in mats], np.float64)
        self.patch_material = np.asarray(scene.patch_material, np.int64)
        self.ulp = patch_ulps(geom)
        # no lights: a headlight at the eye, which casts no shadows (they would hide behind their casters)
        self.headlight = not scene.lights
        lights = list(scene.lights or []) or [Light("point", 1.0, np.ones(3), position=np.asarray(eye, np.float64))]
        total = sum(float(li.intensity) for li in lights)
        self.lights = lights
        self.rgb = [np.asarray(li.color, np.float64) * li.intensity / max(total, 1.0) for li in lights]
        weights = np.array([float(li.intensity) for li in lights])
        self.share = weights / weights.sum() if weights.sum() > 0 else np.full(len(lights), 1.0 / len(lights))
        self.counts = [sample_count(li, opts.light_samples) for li in lights]
        # 'umbra' is 'tmax' and umbra detection (umbra.py)
        self.grown = "tmax" if opts.penumbra == "umbra" else opts.penumbra
        fast = opts.shadows and opts.penumbra != "off"
        self.sets = [expanded_set(geom, li, self.grown) if fast and li.type != "point" else None for li in lights]
        self.umbra = UmbraTest(scene, geom) if fast and opts.penumbra == "umbra" and scene.lights else None
        self.box = scene_box(geom)
        self.width = None
        self.seconds = dict.fromkeys(PHASES, 0.0)
        self.centre_rays = 0
        self.umbra_tests = 0
        self.trivial = 0  # shadow rays decided without tracing: the sample lies behind the surface
        self._lock = threading.Lock()
        # recorder(kind, **rays) sees every batch of secondary rays (the pixel inspector's ray tree,
        # ray_tree.py): kind 'shadow' (pix, code, light, origin, target, occluded, effort), 'proven_lit'
        # (pix, code, light, origin, centre, lit: the points tested only), 'proven_umbra' (pix, code,
        # light, origin, centre, patch: the occluding patch, -1 none; the points tested only), 'secondary' (pix, code,
        # origin, direction, hit: kernel channels of the hits), each with the batch `rays` traced
        # (ray_batch.batch_rays; none for proven_lit) and the boxes and normals the origins left from
        # (box_min, box_max, side); 'samples' (pix, code, light, points (m, S, 3), visible (m, S)).
        self.recorder = None

    def _clock(self, phase, start):
        with self._lock:
            self.seconds[phase] += time.perf_counter() - start

    # ---- a unit ------------------------------------------------------------------------

    def shade_unit(self, frame, pixels: np.ndarray, ids=None) -> None:
        """Radiance, shadow, shadow_rays and penumbra of a unit's pixels (k, 2) into frame. ids: the
        pixels' numbers (k,) that seed their light samples, by default row * width + column (a
        frame holding part of an image gives the whole image's: ray_tree.py)."""
        ys, xs = pixels[:, 0], pixels[:, 1]
        hit = frame.hit[ys, xs]
        if not hit.any():
            return
        ids = (ys.astype(np.int64) * frame.hit.shape[1] + xs if ids is None else np.asarray(ids, np.int64))[hit]
        k = len(ids)
        v = self._primary(frame, ys[hit], xs[hit])
        radiance = np.zeros((k, 3))
        rays = np.zeros(k, np.int32)
        for depth in range(self.opts.max_depth + 1):
            start = time.perf_counter()
            local, kr, kt, eta = self._split(v)
            direct, fraction, traced, klass = self._direct(v, ids[v.pix])
            np.add.at(radiance, v.pix, v.weight * local[:, None] * direct)
            np.add.at(rays, v.pix, traced)
            if depth == 0:
                shadow, penumbra = fraction, klass
            self._clock("shading", start)
            if depth == self.opts.max_depth or len(v.pix) == 0:
                break
            v = self._spawn(v, kr, kt, eta, radiance)
        frame.radiance[ys[hit], xs[hit]] = radiance
        frame.shadow_rays[ys[hit], xs[hit]] = rays
        if self.opts.shadows:
            frame.shadow[ys[hit], xs[hit]] = shadow
            frame.penumbra[ys[hit], xs[hit]] = penumbra

    def _primary(self, frame, ys, xs) -> Vertices:
        d = unit(frame.ray_dir[ys, xs])
        dist = frame.t[ys, xs] * np.linalg.norm(frame.ray_dir[ys, xs], axis=-1)
        m = len(ys)
        return Vertices(np.arange(m), np.ones(m, np.int64), np.ones((m, 3)), frame.box_min[ys, xs],
                        frame.box_max[ys, xs], frame.position[ys, xs], facing(frame.normal[ys, xs], d), d,
                        frame.patch[ys, xs], frame.uv[ys, xs], self.slope * dist, np.full(m, self.slope),
                        np.zeros(m, bool))

    def _split(self, v: Vertices):
        """Per vertex: the surface's own share, the reflected and the refracted weights, and the
        ratio of refractive indices across the surface (Fresnel by Schlick)."""
        mat = self.patch_material[v.patch]
        reflect, transmit, ior = self.reflect[mat], self.transmit[mat], self.ior[mat]
        eta = np.where(v.inside, ior, 1.0 / ior)
        fresnel = schlick(np.clip(-np.sum(v.d * v.normal, axis=1), 0.0, 1.0), eta)
        return 1.0 - reflect - transmit, reflect + transmit * fresnel, transmit * (1.0 - fresnel), eta

    # ---- direct light ---------------------------------------------------------------

    def _direct(self, v: Vertices, pixel_ids):
        """(radiance (m, 3), shadow fraction (m,), shadow rays traced (m,), penumbra class (m,))."""
        m = len(v.pix)
        mat = self.patch_material[v.patch]
        kd, ks, ns = self.kd[mat], self.ks[mat][:, None], self.ns[mat][:, None]
        out = AMBIENT * kd
        fraction = np.zeros(m)
        traced = np.zeros(m, np.int32)
        all_lit, all_umbra, classified = np.ones(m, bool), np.ones(m, bool), False
        view = -v.d
        # one origin per vertex for every light's shadow rays: they all leave on the normal's side
        origin = self._origins(v, v.normal) if self.opts.shadows and not self.headlight and m else None
        for li, light in enumerate(self.lights):
            count = self.counts[li]
            lp = points(light, v.pos, seeds(pixel_ids, v.code, li), count)
            vis, rays, cls = self._visibility(v, lp, li, origin)
            if self.recorder is not None:
                self.recorder("samples", pix=v.pix, code=v.code, light=li, points=lp, visible=vis)
            traced += rays
            if cls is not None:
                all_lit &= cls == LIT
                all_umbra &= cls == UMBRA
                classified = True
            # every sample's Lambert + Phong term at once (m, S, 3), elementwise as one sample at a time
            l_dir = unit(lp - v.pos[:, None])
            ndl = dot3(v.normal[:, None], l_dir)[..., None]
            r = 2.0 * ndl * v.normal[:, None] - l_dir
            rdv = np.clip(dot3(r, view[:, None]), 0.0, 1.0)[..., None]
            phong = rdv ** np.repeat(ns[:, None], count, 1)  # contiguous: numpy's power loop may differ for broadcasts
            term = np.where(vis[..., None], kd[:, None] * ndl + ks[:, None] * phong, 0.0)
            glow = np.zeros((m, 3))
            for s in range(count):  # summed sample by sample: the same sums whatever m
                glow += term[:, s]
            out = out + glow * (self.rgb[li] / count)
            fraction += self.share[li] * vis.sum(axis=1) / count
        klass = np.where(all_umbra, UMBRA, np.where(all_lit, LIT, PENUMBRA)) if classified else np.full(m, UNCLASSIFIED)
        return out, fraction, traced, klass.astype(np.int8)

    def _visibility(self, v: Vertices, lp, li, origin):
        """(visible (m, S) bool, rays traced (m,), penumbra class (m,): LIT, PENUMBRA or UMBRA, or None
        where not asked) of the sample points lp (m, S, 3) of light li; origin: the shadow rays'
        (m, 3), None: unshadowed."""
        m, count = lp.shape[:2]
        front = dot3(v.normal[:, None, :], lp - v.pos[:, None]) > 0.0
        if origin is None:
            return front, np.zeros(m, np.int32), None
        need = front if self.opts.trivial_tests else np.ones_like(front)
        if self.opts.trivial_tests:
            with self._lock:
                self.trivial += int(m * count - front.sum())
        lit = dark = None
        asked = need.any(axis=1)
        if self.sets[li] is not None:
            start = time.perf_counter()
            if self.umbra is not None:  # first: it is cheap, and a point in umbra spares the lit test's walk
                dark = self._proven_umbra(v, origin, li, asked)
                need = need & ~dark[:, None]
            lit, tested = self._proven_lit(origin, li, v.threshold, v.grow, asked if dark is None else asked & ~dark, lp,
                                           v.normal)
            need = need & ~lit[:, None]
            if self.recorder is not None:
                self.recorder("proven_lit", pix=v.pix[tested], code=v.code[tested], light=li, origin=origin[tested],
                              centre=self.lights[li].centre(), lit=lit[tested], box_min=v.lo[tested],
                              box_max=v.hi[tested], side=v.normal[tested])
            self._clock("penumbra_tests", start)
        start = time.perf_counter()
        rows, cols = np.nonzero(need)
        occluded = np.zeros((m, count), bool)
        if dark is not None:  # every sample ray would have met the occluding patch
            occluded[dark] = True
        rays = self.shadow_rays(v, lp, origin, rows, cols)
        if self.bundles is not None:  # in bundles, consecutive points' rays together (shadow_bundles.py)
            occluded[rows, cols], effort = self.bundles.occluded(rays, rows)
        else:
            occluded[rows, cols], effort = self.tracer.occluded(rays)
        self._clock("shadow_rays", start)
        if self.recorder is not None:
            self.recorder("shadow", pix=v.pix[rows], code=v.code[rows], light=li, origin=origin[rows], target=lp[rows, cols],
                          occluded=occluded[rows, cols], effort=effort, rays=rays, box_min=v.lo[rows],
                          box_max=v.hi[rows], side=v.normal[rows])
        cls = None
        if lit is not None:  # umbra: proven (umbra.py), or every sample dark without a ray (facing away)
            umbra = ~asked if dark is None else ~asked | dark
            cls = np.where(lit, LIT, np.where(umbra, UMBRA, PENUMBRA))
        return front & ~occluded, need.sum(axis=1).astype(np.int32), cls

    def shadow_rays(self, v: Vertices, lp, origin, rows, cols) -> np.ndarray:
        """The batch rays from origin[rows] (m, 3) to the sample points lp[rows, cols] of the
        vertices v (their threshold of detail and side plane)."""
        o = origin[rows]
        dt = v.grow[rows] * np.linalg.norm(lp[rows, cols] - o, axis=1)
        return batch_rays(o, lp[rows, cols] - o, 0.0, 1.0, v.threshold[rows], dt, v.normal[rows])

    def _proven_umbra(self, v: Vertices, origin, li, ask):
        """(m,) bool: every shadow ray from these origins to light li proven occluded by one patch
        (umbra.py); asked only where ask (points not proven lit with samples to trace)."""
        cover = self.umbra(self.lights[li], origin, ask)
        if self.recorder is not None:
            self.recorder("proven_umbra", pix=v.pix[ask], code=v.code[ask], light=li, origin=origin[ask],
                          centre=self.lights[li].centre(), patch=cover[ask], box_min=v.lo[ask], box_max=v.hi[ask],
                          side=v.normal[ask])
        with self._lock:
            self.umbra_tests += int(ask.sum())
        return cover >= 0

    def _proven_lit(self, origin, li, threshold, grow, asked, lp, normal):
        """(m,) bool: Lemma 3.1 / 4.2 (penumbra.py) prove every sample ray from these origins to
        the sample points lp (m, S, 3) unoccluded; and (m,) bool: the points tested. normal (m, 3):
        the side the rays leave on."""
        lit = np.zeros(len(origin), bool)
        light = self.lights[li]
        centre, half = light.centre(), half_extent(light)
        ask = asked if self.grown != "tmax" else asked & inside(origin, self.box)
        if self.worth_testing:  # the test must cost less than the bundle of samples it spares
            size = half.max() / np.linalg.norm(centre - origin, axis=1)
            ask &= lp.shape[1] >= WORTH_TESTING * size
        idx = np.nonzero(ask)[0]
        if len(idx):
            es = self.sets[li]
            count = lp.shape[1]
            o = origin[idx]
            n = normal[idx]
            # the cone's side plane: only where every ray of the cone leaves in front of it
            clear = dot3(n, centre - o) > dot3(np.abs(n), half) * (1.0 + 2.0 ** -30) + 2.0 ** -40 * (
                np.abs(n).sum(axis=1) * np.abs(centre - o).sum(axis=1))
            centre_rays = batch_rays(o, centre - o, 0.0, 1.0, side=np.where(clear[:, None], n, 0.0))
            cone = shares_tree(self.opts)  # one cone search stands for the samples' (ray_batch._penumbra_visit)
            if cone:
                samples = np.zeros((0, centre_rays.shape[1]))
            else:
                ends = lp[idx].reshape(-1, 3)
                starts = np.repeat(o, count, axis=0)
                samples = batch_rays(starts, ends - starts, 0.0, 1.0, np.repeat(threshold[idx], count),
                                     np.repeat(grow[idx], count) * np.linalg.norm(ends - starts, axis=1),
                                     np.repeat(n, count, axis=0))
            lit[idx] = self.tracer.proven_lit(es.record, es.stack, es.grown, centre_rays, samples, count, half,
                                              cone)[0]
            with self._lock:
                self.centre_rays += len(idx)
        return lit, ask

    def _origins(self, v: Vertices, side, rows=slice(None)):
        """Robust origins (origins.py) of rays leaving the vertices v[rows] on the side of `side`."""
        return robust_origins(self.opts.origin, lo=v.lo[rows], hi=v.hi[rows], position=v.pos[rows], normal=side,
                              ulp=self.ulp[v.patch[rows]], ulps=self.opts.origin_ulps, threshold=v.threshold[rows],
                              epsilon=self.opts.origin_epsilon)

    # ---- secondary rays --------------------------------------------------------------

    def _spawn(self, v: Vertices, kr, kt, eta, radiance) -> Vertices:
        """The next level: reflected and refracted rays of v, traced; misses add the background."""
        start = time.perf_counter()
        cos_i = np.clip(-np.sum(v.d * v.normal, axis=1), 0.0, 1.0)
        parts = []
        refl = np.nonzero(kr > 0)[0]
        if len(refl):
            d = unit(v.d[refl] + 2.0 * cos_i[refl, None] * v.normal[refl])
            parts.append((refl, d, v.normal[refl], kr[refl], 2 * v.code[refl], v.inside[refl]))
        k2 = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
        refr = np.nonzero((kt > 0) & (k2 > 0))[0]
        if len(refr):
            e = eta[refr, None]
            d = unit(e * v.d[refr] + (e * cos_i[refr, None] - np.sqrt(k2[refr, None])) * v.normal[refr])
            parts.append((refr, d, -v.normal[refr], kt[refr], 2 * v.code[refr] + 1, ~v.inside[refr]))
        if not parts:
            return v.take(np.zeros(0, np.int64))
        src = np.concatenate([p[0] for p in parts])
        d = np.concatenate([p[1] for p in parts])
        side = np.concatenate([p[2] for p in parts])
        weight = v.weight[src] * np.concatenate([p[3] for p in parts])[:, None]
        code = np.concatenate([p[4] for p in parts])
        inside_now = np.concatenate([p[5] for p in parts])
        origin = self._origins(v, side, src)
        grow = v.grow[src]
        if self.slope > 0.0:  # adaptive: a curved mirror spreads the beam (curvature.py)
            kappa = max_curvature(self.scene, v.patch[src], patch_parameters(self.geom, v.patch[src], v.uv[src]))
            grow = grow + 2.0 * kappa * v.threshold[src]
        rays = batch_rays(origin, d, 0.0, np.inf, v.threshold[src], grow, side)
        # in bundles where that changes no answer (shadow_bundles.py), else one by one
        out = (self.bundles or self.tracer).closest(rays)
        hit = out.hit[0]
        if self.recorder is not None:
            self.recorder("secondary", pix=v.pix[src], code=code, origin=origin, direction=d, hit=out, rays=rays,
                          box_min=v.lo[src], box_max=v.hi[src], side=side)
        miss = ~hit
        np.add.at(radiance, v.pix[src[miss]], weight[miss] * environment(d[miss]))
        self._clock("secondary_rays", start)
        t = out.t[0, hit]
        return Vertices(v.pix[src[hit]], code[hit], weight[hit], out.box_min[0, hit], out.box_max[0, hit],
                        out.position[0, hit], facing(out.normal[0, hit], d[hit]), d[hit], out.patch[0, hit],
                        out.uv[0, hit], v.threshold[src[hit]] + grow[hit] * t, grow[hit], inside_now[hit])

    def report(self) -> dict:
        """Time per phase (summed over threads), centre rays of the penumbra tests, shadow rays the
        triviality tests decided, the expanded data sets' build figures."""
        return {"seconds": {k: round(s, 4) for k, s in self.seconds.items()}, "centre_rays": self.centre_rays,
                "umbra_tests": self.umbra_tests,
                "trivially_decided": self.trivial,
                "expanded_sets": [s.report for s in self.sets if s is not None]}
