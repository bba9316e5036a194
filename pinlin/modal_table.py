"""How a :class:`~pinlin.modal.ModalAnalysis` reads as a table: its modes (one eigenvalue per
conjugate or rigid pair), the constraint modes of a dependent-coordinate model, the kind of
each mode (constraint, rigid, oscillatory, ...), the coordinates that dominate its shape, and
the printed table with one row per mode; the analysis's methods of the same names call these
functions.

The printed table shows a real part (and so zeta) as 0 where it is below the eigenvalue's
rounding level (:attr:`ModalAnalysis.rounding`, kappa eps |A|_F: how far rounding A's entries
moves it to first order), so an undamped mode prints zeta 0, not -5e-18; the arrays
``eigenvalues`` and ``zeta`` keep the computed values. Which modes oscillate, decay or grow
(:func:`kind`) is decided by a margin above rounding: a real or imaginary part counts above
10 n times the eigenvalue's rounding level (n eigenvalues: the eigensolver's backward error is
up to ~n eps |A|), or above rigid_tol (:func:`resolved`). rigid_tol alone would be too
coarse where the spectrum is wide: it follows the fastest mode, so beside a 1e7 1/s mode
(rigid_tol 10) it would call -100 +- 5j real and +5 +- 100j undamped.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .modal import ModalAnalysis

#: Default relative threshold [-]: an eigenvalue with |lam| <= RIGID_RTOL max(1, max |lam|)
#: [rad/s] is a rigid-body mode (:func:`pinlin.modal`'s rigid_tol; the penalty error estimate
#: leaves the same modes out).
RIGID_RTOL = 1e-6


def oscillates(analysis: ModalAnalysis, index: int) -> bool:
    """:meth:`ModalAnalysis.oscillates` of ``analysis`` (documented there, in
    :mod:`pinlin.modal`)."""
    # rigid_tol follows the fastest mode; a slow mode's imaginary part may lie below it and
    # still far above its own rounding level (-100 +- 5j beside -1e7: rigid_tol is 10).
    return resolved(analysis, index, abs(analysis.eigenvalues[index].imag))


def resolved(analysis: ModalAnalysis, index: int, value: float) -> bool:
    """Whether a part ``value`` >= 0 [1/s] (|Re| or |Im|) of eigenvalue ``index`` is more than
    rounding: above rigid_tol, or above 10 n times the eigenvalue's rounding level (the
    first-order move kappa eps |A|_F, times the eigensolver's backward error of up to ~n eps
    |A|, times 10; n eigenvalues). Below both, the part counts as zero (an undamped mode, a
    real eigenvalue). The rounding level is at least eps |A|_F (kappa >= 1), so a part below
    10 n eps |A|_F is settled without it: the condition numbers (a second dgeev) are computed
    only for parts between that and rigid_tol."""
    if value > analysis.rigid_tol:
        return True
    if value == 0.0:
        return False
    margin = 10.0 * len(analysis.eigenvalues)
    if value <= margin * analysis.rounding_floor:
        return False
    return value > margin * analysis.rounding[index]


def modes(analysis: ModalAnalysis) -> list[int]:
    """:meth:`ModalAnalysis.modes` of ``analysis`` (documented there, in
    :mod:`pinlin.modal`)."""
    keep: list[int] = []
    skip: set[int] = set()
    lam = analysis.eigenvalues
    for i in range(len(lam)):
        if i in skip:
            continue
        keep.append(i)
        if i + 1 < len(lam) and (
            # A rigid DoF of a mechanical model is a 2x2 Jordan block: two zero eigenvalues.
            (analysis.rigid[i] and analysis.rigid[i + 1] and analysis.model.has_second_order)
            or (oscillates(analysis, i)
                and abs(lam[i + 1] - lam[i].conjugate()) <= 1e-9 * max(1.0, abs(lam[i])))
        ):
            skip.add(i + 1)
    return keep


def constraint(analysis: ModalAnalysis) -> np.ndarray:
    """:attr:`ModalAnalysis.constraint` of ``analysis`` (documented there, in
    :mod:`pinlin.modal`)."""
    G = analysis.model.G
    if G is None or G.shape[0] == 0:
        return np.zeros(len(analysis.eigenvalues), dtype=bool)
    return constraint_mask(analysis.model, analysis.right_vectors)


def constraint_mask(model, vectors: np.ndarray) -> np.ndarray:
    """Which columns of the right eigenvectors ``vectors`` (of a model with G, m rows) are the
    2m constraint modes (:func:`constraint_columns` of their position part)."""
    rows = [k for k, s in enumerate(model.state_names) if s.startswith("q:")]
    return constraint_columns(model.G, vectors[rows])


def constraint_columns(G: np.ndarray, right_q: np.ndarray) -> np.ndarray:
    """Mask of the 2m constraint modes among the columns of ``right_q``, the position part
    (n, k) of right eigenvectors of a dependent-coordinate model whose G has m rows: those
    whose position part lies most in the range of G^T (the penalty model's, the canonical
    model's, the mode table's)."""
    ratio = np.linalg.norm(G @ right_q, axis=0) / (
        np.linalg.norm(G, 2) * np.maximum(np.linalg.norm(right_q, axis=0), np.finfo(float).tiny))
    out = np.zeros(right_q.shape[1], dtype=bool)
    out[np.argsort(-ratio, kind="stable")[:2 * G.shape[0]]] = True
    return out


def kind(analysis: ModalAnalysis, index: int) -> str:
    """:meth:`ModalAnalysis.kind` of ``analysis`` (documented there, in
    :mod:`pinlin.modal`)."""
    lam = analysis.eigenvalues[index]
    if analysis.constraint[index]:
        return "constraint"
    if analysis.rigid[index]:
        return "rigid"
    if lam.real > 0.0 and resolved(analysis, index, lam.real):
        return "unstable osc." if oscillates(analysis, index) else "unstable"
    if oscillates(analysis, index):
        return "oscillatory" if lam.real < 0.0 and resolved(analysis, index, -lam.real) \
            else "undamped"
    return "real"


def dominant(analysis: ModalAnalysis, index: int, threshold: float = 0.5, limit: int = 3
             ) -> list[str]:
    """:meth:`ModalAnalysis.dominant` of ``analysis`` (documented there, in
    :mod:`pinlin.modal`)."""
    mag = np.abs(analysis.shapes[:, index])
    order = np.argsort(-mag, kind="stable")
    return [analysis.coordinate_names[k] for k in order[:limit] if mag[k] >= threshold]


def table(analysis: ModalAnalysis) -> str:
    """:meth:`ModalAnalysis.table` of ``analysis`` (documented there, in
    :mod:`pinlin.modal`)."""
    head = (f"{'#':>3}  {'eigenvalue [1/s]':>28}  {'wn [rad/s]':>11}  {'f [Hz]':>10}  "
            f"{'zeta':>8}  {'kind':<13}  dominant coordinates")
    count = len(analysis.eigenvalues)
    lines = [f"Modes of '{analysis.model.name}' ({analysis.method} eigensolver, "
             f"{count} eigenvalue{'' if count == 1 else 's'}, rigid below "
             f"{analysis.rigid_tol:.1e} rad/s)", head, "-" * len(head)]
    for n, i in enumerate(analysis.modes(), start=1):
        lam = analysis.eigenvalues[i]
        if analysis.rigid[i]:
            ev, wn, f, zeta = "0 (rigid)", "0", "0", "-"
        else:
            im = abs(lam.imag)
            # A real part within rounding of 0 (an undamped mode) prints as 0, zeta too;
            # not where rounding may move the whole eigenvalue (a defective one): as computed.
            noise = abs(lam.real) <= analysis.rounding[i] < abs(lam)
            re = "0" if noise else f"{lam.real:+.6g}"
            ev = f"{re} +- {im:.6g}j" if oscillates(analysis, i) else re
            wn, f = f"{analysis.wn[i]:.6g}", f"{analysis.wn[i] / (2 * np.pi):.6g}"
            zeta = "0" if noise else f"{analysis.zeta[i]:.4g}"
        dom = ", ".join(analysis.dominant(i))
        lines.append(f"{n:>3}  {ev:>28}  {wn:>11}  {f:>10}  {zeta:>8}  {analysis.kind(i):<13}  "
                     f"{dom}")
    return "\n".join(lines)
