"""Circles and surfaces of revolution as exact NURBS (rational quadratic arcs of at most 90
degrees, NURBS Book A7.1 and A8.1), with the map between the circle's spline parameter and its
angle that trimming curves on such surfaces need (CircleParam)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracer.fixed_order import dot, norm
from tracer.nurbs import NurbsCurve, NurbsError, NurbsSurface, bezier_knots


@dataclass(frozen=True)
class CircleParam:
    """The parameter of an exact rational-quadratic circle against the angle.

    The arc [a0, a1] is split into n equal arcs of at most 90 degrees; arc k is
    a symmetric rational quadratic (weights 1, cos(h), 1, h its half angle) on
    the knot span [a0 + 2hk, a0 + 2h(k+1)]. The spline parameter t equals the
    angle at every knot and differs in between: on an arc,
    tan(psi/2) = tan(h/2) * (2*tau - 1), psi the angle from the arc's middle
    and tau the local parameter.
    """
    a0: float
    a1: float
    n: int

    @staticmethod
    def for_sweep(a0: float, a1: float) -> "CircleParam":
        sweep = a1 - a0
        if not (0 < sweep <= 2 * math.pi + 1e-9):
            raise NurbsError(f"angle range [{a0:g}, {a1:g}] must sweep (0, 2*pi]")
        return CircleParam(a0, a1, max(1, math.ceil(sweep / (math.pi / 2) - 1e-9)))

    @property
    def half(self) -> float:
        return (self.a1 - self.a0) / (2 * self.n)

    def knots(self) -> np.ndarray:
        brk = self.a0 + 2 * self.half * np.arange(self.n + 1)
        brk[-1] = self.a1
        return bezier_knots(brk, 2)

    def weights(self) -> np.ndarray:
        """(2n + 1,) weights of the arc's control points."""
        w = np.ones(2 * self.n + 1)
        w[1::2] = math.cos(self.half)
        return w

    def angles(self) -> np.ndarray:
        """(2n + 1,) angle of each control point direction (middle ones at the arc middles)."""
        return self.a0 + self.half * np.arange(2 * self.n + 1)

    def directions(self) -> np.ndarray:
        """(2n + 1, 2) control point directions (cos, sin) of the arc on the unit circle.

        Ends of arcs lie on the circle; each middle point is the corner of the
        two end tangents, (P0 + P2) / (1 + cos 2h). Multiples of 90 degrees
        give exact 0 and +-1, so the standard 9-point circle comes out exact.
        """
        full = abs(self.a1 - self.a0 - 2 * math.pi) < 1e-12  # closed: end = start exactly
        ends = np.array([_cos_sin(self.a0 + 2 * self.half * k) for k in range(self.n)]
                        + [_cos_sin(self.a0 if full else self.a1)])
        out = np.empty((2 * self.n + 1, 2))
        out[0::2] = ends
        out[1::2] = (ends[:-1] + ends[1:]) / (1.0 + _cos_sin(2 * self.half)[0])
        return out

    def breaks(self) -> np.ndarray:
        """Inner knots: angles where param() is only C1."""
        return self.a0 + 2 * self.half * np.arange(1, self.n)

    def _arc(self, theta):
        k = np.clip(np.floor((np.asarray(theta, float) - self.a0) / (2 * self.half)), 0, self.n - 1)
        return k, self.a0 + (2 * k + 1) * self.half

    def param(self, theta):
        """Spline parameter t of angle theta (vectorised)."""
        k, mid = self._arc(theta)
        tau = 0.5 * (1 + np.tan((np.asarray(theta, float) - mid) / 2) / math.tan(self.half / 2))
        return self.a0 + 2 * self.half * (k + tau)

    def dparam(self, theta):
        """dt/dtheta (vectorised)."""
        k, mid = self._arc(theta)
        c = np.cos((np.asarray(theta, float) - mid) / 2)
        return self.half / (2 * math.tan(self.half / 2) * c * c)

    def angle(self, t):
        """Angle of spline parameter t (inverse of `param`)."""
        k = np.clip(np.floor((np.asarray(t, float) - self.a0) / (2 * self.half)), 0, self.n - 1)
        tau = (np.asarray(t, float) - self.a0) / (2 * self.half) - k
        mid = self.a0 + (2 * k + 1) * self.half
        return mid + 2 * np.arctan(math.tan(self.half / 2) * (2 * tau - 1))


def _cos_sin(a: float) -> tuple[float, float]:
    """cos and sin, exact (0, +-1) at multiples of 90 degrees."""
    q = a / (math.pi / 2)
    k = round(q)
    if abs(q - k) < 1e-13:
        return [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][k % 4]
    return math.cos(a), math.sin(a)


def revolve(generatrix: NurbsCurve, origin, axis, a0: float, a1: float) -> tuple[NurbsSurface, CircleParam]:
    """Exact NURBS surface of revolution (NURBS Book A8.1): u along the generatrix, v the turn.

    The generatrix (a 3-D NURBS curve) turns right-handed about `axis` through
    `origin` from angle a0 to a1; v runs over [a0, a1] with the circle
    parameterisation of the returned CircleParam (exact angle only at knots).
    """
    d = np.asarray(axis, dtype=np.float64)
    if not norm(d) > 0:
        raise NurbsError("axis of revolution has zero length")
    d = d / norm(d)
    o = np.asarray(origin, dtype=np.float64)
    circ = CircleParam.for_sweep(a0, a1)
    gp = generatrix.points
    cp = gp[:, :3] - o
    centre = o + np.outer(dot(cp, d), d)            # foot of each point on the axis
    x = gp[:, :3] - centre                          # radial vector (zero on the axis)
    y = np.cross(d, x)
    dirs = circ.directions()                        # (2n+1, 2) multipliers of x and y
    net = np.empty((len(dirs), len(gp), 4))
    for j, (c, si) in enumerate(dirs):
        net[j, :, :3] = centre + c * x + si * y
    net[:, :, 3] = np.outer(circ.weights(), gp[:, 3])
    surf = NurbsSurface(generatrix.degree, 2, generatrix.knots, circ.knots(), net,
                        (*generatrix.domain, a0, a1))
    return surf, circ


def circle_arc(centre, radius: float, a0: float, a1: float, x_axis=(1.0, 0.0), y_axis=(0.0, 1.0)):
    """Exact rational quadratic arc as a NurbsCurve in the plane of x_axis, y_axis."""
    circ = CircleParam.for_sweep(a0, a1)
    xa, ya, c = (np.asarray(v, dtype=np.float64) for v in (x_axis, y_axis, centre))
    d = circ.directions()
    pts = c + radius * (d[:, :1] * xa + d[:, 1:] * ya)
    return NurbsCurve(2, circ.knots(), np.column_stack([pts, circ.weights()])), circ
