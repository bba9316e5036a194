"""The three formulations of chapter 9.1 for systems with constraints Phi(q) = 0.

All start from the second-order terms of H at the operating point (see ``derivatives``): M, C,
K (K includes the geometric stiffness -lam^T Phi_qq of the constraint forces) and the
independent constraint rows G = Phi_q (loops, contacts with the world, mimic couplings).
Everything is in the tangent space, a floating base's six coordinates included: a standing
robot is a constrained system like any other (its K keeps the exact, non-symmetric derivative
of the contact forces on the base's Lie-group block, see :mod:`pinlin.constraints`). With
contacts the model also reports each contact limb's conditioning
(:func:`pinlin.contacts.limb_conditions`, ``info["condition"]["contact_limbs"]``) and warns at
a singular limb (a straight knee).

- **Independent coordinates (9.1.1).** q' = R z' with G R = 0. At a static or steady (relative)
  equilibrium, z' = z'' = 0, so every term of eqs. 9.8-9.11 that carries z' or z'' vanishes and
  the R_z terms reduce to R_z^T (Q - M Sc) = R_z^T G^T lam, which equals -R^T (lam^T Phi_qq) R
  (differentiate G R = 0): the geometric stiffness. Hence

      M_z = R^T M R,   C_z = R^T C R,   K_z = R^T K R,   Bu_z = R^T S.

- **Penalty (9.1.2)**, eqs. 9.35-9.37 at the operating point (Phi = Phi' = 0; the penalty
  force alpha Omega^2 Phi of the loaded equilibrium is lam, which brings lam^T Phi_qq into K):

      M_p = M + G^T a G,   C_p = C + G^T a 2 mu Omega G,   K_p = K + G^T a Omega^2 G.

- **Canonical (9.1.3)**, eq. 9.53 with p = M_p q': E y' = F y + G_u u for y = [p; q] with
  E = [[I, C_p], [0, M_p]], F = [[0, -K_p], [I, 0]] (:mod:`pinlin.formulations.canonical`).

First-order models follow Rowell: x = [dz; z'] (independent), [dq; v] (penalty), [p; q]
(canonical).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import pinocchio as pin
import scipy.linalg as sla
from scipy.linalg import lapack

from ..arrays import read_only
from ..assembly import projection
from ..conditioning import AccuracyWarning, scaled_condition_1, warn_if_ill_conditioned
from ..contacts import limb_conditions, warn_singular_limbs
from ..coordinates import linear_coordinates
from ..derivatives import (
    SecondOrderTerms,
    error_estimate,
    propagated_noise,
    second_order_terms,
)
from ..equilibrium import ConstrainedPoint
from ..exceptions import PinlinError
from ..linear_model import LinearModel
from ..operating_point import OperatingPoint
from ..options import BASES, PENALTY_DEFAULTS, Penalty
from .independent import output_matrices
from .penalty_error import penalty_error

#: Default penalty parameters: alpha [kg or kg*m^2 per row unit^2], Omega [rad/s], mu [-].


def first_order(M: np.ndarray, C: np.ndarray, K: np.ndarray, Bu: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """A = [[0, I], [-M^-1 K, -M^-1 C]], B = [[0], [M^-1 Bu]] with one Cholesky factor of M."""
    return _first_order(M, C, K, Bu)[:2]


def _first_order(M: np.ndarray, C: np.ndarray | None, K: np.ndarray, Bu: np.ndarray,
                 with_inverse: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`first_order` by LAPACK directly (``dpotrf``, ``dpotrs``: what
    ``scipy.linalg.cho_factor``/``cho_solve`` call, without their checks; M symmetric, only
    its upper triangle read, as there). ``C`` None: zero. ``with_inverse``: M^-1 too, from
    the same factor and solve."""
    n = M.shape[0]
    m = Bu.shape[1]
    if n == 0:  # nothing moves (a welded body): A is 0 x 0, B has no rows
        return np.zeros((0, 0)), np.zeros((0, m)), (np.zeros((0, 0)) if with_inverse
                                                     else None)
    if not np.isfinite(M).all():
        raise ValueError("array must not contain infs or NaNs")  # cho_factor's check
    factor, info = lapack.dpotrf(M, lower=0, clean=0)
    if info != 0:
        raise PinlinError("the (reduced) mass matrix is not positive definite: some coordinate "
                          "moves no inertia")
    parts = [K, np.zeros_like(K) if C is None else C, Bu]
    if with_inverse:
        parts.append(np.eye(n))
    rhs = np.hstack(parts)
    if not np.isfinite(rhs).all():
        raise ValueError("array must not contain infs or NaNs")  # cho_solve's check
    X, info = lapack.dpotrs(factor, rhs, lower=0)
    if info != 0:  # pragma: no cover - only bad arguments
        raise PinlinError(f"LAPACK dpotrs failed (info {info})")
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:] = -X[:, :2 * n]
    B = np.zeros((2 * n, m))
    B[n:] = X[:, 2 * n:2 * n + m]
    return A, B, (X[:, 2 * n + m:] if with_inverse else None)


