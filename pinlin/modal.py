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
inverse of the right vectors (:func:`pinlin.eigensolvers.pair_conditions`: one LU inverse of
the real eigenvector matrix, ~1/20 of ``dgeev`` at n = 38; a bound from it clears the usual model at
once). The warning, when due, names the eigenvalue and its condition number from that inverse
(they agree with LAPACK's left vectors to ~cond(V) eps relative: 1e-11 on well conditioned
robots, a few 1e-4 at kappa ~ 1e14, where no digit beyond the first means anything). LAPACK's
left vectors (a second ``dgeev``) are computed only where V is exactly singular or the risk
lies within :func:`pinlin.eigensolvers.risk_margin` of the threshold, when
:attr:`ModalAnalysis.left_vectors`, :attr:`ModalAnalysis.condition` or
:attr:`ModalAnalysis.rounding` is read (the table reads it), or where a real or imaginary part
lies between 10 n eps |A|_F and rigid_tol when :meth:`ModalAnalysis.kind`,
:meth:`ModalAnalysis.oscillates` or :attr:`ModalAnalysis.unstable` decides whether it is more
than rounding (:func:`pinlin.modal_table.resolved`).

Conventions: wn = |lam| [rad/s], zeta = -Re(lam) / |lam|. Eigenvalues with |lam| <= rigid_tol are
rigid-body (zero) modes: wn = 0 and zeta = NaN by definition (never computed as 0/0), labelled
"rigid" in the table. The default rigid_tol is 1e-6 * max(1, largest |lam|) [rad/s], well above
the O(sqrt(eps) |lam|max) spread that rounding gives a zero eigenvalue of a Jordan block.

The printed table and how it labels modes: :mod:`pinlin.modal_table`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.linalg import LinAlgError

from . import eigensolvers as es
from . import modal_table
from .exceptions import ArgumentError, ModelError, PinlinError
from .fields import show
from .linear_model import LinearModel
from .modal_input import check_entries, check_rigid_tol
from .modal_table import RIGID_RTOL

if TYPE_CHECKING:
    from .modal_coordinates import ModalCoordinates
    from .modal_energy import ModalEnergy
    from .scene import Scene

METHODS = ("auto", "symmetric", "general")
SYMMETRY_RTOL = 1e-8
_EPS = float(np.finfo(float).eps)
_TINY = float(np.finfo(float).tiny)


