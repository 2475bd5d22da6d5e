"""The parts of a scene file other than its objects: materials, lights, the camera, the image
size and object transforms, as records, each with the parser of its JSON value (errors name the
key path; tracer.json_checks)."""
import math
from dataclasses import dataclass

import numpy as np

from tracer.errors import SceneError
from tracer.json_checks import as_object, check_keys, integer, is_int, number, numbers, show_value

MAX_IMAGE_SIZE = 16384
MAX_TRANSFORM_CONDITION = 1e12  # a transform worse conditioned than this counts as singular
DEFAULT_MATERIAL = "default"
AREA_SAMPLES = 16  # an area light's samples per shading point unless its "samples" says otherwise
MAX_SAMPLES = 4096

CAMERA_KEYS = ("eye", "look_at", "up", "fov_deg")
IMAGE_KEYS = ("width", "height")
MATERIAL_KEYS = ("color", "reflect", "specular", "shininess", "transmit", "ior")
LIGHT_KEYS = ("type", "intensity", "color")
LIGHT_SHAPE = {"point": ("position",), "sphere": ("center", "radius"),
               "segment": ("a", "b"), "rect": ("corner", "edge1", "edge2")}


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


def default_material() -> Material:
    return Material(DEFAULT_MATERIAL, np.array([0.8, 0.8, 0.8]))



def parse_material(name, m, key) -> Material:
    check_keys(m, MATERIAL_KEYS, key)
    mat = default_material()
    mat.name = name
    if "color" in m:
        mat.color = numbers(m["color"], 3, f"{key}.color", lo=0.0, hi=1.0)
    if "reflect" in m:
        mat.reflect = number(m["reflect"], f"{key}.reflect", lo=0.0, hi=1.0)
    if "specular" in m:
        mat.specular = number(m["specular"], f"{key}.specular", lo=0.0)
    if "shininess" in m:
        mat.shininess = number(m["shininess"], f"{key}.shininess", lo=0.0, open_lo=True)
    if "transmit" in m:
        mat.transmit = number(m["transmit"], f"{key}.transmit", lo=0.0, hi=1.0)
    if "ior" in m:
        mat.ior = number(m["ior"], f"{key}.ior", lo=0.0, open_lo=True, hi=100.0)
    if mat.reflect + mat.transmit > 1.0:
        raise SceneError(f"reflect + transmit must be at most 1, got {mat.reflect:g} + {mat.transmit:g}", key=key)
    return mat


def parse_light(spec, key) -> Light:
    as_object(spec, key)
    if "type" not in spec:
        raise SceneError("missing required key 'type'", key=key)
    kind = spec["type"]
    if not isinstance(kind, str) or kind not in LIGHT_SHAPE:
        raise SceneError(f"expected one of: {', '.join(LIGHT_SHAPE)}, got {show_value(kind)}",
                         key=f"{key}.type")
    shape = LIGHT_SHAPE[kind]
    area = () if kind == "point" else ("samples",)
    check_keys(spec, LIGHT_KEYS + shape + area, key, required=("type",) + shape)
    light = Light(kind, number(spec.get("intensity", 1.0), f"{key}.intensity", lo=0.0),
                  numbers(spec.get("color", [1.0, 1.0, 1.0]), 3, f"{key}.color", lo=0.0))
    for k in shape:
        if k == "radius":
            light.radius = number(spec[k], f"{key}.radius", lo=0.0, open_lo=True)
        else:
            setattr(light, k, numbers(spec[k], 3, f"{key}.{k}"))
    if "samples" in spec:
        light.samples = integer(spec["samples"], f"{key}.samples", 1, MAX_SAMPLES)
    elif kind == "point":
        light.samples = 1
    # zero-size area lights would divide by zero when sampled
    if kind == "segment" and np.array_equal(light.a, light.b):
        raise SceneError("segment light has zero length (a == b)", key=key)
    if kind == "rect" and not np.any(np.cross(light.edge1, light.edge2)):
        raise SceneError("rect light has zero area (edge1, edge2 parallel or zero)", key=key)
    return light


def parse_camera(c) -> Camera:
    check_keys(c, CAMERA_KEYS, "camera", required=CAMERA_KEYS)
    cam = Camera(*(numbers(c[k], 3, f"camera.{k}") for k in CAMERA_KEYS[:3]),
                 fov_deg=number(c["fov_deg"], "camera.fov_deg", lo=0.0, hi=180.0,
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


def parse_image(im) -> tuple[int, int]:
    check_keys(im, IMAGE_KEYS, "image", required=IMAGE_KEYS)
    size = []
    for k in IMAGE_KEYS:
        v = im[k]
        if not is_int(v) or not 1 <= v <= MAX_IMAGE_SIZE:
            raise SceneError(f"expected an integer in 1..{MAX_IMAGE_SIZE}, got {show_value(v)}",
                             key=f"image.{k}")
        size.append(v)
    return size[0], size[1]


def parse_transform(t, key) -> np.ndarray:
    m = np.array(numbers(t, 16, key, what="16 finite numbers (row-major 4x4)")).reshape(4, 4)
    if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
        raise SceneError(f"not affine: last row must be 0 0 0 1, got {show_value(t[12:])}", key=key)
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
