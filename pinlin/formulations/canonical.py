"""The canonical (momentum) formulation (9.1.3) of a constrained system: eq. 9.53 with
p = M_p q', E y' = F y + G_u u for y = [p; q], E = [[I, C_p], [0, M_p]], F = [[0, -K_p], [I, 0]],
solved for y' in closed form and checked against the penalty model (9.1.2), whose spectrum it
shares (see :mod:`pinlin.formulations.constrained`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
import scipy.linalg as sla

from ..conditioning import AccuracyWarning
from ..equilibrium import ConstrainedPoint
from ..exceptions import ArgumentError
from ..linear_model import LinearModel
from ..modal_table import constraint_columns
from ..operating_point import OperatingPoint
from .constrained import (
    _alt,
    _info,
    _penalty_setup,
    penalty_elimination,
    penalty_first_order,
    penalty_numeric_info,
)
from .independent import output_matrices
from .penalty_error import penalty_error


def canonical_first_order(M: np.ndarray, C: np.ndarray, K: np.ndarray, G: np.ndarray,
                          Bu: np.ndarray, alpha: float, mu: float, omega: float,
                          elimination: Callable[[float], tuple[np.ndarray, np.ndarray]]
                          | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A, B of eq. 9.53 solved for y' (y = [p; q]) without factoring E.

    E^-1 = [[I, -C_p M_p^-1], [0, M_p^-1]] in closed form, so
    A = [[-C_p M_p^-1, -K_p], [M_p^-1, 0]] and B = [Bu; 0] exactly. M_p^-1 and M_p^-1 C_p^T
    come from the same stable block elimination as the penalty model (no M + alpha G^T G is
    ever factored); only K_p carries alpha explicitly, as the canonical state matrix must.

    ``elimination``: :func:`~pinlin.formulations.constrained.penalty_elimination` of
    (M, C, K, G, I) when the caller has it (to take the penalty model at other alphas too).

    Returns:
        A, B, M_p^-1 and the penalty model's A (the same spectrum, well scaled).
    """
    n = M.shape[0]
    if elimination is None:
        elimination = penalty_elimination(M, C, K, G, np.eye(n), mu, omega)
    A_pen, Mp_inv = elimination(alpha)
    Mp_inv = Mp_inv[n:]
    minus_Mp_inv_CpT = penalty_first_order(M, C.T, K, G, np.zeros((n, 0)), alpha, mu,
                                           omega)[0][n:, n:]
    A = np.zeros((2 * n, 2 * n))
    A[:n, :n] = minus_Mp_inv_CpT.T
    A[:n, n:] = -(K + (alpha * omega**2) * (G.T @ G))
    A[n:, :n] = Mp_inv
    B = np.vstack([Bu, np.zeros_like(Bu)])
    return A, B, Mp_inv, A_pen


#: The canonical state matrix carries K_p = K + alpha Omega^2 G^T G, entries growing like
#: alpha, so rounding perturbs its eigenvalues by ~ eps alpha. Its spectrum is that of the
#: penalty model (y = [M_p v; dq]), whose A stays O(1) in alpha: pinlin compares the two and
#: refuses the model when they differ by more than CANONICAL_REFUSE (relative) or when the
#: canonical one shows a growing mode the penalty one does not; it warns above
#: CANONICAL_WARN. Measured (four-bar, slider-crank, delta): 2e-8 at alpha = 1e7, 5e-7-5e-6
#: at 1e9, 3e-3-5e-3 and false instabilities at 1e12.
CANONICAL_WARN, CANONICAL_REFUSE = 1e-6, 1e-4
_EPS = float(np.finfo(float).eps)


