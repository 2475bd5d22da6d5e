"""`psrt bench --penumbra-sweep`: the fast penumbra against light size, as Lukaszewski's table 4.4.

The scene's first light, a sphere, is given radii that are fractions of the scene's diagonal;
each radius is rendered with every sample traced (penumbra off) and with the expanded and tmax
methods, and checked bit for bit against off. Frames are timed by the process's CPU time with
one render thread (the median of `runs`, the methods taking turns within each run, so drift of
the machine's speed hits them alike), beside the primary rays alone (no shadows, no
reflections) and the scene's own light at its own samples.
"""
from __future__ import annotations

import statistics
import time
from dataclasses import replace

import numpy as np

from .fixed_order import norm
from .geometry import prepare
from .options import PENUMBRAS
from .render import render

RADII = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2)


def _cpu(f):
    start = time.process_time()
    out = f()
    return time.process_time() - start, out


def _timed(scene, geom, configs: dict, size, runs: int) -> tuple:
    """{name: median CPU s} and {name: last frame} of configurations taking turns, after a warm-up."""
    frames = {k: render(scene, o, size=size, geometry=geom) for k, o in configs.items()}
    times = {k: [] for k in configs}
    for _ in range(runs):
        for k, o in configs.items():
            seconds, frames[k] = _cpu(lambda: render(scene, o, size=size, geometry=geom))
            times[k].append(seconds)
    return {k: statistics.median(v) for k, v in times.items()}, frames


def run_penumbra(scene, base, *, size=(256, 256), runs: int = 3, samples: int = 32, radii=RADII, log=None) -> dict:
    """Time every penumbra method per light radius; raises ValueError without a sphere light."""
    if not scene.lights or scene.lights[0].type != "sphere":
        raise ValueError("--penumbra-sweep: the scene's first light must be a sphere (its radius is swept)")
    base = base.with_(threads=1)
    geom = prepare(scene, base.precision)
    lo, hi = scene.bounds()
    diagonal = norm(np.asarray(hi) - np.asarray(lo))
    light = scene.lights[0]
    own = {"primary": base.with_(shadows=False, reflections=False), "scene off": base.with_(penumbra="off"),
           "scene tmax": base.with_(penumbra="tmax"), "scene umbra": base.with_(penumbra="umbra")}
    own_times, _ = _timed(scene, geom, own, size, runs)
    rows = []
    for fraction in radii:
        scene.lights[0] = replace(light, radius=fraction * diagonal)
        configs = {m: base.with_(penumbra=m, light_samples=samples) for m in PENUMBRAS}
        times, frames = _timed(scene, geom, configs, size, runs)
        off = frames["off"]
        same = all(np.array_equal(frames[m].radiance, off.radiance, equal_nan=True) for m in PENUMBRAS)
        hit = off.hit
        rows.append({"radius": fraction, "seconds": times, "identical": bool(same),
                     "proven_lit": float(np.mean(frames["tmax"].penumbra[hit] == 0)),
                     "proven_umbra": float(np.mean(frames["umbra"].penumbra[hit] == 2)),
                     "rays_per_hit": {m: float(frames[m].shadow_rays[hit].mean()) for m in PENUMBRAS}})
        if log is not None:
            log(f"radius {fraction:g}: off {times['off']:.3f} s, tmax {times['tmax']:.3f} s, umbra {times['umbra']:.3f} s")
    scene.lights[0] = light
    return {"size": list(size), "runs": runs, "samples": samples, "own": own_times,
            "own_samples": light.samples, "own_radius": light.radius / diagonal, "rows": rows}


def format_penumbra(result: dict) -> str:
    w, h = result["size"]
    own = result["own"]
    lines = [f"{'radius':>7} {'off s':>7} {'expanded s':>10} {'tmax s':>7} {'umbra s':>7} {'off/tmax':>8} "
             f"{'off/umbra':>9} {'lit %':>6} {'umbra %':>7} {'rays/hit off':>12} {'tmax':>5} {'umbra':>5} {'same':>5}"]
    for r in result["rows"]:
        s, rays = r["seconds"], r["rays_per_hit"]
        lines.append(f"{r['radius']:7.3f} {s['off']:7.3f} {s['expanded']:10.3f} {s['tmax']:7.3f} {s['umbra']:7.3f} "
                     f"{s['off'] / s['tmax']:8.2f} {s['off'] / s['umbra']:9.2f} {100 * r['proven_lit']:6.1f} "
                     f"{100 * r['proven_umbra']:7.1f} {rays['off']:12.1f} {rays['tmax']:5.1f} {rays['umbra']:5.1f} "
                     f"{'yes' if r['identical'] else 'NO':>5}")
    lines.append(f"{w}x{h}, {result['samples']} samples a light, one thread, CPU s (median of {result['runs']}); "
                 "radius as a fraction of the scene's diagonal; same: every method's image bit-identical to off")
    lines.append(f"the scene's own light (radius {result['own_radius']:.3f}, {result['own_samples']} samples): "
                 f"primary rays alone {own['primary']:.3f} s, off {own['scene off']:.3f} s "
                 f"({own['scene off'] / own['primary']:.2f}x), tmax {own['scene tmax']:.3f} s "
                 f"({own['scene tmax'] / own['primary']:.2f}x), umbra {own['scene umbra']:.3f} s "
                 f"({own['scene umbra'] / own['primary']:.2f}x the primary rays)")
    return "\n".join(lines)
