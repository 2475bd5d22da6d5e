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
import math
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
from tracer.nurbs import FreeformModel, SurfaceInfo
from tracer.trim import TrimSet, build_trimset

MAX_IMAGE_SIZE = 16384
MAX_TRANSFORM_CONDITION = 1e12  # a transform worse conditioned than this counts as singular
JSON_INT_DIGITS = 400           # longer integers are no finite float64 (1.8e308 has 309 digits)
DEFAULT_MATERIAL = "default"

_TOP_KEYS = ("camera", "image", "objects", "materials", "lights")
_CAMERA_KEYS = ("eye", "look_at", "up", "fov_deg")
_IMAGE_KEYS = ("width", "height")
_OBJECT_KEYS = ("file", "patches", "transform", "material", "name")
_MATERIAL_KEYS = ("color", "reflect", "specular", "shininess", "transmit", "ior")
_PATCH_KEYS = ("degree", "points")
_LIGHT_KEYS = ("type", "intensity", "color")
AREA_SAMPLES = 16  # an area light's samples per shading point unless its "samples" says otherwise
MAX_SAMPLES = 4096
_LIGHT_SHAPE = {"point": ("position",), "sphere": ("center", "radius"),
                "segment": ("a", "b"), "rect": ("corner", "edge1", "edge2")}
_FILE_TYPES = (".bpt", ".obj", ".igs", ".iges")


@dataclass
class Material:
    name: str
    color: np.ndarray  # (3,) float64 in [0, 1]
    reflect: float = 0.0
    specular: float = 0.3
    shininess: float = 40.0
    transmit: float = 0.0  # refracted fraction (0..1)
    ior: float = 1.5       # index of refraction of the material behind the surface


@dataclass
class Light:
    type: str  # 'point' | 'sphere' | 'segment' | 'rect'
    intensity: float
    color: np.ndarray  # (3,) float64, >= 0
    position: np.ndarray | None = None  # point
    center: np.ndarray | None = None    # sphere
    radius: float | None = None         # sphere
    a: np.ndarray | None = None         # segment
    b: np.ndarray | None = None         # segment
    corner: np.ndarray | None = None    # rect
    edge1: np.ndarray | None = None     # rect
    edge2: np.ndarray | None = None     # rect
    samples: int = AREA_SAMPLES         # area lights: samples per shading point

    def centre(self) -> np.ndarray:
        """Centre of the emitter, (3,) float64."""
        if self.type == "point":
            return self.position.copy()
        if self.type == "sphere":
            return self.center.copy()
        if self.type == "segment":
            return (self.a + self.b) / 2
        return self.corner + (self.edge1 + self.edge2) / 2


@dataclass
class Camera:
    eye: np.ndarray      # (3,) float64
    look_at: np.ndarray  # (3,)
    up: np.ndarray       # (3,)
    fov_deg: float       # vertical field of view


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


def default_material() -> Material:
    return Material(DEFAULT_MATERIAL, np.array([0.8, 0.8, 0.8]))


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
        data = json.loads(text, object_pairs_hook=_no_duplicates, parse_int=_json_int)
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
    _keys(data, _TOP_KEYS, "", required=("objects",))
    materials = [_material(name, m, f"materials.{name}")
                 for name, m in _dict(data.get("materials", {}), "materials").items()]
    objects = _list(data["objects"], "objects")
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
    lights = [_light(spec, f"lights[{i}]")
              for i, spec in enumerate(_list(data.get("lights", []), "lights"))]
    camera = _camera(data["camera"]) if "camera" in data else None
    image = _image(data["image"]) if "image" in data else None
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
    _keys(o, _OBJECT_KEYS, key)
    if ("file" in o) == ("patches" in o):
        raise SceneError("expected exactly one of 'file' or 'patches'", key=key)
    material = _str(o.get("material", DEFAULT_MATERIAL), f"{key}.material")
    transform = _transform(o["transform"], f"{key}.transform") if "transform" in o else np.eye(4)
    if "file" in o:
        source = _str(o["file"], f"{key}.file")
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
        plist = _list(o["patches"], f"{key}.patches")
        if not plist:
            raise SceneError("expected at least one patch", key=f"{key}.patches")
        patches = [_inline_patch(p, f"{key}.patches[{j}]") for j, p in enumerate(plist)]
        source, name = "inline", f"object{index}"
        loaded = None
    if "name" in o:
        name = _str(o["name"], f"{key}.name")
    if loaded is not None:
        loaded.name = name
        return loaded
    return _Obj(name, source, material, PatchArrays.of(patches), transform)


