"""Modal analysis of a linear model: eigenvalues, natural frequencies, damping, mode shapes.

Two solvers:

- **symmetric**: when the model has no velocity-dependent terms (C_damp = 0) and a symmetric
  stiffness, the 2n eigenvalues of A are +-sqrt(-w2) for the n eigenvalues w2 of the symmetric
  definite pencil (K, M) (LAPACK ``dsygvd``, as ``scipy.linalg.eigh(K, M, driver="gvd")``,
  without vectors; the mass-normalized shapes phi are computed on first access by a second
  ``dsygvd`` with vectors, which costs about twice the first). Right and left eigenvectors
  of A follow in closed form: r = [phi; lam phi], l = [M phi / 2; M phi / (2 lam)*] with
  l^H r = 1. A zero w2 (rigid-body mode) is a 2x2 Jordan block of A: its pair of vectors is
  the chain [phi; 0], [0; phi] with left vectors [M phi; 0], [0; M phi].
- **general**: LAPACK ``dgeev`` of A (size 2n) with right vectors only, as
  ``scipy.linalg.eig(A)`` computes them (the same workspace, so the same digits). The left
  vectors, scaled to l^H r = 1, and the eigenvalue condition numbers
  kappa = |l| |r| / |l^H r| are computed when first read (:attr:`ModalAnalysis.left_vectors`,
  :attr:`ModalAnalysis.condition`; ``dgeev`` again with left vectors, which returns the same
  eigenvalues and right vectors bit for bit).

What costs what: ``modal`` runs one LAPACK eigensolver and O(n) to O(n^2) NumPy work; the mode
shapes (scaled), names, wn and zeta, the eigenvector matrices, the condition numbers, the
modal form (:attr:`ModalAnalysis.decoupling`) and the table are built on first access. On the
general path the accuracy warning needs condition numbers, which ``modal`` takes from the
inverse of the right vectors (:func:`_pair_conditions`: one LU inverse of the real
eigenvector matrix, ~1/20 of ``dgeev`` at n = 38; a bound from it clears the usual model at
once). The warning, when due, names the eigenvalue and its condition number from that inverse
(they agree with LAPACK's left vectors to ~cond(V) eps relative: 1e-11 on well conditioned
robots, a few 1e-4 at kappa ~ 1e14, where no digit beyond the first means anything). LAPACK's
left vectors (a second ``dgeev``) are computed only where V is exactly singular or the risk
lies within :func:`_risk_margin` of the threshold, or when
:attr:`ModalAnalysis.left_vectors` or :attr:`ModalAnalysis.condition` is read.

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
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import LinAlgError, lapack

from .conditioning import AccuracyWarning
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
_EPS = float(np.finfo(float).eps)
_TINY = float(np.finfo(float).tiny)


def symmetric_applicable(model: LinearModel) -> bool:
    """Whether the (K, M) path applies: second-order model, C_damp = 0, K symmetric, B, A
    consistent with them (no E)."""
    if model.M is None or model.E is not None:
        return False
    if model.info.get("velocity_terms", True) and np.count_nonzero(model.C_damp):
        return False
    K = model.K
    if K.size == 0:
        return True
    scale = max(float(np.abs(K).max()), _TINY)
    return float(np.abs(K - K.T).max()) <= SYMMETRY_RTOL * scale


@dataclass(frozen=True, eq=False)
class ModalAnalysis:
    """Eigen-analysis of a linear model; print it for a table.

    Attributes:
        eigenvalues: 2n eigenvalues, by increasing |lam|, conjugate pairs adjacent (+Im first).
        shapes: Mode shapes in the coordinates (position part of the right vectors), each scaled
            so that its largest entry is exactly 1 (built on first access).
        coordinate_names: Names of the shape entries.
        wn: Natural frequency |lam| [rad/s] (0 for rigid modes).
        zeta: Damping ratio -Re(lam)/|lam| (NaN for rigid modes).
        rigid: Mask of rigid-body (zero) eigenvalues.
        rigid_tol: Threshold used for ``rigid`` [rad/s].
        method: ``"symmetric"`` or ``"general"``.
        model: The analysed model.
    """

    eigenvalues: np.ndarray
    rigid: np.ndarray
    rigid_tol: float
    method: str
    model: LinearModel
    #: State rows of the shapes (the position coordinates).
    _rows: slice | np.ndarray
    #: Symmetric path: the permutation that orders dsygvd's ascending w2 by |w2| (None: the
    #: identity); the eigenvectors phi are computed on first access (:attr:`_phi`).
    _pencil_order: np.ndarray | None = None
    #: General path: dgeev's real right vectors (a complex pair u +- iv stored as columns u, v),
    #: the imaginary parts of its eigenvalues, and the dgeev index of each sorted eigenvalue.
    _vectors: np.ndarray | None = None
    _imag: np.ndarray | None = None
    _order: np.ndarray | None = None

    @classmethod
    def _made(cls, eigenvalues: np.ndarray, rigid: np.ndarray, rigid_tol: float, method: str,
              model: LinearModel, rows: slice | np.ndarray,
              pencil_order: np.ndarray | None = None, vectors: np.ndarray | None = None,
              imag: np.ndarray | None = None, order: np.ndarray | None = None) -> ModalAnalysis:
        """An analysis from this module's solvers, whose fields are consistent by construction:
        skips the frozen dataclass's per-field ``__setattr__`` (a microsecond or two, which
        counts against a 4 x 4 ``eig``)."""
        obj = object.__new__(cls)
        obj.__dict__.update(eigenvalues=eigenvalues, rigid=rigid, rigid_tol=rigid_tol,
                            method=method, model=model, _rows=rows,
                            _pencil_order=pencil_order,
                            _vectors=vectors, _imag=imag, _order=order)
        return obj

    # ----------------------------------------------------------------------------------------
    @functools.cached_property
    def _phi(self) -> np.ndarray | None:
        """Symmetric path: the (K, M) eigenvectors by increasing |w2|, phi^T M phi = I (None on
        the general path). ``modal`` solves the pencil for its eigenvalues only (``dsygvd``
        without vectors, about half the cost); the first access solves it again with vectors.
        Both return w2 in ascending order, so column k belongs to the k-th eigenvalue (the two
        runs' w2 agree to rounding, ~1e-15 relative), and the same reordering by |w2| applies."""
        if self.method != "symmetric":
            return None
        if not self.model.M.shape[0]:
            return np.zeros((0, 0))
        _, phi = _solve_pencil(self.model, vectors=True)
        return phi if self._pencil_order is None else phi[:, self._pencil_order]

    @functools.cached_property
    def _wn_zeta(self) -> tuple[np.ndarray, np.ndarray]:
        return _frequencies(self.eigenvalues, self.rigid)

    @functools.cached_property
    def wn(self) -> np.ndarray:
        """Natural frequencies |lam| [rad/s] (0 for rigid modes)."""
        return self._wn_zeta[0]

    @functools.cached_property
    def zeta(self) -> np.ndarray:
        """Damping ratios -Re(lam)/|lam| (NaN for rigid modes)."""
        return self._wn_zeta[1]

    @functools.cached_property
    def shapes(self) -> np.ndarray:
        """Mode shapes in the coordinates (position part of the right vectors), each scaled so
        that its largest entry is exactly 1."""
        if self.method == "symmetric":
            return _normalize_shapes(np.repeat(self._phi, 2, axis=1))
        return _normalize_shapes(self.right_vectors[self._rows])

    @functools.cached_property
    def coordinate_names(self) -> tuple[str, ...]:
        """Names of the shape entries (state names without their ``q:`` prefix)."""
        names = self.model.state_names
        rows = self._rows
        picked = names[rows] if isinstance(rows, slice) else [names[k] for k in rows]
        return tuple(s[2:] if s.startswith("q:") else s for s in picked)

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
        if self.method == "symmetric":
            return _symmetric_right(self.eigenvalues, self._phi, self.rigid)
        return _complex_vectors(self._vectors, self._imag)[:, self._order]

    @functools.cached_property
    def left_vectors(self) -> np.ndarray:
        """Left eigenvectors as columns, scaled so that l_i^H r_i = 1; built on first access
        (general path: LAPACK ``dgeev`` once more, with left vectors)."""
        if self.method == "symmetric":
            return _symmetric_left(self.eigenvalues, self.model.M @ self._phi, self.rigid)
        return _general_left(self.model.A, self._vectors, self._imag, self._order,
                             self.right_vectors)

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
                # A real part within rounding of 0 (an undamped mode) prints as 0, zeta too;
                # not where rounding may move the whole eigenvalue (a defective one): as computed.
                noise = abs(lam.real) <= self.rounding[i] < abs(lam)
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
        rigid_tol = _check_rigid_tol(rigid_tol)
    a2: float | None = _check_entries(model)
    if model.E is not None and np.count_nonzero(model.E):
        model, a2 = model.standard_form(), None
    if method == "general":
        return _general(model, rigid_tol, a2)
    if symmetric_applicable(model):
        return _symmetric(model, rigid_tol)
    if method == "symmetric":
        raise PinlinError(f"model '{model.name}' has velocity terms or a non-symmetric stiffness: "
                          "the symmetric (K, M) eigensolver does not apply; use method='general'")
    return _general(model, rigid_tol, a2)


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


def _check_entries(model: LinearModel) -> float:
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
        total = float(np.vdot(mat, mat))
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


def _rigid_tol(largest: float, rigid_tol: float | None) -> float:
    """The rigid-body threshold [rad/s]: ``rigid_tol`` (checked) or the default relative to
    the ``largest`` |lam| [rad/s]."""
    if rigid_tol is not None:
        return rigid_tol
    return RIGID_RTOL * max(1.0, largest)


def _frequencies(lam: np.ndarray, rigid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    wn = np.where(rigid, 0.0, np.abs(lam))
    safe = np.where(rigid, 1.0, wn)
    zeta = np.where(rigid, np.nan, -lam.real / safe) + 0.0  # no "-0"
    return wn, zeta


# --------------------------------------------------------------------------------------------
# Symmetric path
def _solve_pencil(model: LinearModel, vectors: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """w2 (ascending) and, with ``vectors``, phi (phi^T M phi = I) of the definite pencil
    (K_s, M), K_s = (K + K^T) / 2: LAPACK ``dsygvd``, the call and workspace of
    ``scipy.linalg.eigh(K_s, M, driver="gvd", eigvals_only=not vectors)``, without its
    checks (the entries are checked by ``modal``)."""
    K = model.K
    Ks = 0.5 * (K + K.T)    # symmetric bit for bit, so Ks.T is itself in Fortran order
    w2, phi, info = lapack.dsygvd(Ks.T, model.M, jobz="V" if vectors else "N", overwrite_a=1)
    if info:
        raise LinAlgError(_sygvd_failure(info, K.shape[0]))
    return w2, (phi if vectors else None)


def _symmetric(model: LinearModel, rigid_tol: float | None) -> ModalAnalysis:
    n = model.M.shape[0]
    if n == 0:
        return ModalAnalysis._made(np.zeros(0, dtype=complex), np.zeros(0, dtype=bool),
                                   _rigid_tol(0.0, rigid_tol), "symmetric", model, slice(0, 0))
    w2, _ = _solve_pencil(model, vectors=False)
    mag = np.sqrt(np.abs(w2))
    tol = _rigid_tol(float(max(mag[0], mag[-1])), rigid_tol)  # w2 ascending: |w2| peaks at an end
    order = None
    if not w2[0] >= 0.0:      # negative w2 (unstable or rounding): order by |w2|
        order = np.argsort(np.abs(w2), kind="stable")
        w2, mag = w2[order], mag[order]
        root = np.where(w2 >= 0, 1j * mag, mag)  # +i w (stable) or +sigma (unstable)
    else:                           # ascending and >= 0: already ordered by |w2|
        root = 1j * mag
    rigid_mode = mag <= tol
    if np.count_nonzero(rigid_mode):
        root[rigid_mode] = 0.0
    lam = np.empty(2 * n, dtype=complex)
    lam[0::2], lam[1::2] = root, -root       # +i w first (oscillatory), +sigma first (unstable)
    return ModalAnalysis._made(lam, rigid_mode.repeat(2), tol, "symmetric", model,
                               slice(0, n), pencil_order=order)


def _sygvd_failure(info: int, n: int) -> str:
    """scipy.linalg.eigh's message for a failed dsygvd."""
    if info > n:
        return (f"The leading minor of order {info - n} of B is not positive definite. The "
                "factorization of B could not be completed and no eigenvalues or eigenvectors "
                "were computed.")
    if info < 0:
        return f"Illegal value in argument {-info} of internal dsygvd"
    return ("The algorithm failed to compute an eigenvalue while working on the submatrix "
            f"lying in rows and columns {info}/{n + 1} through mod({info},{n + 1}).")


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
    """l = [M phi / 2; M phi / (2 lam)*]; a rigid pair [M phi; 0], [0; M phi]."""
    n = mphi.shape[0]
    L = np.zeros((2 * n, 2 * n), dtype=complex)
    rigid_mode = rigid[0::2]
    moving = ~rigid_mode
    cols = np.flatnonzero(np.repeat(moving, 2))      # both columns of each moving pair
    m = np.repeat(mphi[:, moving], 2, axis=1)
    L[:n, cols] = 0.5 * m
    L[n:, cols] = np.conj(1.0 / (2.0 * lam[cols])) * m
    still = np.flatnonzero(rigid_mode)
    L[:n, 2 * still] = mphi[:, still]
    L[n:, 2 * still + 1] = mphi[:, still]
    return L


# --------------------------------------------------------------------------------------------
# General path
@functools.lru_cache(maxsize=256)
def _geev_lwork(n: int, left: bool) -> int:
    """dgeev's optimal workspace, as scipy.linalg.eig asks for it (a smaller one changes the
    blocking and so the last digits)."""
    work, info = lapack.dgeev_lwork(n, compute_vl=int(left))
    if info:
        raise LinAlgError(f"dgeev workspace query failed (LAPACK info={info})")
    return int(work)


def _geev(A: np.ndarray, left: bool) -> tuple[np.ndarray, ...]:
    """wr, wi, vl, vr of LAPACK dgeev (vl empty unless ``left``), as scipy.linalg.eig calls it."""
    wr, wi, vl, vr, info = lapack.dgeev(A, compute_vl=int(left),
                                        lwork=_geev_lwork(A.shape[0], left))
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of internal eig algorithm (geev)")
    if info > 0:
        raise LinAlgError(f"eig algorithm (geev) did not converge (only eigenvalues with order "
                          f">= {info} have converged)")
    return wr, wi, vl, vr


def _complex_vectors(v: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """dgeev's eigenvectors as columns (complex when a pair is): a conjugate pair's columns
    u, v become u + iv, u - iv (as scipy.linalg.eig returns them, real when all are)."""
    if not wi.any():
        return v
    out = v.astype(complex)
    first = wi > 0
    first[:-1] |= wi[1:] < 0
    idx = np.flatnonzero(first)
    out.imag[:, idx] = v[:, idx + 1]
    out[:, idx + 1] = out[:, idx].conj()
    return out


def _general(model: LinearModel, rigid_tol: float | None, a2: float | None = None
             ) -> ModalAnalysis:
    """The general path; ``a2`` is |A|_F^2 when the caller has it (inf or None: not known)."""
    A = model.A
    if A.shape[0] == 0:
        return _empty(model, rigid_tol)
    wr, wi, _, vr = _geev(A, left=False)
    lam = wr + 1j * wi
    magnitudes = np.abs(lam)                # in dgeev's order
    # Sort by |lam|, then Re, then +Im first: LAPACK returns conjugate pairs of a real matrix
    # as exact conjugates, so each pair ties on (|lam|, Re) and lands adjacent.
    order = _pairs_adjacent(np.lexsort((-wi, wr, magnitudes)), wi)
    tol = _rigid_tol(float(magnitudes[order[-1]]), rigid_tol)
    lam = lam[order]
    rigid = magnitudes[order] <= tol        # a leading run: sorted by |lam|
    n_rigid = int(np.count_nonzero(rigid))
    if n_rigid:
        lam[:n_rigid] = 0.0
    if model.M is not None:
        rows: slice | np.ndarray = slice(0, A.shape[0] // 2)
    elif model.G is not None:  # canonical (p, q): shapes in q
        rows = np.array([k for k, s in enumerate(model.state_names) if s.startswith("q:")],
                        dtype=int)
    else:
        rows = slice(None)
    result = ModalAnalysis._made(lam, rigid, tol, "general", model, rows, vectors=vr, imag=wi,
                                 order=order)
    if n_rigid < len(order):                # no warning about rigid modes
        _warn_if_at_risk(result, vr, wi, magnitudes, n_rigid, a2)
    return result


def _pairs_adjacent(order: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """``order`` with each conjugate pair adjacent, +Im first. dgeev stores a pair in columns
    p (Im > 0) and p + 1; sorting by (|lam|, Re, -Im) keeps them adjacent unless another pair
    is equal to the bit (a repeated eigenvalue, e.g. symmetric constraint modes), which puts
    both +Im first: then each +Im is followed by its own partner."""
    pos = np.flatnonzero(wi[order] > 0)
    if np.array_equal(order[np.minimum(pos + 1, len(order) - 1)], order[pos] + 1):
        return order
    out: list[int] = []
    for p in order.tolist():
        if wi[p] > 0:
            out += [p, p + 1]
        elif wi[p] == 0:
            out.append(p)
    return np.array(out, dtype=order.dtype)


def _empty(model: LinearModel, rigid_tol: float | None) -> ModalAnalysis:
    """The analysis of a model without states."""
    empty = np.zeros((0, 0))
    return ModalAnalysis(np.zeros(0, dtype=complex), np.zeros(0, dtype=bool),
                         _rigid_tol(0.0, rigid_tol), "general", model, slice(None),
                         _vectors=empty, _imag=np.zeros(0), _order=np.zeros(0, dtype=int))


def _general_left(A: np.ndarray, vr: np.ndarray, wi: np.ndarray, order: np.ndarray,
                  right: np.ndarray) -> np.ndarray:
    """Left eigenvectors matching ``right`` (sorted by ``order``), scaled to l^H r = 1.

    dgeev with left vectors repeats the reduction of the right-only call, so its right vectors
    (and eigenvalues) come out the same bit for bit; should they not, the rows of R^-1 are
    used (left vectors biorthogonal to R by construction)."""
    if A.shape[0] == 0:
        return np.zeros((0, 0))
    _, wi2, vl, vr2 = _geev(A, left=True)
    if not (np.array_equal(vr2, vr) and np.array_equal(wi2, wi)):
        return np.linalg.solve(right, np.eye(len(order))).conj().T
    vl = _complex_vectors(vl, wi)[:, order]
    dots = np.einsum("ij,ij->j", vl.conj(), right)
    ok = np.abs(dots) > np.finfo(float).eps
    return np.where(ok, vl / np.where(ok, dots, 1.0).conj(), vl)


#: modal warns when rounding in A alone may move an eigenvalue by more than this (relative).
EIGENVALUE_RISK = 1e-6
#: Factor below EIGENVALUE_RISK under which the cheap bound (:func:`_warn_if_at_risk`)
#: settles that no warning is due (it is within a factor 2 N of kappa eps max|A| / |lam|).
RISK_MARGIN = 4.0
#: Least factor by which the risk from V^-1 must clear the threshold to be trusted over
#: LAPACK's (:func:`_risk_margin`); within it, LAPACK's left vectors decide.
RISK_MARGIN_MIN = 1.01


def _inverse(vr: np.ndarray) -> np.ndarray | None:
    """V^-1 by LU (LAPACK ``dgetrf``, ``dgetri``), or None when V is exactly singular."""
    lu, piv, info = lapack.dgetrf(vr)
    if info:
        return None
    inv, info = lapack.dgetri(lu, piv, overwrite_lu=1)
    return None if info else inv


def _pair_conditions(k2: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """Eigenvalue condition numbers kappa (dgeev's order) from the squared row norms ``k2`` of
    V^-1, V being dgeev's real right vectors (``wi``: imaginary parts of the eigenvalues).

    For a diagonalizable A = R Lam R^-1, the left vector scaled to l_i^H r_i = 1 is row i of
    R^-1 (conjugated), so kappa_i = |l_i| |r_i| / |l_i^H r_i| = |e_i^T R^-1| |r_i|, and dgeev
    scales every r_i to |r_i| = 1. It stores R as the real V (a pair u +- iv as columns u, v,
    |u|^2 + |v|^2 = 1): R = V P with P = [[1, 1], [i, -i]] on each pair, so the pair's rows
    of R^-1 = P^-1 V^-1 are (w_u -+ i w_v) / 2, with w the rows of V^-1:
    kappa^2 = (|w_u|^2 + |w_v|^2) / 4 for both, and a real eigenvalue has kappa = |w|. These
    agree with the kappa of LAPACK's left vectors to ~cond(V) eps relative (1e-11 on pinlin's
    robots; 2e-4 where kappa ~ 1e14, whose digits beyond the first are rounding either way).
    The rows of a (nearly) defective block, such as a floating base's rigid modes (2x2
    Jordan blocks), overflow to inf; the others stay accurate."""
    kappa = np.sqrt(k2)
    if np.count_nonzero(wi):
        u = np.flatnonzero(wi > 0)          # a pair's columns are u (wi > 0), then v
        pair = np.sqrt(0.25 * (k2[u] + k2[u + 1]))
        kappa[u] = pair
        kappa[u + 1] = pair
    return kappa


def _warn_if_at_risk(result: ModalAnalysis, vr: np.ndarray, wi: np.ndarray,
                     magnitudes: np.ndarray, n_rigid: int, a2: float | None = None) -> None:
    """AccuracyWarning when rounding in A (eps max|A|) can move a non-rigid eigenvalue by
    more than EIGENVALUE_RISK of itself: kappa eps max|A| / |lam| > 1e-6 (``vr``, ``wi``,
    ``magnitudes`` |lam|: in dgeev's order; the first ``n_rigid`` sorted eigenvalues are rigid;
    ``a2``: |A|_F^2 if known).

    One LU inverse of the right vectors V settles it (:func:`_pair_conditions`): first a bound
    (max over the columns of |row of V^-1| / |lam|, >= kappa / |lam|, times eps |A|_F >=
    eps max|A|), which clears the usual model; else kappa itself. Only where V is singular or
    kappa lies within :func:`_risk_margin` of the threshold are LAPACK's left vectors computed
    (:attr:`ModalAnalysis.condition`, a second ``dgeev``), so that a borderline case is settled
    exactly as the condition numbers a user reads would settle it."""
    A, order = result.model.A, result._order
    inv = _inverse(vr)
    if inv is not None:
        # Squared row norms (einsum: no overflow warning where V^-1 is huge, inf then).
        k2 = np.einsum("ij,ij->i", inv, inv)
        moving = order[n_rigid:]                        # sorted, non-rigid, dgeev's indices
        k2_moving, lam_moving = (k2[moving], magnitudes[moving]) if n_rigid else (k2, magnitudes)
        worst_column = float((np.sqrt(k2_moving) / lam_moving).max())
        frobenius = math.sqrt(a2 if a2 is not None and a2 < math.inf else np.vdot(A, A))
        if worst_column * _EPS * frobenius <= EIGENVALUE_RISK / RISK_MARGIN:   # False for NaN
            return
        scale = _EPS * float(np.abs(A).max())
        kappa = _pair_conditions(k2, wi)[moving]
        risk = kappa * scale / magnitudes[moving]
        worst = int(np.argmax(risk))        # a NaN wins argmax, and fails both tests below
        ratio = float(risk[worst]) / EIGENVALUE_RISK
        margin = _risk_margin(k2_moving, k2.size)
        if ratio * margin < 1.0:
            return
        if margin < ratio < math.inf:
            _warn(result, n_rigid + worst, float(kappa[worst]), float(risk[worst]))
            return
    scale = _EPS * float(np.abs(A).max())
    ok = ~result.rigid
    kappa = result.condition[ok]
    risk = kappa * scale / result.wn[ok]
    worst = int(np.argmax(risk))
    if risk[worst] > EIGENVALUE_RISK:
        _warn(result, int(np.flatnonzero(ok)[worst]), float(kappa[worst]), float(risk[worst]))


def _risk_margin(k2: np.ndarray, n: int) -> float:
    """How far (a factor > 1) the risk from V^-1 must lie from the threshold to be trusted
    over LAPACK's: 1 + 100 n c eps with c = sqrt(n sum k2) (``k2``: squared norms of the rows
    of V^-1 that belong to non-rigid eigenvalues; n: size of A), the relative error of either
    kappa bounded generously (those rows are accurate to ~c eps relative, c being cond_F(V)
    restricted to them; dgeev's columns have unit norm). 1.01 for pinlin's robots at rest;
    ~150 where kappa ~ 1e14 (the floating bases at a moving state: those warn far above it).
    NaN or inf rows give inf: LAPACK decides."""
    cond = math.sqrt(n * float(k2.sum()))
    return max(RISK_MARGIN_MIN, 1.0 + 100.0 * n * cond * _EPS)


def _warn(result: ModalAnalysis, index: int, kappa: float, risk: float) -> None:
    """The AccuracyWarning for eigenvalue ``index`` (sorted) of condition number ``kappa``
    and relative risk ``risk``."""
    lam = result.eigenvalues[index]
    warnings.warn(AccuracyWarning(
        f"model '{result.model.name}': eigenvalue {lam:.6g} has condition number "
        f"{kappa:.2e}; rounding in A alone may move it by {risk:.1e} (relative)", kappa),
        stacklevel=5)  # _warn, _warn_if_at_risk, _general, modal, the caller
