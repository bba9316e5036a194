"""Time responses of a linear model: modal superposition or the matrix exponential.

``response(model, t, x0, u, method)`` gives x(t) and y(t) at the sample times ``t`` [s] of

    x' = f0 + A x + B u + E u',    y = C x + D u + F u'

from x(t[0]) = x0 (deviations from the operating point; f0 the drift there, zero at an
equilibrium). The input ``u`` is one of:

- ``None``: the free (initial-condition) response;
- a :class:`~pinlin.signals.Signal` (``pinlin.step``, ``pinlin.impulse``, ``pinlin.harmonic``
  and their sums): integrated exactly, as the complex exponentials it is made of;
- an array of samples, shape (N, m) (or (N,) for a single input), one row per time in ``t``;
- a callable ``u(t) -> (m,)`` of the time [s], sampled at ``t``.

Samples (arrays and callables) are held between sample times (zero-order hold): u(t) = u[k]
on [t[k], t[k+1]); both methods are exact for that held input, so a smooth input needs a fine
``t`` (or a Signal).

Methods (continuous models):

- ``"modal"``: each block of :class:`~pinlin.modal_coordinates.ModalCoordinates` on its own,
  superposed (x = Re(T r)). A mode r_i' = lam_i r_i + b_i u + f_i + b_i c e^{mu (t - t0)}
  advances over a step h from t_k by::

      r_i <- e^{lam h} r_i + h phi1(lam h) (b_i u_k + f_i)
             + b_i c e^{mu (t_k - t0)} (e^{mu h} - e^{lam h}) / (mu - lam)

  with phi1(z) = (e^z - 1) / z (``expm1``); the last factor is evaluated as h e^{a} phi1(b - a)
  with a the exponent of larger real part, so it holds at resonance (mu = lam: h e^{lam h},
  the secular t e^{lam t} growth) and for stiff modes. A Jordan or Schur block (rigid-body
  pairs, defective clusters) advances by the matrix exponential of its augmented block.
- ``"exact"``: the matrix exponential of the augmented matrix (Van Loan)::

      [[A, B, B c, f0],
       [0, 0, 0,   0 ],     exp(. h) -> x(t+h) from x(t), the held u, the signal states
       [0, 0, diag(mu), 0],              w = e^{mu (t - t0)} and f0
       [0, 0, 0,   0 ]]

  Its rounding is checked after the march (:func:`_check_rounding`): where A is far from
  normal the exponential applied to x is a small difference of large terms, and two more
  marches with A, B and f0 moved by 2 eps tell how many digits are left (a warning above
  1e-6, a refusal from 1).

Discrete models (``dt`` > 0) step their difference equation x[k+1] = f0 + A x[k] + B u[k]
whatever the method (``Response.method == "difference"``): ``t`` must be t[0] + k dt, a signal is
sampled at ``t`` and an impulse becomes u[0] = amplitude / dt (one sample of that area).

Input-derivative terms (E, graph models): handled by the standard form (Rowell eqs. 90-93),
xs = x - E u, xs' = f0 + A xs + (B + A E) u, y = C xs + (D + C E) u + F u'; the reported x is
xs + E u with u at the sample (after the jump, for held samples). A signal starts at t[0]
from zero input and x0 is the state just before it, as for an impulse: its jump u(t0+)
enters through E, x[0] = x0 + E u(t0+) (a step from rest is the step response of H(s) / s).
Held samples have no value before t[0]: x0 is the state at t[0], their first sample applied
(x[0] = x0). F u' needs the input's derivative: given for signals (exact), refused for
samples, whose derivative is a train of impulses.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla

from .arrays import real_array, sample_times
from .conditioning import AccuracyWarning
from .discretization import WARN_ZOH_ERROR, warn_if_inaccurate
from .exceptions import ArgumentError, ModelError, ShapeError
from .linear_model import LinearModel
from .resources import check_memory
from .signals import Signal

if TYPE_CHECKING:
    from .modal import ModalAnalysis
    from .modal_coordinates import ModalCoordinates

METHODS = ("modal", "exact")
#: Sample times of a discrete model may differ from t[0] + k dt by this fraction of dt
#: (``np.arange`` and ``np.linspace`` grids are within ~k eps of it).
DT_RTOL = 1e-6
_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True, eq=False)
class Response:
    """A time response; arrays are read-only.

    Attributes:
        t: Sample times (N) [s].
        x: States (N, n), deviations from the operating point, named by ``state_names``.
        y: Outputs (N, p), deviations, named by ``output_names``.
        u: Inputs at the sample times (N, m) [N*m or N] (the held value for samples; an
            impulse is not shown: it acts at t[0], before the first sample x(t0+)).
        state_names, input_names, output_names: Signal names.
        method: ``"modal"``, ``"exact"`` or ``"difference"`` (discrete models).
        name: The model's name.
        notes: What was done (the modal form used, input hold, standard form, impulse).
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    u: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    method: str
    name: str
    notes: tuple[str, ...]

    def state(self, name: str) -> np.ndarray:
        """The column of ``x`` named ``name`` (``q:<coordinate>``/``v:<coordinate>``)."""
        return self.x[:, _index(name, self.state_names, "state")]

    def output(self, name: str) -> np.ndarray:
        """The column of ``y`` named ``name``."""
        return self.y[:, _index(name, self.output_names, "output")]


