"""Frequency responses of a linear model, from its modal form, and Bode plots.

For x' = A x + B u + E u', y = C x + D u + F u' and u = U e^{jwt}, the steady-state output is
Y = H(jw) U with::

    H(jw) = C (jw I - A)^-1 (B + jw E) + D + jw F
          = C (jw I - A)^-1 B' + D' + jw F           (standard form: B' = B + A E, D' = D + C E)

computed from the modal form x = T r (:mod:`pinlin.modal_coordinates`)::

    H(jw) = sum_i c_i b_i^T / (jw - lam_i) + D' + jw F      (c_i = C r_i, b_i^T = l_i^H B')

with a Jordan or Schur block of the modal form solved as one small system (jw I - Lam_b)^-1.
A discrete model (dt > 0) gives H(e^{jw dt}) = C (z I - A)^-1 B + D at z = e^{jw dt}, from the
eigenvectors of its A. Where jw makes a block of the modal form exactly singular (an undamped
mode's frequency, rigid modes at w = 0) H is infinite (inf) in the entries that see that pole
and finite in the others (an uncontrollable or unobservable mode adds nothing). Near a pole, or
at one the modal form does not resolve exactly, H is large and finite, as accurate as the
conditioning of jw I - A allows.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .arrays import real_array
from .exceptions import ArgumentError, ModelError
from .fields import show
from .files import PNG_METADATA, check_file_target, write_atomic
from .linear_model import LinearModel
from .resources import check_memory

#: A Bode figure draws at most this many (output, input) curves: beyond, select some with
#: ``inputs=`` / ``outputs=``.
MAX_CURVES = 36


@dataclass(frozen=True, eq=False)
class FrequencyResponse:
    """H(jw) on a grid of frequencies; arrays are read-only.

    Attributes:
        w: Frequencies [rad/s].
        H: Complex gains, shape (len(w), p, m): H[k, i, j] = y_i / u_j at w[k] (units of the
            output per unit of the input).
        input_names, output_names: The m inputs and p outputs selected.
        name: The model's name.
        note: How H was computed (the modal form used).
    """

    w: np.ndarray
    H: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    name: str
    note: str

    @property
    def magnitude(self) -> np.ndarray:
        """|H| (same shape as H)."""
        return np.abs(self.H)

    @property
    def magnitude_db(self) -> np.ndarray:
        """20 log10 |H| [dB] (-inf where H = 0)."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(np.abs(self.H))

    @property
    def phase(self) -> np.ndarray:
        """Phase of H [rad], unwrapped along w."""
        return np.unwrap(np.angle(self.H), axis=0)

    def gain(self, output: str, input: str) -> np.ndarray:  # noqa: A002 (the signal's name)
        """H[:, output, input] (len(w)) for the named output and input (an input may be named
        without its ``u:`` prefix, as for :func:`frequency_response`)."""
        for what, name in (("output", output), ("input", input)):
            if not isinstance(name, str):
                raise ArgumentError(what, f"expected one {what} name, got {show(name)}")
        return self.H[:, _select(output, self.output_names, "output")[0],
                      _select(input, self.input_names, "input")[0]]


def _select(chosen: Sequence[str] | str | None, names: tuple[str, ...], what: str) -> list[int]:
    if chosen is None:
        return list(range(len(names)))
    if isinstance(chosen, str):
        chosen = [chosen]
    if not isinstance(chosen, list | tuple | np.ndarray) or not len(chosen):
        raise ArgumentError(f"{what}s", f"expected a name or a non-empty list of {what} "
                                        f"names, got {show(chosen)}")
    out = []
    for name in chosen:
        if not isinstance(name, str):
            raise ArgumentError(f"{what}s", f"expected {what} names, got "
                                            f"{type(name).__name__}")
        idx = [i for i, n in enumerate(names) if n == name or n == f"u:{name}"]
        if not idx:
            close = difflib.get_close_matches(name, names, n=3)
            hint = (f"did you mean {', '.join(map(repr, close))}?" if close
                    else f"the model's {what}s are {', '.join(names) or '(none)'}")
            raise ArgumentError(f"{what}s", f"no {what} named {show(name)}; {hint}")
        if idx[0] in out:
            raise ArgumentError(f"{what}s", f"{what} {names[idx[0]]!r} is named twice")
        out.append(idx[0])
    return out