def penalty_first_order(M: np.ndarray, C: np.ndarray, K: np.ndarray, G: np.ndarray,
                        Bu: np.ndarray, alpha: float, mu: float, omega: float,
                        K_extra: np.ndarray | None = None, C_extra: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """A, B of the penalty model without forming M + G^T alpha G.

    Plain assembly solves with M_p = M + alpha G^T G, whose condition number grows like alpha:
    float64 loses the physical eigenvalues' accuracy near alpha = 1e7-1e8 and can invent a
    positive real part. Here the coordinates are rotated by the orthogonal Q = [Z, N] from the
    SVD G = U S N^T (Z spans the nullspace of G): G Q = [0, U S] exactly, so the penalty terms
    live only in the constrained block eta as alpha S^2, 2 mu Omega alpha S^2 and
    alpha Omega^2 S^2 (diagonal). M_p^-1 [K_p, C_p, Bu] is then formed by block elimination:
    D = M_eta,eta + alpha S^2 is inverted only against right-hand sides of its own size
    (D^-1 alpha Omega^2 S^2 -> Omega^2, no cancellation), and the free block through the Schur
    complement M_zz - M_z,eta D^-1 M_eta,z, which tends to R^T M R as alpha grows. Every
    quantity stays O(1) in alpha, so the physical eigenvalues keep their O(1/alpha) penalty
    error down to rounding, up to alpha = 1e14 and beyond. The same model as plain assembly in
    exact arithmetic; A and B are returned in the original coordinates.

    ``K_extra`` and ``C_extra`` (m x n) add alpha G^T K_extra and alpha G^T C_extra to K_p and
    C_p (the penalty force's dependence on the motion at a moving state): rotated, they too
    fill only the constrained rows, as alpha S U^T X Q.
    """
    return penalty_elimination(M, C, K, G, Bu, mu, omega, K_extra, C_extra)(alpha)


def penalty_elimination(M: np.ndarray, C: np.ndarray, K: np.ndarray, G: np.ndarray,
                        Bu: np.ndarray, mu: float, omega: float,
                        K_extra: np.ndarray | None = None, C_extra: np.ndarray | None = None
                        ) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
    """:func:`penalty_first_order` as a function of alpha: the SVD of G and the rotation by Q
    are done once, each alpha then costs the elimination alone (the error estimate needs the
    model at alpha and 2 alpha, :mod:`pinlin.formulations.penalty_error`). The same
    arithmetic as one call, so the model at alpha is the same to the bit."""
    n, m = M.shape[0], G.shape[0]
    if m == 0:
        return lambda alpha: first_order(M, C, K, Bu)
    u_svd, sv, vt = np.linalg.svd(G)
    Q = np.hstack([vt[m:].T, vt[:m].T])  # [Z, N]
    f = n - m
    w = sv[:m] ** 2
    Mt, Ct0, Kt0, Bt = Q.T @ M @ Q, Q.T @ C @ Q, Q.T @ K @ Q, Q.T @ Bu
    Mt = 0.5 * (Mt + Mt.T)
    eta = np.arange(f, n)
    KX = None if K_extra is None else sv[:m, None] * (u_svd.T @ K_extra @ Q)
    CX = None if C_extra is None else sv[:m, None] * (u_svd.T @ C_extra @ Q)

    def at(alpha: float) -> tuple[np.ndarray, np.ndarray]:
        Ct, Kt = Ct0.copy(), Kt0.copy()
        Ct[eta, eta] += 2.0 * alpha * mu * omega * w
        Kt[eta, eta] += alpha * omega**2 * w
        if KX is not None:
            Kt[f:] += alpha * KX
        if CX is not None:
            Ct[f:] += alpha * CX
        D = Mt[f:, f:].copy()
        D[np.arange(m), np.arange(m)] += alpha * w
        rhs = np.hstack([Kt, Ct, Bt])
        Dfac = sla.cho_factor(D)
        DinvM = sla.cho_solve(Dfac, Mt[f:, :f])         # D^-1 M_eta,z
        Dinv_rhs = sla.cho_solve(Dfac, rhs[f:])          # D^-1 Y_eta
        X = np.zeros_like(rhs)
        if f:
            schur = Mt[:f, :f] - Mt[:f, f:] @ DinvM
            X[:f] = sla.solve(0.5 * (schur + schur.T), rhs[:f] - Mt[:f, f:] @ Dinv_rhs,
                              assume_a="pos")
        X[f:] = Dinv_rhs - DinvM @ X[:f]
        XK, XC, XB = X[:, :n], X[:, n:2 * n], X[:, 2 * n:]
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :n] = -(Q @ XK @ Q.T)
        A[n:, n:] = -(Q @ XC @ Q.T)
        B = np.zeros((2 * n, Bu.shape[1]))
        B[n:] = Q @ XB
        return A, B

    return at


