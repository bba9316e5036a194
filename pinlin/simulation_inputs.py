"""The inputs of :func:`pinlin.simulate`: u = u0 + du(t) + du_fb(t, x).

- du(t), open loop: none, a callable of the time, samples held from t_k to t_(k+1)
  (zero-order hold) or a :class:`~pinlin.Signal` of steps and sinusoids.
- du_fb(t, x), state feedback: a gain matrix K (du = -K x, the sign of python-control's
  ``lqr`` and ``place``) or a callable of the time and the state. x is the state of the linear
  model about the operating point simulated, [difference(q0, q); v - v0] of the nonlinear
  state at that instant: so that a controller designed on ``pinlin.linearize(scene)`` (an LQR,
  a pole placement) closes the loop around the nonlinear robot unchanged. For a mechanism the
  model's state is [dz; dz'] (2 nz, its independent coordinates); a gain over all 2 nv
  coordinates (a dependent-coordinate model's) is taken too.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .arrays import real_array
from .closed_loop import designed_gain
from .exceptions import ArgumentError, PinlinError
from .fields import show
from .operating_point import OperatingPoint
from .signals import Signal

#: Feedback: (t [s], x) -> du [N*m or N].
Law = Callable[[float, np.ndarray], np.ndarray]


class Inputs:
    """u0 + du(t) (+ feedback once :meth:`close_loop` is called).

    Attributes:
        u0: The operating point's inputs [N*m or N].
        samples: (N, nu) held samples, or None.
        function: du(t), or None.
        breaks: Times where a held sample changes [s] (the integrator restarts there).
        feedback: du_fb(t, x_full) with x_full the 2 nv state (the law's own columns picked),
            or None (open loop).
        feedback_note: What the feedback is, for ``Simulation.info["feedback"]``.
    """

    def __init__(self, u: object, t: np.ndarray, u0: np.ndarray,
                 names: tuple[str, ...] = ()) -> None:
        nu = u0.size
        self.u0, self.t = u0, t
        self.samples: np.ndarray | None = None
        self.function: Callable[[float], np.ndarray] | None = None
        self.feedback: Law | None = None
        self.feedback_note = "none"
        self.breaks = np.zeros(0)
        if u is None:
            return
        if isinstance(u, Signal):   # steps and sinusoids: u(t) = Re sum_j c_j e^{mu_j t}
            impulse, c, mu = u.resolve(names, 0.0)
            if np.any(impulse):
                raise ArgumentError("u", "an impulse is a jump of the velocities: give it "
                                         "in the initial deviation dx0 (its velocity part "
                                         "M^-1 B a), or use pinlin.response for the linear "
                                         "model")
            self.function = lambda tk: (np.exp(tk * mu) @ c.T).real
            return
        if callable(u):
            self.function = u
            self.at(float(t[0]))  # checks the shape once
            return
        samples = real_array(u, "u", f"a callable u(t) -> ({nu},) or an array of real "
                                     f"numbers of shape ({t.size}, {nu})")
        if samples.ndim == 1 and nu == 1:
            samples = samples[:, None]
        if samples.shape != (t.size, nu):
            raise ArgumentError("u", f"expected an array of shape (N, nu) = ({t.size}, {nu}) "
                                     f"(one row per time), got shape {samples.shape}")
        if not np.all(np.isfinite(samples)):
            raise ArgumentError("u", "contains NaN or inf")
        self.samples = samples
        change = np.flatnonzero(np.any(samples[1:] != samples[:-1], axis=1)) + 1
        self.breaks = t[change]

    def at(self, t: float) -> np.ndarray:
        """u0 + du(t) [N*m or N] (samples: the one held at t), feedback left out."""
        if self.samples is not None:
            k = max(int(np.searchsorted(self.t, t, side="right")) - 1, 0)
            return self.u0 + self.samples[k]
        if self.function is None:
            return self.u0
        du = real_array(self.function(t), "u", f"u(t) to return {self.u0.size} real "
                                               f"numbers (at t = {t:g} s)").reshape(-1)
        if du.size != self.u0.size or not np.all(np.isfinite(du)):
            raise ArgumentError("u", f"u(t) must return {self.u0.size} finite numbers, got "
                                     f"{show(du)} at t = {t:g} s")
        return self.u0 + du

    def close_loop(self, feedback: object, columns: np.ndarray, nv: int, x0: np.ndarray,
                   state_names: tuple[str, ...], point: OperatingPoint) -> None:
        """Add the state feedback ``feedback`` (see the module docstring): a gain K of shape
        (nu, 2 nz) acting on the model's state x[cols] (``columns``: the coordinates z of a
        mechanism, all nv for an open chain) or (nu, 2 nv) on the whole x; a pair (K, model)
        whose model's states and operating point are checked against those and ``point``
        (:func:`pinlin.closed_loop.designed_gain`); or a callable feedback(t, x[cols]) ->
        (nu,). ``x0``: the initial 2 nv state, on which a callable is tried once (its output
        checked); ``state_names``: the names of x's 2 nv entries."""
        nu, nz = self.u0.size, columns.size
        if nu == 0:
            raise ArgumentError("feedback", "the scene has no inputs to feed back to (its "
                                            "inputs.actuated names no joint)")
        picked = np.concatenate([columns, nv + columns])
        if callable(feedback):
            self.feedback = _law(feedback, picked, nu)
            self.feedback_note = "a callable of (t, x)"
            try:
                self.feedback(float(self.t[0]), x0)
            except PinlinError:
                raise
            except Exception as exc:   # a wrong signature, x indexed beyond its size, ...
                size = f"2 nz = {picked.size}" if nz < nv else f"2 nv = {picked.size}"
                raise ArgumentError("feedback", f"expected a function feedback(t, x) of the time "
                                                f"[s] and the state ({size} numbers) returning "
                                                f"{nu} inputs; calling it so raised "
                                                f"{type(exc).__name__}: {str(exc):.120}"
                                                ) from exc
            return
        states = [state_names, tuple(state_names[k] for k in picked)]
        gain = designed_gain(feedback, nu, [2 * nz, 2 * nv], states, point, "feedback")
        self.feedback_note = f"du = -K x, K of shape {gain.shape}"
        if gain.shape[1] == 2 * nv:
            self.feedback = lambda t, x: -(gain @ x)
        else:
            self.feedback = lambda t, x: -(gain @ x[picked])

    def total(self, t: float, x: Callable[[], np.ndarray], u: np.ndarray | None = None
              ) -> np.ndarray:
        """u0 + du(t) + du_fb(t, x) [N*m or N] (``u``: u0 + du(t) when the caller holds it;
        ``x``: a function giving the 2 nv state, called only with feedback)."""
        base = self.at(t) if u is None else u
        if self.feedback is None:
            return base
        return base + self.feedback(t, x())


def _law(law: Callable, picked: np.ndarray, nu: int) -> Law:
    """``law(t, x[picked])`` with its output checked: nu finite real numbers [N*m or N]."""

    def closed(t: float, x: np.ndarray) -> np.ndarray:
        du = real_array(law(t, x[picked]), "feedback",
                        f"feedback(t, x) to return {nu} real numbers (at t = {t:g} s)"
                        ).reshape(-1)
        if du.size != nu or not np.all(np.isfinite(du)):
            raise ArgumentError("feedback", f"feedback(t, x) must return {nu} finite numbers, "
                                            f"got {du!r:.80} at t = {t:g} s")
        return du

    return closed


__all__ = ["Inputs", "Law"]
