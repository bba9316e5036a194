"""The linear model under state feedback: u = -K x + r.

With x' = A x + B u (+ f0) and y = C x + D u, the loop u = -K x + r (K: nu x n, r the new
input, what is added to the feedback) gives::

    x' = (A - B K) x + B r (+ f0),    y = (C - D K) x + D r

the same algebra for a discrete model (x[k+1]). A mechanical model keeps its second-order form
M v' + C_damp v + K q = Bu u with the gain split as K = [K_q, K_v]: the loop adds Bu K_q to
the stiffness and Bu K_v to the damping (:meth:`pinlin.LinearModel.closed_loop`), so that
:func:`pinlin.modal` and the modal energies read the closed loop's matrices. Its modes are then
the closed loop's; modal takes the symmetric (K, M) path only where the loop keeps the model
undamped and symmetric (K_v = 0 and K + Bu K_q symmetric), the general one otherwise. A
discrete model's A_d - B_d K has no such second-order form: it has none to keep.

The nonlinear counterpart is ``pinlin.simulate(scene, ..., feedback=K)``, which applies the
same law to the scene's nonlinear dynamics (:mod:`pinlin.simulation_inputs`), and
``pinlin.validity(scene, feedback=K)``, how far the closed loop's linear model holds.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from .arrays import real_array
from .exceptions import ArgumentError, ModelError

if TYPE_CHECKING:
    from .linear_model import LinearModel
    from .operating_point import OperatingPoint


#: Largest gain entry taken (as :data:`pinlin.modal_input.ENTRY_LIMIT` for a model's matrices): a
#: 1e155 velocity gain sent the stiff integrator's Jacobian to inf and out with a traceback.
GAIN_LIMIT = 1e150


def is_pair(K: object) -> bool:
    """Whether ``K`` is a pair (gain, the LinearModel it was designed on)."""
    from .linear_model import LinearModel

    return isinstance(K, tuple) and len(K) == 2 and isinstance(K[1], LinearModel)


def gain_matrix(K: object, n_inputs: int, widths: Sequence[int], name: str = "K"
                ) -> np.ndarray:
    """``K`` as a finite (n_inputs x w) float array, w one of ``widths`` (a vector when
    n_inputs is 1).

    Raises:
        ArgumentError: naming ``name``: not real numbers, another shape, NaN or inf.
    """
    shapes = " or ".join(f"({n_inputs}, {w})" for w in sorted(set(widths)))
    what = f"a gain matrix of shape {shapes} (inputs x states: u = -K x)"
    gain = real_array(K, name, what + ", or a pair (K, model)")
    given = gain.shape
    if gain.ndim == 1 and n_inputs == 1:
        gain = gain[None, :]
    if gain.ndim != 2 or gain.shape[0] != n_inputs or gain.shape[1] not in widths:
        raise ArgumentError(name, f"expected {what}, got shape {given}")
    if not np.all(np.isfinite(gain)):
        where = [int(i) for i in np.argwhere(~np.isfinite(gain))[0]]
        raise ArgumentError(name, f"the gain matrix contains NaN or inf (the first at "
                                  f"{where}: {gain[tuple(where)]})")
    largest = float(np.abs(gain).max(initial=0.0))
    if largest > GAIN_LIMIT:
        raise ArgumentError(name, f"the gain matrix has entries beyond {GAIN_LIMIT:g} "
                                  f"({largest:.3g}): K x and the closed loop's products overflow "
                                  "float64")
    return gain


def _listed(names: Sequence[str]) -> str:
    return ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")


def same_point(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether a gain's design point ``a`` (q or v) is ``b``: same size, equal to 1e-9 of b's
    largest entry (or 1e-9 absolute; a point printed to 17 digits, or recomputed by the same
    solver, passes; an upright pendulum's q = pi against the hanging 0 does not)."""
    return a.shape == b.shape and bool(np.abs(a - b).max(initial=0.0) <= 1e-9 * max(
        1.0, float(np.abs(b).max(initial=0.0))))


def designed_gain(K: object, n_inputs: int, widths: Sequence[int],
                  states: Sequence[tuple[str, ...]], point: OperatingPoint | None,
                  name: str = "K") -> np.ndarray:
    """:func:`gain_matrix` of ``K``, or of a pair (K, model) whose model must have one of the
    ``states`` (name tuples), as many states as K has columns, and the operating point
    ``point`` (q and v to 1e-9 relative): a gain designed about another point (an upright
    pendulum's used about the hanging one) or on other states (a canonical model's [p; q]) is
    refused.

    Raises:
        ArgumentError: naming ``name`` and what differs.
    """
    if not is_pair(K):
        return gain_matrix(K, n_inputs, widths, name)
    K, designed = K
    own = tuple(designed.state_names)
    if own not in [tuple(s) for s in states]:
        raise ArgumentError(name, f"the gain was designed on model '{designed.name}', whose "
                                  f"states ({_listed(own)}) are not the ones fed back "
                                  f"({_listed(states[0])}); design it on the independent or "
                                  "penalty model with the partitioned basis (pinlin.linearize's "
                                  "default)")
    gain = gain_matrix(K, n_inputs, [designed.n_states], name)
    there = designed.operating_point
    if point is not None and there is not None:
        for what, a, b in (("q", there.q, point.q), ("v", there.v, point.v)):
            if not same_point(a, b):
                raise ArgumentError(name, f"the gain was designed about another point: its "
                                          f"model's {what} = {np.round(a, 6).tolist()!s:.80}, "
                                          f"this one's {np.round(b, 6).tolist()!s:.80}")
    return gain


