"""Modal analysis of a linear model: eigenvalues, natural frequencies, damping, mode shapes.

Two solvers:

- **symmetric**: when the model has no velocity-dependent terms (C_damp = 0) and a symmetric
  stiffness, the 2n eigenvalues of A are +-sqrt(-w2) for the n eigenvalues w2 of the symmetric
  definite pencil (K, M) (``scipy.linalg.eigh``, mass-normalized shapes phi). Right and left
  eigenvectors of A follow in closed form: r = [phi; lam phi], l = [M phi / 2; M phi / (2 lam)*]
  with l^H r = 1. A zero w2 (rigid-body mode) is a 2x2 Jordan block of A: its pair of vectors is
  the chain [phi; 0], [0; phi] with left vectors [M phi; 0], [0; M phi].
- **general**: ``scipy.linalg.eig(A, left=True)`` of size 2n, left vectors scaled to l^H r = 1,
  and the eigenvalue condition numbers kappa = |l| |r| / |l^H r|.

Conventions: wn = |lam| [rad/s], zeta = -Re(lam) / |lam|. Eigenvalues with |lam| <= rigid_tol are
rigid-body (zero) modes: wn = 0 and zeta = NaN by definition (never computed as 0/0), labelled
"rigid" in the table. The default rigid_tol is 1e-6 * max(1, largest |lam|) [rad/s], well above
the O(sqrt(eps) |lam|max) spread that rounding gives a zero eigenvalue of a Jordan block.

The printed table shows a real part (and so zeta) as 0 where it is below the eigenvalue's
rounding level (:attr:`ModalAnalysis.rounding`, kappa eps |A|_F: how far rounding A's entries
moves it to first order), so an undamped mode prints zeta 0, not -5e-18; the arrays
``eigenvalues`` and ``zeta`` keep the computed values, and which modes are stable does not
change (that uses rigid_tol, many orders above).
"""

from __future__ import annotations

import functools
import math
import numbers
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla

from .exceptions import ArgumentError, ModelError, PinlinError
from .linear_model import LinearModel

if TYPE_CHECKING:
    from .modal_coordinates import ModalCoordinates
    from .modal_energy import ModalEnergy
    from .scene import Scene

METHODS = ("auto", "symmetric", "general")
RIGID_RTOL = 1e-6
SYMMETRY_RTOL = 1e-8
#: Largest |entry| of the matrices modal analyses. The eigensolvers and this module square
#: entries (K + K^T, |lam|^2 = K/M, vector norms, kappa eps max|A|): 1e150^2 = 1e300 stays
#: below float64's 1.8e308. A physical model in SI units is many decades below (see the
#: ranges in :mod:`pinlin.fields`); one beyond is refused rather than analysed into inf/NaN.
ENTRY_LIMIT = 1e150


def symmetric_applicable(model: LinearModel) -> bool:
    """Whether the (K, M) path applies: second-order model, C_damp = 0, K symmetric, B, A
    consistent with them (no E)."""
    if not model.has_second_order or model.E is not None:
        return False
    if model.info.get("velocity_terms", True) and np.any(model.C_damp):
        return False
    K = model.K
    scale = max(float(np.abs(K).max(initial=0.0)), np.finfo(float).tiny)
    return float(np.abs(K - K.T).max(initial=0.0)) <= SYMMETRY_RTOL * scale