def _frequencies(w: object) -> np.ndarray:
    arr = real_array(w, "w", "a 1-D sequence of finite frequencies [rad/s]")
    arr = arr.reshape(-1) if arr.ndim <= 1 else None
    if arr is None or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise ArgumentError("w", "expected a 1-D sequence of finite frequencies [rad/s]")
    return arr


def _block_gain(M: np.ndarray, c: np.ndarray, b: np.ndarray, s: complex
                ) -> tuple[np.ndarray, np.ndarray]:
    """c (s I - M)^-1 b of one block of the modal form that is singular at s, and where it is
    infinite (the entries that see the pole; the finite part is returned there as 0).

    The eigenvalues of the block at s form a cluster: a defective one is computed only to
    ~eps^(1/k) (k the block size; a Schur block of rigid modes holds zeros and 1e-7s), so
    those within eps^(1/k) k max(1, |M|) of s count as s. When the whole block is that
    cluster, (s' I - M)^-1 = sum_j N^j / (s' - s)^(j+1) with N = M - s I (nilpotent to
    rounding): an entry is infinite iff some c N^j b is non-zero, else 0. Otherwise the
    eigenvalues are split: those at s give the poles, the others the finite remainder. A
    residue is a pole however small (the limit w -> 0 of the computed model grows without
    bound); only an entry that does not couple to the block at all stays finite."""
    k = M.shape[0]
    lam, V = np.linalg.eig(M)
    radius = np.finfo(float).eps ** (1.0 / k) * k * max(1.0, float(np.abs(M).max()))
    near = np.abs(lam - s) <= radius
    shape = (c.shape[0], b.shape[1])
    if near.all():
        N = M - s * np.eye(k)
        at = np.zeros(shape, dtype=bool)
        power = np.eye(k)
        for _ in range(k):
            at |= (c @ power @ b) != 0
            power = power @ N
        return np.zeros(shape, dtype=complex), at
    cv, vb = c @ V, np.linalg.solve(V, b)
    gain = sum((np.outer(cv[:, i], vb[i]) / (s - lam[i]) for i in np.flatnonzero(~near)),
               np.zeros(shape, dtype=complex))
    at = np.zeros(shape, dtype=bool)
    for i in np.flatnonzero(near):
        at |= np.outer(cv[:, i], vb[i]) != 0
    return gain, at


def _direct_where_fast(H: np.ndarray, std: LinearModel, s: np.ndarray, rows: list[int],
                       cols: list[int]) -> None:
    """Overwrite the strictly proper part of H at the frequencies |s| >= 2 |A|_F by
    C (sI - A)^-1 B solved directly (cond(sI - A) <= 3 there, no pole). The modal sum
    sum c_i b_i / (s - lam_i) cancels there: with C B = 0 (a position per force) its terms
    are of size 1/w and their sum 1/w^2, so it loses (w / |lam|) digits (ur5 at 1e15 rad/s:
    all of them)."""
    n = std.A.shape[0]
    if not n or not rows or not cols:
        return
    fast = np.flatnonzero(np.abs(s) >= 2.0 * np.linalg.norm(std.A))
    if not fast.size:
        return
    mats = s[fast, None, None] * np.eye(n) - std.A
    X = np.linalg.solve(mats, np.broadcast_to(std.B[:, cols], (fast.size, n, len(cols))))
    H[fast] = np.einsum("pi,kim->kpm", std.C[rows], X)


