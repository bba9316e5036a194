"""How far a finite penalty leaves the physical eigenvalues from the constrained system's.

The penalty model's physical eigenvalues tend to those of the constrained system (the
independent model) as alpha grows: lam(alpha) = lam + c / alpha + O(1 / alpha^2), so
lam(alpha) - lam(2 alpha) = c / (2 alpha) to first order and the error c / alpha is twice that
difference. pinlin takes the difference from the two state matrices rather than from two
spectra (no matching of eigenvalues needed): with x_i and y_i the right and left eigenvectors
of A(alpha), first-order perturbation gives lam_i(alpha) - lam_i(2 alpha) =
y_i^H (A(alpha) - A(2 alpha)) x_i / (y_i^H x_i). Both state matrices come from the stable
elimination (:func:`~pinlin.formulations.constrained.penalty_first_order`), whose entries stay
O(1) in alpha, so their difference carries the c / alpha signal down to rounding.

Measured (``tests/test_penalty_error.py``) against the independent model's eigenvalues at
rest, and against the penalty model with 1e4 alpha at a moving state (away from an
equilibrium the eigenvalues depend on the coordinates, so the limit is the penalty model's
own): the estimate gives the error within 3 % wherever it lies between rounding and 1e-3
(to 3 digits or better on the bundled mechanisms and standing robots at their own size), and
0.08 against 0.115 where alpha is far too small (a four-bar of a thousand tonnes at 8 mm),
where second-order terms count. Rounding is not part of it (:func:`pinlin.modal` checks that).
The 2m constraint modes (their position part lies most in the range of G^T) and
rigid-body modes (|lam| <= 1e-6 max(1, max |lam|) [rad/s], as :func:`pinlin.modal` counts them)
are left out: the first converge to the roots of s^2 + 2 mu Omega s + Omega^2, not to a
physical eigenvalue, and a rigid mode's relative error has no scale. A physical eigenvalue
that is defective in the limit (a mode critically damped to within about 1e-8) is split by the
penalty and converges like alpha^-1/2, not 1/alpha: there the estimate runs about 2x low (at
zeta = 1 +- 1e-4 it is exact again).
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla

from ..conditioning import AccuracyWarning
from ..modal_table import RIGID_RTOL, constraint_columns

#: A penalty or canonical model warns where :func:`penalty_error` exceeds this: its physical
#: eigenvalues are off in their third digit or worse.
PENALTY_WARN = 1e-3


def penalty_error(A: np.ndarray, A_double: np.ndarray, G: np.ndarray, alpha: float,
                  name: str, stacklevel: int = 4) -> float:
    """First-order estimate of the largest relative error that the penalty leaves in the
    physical eigenvalues of the penalty model ``A`` (x = [dq; v]), from ``A_double``, the same
    model with 2 alpha (module docstring), with an AccuracyWarning above
    :data:`PENALTY_WARN`. Returns the estimate [-] (0 without constraint rows or physical
    modes; inf where a physical eigenvector pair is orthogonal to rounding, |y^H x| <= eps,
    so that first order says nothing; NaN where A is not finite)."""
    n, m = G.shape[1], G.shape[0]
    if m == 0:
        return 0.0
    lam, left, right = sla.eig(A, left=True, right=True, check_finite=False)
    scale = RIGID_RTOL * max(1.0, float(np.abs(lam).max(initial=0.0)))
    physical = ~constraint_columns(G, right[:n]) & (np.abs(lam) > scale)
    if not physical.any():
        return 0.0
    y, x = left[:, physical], right[:, physical]
    overlap = np.einsum("ij,ij->j", y.conj(), x)
    shift = 2.0 * np.einsum("ij,ij->j", y.conj(), (A - A_double) @ x)
    # |y^H x| below eps |y| |x| (both unit vectors): a defective eigenvalue, no first order.
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(np.abs(overlap) > np.finfo(float).eps,
                       np.abs(shift) / np.maximum(np.abs(overlap), np.finfo(float).tiny),
                       np.inf) / np.abs(lam[physical])
    error = float(rel.max())
    if not error <= PENALTY_WARN:   # NaN or inf too
        what = (f"the penalty alpha = {alpha:.3g} is small for this system's mass and "
                f"stiffness: its physical eigenvalues are off by about {error:.1e} (relative, "
                f"first-order estimate); raise alpha (about {min(alpha * error / 1e-6, 1e14):.1e}"
                " for 1e-6) or use the independent formulation" if np.isfinite(error) else
                "a physical eigenvalue of the penalty model is defective (a repeated root), "
                "so the penalty's error on it cannot be estimated to first order; compare "
                "with the independent formulation" if error == np.inf else
                "the penalty's error on its physical eigenvalues could not be estimated (not "
                "a number); compare with the independent formulation")
        warnings.warn(AccuracyWarning(f"model '{name}': {what}", error), stacklevel=stacklevel)
    return error
