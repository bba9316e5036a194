"""Discrete-time models from continuous ones: zero-order hold and semi-implicit Euler.

A continuous model x' = f0 + A x + B u (x, u deviations from the operating point, f0 the drift
there) becomes x[k+1] = f0_d + A_d x[k] + B_d u[k] over a sample time dt [s]:

- ``"zoh"``: the input held over the step, exact for the linear model. One matrix
  exponential of the augmented matrix [[A, B, f0], [0, 0, 0]] dt gives [[A_d, B_d, f0_d],
  [0, I, 0]] (Van Loan's construction; scipy's Padé ``expm`` with scaling and squaring).
- ``"euler"``: the semi-implicit (symplectic) Euler step of MuJoCo and most simulators, for
  mechanical models in x = [dq; v]: the velocity first, v+ = v + dt v', then the position with
  the new velocity, dq+ = dq + dt (f0_q + A_qq dq + A_qv v+). With A = [[A_qq, A_qv],
  [A_vq, A_vv]] and B = [0; B_v]::

      A_d = [[I + dt A_qq + dt^2 A_qv A_vq, dt A_qv (I + dt A_vv)], [dt A_vq, I + dt A_vv]]
      B_d = [[dt^2 A_qv B_v], [dt B_v]],   f0_d = [[dt f0_q + dt^2 A_qv f0_v], [dt f0_v]]

  At rest (A_qq = 0, A_qv = I) this is MuJoCo's Euler map A_d = I + dt [[dt A_v + [0 I]],
  [A_v]] (A_v the lower block row). MuJoCo integrates joint damping implicitly, (M + dt D)^-1;
  pinlin's step treats every velocity term explicitly, so the two differ by O(dt^2 D / M)
  where the scene has damping.

Output matrices are unchanged (y[k] = C x[k] + D u[k]); the second-order matrices of the
continuous model (M, C_damp, K, Bu) are not carried over, since they describe its derivatives.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import scipy.linalg as sla

from .conditioning import AccuracyWarning
from .exceptions import ArgumentError, ModelError
from .fields import show

METHODS = ("zoh", "euler")
#: A zero-order hold whose estimated relative error (:func:`zoh_rounding`) exceeds this gets
#: an AccuracyWarning (the level at which pinlin's other estimates warn).
WARN_ZOH_ERROR = 1e-6
_EPS = float(np.finfo(float).eps)


FLOAT_MAX = float(np.finfo(float).max)
FLOAT_TINY = float(np.finfo(float).tiny)


def check_step(dt: object, method: object) -> float:
    """``dt`` [s] as a float, and ``method`` one of :data:`METHODS`.

    Raises:
        ArgumentError: ``dt`` not a positive finite number [s], or an unknown method.
    """
    if isinstance(dt, bool | np.bool_) or \
            not isinstance(dt, int | float | np.integer | np.floating) \
            or not 0 < (float(dt) if isinstance(dt, np.floating) else dt) <= FLOAT_MAX:
        # (an int beyond float64 compares exactly; a float32 compared as itself would warn)
        raise ArgumentError("dt", f"expected a sample time > 0 [s], got {show(dt)}")
    if float(dt) < FLOAT_TINY:
        raise ArgumentError("dt", f"{float(dt)!r} s is subnormal (fewer than 53 significant "
                                  "bits: A dt and B dt would lose their digits); expected a "
                                  f"sample time >= {FLOAT_TINY:.3g} s")
    if not isinstance(method, str) or method not in METHODS:
        raise ArgumentError("method", f"expected one of {', '.join(map(repr, METHODS))}, got "
                                      f"{method!r}")
    return float(dt)


def discretize(model, dt: float, method: str = "zoh"):
    """The discrete model of ``model`` (a continuous :class:`~pinlin.LinearModel`) over ``dt``
    [s] by ``method`` (see the module docstring).

    Raises:
        ArgumentError: ``dt`` not a positive finite number [s], an unknown method, a model
            already discrete, or ``"euler"`` on a model whose states are not [q:...; v:...].
        ModelError: the model has input-derivative terms (E): discretize its standard form;
            an output term F u' (held samples have no derivative); or ``dt`` so long
            that a discrete matrix overflows (:func:`refuse_overflow`) or that the
            zero-order hold keeps no correct digit (:func:`warn_if_inaccurate`).
    """
    from .linear_model import LinearModel

    dt = check_step(dt, method)
    if model.dt:
        raise ArgumentError("model", f"model '{model.name}' is already discrete (dt = "
                                     f"{model.dt:g} s)")
    if model.F is not None and np.any(model.F):   # (standard_form keeps F: said first)
        raise ModelError(f"model '{model.name}' has an output term F u' (input derivative): a "
                         "discrete model's inputs are held samples, which have no derivative; "
                         "discretize a model without it, or simulate the continuous one with a "
                         "Signal (pinlin.response)")
    if model.E is not None and np.any(model.E):
        raise ModelError(f"model '{model.name}' has input-derivative terms (E u'): discretize "
                         "model.standard_form() instead, whose state is x - E u")
    dt = float(dt)
    n, m = model.B.shape
    f0 = np.zeros(n) if model.f0 is None else model.f0
    if method == "zoh":   # before the exponential: refuses a dt without a correct digit
        warn_if_inaccurate(model.name, dt, model.A)
    with np.errstate(over="ignore", invalid="ignore"):  # refused below, naming dt
        if method == "zoh":
            aug = np.zeros((n + m + 1, n + m + 1))
            aug[:n, :n] = model.A
            aug[:n, n:n + m] = model.B
            aug[:n, -1] = f0
            phi = sla.expm(aug * dt)
            A_d, B_d, f_d = phi[:n, :n], phi[:n, n:n + m], phi[:n, -1]
        else:
            A_d, B_d, f_d = _semi_implicit_euler(model, dt, f0)
    refuse_overflow(model.name, dt, method, A_d, B_d, f_d)
    return LinearModel(
        A=A_d, B=B_d, C=model.C, D=model.D, state_names=model.state_names,
        input_names=model.input_names, output_names=model.output_names, F=model.F,
        operating_point=model.operating_point, G=model.G, name=model.name,
        info={**model.info, "discretization": {"method": method, "dt": dt}},
        f0=f_d if model.f0 is not None else None, dt=dt)


def zoh_rounding(A: np.ndarray, dt: float) -> float:
    """Estimated relative error of expm(A dt) in double precision: eps ||A||_1 dt. Scaling and
    squaring halves A dt until it is small, then squares s ~ log2 ||A dt|| times, and each
    squaring's rounding, relative to the result, compounds with the growth it undoes: the
    error grows in proportion to ||A dt||, as does the rounding of A dt itself (a phase
    w dt known to eps w dt). An undamped 3.13 rad/s oscillator against its closed form: 0.6 to
    11 times this estimate from dt = 0.01 to 1e13 s. ``A``: one matrix or a stack (the
    largest point's)."""
    if A.size == 0:
        return 0.0
    norm = float(np.abs(A).sum(axis=-2).max())     # max column sum: ||A||_1, of every point
    return _EPS * norm * dt


def warn_if_inaccurate(name: str, dt: float, A: np.ndarray, advice: str = "use a shorter dt",
                       what: str = "a zero-order hold over dt") -> float:
    """AccuracyWarning when the zero-order hold over ``dt`` [s] of ``A`` may lose more than
    WARN_ZOH_ERROR (relative) to rounding: the sample time is ~1e10 times the model's fastest
    time scale or more, and the discrete matrices keep few correct digits; a ModelError
    where the estimate reaches 1, no correct digit left (an undamped double pendulum over
    1e15 s came back with |eig(A_d)| = 0.55 for 1, over 1e30 s with A_d = 0). Neither where
    every mode decays below rounding within the step (max Re lambda dt < ln eps, every point
    of a stack): exp(A dt) is then 0 to rounding and the hold's B_d the steady state
    -A^-1 B, both computed to working precision (a damped pendulum over 1e15 s). ``what``
    names the step in the message and ``advice`` ends it. Returns the estimate it warned
    with, 0.0 where it did not warn."""
    error = zoh_rounding(A, dt)
    if error <= WARN_ZOH_ERROR or not _survives(A, dt):
        return 0.0
    if error >= 1.0:
        raise ModelError(f"model '{name}': {what} = {dt:g} s spans ||A|| dt = "
                         f"{error / _EPS:.2e} of the model's fastest time scale; rounding in "
                         f"the matrix exponential reaches {error:.1e} (relative), no correct "
                         f"digit is left; {advice}")
    warnings.warn(AccuracyWarning(
        f"model '{name}': {what} = {dt:g} s spans ||A|| dt = {error / _EPS:.2e} of the "
        f"model's fastest time scale; rounding in the matrix exponential may reach "
        f"{error:.1e} (relative) of the discrete matrices; {advice}",
        1.0 / max(error, _EPS)), stacklevel=3)
    return error


def _survives(A: np.ndarray, dt: float) -> bool:
    """Whether some mode of ``A`` (one matrix, or a stack) keeps more than eps of itself over
    ``dt`` [s]: max Re lambda dt > ln eps (a rigid or undamped mode always does)."""
    if A.size == 0:
        return False
    with np.errstate(over="ignore", invalid="ignore"):
        growth = float(np.linalg.eigvals(A).real.max()) * dt
    return not growth < math.log(_EPS)    # NaN (no eigenvalues computed) survives


def refuse_overflow(name: str, dt: float, method: str, A_d: np.ndarray, B_d: np.ndarray,
                    f_d: np.ndarray) -> None:
    """ModelError when the discrete matrices (a model's, or stacks with points first) are not
    finite: dt is too long for the model's fastest growing or fastest mode (exp(lambda dt)
    overflows, or Euler's powers of dt do), naming dt and, for stacks, the first point."""
    for label, arr in (("A", A_d), ("B", B_d), ("f0", f_d)):
        bad = ~np.isfinite(arr)
        if not bad.any():
            continue
        where = ""
        if arr.ndim == 3 or (arr.ndim == 2 and label == "f0"):
            where = f" at trajectory point {int(np.argwhere(bad)[0][0])}"
        raise ModelError(f"model '{name}': discretizing over dt = {dt:g} s ('{method}') "
                         f"overflows: the discrete {label} has NaN or inf{where} (exp(lambda "
                         "dt) of a growing mode, or a power of dt, beyond float range); use "
                         "a shorter dt")


def check_mechanical(name: str, state_names: tuple[str, ...], B: np.ndarray) -> None:
    """Refuse the semi-implicit Euler step where it does not apply: states other than
    [q:...; v:...] (n/2 each), or inputs acting on the positions (``B``: one matrix or a stack
    with points first).

    Raises:
        ArgumentError: naming the model.
    """
    n = len(state_names)
    nv = n // 2
    mechanical = (n % 2 == 0 and all(s.startswith("q:") for s in state_names[:nv])
                  and all(s.startswith("v:") for s in state_names[nv:]))
    if not mechanical or np.any(B[..., :nv, :]):
        raise ArgumentError("method", f"'euler' steps velocities then positions: model "
                                      f"'{name}' needs states [q:...; v:...] and inputs "
                                      "acting on the velocities only; use 'zoh'")


def _semi_implicit_euler(model, dt: float, f0: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    check_mechanical(model.name, model.state_names, model.B)
    nv = model.A.shape[0] // 2
    A = model.A
    Aqq, Aqv, Avq, Avv = A[:nv, :nv], A[:nv, nv:], A[nv:, :nv], A[nv:, nv:]
    Bv = model.B[nv:]
    eye = np.eye(nv)
    A_d = np.empty_like(A)
    A_d[:nv, :nv] = eye + dt * Aqq + dt * dt * (Aqv @ Avq)
    A_d[:nv, nv:] = dt * (Aqv @ (eye + dt * Avv))
    A_d[nv:, :nv] = dt * Avq
    A_d[nv:, nv:] = eye + dt * Avv
    B_d = np.vstack([dt * dt * (Aqv @ Bv), dt * Bv])
    f_d = np.concatenate([dt * f0[:nv] + dt * dt * (Aqv @ f0[nv:]), dt * f0[nv:]])
    return A_d, B_d, f_d


#: Points per block of the stacked zero-order hold (bounds its temporary memory).
ZOH_BLOCK = 128


def stacked_zoh(A: np.ndarray, B: np.ndarray, f0: np.ndarray, dt: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Van Loan's augmented exponential, expm([[A, B, f0], [0, 0, 0]] dt), for stacks of
    models (points first), in blocks of :data:`ZOH_BLOCK` points."""
    N, n, m = B.shape
    A_d, B_d, f_d = np.empty_like(A), np.empty_like(B), np.empty_like(f0)
    for lo in range(0, N, ZOH_BLOCK):
        hi = min(N, lo + ZOH_BLOCK)
        aug = np.zeros((hi - lo, n + m + 1, n + m + 1))
        aug[:, :n, :n] = A[lo:hi]
        aug[:, :n, n:n + m] = B[lo:hi]
        aug[:, :n, -1] = f0[lo:hi]
        phi = sla.expm(aug * dt)
        A_d[lo:hi], B_d[lo:hi], f_d[lo:hi] = phi[:, :n, :n], phi[:, :n, n:n + m], phi[:, :n, -1]
    return A_d, B_d, f_d


def stacked_euler(A: np.ndarray, B: np.ndarray, f0: np.ndarray, dt: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The semi-implicit Euler map of :func:`discretize`, for stacks of models (points first)."""
    nv = A.shape[1] // 2
    Aqq, Aqv, Avq, Avv = A[:, :nv, :nv], A[:, :nv, nv:], A[:, nv:, :nv], A[:, nv:, nv:]
    Bv = B[:, nv:]
    eye = np.eye(nv)
    A_d = np.empty_like(A)
    A_d[:, :nv, :nv] = eye + dt * Aqq + dt * dt * (Aqv @ Avq)
    A_d[:, :nv, nv:] = dt * (Aqv @ (eye + dt * Avv))
    A_d[:, nv:, :nv] = dt * Avq
    A_d[:, nv:, nv:] = eye + dt * Avv
    B_d = np.concatenate([dt * dt * (Aqv @ Bv), dt * Bv], axis=1)
    f_d = np.concatenate([dt * f0[:, :nv] + dt * dt * (Aqv @ f0[:, nv:, None])[..., 0],
                          dt * f0[:, nv:]], axis=1)
    return A_d, B_d, f_d


__all__ = ["METHODS", "ZOH_BLOCK", "check_mechanical", "discretize", "stacked_euler",
           "stacked_zoh"]