def _inline_patch(p, key) -> PatchData:
    _keys(p, _PATCH_KEYS, key, required=_PATCH_KEYS)
    deg = _list(p["degree"], f"{key}.degree")
    if len(deg) != 2 or not all(_is_int(d) and 1 <= d <= MAX_DEGREE for d in deg):
        raise SceneError(f"expected [m, n], two integers in 1..{MAX_DEGREE}, "
                         f"got {_show(deg)}", key=f"{key}.degree")
    m, n = deg
    count = (m + 1) * (n + 1)
    pts = _list(p["points"], f"{key}.points")
    if len(pts) != count:
        raise SceneError(f"degree [{m}, {n}] needs {count} points, got {len(pts)}",
                         key=f"{key}.points")
    first = pts[0] if pts else None
    if not isinstance(first, list) or len(first) not in (3, 4):
        raise SceneError(f"expected a list of 3 or 4 numbers (x y z or x y z w), "
                         f"got {_show(first)}", key=f"{key}.points[0]")
    width, rows = len(first), []
    for k, q in enumerate(pts):
        rows.append(_numbers(q, width, f"{key}.points[{k}]"))
        if width == 4 and rows[-1][3] <= 0:
            raise SceneError(f"weight must be > 0, got {_show(q[3])}", key=f"{key}.points[{k}]")
    arr = np.ones((count, 4))
    arr[:, :width] = rows
    return PatchData(m, n, arr, width == 4, -1)


def _material(name, m, key) -> Material:
    _keys(m, _MATERIAL_KEYS, key)
    mat = default_material()
    mat.name = name
    if "color" in m:
        mat.color = _numbers(m["color"], 3, f"{key}.color", lo=0.0, hi=1.0)
    if "reflect" in m:
        mat.reflect = _number(m["reflect"], f"{key}.reflect", lo=0.0, hi=1.0)
    if "specular" in m:
        mat.specular = _number(m["specular"], f"{key}.specular", lo=0.0)
    if "shininess" in m:
        mat.shininess = _number(m["shininess"], f"{key}.shininess", lo=0.0, open_lo=True)
    if "transmit" in m:
        mat.transmit = _number(m["transmit"], f"{key}.transmit", lo=0.0, hi=1.0)
    if "ior" in m:
        mat.ior = _number(m["ior"], f"{key}.ior", lo=0.0, open_lo=True, hi=100.0)
    if mat.reflect + mat.transmit > 1.0:
        raise SceneError(f"reflect + transmit must be at most 1, got {mat.reflect:g} + {mat.transmit:g}", key=key)
    return mat


def _light(spec, key) -> Light:
    _dict(spec, key)
    if "type" not in spec:
        raise SceneError("missing required key 'type'", key=key)
    kind = spec["type"]
    if not isinstance(kind, str) or kind not in _LIGHT_SHAPE:
        raise SceneError(f"expected one of: {', '.join(_LIGHT_SHAPE)}, got {_show(kind)}",
                         key=f"{key}.type")
    shape = _LIGHT_SHAPE[kind]
    area = () if kind == "point" else ("samples",)
    _keys(spec, _LIGHT_KEYS + shape + area, key, required=("type",) + shape)
    light = Light(kind, _number(spec.get("intensity", 1.0), f"{key}.intensity", lo=0.0),
                  _numbers(spec.get("color", [1.0, 1.0, 1.0]), 3, f"{key}.color", lo=0.0))
    for k in shape:
        if k == "radius":
            light.radius = _number(spec[k], f"{key}.radius", lo=0.0, open_lo=True)
        else:
            setattr(light, k, _numbers(spec[k], 3, f"{key}.{k}"))
    if "samples" in spec:
        light.samples = _integer(spec["samples"], f"{key}.samples", 1, MAX_SAMPLES)
    elif kind == "point":
        light.samples = 1
    # zero-size area lights would divide by zero when sampled
    if kind == "segment" and np.array_equal(light.a, light.b):
        raise SceneError("segment light has zero length (a == b)", key=key)
    if kind == "rect" and not np.any(np.cross(light.edge1, light.edge2)):
        raise SceneError("rect light has zero area (edge1, edge2 parallel or zero)", key=key)
    return light


def _camera(c) -> Camera:
    _keys(c, _CAMERA_KEYS, "camera", required=_CAMERA_KEYS)
    cam = Camera(*(_numbers(c[k], 3, f"camera.{k}") for k in _CAMERA_KEYS[:3]),
                 fov_deg=_number(c["fov_deg"], "camera.fov_deg", lo=0.0, hi=180.0,
                                 open_lo=True, open_hi=True))
    with np.errstate(over="ignore"):
        view = cam.look_at - cam.eye
    if not np.any(view):
        raise SceneError("eye and look_at coincide", key="camera")
    if not np.all(np.isfinite(view)):
        raise SceneError("eye and look_at are too far apart (their difference overflows)",
                         key="camera")
    if not np.any(np.cross(view, cam.up)):
        raise SceneError("up is zero or parallel to the view direction", key="camera.up")
    from tracer.camera import View  # the renderer's own test, so a camera loaded is one it takes
    try:
        View(tuple(cam.eye), tuple(cam.look_at), tuple(cam.up), cam.fov_deg).basis()
    except ValueError as e:
        why = str(e).removeprefix("camera: ")
        raise SceneError(why, key="camera.up" if "up " in why else "camera") from None
    return cam