@dataclass(frozen=True, eq=False)
class ModalAnalysis:
    """Eigen-analysis of a linear model; print it for a table.

    Attributes:
        eigenvalues: 2n eigenvalues, by increasing |lam|, conjugate pairs adjacent (+Im first).
        shapes: Mode shapes in the coordinates (position part of the right vectors), each scaled
            so that its largest entry is exactly 1.
        coordinate_names: Names of the shape entries.
        wn: Natural frequency |lam| [rad/s] (0 for rigid modes).
        zeta: Damping ratio -Re(lam)/|lam| (NaN for rigid modes).
        rigid: Mask of rigid-body (zero) eigenvalues.
        rigid_tol: Threshold used for ``rigid`` [rad/s].
        method: ``"symmetric"`` or ``"general"``.
        model: The analysed model.
    """

    eigenvalues: np.ndarray
    shapes: np.ndarray
    coordinate_names: tuple[str, ...]
    wn: np.ndarray
    zeta: np.ndarray
    rigid: np.ndarray
    rigid_tol: float
    method: str
    model: LinearModel
    _right: np.ndarray | None = None
    _left: np.ndarray | None = None
    _phi: np.ndarray | None = None

    # ----------------------------------------------------------------------------------------
    @property
    def frequencies_hz(self) -> np.ndarray:
        """Natural frequencies wn / 2 pi [Hz]."""
        return self.wn / (2.0 * np.pi)

    @property
    def unstable(self) -> np.ndarray:
        """Mask of eigenvalues with Re(lam) > rigid_tol (exponentially growing modes)."""
        return self.eigenvalues.real > self.rigid_tol

    @property
    def is_stable(self) -> bool:
        """No eigenvalue with a positive real part beyond the tolerance."""
        return not bool(np.any(self.unstable))

    @functools.cached_property
    def right_vectors(self) -> np.ndarray:
        """Right eigenvectors of A as columns (Jordan chains for rigid modes of the symmetric
        path); built on first access."""
        if self._right is not None:
            return self._right
        return _symmetric_right(self.eigenvalues, self._phi, self.rigid)

    @functools.cached_property
    def left_vectors(self) -> np.ndarray:
        """Left eigenvectors as columns, scaled so that l_i^H r_i = 1; built on first access."""
        if self._left is not None:
            return self._left
        return _symmetric_left(self.eigenvalues, self.model.M @ self._phi, self.rigid)

    @functools.cached_property
    def condition(self) -> np.ndarray:
        """Eigenvalue condition numbers |l| |r| / |l^H r| (1 for a normal matrix; large values
        mean the eigenvalue is sensitive to perturbations of A; inf at a Jordan block)."""
        L, R = self.left_vectors, self.right_vectors
        dots = np.abs(np.einsum("ij,ij->j", L.conj(), R))
        norms = np.linalg.norm(L, axis=0) * np.linalg.norm(R, axis=0)
        with np.errstate(divide="ignore"):
            kappa = np.where(dots > 0, norms / np.where(dots > 0, dots, 1.0), np.inf)
        if self.method == "symmetric":
            kappa = np.where(self.rigid, np.inf, kappa)  # Jordan blocks are defective
        return kappa

    @functools.cached_property
    def rounding(self) -> np.ndarray:
        """Rounding level of each eigenvalue [1/s]: kappa eps |A|_F, the first-order move of
        an eigenvalue with condition number kappa when A's entries are rounded (the backward
        error of the eigensolver is of that size). Zero for the symmetric solver, whose
        eigenvalues +-i w and +-sigma have exactly zero real or imaginary parts; at most
        sqrt(eps) |A|_F (a defective eigenvalue, kappa = inf, moves like sqrt(eps))."""
        if self.method == "symmetric":
            return np.zeros(len(self.eigenvalues))
        eps = np.finfo(float).eps
        norm = float(np.linalg.norm(self.model.A))
        kappa = np.nan_to_num(self.condition, nan=np.inf)
        return np.minimum(kappa * eps, np.sqrt(eps)) * norm

    # Decoupling and energy live in pinlin.modal_coordinates and pinlin.modal_energy.
    @functools.cached_property
    def decoupling(self) -> ModalCoordinates:
        """The modal form r' = Lam r + B_r u + f_r of the model (x = T r, r = L^H x with
        L^H R = I; Jordan or Schur blocks where A is defective or nearly so): a
        :class:`~pinlin.modal_coordinates.ModalCoordinates`, built on first access."""
        from .modal_coordinates import from_analysis

        return from_analysis(self)

    def to_modal(self, x: np.ndarray) -> np.ndarray:
        """Modal coordinates r = L^H x of states ``x`` ((n,) or (N, n)); see
        :attr:`decoupling` for their order (its blocks)."""
        return self.decoupling.to_modal(x)

    def from_modal(self, r: np.ndarray) -> np.ndarray:
        """States x = Re(R r) of modal coordinates ``r`` ((n,) or (N, n))."""
        return self.decoupling.from_modal(r)

    def energy(self, scene: Scene | None = None) -> ModalEnergy:
        """Kinetic and potential energy shares of each mode per coordinate (and the kinetic
        share per body when ``scene``, the model's :class:`~pinlin.Scene`, is given): a
        :class:`~pinlin.modal_energy.ModalEnergy`."""
        from .modal_energy import modal_energy

        return modal_energy(self, scene)

    def dominant(self, index: int, threshold: float = 0.5, limit: int = 3) -> list[str]:
        """Names of the coordinates whose |shape| entry is at least ``threshold`` in mode
        ``index``, largest first."""
        mag = np.abs(self.shapes[:, index])
        order = np.argsort(-mag, kind="stable")
        return [self.coordinate_names[k] for k in order[:limit] if mag[k] >= threshold]

    def modes(self) -> list[int]:
        """Indices of one eigenvalue per mode: conjugate pairs and rigid pairs counted once."""
        keep: list[int] = []
        skip: set[int] = set()
        lam = self.eigenvalues
        for i in range(len(lam)):
            if i in skip:
                continue
            keep.append(i)
            if i + 1 < len(lam) and (
                # A rigid DoF of a mechanical model is a 2x2 Jordan block: two zero eigenvalues.
                (self.rigid[i] and self.rigid[i + 1] and self.model.has_second_order)
                or (abs(lam[i].imag) > self.rigid_tol
                    and abs(lam[i + 1] - lam[i].conjugate()) <= 1e-9 * max(1.0, abs(lam[i])))
            ):
                skip.add(i + 1)
        return keep

    @functools.cached_property
    def constraint(self) -> np.ndarray:
        """Mask of constraint modes of a dependent-coordinate model (penalty, canonical): the
        2m eigenvalues whose position vectors lie most in the range of Phi_q^T (m constraint
        rows), measured by |G v_q| / (|G| |v_q|); physical modes have |G v_q| = O(1/alpha)."""
        G = self.model.G
        out = np.zeros(len(self.eigenvalues), dtype=bool)
        if G is None or G.shape[0] == 0:
            return out
        rows = [k for k, s in enumerate(self.model.state_names) if s.startswith("q:")]
        vq = self.right_vectors[rows]
        ratio = np.linalg.norm(G @ vq, axis=0) / (
            np.linalg.norm(G, 2) * np.maximum(np.linalg.norm(vq, axis=0), np.finfo(float).tiny))
        out[np.argsort(-ratio, kind="stable")[:2 * G.shape[0]]] = True
        return out

    def kind(self, index: int) -> str:
        lam = self.eigenvalues[index]
        if self.constraint[index]:
            return "constraint"
        if self.rigid[index]:
            return "rigid"
        if lam.real > self.rigid_tol:
            return "unstable" if abs(lam.imag) <= self.rigid_tol else "unstable osc."
        if abs(lam.imag) > self.rigid_tol:
            return "oscillatory" if lam.real < -self.rigid_tol else "undamped"
        return "real"

    def table(self) -> str:
        """A readable table with one row per mode."""
        head = (f"{'#':>3}  {'eigenvalue [1/s]':>28}  {'wn [rad/s]':>11}  {'f [Hz]':>10}  "
                f"{'zeta':>8}  {'kind':<13}  dominant coordinates")
        count = len(self.eigenvalues)
        lines = [f"Modes of '{self.model.name}' ({self.method} eigensolver, "
                 f"{count} eigenvalue{'' if count == 1 else 's'}, rigid below "
                 f"{self.rigid_tol:.1e} rad/s)", head, "-" * len(head)]
        for n, i in enumerate(self.modes(), start=1):
            lam = self.eigenvalues[i]
            if self.rigid[i]:
                ev, wn, f, zeta = "0 (rigid)", "0", "0", "-"
            else:
                im = abs(lam.imag)
                # A real part within rounding of 0 (an undamped mode) prints as 0, zeta too.
                noise = abs(lam.real) <= self.rounding[i]
                re = "0" if noise else f"{lam.real:+.6g}"
                ev = f"{re} +- {im:.6g}j" if im > self.rigid_tol else re
                wn, f = f"{self.wn[i]:.6g}", f"{self.wn[i] / (2 * np.pi):.6g}"
                zeta = "0" if noise else f"{self.zeta[i]:.4g}"
            dom = ", ".join(self.dominant(i))
            lines.append(f"{n:>3}  {ev:>28}  {wn:>11}  {f:>10}  {zeta:>8}  {self.kind(i):<13}  "
                         f"{dom}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()


# --------------------------------------------------------------------------------------------
def modal(model: LinearModel, *, method: str = "auto", rigid_tol: float | None = None
          ) -> ModalAnalysis:
    """Eigenvalues, frequencies, damping ratios and mode shapes of ``model``.

    Args:
        model: A linear model (mechanical or linear graph).
        method: ``"auto"`` (symmetric when :func:`symmetric_applicable`, else general),
            ``"symmetric"`` or ``"general"``.
        rigid_tol: |lam| below which an eigenvalue is a rigid-body mode [rad/s]; default
            ``1e-6 * max(1, max |lam|)``.

    Raises:
        ArgumentError: ``model`` is not a LinearModel, ``method`` unknown, ``rigid_tol`` not a
            finite number >= 0.
        ModelError: a matrix of the model has a NaN, an inf or an entry beyond
            :data:`ENTRY_LIMIT` (the message names the matrix and the entry).
        PinlinError: ``method="symmetric"`` for a model it does not apply to.
    """
    if not isinstance(model, LinearModel):
        raise ArgumentError("model", f"expected a pinlin LinearModel, got "
                                     f"{type(model).__name__}")
    if model.dt:
        raise ArgumentError("model", f"model '{model.name}' is discrete (dt = {model.dt:g} s): "
                                     "its eigenvalues are z = exp(s dt), not frequencies; "
                                     "analyse the continuous model")
    if not isinstance(method, str) or method not in METHODS:
        raise ArgumentError("method", f"unknown eigensolver method {method!r:.60}; expected one "
                                      f"of {', '.join(METHODS)}")
    if rigid_tol is not None:
        _check_rigid_tol(rigid_tol)
    _check_entries(model)
    if model.E is not None and np.any(model.E):
        model = model.standard_form()
    use_symmetric = symmetric_applicable(model) if method == "auto" else method == "symmetric"
    if use_symmetric and not symmetric_applicable(model):
        raise PinlinError(f"model '{model.name}' has velocity terms or a non-symmetric stiffness: "
                          "the symmetric (K, M) eigensolver does not apply; use method='general'")
    if use_symmetric:
        return _symmetric(model, rigid_tol)
    return _general(model, rigid_tol)


def _coordinate_names(model: LinearModel, n: int) -> tuple[str, ...]:
    names = model.state_names[:n]
    return tuple(s[2:] if s.startswith("q:") else s for s in names)


def _normalize_shapes(shapes: np.ndarray) -> np.ndarray:
    out = np.array(shapes, dtype=complex)
    if out.size == 0:
        return out
    idx = np.argmax(np.abs(out), axis=0)
    pivot = out[idx, np.arange(out.shape[1])]
    pivot = np.where(np.abs(pivot) > 0, pivot, 1.0)
    return out / pivot


def _check_rigid_tol(rigid_tol: object) -> float:
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


def _check_entries(model: LinearModel) -> None:
    """Refuse a model whose matrices modal reads hold NaN, inf or |entry| > ENTRY_LIMIT."""
    for key in ("A", "E", "M", "C_damp", "K"):
        mat = getattr(model, key)
        if mat is None or mat.size == 0:
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


def _rigid_tol(magnitudes: np.ndarray, rigid_tol: float | None) -> float:
    if rigid_tol is not None:
        return _check_rigid_tol(rigid_tol)
    return RIGID_RTOL * max(1.0, float(magnitudes.max(initial=0.0)))


def _frequencies(lam: np.ndarray, rigid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    wn = np.where(rigid, 0.0, np.abs(lam))
    safe = np.where(rigid, 1.0, wn)
    zeta = np.where(rigid, np.nan, -lam.real / safe) + 0.0  # no "-0"
    return wn, zeta


def _symmetric(model: LinearModel, rigid_tol: float | None) -> ModalAnalysis:
    n = model.M.shape[0]
    K = 0.5 * (model.K + model.K.T)
    w2, phi = sla.eigh(K, model.M, driver="gvd")  # phi^T M phi = I (divide and conquer)
    tol = _rigid_tol(np.sqrt(np.abs(w2)), rigid_tol)
    order = np.argsort(np.abs(w2), kind="stable")
    w2, phi = w2[order], phi[:, order]
    rigid_mode = np.sqrt(np.abs(w2)) <= tol
    root = np.sqrt(np.abs(w2)).astype(complex)
    root = np.where(w2 >= 0, 1j * root, root)           # +i w (stable) or +sigma (unstable)
    root = np.where(rigid_mode, 0.0, root)
    lam = np.empty(2 * n, dtype=complex)
    lam[0::2], lam[1::2] = root, -root       # +i w first (oscillatory), +sigma first (unstable)
    rigid = np.repeat(rigid_mode, 2)
    wn, zeta = _frequencies(lam, rigid)
    shapes = _normalize_shapes(np.repeat(phi, 2, axis=1))
    return ModalAnalysis(lam, shapes, _coordinate_names(model, n), wn, zeta, rigid, tol,
                         "symmetric", model, _phi=phi)


def _symmetric_right(lam: np.ndarray, phi: np.ndarray, rigid: np.ndarray) -> np.ndarray:
    """r = [phi; lam phi]; a rigid pair is the Jordan chain [phi; 0], [0; phi]."""
    n = phi.shape[0]
    rigid_mode = rigid[0::2]
    root = lam[0::2]
    R = np.zeros((2 * n, 2 * n), dtype=complex)
    R[:n, 0::2] = phi
    R[n:, 0::2] = root * phi
    R[:n, 1::2] = np.where(rigid_mode, 0.0, 1.0) * phi
    R[n:, 1::2] = np.where(rigid_mode, 1.0, -root) * phi
    return R


def _symmetric_left(lam: np.ndarray, mphi: np.ndarray, rigid: np.ndarray) -> np.ndarray:
    n = mphi.shape[0]
    L = np.zeros((2 * n, 2 * n), dtype=complex)
    rigid_mode = rigid[0::2]
    for k in range(n):
        m = mphi[:, k]
        if rigid_mode[k]:
            L[:n, 2 * k] = m
            L[n:, 2 * k + 1] = m
            continue
        for col in (2 * k, 2 * k + 1):
            L[:n, col] = 0.5 * m
            L[n:, col] = np.conj(1.0 / (2.0 * lam[col])) * m
    return L


def _general(model: LinearModel, rigid_tol: float | None) -> ModalAnalysis:
    A = model.A
    lam, vl, vr = sla.eig(A, left=True, right=True)
    tol = _rigid_tol(np.abs(lam), rigid_tol)
    # Sort by |lam|, then Re, then +Im first: LAPACK returns conjugate pairs of a real matrix
    # as exact conjugates, so each pair ties on (|lam|, Re) and lands adjacent.
    order = np.lexsort((-lam.imag, lam.real, np.abs(lam)))
    lam, vl, vr = lam[order], vl[:, order], vr[:, order]
    dots = np.einsum("ij,ij->j", vl.conj(), vr)
    ok = np.abs(dots) > np.finfo(float).eps
    vl = np.where(ok, vl / np.where(ok, dots, 1.0).conj(), vl)
    rigid = np.abs(lam) <= tol
    lam = np.where(rigid, 0.0, lam)
    wn, zeta = _frequencies(lam, rigid)
    if model.has_second_order:
        rows = np.arange(model.n_states // 2)
    elif model.G is not None:  # canonical (p, q): shapes in q
        rows = np.array([k for k, s in enumerate(model.state_names) if s.startswith("q:")])
    else:
        rows = np.arange(model.n_states)
    shapes = _normalize_shapes(vr[rows])
    names = tuple(model.state_names[k] for k in rows)
    names = tuple(s[2:] if s.startswith("q:") else s for s in names)
    result = ModalAnalysis(lam, shapes, names, wn, zeta, rigid, tol, "general", model,
                           _right=vr, _left=vl)
    _warn_ill_conditioned_eigenvalues(result)
    return result


#: modal warns when rounding in A alone may move an eigenvalue by more than this (relative).
EIGENVALUE_RISK = 1e-6


def _warn_ill_conditioned_eigenvalues(result: ModalAnalysis) -> None:
    """AccuracyWarning when rounding in A (eps |A|) can move a non-rigid eigenvalue by more
    than EIGENVALUE_RISK of itself: kappa eps max|A| / |lam| > 1e-6."""
    import warnings

    from .conditioning import AccuracyWarning

    ok = ~result.rigid
    if not ok.any():
        return
    kappa = result.condition[ok]
    risk = kappa * np.finfo(float).eps * np.abs(result.model.A).max() / result.wn[ok]
    worst = int(np.argmax(risk))
    if risk[worst] > EIGENVALUE_RISK:
        lam = result.eigenvalues[ok][worst]
        warnings.warn(AccuracyWarning(
            f"model '{result.model.name}': eigenvalue {lam:.6g} has condition number "
            f"{kappa[worst]:.2e}; rounding in A alone may move it by {risk[worst]:.1e} "
            "(relative)", float(kappa[worst])), stacklevel=4)