def _info(system, op: OperatingPoint, cp: ConstrainedPoint, formulation: str, backend: str,
          **extra) -> dict:
    warn_if_ill_conditioned("dependent-coordinate block of the loop Jacobian (near a singular "
                            "position)", cp.partition.condition, system.scene.name, 1e6,
                            stacklevel=5)
    limbs = limb_conditions(system, op.q)
    warn_singular_limbs(system, limbs, stacklevel=5)
    info = {
        "formulation": formulation,
        "derivatives": backend,
        "effects": constrained_effects(system),
        "velocity_terms": True,
        "base": "free" if system.base_joint else "fixed",
        "notes": list(op.notes),
        "independent": [system.coordinate_names[i] for i in cp.partition.independent],
        "constraint_rows": [system.constraints.row_names[i] for i in cp.partition.rows],
        "dropped_rows": list(cp.partition.dropped),
        "condition": {"constraint_jacobian": cp.partition.condition},
    }
    if limbs:
        info["condition"]["contact_limbs"] = limbs
    info.update(extra)
    return info


def constrained_effects(system) -> list[str]:
    """The scene's effects in play, then ``loops`` and ``contacts`` where it has them."""
    scene = system.scene
    return (scene.effects.in_play() + (["loops"] if scene.loops else [])
            + (["contacts"] if scene.contacts else []))


def _terms(system, op, derivatives, step, estimate_error=True):
    terms = second_order_terms(system, op, derivatives, step, estimate_error)
    C = terms.C if terms.C is not None else np.zeros_like(terms.M)
    return terms, C


def _alt(terms) -> tuple[np.ndarray, np.ndarray] | None:
    """(K, C) of the error-estimate companion, C as a matrix."""
    if terms.alt is None:
        return None
    K_alt, C_alt = terms.alt
    return K_alt, (C_alt if C_alt is not None else np.zeros_like(terms.M))


def _numeric_info(terms, A: np.ndarray, A_alt: np.ndarray | None,
                  rounding: float = 0.0, scale: float | None = None) -> dict:
    """Steps and error estimate; ``rounding`` is the rounding bound of K and C pushed into A
    [units of A]; ``scale``: the size of the numerically derived part of A (default max |A|)."""
    out: dict = {}
    if terms.steps is not None:
        out["step"] = dict(terms.steps)
    if A_alt is not None:
        out.update(error_estimate(A, A_alt, rounding, scale))
    return out


def penalty_numeric_info(terms, A: np.ndarray, A_alt: np.ndarray | None,
                         Mp_inv: np.ndarray | None, C: np.ndarray) -> dict:
    """:func:`_numeric_info` of a penalty model's A (dA = -M_p^-1 [dK, dC]): the rounding of
    K and C pushed through M_p^-1, the error relative to max |M_p^-1 [K, C]|, the size of what
    the finite differences give (the rows -M_p^-1 [K_p, C_p] also hold the penalty terms
    ~Omega^2 and ~2 mu Omega, exact, which would make an error relative to max |A| look
    small). ``Mp_inv`` is needed only with ``A_alt``."""
    if A_alt is None:
        return _numeric_info(terms, A, None)
    rounding = max(propagated_noise(Mp_inv, sigma) for sigma in terms.rounding)
    scale = max(float(np.abs(Mp_inv @ terms.K).max(initial=0.0)),
                float(np.abs(Mp_inv @ C).max(initial=0.0)))
    return _numeric_info(terms, A, A_alt, rounding, scale)


def _input_matrix(system, terms) -> np.ndarray:
    return system.input_matrix if terms.Bu is None else terms.Bu


