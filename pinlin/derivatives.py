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

import math
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from .exceptions import ArgumentError, PinlinError
from .fields import show
from .operating_point import OperatingPoint
from .system import System

BACKENDS = ("analytic", "fd3", "fd5")
#: Default steps per perturbed variable: "q" [rad or m], "v" [rad/s or m/s], "u" [N*m or N]
#: (the input's step is scaled by max(1, |u0|): the dynamics are linear in u).
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


#: Steps outside [STEP_MIN, STEP_MAX] are refused: beyond 0.1 the formulas leave their asymptotic
#: range, where the error estimate was measured to hold (it under-reports from h ~ 0.3 on Talos
#: and solo12); below 1e-10 rounding leaves fewer than ~5 significant digits and the estimate
#: itself starts to fail (h = 1e-12 on a slider-crank). See validation/reports/error_estimate.md.
STEP_MIN, STEP_MAX = 1e-10, 0.1


def resolve_steps(backend: str, step: float | Mapping[str, float] | None) -> dict[str, float]:
    """Steps for ``backend``: the defaults, one number for all, or a {"q", "v", "u"} table.

    Raises:
        ArgumentError: an unknown key, or a step that is not a number in
            [:data:`STEP_MIN`, :data:`STEP_MAX`].
    """
    steps = dict(DEFAULT_STEPS[backend])
    if step is None:
        return steps
    if isinstance(step, Mapping):
        given = step
    elif isinstance(step, int | float | np.floating | np.integer) and not isinstance(step, bool):
        given = dict.fromkeys(STEP_KEYS, step)
    else:
        raise ArgumentError("step", "expected a number or a table {'q': .., 'v': .., 'u': ..}, "
                                    f"got {type(step).__name__}")
    for key, value in given.items():
        if key not in STEP_KEYS:
            raise ArgumentError("step", f"unknown step key {show(key)}; expected "
                                        f"{', '.join(STEP_KEYS)}")
        try:  # complex numbers too: float() would drop their imaginary part
            h = float(value) if not isinstance(value, bool | str | complex | np.complexfloating) \
                else float("nan")
        except (TypeError, ValueError, OverflowError):
            h = float("nan")
        if not (np.isfinite(h) and h > 0):
            raise ArgumentError("step", f"finite-difference step must be a positive number, "
                                        f"got {show(value)}")
        if not STEP_MIN <= h <= STEP_MAX:
            raise ArgumentError("step", f"finite-difference step {h:g} is outside "
                                        f"[{STEP_MIN:g}, {STEP_MAX:g}] (rad, m, rad/s, m/s, N*m "
                                        "or N): larger steps leave the range where the "
                                        "difference formulas and their error estimate hold, "
                                        "smaller ones lose the result to rounding")
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
        rounding: Standard deviation of the rounding noise of an entry of K and of C in each
            row, in their units (numerical backends; zeros without an estimate; see
            :func:`entry_noise`).
        steps: Steps used (numerical backends).
    """

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray | None
    backend: str
    Bu: np.ndarray | None = None
    alt: tuple[np.ndarray, np.ndarray | None] | None = None
    rounding: tuple[np.ndarray, np.ndarray] | None = None
    steps: Mapping[str, float] | None = None


def velocity_terms(system: System, op: OperatingPoint) -> bool:
    """Whether dH/dv can be non-zero: damping present or a non-zero velocity."""
    return system.has_damping or system.rotation is not None or bool(np.count_nonzero(op.v))


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
                ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Columns j of d fun(x)/dx_j at x = 0 by the backend's formula with step h, the companion
    columns for the error estimate (or None), and the largest |fun| seen per component (for
    rounding)."""
    formula, companion, _ = _PLANS[backend]
    offsets = sorted(set(formula) | (set(companion) if estimate else set()))
    D = D_alt = scale = None
    e = np.zeros(n)
    for j in range(n):
        e[j] = 1.0
        values = {k: fun(k * h * e) for k in offsets}
        e[j] = 0.0
        col = sum(w * values[k] for k, w in formula.items()) / h
        if D is None:
            D = np.zeros((col.size, n))
            D_alt = np.zeros((col.size, n)) if estimate else None
            scale = np.zeros(col.size)
        D[:, j] = col
        if D_alt is not None:
            D_alt[:, j] = sum(w * values[k] for k, w in companion.items()) / h
        for v in values.values():
            np.maximum(scale, np.abs(v), out=scale)
    assert D is not None and scale is not None
    return D, D_alt, scale


