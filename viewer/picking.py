"""From window coordinates to image pixels, and from a pixel to its subdivision trace.

The inspector traces the clicked pixel's ray exactly as the renderer does (same
primary rays, same kernel, same options) with step recording, plus the float64
reference trace of the same ray for its error; then the pixel's ray tree (tracer.ray_tree)
with each ray's subdivision trace.
"""
from __future__ import annotations

import numpy as np

from tracer.camera import primary_rays
from tracer.search_steps import EVENT_NAMES
from tracer.options import Options
from tracer.plot import EVENT_COLOURS
from tracer.ray_tree import RayTree, ray_tree, trace_steps
from tracer.trace_one import PixelTrace, trace_ray_steps
from tracer.variants import COMPILED, label, variant_for

from .state import Inspection
from .surface_info import hit_surface, info_json

MAX_OUTLINED_BOXES = 4000
MAX_TRACED_RAYS = 256  # rays of a tree given their subdivision trace (thousands of light samples would take long)
CURRENT_RGBA = (1.0, 1.0, 1.0, 1.0)
HIT_BOX_RGBA = (1.0, 0.1, 0.1, 1.0)
# Edges of a box as pairs of corner indices; corner k has x = bit 0, y = bit 1, z = bit 2.
_EDGES = np.array([(a, b) for a in range(8) for b in range(8) if a < b and bin(a ^ b).count("1") == 1])


def window_to_pixel(region, image_size, mx: float, my: float):
    """Image pixel (column, row) under window point (mx, my), or None outside the image."""
    x0, y0, w, h = region
    iw, ih = image_size
    if w <= 0 or h <= 0 or not (x0 <= mx < x0 + w and y0 <= my < y0 + h):
        return None
    px, py = int((mx - x0) * iw / w), int((my - y0) * ih / h)
    return (px, py) if 0 <= px < iw and 0 <= py < ih else None


def pixel_to_window(region, image_size, px: int, py: int):
    """Window coordinates of the centre of image pixel (px, py)."""
    x0, y0, w, h = region
    iw, ih = image_size
    return x0 + (px + 0.5) * w / iw, y0 + (py + 0.5) * h / ih


def pixel_ray(view, size, precision: str, px: int, py: int):
    """Origin, direction and pixel angle of pixel (px, py): the renderer's own ray."""
    width, height = size
    origins, dirs = primary_rays(view, width, height, precision)
    return origins[py, px], dirs[py, px], view.pixel_angle(height)


REFERENCE_OPTIONS = Options(criterion="float", precision="f64")


def uncompiled_variants(geometry, scene, opts: Options, tree: bool = False) -> list:
    """Labels of the step-recording kernel variants inspect_pixel (or with `tree`, inspect_tree: its
    secondary rays go through the BVH) needs and this process has not compiled (or loaded) yet:
    the first inspection compiles them."""
    if tree:
        geom, bvh = geometry.get(scene, opts.precision), opts.with_(accel="bvh")
        needed = [variant_for(geom, bvh, trace=True, driver=d) for d in ("closest", "any")]
    else:
        needed = [variant_for(geometry.get(scene, o.precision), o, trace=True) for o in (opts, REFERENCE_OPTIONS)]
    return [label(v) for v in dict.fromkeys(needed) if ("ray", v) not in COMPILED]


def inspect_pixel(geometry, scene, opts: Options, view, size, px: int, py: int) -> Inspection:
    """Trace pixel (px, py) with step recording in the working options and in float64."""
    origin, direction, angle = pixel_ray(view, size, opts.precision, px, py)
    trace = trace_ray_steps(geometry.get(scene, opts.precision), opts, origin, direction, angle, (px, py))
    ref = trace_ray_steps(geometry.get(scene, "f64"), REFERENCE_OPTIONS, origin, direction, 0.0, (px, py))
    error = None
    if trace.hit and ref.hit:
        error = float(np.sum(np.abs(trace.position - ref.position)))
    # The hit's surface (NURBS, IGES entity, trim loops): gathered once here, where the scene is at hand.
    surface = hit_surface(scene, trace.patch, trace.uv) if trace.hit else None
    return Inspection((px, py), trace, ref, len(trace.steps_f) - 1, error, view, opts, surface)


def inspect_tree(geometry, scene, opts: Options, view, size, px: int, py: int) -> RayTree:
    """Pixel (px, py)'s ray tree, its first MAX_TRACED_RAYS rays with their subdivision traces."""
    geom = geometry.get(scene, opts.precision)
    tree = ray_tree(scene, opts, px, py, size=size, view=view, geometry=geom)
    trace_steps(tree, scene, geom, opts, view, size, MAX_TRACED_RAYS)
    return tree


def shown_trace(ins: Inspection) -> PixelTrace:
    """The subdivision trace the inspector shows: the chosen ray's of the tree, else the pixel's."""
    tree = ins.tree
    if tree is not None and 0 < ins.ray < len(tree.rays) and tree.rays[ins.ray].steps is not None:
        return tree.rays[ins.ray].steps
    return ins.trace


