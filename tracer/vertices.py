"""The vertices of the ray trees lighting.py walks, level by level, and what happens at them:
facing normals, Fresnel's reflectance, and the background seen by rays that leave the scene."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .shade import BG_BOTTOM, BG_TOP, srgb_decode


@dataclass
class Vertices:
    """m hits of one level of the ray trees of a unit: the unit's pixel index, the path code (1
    primary; 2c reflected, 2c + 1 refracted from c), the weight of their radiance, the hit box
    and its centre, the unit normal facing the incoming ray, the incoming unit direction, the
    patch and the (surface's) parameters of the hit, the threshold of detail there and its growth
    per unit length along the rays leaving it, and whether the path is inside a refracting body."""

    pix: np.ndarray
    code: np.ndarray
    weight: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    d: np.ndarray
    patch: np.ndarray
    uv: np.ndarray
    threshold: np.ndarray
    grow: np.ndarray
    inside: np.ndarray

    def take(self, keep) -> "Vertices":
        return Vertices(*(getattr(self, f)[keep] for f in self.__dataclass_fields__))


def facing(normal, d):
    """Normals turned to face against the directions d."""
    return np.where(np.sum(normal * d, axis=-1, keepdims=True) > 0, -normal, normal)


def schlick(cos_i: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Fresnel reflectance by Schlick's approximation for light arriving at cos_i to the normal from
    a medium of relative index 1 / eta (eta = n_from / n_to); 1 under total internal reflection."""
    sin2_t = eta * eta * (1.0 - cos_i * cos_i)
    r0 = ((1.0 - eta) / (1.0 + eta)) ** 2
    return np.where(sin2_t >= 1.0, 1.0, r0 + (1.0 - r0) * (1.0 - cos_i) ** 5)


def environment(d: np.ndarray) -> np.ndarray:
    """Linear radiance of the background's grey seen along unit directions d (k, 3): lighter
    upwards (+z), between the display gradient's ends."""
    g = BG_BOTTOM + (BG_TOP - BG_BOTTOM) * 0.5 * (1.0 + d[:, 2:3])
    return np.repeat(srgb_decode(g), 3, axis=1)
