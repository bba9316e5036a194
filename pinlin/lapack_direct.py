"""Small dense solves with LAPACK called directly.

On the small matrices of loop assembly and statics (m, nv <= ~40) the checked wrappers of
numpy and scipy cost 3-10x the factorization itself. Each helper computes what the wrapper
named in its docstring computes, with the same tolerances (``tests/test_loop_cache.py``
compares them with the wrappers on square, tall, wide, rank-deficient and nearly singular
matrices).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from scipy.linalg import lapack

#: A square Newton system is solved by LU when its smallest pivot exceeds this fraction of
#: the largest (far from singular); else by the SVD least squares, as np.linalg.lstsq would.
LU_PIVOT_RATIO = 1e-8
_EPS = float(np.finfo(float).eps)

_GELSD_WORK: dict[tuple[int, int], tuple[int, int]] = {}


def lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.lstsq(a, b, rcond=None)[0]`` for a vector b: the minimum-norm least-squares
    solution, singular values below eps max(m, n) s_max dropped (LAPACK ``dgelsd``).

    Rows of ``a`` that are exactly zero do not change the minimizer (a planar loop's
    out-of-plane row): they are left out. A square rest whose LU pivots stay within
    :data:`LU_PIVOT_RATIO` of each other is solved by LU (``dgesv``): the same solution to
    rounding, several times cheaper."""
    m, n = a.shape
    if m > n:
        # A few rows of a few numbers: Python's any() on them is cheaper than numpy's calls.
        nonzero = [i for i, row in enumerate(a.tolist()) if any(row)]
        if len(nonzero) == n:
            a, b, m = a.take(nonzero, axis=0), b.take(nonzero), n
    if m == n and n:
        lu, _, x, info = lapack.dgesv(a, b)
        if info == 0:
            pivots = np.abs(lu.diagonal()).tolist()  # a few numbers: Python's min/max
            if min(pivots) > LU_PIVOT_RATIO * max(pivots):  # False on NaN
                return x
    return lstsq_rank(a, b)[0]


def lstsq_rank(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, int]:
    """``np.linalg.lstsq(a, b, rcond=None)``'s solution and rank for a vector b (LAPACK
    ``dgelsd``, the routine numpy calls, with numpy's rcond = eps max(m, n))."""
    m, n = a.shape
    work = _GELSD_WORK.get((m, n))
    if work is None and min(m, n):
        lw, liw, info = lapack.dgelsd_lwork(m, n, 1, -1.0)
        work = _GELSD_WORK[(m, n)] = (int(lw), int(liw)) if info == 0 else (0, 0)
    if not min(m, n) or work is None or not work[0]:
        x, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
        return x, int(rank)
    rhs = np.zeros(max(m, n))
    rhs[:m] = b
    x, _, rank, info = lapack.dgelsd(a, rhs, work[0], work[1], _EPS * max(m, n))
    if info != 0:  # the SVD did not converge: numpy's path raises its own error
        x, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
        return x, int(rank)
    return x[:n], int(rank)


def pivoted_qr(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|diag R| and the column permutation of ``scipy.linalg.qr(a, pivoting=True)`` (LAPACK
    ``dgeqp3``, the routine scipy calls)."""
    qr, jpvt, _, _, info = lapack.dgeqp3(a)
    if info != 0:  # pragma: no cover - dgeqp3 only fails on bad arguments
        _, r, piv = sla.qr(a, mode="economic", pivoting=True)
        return np.abs(np.diag(r)), piv
    return np.abs(qr.diagonal()), jpvt - 1


def condition_2(a: np.ndarray) -> float:
    """``np.linalg.cond(a)``: the 2-norm condition number s_max / s_min (LAPACK ``dgesdd``,
    singular values only); inf when s_min is 0, NaN when ``a`` is not finite."""
    if not np.isfinite(a).all():
        return float("nan")
    _, sv, _, info = lapack.dgesdd(a, compute_uv=0, full_matrices=0)
    if info != 0:
        return float(np.linalg.cond(a))
    with np.errstate(divide="ignore"):
        return float(sv[0] / sv[-1])