#: The model's sensitivity to where the assembly put the operating point is measured when the
#: dependent-coordinate Jacobian's condition exceeds SENSITIVITY_CHECK (cheap otherwise: never
#: measured), and warned about above SENSITIVITY_WARN (relative change of A).
SENSITIVITY_CHECK, SENSITIVITY_WARN = 1e3, 1e-6


def indistinguishable_move(system, op: OperatingPoint, cp: ConstrainedPoint) -> np.ndarray:
    """The move dq (nv, velocity coordinates [rad or m]) from q0 to the farthest configuration,
    z held, that closes the loops as well as q0 does (:func:`assembly_sensitivity`), in one
    unit: its direction is the smallest right singular vector of Phi_d with the rows as the
    assembly measures them (each relative to its scale) and the columns of lengths in units
    of the robot's characteristic length (:func:`pinlin.assembly.unit_factors`), so the same
    mechanism at another size moves along the same direction."""
    from ..assembly import ASSEMBLY_TOL, unit_factors

    part, G = cp.partition, cp.jacobian
    dep = part.dependent
    cons = system.constraints
    # Rows as the assembly measures them: relative to their scale (closure_error).
    scale = cons.row_scale[part.rows]
    factors = unit_factors(system)
    length = np.ones(dep.size) if factors is None else factors[1][dep]
    _, sv, vt = np.linalg.svd(G[:, dep] * length / scale[:, None])
    tol = max(ASSEMBLY_TOL, float((np.abs(cons.residual(op.q)[part.rows]) / scale).max()))
    move = np.zeros(system.nv)
    move[dep] = (tol / sv[-1]) * length * vt[-1]
    return move


def assembly_sensitivity(system, op: OperatingPoint, cp: ConstrainedPoint,
                         A: np.ndarray) -> tuple[float, float]:
    """Relative change of the reduced A between configurations the assembly cannot tell apart.

    Assembly stops at max |Phi| <= ASSEMBLY_TOL, each row relative to its scale (or at the
    residual reached, if larger). Along the right singular vector w of Phi_d (rows scaled
    alike) for its smallest singular value s_min, every
    configuration within d = tol / s_min of q0 (z held) satisfies that test as well as q0
    does, so the operating point is known only to within d there: near a fold (a crank driven
    to its limit) d grows like the condition number of Phi_d and the model can change by O(1)
    across it, though the condition number alone stays moderate. The model is rebuilt (analytic
    terms, constraint forces and inputs held) at q0 -/+ d w and compared with A.

    Returns:
        (max |A(+) - A(-)| / (2 max |A|), the move d w [rad or m], nv).
    """
    def rebuild(moved: OperatingPoint, moved_cp: ConstrainedPoint) -> np.ndarray:
        terms = second_order_terms(system, moved, "analytic")
        R = projection(moved_cp.jacobian, moved_cp.partition)
        C = terms.C if terms.C is not None else np.zeros_like(terms.M)
        return first_order(R.T @ terms.M @ R, R.T @ C @ R, R.T @ terms.K @ R,
                           R.T @ system.input_matrix)[0]

    return sensitivity_across(system, op, cp, A, rebuild)


def sensitivity_across(system, op: OperatingPoint, cp: ConstrainedPoint, A: np.ndarray,
                       rebuild) -> tuple[float, np.ndarray]:
    """(max |A(+) - A(-)| / (2 max |A|), the move d w) with A(-/+) = ``rebuild(point,
    constrained point)`` at q0 -/+ d w (:func:`indistinguishable_move`; everything but q and
    Phi_q held), shared by the models at rest and at a moving state."""
    part = cp.partition
    move = indistinguishable_move(system, op, cp)
    models = []
    for sign in (-1.0, 1.0):
        q = pin.integrate(system.model, op.q, sign * move)
        moved = OperatingPoint.trusted(**{**op.__dict__, "q": q})
        models.append(rebuild(moved, ConstrainedPoint(
            part, system.constraints.jacobian(q)[part.rows])))
    scale = float(np.abs(A).max())
    return (float(np.abs(models[1] - models[0]).max()) / (2 * scale) if scale else 0.0), move


