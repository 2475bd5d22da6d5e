"""Scene loading: `.json` scene files and bare `.bpt`, `.obj`, `.igs` files into flat arrays.

The format is the contract in /work/shared/scene-format.md. Every problem is a
SceneError naming the file and the JSON key path (or the file's line).

Free-form files (OBJ free-form, IGES) hold NURBS surfaces; each becomes its
Bezier patches (v span outer, u span inner, see tracer.nurbs) in file order.
patch_surface maps a patch back to Scene.surfaces and patch_domain gives the
patch's rectangle in that surface's parameters, so a hit at patch parameters
(s, t) in [0, 1]^2 lies at u = u0 + s*(u1 - u0), v = v0 + t*(v1 - v0).
Trimming loops live in those surface parameters (Scene.trims, tracer.trim).
"""
import dataclasses
import json
import os
import re
from dataclasses import dataclass

import numpy as np

from tracer.errors import SceneError
from tracer.fixed_order import affine
from tracer.formats.source import check_file, quote, read_text, shown
from tracer.formats.bpt import MAX_DEGREE, PatchArrays, PatchData, load_bpt_arrays
from tracer.formats.losses import has_losses, summary_line
from tracer.formats.obj import load_obj
from tracer.json_checks import (JSON_INT_DIGITS, as_list, as_object, as_string, check_keys, is_int, json_int,
                                no_duplicates, numbers, show_value)
from tracer.nurbs import FreeformModel, SurfaceInfo
from tracer.scene_parts import (DEFAULT_MATERIAL, Camera, Light, Material, default_material, parse_camera,
                                parse_image, parse_light, parse_material, parse_transform)
from tracer.trim import TrimSet, build_trimset

__all__ = ["Camera", "Light", "Material", "Scene", "SceneError", "SceneObject", "load_scene", "scene_from_dict"]

_TOP_KEYS = ("camera", "image", "objects", "materials", "lights")
_OBJECT_KEYS = ("file", "patches", "transform", "material", "name")
_PATCH_KEYS = ("degree", "points")
_FILE_TYPES = (".bpt", ".obj", ".igs", ".iges")


@dataclass
class SceneObject:
    name: str
    source: str  # file path as written in the scene, or "inline"
    material: int  # index into Scene.materials
    first_patch: int
    patch_count: int