def inspection_surface(ins: Inspection) -> dict | None:
    """The inspected hit's surface_info.hit_surface(...), or None (a miss, or not gathered)."""
    return ins.surface


def inspection_json(ins: Inspection) -> dict:
    """The contract's trace JSON for the inspected pixel, with the error against float64 and the
    hit's surface (surface_info.hit_surface: NURBS surface, parameters, trim loops) added."""
    out = ins.trace.to_json()
    ref = ins.reference
    out["error"] = ins.error
    out["reference"] = {"hit": bool(ref.hit), "patch": int(ref.patch),
                        "position": [float(v) for v in ref.position] if ref.hit else None} if ref else None
    out["options"] = {k: getattr(ins.opts, k) for k in ins.opts.__dataclass_fields__} if ins.opts else None
    out["surface"] = info_json(inspection_surface(ins))
    if ins.tree is not None:  # a new key, as `psrt trace --rays` writes it
        out["ray_tree"] = ins.tree.to_json()
    return out


def box_lines(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(n, 24, 3) edge endpoints of n boxes."""
    bits = np.array([[(k >> a) & 1 for a in range(3)] for k in range(8)], bool)
    corners = np.where(bits[None], hi[:, None, :], lo[:, None, :])  # (n, 8, 3)
    return corners[:, _EDGES.ravel(), :]


def outline_vertices(ins: Inspection, max_boxes: int = MAX_OUTLINED_BOXES) -> np.ndarray:
    """Line vertices (rows x y z r g b a) for the boxes visited up to the chosen step.

    Boxes are coloured by their event (tracer.plot's colours), fainter the older they are;
    the chosen step's box is white and the reported hit box red, drawn last (on top).
    """
    tr = shown_trace(ins)
    k = len(tr.steps_f)
    if k == 0:
        return np.zeros((0, 7), np.float32)
    step = k - 1 if ins.step < 0 else min(ins.step, k - 1)
    first = max(0, step + 1 - max_boxes)
    sel = np.arange(first, step + 1)
    lo, hi = tr.steps_f[sel, 4:7], tr.steps_f[sel, 7:10]
    rgba = np.empty((len(sel), 4))
    events = tr.steps_i[sel, 2]
    for code, name in enumerate(EVENT_NAMES):
        rgba[events == code, :3] = np.asarray(EVENT_COLOURS[name]) / 255.0
    age = (step - sel) / max(len(sel), 1)
    rgba[:, 3] = 0.9 - 0.6 * age
    lists = [(lo, hi, rgba)]
    lists.append((tr.steps_f[[step], 4:7], tr.steps_f[[step], 7:10], np.array([CURRENT_RGBA])))
    hit_step = tr.hit_step()
    if 0 <= hit_step <= step:
        lists.append((tr.steps_f[[hit_step], 4:7], tr.steps_f[[hit_step], 7:10], np.array([HIT_BOX_RGBA])))
    out = []
    for lo_, hi_, col in lists:
        pts = box_lines(lo_, hi_).reshape(-1, 3)
        cols = np.repeat(col, 24, axis=0)
        out.append(np.concatenate([pts, cols], axis=1))
    if tr.hit and 0 <= hit_step <= step and ins.view is not None:
        out.append(hit_marker(tr.position, ins.view))
    return np.concatenate(out).astype(np.float32)


def hit_marker(position, view, size: float = 0.015, rgba=HIT_BOX_RGBA) -> np.ndarray:
    """A 3-D cross at the hit (red), `size` of the eye distance long: final boxes are sub-pixel."""
    p = np.asarray(position, float)
    arm = size * float(np.linalg.norm(p - np.asarray(view.eye, float)))
    pts = np.concatenate([[p - arm * e, p + arm * e] for e in np.eye(3)])
    return np.concatenate([pts, np.tile(rgba, (6, 1))], axis=1)


def hover_values(state, px: int, py: int) -> list:
    """(label, text) pairs describing pixel (px, py) of the current frame and reference."""
    frame = state.render.frame
    rows = [("pixel", f"{px}, {py}")]
    if frame is None or not (py < frame.hit.shape[0] and px < frame.hit.shape[1]):
        return rows
    if frame.patch[py, px] < 0 and frame.effort[py, px] == 0 and not frame.hit[py, px]:
        rows.append(("hit", "miss (or not traced yet)"))
    elif not frame.hit[py, px]:
        rows.append(("hit", "miss"))
    else:
        p = frame.position[py, px]
        rows += [("hit", f"patch {frame.patch[py, px]}"), ("t", f"{frame.t[py, px]:.6g}"),
                 ("position", f"{p[0]:.5g}, {p[1]:.5g}, {p[2]:.5g}")]
    rows.append(("effort", f"{frame.effort[py, px]} box tests"))
    ref = state.render.reference
    if ref is not None and state.render.phase == "done":
        if ref.hit[py, px] and frame.hit[py, px]:
            err = float(np.sum(np.abs(frame.position[py, px] - ref.position[py, px])))
            rows.append(("error", f"{err:.3g} (L1, world units)"))
        elif ref.hit[py, px] != frame.hit[py, px]:
            rows.append(("error", "hole" if ref.hit[py, px] else "false hit"))
    return rows