def _warn_sensitive(system, change: float, move: np.ndarray) -> None:
    if change > SENSITIVITY_WARN:
        linear = linear_coordinates(system)
        angle = float(np.abs(move[~linear]).max(initial=0.0))
        length = float(np.abs(move[linear]).max(initial=0.0))
        parts = [f"{angle:.1e} rad"] if angle or not length else []
        if length:
            parts.append(f"{length:.1e} m")
        within = " and ".join(parts)
        warnings.warn(AccuracyWarning(
            f"model '{system.scene.name}': the operating point is at or near a singular "
            f"position of the mechanism: configurations the assembly cannot tell apart (within "
            f"{within} of q0 along the dependent coordinates) give state matrices "
            f"{change:.1e} (relative) apart; the model there is not reliable (move q0 away "
            "from the limit, or name other independent coordinates)", 1.0 / change),
            stacklevel=5)


def linearize_reduced(system, op: OperatingPoint, cp: ConstrainedPoint, *,
                      derivatives: str = "analytic", step=None, basis: str = "partitioned",
                      estimate_error: bool = True) -> LinearModel:
    """Independent-coordinate model (9.1.1) of a constrained system."""
    if basis not in BASES:
        raise PinlinError(f"unknown basis '{basis}'; expected one of {', '.join(BASES)}")
    terms = second_order_terms(system, op, derivatives, step, estimate_error)
    R = projection(cp.jacobian, cp.partition, basis)
    Rt = R.T
    Mz = Rt @ terms.M @ R
    Mz = 0.5 * (Mz + Mz.T)
    Kz = Rt @ terms.K @ R
    Cz = None if terms.C is None else Rt @ terms.C @ R
    # R^T S with S the 0/1 selection is R's actuated rows, exactly.
    Bz = R[system.actuated].T.copy() if terms.Bu is None else Rt @ terms.Bu
    A, B, Mz_inv = _first_order(Mz, Cz, Kz, Bz, with_inverse=True)
    if Cz is None:
        Cz = np.zeros_like(Mz)
    # np.linalg.cond(Ms, 1) of Mz scaled to unit diagonal, the inverse from the same
    # Cholesky factor (pinlin.conditioning).
    mass_condition = scaled_condition_1(Mz, Mz_inv)
    warn_if_ill_conditioned("reduced mass matrix", mass_condition, system.scene.name,
                            stacklevel=5, size=Mz.shape[0])
    alt = _alt(terms)
    A_alt = rounding = None
    if alt is not None:
        A_alt = first_order(Mz, Rt @ alt[1] @ R, Rt @ alt[0] @ R, Bz)[0]
        # dA = -Mz^-1 R^T [dK, dC] R: rounding in K, C amplified by Mz^-1 R^T and R.
        X = sla.solve(Mz, Rt, assume_a="pos")
        rounding = max(propagated_noise(X, sigma, R) for sigma in terms.rounding)
    if basis == "partitioned":
        coords = [system.coordinate_names[i] for i in cp.partition.independent]
    else:
        coords = [f"z[{i}]" for i in range(R.shape[1])]
    states = tuple([f"q:{c}" for c in coords] + [f"v:{c}" for c in coords])
    Cout, D, out_names, y0 = output_matrices(system, op)
    nv = system.nv
    if system.outputs is None:
        Cout, out_names = np.eye(2 * R.shape[1]), states
        y0 = np.zeros(2 * R.shape[1])
    else:
        Cout = np.hstack([Cout[:, :nv] @ R, Cout[:, nv:] @ R])
    info = _info(system, op, cp, "independent", terms.backend, basis=basis,
                 velocity_terms=bool(np.any(Cz)), R=R.tolist(),
                 **_numeric_info(terms, A, A_alt, rounding or 0.0))
    info["condition"]["mass_matrix"] = mass_condition
    if cp.partition.condition > SENSITIVITY_CHECK:
        change, move = assembly_sensitivity(system, op, cp, A)
        info["condition"]["operating_point_sensitivity"] = change
        _warn_sensitive(system, change, move)
    # Built here with consistent shapes: the trusted constructor keeps the finite and
    # distinct-name checks and skips the rest.
    return LinearModel.assembled(
        A=read_only(A), B=read_only(B), C=read_only(Cout),
        D=read_only(np.zeros((Cout.shape[0], B.shape[1]))), E=None, F=None,
        state_names=states, input_names=system.input_names, output_names=tuple(out_names),
        M=read_only(Mz), C_damp=read_only(Cz), K=read_only(Kz), Bu=read_only(Bz), G=None,
        operating_point=op.with_outputs(y0), name=system.scene.name, info=info)