def _index(name: str, names: tuple[str, ...], what: str) -> int:
    if name not in names:
        raise ArgumentError(what, f"no {what} named {name!r:.60}; expected one of "
                                  f"{', '.join(names)}")
    return names.index(name)


# --------------------------------------------------------------------------------------------
def response(model: LinearModel, t: np.ndarray | Sequence[float],
             x0: np.ndarray | Sequence[float] | None = None,
             u: Signal | np.ndarray | Callable[[float], np.ndarray] | None = None,
             method: str = "modal", *, modes: ModalAnalysis | None = None) -> Response:
    """The response of ``model`` at times ``t`` [s] from ``x0`` to the input ``u``.

    Args:
        model: A :class:`~pinlin.LinearModel` (continuous or discrete).
        t: Increasing sample times [s], N >= 1; x[0] is the state at t[0].
        x0: Initial state deviation (n), default zeros ([rad or m; rad/s or m/s]): x[0]
            itself, but for a Signal's jump through B (impulse) or E (module docstring), which
            acts just after x0.
        u: None, a :class:`~pinlin.signals.Signal`, samples (N, m), or a callable u(t) -> (m,)
            (see the module docstring; an exception the callable raises reaches the caller
            unchanged; what it returns must be m finite real numbers).
        method: ``"modal"`` (superposition of the decoupled modes) or ``"exact"`` (matrix
            exponential). Ignored for discrete models.
        modes: A :func:`pinlin.modal` analysis of the model (reused for ``"modal"``).

    Raises:
        ArgumentError: not a LinearModel, unknown method, bad ``t``, ``x0`` or ``u``, or
            ``modes`` of another model.
        ShapeError: ``x0`` or ``u`` of the wrong shape.
        ModelError: F u' terms with sampled inputs; E or F on a discrete model.
    """
    if not isinstance(model, LinearModel):
        raise ArgumentError("model", f"expected a pinlin LinearModel, got "
                                     f"{type(model).__name__}")
    if not isinstance(method, str) or method not in METHODS:
        raise ArgumentError("method", f"expected one of {', '.join(map(repr, METHODS))}, got "
                                      f"{method!r:.60}")
    t = sample_times(t)
    n, m = model.n_states, model.n_inputs
    # The arrays of the march (complex modal coordinates, states, outputs, inputs, held
    # samples, signal states) before any is allocated (2e7 samples of ur5 raised numpy's
    # MemoryError).
    check_memory(len(t) * 16 * (4 * n + model.n_outputs + 3 * m + 2),
                 f"model '{model.name}': the response at {len(t)} sample times")
    std = model.standard_form()
    x0 = _initial(x0, model)
    U, signal = _inputs(u, model, t)
    has_E = std is not model
    F = std.F if std.F is not None and np.any(std.F) else None
    notes: list[str] = []
    if model.dt:
        return _discrete(model, t, x0, U, signal, notes)
    if F is not None and signal is None and u is not None:
        raise ModelError(f"model '{model.name}' has an output term F u' (input derivative): "
                         "held samples have no derivative (impulses at each sample); give the "
                         "input as a Signal (pinlin.step, pinlin.harmonic), whose derivative "
                         "is known")
    impulse, c, mu = (signal.resolve(model.input_names, float(t[0])) if signal is not None
                      else (np.zeros(m), np.zeros((m, 0)), np.zeros(0)))
    E = model.E if has_E else np.zeros((n, m))
    # The drift is the same in the standard form, xs' = f0 + A xs + (B + A E) u (which
    # LinearModel.standard_form does not carry).
    f0 = np.zeros(n) if model.f0 is None else model.f0
    # A signal starts at t[0] from zero input, x0 the state just before it: its jump u(t0+)
    # passes through E (x[0] = x0 + E u(t0+)) as an impulse passes through B. Held samples
    # have no value before t[0]: x0 is the state at t[0], their first sample applied.
    xs0 = x0 + std.B @ impulse if signal is not None else x0 - E @ U[0]
    if has_E:
        notes.append("input-derivative terms E by the standard form xs = x - E u" + (
            "; the signal's jump at t[0] through E: x[0] = x0 + E u(t0+)"
            if signal is not None and np.any(E @ U[0]) else ""))
    if np.any(impulse):
        notes.append("impulse at t[0]: x[0] is the state just after it, x0 + B a")
    if signal is None and u is not None:
        notes.append("input samples held between sample times (zero-order hold)")
    held = U if signal is None else np.zeros_like(U)   # a signal enters as exponentials
    with np.errstate(over="ignore", invalid="ignore"):
        x, y = _march_all(model, std, method, modes, f0, c, mu, t, held, xs0, U, E,
                          F if signal is not None else None, notes)
    _check_finite(model, t, x, y)
    return _result(model, t, x, y, U, method, notes)


