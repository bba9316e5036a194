"""Condition estimates and the warning pinlin gives when accuracy is at risk.

A linear model loses about log10(cond) of float64's 16 digits where it solves with a matrix of
condition number cond. pinlin records the estimates it can get cheaply in
``model.info["condition"]`` and warns (:class:`AccuracyWarning`, carrying the estimate) above
:data:`WARN_CONDITION`:

- ``mass_matrix``: condition of the (reduced) mass matrix scaled to unit diagonal,
  Ms = D^-1/2 M D^-1/2 with D = diag(M) (near-dependent coordinates: two joints that move
  the same mass the same way): sum_i M_ii (M^-1)_ii = tr(Ms) tr(Ms^-1) / n for open chains
  (within a factor n of cond_2(Ms)), the 1-norm condition of Ms for the reduced mass
  matrices of mechanisms. The scaling takes the units out (kg against kg*m^2 on a floating
  base, a graded chain of light links): a Cholesky solve with M loses about log10
  cond_2(Ms) digits, not log10 cond_2(M) (van der Sluis). Unscaled, a 15 um box was told
  its mass matrix had condition 2e11 and PR2's reported 9e6 where its scaled one is 69;
- ``constraint_jacobian``: 2-norm condition of the dependent-coordinate block Phi_d of the
  loop Jacobian (a mechanism near a toggle or singular position: R ill-conditioned); warned
  above 1e6, since near a fold it grows only like 1 / sqrt(distance to the fold). Measured in
  one unit (:func:`pinlin.assembly.in_one_unit`: a slider's or floating base's columns and
  a weld's rotation rows times the robot's length), so that it does not change with the
  robot's size.

``pinlin.modal`` warns the same way when an eigenvalue's condition number kappa times the
rounding level of A exceeds 1e-8 of the eigenvalue.

Beyond warning, pinlin refuses a mass matrix that is singular to working precision
(:func:`singular_to_working_precision`): ``pinlin.linearize`` raises
:class:`~pinlin.ModelError` unless called with ``allow_ill_conditioned=True``
(``--allow-ill-conditioned``). The test is unit-independent: M is first scaled to unit
diagonal, Ms = D^-1/2 M D^-1/2 with D = diag(M) (Jacobi scaling: within a factor n of the best
diagonal scaling, van der Sluis), so that a chain whose masses fall by 1e-6 per link (cond_2(M)
~ 1e18, cond_2(Ms) ~ 1) is not refused: graded like that, its model keeps its digits (in
tests/hard the two eigensolvers agree to rounding on it). M^-1 along Ms's weakest direction
carries a relative error of about n eps cond_2(Ms); Ms is singular to working precision when
that reaches 0.1, i.e. cond_2(Ms) >= :func:`refuse_condition` = 0.1 / (n eps): not one
reliable digit is left there (numpy.linalg.matrix_rank would call Ms rank-deficient 10x
further on). A mass matrix that is exactly singular (icub's head, a point mass turned about
its centre by two neck joints) computes to cond_2(Ms) = 3e14 to 9e14 at n = 38 (300 random
postures), 25-75x above the 1.2e13 limit; the next worst loadable robot is below 1e3. Below
the limit the scaled estimate warns from :data:`WARN_CONDITION`.
"""

from __future__ import annotations

import math
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
    """Estimate of cond_2 of a symmetric positive definite M scaled to unit diagonal
    (Ms = D^-1/2 M D^-1/2, D = diag M) from M and its inverse: tr(Ms) tr(Ms^-1) / n =
    sum_i M_ii (M^-1)_ii, within a factor n of cond_2(Ms) (since cond_2 <= tr(Ms) tr(Ms^-1)
    <= n^2 cond_2); two diagonals, no factorization. 1 for n = 0."""
    if M.shape[0] == 0:
        return 1.0
    return float(np.dot(M.diagonal(), Minv.diagonal()))


def scaled_condition_1(M: np.ndarray, Minv: np.ndarray) -> float:
    """The 1-norm condition of M scaled to unit diagonal, |Ms|_1 |Ms^-1|_1 with
    Ms^-1 = D^1/2 M^-1 D^1/2, from M and its inverse (np.linalg.cond(Ms, 1)); 1 for n = 0,
    inf where a diagonal entry of M is not positive."""
    if M.shape[0] == 0:
        return 1.0
    d = M.diagonal()
    if not d.min() > 0.0:
        return float("inf")
    s = np.sqrt(d)
    return float(np.abs(M / np.outer(s, s)).sum(axis=0).max()
                 * np.abs(Minv * np.outer(s, s)).sum(axis=0).max())


def refuse_condition(n: int) -> float:
    """Scaled condition number at which an n x n symmetric positive semi-definite matrix is
    singular to working precision: 0.1 / (n eps), where its inverse along the weakest
    direction keeps less than one significant digit."""
    return 0.1 / (max(n, 1) * float(np.finfo(float).eps))


def scaled_condition(M: np.ndarray) -> float:
    """2-norm condition number of Ms = D^-1/2 M D^-1/2 (D = diag M) from its eigenvalues: the
    condition that does not depend on the units or scales of the coordinates; inf when a
    diagonal entry or the smallest eigenvalue is not positive."""
    n = M.shape[0]
    if n == 0:
        return 1.0
    d = np.diagonal(M)
    if not d.min() > 0.0:
        return float("inf")
    s = 1.0 / np.sqrt(d)
    w = np.linalg.eigvalsh(0.5 * (M + M.T) * np.outer(s, s))
    return float(w[-1] / w[0]) if w[0] > 0.0 else float("inf")


def singular_to_working_precision(M: np.ndarray, bound: float = float("inf")) -> float | None:
    """The scaled condition of M (:func:`scaled_condition`) when it reaches
    :func:`refuse_condition`, else None.

    ``bound`` is an upper bound on the scaled condition that the caller has for free (for M
    and M^-1 at hand, n * sum_i M_ii (M^-1)_ii bounds it, since tr(Ms) tr(Ms^-1) >= cond_2(Ms)):
    below the limit it settles the question without the O(n^3) eigenvalues. A non-finite or
    non-positive bound (M^-1 not positive definite) is always checked.
    """
    n = M.shape[0]
    limit = refuse_condition(n)
    if n == 0 or (np.isfinite(bound) and 0.0 < bound < limit):
        return None
    cond = scaled_condition(M)
    return cond if cond >= limit else None


def warn_if_ill_conditioned(what: str, condition: float, name: str,
                            threshold: float = WARN_CONDITION, stacklevel: int = 4,
                            size: int | None = None) -> None:
    """Issue an :class:`AccuracyWarning` when ``condition`` exceeds ``threshold`` (a
    non-positive estimate, from an inverse that is not positive definite, counts as infinite).
    The digits it says are reliable: 16 - log10(condition), or with the matrix's ``size`` n,
    -log10(n eps condition), the relative error of a solve (0 where the refusal limit
    0.1 / (n eps) of :func:`refuse_condition` is reached)."""
    if not math.isfinite(condition) or condition <= 0.0:
        condition = float("inf")
    if condition > threshold:
        if not math.isfinite(condition):
            digits = 0.0
        elif size is None:
            digits = 16 - math.log10(condition)
        else:
            digits = -math.log10(max(size, 1) * float(np.finfo(float).eps) * condition)
        warnings.warn(AccuracyWarning(
            f"model '{name}': the {what} has condition number {condition:.2e}; about "
            f"{max(digits, 0):.0f} significant digits of the result are reliable", condition),
            stacklevel=stacklevel)
