"""Derivatives of the equations of motion at an operating point (chapter 9.1.1 and 9.2).

The residual form of the equations of motion is::

    H(q, v, a, u) = rnea(q, v, a) - tau_spring(q) - tau_damping(v) - S u - Phi_q(q)^T lam = 0

so that M = dH/da, K = dH/d(dq), C = dH/dv and Bu = S, where dq is the tangent-space
perturbation q = ``pin.integrate(q0, dq)``. With constraints, lam is held at its value at the
operating point and K carries the geometric stiffness -lam^T Phi_qq of the constraint forces
(exact by polarization in the analytic backend, differenced with the rest of H in fd3/fd5).
A rotating scene's rnea includes the centrifugal and Coriolis forces. Backends:

- ``analytic``: Pinocchio's ``computeRNEADerivatives`` (which also returns M).
- ``fd3``: central differences, O(h^2) (eq. 9.54/9.56).
- ``fd5``: five-point central differences, O(h^4) (eq. 9.55).

Numerical backends perturb q on the manifold with ``pin.integrate`` and take M from
``pin.crba`` (H is linear in a, so its derivative there needs no step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .exceptions import PinlinError
from .operating_point import OperatingPoint
from .system import System

BACKENDS = ("analytic", "fd3", "fd5")
#: Default steps (dimensionless in SI units: [rad or m] for q, [rad/s or m/s] for v).
DEFAULT_STEPS = {"fd3": 1e-5, "fd5": 5e-4}

_STENCILS = {
    "fd3": ((1.0, 0.5), (-1.0, -0.5)),
    "fd5": ((-2.0, 1.0 / 12), (-1.0, -8.0 / 12), (1.0, 8.0 / 12), (2.0, -1.0 / 12)),
}


@dataclass(frozen=True)
class SecondOrderTerms:
    """Second-order matrices at an operating point (nv x nv each).

    Attributes:
        M: Mass matrix [kg or kg*m^2] (armature included).
        K: Stiffness dH/d(dq) [N*m/rad, N/m].
        C: Velocity matrix dH/dv [N*m*s/rad, N*s/m], or None when it is structurally zero
            (at rest, v = 0, the Coriolis matrix vanishes; without damping nothing else is there).
        backend: Name of the backend that produced them.
    """

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray | None
    backend: str


def velocity_terms(system: System, op: OperatingPoint) -> bool:
    """Whether dH/dv can be non-zero: damping present or a non-zero velocity."""
    return system.has_damping or system.rotation is not None or bool(op.v.any())


def second_order_terms(system: System, op: OperatingPoint, backend: str = "analytic",
                       step: float | None = None) -> SecondOrderTerms:
    """M, K, C at ``op`` from the chosen backend."""
    if backend == "analytic":
        return _analytic(system, op)
    if backend in _STENCILS:
        h = DEFAULT_STEPS[backend] if step is None else float(step)
        if not (np.isfinite(h) and h > 0):
            raise PinlinError(f"finite-difference step must be a positive number, got {step!r}")
        return _numerical(system, op, backend, h)
    raise PinlinError(f"unknown derivatives backend '{backend}'; expected one of "
                      f"{', '.join(BACKENDS)}")


def _analytic(system: System, op: OperatingPoint) -> SecondOrderTerms:
    K, dtau_dv, M = system.rnea_derivatives(op.q, op.v, op.a)
    if system.has_springs:
        # Springs act on 1-DoF joints, where d(difference)/d(dq) = 1.
        K.flat[::K.shape[0] + 1] += system.stiffness
    if op.lam is not None:
        K -= system.constraints.hessian(op.q, op.lam)
    C = None
    if velocity_terms(system, op):
        C = dtau_dv
        C.flat[::C.shape[0] + 1] += system.damping
    return SecondOrderTerms(M, K, C, "analytic")


def residual_forces(system: System, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                    lam: np.ndarray | None = None) -> np.ndarray:
    """H without the input term: rnea(q, v, a) - tau_spring(q) - tau_damping(v)
    - Phi_q(q)^T lam [N*m or N]."""
    tau = system.rnea(q, v, a)
    if lam is not None:
        tau -= system.constraints.jacobian(q).T @ lam
    if system.has_springs:
        tau -= system.spring_torque(q)
    if system.has_damping:
        tau += system.damping * v
    return tau


def _numerical(system: System, op: OperatingPoint, backend: str, h: float) -> SecondOrderTerms:
    model, nv = system.model, system.nv
    stencil = _STENCILS[backend]
    K = np.zeros((nv, nv))
    C = np.zeros((nv, nv)) if velocity_terms(system, op) else None
    e = np.zeros(nv)
    for j in range(nv):
        e[j] = 1.0
        col = np.zeros(nv)
        for k, w in stencil:
            col += w * residual_forces(system, pin.integrate(model, op.q, k * h * e), op.v, op.a,
                                       op.lam)
        K[:, j] = col / h
        if C is not None:
            col = np.zeros(nv)
            for k, w in stencil:
                col += w * residual_forces(system, op.q, op.v + k * h * e, op.a)
            C[:, j] = col / h
        e[j] = 0.0
    return SecondOrderTerms(system.mass_matrix(op.q), K, C, backend)
