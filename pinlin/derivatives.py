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

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from .exceptions import PinlinError
from .operating_point import OperatingPoint
from .system import System

BACKENDS = ("analytic", "fd3", "fd5")
#: Default steps per perturbed variable: "q" [rad or m], "v" [rad/s or m/s], "u" [N*m or N].
#: Chosen at the bottom of the measured V-curves (validation/reports/accuracy_vs_time.md).
DEFAULT_STEPS = {"fd3": {"q": 1e-5, "v": 1e-5, "u": 1e-3},
                 "fd5": {"q": 1e-3, "v": 1e-3, "u": 1e-3}}
STEP_KEYS = ("q", "v", "u")

# Offsets (in steps) and weights of the derivative formulas, and of their companions for the
# error estimate: fd3 is compared with the 5-point formula on the same +-h, +-2h points
# (the difference is fd3's truncation error to O(h^4)); fd5 with itself at 2h (Richardson:
# error(h) ~ (D(2h) - D(h)) / 15).
_FD3 = {1: 0.5, -1: -0.5}
_FD5 = {-2: 1.0 / 12, -1: -8.0 / 12, 1: 8.0 / 12, 2: -1.0 / 12}
_FD5_2H = {-4: 1.0 / 24, -2: -8.0 / 24, 2: 8.0 / 24, 4: -1.0 / 24}
_PLANS = {  # backend: (formula, companion, companion weight in the estimate)
    "fd3": (_FD3, _FD5, 1.0),
    "fd5": (_FD5, _FD5_2H, 1.0 / 15),
}


def resolve_steps(backend: str, step: float | Mapping[str, float] | None) -> dict[str, float]:
    """Steps for ``backend``: the defaults, one number for all, or a {"q", "v", "u"} table."""
    steps = dict(DEFAULT_STEPS[backend])
    if step is None:
        return steps
    given = step if isinstance(step, Mapping) else dict.fromkeys(STEP_KEYS, step)
    for key, value in given.items():
        if key not in STEP_KEYS:
            raise PinlinError(f"unknown step key '{key}'; expected {', '.join(STEP_KEYS)}")
        try:
            h = float(value)
        except (TypeError, ValueError):
            h = float("nan")
        if not (np.isfinite(h) and h > 0):
            raise PinlinError(f"finite-difference step must be a positive number, got {value!r}")
        steps[key] = h
    return steps


class SecondOrderTerms(NamedTuple):
    """Second-order matrices at an operating point (nv x nv each).

    Attributes:
        M: Mass matrix [kg or kg*m^2] (armature included).
        K: Stiffness dH/d(dq) [N*m/rad, N/m].
        C: Velocity matrix dH/dv [N*m*s/rad, N*s/m], or None when it is structurally zero
            (at rest, v = 0, the Coriolis matrix vanishes; without damping nothing else is there).
        backend: Name of the backend that produced them.
        Bu: -dH/du, the input matrix [-] (numerical backends difference it too; else None).
        alt: The companion estimate of (K, C) for the error estimate (numerical backends with
            an estimate), else None.
        rounding: Estimated rounding error of K and C, absolute [N*m/rad ...] (numerical).
        steps: Steps used (numerical backends).
    """

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray | None
    backend: str
    Bu: np.ndarray | None = None
    alt: tuple[np.ndarray, np.ndarray | None] | None = None
    rounding: float = 0.0
    steps: Mapping[str, float] | None = None


def velocity_terms(system: System, op: OperatingPoint) -> bool:
    """Whether dH/dv can be non-zero: damping present or a non-zero velocity."""
    return system.has_damping or system.rotation is not None or bool(op.v.any())


def second_order_terms(system: System, op: OperatingPoint, backend: str = "analytic",
                       step: float | Mapping[str, float] | None = None,
                       estimate_error: bool = True) -> SecondOrderTerms:
    """M, K, C at ``op`` from the chosen backend (``estimate_error``: numerical backends also
    evaluate the companion formula of the error estimate, at 2x (fd3) or 1.5x (fd5) cost)."""
    if backend == "analytic":
        return _analytic(system, op)
    if backend in _PLANS:
        return _numerical(system, op, backend, resolve_steps(backend, step), estimate_error)
    raise PinlinError(f"unknown derivatives backend '{backend}'; expected one of "
                      f"{', '.join(BACKENDS)}")