@dataclass
class Scene:
    """A scene flattened into per-patch arrays; patches in scene order."""
    path: str | None
    points: np.ndarray          # (total_points, 4) float64, world space, Euclidean x y z + weight w
    point_start: np.ndarray     # (n_patches + 1,) int64
    degree_u: np.ndarray        # (n_patches,) int32
    degree_v: np.ndarray        # (n_patches,) int32
    rational: np.ndarray        # (n_patches,) bool
    patch_object: np.ndarray    # (n_patches,) int32
    patch_material: np.ndarray  # (n_patches,) int32
    patch_line: np.ndarray      # (n_patches,) int32, -1 for inline patches
    objects: list[SceneObject]
    materials: list[Material]
    lights: list[Light]
    camera: Camera | None
    image_size: tuple[int, int] | None  # (width, height)
    patch_surface: np.ndarray | None = None  # (n_patches,) int32 index into surfaces, -1: plain Bezier
    patch_domain: np.ndarray | None = None   # (n_patches, 4) float64 u0 u1 v0 v1 (0 1 0 1 if plain)
    surfaces: list[SurfaceInfo] | None = None  # free-form surfaces in scene order
    trims: TrimSet | None = None             # trimming loops per surface (tracer.trim)
    import_report: dict | None = None        # per free-form file (source): what was converted

    def __post_init__(self):
        n = len(self.degree_u)
        if self.patch_surface is None:
            self.patch_surface = np.full(n, -1, np.int32)
        if self.patch_domain is None:
            self.patch_domain = np.tile(np.array([0.0, 1.0, 0.0, 1.0]), (n, 1))
        if self.surfaces is None:
            self.surfaces = []
        if self.trims is None:
            self.trims = build_trimset([[] for _ in self.surfaces])
        if self.import_report is None:
            self.import_report = {}

    @property
    def n_patches(self) -> int:
        return len(self.degree_u)

    @property
    def patch_has_trim(self) -> np.ndarray:
        """(n_patches,) bool: the patch's surface has trimming loops."""
        s = self.patch_surface
        out = np.zeros(len(s), bool)
        out[s >= 0] = self.trims.has_trim[s[s >= 0]]
        return out

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi), each (3,): the box of all control points."""
        xyz = self.points[:, :3]
        return xyz.min(axis=0), xyz.max(axis=0)


def load_scene(path) -> Scene:
    """Load a `.json` scene, or a bare `.bpt`, `.obj`, `.igs`/`.iges` file as a one-object scene."""
    label = str(path)
    ext = os.path.splitext(label)[1].lower()
    if ext in _FILE_TYPES:
        name = os.path.splitext(os.path.basename(label))[0]
        obj = _Obj(name, label, DEFAULT_MATERIAL, None, np.eye(4))
        _read_file(obj, path, ext)
        return _assemble(label, [obj], [default_material()], [], None, None)
    if ext != ".json":
        raise SceneError(f"unsupported scene file type {quote(ext)} (supported: .json, "
                         f"{', '.join(_FILE_TYPES)})", path=label)
    text = read_text(path)
    try:
        data = json.loads(text, object_pairs_hook=no_duplicates, parse_int=json_int)
    except SceneError as e:
        e.path = label
        if e.line is None and (long := re.search("[0-9]{%d,}" % (JSON_INT_DIGITS + 1), text)):
            e.line = text.count("\n", 0, long.start()) + 1
        raise
    except json.JSONDecodeError as e:
        raise SceneError(f"invalid JSON (column {e.colno}): {e.msg}",
                         path=label, line=e.lineno) from None
    except RecursionError:
        raise SceneError("invalid JSON: nested too deeply", path=label) from None
    return scene_from_dict(data, label, os.path.dirname(os.path.abspath(label)))


def scene_from_dict(data, path_label: str, base_dir: str) -> Scene:
    """Build a Scene from parsed JSON; `file` paths resolve against base_dir."""
    try:
        return _scene(data, path_label, base_dir)
    except SceneError as e:
        if e.path is None:  # errors from the JSON checks name the scene file
            e.path = path_label
        raise


# ---- building -----------------------------------------------------------------

@dataclass
class _Obj:
    name: str
    source: str
    material: str
    patches: PatchArrays | None
    transform: np.ndarray  # (4, 4)
    model: FreeformModel | None = None   # free-form files: surfaces, loops, report
    patch_surface: list[int] | None = None  # per patch: index into model.surfaces
    patch_domain: list[np.ndarray] | None = None  # per surface: (its patches, 4)


def _read_file(o: _Obj, path, ext: str) -> None:
    """Fill o's patches from a .bpt, .obj or .igs/.iges file."""
    if ext == ".bpt":
        o.patches = load_bpt_arrays(path)
        return
    if ext == ".obj":
        model = load_obj(path)
    else:
        from tracer.formats.iges import load_iges  # needs pyiges; import only when used
        model = load_iges(path)
    if not model.surfaces:
        lost = f": {summary_line(model.report)}" if has_losses(model.report) else ""
        raise SceneError(f"no free-form surfaces in the file{lost}", path=str(path))
    o.model, o.patch_surface, o.patch_domain, parts = model, [], [], []
    for si, fs in enumerate(model.surfaces):
        net = fs.surface.bezier_patches()
        k = len(net.points)
        parts.append(PatchArrays(np.concatenate(net.points), np.arange(k + 1) * len(net.points[0]),
                                 np.full(k, net.degree_u), np.full(k, net.degree_v),
                                 np.asarray(net.rational, bool),
                                 np.full(k, fs.info.entity.get("line", -1))))
        o.patch_surface += [si] * k
        o.patch_domain.append(net.domains)
    o.patches = PatchArrays.join(parts)


def _scene(data, label, base_dir) -> Scene:
    check_keys(data, _TOP_KEYS, "", required=("objects",))
    materials = [parse_material(name, m, f"materials.{name}")
                 for name, m in as_object(data.get("materials", {}), "materials").items()]
    objects = as_list(data["objects"], "objects")
    if not objects:
        raise SceneError("expected at least one object", key="objects")
    objs = [_object(o, f"objects[{i}]", i, base_dir) for i, o in enumerate(objects)]
    names = [m.name for m in materials]
    for i, o in enumerate(objs):
        if o.material == DEFAULT_MATERIAL and DEFAULT_MATERIAL not in names:
            materials.append(default_material())
            names.append(DEFAULT_MATERIAL)
        if o.material not in names:
            raise SceneError(f"undefined material {quote(o.material)} "
                             f"(defined: {shown(', '.join(names)) or 'none'})",
                             key=f"objects[{i}].material")
    lights = [parse_light(spec, f"lights[{i}]")
              for i, spec in enumerate(as_list(data.get("lights", []), "lights"))]
    camera = parse_camera(data["camera"]) if "camera" in data else None
    image = parse_image(data["image"]) if "image" in data else None
    return _assemble(label, objs, materials, lights, camera, image)