def _image(im) -> tuple[int, int]:
    _keys(im, _IMAGE_KEYS, "image", required=_IMAGE_KEYS)
    size = []
    for k in _IMAGE_KEYS:
        v = im[k]
        if not _is_int(v) or not 1 <= v <= MAX_IMAGE_SIZE:
            raise SceneError(f"expected an integer in 1..{MAX_IMAGE_SIZE}, got {_show(v)}",
                             key=f"image.{k}")
        size.append(v)
    return size[0], size[1]


def _transform(t, key) -> np.ndarray:
    m = np.array(_numbers(t, 16, key, what="16 finite numbers (row-major 4x4)")).reshape(4, 4)
    if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise SceneError(f"not affine: last row must be 0 0 0 1, got {_show(t[12:])}", key=key)
    # the condition number of the 3x3 part, scaled to entries <= 1 first: a uniform scale
    # (even 1e300, whose determinant overflows) is fine, a rank-deficient matrix is not
    lin = m[:3, :3]
    big = np.abs(lin).max()
    cond = np.linalg.cond(lin / big) if big > 0 else math.inf
    if not cond <= MAX_TRANSFORM_CONDITION:
        raise SceneError(f"singular transform: the 3x3 part is not safely invertible "
                         f"(condition number {cond:.3g}, limit {MAX_TRANSFORM_CONDITION:g})",
                         key=key)
    return m


# ---- JSON checks --------------------------------------------------------------

def _no_duplicates(pairs):
    d = {}
    for k, v in pairs:
        if k in d:
            raise SceneError(f"duplicate key {quote(k)} in a JSON object")
        d[k] = v
    return d


def _show(v, limit=60) -> str:
    """Short JSON rendering of a value for error messages."""
    try:
        s = json.dumps(v)
    except (TypeError, ValueError, RecursionError):
        s = "<" + type(v).__name__ + ">"
    return s if len(s) <= limit else s[:limit - 3] + "..."


def _got(v) -> str:
    """'a list [1, 2]', 'a string "x"', 'null', '3': the value, with its kind where useful."""
    kind = {dict: "an object ", list: "a list ", str: "a string "}.get(type(v), "")
    return kind + _show(v)


def _dict(v, key) -> dict:
    if not isinstance(v, dict):
        raise SceneError(f"expected an object, got {_got(v)}", key=key or None)
    return v


def _list(v, key) -> list:
    if not isinstance(v, list):
        raise SceneError(f"expected a list, got {_got(v)}", key=key)
    return v


def _str(v, key) -> str:
    if not isinstance(v, str) or not v:
        raise SceneError(f"expected a non-empty string, got {_show(v)}", key=key)
    return v


def _keys(d, allowed, key, required=()):
    """d must be an object whose keys are all allowed and include the required ones."""
    _dict(d, key)
    prefix = f"{key}." if key else ""
    for k in d:
        if k not in allowed:
            raise SceneError(f"unknown key (expected one of: {', '.join(allowed)})",
                             key=prefix + shown(k))
    for k in required:
        if k not in d:
            raise SceneError(f"missing required key '{k}'", key=key or None)


def _json_int(text: str) -> int:
    """JSON integers as int, but none longer than any finite number (int() has a digit limit)."""
    digits = len(text.lstrip("-"))
    if digits > JSON_INT_DIGITS:
        raise SceneError(f"a number of {digits:,} digits: too long (at most {JSON_INT_DIGITS})")
    return int(text)


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v) -> bool:
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:  # an integer too large for a float
        return False


def _number(v, key, lo=None, hi=None, open_lo=False, open_hi=False) -> float:
    if not _is_number(v):
        raise SceneError(f"expected a finite number, got {_show(v)}", key=key)
    v = float(v)
    if (lo is not None and (v < lo or (open_lo and v == lo))) or \
       (hi is not None and (v > hi or (open_hi and v == hi))):
        if hi is None:
            rng = f"{'>' if open_lo else '>='} {lo:g}"
        else:
            rng = "in " + ("(" if open_lo else "[") + f"{lo:g}, {hi:g}" + (")" if open_hi else "]")
        raise SceneError(f"expected a number {rng}, got {_show(v)}", key=key)
    return v


def _numbers(v, count, key, lo=None, hi=None, what=None) -> np.ndarray:
    """A list of `count` finite numbers (optionally in [lo, hi]) as float64."""
    what = what or f"{count} finite numbers"
    if not isinstance(v, list) or len(v) != count or not all(_is_number(x) for x in v):
        raise SceneError(f"expected a list of {what}, got {_show(v)}", key=key)
    for i, x in enumerate(v):
        _number(x, f"{key}[{i}]", lo=lo, hi=hi)
    return np.array(v, dtype=np.float64)


def _integer(v, key, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise SceneError(f"expected an integer in [{lo}, {hi}], got {_show(v)}", key=key)
    return int(v)