def symmetric_applicable(model: LinearModel) -> bool:
    """Whether the (K, M) path applies: second-order model, C_damp = 0, K symmetric, B, A
    consistent with them (no E)."""
    if model.M is None or model.E is not None:
        return False
    if np.count_nonzero(model.C_damp):   # (not model.info: a hand-built model's says anything)
        return False
    for mat in (model.K, model.M):     # dsygvd reads one triangle of each
        # max |mat - mat^T| in one reduction: the difference is antisymmetric, exactly (a - b
        # and b - a round alike), so its largest entry is its largest magnitude.
        skew = float((mat - mat.T).max(initial=0.0))
        if skew > 0.0 and skew > SYMMETRY_RTOL * max(float(np.abs(mat).max()), _TINY):
            return False
    return True


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
        _, phi = es.solve_pencil(self.model, vectors=True)
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
        return tuple(s.removeprefix("q:") for s in picked)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Natural frequencies wn / 2 pi [Hz]."""
        return self.wn / (2.0 * np.pi)

    @property
    def unstable(self) -> np.ndarray:
        """Mask of exponentially growing modes: Re(lam) > 0 by more than rounding (above
        rigid_tol, or above 10 n times :attr:`rounding`: a slow unstable mode beside much
        faster ones; :meth:`kind` says "unstable" for the same eigenvalues;
        :func:`pinlin.modal_table.resolved`)."""
        return np.array([r > 0.0 and modal_table.resolved(self, i, r)
                         for i, r in enumerate(self.eigenvalues.real.tolist())], dtype=bool)

    @property
    def is_stable(self) -> bool:
        """No eigenvalue with a positive real part beyond the tolerance."""
        return not bool(np.any(self.unstable))

    @functools.cached_property
    def right_vectors(self) -> np.ndarray:
        """Right eigenvectors of A as columns (Jordan chains for rigid modes of the symmetric
        path); built on first access."""
        if self.method == "symmetric":
            return es.symmetric_right(self.eigenvalues, self._phi, self.rigid)
        return es.complex_vectors(self._vectors, self._imag)[:, self._order]

    @functools.cached_property
    def left_vectors(self) -> np.ndarray:
        """Left eigenvectors as columns, scaled so that l_i^H r_i = 1; built on first access
        (general path: LAPACK ``dgeev`` once more, with left vectors)."""
        if self.method == "symmetric":
            return es.symmetric_left(self.eigenvalues, self.model.M @ self._phi, self.rigid)
        return es.general_left(self.model.A, self._vectors, self._imag, self._order,
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
    def rounding_floor(self) -> float:
        """eps |A|_F [1/s]: the least :attr:`rounding` level any eigenvalue has (kappa >= 1),
        without its condition numbers; 0 for the symmetric solver."""
        if self.method == "symmetric":
            return 0.0
        return float(np.finfo(float).eps * np.linalg.norm(self.model.A))

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
        ``index``, largest first.

        Raises:
            ArgumentError: ``index`` is not an eigenvalue index 0 <= index < n; ``threshold``
                not in (0, 1] (shapes are scaled to a largest entry of 1); ``limit`` not an
                integer >= 1.
        """
        if isinstance(threshold, bool) or not isinstance(threshold, int | float | np.floating) \
                or not 0.0 < threshold <= 1.0:
            raise ArgumentError("threshold", f"expected a number in (0, 1] (the shapes' "
                                             f"largest entry is 1), got {threshold!r}")
        if isinstance(limit, bool) or not isinstance(limit, int | np.integer) or limit < 1:
            raise ArgumentError("limit", f"expected an integer >= 1, got {limit!r}")
        return modal_table.dominant(self, self._index(index), threshold, limit)

    def _index(self, index: object) -> int:
        """``index`` as an eigenvalue index, or an ArgumentError (no negative wrap-around)."""
        n = len(self.eigenvalues)
        if isinstance(index, bool) or not isinstance(index, int | np.integer) \
                or not 0 <= index < n:
            raise ArgumentError("index", f"expected an eigenvalue index from 0 to {n - 1}, got "
                                         f"{show(index)}" if n else
                                f"model '{self.model.name}' has no eigenvalue, got {show(index)}")
        return int(index)

    def modes(self) -> list[int]:
        """Indices of one eigenvalue per mode: conjugate pairs and rigid pairs counted once."""
        return modal_table.modes(self)

    @functools.cached_property
    def constraint(self) -> np.ndarray:
        """Mask of constraint modes of a dependent-coordinate model (penalty, canonical): the
        2m eigenvalues whose position vectors lie most in the range of Phi_q^T (m constraint
        rows), measured by |G v_q| / (|G| |v_q|); physical modes have |G v_q| = O(1/alpha)."""
        return modal_table.constraint(self)

    def oscillates(self, index: int) -> bool:
        """Whether eigenvalue ``index`` has an imaginary part: above ``rigid_tol`` or above 10 n
        times its rounding level (:attr:`rounding`; a slow oscillation beside much faster
        modes, whose rigid_tol is larger than its imaginary part;
        :func:`pinlin.modal_table.resolved`). An eigenvalue that does not is real: its row
        shows no +-j and its kind is "real", "unstable" or "rigid".

        Raises:
            ArgumentError: ``index`` is not an eigenvalue index 0 <= index < n.
        """
        return modal_table.oscillates(self, self._index(index))

    def kind(self, index: int) -> str:
        """What eigenvalue ``index`` is: "rigid", "constraint", "oscillatory", "undamped",
        "real", "unstable" or "unstable osc.".

        Raises:
            ArgumentError: ``index`` is not an eigenvalue index 0 <= index < n.
        """
        return modal_table.kind(self, self._index(index))

    def table(self) -> str:
        """A readable table with one row per mode."""
        return modal_table.table(self)

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
            :data:`pinlin.modal_input.ENTRY_LIMIT` (the message names the matrix and the entry).
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
        rigid_tol = check_rigid_tol(rigid_tol)
    a2: float | None = check_entries(model)
    if model.E is not None and np.count_nonzero(model.E):
        model, a2 = model.standard_form(), None
    if method == "general":
        return _general(model, rigid_tol, a2)
    if symmetric_applicable(model):
        try:
            return _symmetric(model, rigid_tol)
        except LinAlgError as exc:   # M not positive definite (a hand-built model), or no
            if method == "symmetric":   # convergence: the general solver takes A as it is
                raise ModelError(f"model '{model.name}': the symmetric (K, M) eigensolver "
                                 f"failed: {exc}; use method='general'") from None
            return _general(model, rigid_tol, a2)
    if method == "symmetric":
        raise PinlinError(f"model '{model.name}' has velocity terms or a non-symmetric stiffness "
                          "or mass matrix: the symmetric (K, M) eigensolver does not apply; use "
                          "method='general'")
    return _general(model, rigid_tol, a2)


