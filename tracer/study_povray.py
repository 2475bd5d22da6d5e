"""The study's POV-Ray peer (tracer/study.py): POV-Ray 3.7's `bicubic_patch` at a flatness.

Only for scenes of integral (non-rational) patches of degree at most 3 (lower degrees elevated to
bicubic, exactly up to rounding). POV-Ray traces its own camera's rays, set up from psrt's view
through the same pixel centres (they differ from psrt's float32 rays by those rays' rounding).
Each patch's pigment writes, without lighting, into a 16-bit PPM: red the depth's high 16 bits,
green its low 16 bits (the distance from the eye over the scene's depth range, to 32 bits), blue
the patch's index + 1; the hit point is read back as eye + depth along psrt's ray. Timed as a
first image: the CPU time of the povray process (parse, build, trace), rendering with one thread
(+WT1) as psrt's points do, so that a point on a Dask worker keeps to its worker's core.
"""
from __future__ import annotations

import os
import re
import resource
import shutil
import subprocess
import tempfile

import numpy as np

from .fixed_order import norm

FLATNESSES = (0.1, 0.01, 1e-3, 1e-4)
STEPS = 8            # u_steps and v_steps: at most 2^8 x 2^8 triangles per patch
LEVELS = 65535       # a 16-bit channel
# A phase of povray's statistics: '(0.123 seconds)' of wall time, then 'using 1 thread(s) with 0.120
# CPU-seconds total'. The povray process also idles about 0.6 s of wall time around its phases, so
# only the phases tell whether its core was shared.
PHASE = re.compile(r"\(([0-9.]+) seconds\)\s+using \d+ thread\(s\) with ([0-9.]+) CPU-seconds")


def available() -> bool:
    return shutil.which("povray") is not None


def bicubic_nets(scene):
    """(P, 16, 3) control nets of every patch elevated to bicubic, or None with why not."""
    if scene.n_patches >= LEVELS:
        return None, "more patches than the 16-bit patch channel holds"
    if np.any(scene.points[:, 3] != 1.0):
        return None, "rational patches (bicubic_patch is integral)"
    if np.any(scene.degree_u > 3) or np.any(scene.degree_v > 3):
        return None, "patches of degree above 3"
    nets = []
    for p in range(scene.n_patches):
        m, d = int(scene.degree_u[p]), int(scene.degree_v[p])
        start = int(scene.point_start[p])
        net = scene.points[start:start + (m + 1) * (d + 1), :3].reshape(d + 1, m + 1, 3)
        nets.append(_elevated(_elevated(net).swapaxes(0, 1)).swapaxes(0, 1).reshape(16, 3))
    return np.array(nets), None


def _elevated(net):
    """The net (rows, n + 1, 3) degree-elevated along its second axis to 3 (Q_i = i/(n+1) P_{i-1} +
    (1 - i/(n+1)) P_i, repeated)."""
    while net.shape[1] < 4:
        n = net.shape[1] - 1
        a = (np.arange(n + 2) / (n + 1))[None, :, None]
        padded_prev = np.concatenate([net[:, :1] * 0, net], axis=1)
        padded_next = np.concatenate([net, net[:, :1] * 0], axis=1)
        net = a * padded_prev + (1 - a) * padded_next
    return net


def _vec(v) -> str:
    return "<" + ", ".join(repr(float(x)) for x in v) + ">"


