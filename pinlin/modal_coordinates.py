"""Modal coordinates: the equations x' = f0 + A x + B u split into independent modes.

García de Jalón & Bayo (eqs. 9.62-9.66) uncouple the linearized equations with the transposed
right eigenvectors v_i^T. That holds for a symmetric problem only: for a non-symmetric A (damping,
gyroscopic terms, constraint penalties) v_i^T A v_j != 0 for i != j. What uncouples them are the
*left* eigenvectors l_i (l_i^H A = lam_i l_i^H) scaled so that l_i^H r_j = delta_ij (L^H R = I).
With x = R r (eq. 9.64 with the right vectors)::

    L^H R r' = L^H A R r + L^H B u + L^H f0
          r_i' = lam_i r_i + (L^H B u)_i + (L^H f0)_i        (one first-order equation per mode)

(eq. 9.66 as printed also has u(t) where the forcing U(t) belongs). For a real A the modes come
in conjugate pairs and x = R r is real; :meth:`ModalCoordinates.from_modal` returns its real part.

A matrix that is not diagonalizable has no such R: a rigid-body degree of freedom of a mechanical
model is a 2x2 Jordan block at zero (A r1 = 0, A r2 = r1), and nearly repeated eigenvalues can
make the computed R nearly singular. Such cases get a block form instead, x = T r with T^-1 A T
block diagonal and each block an independent group of equations r_b' = Lam_b r_b + ...:

- ``"diagonal"``: every block 1x1, T = R, T^-1 = L^H (the corrected eqs. 9.62-9.66).
- ``"jordan"``: the symmetric (K, M) eigensolver's rigid pairs kept as 2x2 blocks on their
  Jordan chains [phi; 0], [0; phi] (block [[0, 1], [-w2, 0]] with w2 = phi^T K phi, zero for a
  true rigid mode), all other modes 1x1.
- ``"schur"``: when the eigenvector matrix is ill-conditioned (condition number of R with unit
  columns beyond :data:`COND_LIMIT`): the complex Schur form A = Z T Z^H, reordered so that
  close eigenvalues sit together (LAPACK ``ztrexc``) and block-diagonalized by Sylvester
  equations (LAPACK ``ztrsyl``; Bavely & Stewart, 1979): a block grows until the coupling X that
  removes it from the rest stays below :data:`BLOCK_BOUND`, so T = Z Y has a bounded condition
  number. Isolated eigenvalues end up in 1x1 blocks (modes); a defective cluster in one block.

Every block is solved exactly (a scalar exponential for 1x1 blocks, a matrix exponential of the
small block otherwise): see :mod:`pinlin.response`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla
from scipy.linalg import lapack

from .arrays import real_array
from .exceptions import ArgumentError, ShapeError

if TYPE_CHECKING:
    from .modal import ModalAnalysis

#: Largest condition number of the right eigenvector matrix R (unit columns), times the
#: largest eigenvalue condition number |l_i| |r_i| of a 1x1 block, accepted for the diagonal
#: form. r = R^-1 x by an LU solve and x = R r carry a relative error of about kappa(R) eps
#: each (backward-stable solve and product), and each computed eigenvalue one of about
#: |l_i| |r_i| eps |A|, which the exponentials turn into errors of the modes that the
#: transformation then amplifies by kappa(R): near a nearly repeated pair (a mode damped to
#: within 6e-10 of critical) both are ~1e5 and the response lost 8 digits (4.7e-8 against
#: expm) where kappa(R) alone, 9.96e4, passed. At 1e5 the product keeps the error of the
#: transformation at 2.2e-11, five times below the 1e-10 at which pinlin promises the modal
#: response equals the matrix exponential's; the eigenvalues' own error, s eps |A| each,
#: grows along the response like |A| t, which this limit does not bound (the tests' models
#: and horizons measure 2e-15 to 7e-14 against expm). A defective pair has kappa ~
#: 1/sqrt(eps) ~ 7e7 (its two computed eigenvectors differ by O(sqrt(eps))), far beyond:
#: it always takes the Schur path.
COND_LIMIT = 1e5
#: Largest |entry| of a Sylvester solution X accepted to split a Schur block from the rest.
#: T = Z Y with unitary Z and Y unit block upper triangular: each split adds at most |X| to
#: the growth of |Y| and |Y^-1|, so with entries <= 1e2 (|X|_2 <= 1e2 n) the transformation
#: stays within a few decades of COND_LIMIT for the model sizes pinlin handles (n <= ~200).
#: Eigenvalues closer than ~|A| / 1e2 with strong coupling share a block.
BLOCK_BOUND = 1e2
#: Largest off-block residual |T^-1 A T - Lam| / |A| (max-entry norms) accepted for the
#: closed-form vectors of the symmetric eigensolver. Rounding in phi (eigh) and the products
#: gives ~ n eps kappa ~ 1e-13 for pinlin's models; a stiffness symmetric only to
#: SYMMETRY_RTOL (1e-8, which the symmetric path allows) leaves up to 1e-8: beyond 1e-11 the
#: vectors of the general eigensolver (exact for the unsymmetrized A) are used instead.
RESIDUAL_LIMIT = 1e-11

KINDS = ("diagonal", "jordan", "schur")


@dataclass(frozen=True, eq=False)
class ModalCoordinates:
    """The modal (block-diagonal) form of x' = f0 + A x + B u, y = C x + D u.

    With x = T r (``right``) and r = T^-1 x (``inverse``, = L^H in the diagonal case)::

        r' = Lam r + B_r u + f_r,    y = C_r r + D u

    where Lam = T^-1 A T is block diagonal (``blocks``), B_r = T^-1 B, f_r = T^-1 f0 and
    C_r = C T. In the diagonal form each r_i obeys r_i' = lam_i r_i + (B_r u)_i + (f_r)_i.

    Attributes:
        right: T (n x n, complex): columns are the right eigenvectors (diagonal form) or bases
            of the blocks' invariant subspaces.
        inverse: T^-1 (n x n, complex): rows are the left eigenvectors l_i^H with L^H R = I.
        matrix: Lam (n x n, complex), T^-1 A T with the entries outside the blocks set to 0
            [1/s].
        blocks: (start, stop) index range of each block, in order; 1x1 blocks are modes.
        kind: ``"diagonal"``, ``"jordan"`` or ``"schur"`` (see the module docstring).
        condition: 2-norm condition number of T with unit columns.
        residual: max |T^-1 A T - Lam| / max |A|: the coupling left between blocks (rounding).
        input_matrix: B_r = T^-1 B (n x m).
        drift: f_r = T^-1 f0 (n), zeros at an equilibrium.
        output_matrix: C_r = C T (p x n).
        note: What was done and why (the fallback's reason when kind != "diagonal").
    """

    right: np.ndarray
    inverse: np.ndarray
    matrix: np.ndarray
    blocks: tuple[tuple[int, int], ...]
    kind: str
    condition: float
    residual: float
    input_matrix: np.ndarray
    drift: np.ndarray
    output_matrix: np.ndarray
    note: str

    @property
    def left(self) -> np.ndarray:
        """L = (T^-1)^H: left eigenvectors as columns, L^H R = I."""
        return self.inverse.conj().T

    @property
    def diagonal(self) -> bool:
        """Whether every mode is uncoupled (all blocks 1x1)."""
        return self.kind == "diagonal"

    @property
    def eigenvalues(self) -> np.ndarray:
        """The eigenvalues of the blocks, in block order [1/s] (those of A, to rounding)."""
        out = [np.linalg.eigvals(self.matrix[s:e, s:e]) for s, e in self.blocks]
        return np.concatenate(out) if out else np.zeros(0, dtype=complex)

    def to_modal(self, x: np.ndarray) -> np.ndarray:
        """Modal coordinates r = T^-1 x (= L^H x) of states ``x`` (shape (n,) or (N, n))."""
        x = _states(x, self.right.shape[0], "x")
        return x @ self.inverse.T

    def from_modal(self, r: np.ndarray) -> np.ndarray:
        """States x = Re(T r) of modal coordinates ``r`` (shape (n,) or (N, n)).

        The imaginary part dropped is zero to rounding for r = to_modal(x) of a real x (the
        conjugate modes of a real model carry conjugate coordinates); for other r, x is the
        real motion that the complex modes describe."""
        r = _states(r, self.right.shape[0], "r")
        return (r @ self.right.T).real

    def derivative(self, r: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """r' = Lam r + B_r u + f_r for one modal state ``r`` (n,) and input ``u`` (m,)."""
        r = _states(r, self.right.shape[0], "r")
        out = r @ self.matrix.T + self.drift
        if u is not None:
            m = self.input_matrix.shape[1]
            u = real_array(u, "u", f"{m} real input values")
            if u.shape != (m,) or not np.all(np.isfinite(u)):
                raise ArgumentError("u", f"expected {m} finite input values, got shape "
                                         f"{u.shape}")
            out = out + u @ self.input_matrix.T
        return out


def _states(x: np.ndarray, n: int, name: str) -> np.ndarray:
    """``x`` as an array of states (n,) or (N, n): numbers (complex ones too: modal
    coordinates are complex), finite."""
    arr = np.asarray(x)
    if arr.dtype.kind not in "fiuc":
        raise ArgumentError(name, f"expected numbers, got an array of {arr.dtype}")
    if arr.ndim not in (1, 2) or arr.shape[-1] != n:
        raise ShapeError(f"{name} must have shape ({n},) or (N, {n}) (one state per row), got "
                         f"{arr.shape}")
    if not np.isfinite(arr).all():
        raise ArgumentError(name, "has NaN or inf entries")
    return arr


# --------------------------------------------------------------------------------------------
def decouple(A: np.ndarray, B: np.ndarray, C: np.ndarray, f0: np.ndarray | None = None, *,
             right: np.ndarray | None = None, left: np.ndarray | None = None,
             pairs: Sequence[int] = (), why: str = "") -> ModalCoordinates:
    """The modal form of (A, B, C, f0).

    Args:
        A, B, C: State, input and output matrices (n x n, n x m, p x n).
        f0: Drift (n) or None.
        right, left: Eigenvectors to use (columns, left scaled to L^H R = I), e.g. the closed
            form of the symmetric eigensolver; default: ``scipy.linalg.eig(A)`` with
            T^-1 = R^-1 (the left vectors that are exactly biorthogonal to R, also within
            repeated eigenvalues, where LAPACK's separate left vectors need not be).
        pairs: First columns of 2x2 Jordan blocks in ``right`` (rigid pairs (k, k+1)).
        why: Text added to the note (where the vectors come from).
    """
    A = np.asarray(A, dtype=float)
    n = A.shape[0]
    f = np.zeros(n) if f0 is None else np.asarray(f0, dtype=float)
    if n == 0:
        empty = np.zeros((0, 0), dtype=complex)
        return ModalCoordinates(empty, empty, empty, (), "diagonal", 1.0, 0.0,
                                np.zeros((0, B.shape[1]), complex), np.zeros(0, complex),
                                np.zeros((C.shape[0], 0), complex), "no states")
    if right is None:
        _, right = sla.eig(A)
        left, pairs = None, ()
    right = np.asarray(right, dtype=complex)
    kappa = _unit_condition(right)
    blocks = _blocks(n, pairs)
    if kappa <= COND_LIMIT:
        inverse = left.conj().T if left is not None else sla.solve(right, np.eye(n))
        worst = _eigenvalue_condition(right, inverse, blocks)
        spread = kappa * worst
        product = (f"eigenvector matrix condition {kappa:.2e} x largest eigenvalue "
                   f"condition {worst:.2e} = {spread:.2e}")
        if spread <= COND_LIMIT:
            kind = "jordan" if pairs else "diagonal"
            result = _finish(A, B, C, f, right, inverse, blocks, kind, kappa,
                             f"{why}{product} <= {COND_LIMIT:.0e}"
                             + (f"; {len(pairs)} rigid-body Jordan pair(s) kept as 2x2 blocks"
                                if pairs else ""))
            if left is None or result.residual <= RESIDUAL_LIMIT:
                return result
            return decouple(A, B, C, f0, why=f"closed-form vectors left a residual "
                                             f"{result.residual:.1e}; ")
    else:
        product = f"eigenvector matrix condition {kappa:.2e}"
    S, Sinv, blocks = _schur_blocks(A)
    sizes = [e - s for s, e in blocks]
    big = sum(k > 1 for k in sizes)
    note = (f"{why}{product} > {COND_LIMIT:.0e} (defective or nearly repeated eigenvalues): "
            f"block-diagonal Schur form with {len(blocks)} blocks, {big} of them larger than "
            f"1x1 (sizes {sorted(set(sizes))})")
    return _finish(A, B, C, f, S, Sinv, tuple(blocks), "schur", _unit_condition(S), note)


def _eigenvalue_condition(right: np.ndarray, inverse: np.ndarray,
                          blocks: Sequence[tuple[int, int]]) -> float:
    """The largest eigenvalue condition number |l_i| |r_i| (l_i^H: row i of R^-1) over the
    1x1 blocks (1 without any)."""
    single = [s for s, e in blocks if e - s == 1]
    if not single:
        return 1.0
    rows = np.linalg.norm(inverse[single], axis=1)
    cols = np.linalg.norm(right[:, single], axis=0)
    return float((rows * cols).max())


def _unit_condition(T: np.ndarray) -> float:
    norms = np.linalg.norm(T, axis=0)
    if np.any(norms == 0):
        return np.inf
    return float(np.linalg.cond(T / norms))


def _blocks(n: int, pairs: Sequence[int]) -> tuple[tuple[int, int], ...]:
    starts = set(pairs)
    out, k = [], 0
    while k < n:
        size = 2 if k in starts else 1
        out.append((k, k + size))
        k += size
    return tuple(out)


def _finish(A: np.ndarray, B: np.ndarray, C: np.ndarray, f: np.ndarray, T: np.ndarray,
            Tinv: np.ndarray, blocks: Sequence[tuple[int, int]], kind: str, kappa: float,
            note: str) -> ModalCoordinates:
    full = Tinv @ A @ T
    lam = np.zeros_like(full)
    for s, e in blocks:
        lam[s:e, s:e] = full[s:e, s:e]
    scale = max(float(np.abs(A).max(initial=0.0)), np.finfo(float).tiny)
    residual = float(np.abs(full - lam).max(initial=0.0)) / scale
    arrays = [T, Tinv, lam, Tinv @ B, Tinv @ f, C @ T]
    for arr in arrays:
        arr.flags.writeable = False
    return ModalCoordinates(arrays[0], arrays[1], arrays[2], tuple(blocks), kind, kappa,
                            residual, arrays[3], arrays[4], arrays[5], note)


def _schur_blocks(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """T, T^-1 and the blocks of a block-diagonal Schur form of A (Bavely-Stewart).

    Walks the diagonal of the complex Schur form T (A = Z T Z^H): a block [s, e) is split from
    the rest [e, n) by X with T11 X - X T22 = -T12 (then Y = [[I, X], [0, I]] zeroes T12) when
    every |X_ij| <= BLOCK_BOUND; otherwise the remaining eigenvalue nearest to the block is
    swapped to position e (a unitary reordering) and the block grows by one."""
    T, Z = sla.schur(np.asarray(A, dtype=complex), output="complex")
    n = T.shape[0]
    S = Z.copy()
    blocks: list[tuple[int, int]] = []
    s = 0
    while s < n:
        e = s + 1
        while e < n:
            x, scale, info = lapack.ztrsyl(T[s:e, s:e], T[e:, e:], -T[s:e, e:], isgn=-1)
            if info == 0 and scale > 0:
                X = x / scale
                if np.all(np.abs(X) <= BLOCK_BOUND):
                    T[s:e, e:] = 0.0
                    S[:, e:] += S[:, s:e] @ X
                    break
            d = np.diag(T)
            dist = np.abs(d[e:, None] - d[None, s:e]).min(axis=1)
            j = e + int(np.argmin(dist))
            if j != e:
                T, Q, info = lapack.ztrexc(T, np.eye(n, dtype=complex), j + 1, e + 1)
                Q = Q[e:j + 1, e:j + 1]  # the swaps touch rows and columns e..j only
                S[:, e:j + 1] = S[:, e:j + 1] @ Q
            e += 1
        blocks.append((s, e))
        s = e
    # Unit columns (a diagonal scaling keeps the blocks): the splits grow them (to ~60 for
    # solo12), and |T| |T^-1| |A| eps is the rounding of every product with T and T^-1.
    # T^-1 by an LU solve (relative error ~ cond(T) eps), not by accumulating the inverses of
    # the splits and swaps, whose rounding adds up over the n steps.
    S /= np.linalg.norm(S, axis=0)
    return S, sla.solve(S, np.eye(n, dtype=complex)), blocks


def from_analysis(modes: ModalAnalysis) -> ModalCoordinates:
    """The modal form of a :class:`~pinlin.modal.ModalAnalysis`'s model (its standard form
    when it has E): the symmetric eigensolver's closed-form vectors, with rigid pairs as
    Jordan blocks, else the general eigensolver's right vectors with T^-1 = R^-1."""
    model = modes.model
    if modes.method == "symmetric":
        pairs = [int(k) for k in np.flatnonzero(modes.rigid[0::2]) * 2]
        return decouple(model.A, model.B, model.C, model.f0, right=modes.right_vectors,
                        left=modes.left_vectors, pairs=pairs,
                        why="symmetric (K, M) eigenvectors; ")
    return decouple(model.A, model.B, model.C, model.f0, right=modes.right_vectors,
                    why="general eigenvectors, left vectors = rows of R^-1; ")


__all__ = ["BLOCK_BOUND", "COND_LIMIT", "KINDS", "ModalCoordinates", "decouple", "from_analysis"]