def _analytic(system: System, op: OperatingPoint) -> SecondOrderTerms:
    with_v = velocity_terms(system, op)
    K, dtau_dv, M = system.rnea_derivatives(op.q, op.v, op.a, with_v)
    if system.has_springs:
        # Springs act on 1-DoF joints, where d(difference)/d(dq) = 1.
        K.flat[::K.shape[0] + 1] += system.stiffness
    if op.lam is not None:
        K -= system.constraints.hessian(op.q, op.lam)
    C = None
    if with_v:
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


def _difference(fun, n: int, h: float, backend: str, estimate: bool
                ) -> tuple[np.ndarray, np.ndarray | None, float]:
    """Columns j of d fun(x)/dx_j at x = 0 by the backend's formula with step h, the companion
    columns for the error estimate (or None), and the largest |fun| seen (for rounding)."""
    formula, companion, _ = _PLANS[backend]
    offsets = sorted(set(formula) | (set(companion) if estimate else set()))
    D = D_alt = None
    scale = 0.0
    e = np.zeros(n)
    for j in range(n):
        e[j] = 1.0
        values = {k: fun(k * h * e) for k in offsets}
        e[j] = 0.0
        col = sum(w * values[k] for k, w in formula.items()) / h
        if D is None:
            D = np.zeros((col.size, n))
            D_alt = np.zeros((col.size, n)) if estimate else None
        D[:, j] = col
        if D_alt is not None:
            D_alt[:, j] = sum(w * values[k] for k, w in companion.items()) / h
        scale = max(scale, max(float(np.abs(v).max(initial=0.0)) for v in values.values()))
    assert D is not None
    return D, D_alt, scale


def _numerical(system: System, op: OperatingPoint, backend: str, steps: Mapping[str, float],
               estimate: bool) -> SecondOrderTerms:
    model, nv = system.model, system.nv
    S = system.input_matrix
    formula, _, weight = _PLANS[backend]
    eps = np.finfo(float).eps
    K, K_alt, scale_q = _difference(
        lambda d: residual_forces(system, pin.integrate(model, op.q, d), op.v, op.a, op.lam),
        nv, steps["q"], backend, estimate)
    rounding = eps * scale_q * sum(abs(w) for w in formula.values()) / steps["q"]
    C = C_alt = None
    if velocity_terms(system, op):
        C, C_alt, scale_v = _difference(
            lambda d: residual_forces(system, op.q, op.v + d, op.a), nv, steps["v"], backend,
            estimate)
        rounding = max(rounding,
                       eps * scale_v * sum(abs(w) for w in formula.values()) / steps["v"])
    Bu = np.zeros_like(S)
    if S.shape[1]:
        # Bu = -dH/du. H is linear in u: the difference is exact up to rounding, any step.
        def h_of_u(d: np.ndarray) -> np.ndarray:
            return S @ (op.u + d) - residual_forces(system, op.q, op.v, op.a, op.lam)

        Bu, _, _ = _difference(h_of_u, S.shape[1], steps["u"], backend, False)
    alt = None
    if estimate:
        # Companion matrices scaled so that (alt - main) is the estimated error of main.
        K_est = K + weight * (K_alt - K)
        C_est = None if C is None else C + weight * (C_alt - C)
        alt = (K_est, C_est)
    return SecondOrderTerms(system.mass_matrix(op.q), K, C, backend, Bu=Bu, alt=alt,
                            rounding=rounding, steps=dict(steps))


def error_estimate(A: np.ndarray, A_alt: np.ndarray, terms: SecondOrderTerms) -> float:
    """Relative error estimate of a numerically derived A: truncation, from the companion
    formula pushed through the same formulation (``A_alt``), plus rounding relative to K."""
    scale = max(float(np.abs(A).max(initial=0.0)), np.finfo(float).tiny)
    k_scale = max(float(np.abs(terms.K).max(initial=0.0)), np.finfo(float).tiny)
    return float(np.abs(A_alt - A).max(initial=0.0)) / scale + terms.rounding / k_scale
