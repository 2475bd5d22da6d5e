"""The study's peers (tracer/study.py): what psrt's direct intersection is measured against.

Tessellation: every patch tessellated uniformly into N x N quads (two triangles each) in float64,
traced with Embree through trimesh's embreex interface (first hit), on the very rays of psrt's
float32 series. Timed as a first image (tessellate + build + trace) and per frame (the trace of the
built scene again), CPU time of the process (Embree's own threads included). Trims are ignored.
"""
from __future__ import annotations

import numpy as np

from .stress import grid_points

TESSELLATIONS = (2, 4, 8, 16, 32, 64, 128, 256)
# Tessellations with more vertices than this are left out (and named in the results): the float64
# grid alone takes 24 bytes a vertex, and trimesh and Embree several copies more.
MAX_VERTICES = 20_000_000


def fits(scene, n: int) -> bool:
    """Whether the scene tessellated at n x n per patch stays within MAX_VERTICES."""
    return scene.n_patches * (n + 1) ** 2 <= MAX_VERTICES


def tessellate(scene, n: int):
    """(vertices (V, 3), faces (F, 3) int64, face_patch (F,) int64): each patch's (n + 1)^2 grid of
    surface points in float64, its quads cut into two triangles, faces patch by patch."""
    ts = np.linspace(0.0, 1.0, n + 1)
    grid = np.zeros((scene.n_patches, n + 1, n + 1, 3))
    for patches, xyz in grid_points(scene, ts):
        grid[patches] = xyz.transpose(2, 0, 1, 3)  # [patch, v, u, xyz]
    corner = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)[:-1, :-1].reshape(-1)
    a, b, c, e = corner, corner + 1, corner + n + 2, corner + n + 1   # the quad's corners, counter-clockwise
    quad = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, e], 1)])
    per_patch = (n + 1) ** 2
    faces = (np.arange(scene.n_patches)[:, None, None] * per_patch + quad[None]).reshape(-1, 3)
    face_patch = np.repeat(np.arange(scene.n_patches), len(quad))
    return grid.reshape(-1, 3), faces, face_patch


def embree_trace(intersector, origins, dirs, face_patch):
    """(hit (H, W), position (H, W, 3), patch (H, W)) of the first hits of rays (H, W, 3)."""
    h, w = origins.shape[:2]
    tri, ray, location = intersector.intersects_id(origins.reshape(-1, 3).astype(np.float64),
                                                   dirs.reshape(-1, 3).astype(np.float64),
                                                   multiple_hits=False, return_locations=True)
    hit = np.zeros(h * w, bool)
    position = np.full((h * w, 3), np.nan)
    patch = np.full(h * w, -1, np.int64)
    hit[ray], position[ray], patch[ray] = True, location, face_patch[tri]
    return hit.reshape(h, w), position.reshape(h, w, 3), patch.reshape(h, w)


def embree_scene(scene, n: int):
    """(intersector, face_patch): the scene tessellated at n and handed to Embree (built lazily, on
    the first trace)."""
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    vertices, faces, face_patch = tessellate(scene, n)
    mesh = trimesh.Trimesh(vertices, faces, process=False)  # keep the faces as made: face -> patch
    return RayMeshIntersector(mesh), face_patch


_WARM = []


def warm_up_embree() -> None:
    """Load Embree and trimesh's ray code once per process, so no point's time includes it."""
    if _WARM:
        return
    _WARM.append(True)
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    RayMeshIntersector(trimesh.creation.icosahedron()).intersects_id(
        np.zeros((1, 3)), np.ones((1, 3)), multiple_hits=False, return_locations=True)
