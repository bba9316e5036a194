"""Screening a batch's stacks (:mod:`pinlin.batch`): which points need the single call's
checks, and those checks.

While the batch fills a block of points it flags, from the diagonals of M and M^-1 it has at
every point, those where M may be singular to working precision (:func:`suspect`) or ill
conditioned enough for the single call's AccuracyWarning (:func:`may_warn`), and every point
whose matrices hold NaN or inf (:func:`screen`). :func:`check` then runs the single call's
own tests at the flagged points only: the refusal of :meth:`pinlin.System.mass_inverse`,
naming the first bad point, and the warning at the worst one.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .conditioning import trace_condition, warn_if_ill_conditioned
from .exceptions import ModelError, PinlinError
from .system import System

#: The per-point second-order stacks of ``second_order=True`` (Bu = S is constant).
SECOND_ORDER = ("M", "C_damp", "K")
#: A screen flags a point whose estimate comes within this factor of its limit: the batch's
#: M and M^-1 round differently from those the exact check computes (:func:`check`), so a
#: point on the edge is left to that check, never passed by the screen alone.
SCREEN_MARGIN = 0.5


def scaled_traces(m_diag: np.ndarray, minv_diag: np.ndarray) -> np.ndarray:
    """sum_i M_ii (M^-1)_ii of each point (rows: diag M and diag M^-1 per point), the single
    call's condition estimate (:func:`pinlin.conditioning.trace_condition`): tr(Ms) tr(Ms^-1)
    / n of M scaled to unit diagonal. What :func:`suspect` and :func:`may_warn` test."""
    with np.errstate(invalid="ignore", over="ignore"):
        return np.einsum("ij,ij->i", m_diag, minv_diag)


def suspect(traces: np.ndarray, minv_diag: np.ndarray, limit: float) -> np.ndarray:
    """Points where M may be singular to working precision: the first test of
    :meth:`System.check_mass_inverse`, n sum_i M_ii (M^-1)_ii (``traces``: :func:`scaled_traces`;
    >= the condition of M scaled to unit diagonal), does not clear ``limit`` (the refusal
    condition) by :data:`SCREEN_MARGIN`, or M^-1 is not positive on its diagonal (NaN
    included)."""
    n = minv_diag.shape[1]
    if not n:   # no coordinate: nothing to invert
        return np.zeros(minv_diag.shape[0], dtype=bool)
    with np.errstate(invalid="ignore", over="ignore"):
        estimate = n * traces
    return ~((estimate > 0.0) & (estimate < SCREEN_MARGIN * limit)
             & (minv_diag.min(axis=1, initial=np.inf) > 0.0))


def may_warn(traces: np.ndarray, threshold: float) -> np.ndarray:
    """Points where the single call's condition estimate (``traces``: :func:`scaled_traces`)
    may exceed ``threshold`` (its AccuracyWarning), within :data:`SCREEN_MARGIN`;
    :func:`check` computes the estimate itself where this says it may."""
    return traces > SCREEN_MARGIN * threshold


def screen(system: System, arrays: Mapping[str, np.ndarray], lo: int, hi: int,
           bad: np.ndarray, watch: np.ndarray | None = None) -> None:
    """Mark ``bad`` and the non-finite points of lo:hi in ``arrays["bad"]`` (1): one sum per
    point and matrix (NaN or inf makes it non-finite; so may finite entries that overflow,
    which :func:`check` tells apart); ``watch`` (0.5): points whose mass matrix may be ill
    conditioned enough for the single call's AccuracyWarning."""
    nv = system.nv
    for key in ("f0", "A", "B", "C", *SECOND_ORDER):
        stack = arrays.get(key)
        if stack is None or not stack.size:
            continue
        part = stack[lo:hi, nv:] if key in ("A", "B") else stack[lo:hi]
        rows = part.reshape(hi - lo, -1)  # a view: each point's rows are contiguous
        bad |= ~np.isfinite(np.add.reduce(rows, axis=1))  # no BLAS: no threads woken
    arrays["bad"][lo:hi] = bad if watch is None else np.where(bad, 1.0, 0.5 * watch)


def at_point(exc: PinlinError, k: int) -> PinlinError:
    """``exc`` with "trajectory point k: " before its message, same class (the class's own
    constructor is bypassed: some take several fields)."""
    new = type(exc).__new__(type(exc))
    Exception.__init__(new, f"trajectory point {k}: {exc}")
    new.__dict__.update(exc.__dict__)
    return new


def check(system: System, arrays: Mapping[str, np.ndarray]) -> None:
    """Refuse a stack that :func:`fill` marked bad, naming the first bad point.

    Raises:
        ModelError: the first bad point's: the mass matrix's own refusal where M(q) is singular
            (:meth:`System.mass_inverse`), else which matrix is not finite.
    """
    passed = []   # suspected, then accepted: their condition is checked below too
    for k in (int(i) for i in np.flatnonzero(arrays["bad"] == 1.0)):
        try:
            system.mass_inverse(arrays["q"][k])
        except ModelError as exc:
            raise at_point(exc, k) from None
        where = [key for key in ("f0", "A", "B", "C", *SECOND_ORDER) if key in arrays
                 and not np.all(np.isfinite(arrays[key][k]))]
        if where:
            raise ModelError(f"trajectory point {k}: scene '{system.scene.name}': the linear "
                             f"model has NaN or inf in {', '.join(where)}; a model with NaN "
                             "or inf is never returned")
        # else: finite entries whose sum overflowed, and a mass matrix System accepts
        passed.append(k)
    watch = [*np.flatnonzero(arrays["bad"] == 0.5), *passed]
    if watch:   # the single call's warning, at the worst of the points it may concern
        worst, condition = 0, 0.0
        for k in (int(i) for i in watch):
            q = arrays["q"][k]
            c = trace_condition(system.mass_matrix(q),
                                system.mass_inverse(q, allow_ill_conditioned=True))
            if not c <= condition:   # NaN wins
                worst, condition = k, c
        warn_if_ill_conditioned(f"mass matrix at trajectory point {worst}", condition,
                                system.scene.name, size=system.nv)


__all__ = ["SCREEN_MARGIN", "SECOND_ORDER", "at_point", "check", "may_warn", "scaled_traces",
           "screen", "suspect"]