def frequency_response(model: LinearModel, w: np.ndarray | Sequence[float],
                       inputs: Sequence[str] | str | None = None,
                       outputs: Sequence[str] | str | None = None) -> FrequencyResponse:
    """H(jw) of ``model`` at the frequencies ``w`` [rad/s], from its modal form.

    Args:
        model: A :class:`~pinlin.LinearModel` (continuous, or discrete: H(e^{jw dt})).
        w: Frequencies [rad/s].
        inputs, outputs: Names to keep (default all); an input may be named without its
            ``u:`` prefix.

    Raises:
        ArgumentError: not a LinearModel, bad ``w``, or an input or output name the model
            does not have.
        ModelError: a discrete model with input-derivative terms (E, F).
        ResourceError: the response would exceed the memory limit
            (:mod:`pinlin.resources`).
    """
    if not isinstance(model, LinearModel):
        raise ArgumentError("model", f"expected a pinlin LinearModel, got "
                                     f"{type(model).__name__}")
    w = _frequencies(w)
    cols = _select(inputs, model.input_names, "input")
    rows = _select(outputs, model.output_names, "output")
    # H, its pole mask and one einsum temporary (16 + 1 + 16 bytes an entry), the resolvent
    # of the scalar modes with its gap and mask (about 48 bytes per state and frequency),
    # before any is allocated (1e8 frequencies of a double pendulum raised numpy's
    # MemoryError).
    check_memory(len(w) * (33 * len(rows) * len(cols) + 48 * model.n_states + 16),
                 f"model '{model.name}': the frequency response at {len(w)} frequencies")
    std = model.standard_form()
    if model.dt:
        for key in ("E", "F"):
            mat = getattr(model, key)
            if mat is not None and np.any(mat):
                raise ModelError(f"model '{model.name}' is discrete with input-derivative "
                                 f"terms ({key}): no frequency response")
        from .modal_coordinates import decouple

        dec = decouple(std.A, std.B, std.C, why="eigenvectors of the discrete A; ")
        s = np.exp(1j * w * model.dt)
    else:
        from .modal import modal

        modes = modal(std)
        dec = modes.decoupling
        s = 1j * w
    Br, Cr = dec.input_matrix[:, cols], dec.output_matrix[rows]
    H = np.zeros((len(w), len(rows), len(cols)), dtype=complex)
    pole = np.zeros(H.shape, dtype=bool)     # entries whose pole s hits exactly: infinite
    with np.errstate(all="ignore"):   # overflow near a pole: inf, or NaN refused below
        scalars = [s_ for s_, e in dec.blocks if e - s_ == 1]
        if scalars:
            lam = np.diag(dec.matrix)[scalars]
            gap = s[:, None] - lam[None, :]
            hit = gap == 0
            resolvent = np.where(hit, 0.0, 1.0 / np.where(hit, 1.0, gap))
            H += np.einsum("pi,ki,im->kpm", Cr[:, scalars], resolvent, Br[scalars])
            for k, i in zip(*np.nonzero(hit), strict=True):
                pole[k] |= np.outer(Cr[:, scalars[i]], Br[scalars[i]]) != 0
        for s_, e in ((s_, e) for s_, e in dec.blocks if e - s_ > 1):
            k = e - s_
            M, c, b = dec.matrix[s_:e, s_:e], Cr[:, s_:e], Br[s_:e]
            mats = s[:, None, None] * np.eye(k) - M
            try:
                H += np.einsum("pi,kim->kpm", c, np.linalg.solve(
                    mats, np.broadcast_to(b, (len(w), k, len(cols)))))
            except np.linalg.LinAlgError:   # s hits an eigenvalue of the block exactly
                for j in range(len(w)):
                    try:
                        H[j] += c @ np.linalg.solve(mats[j], b)
                    except np.linalg.LinAlgError:
                        gain, at = _block_gain(M, c, b, s[j])
                        H[j] += gain
                        pole[j] |= at
    if not model.dt:
        _direct_where_fast(H, std, s, rows, cols)
    H += std.D[np.ix_(rows, cols)]
    if std.F is not None and np.any(std.F) and not model.dt:
        H += s[:, None, None] * std.F[np.ix_(rows, cols)]
    H[pole] = np.inf
    if np.isnan(H).any():   # 1/w^2 of a rigid pair overflowing at w ~ 1e-155, inf - inf
        k = int(np.flatnonzero(np.isnan(H).any(axis=(1, 2)))[0])
        raise ModelError(f"model '{model.name}': its frequency response at w = {w[k]:.3g} "
                         "rad/s leaves float64's range (a pole at or near the origin, seen "
                         "from that close); give frequencies further from it")
    for arr in (w, H):
        arr.flags.writeable = False
    return FrequencyResponse(w, H, tuple(model.input_names[j] for j in cols),
                             tuple(model.output_names[i] for i in rows), model.name,
                             f"{dec.kind} modal form: {dec.note}")