def _march_all(model, std, method, modes, f0, c, mu, t, held, xs0, U, E, F, notes):
    """(x, y) at the samples: the march in the chosen coordinates (see :func:`response`);
    ``F`` only where the input is a signal (its derivative known)."""
    n = model.n_states
    if method == "exact":   # each step h an expm of A h: as a zero-order hold over h warns
        longest = float(np.diff(t).max()) if len(t) > 1 else 0.0
        said = longest and warn_if_inaccurate(
            model.name, longest, std.A,
            "use shorter steps between the sample times, or method='modal' (exact per mode)",
            "the longest exact step between two sample times, h")
        xs = _march(std.A, ((0, n),), std.B, f0, c, mu, t, held, xs0).real
        if longest:
            _check_rounding(model.name, std, f0, c, mu, t, held, xs0, xs, said)
        notes.append("matrix exponential of the augmented matrix [[A, B, f0], [0, 0, 0]] h")
    else:
        dec = _coordinates(std, modes)
        r = _march(dec.matrix, dec.blocks, dec.input_matrix, dec.inverse @ f0, c, mu, t, held,
                   xs0 @ dec.inverse.T)
        xs = (r @ dec.right.T).real     # unchecked: _check_finite names where it overflowed
        notes.append(f"modal superposition, {dec.kind} form: {dec.note}")
    x = xs + U @ E.T
    y = xs @ std.C.T + U @ std.D.T
    if F is not None:
        du = (np.exp(np.outer(t - t[0], mu)) * mu) @ c.T    # u' of the signal's exponentials
        y = y + du.real @ F.T
    return x, y


#: Perturbed marches of the exact response's check, and the factor between their largest
#: spread and the error it reports: one sample of a random perturbation fell 66x short of the
#: error on one of a few hundred closed loops, and each further sample makes such a shortfall
#: rarer (statistical condition estimation: the chance falls like a power of the factor).
ROUNDING_SAMPLES = 2
ROUNDING_FACTOR = 10.0