def pov_source(nets, view, width: int, height: int, depth0: float, depth_range: float, flatness: float) -> str:
    """The POV-Ray scene: psrt's camera by explicit vectors, each patch with its encoding pigment."""
    forward, right, up = view.basis()
    half = np.tan(np.radians(view.fov_deg) / 2.0)
    e = view.eye
    lines = ["global_settings { assumed_gamma 1.0 }", "background { rgb 0 }",
             f"camera {{ perspective location {_vec(e)} direction {_vec(forward)} "
             f"right {_vec(right * 2 * half * width / height)} up {_vec(up * 2 * half)} }}",
             f"#declare Depth = function(x, y, z) {{ (sqrt((x - {e[0]!r})*(x - {e[0]!r}) + (y - {e[1]!r})*(y - {e[1]!r})"
             f" + (z - {e[2]!r})*(z - {e[2]!r})) - {depth0!r}) / {depth_range!r} * {LEVELS} }}",
             f"#declare High = function(x, y, z) {{ (floor(Depth(x, y, z)) + 0.5) / {LEVELS} }}",
             "#declare Low = function(x, y, z) { Depth(x, y, z) - floor(Depth(x, y, z)) }"]
    for p, net in enumerate(nets):
        points = ", ".join(_vec(q) for q in net)
        lines.append(
            f"bicubic_patch {{ type 1 flatness {flatness!r} u_steps {STEPS} v_steps {STEPS} {points} "
            "texture { pigment { average pigment_map { "
            "[1 function { High(x, y, z) } color_map { [0 rgb 0] [1 rgb <3, 0, 0>] }] "
            "[1 function { Low(x, y, z) } color_map { [0 rgb 0] [1 rgb <0, 3, 0>] }] "
            f"[1 color rgb <0, 0, {3 * (p + 1) / LEVELS!r}>] }} }} "
            "finish { emission 1 diffuse 0 ambient 0 specular 0 } } }")
    return "\n".join(lines) + "\n"


def read_ppm16(path) -> np.ndarray:
    """(H, W, 3) uint16 of a binary 16-bit PPM (P6, maxval 65535)."""
    data = open(path, "rb").read()
    fields, pos = [], 0
    while len(fields) < 4:  # magic, width, height, maxval; whitespace and '#' comments between them
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos)
        elif data[pos:pos + 1].isspace():
            pos += 1
        else:
            end = pos
            while not data[end:end + 1].isspace():
                end += 1
            fields.append(data[pos:end])
            pos = end
    w, h = int(fields[1]), int(fields[2])
    return np.frombuffer(data, ">u2", count=w * h * 3, offset=pos + 1).reshape(h, w, 3)


def trace(scene, view, origins, dirs, flatness: float):
    """((hit, position, patch), CPU seconds of povray, [wall, CPU] seconds of povray's parse, bounding
    and trace phases as it reports them) of the scene at `flatness`; positions on psrt's rays
    (origins, dirs (H, W, 3)) at POV-Ray's depths."""
    nets, why = bicubic_nets(scene)
    if nets is None:
        raise ValueError(f"POV-Ray peer: {why}")
    h, w = origins.shape[:2]
    lo, hi = scene.bounds()
    centre, radius = (lo + hi) / 2, float(norm(hi - lo)) / 2
    depth0 = max(float(norm(np.asarray(view.eye) - centre)) - radius, 0.0)
    with tempfile.TemporaryDirectory(prefix="psrt_pov") as tmp:
        src, out = os.path.join(tmp, "s.pov"), os.path.join(tmp, "s.ppm")
        with open(src, "w") as f:
            f.write(pov_source(nets, view, w, h, depth0, 2 * radius, flatness))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run(["povray", f"+I{src}", f"+O{out}", f"+W{w}", f"+H{h}", "+FP16", "+WT1", "-A", "-D",
                               "-P", "File_Gamma=1.0"], check=True, capture_output=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        rgb = read_ppm16(out).astype(np.int64)
    seconds = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    phases = PHASE.findall(done.stderr.decode(errors="replace"))
    wall_cpu = [sum(float(w) for w, _ in phases), sum(float(c) for _, c in phases)]
    hit = rgb[..., 2] > 0
    depth = depth0 + (rgb[..., 0] + rgb[..., 1] / LEVELS) / LEVELS * 2 * radius
    unit = dirs / np.sqrt(np.sum(dirs * dirs, axis=-1, keepdims=True))
    position = np.where(hit[..., None], origins + depth[..., None] * unit, np.nan)
    return (hit, position, np.where(hit, rgb[..., 2] - 1, -1)), seconds, wall_cpu