#: Computational noise of H is measured (Moré & Wild, "Estimating computational noise", SIAM J.
#: Sci. Comput. 33, 2011) from the NOISE_ORDER-th differences of H at NOISE_POINTS points
#: spaced NOISE_SPACING apart along fixed pseudo-random unit directions, once through the
#: operating point and once through a point one step away (the noise grows with |H| and the
#: difference points lie up to 4 steps away: a hanging pendulum has H(q0) = 0 exactly). The
#: smooth part of such a difference is ~ H^(4) (1e-9)^4, far below rounding; what is left is
#: noise, whose standard deviation the difference multiplies by sqrt(C(2m, m)).
NOISE_ORDER, NOISE_POINTS, NOISE_SPACING = 4, 7, 1e-9


def computational_noise(fun, n: int, h: float) -> np.ndarray:
    """Standard deviation of the rounding noise of each component of ``fun`` (R^n -> R^m) near
    x = 0 and one step ``h`` away, in the units of ``fun`` (size m)."""
    if n == 0:
        return np.zeros_like(fun(np.zeros(0)))
    rng = np.random.default_rng(20111)
    diffs = []
    for center in (0.0, h):
        d = rng.standard_normal(n)
        d /= np.linalg.norm(d)
        x0 = center * rng.standard_normal(n) / np.sqrt(n)
        values = np.array([fun(x0 + k * NOISE_SPACING * d) for k in range(NOISE_POINTS)])
        diffs.append(np.diff(values, NOISE_ORDER, axis=0))
    dd = np.vstack(diffs)
    return np.sqrt((dd**2).mean(axis=0) / math.comb(2 * NOISE_ORDER, NOISE_ORDER))


def entry_noise(noise: np.ndarray, scale: np.ndarray, backend: str, h: float) -> np.ndarray:
    """Standard deviation of the rounding error of a differenced entry in each row [units of
    fun / units of x]: the row's evaluation noise (measured ``noise``; at least eps ``scale``,
    the rounding of the weighted sum itself) times the formula's sqrt(sum w_k^2) / h."""
    eps = np.finfo(float).eps
    weights = math.sqrt(sum(w * w for w in _PLANS[backend][0].values()))
    return np.maximum(noise, eps * scale) * weights / h


def _numerical(system: System, op: OperatingPoint, backend: str, steps: Mapping[str, float],
               estimate: bool) -> SecondOrderTerms:
    model, nv = system.model, system.nv
    S = system.input_matrix
    _, _, weight = _PLANS[backend]

    def h_of_q(d: np.ndarray) -> np.ndarray:
        return residual_forces(system, pin.integrate(model, op.q, d), op.v, op.a, op.lam)

    def h_of_v(d: np.ndarray) -> np.ndarray:
        return residual_forces(system, op.q, op.v + d, op.a)

    K, K_alt, scale_q = _difference(h_of_q, nv, steps["q"], backend, estimate)
    C = C_alt = None
    rounding = (np.zeros(nv), np.zeros(nv))
    if estimate:
        rounding = (entry_noise(computational_noise(h_of_q, nv, steps["q"]), scale_q, backend,
                                steps["q"]), rounding[1])
    if velocity_terms(system, op):
        C, C_alt, scale_v = _difference(h_of_v, nv, steps["v"], backend, estimate)
        if estimate:
            rounding = (rounding[0], entry_noise(computational_noise(h_of_v, nv, steps["v"]),
                                                 scale_v, backend, steps["v"]))
    Bu = np.zeros_like(S)
    if S.shape[1]:
        # Bu = -dH/du. H is linear in u: the difference is exact up to the rounding of
        # u0 +- h, eps |u0| / h relative, so each input's step is h max(1, |u0_j|) (a tonne
        # held at 1e7 N*m lost 8 digits of B to a step of 1e-3 N*m).
        size = np.maximum(1.0, np.abs(op.u))

        def h_of_u(d: np.ndarray) -> np.ndarray:
            return S @ (op.u + size * d) - residual_forces(system, op.q, op.v, op.a, op.lam)

        Bu, _, _ = _difference(h_of_u, S.shape[1], steps["u"], backend, False)
        Bu /= size
    alt = None
    if estimate:
        # Companion matrices scaled so that (alt - main) is the estimated error of main.
        K_est = K + weight * (K_alt - K)
        C_est = None if C is None else C + weight * (C_alt - C)
        alt = (K_est, C_est)
    return SecondOrderTerms(system.mass_matrix(op.q), K, C, backend, Bu=Bu, alt=alt,
                            rounding=rounding, steps=dict(steps))