def _check_canonical_spectrum(A: np.ndarray, A_pen: np.ndarray, G: np.ndarray, alpha: float,
                              name: str) -> float:
    """Largest relative distance between the physical eigenvalues of the canonical model and
    the penalty model's (matched by assignment). The 2m constraint modes, whose position
    vectors lie most in the range of G^T, are left out of the distance (with mu = 1 they are a
    defective double root, moved by sqrt(rounding) in either model) but not out of the
    growth check: a mode that decays in the penalty model must not grow in the canonical one
    (a false instability; it appears once rounding exceeds the penalty error c / alpha)."""
    from scipy.optimize import linear_sum_assignment

    n = G.shape[1]
    lam_c = sla.eigvals(A, check_finite=False)
    lam_p, vec = sla.eig(A_pen, check_finite=False)
    physical = ~constraint_columns(G, vec[:n])
    ref = np.maximum(np.abs(lam_p), 1e-6 * max(float(np.abs(lam_p).max(initial=0.0)), 1.0))
    cost = np.abs(lam_c[:, None] - lam_p[None, :]) / ref[None, :]
    rows, cols = linear_sum_assignment(cost)
    gap = float(cost[rows, cols][physical[cols]].max(initial=0.0))
    # A decaying (or undamped, Re = -O(1/alpha)) penalty mode that grows in the canonical one.
    # Growth below eps |A|_F is rounding: every eigenvalue of A computed in float64 carries a
    # backward error of that size (K_p ~ alpha makes it large), so it decides nothing.
    floor = _EPS * float(np.linalg.norm(A))
    grows = bool(np.any((lam_c[rows].real > floor) & (lam_p[cols].real < 0.0)))
    if gap > CANONICAL_REFUSE or grows:
        what = "shows a growing mode the penalty model does not have" if grows else \
            f"has eigenvalues {gap:.1e} (relative) away from the penalty model's"
        raise ArgumentError("alpha", f"model '{name}': with alpha = {alpha:g} the canonical "
                                     f"state matrix {what}: its K_p = K + alpha Omega^2 G^T G "
                                     "grows like alpha and float64 cannot hold both scales; "
                                     "use a smaller alpha or formulation='penalty' (the same "
                                     "spectrum, with A bounded in alpha)")
    if gap > CANONICAL_WARN:
        warnings.warn(AccuracyWarning(
            f"model '{name}': with alpha = {alpha:g} the canonical state matrix's eigenvalues "
            f"are {gap:.1e} (relative) from the penalty model's (K_p grows like alpha); "
            "formulation='penalty' keeps them to rounding", 1.0 / gap), stacklevel=5)
    return gap


def linearize_canonical(system, op: OperatingPoint, cp: ConstrainedPoint, *,
                        derivatives: str = "analytic", step=None, alpha: float | None = None,
                        mu: float | None = None, omega: float | None = None,
                        estimate_error: bool = True) -> LinearModel:
    """Canonical (momentum) model (9.1.3): state y = [p; q], eq. 9.53 solved for y'.

    Raises:
        ArgumentError: alpha is too large for the canonical state matrix in float64 (see
            :data:`CANONICAL_REFUSE`).
    """
    alpha, mu, omega, Mp, Cp, Kp, terms, S = _penalty_setup(
        system, op, cp, derivatives, step, alpha, mu, omega, estimate_error)
    n = system.nv
    G = cp.jacobian
    C = terms.C if terms.C is not None else np.zeros((n, n))
    # One SVD and rotation of G for the model at alpha and the error estimate's 2 alpha.
    elimination = penalty_elimination(terms.M, C, terms.K, G, np.eye(n), mu, omega)
    A, B, Mp_inv, A_pen = canonical_first_order(terms.M, C, terms.K, G, S, alpha, mu, omega,
                                                elimination)
    error = penalty_error(A_pen, elimination(2.0 * alpha)[0], G, alpha, system.scene.name)
    gap = (_check_canonical_spectrum(A, A_pen, G, alpha, system.scene.name) if G.size
           else 0.0)
    alt = _alt(terms)
    # The estimate is taken on the penalty model of the same terms (the same spectrum): the
    # canonical A holds K_p ~ alpha Omega^2 exactly, which would dilute it.
    A_pen_alt = (None if alt is None else
                 canonical_first_order(terms.M, alt[1], alt[0], G, S, alpha, mu, omega)[3])
    numeric = penalty_numeric_info(terms, A_pen, A_pen_alt, Mp_inv, C)
    Cfull, D, out_names, y0 = output_matrices(system, op)
    # Outputs read dq and v; in (p, q): dq = q, v = M_p^-1 p.
    Cout = np.hstack([Cfull[:, n:] @ Mp_inv, Cfull[:, :n]])
    coords = system.coordinate_names
    states = tuple([f"p:{c}" for c in coords] + [f"q:{c}" for c in coords])
    if system.outputs is None:
        Cout, out_names, y0 = np.eye(2 * n), states, np.zeros(2 * n)
    info = _info(system, op, cp, "canonical", terms.backend, alpha=alpha, mu=mu,
                 omega=omega, penalty_error=error, **numeric)
    info["condition"]["canonical_vs_penalty_spectrum"] = gap
    return LinearModel(A=A, B=B, C=Cout, D=np.zeros((Cout.shape[0], S.shape[1])),
                       state_names=states, input_names=system.input_names,
                       output_names=out_names, G=G,
                       operating_point=op.with_outputs(y0),
                       name=system.scene.name, info=info)


__all__ = ["CANONICAL_REFUSE", "CANONICAL_WARN", "canonical_first_order", "linearize_canonical"]
