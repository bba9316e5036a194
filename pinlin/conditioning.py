"""Condition estimates and the warning pinlin gives when accuracy is at risk.

A linear model loses about log10(cond) of float64's 16 digits where it solves with a matrix of
condition number cond. pinlin records the estimates it can get cheaply in
``model.info["condition"]`` and warns (:class:`AccuracyWarning`, carrying the estimate) above
:data:`WARN_CONDITION`:

- ``mass_matrix``: condition of the (reduced) mass matrix (mass or inertia ratios along a
  chain, near-massless bodies): tr(M) tr(M^-1) / n for open chains (within a factor n of
  cond_2), the 1-norm condition for reduced mass matrices of mechanisms;
- ``constraint_jacobian``: 2-norm condition of the dependent-coordinate block Phi_d of the
  loop Jacobian (a mechanism near a toggle or singular position: R ill-conditioned); warned
  above 1e6, since near a fold it grows only like 1 / sqrt(distance to the fold).

``pinlin.modal`` warns the same way when an eigenvalue's condition number kappa times the
rounding level of A exceeds 1e-8 of the eigenvalue.
"""

from __future__ import annotations

import warnings

import numpy as np

#: Condition number above which pinlin warns: at most ~6 significant digits are left.
WARN_CONDITION = 1e10


class AccuracyWarning(UserWarning):
    """Accuracy of a result is at risk; ``condition`` holds the estimate that says so."""

    def __init__(self, message: str, condition: float) -> None:
        super().__init__(message)
        self.condition = condition


def trace_condition(M: np.ndarray, Minv: np.ndarray) -> float:
    """Estimate of cond_2 of a symmetric positive definite M from M and its inverse:
    tr(M) tr(M^-1) / n, within a factor n of cond_2 (since cond_2 <= tr(M) tr(M^-1) <=
    n^2 cond_2); two traces, no factorization."""
    n = M.shape[0]
    if n == 0:
        return 1.0
    return float(M.trace() * Minv.trace() / n)


def warn_if_ill_conditioned(what: str, condition: float, name: str,
                            threshold: float = WARN_CONDITION, stacklevel: int = 4) -> None:
    """Issue an :class:`AccuracyWarning` when ``condition`` exceeds ``threshold``."""
    if not np.isfinite(condition) or condition > threshold:
        digits = 16 - np.log10(condition) if np.isfinite(condition) else 0.0
        warnings.warn(AccuracyWarning(
            f"model '{name}': the {what} has condition number {condition:.2e}; about "
            f"{max(digits, 0):.0f} significant digits of the result are reliable", condition),
            stacklevel=stacklevel)