def _check_rounding(name: str, std: LinearModel, f0: np.ndarray, c: np.ndarray, mu: np.ndarray,
                    t: np.ndarray, held: np.ndarray, xs0: np.ndarray, xs: np.ndarray,
                    said: float = 0.0) -> None:
    """Warn (or refuse) where the exact march is at the mercy of rounding.

    eps ||A|| h (:func:`~pinlin.discretization.warn_if_inaccurate`) measures the rounding of a
    normal A. A strongly non-normal A (||A|| far above its eigenvalues: a canonical penalty
    model under a full-state gain, ||A||_1 = 1e9 with eigenvalues near -10) amplifies it far
    beyond that: the squarings of scaling and squaring pass through a transient growth of
    exp(A tau), and x(t) = exp(A h) x is then a small difference of large terms. Such a four-bar
    came back 20x off with no word. The check marches ROUNDING_SAMPLES more times with every
    entry of A, B and f0 moved by 2 eps of itself (random signs from a fixed seed: the same
    verdict on every run; exact zeros stay zero), a perturbation of the size of their own
    rounding (statistical condition estimation, Kenney and Laub). ROUNDING_FACTOR times the
    largest spread from the first march, relative to the largest |x|, is the error estimate:
    above WARN_ZOH_ERROR an AccuracyWarning, from 1 a ModelError (no correct digit). It runs
    also where eps ||A|| h has already warned (``said``: the error that warning gave; a
    four-bar's warning of 1.1e-6 came with an answer 1e18 off), and then warns again only
    where it finds more than 10x that. Costs ROUNDING_SAMPLES more marches."""
    scale = float(np.abs(xs).max())
    if not scale > 0.0 or not np.isfinite(scale):
        return
    rng = np.random.default_rng(0)

    def nudged(a: np.ndarray) -> np.ndarray:
        return a * (1.0 + 2.0 * _EPS * rng.choice((-1.0, 1.0), size=a.shape))

    n = std.n_states
    spread = 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(ROUNDING_SAMPLES):
            again = _march(nudged(std.A), ((0, n),), nudged(std.B), nudged(f0), c, mu, t,
                           held, xs0).real
            spread = max(spread, float(np.abs(again - xs).max()) / scale)   # NaN: stays
    error = ROUNDING_FACTOR * spread if np.isfinite(spread) else math.inf
    if error < 1.0 and error <= max(WARN_ZOH_ERROR, 10.0 * said):
        return
    what = (f"moving each entry of A, B and f0 by 2 eps of itself changes it by {spread:.1e} "
            f"of its largest value, an error of up to {error:.1e} (||A||_1 = "
            f"{np.abs(std.A).sum(axis=0).max():.2e} 1/s, the longest step "
            f"{float(np.diff(t).max()):g} s)")
    if error >= 1.0:
        raise ModelError(f"model '{name}': the exact response is lost to rounding: {what}; no "
                         "correct digit can be relied on; use method='modal'")
    warnings.warn(AccuracyWarning(
        f"model '{name}': the exact response is sensitive to rounding: {what}; compare "
        "method='modal'", 1.0 / error), stacklevel=4)


def _check_finite(model: LinearModel, t: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    """Refuse a response that leaves float64's range (a growing mode over a long horizon):
    name the first sample time and the fastest growth rate."""
    bad = ~(np.isfinite(x).all(axis=1) & np.isfinite(y).all(axis=1))
    if not bad.any():
        return
    k = int(np.argmax(bad))
    A = model.standard_form().A
    lam = np.linalg.eigvals(A) if not model.dt else None
    # Re(lam) within rounding of zero (10 n eps |A|_F, as modal's) is no growth: a neutrally
    # stable model (3e-17 1/s from eigvals) over 1e308 s overflows by rounding alone.
    noise = 10 * A.shape[0] * float(np.finfo(float).eps) * float(np.linalg.norm(A))
    growth = "" if lam is None or not lam.size else (
        f"; its fastest mode grows at Re(lam) = {float(lam.real.max()):.4g} 1/s"
        if lam.real.max() > noise else "; no mode grows beyond rounding, but its rounding "
        "does over this horizon")
    raise ModelError(f"model '{model.name}': the response leaves float64's range at "
                     f"t = {t[k]:.6g} s (sample {k}){growth}; end the time span earlier")


def _coordinates(std: LinearModel, modes: ModalAnalysis | None) -> ModalCoordinates:
    from .modal import ModalAnalysis, modal

    if modes is None:
        return modal(std).decoupling
    if not isinstance(modes, ModalAnalysis):
        raise ArgumentError("modes", f"expected a pinlin.modal(...) result, got "
                                     f"{type(modes).__name__}")
    if not (np.array_equal(modes.model.A, std.A) and np.array_equal(modes.model.B, std.B)):
        raise ArgumentError("modes", f"the modal analysis is of model '{modes.model.name}' "
                                     f"with other A or B matrices than '{std.name}'")
    return modes.decoupling


def _result(model: LinearModel, t: np.ndarray, x: np.ndarray, y: np.ndarray, U: np.ndarray,
            method: str, notes: list[str]) -> Response:
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (t, x, y, U)]
    for a in arrays:
        a.flags.writeable = False
    return Response(*arrays, model.state_names, model.input_names, model.output_names,
                    method, model.name, tuple(notes))