def model_gain(model: LinearModel, K: object, name: str = "K"
               ) -> tuple[np.ndarray, np.ndarray]:
    """(the gain on ``model``'s states, the gain as given): ``K`` of its size, a pair (K, the
    model K was designed on: states and point checked, :func:`designed_gain`), or for a
    mechanism's model in [dz; dz'] a gain over all 2 nv coordinates, K = [K_q, K_v], whose
    gain on [dz; dz'] is [K_q R, K_v R] (R = ``info["R"]``, the nullspace basis: dq = R dz
    and v = R dz' to first order, the same law to the linear model's order).

    Raises:
        ArgumentError: naming ``name``: a model without inputs, a pair's other states or
            point, a bad gain.
    """
    if model.n_inputs == 0:
        raise ArgumentError(name, f"model '{model.name}' has no inputs to feed back to")
    R = model.info.get("R")
    R = None if R is None else np.asarray(R, dtype=float)
    widths = [model.n_states]
    if R is not None and R.shape[0] != R.shape[1] and model.n_states == 2 * R.shape[1]:
        widths.append(2 * R.shape[0])
    gain = designed_gain(K, model.n_inputs, widths, [model.state_names],
                         model.operating_point, name)
    if gain.shape[1] == model.n_states:
        return gain, gain
    nv = R.shape[0]
    return np.hstack([gain[:, :nv] @ R, gain[:, nv:] @ R]), gain


def closed_loop(model: LinearModel, K: object) -> LinearModel:
    """``model`` under u = -K x + r (module docstring): A - B K, C - D K; r takes the inputs'
    names. ``K``: the gain, or a pair (K, the model it was designed on: states checked).
    ``info["closed_loop_gains"]`` lists every gain applied. Second-order matrices follow for
    a continuous model in x = [dq; v]; a model in other states (canonical [p; q]) or a
    discrete one drops them (its A is the closed loop's).

    Raises:
        ArgumentError: K not a finite (nu x n) gain; a model without inputs.
        ModelError: input-derivative terms E or F (close the loop on
            :meth:`~pinlin.LinearModel.standard_form`).
    """
    from .linear_model import LinearModel

    n = model.n_states
    gain = model_gain(model, K)[0]
    if model.F is not None and np.any(model.F):
        raise ModelError(f"model '{model.name}' has an output term F u' (the derivative of "
                         "the input): with u = -K x + r the outputs would read x' and r'; "
                         "closed_loop takes models without it")
    if model.E is not None and np.any(model.E):
        raise ModelError(f"model '{model.name}' has input-derivative terms E (x' = A x + B u + "
                         "E u'): the loop would feed back x' as well; model.standard_form() "
                         "removes them in the state x - E u, on which a gain then acts")
    second: dict[str, np.ndarray | None] = dict.fromkeys(("M", "C_damp", "K", "Bu"))
    nv = n // 2
    info = dict(model.info)
    if model.M is not None and not model.dt and \
            all(s.startswith("q:") for s in model.state_names[:nv]) and \
            all(s.startswith("v:") for s in model.state_names[nv:]):
        Kq, Kv = gain[:, :nv], gain[:, nv:]
        second = {"M": model.M, "C_damp": model.C_damp + model.Bu @ Kv,
                  "K": model.K + model.Bu @ Kq, "Bu": model.Bu}
        info["velocity_terms"] = bool(info.get("velocity_terms") or np.any(Kv))
    loops = [*info.get("closed_loop_gains", []), gain.tolist()]
    info["closed_loop"] = (f"u = -K x + r, K of shape {gain.shape}"
                           + (f" (closed {len(loops)} times)" if len(loops) > 1 else ""))
    info["closed_loop_gains"] = loops   # each K applied, in order
    return LinearModel(model.A - model.B @ gain, model.B, model.C - model.D @ gain, model.D,
                       model.state_names, model.input_names, model.output_names,
                       G=model.G, operating_point=model.operating_point,
                       name=model.name, info=info, f0=model.f0, dt=model.dt, **second)


__all__ = ["closed_loop", "designed_gain", "gain_matrix", "is_pair", "model_gain"]