def _assemble(label, objs, materials, lights, camera, image) -> Scene:
    names = [m.name for m in materials]
    parts, pobj, pmat, objects = [], [], [], []
    psurf, pdom, surfaces, loops, reports = [], [], [], [], {}
    first_patch = 0
    for oi, o in enumerate(objs):
        mi = names.index(o.material)
        objects.append(SceneObject(o.name, o.source, mi, first_patch, len(o.patches)))
        if o.model is None:
            psurf.append(np.full(len(o.patches), -1, np.int32))
            pdom.append(np.tile([0.0, 1.0, 0.0, 1.0], (len(o.patches), 1)))
        else:
            first = np.searchsorted(o.patch_surface, np.arange(len(o.model.surfaces)))
            for si, fs in enumerate(o.model.surfaces):
                info = dataclasses.replace(fs.info, object=oi, first_patch=first_patch + int(first[si]),
                                           patch_count=len(o.patch_domain[si]))
                surfaces.append(info)
                loops.append(fs.loops)
            psurf.append(np.asarray(o.patch_surface, np.int32) + (len(surfaces)
                                                                  - len(o.model.surfaces)))
            pdom.append(np.concatenate(o.patch_domain))
            reports[o.source] = o.model.report
        p = o.patches
        with np.errstate(over="ignore", invalid="ignore"):
            xyz = affine(p.points[:, :3], o.transform)  # the Euclidean points, keep w
        if not np.all(np.isfinite(xyz)):
            raise SceneError(f"the transform takes control points past float64's largest number, "
                             f"{np.finfo(np.float64).max:.3g}", key=f"objects[{oi}].transform")
        parts.append(dataclasses.replace(p, points=np.column_stack([xyz, p.points[:, 3]])))
        pobj.append(np.full(len(p), oi, np.int32))
        pmat.append(np.full(len(p), mi, np.int32))
        first_patch += len(p)
    p = PatchArrays.join(parts)
    return Scene(
        path=label, points=p.points, point_start=p.start,
        degree_u=p.degree_u, degree_v=p.degree_v,
        rational=p.rational, patch_object=np.concatenate(pobj),
        patch_material=np.concatenate(pmat), patch_line=p.line,
        objects=objects, materials=materials, lights=lights, camera=camera,
        image_size=image, patch_surface=np.concatenate(psurf).astype(np.int32),
        patch_domain=np.concatenate(pdom).astype(np.float64).reshape(-1, 4),
        surfaces=surfaces, trims=build_trimset(loops), import_report=reports)


def _object(o, key, index, base_dir) -> _Obj:
    check_keys(o, _OBJECT_KEYS, key)
    if ("file" in o) == ("patches" in o):
        raise SceneError("expected exactly one of 'file' or 'patches'", key=key)
    material = as_string(o.get("material", DEFAULT_MATERIAL), f"{key}.material")
    transform = parse_transform(o["transform"], f"{key}.transform") if "transform" in o else np.eye(4)
    if "file" in o:
        source = as_string(o["file"], f"{key}.file")
        ext = os.path.splitext(source)[1].lower()
        if ext not in _FILE_TYPES:
            raise SceneError(f"unsupported file type {quote(ext)} (supported: "
                             f"{', '.join(_FILE_TYPES)})", key=f"{key}.file")
        resolved = os.path.normpath(os.path.join(base_dir, source))
        check_file(resolved, key=f"{key}.file")
        loaded = _Obj("", source, material, None, transform)
        _read_file(loaded, resolved, ext)
        name = os.path.splitext(os.path.basename(source))[0]
    else:
        plist = as_list(o["patches"], f"{key}.patches")
        if not plist:
            raise SceneError("expected at least one patch", key=f"{key}.patches")
        patches = [_inline_patch(p, f"{key}.patches[{j}]") for j, p in enumerate(plist)]
        source, name = "inline", f"object{index}"
        loaded = None
    if "name" in o:
        name = as_string(o["name"], f"{key}.name")
    if loaded is not None:
        loaded.name = name
        return loaded
    return _Obj(name, source, material, PatchArrays.of(patches), transform)


def _inline_patch(p, key) -> PatchData:
    check_keys(p, _PATCH_KEYS, key, required=_PATCH_KEYS)
    deg = as_list(p["degree"], f"{key}.degree")
    if len(deg) != 2 or not all(is_int(d) and 1 <= d <= MAX_DEGREE for d in deg):
        raise SceneError(f"expected [m, n], two integers in 1..{MAX_DEGREE}, "
                         f"got {show_value(deg)}", key=f"{key}.degree")
    m, n = deg
    count = (m + 1) * (n + 1)
    pts = as_list(p["points"], f"{key}.points")
    if len(pts) != count:
        raise SceneError(f"degree [{m}, {n}] needs {count} points, got {len(pts)}",
                         key=f"{key}.points")
    first = pts[0] if pts else None
    if not isinstance(first, list) or len(first) not in (3, 4):
        raise SceneError(f"expected a list of 3 or 4 numbers (x y z or x y z w), "
                         f"got {show_value(first)}", key=f"{key}.points[0]")
    width, rows = len(first), []
    for k, q in enumerate(pts):
        rows.append(numbers(q, width, f"{key}.points[{k}]"))
        if width == 4 and rows[-1][3] <= 0:
            raise SceneError(f"weight must be > 0, got {show_value(q[3])}", key=f"{key}.points[{k}]")
    arr = np.ones((count, 4))
    arr[:, :width] = rows
    return PatchData(m, n, arr, width == 4, -1)