def bode(model: LinearModel, w: np.ndarray | Sequence[float], path: str | Path,
         inputs: Sequence[str] | str | None = None,
         outputs: Sequence[str] | str | None = None) -> FrequencyResponse:
    """Draw the Bode plot of ``model`` (magnitude [dB] and phase [deg] against w [rad/s],
    log scale) into the PNG file ``path``, written atomically; returns the response drawn.

    Args:
        model: The model.
        w: Frequencies [rad/s], > 0 (logarithmic axis).
        path: Output file, ending in ``.png``.
        inputs, outputs: Names to draw (default all, at most :data:`MAX_CURVES` pairs).

    Raises:
        ArgumentError: a path not ending in .png, w <= 0, or too many curves.
        ModelFileError: the file cannot be written.
    """
    path = check_file_target(path)
    if path.suffix.lower() != ".png":
        raise ArgumentError("path", f"a Bode plot is written as PNG: expected a name ending "
                                    f"in .png, got '{path.name}'")
    freq = _frequencies(w)
    if np.any(freq <= 0):
        raise ArgumentError("w", "a Bode plot needs frequencies > 0 [rad/s] (log axis)")
    if not isinstance(model, LinearModel):
        raise ArgumentError("model", f"expected a pinlin LinearModel, got "
                                     f"{type(model).__name__}")
    rows = _select(outputs, model.output_names, "output")
    cols = _select(inputs, model.input_names, "input")
    if len(rows) * len(cols) > MAX_CURVES:
        raise ArgumentError("inputs", f"{len(rows)} outputs x {len(cols)} inputs = "
                                      f"{len(rows) * len(cols)} curves, more than "
                                      f"{MAX_CURVES}: choose some with inputs= / outputs=")
    fr = frequency_response(model, np.sort(freq), inputs, outputs)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_mag, ax_ph) = plt.subplots(2, 1, sharex=True, figsize=(7.0, 6.0))
    finite = np.isfinite(fr.H)
    with np.errstate(divide="ignore"):
        db = np.where(finite, fr.magnitude_db, np.nan)
    phase = np.degrees(np.unwrap(np.angle(np.where(finite, fr.H, 1.0)), axis=0))
    phase = np.where(finite, phase, np.nan)
    for i, out in enumerate(fr.output_names):
        for j, inp in enumerate(fr.input_names):
            label = f"{out} / {inp}"
            ax_mag.semilogx(fr.w, db[:, i, j], label=label)
            ax_ph.semilogx(fr.w, phase[:, i, j], label=label)
    ax_mag.set_ylabel("magnitude [dB]")
    ax_ph.set_ylabel("phase [deg]")
    ax_ph.set_xlabel("w [rad/s]")
    ax_mag.set_title(f"Bode plot of '{model.name}'")
    for ax in (ax_mag, ax_ph):
        ax.grid(True, which="both", alpha=0.3)
    ax_mag.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    try:
        write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=80,
                                                  bbox_inches="tight", metadata=PNG_METADATA))
    finally:
        plt.close(fig)
    return fr


__all__ = ["MAX_CURVES", "FrequencyResponse", "bode", "frequency_response"]
