"""LAPACK eigensolvers behind :func:`pinlin.modal` and the eigenvalue-conditioning test of
its accuracy warning.

- The definite pencil (K, M) by ``dsygvd`` (:func:`solve_pencil`), and the right and left
  eigenvectors of the first-order A that follow from its shapes in closed form
  (:func:`symmetric_right`, :func:`symmetric_left`).
- The general A by ``dgeev`` with right vectors only (:func:`geev`; the call and workspace of
  ``scipy.linalg.eig``, so the same digits), left vectors on request (:func:`general_left`).
- Condition numbers from one LU inverse of the right vectors (:func:`pair_conditions`) and the
  warning when rounding in A may move an eigenvalue by more than :data:`EIGENVALUE_RISK`
  (:func:`warn_if_at_risk`).
"""

from __future__ import annotations

import contextlib
import functools
import math
import warnings
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import LinAlgError, lapack

from .conditioning import AccuracyWarning

if TYPE_CHECKING:
    from .linear_model import LinearModel
    from .modal import ModalAnalysis

_EPS = float(np.finfo(float).eps)


def solve_pencil(model: LinearModel, vectors: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """w2 (ascending) and, with ``vectors``, phi (phi^T M phi = I) of the definite pencil
    (K_s, M), K_s = (K + K^T) / 2: LAPACK ``dsygvd``, the call and workspace of
    ``scipy.linalg.eigh(K_s, M, driver="gvd", eigvals_only=not vectors)``, without its
    checks (the entries are checked by ``modal``)."""
    K = model.K
    Ks = 0.5 * (K + K.T)    # symmetric bit for bit, so Ks.T is itself in Fortran order
    w2, phi, info = lapack.dsygvd(Ks.T, model.M, jobz="V" if vectors else "N", overwrite_a=1)
    if info:
        raise LinAlgError(sygvd_failure(info, K.shape[0]))
    return w2, (phi if vectors else None)


def sygvd_failure(info: int, n: int) -> str:
    """scipy.linalg.eigh's message for a failed dsygvd."""
    if info > n:
        return (f"The leading minor of order {info - n} of B is not positive definite. The "
                "factorization of B could not be completed and no eigenvalues or eigenvectors "
                "were computed.")
    if info < 0:
        return f"Illegal value in argument {-info} of internal dsygvd"
    return ("The algorithm failed to compute an eigenvalue while working on the submatrix "
            f"lying in rows and columns {info}/{n + 1} through mod({info},{n + 1}).")


def symmetric_right(lam: np.ndarray, phi: np.ndarray, rigid: np.ndarray) -> np.ndarray:
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


def symmetric_left(lam: np.ndarray, mphi: np.ndarray, rigid: np.ndarray) -> np.ndarray:
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


@functools.lru_cache(maxsize=256)
def geev_lwork(n: int, left: bool) -> int:
    """dgeev's optimal workspace, as scipy.linalg.eig asks for it (a smaller one changes the
    blocking and so the last digits)."""
    work, info = lapack.dgeev_lwork(n, compute_vl=int(left))
    if info:
        raise LinAlgError(f"dgeev workspace query failed (LAPACK info={info})")
    return int(work)


#: Largest entries |a_ij| outside this range are scaled by :func:`geev` before dgeev. dgeev
#: scales a matrix whose largest entry lies outside [sqrt(safmin)/eps, eps/sqrt(safmin)]
#: (6.7e-139, 1.5e138) to that bound, and the scipy-openblas builds measured here return the
#: eigenvalues of the scaled matrix without undoing it: diag(-1e150, -1) came back as
#: (-1.5e138, -1.5e-12), scipy.linalg.eig alike. The margin keeps dgeev's own test well clear.
GEEV_RANGE = (1e-130, 1e130)


def geev_scale(A: np.ndarray, a2: float | None = None) -> int:
    """The power of 2, k, such that 2^k A has its largest |a_ij| in [0.5, 1) when that entry
    lies outside :data:`GEEV_RANGE`, else 0 (``a2``: |A|_F^2 when the caller has it, which
    settles the usual case without a pass over A: max|a_ij| lies in [|A|_F / n, |A|_F]).
    Subnormal entries included: k up to ~1075."""
    n = max(A.shape[0], 1)
    lo, hi = GEEV_RANGE
    if a2 is not None and lo * lo * n * n < a2 < hi * hi:   # (a2 of tiny entries underflows)
        return 0
    largest = max(float(A.max(initial=0.0)), -float(A.min(initial=0.0)))
    if largest == 0.0 or lo < largest < hi or not math.isfinite(largest):
        return 0
    return -math.frexp(largest)[1]


def geev(A: np.ndarray, left: bool, a2: float | None = None) -> tuple[np.ndarray, ...]:
    """wr, wi, vl, vr of LAPACK dgeev (vl empty unless ``left``), as scipy.linalg.eig calls it;
    a matrix with entries beyond :data:`GEEV_RANGE` is scaled by a power of 2 first
    (:func:`geev_scale`) and its eigenvalues scaled back, both exact (the eigenvectors do not
    change). ``a2``: |A|_F^2 if known (:func:`geev_scale`)."""
    k = geev_scale(A, a2)
    wr, wi, vl, vr, info = lapack.dgeev(np.ldexp(A, k) if k else A, compute_vl=int(left),
                                        lwork=geev_lwork(A.shape[0], left))
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of internal eig algorithm (geev)")
    if info > 0:
        raise LinAlgError(f"eig algorithm (geev) did not converge (only eigenvalues with order "
                          f">= {info} have converged)")
    if k:   # np.ldexp: exact, no 2^k to overflow where k > 1023
        wr, wi = np.ldexp(wr, -k), np.ldexp(wi, -k)
    return wr, wi, vl, vr


def complex_vectors(v: np.ndarray, wi: np.ndarray) -> np.ndarray:
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


def general_left(A: np.ndarray, vr: np.ndarray, wi: np.ndarray, order: np.ndarray,
                  right: np.ndarray) -> np.ndarray:
    """Left eigenvectors matching ``right`` (sorted by ``order``), scaled to l^H r = 1.

    dgeev with left vectors repeats the reduction of the right-only call, so its right vectors
    (and eigenvalues) come out the same bit for bit; should they not, the rows of R^-1 are
    used (left vectors biorthogonal to R by construction)."""
    if A.shape[0] == 0:
        return np.zeros((0, 0))
    _, wi2, vl, vr2 = geev(A, left=True)
    if not (np.array_equal(vr2, vr) and np.array_equal(wi2, wi)):
        return np.linalg.solve(right, np.eye(len(order))).conj().T
    vl = complex_vectors(vl, wi)[:, order]
    dots = np.einsum("ij,ij->j", vl.conj(), right)
    ok = np.abs(dots) > np.finfo(float).eps
    return np.where(ok, vl / np.where(ok, dots, 1.0).conj(), vl)


#: modal warns when rounding in A alone may move an eigenvalue by more than this (relative).
EIGENVALUE_RISK = 1e-6


#: Factor below EIGENVALUE_RISK under which the cheap bound (:func:`warn_if_at_risk`)
#: settles that no warning is due (it is within a factor 2 N of kappa eps max|A| / |lam|).
RISK_MARGIN = 4.0


#: Least factor by which the risk from V^-1 must clear the threshold to be trusted over
#: LAPACK's (:func:`risk_margin`); within it, LAPACK's left vectors decide.
RISK_MARGIN_MIN = 1.01


def inverse(vr: np.ndarray) -> np.ndarray | None:
    """V^-1 by LU (LAPACK ``dgetrf``, ``dgetri``), or None when V is exactly singular."""
    lu, piv, info = lapack.dgetrf(vr)
    if info:
        return None
    inv, info = lapack.dgetri(lu, piv, overwrite_lu=1)
    return None if info else inv


def pair_conditions(k2: np.ndarray, wi: np.ndarray) -> np.ndarray:
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


def rounding_shift(kappa: np.ndarray, gaps: np.ndarray, delta: float, frobenius: float
                   ) -> np.ndarray:
    """How far a perturbation of size ``delta`` can move eigenvalues of condition ``kappa``
    (``gaps`` (n, 2): the distances to their nearest and second nearest other eigenvalue):
    kappa delta (first order), but at most the reach of a coalescing pair where no third
    eigenvalue is near. A pair's 2 x 2 Schur block [[l1, s], [0, l2]] (gap g = |l1 - l2|),
    perturbed by E of size delta, has eigenvalues apart by about
    sqrt((g + 2 delta)^2 + 4 (s + delta) delta), so each moves by at most
    sqrt((s + delta) delta) + delta with s <= |A|_F (the block is part of a unitary
    similarity of A): sqrt(eps) for a defective pair (a critically damped mode's double
    eigenvalue moves by ~1e-8, not by kappa eps ~ 1 as first order says), while kappa delta
    stays the smaller wherever the pair is apart. Three that coalesce move by delta^(1/3),
    further: the cap is taken only where the second nearest lies beyond twice the reach."""
    first = kappa * delta
    reach = math.sqrt((frobenius + delta) * delta) + delta
    return np.where(gaps[:, 1] > 2.0 * reach, np.minimum(first, reach), first)


def nearest_gaps(lam: np.ndarray) -> np.ndarray:
    """(n, 2): for each eigenvalue, the distances to its nearest and second nearest other
    one (inf where there is none)."""
    d = np.abs(lam[:, None] - lam[None, :])
    np.fill_diagonal(d, math.inf)
    d = np.hstack([d, np.full((lam.size, 2), math.inf)])
    return np.sort(d, axis=1)[:, :2]


def warn_if_at_risk(result: ModalAnalysis, vr: np.ndarray, wi: np.ndarray,
                     magnitudes: np.ndarray, n_rigid: int, a2: float | None = None) -> None:
    """AccuracyWarning when rounding in A (eps max|A|) can move a non-rigid eigenvalue by
    more than EIGENVALUE_RISK of itself: kappa eps max|A| / |lam| > 1e-6, or where the
    eigenvalue and its nearest neighbour coalesce under it, the pair's shift
    (:func:`rounding_shift`) / |lam| > 1e-6 (``vr``, ``wi``,
    ``magnitudes`` |lam|: in dgeev's order; the first ``n_rigid`` sorted eigenvalues are rigid;
    ``a2``: |A|_F^2 if known).

    One LU inverse of the right vectors V settles it (:func:`pair_conditions`): first a bound
    (max over the columns of |row of V^-1| / |lam|, >= kappa / |lam|, times eps |A|_F >=
    eps max|A|), which clears the usual model; else kappa itself. Only where V is singular or
    kappa lies within :func:`risk_margin` of the threshold are LAPACK's left vectors computed
    (:attr:`ModalAnalysis.condition`, a second ``dgeev``), so that a borderline case is settled
    exactly as the condition numbers a user reads would settle it."""
    A, order = result.model.A, result._order
    frobenius = math.sqrt(a2 if a2 is not None and a2 < math.inf else np.vdot(A, A))
    gaps = None   # nearest_gaps of the sorted eigenvalues, once past the cheap bound
    inv = inverse(vr)
    if inv is not None:
        # Squared row norms (einsum: no overflow warning where V^-1 is huge, inf then).
        k2 = np.einsum("ij,ij->i", inv, inv)
        moving = order[n_rigid:]                        # sorted, non-rigid, dgeev's indices
        k2_moving, lam_moving = (k2[moving], magnitudes[moving]) if n_rigid else (k2, magnitudes)
        # sqrt(k2) / |lam| overflows only below |lam| ~ 1e-150 (inf: LAPACK's left vectors
        # decide); errstate costs a microsecond, so only there
        with (np.errstate(over="ignore") if magnitudes[moving[0]] <= 1e-150
              else contextlib.nullcontext()):
            worst_column = float((np.sqrt(k2_moving) / lam_moving).max())
        if worst_column * _EPS * frobenius <= EIGENVALUE_RISK / RISK_MARGIN:   # False for NaN
            return
        scale = _EPS * float(np.abs(A).max())
        kappa = pair_conditions(k2, wi)[moving]
        gaps = nearest_gaps(result.eigenvalues)         # sorted: moving[j] is n_rigid + j
        risk = rounding_shift(kappa, gaps[n_rigid:], scale, frobenius) / magnitudes[moving]
        worst = int(np.argmax(risk))        # a NaN wins argmax, and fails both tests below
        ratio = float(risk[worst]) / EIGENVALUE_RISK
        margin = risk_margin(k2_moving, k2.size)
        if ratio * margin < 1.0:
            return
        if margin < ratio < math.inf:
            warn(result, n_rigid + worst, float(kappa[worst]), float(risk[worst]))
            return
    scale = _EPS * float(np.abs(A).max())
    ok = ~result.rigid
    kappa = result.condition[ok]
    if gaps is None:
        gaps = nearest_gaps(result.eigenvalues)
    risk = rounding_shift(kappa, gaps[ok], scale, frobenius) / result.wn[ok]
    worst = int(np.argmax(risk))
    if risk[worst] > EIGENVALUE_RISK:
        warn(result, int(np.flatnonzero(ok)[worst]), float(kappa[worst]), float(risk[worst]))


def risk_margin(k2: np.ndarray, n: int) -> float:
    """How far (a factor > 1) the risk from V^-1 must lie from the threshold to be trusted
    over LAPACK's: 1 + 100 n c eps with c = sqrt(n sum k2) (``k2``: squared norms of the rows
    of V^-1 that belong to non-rigid eigenvalues; n: size of A), the relative error of either
    kappa bounded generously (those rows are accurate to ~c eps relative, c being cond_F(V)
    restricted to them; dgeev's columns have unit norm). 1.01 for pinlin's robots at rest;
    ~150 where kappa ~ 1e14 (the floating bases at a moving state: those warn far above it).
    NaN or inf rows give inf: LAPACK decides."""
    cond = math.sqrt(n * float(k2.sum()))
    return max(RISK_MARGIN_MIN, 1.0 + 100.0 * n * cond * _EPS)


def warn(result: ModalAnalysis, index: int, kappa: float, risk: float) -> None:
    """The AccuracyWarning for eigenvalue ``index`` (sorted) of condition number ``kappa``
    and relative risk ``risk``."""
    lam = result.eigenvalues[index]
    warnings.warn(AccuracyWarning(
        f"model '{result.model.name}': eigenvalue {lam:.6g} has condition number "
        f"{kappa:.2e}; rounding in A alone may move it by {risk:.1e} (relative)", kappa),
        stacklevel=5)  # warn, warn_if_at_risk, _general, modal, the caller