def penalty_parameters(alpha: float | None, mu: float | None, omega: float | None
                       ) -> tuple[float, float, float]:
    """Checked (alpha, mu, Omega) with the defaults filled in (:class:`pinlin.Penalty`)."""
    p = Penalty(**{k: v for k, v in (("alpha", alpha), ("mu", mu), ("omega", omega))
                   if v is not None})
    return p.alpha, p.mu, p.omega


def penalty_matrices(system, op, cp, derivatives, step, alpha, mu, omega, estimate_error=True):
    """(M_p, C_p, K_p, terms) of eqs. 9.35-9.37 at the operating point."""
    terms, C = _terms(system, op, derivatives, step, estimate_error)
    G = cp.jacobian
    GtG = G.T @ G
    Mp = terms.M + alpha * GtG
    Cp = C + (2.0 * alpha * mu * omega) * GtG
    Kp = terms.K + (alpha * omega**2) * GtG
    return 0.5 * (Mp + Mp.T), Cp, Kp, terms


class _PenaltySetup(NamedTuple):
    """What the penalty and canonical models start from."""

    alpha: float
    mu: float
    omega: float
    Mp: np.ndarray
    Cp: np.ndarray
    Kp: np.ndarray
    terms: SecondOrderTerms
    S: np.ndarray


def _penalty_setup(system, op, cp, derivatives, step, alpha, mu, omega, estimate_error
                   ) -> _PenaltySetup:
    """Checked (alpha, mu, Omega), the penalty matrices, the terms and the input matrix."""
    alpha, mu, omega = penalty_parameters(alpha, mu, omega)
    Mp, Cp, Kp, terms = penalty_matrices(system, op, cp, derivatives, step, alpha, mu, omega,
                                         estimate_error)
    return _PenaltySetup(alpha, mu, omega, Mp, Cp, Kp, terms, _input_matrix(system, terms))


def linearize_penalty(system, op: OperatingPoint, cp: ConstrainedPoint, *,
                      derivatives: str = "analytic", step=None, alpha: float | None = None,
                      mu: float | None = None, omega: float | None = None,
                      estimate_error: bool = True) -> LinearModel:
    """Dependent-coordinate model with the penalty formulation (9.1.2)."""
    alpha, mu, omega, Mp, Cp, Kp, terms, S = _penalty_setup(
        system, op, cp, derivatives, step, alpha, mu, omega, estimate_error)
    C = terms.C if terms.C is not None else np.zeros_like(terms.M)
    elimination = penalty_elimination(terms.M, C, terms.K, cp.jacobian, S, mu, omega)
    A, B = elimination(alpha)
    error = penalty_error(A, elimination(2.0 * alpha)[0], cp.jacobian, alpha, system.scene.name)
    alt = _alt(terms)
    A_alt = Mp_inv = None
    if alt is not None:
        A_alt = penalty_first_order(terms.M, alt[1], alt[0], cp.jacobian, S, alpha, mu,
                                    omega)[0]
        # dA = -M_p^-1 [dK, dC]; M_p^-1 from the same stable elimination (B of Bu = I).
        n = terms.M.shape[0]
        Mp_inv = penalty_first_order(terms.M, C, terms.K, cp.jacobian, np.eye(n), alpha, mu,
                                     omega)[1][n:]
    Cout, D, out_names, y0 = output_matrices(system, op)
    info = _info(system, op, cp, "penalty", terms.backend, alpha=alpha, mu=mu,
                 omega=omega, penalty_error=error,
                 **penalty_numeric_info(terms, A, A_alt, Mp_inv, C))
    return LinearModel(A=A, B=B, C=Cout, D=D, state_names=system.state_names,
                       input_names=system.input_names, output_names=out_names, M=Mp,
                       C_damp=Cp, K=Kp, Bu=S, G=cp.jacobian, operating_point=op.with_outputs(y0),
                       name=system.scene.name, info=info)


# The canonical formulation (9.1.3) lives in pinlin.formulations.canonical, which builds on the
# penalty model above. Its names stay importable from here, loaded on first access (PEP 562): a
# plain import at the top would be circular.
_CANONICAL = frozenset({"CANONICAL_REFUSE", "CANONICAL_WARN", "_EPS", "_check_canonical_spectrum",
                        "canonical_first_order", "linearize_canonical"})


def __getattr__(name: str) -> object:
    if name in _CANONICAL:
        from . import canonical

        return getattr(canonical, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["BASES", "PENALTY_DEFAULTS", "canonical_first_order", "first_order",  # noqa: F822
           "linearize_canonical", "linearize_penalty", "linearize_reduced",  # noqa: F822
           "penalty_parameters"]
