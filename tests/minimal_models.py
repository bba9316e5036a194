"""Single-coordinate models of the bundled mechanisms, written from their geometry alone.

A mechanism with one degree of freedom theta and constant input torque u obeys
m(theta) theta'' + m'(theta) theta'^2 / 2 + V'(theta) = u, so about a static equilibrium
(V'(theta0) = u0) the linear model is m(theta0) dtheta'' + V''(theta0) dtheta = du.
m = sum of m_i |dG_i/dtheta|^2 + I_i (dphi_i/dtheta)^2 over the bodies, V = gravity + springs.
Exact first and second derivatives come from hyper-dual numbers (no step, no truncation error).
The geometry (lengths, masses, rod radius 0.01 m) is copied from the URDF provenance comments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

G0 = 9.81
R_ROD = 0.01


@dataclass
class HD:
    """Hyper-dual number a + b e1 + c e2 + d e1 e2 (e1^2 = e2^2 = 0)."""

    a: float
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0

    @staticmethod
    def variable(x: float) -> HD:
        return HD(x, 1.0, 1.0, 0.0)

    def _lift(self, o) -> HD:
        return o if isinstance(o, HD) else HD(float(o))

    def __add__(self, o):
        o = self._lift(o)
        return HD(self.a + o.a, self.b + o.b, self.c + o.c, self.d + o.d)

    __radd__ = __add__

    def __neg__(self):
        return HD(-self.a, -self.b, -self.c, -self.d)

    def __sub__(self, o):
        return self + (-self._lift(o))

    def __rsub__(self, o):
        return self._lift(o) - self

    def __mul__(self, o):
        o = self._lift(o)
        return HD(self.a * o.a, self.a * o.b + self.b * o.a, self.a * o.c + self.c * o.a,
                  self.a * o.d + self.b * o.c + self.c * o.b + self.d * o.a)

    __rmul__ = __mul__

    def apply(self, f0: float, f1: float, f2: float) -> HD:
        """f(self) given f, f', f'' at self.a."""
        return HD(f0, f1 * self.b, f1 * self.c, f1 * self.d + f2 * self.b * self.c)

    def __truediv__(self, o):
        o = self._lift(o)
        inv = o.apply(1 / o.a, -1 / o.a**2, 2 / o.a**3)
        return self * inv


def sin(x: HD) -> HD:
    return x.apply(math.sin(x.a), math.cos(x.a), -math.sin(x.a))


def cos(x: HD) -> HD:
    return x.apply(math.cos(x.a), -math.sin(x.a), -math.cos(x.a))


def sqrt(x: HD) -> HD:
    r = math.sqrt(x.a)
    return x.apply(r, 0.5 / r, -0.25 / r**3)


def acos(x: HD) -> HD:
    s = math.sqrt(1 - x.a**2)
    return x.apply(math.acos(x.a), -1 / s, -x.a / s**3)


def atan2(y: HD, x: HD) -> HD:
    """atan2 through its gradient and Hessian in (x, y)."""
    r2 = x.a**2 + y.a**2
    fx, fy = -y.a / r2, x.a / r2
    fxx, fyy, fxy = 2 * x.a * y.a / r2**2, -2 * x.a * y.a / r2**2, (y.a**2 - x.a**2) / r2**2
    return HD(math.atan2(y.a, x.a), fx * x.b + fy * y.b, fx * x.c + fy * y.c,
              fx * x.d + fy * y.d + fxx * x.b * x.c + fyy * y.b * y.c
              + fxy * (x.b * y.c + x.c * y.b))


def rod_inertia(mass: float, length: float) -> float:
    """Moment of inertia of a solid rod (cylinder, radius 0.01 m) about its centre, across."""
    return mass * (3 * R_ROD**2 + length**2) / 12


@dataclass
class Body:
    mass: float
    inertia: float  # about the centre of mass, normal to the plane [kg m^2]
    x: HD
    z: HD
    angle: HD


def linear_model(bodies: list[Body], spring_energy: HD) -> tuple[float, float, float]:
    """(m(theta0), V'(theta0), V''(theta0)) from bodies built with theta = HD.variable."""
    m = 0.0
    V = spring_energy
    for b in bodies:
        m += b.mass * (b.x.b**2 + b.z.b**2) + b.inertia * b.angle.b**2
        V = V + b.mass * G0 * b.z
    return m, V.b, V.d


def four_bar(theta: float, branch: float = -1.0) -> tuple[float, float, float]:
    """urdf/four_bar: a=0.2, b=0.5, c=0.4, d=0.45 m; 0.4, 1.0, 0.8 kg; crank spring 2 N m/rad
    about rest 1 rad. Angles counter-clockwise from +x in the x-z plane; branch -1: the rocker
    angle is atan2(O4B) - acos(...), the assembly the bundled scene starts near."""
    a, b, c, d = 0.2, 0.5, 0.4, 0.45
    ma, mb, mc = 0.4, 1.0, 0.8
    t = HD.variable(theta)
    bx, bz = a * cos(t), a * sin(t)
    px, pz = bx - d, bz  # from O4 to B
    e = sqrt(px * px + pz * pz)
    psi = atan2(pz, px) + branch * acos((c * c + e * e - b * b) / (2 * c * e))
    cx, cz = d + c * cos(psi), c * sin(psi)
    phi = atan2(cz - bz, cx - bx)
    bodies = [
        Body(ma, rod_inertia(ma, a), 0.5 * bx, 0.5 * bz, t),
        Body(mb, rod_inertia(mb, b), 0.5 * (bx + cx), 0.5 * (bz + cz), phi),
        Body(mc, rod_inertia(mc, c), d + 0.5 * c * cos(psi), 0.5 * c * sin(psi), psi),
    ]
    return linear_model(bodies, 0.5 * 2.0 * (t - 1.0) * (t - 1.0))


def slider_crank(theta: float) -> tuple[float, float, float]:
    """urdf/slider_crank: r=0.1, l=0.35 m; crank 0.3 kg, rod 0.6 kg, slider 0.5 kg on x;
    crank spring 3 N m/rad about 0.8 rad, slider spring 50 N/m about x = 0.3 m."""
    r, ell = 0.1, 0.35
    mr, ml, ms = 0.3, 0.6, 0.5
    t = HD.variable(theta)
    bx, bz = r * cos(t), r * sin(t)
    x = bx + sqrt(ell * ell - bz * bz)
    phi = atan2(-bz, x - bx)
    bodies = [
        Body(mr, rod_inertia(mr, r), 0.5 * bx, 0.5 * bz, t),
        Body(ml, rod_inertia(ml, ell), 0.5 * (bx + x), 0.5 * bz, phi),
        Body(ms, 0.0, x, HD(0.0), HD(0.0)),
    ]
    springs = 0.5 * 3.0 * (t - 0.8) * (t - 0.8) + 0.5 * 50.0 * (x - 0.3) * (x - 0.3)
    return linear_model(bodies, springs)