# --------------------------------------------------------------------------------------------
def _initial(x0: object, model: LinearModel) -> np.ndarray:
    n = model.n_states
    if x0 is None:
        return np.zeros(n)
    arr = real_array(x0, "x0", f"{n} real numbers (the state {', '.join(model.state_names[:3])}"
                               f"{', ...' if n > 3 else ''})")
    if arr.shape != (n,):
        raise ShapeError(f"x0 must have shape ({n},) (states {', '.join(model.state_names)}),"
                         f" got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ArgumentError("x0", "expected finite numbers, got NaN or inf")
    return arr


def _inputs(u: object, model: LinearModel, t: np.ndarray) -> tuple[np.ndarray, Signal | None]:
    """(U, signal): the input at the samples (N, m) and the Signal if ``u`` is one."""
    N, m = len(t), model.n_inputs
    if u is None:
        return np.zeros((N, m)), None
    if isinstance(u, Signal):
        return u(t, model.input_names), u
    if callable(u):
        rows = [_call(u, float(tk), m) for tk in t]
        return np.array(rows).reshape(N, m), None
    arr = real_array(u, "u", f"None, a Signal, real samples ({N}, {m}) or a callable u(t)")
    if arr.ndim == 1 and m == 1 and arr.shape[0] == N:
        arr = arr[:, None]
    if arr.shape != (N, m):
        raise ShapeError(f"u must have shape ({N}, {m}) (one row per sample time, one column "
                         f"per input: {', '.join(model.input_names)}), got {arr.shape}; for a "
                         "constant input use pinlin.step")
    if not np.all(np.isfinite(arr)):
        raise ArgumentError("u", "expected finite input samples, got NaN or inf")
    return arr, None


def _call(u: Callable, tk: float, m: int) -> np.ndarray:
    value = real_array(u(tk), "u", f"u(t) to return {m} real numbers (at t = {tk:g} s)")
    value = value.reshape(-1)
    if value.shape != (m,) or not np.all(np.isfinite(value)):
        raise ArgumentError("u", f"u(t) must return {m} finite values; at t = {tk:g} s it "
                                 f"returned {value.shape[0]} value(s) {value[:4]}")
    return value


# --------------------------------------------------------------------------------------------
#: Below this |z|, phi1(z) = 1 + z / 2: the next term, z^2 / 6, is under 2e-17 (half an
#: ulp of 1), and a subnormal z made expm1(z) / z inf or NaN (a step of 1e-310 s).
PHI1_SERIES = 1e-8


def _phi1(z: np.ndarray) -> np.ndarray:
    """(e^z - 1) / z, 1 at z = 0 (numpy's expm1 keeps the digits of small complex z; the
    series 1 + z / 2 below :data:`PHI1_SERIES`)."""
    z = np.asarray(z, dtype=complex)
    out = 1.0 + z / 2.0
    far = np.abs(z) >= PHI1_SERIES
    out[far] = np.expm1(z[far]) / z[far]
    return out


def _phi_pair(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(e^b - e^a) / (b - a), e^a at b = a: the exponential of the larger real part times
    phi1 of an argument with real part <= 0 (no overflow against underflow)."""
    a, b = np.broadcast_arrays(np.asarray(a, complex), np.asarray(b, complex))
    swap = b.real > a.real
    big, small = np.where(swap, b, a), np.where(swap, a, b)
    return np.exp(big) * _phi1(small - big)


def _block_propagators(lam: np.ndarray, Bb: np.ndarray, fb: np.ndarray, c: np.ndarray,
                       mu: np.ndarray, steps: np.ndarray) -> tuple[np.ndarray, ...]:
    """(Phi, Gu, Gw, g) stacked over ``steps``: exp of the augmented block matrix times h."""
    k, m, J = lam.shape[0], Bb.shape[1], len(mu)
    size = k + m + J + 1
    complex_ = any(np.iscomplexobj(a) for a in (lam, Bb, fb, c, mu))
    aug = np.zeros((size, size), complex if complex_ else float)
    aug[:k, :k] = lam
    aug[:k, k:k + m] = Bb
    aug[:k, k + m:k + m + J] = Bb @ c
    aug[:k, -1] = fb
    aug[k + m:k + m + J, k + m:k + m + J] = np.diag(mu)
    out = np.stack([sla.expm(aug * h) for h in steps])
    return out[:, :k, :k], out[:, :k, k:k + m], out[:, :k, k + m:k + m + J], out[:, :k, -1]


def _march(lam: np.ndarray, blocks: Sequence[tuple[int, int]], Bm: np.ndarray, fm: np.ndarray,
           c: np.ndarray, mu: np.ndarray, t: np.ndarray, U: np.ndarray, r0: np.ndarray
           ) -> np.ndarray:
    """r at the times t of r' = lam r + Bm u + fm + Bm c e^{mu (t - t0)} (lam block diagonal
    on ``blocks``), u held at U[k] over [t[k], t[k+1])."""
    N, n = len(t), lam.shape[0]
    complex_ = any(np.iscomplexobj(a) for a in (lam, Bm, fm, c, mu, r0))
    r = np.zeros((N, n), complex if complex_ else float)
    r[0] = r0
    if N == 1 or n == 0:
        return r
    h = np.diff(t)
    W = np.exp(np.outer(t - t[0], mu))                      # signal states at the samples
    scalars = np.array([s for s, e in blocks if e - s == 1], dtype=int)
    if scalars.size:
        ls, Bs, fs = lam[scalars, scalars], Bm[scalars], fm[scalars]
        z = np.outer(h, ls)
        Z = np.exp(z)
        g = (h[:, None] * _phi1(z)) * (U[:-1] @ Bs.T + fs)
        for j in range(len(mu)):
            g = g + ((Bs @ c[:, j])[None, :] * (W[:-1, j] * h)[:, None]
                     * _phi_pair(z, h[:, None] * mu[j]))
    big = [(s, e) for s, e in blocks if e - s > 1]
    steps, which = np.unique(h, return_inverse=True)
    props = []
    for s, e in big:
        Phi, Gu, Gw, gb = _block_propagators(lam[s:e, s:e], Bm[s:e], fm[s:e], c, mu, steps)
        forced = (np.einsum("kij,kj->ki", Gu[which], U[:-1])
                  + np.einsum("kij,kj->ki", Gw[which], W[:-1]) + gb[which])
        props.append((s, e, Phi, forced))
    for k in range(N - 1):
        if scalars.size:
            r[k + 1, scalars] = Z[k] * r[k, scalars] + g[k]
        for s, e, Phi, forced in props:
            r[k + 1, s:e] = Phi[which[k]] @ r[k, s:e] + forced[k]
    return r


def _discrete(model: LinearModel, t: np.ndarray, x0: np.ndarray, U: np.ndarray,
              signal: Signal | None, notes: list[str]) -> Response:
    dt = model.dt
    N = len(t)
    grid = t[0] + dt * np.arange(N)
    if np.abs(t - grid).max() > DT_RTOL * dt:
        raise ArgumentError("t", f"model '{model.name}' is discrete (dt = {dt!r} s): the "
                                 f"sample times must be t[0] + k dt")
    for key in ("E", "F"):
        mat = getattr(model, key)
        if mat is not None and np.any(mat):
            raise ModelError(f"model '{model.name}' is discrete with input-derivative terms "
                             f"({key}); discretize the continuous model's standard form")
    U = U.copy()
    if signal is not None:
        impulse, _, _ = signal.resolve(model.input_names, float(t[0]))
        if np.any(impulse):
            U[0] += impulse / dt
            notes.append(f"impulse as u[0] = a / dt (dt = {dt:g} s)")
    f0 = np.zeros(model.n_states) if model.f0 is None else model.f0
    x = np.empty((N, model.n_states))
    x[0] = x0
    BU = U @ model.B.T + f0
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(N - 1):
            x[k + 1] = model.A @ x[k] + BU[k]
        y = x @ model.C.T + U @ model.D.T
    _check_finite(model, t, x, y)
    notes.append("difference equation x[k+1] = f0 + A x[k] + B u[k]")
    return _result(model, t, x, y, U, "difference", notes)


__all__ = ["METHODS", "Response", "response"]
