"""What :func:`pinlin.modal` accepts: a rigid-body threshold that is a finite number >= 0,
and matrices whose entries float64 can square (:data:`ENTRY_LIMIT`)."""

from __future__ import annotations

import math
import numbers
from typing import TYPE_CHECKING

import numpy as np

from .arrays import sum_of_squares
from .exceptions import ArgumentError, ModelError

if TYPE_CHECKING:
    from .linear_model import LinearModel

#: Largest |entry| of the matrices modal analyses. The eigensolvers and this module square
#: entries (K + K^T, |lam|^2 = K/M, vector norms, kappa eps max|A|): 1e150^2 = 1e300 stays
#: below float64's 1.8e308. A physical model in SI units is many decades below (see the
#: ranges in :mod:`pinlin.fields`); one beyond is refused rather than analysed into inf/NaN.
ENTRY_LIMIT = 1e150

def check_rigid_tol(rigid_tol: object) -> float:
    """``rigid_tol`` as a float: a real number (not a bool), finite and >= 0 [rad/s]."""
    bad = ArgumentError("rigid_tol", f"expected a finite number >= 0 [rad/s] or None, got "
                                     f"{type(rigid_tol).__name__} {rigid_tol!r:.60}")
    if not isinstance(rigid_tol, numbers.Real) or isinstance(rigid_tol, bool | np.bool_):
        raise bad
    try:
        value = float(rigid_tol)
    except (OverflowError, ValueError, TypeError):
        raise bad from None
    if not (math.isfinite(value) and value >= 0.0):
        raise bad
    return value


def check_entries(model: LinearModel) -> float:
    """Refuse a model whose matrices modal reads hold NaN, inf or |entry| > ENTRY_LIMIT;
    return sum A_ij^2 (|A|_F^2, which the general path's accuracy bound uses).

    One dot product per matrix settles the usual case: sum x^2 <= ENTRY_LIMIT^2 holds for no
    NaN, inf or entry beyond the limit (its square alone exceeds ENTRY_LIMIT^2); only a matrix
    that fails it is searched entry by entry (many entries near the limit pass there)."""
    limit2 = ENTRY_LIMIT * ENTRY_LIMIT
    a2 = math.inf
    for key in ("A", "E", "M", "C_damp", "K"):
        mat = getattr(model, key)
        if mat is None or mat.size == 0:
            continue
        total = sum_of_squares(mat)
        if key == "A":
            a2 = total
        if total <= limit2:  # NaN compares False (BLAS ddot: no FP warnings)
            continue
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(mat) <= ENTRY_LIMIT)  # NaN compares False
        if not bad.any():
            continue
        i, j = (int(k) for k in np.argwhere(bad)[0])
        raise ModelError(f"model '{model.name}': matrix {key} has {int(bad.sum())} entries "
                         f"that are NaN, inf or beyond {ENTRY_LIMIT:g} in magnitude (first "
                         f"{key}[{i}, {j}] = {mat[i, j]:.3g}); modal analysis needs finite "
                         f"entries with |x| <= {ENTRY_LIMIT:g} (float64 squares them)")
    return a2