#: The rounding part of the estimate is NOISE_SIGMAS standard deviations of the noise pushed
#: into A: A has at most 4 nv^2 entries (10^4 for nv = 50), and a Gaussian exceeds 4.5 sigma
#: with probability 7e-6.
NOISE_SIGMAS = 4.5
#: The truncation part is TRUNCATION_SAFETY times the companion's estimate, which carries a
#: relative error of its own of O(h^2) (the next term of the series; measured up to 0.5 % at
#: h = 3e-2 on Talos, solo12 and a rotating pendulum).
TRUNCATION_SAFETY = 1.5
#: Rounding of the formulation itself (A from K and C by solves and products): a few units
#: of eps relative to max |A| (measured up to 0.3 eps between two computations).
FORMULATION_ROUNDING = 4 * np.finfo(float).eps


def propagated_noise(X: np.ndarray, sigma: np.ndarray, Y: np.ndarray | None = None) -> float:
    """Largest standard deviation of an entry of X dK Y when the entries of dK are independent
    with standard deviation ``sigma[k]`` in row k: max_i ||X[i, :] sigma||_2 max_j ||Y[:, j]||_2
    (Y None: the identity)."""
    Xs = X * sigma[None, :]
    x = float(np.sqrt((Xs * Xs).sum(axis=1).max(initial=0.0)))
    return x if Y is None else x * float(np.sqrt((Y * Y).sum(axis=0).max(initial=0.0)))


def error_estimate(A: np.ndarray, A_alt: np.ndarray, noise: float,
                   scale: float | None = None) -> dict[str, float]:
    """Relative error estimate of a numerically derived A, max |error| / max |A|:
    :data:`TRUNCATION_SAFETY` times the truncation error, from the companion formula pushed
    through the same formulation (``A_alt``), plus :data:`NOISE_SIGMAS` times ``noise``, the
    standard deviation [units of A] of the rounding noise of K and C pushed through the
    formulation (see :func:`propagated_noise`), plus the formulation's own rounding.

    Returns:
        ``{"error_estimate": total, "error_estimate_rounding": the rounding part}`` (the keys
        of ``model.info``); relative to ``scale`` [units of A] when given (the size of the
        numerically derived part of A: a penalty model's Omega^2 and 2 mu Omega entries would
        dilute max |A|), else to max |A|.
    """
    largest = float(np.abs(A).max(initial=0.0))
    # A given scale is floored at A's own rounding (a negligible derived part, extreme values).
    scale = largest if scale is None else max(scale, np.finfo(float).eps * largest)
    scale = max(scale, np.finfo(float).tiny)
    truncation = TRUNCATION_SAFETY * float(np.abs(A_alt - A).max(initial=0.0)) / scale
    rounding = NOISE_SIGMAS * noise / scale + FORMULATION_ROUNDING
    return {"error_estimate": truncation + rounding, "error_estimate_rounding": rounding}