def _normalize_shapes(shapes: np.ndarray) -> np.ndarray:
    out = np.array(shapes, dtype=complex)
    if out.size == 0:
        return out
    idx = np.argmax(np.abs(out), axis=0)
    pivot = out[idx, np.arange(out.shape[1])]
    pivot = np.where(np.abs(pivot) > 0, pivot, 1.0)
    return out / pivot


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


def _symmetric(model: LinearModel, rigid_tol: float | None) -> ModalAnalysis:
    n = model.M.shape[0]
    if n == 0:
        return ModalAnalysis._made(np.zeros(0, dtype=complex), np.zeros(0, dtype=bool),
                                   _rigid_tol(0.0, rigid_tol), "symmetric", model, slice(0, 0))
    w2, _ = es.solve_pencil(model, vectors=False)
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


# --------------------------------------------------------------------------------------------
# General path


def _general(model: LinearModel, rigid_tol: float | None, a2: float | None = None
             ) -> ModalAnalysis:
    """The general path; ``a2`` is |A|_F^2 when the caller has it (inf or None: not known)."""
    A = model.A
    if A.shape[0] == 0:
        return _empty(model, rigid_tol)
    wr, wi, _, vr = es.geev(A, left=False, a2=a2)
    lam = np.empty(wr.size, dtype=complex)
    lam.real, lam.imag = wr, wi
    magnitudes = np.abs(lam)                # in dgeev's order
    # Sort by |lam|, then Re, then +Im first: LAPACK returns conjugate pairs of a real matrix
    # as exact conjugates, so each pair ties on (|lam|, Re) and lands adjacent.
    order = _pairs_adjacent(np.lexsort((-wi, wr, magnitudes)), wi)
    largest = float(magnitudes[order[-1]])
    if rigid_tol is None and model.G is not None and model.G.shape[0] and len(order) > \
            2 * model.G.shape[0]:
        # Dependent coordinates: the constraint modes (Omega, mu) can be decades above the
        # physical ones; the rigid threshold follows the physical modes, so that they are
        # never called rigid, and their accuracy is checked below.
        physical = ~modal_table.constraint_mask(model, es.complex_vectors(vr, wi))
        largest = float(magnitudes[physical].max())
    tol = _rigid_tol(largest, rigid_tol)
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
        es.warn_if_at_risk(result, vr, wi, magnitudes, n_rigid, a2)
    return result


def _pairs_adjacent(order: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """``order`` with each conjugate pair adjacent, +Im first. dgeev stores a pair in columns
    p (Im > 0) and p + 1; sorting by (|lam|, Re, -Im) keeps them adjacent unless another pair
    is equal to the bit (a repeated eigenvalue, e.g. symmetric constraint modes), which puts
    both +Im first: then each +Im is followed by its own partner."""
    o, w = order.tolist(), wi.tolist()     # a few dozen numbers: Python beats numpy calls
    n = len(o)
    if all(not w[p] > 0.0 or (k + 1 < n and o[k + 1] == p + 1) for k, p in enumerate(o)):
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
