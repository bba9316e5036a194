"""The linear model under state feedback: u = -K x + r.

With x' = A x + B u (+ f0) and y = C x + D u, the loop u = -K x + r (K: nu x n, r the new
input, what is added to the feedback) gives::

    x' = (A - B K) x + B r (+ f0),    y = (C - D K) x + D r

the same algebra for a discrete model (x[k+1]). A mechanical model keeps its second-order form
M v' + C_damp v + K q = Bu u with the gain split as K = [K_q, K_v]: the loop adds Bu K_q to
the stiffness and Bu K_v to the damping (:meth:`pinlin.LinearModel.closed_loop`), so that
:func:`pinlin.modal` and the modal energies read the closed loop's matrices. Its modes are then
the closed loop's: a gain that is not symmetric (most are) sends modal to the general
eigensolver.

The nonlinear counterpart is ``pinlin.simulate(scene, ..., feedback=K)``, which applies the
same law to the scene's nonlinear dynamics (:mod:`pinlin.simulation_inputs`), and
``pinlin.validity(scene, feedback=K)``, how far the closed loop's linear model holds.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .arrays import real_array
from .exceptions import ArgumentError, ModelError

if TYPE_CHECKING:
    from .linear_model import LinearModel


def gain_matrix(K: object, n_inputs: int, n_states: int, name: str = "K") -> np.ndarray:
    """``K`` as a finite (n_inputs x n_states) float array (a vector when n_inputs is 1).

    Raises:
        ArgumentError: naming ``name``: not real numbers, another shape, NaN or inf.
    """
    what = f"a gain matrix of shape ({n_inputs}, {n_states}) (inputs x states: u = -K x)"
    gain = real_array(K, name, what)
    given = gain.shape
    if gain.ndim == 1 and n_inputs == 1:
        gain = gain[None, :]
    if gain.shape != (n_inputs, n_states):
        raise ArgumentError(name, f"expected {what}, got shape {given}")
    if not np.all(np.isfinite(gain)):
        raise ArgumentError(name, "the gain matrix contains NaN or inf")
    return gain


def closed_loop(model: LinearModel, K: object) -> LinearModel:
    """``model`` under u = -K x + r (module docstring): A - B K, C - D K; r takes the inputs'
    names. Second-order matrices follow for a model in x = [dq; v]; a model in other states
    (canonical [p; q]) drops them (its A is the closed loop's).

    Raises:
        ArgumentError: K not a finite (nu x n) gain; a model without inputs.
        ModelError: input-derivative terms E or F (close the loop on
            :meth:`~pinlin.LinearModel.standard_form`).
    """
    from .linear_model import LinearModel

    n, m = model.n_states, model.n_inputs
    if m == 0:
        raise ArgumentError("K", f"model '{model.name}' has no inputs to feed back to")
    gain = gain_matrix(K, m, n)
    if (model.E is not None and np.any(model.E)) or (model.F is not None and np.any(model.F)):
        raise ModelError(f"model '{model.name}' has input-derivative terms (E or F): the loop "
                         "would feed back x' as well; close it on model.standard_form() (F: "
                         "a loop through u' is not a state feedback)")
    second: dict[str, np.ndarray | None] = dict.fromkeys(("M", "C_damp", "K", "Bu"))
    nv = n // 2
    if model.M is not None and all(s.startswith("q:") for s in model.state_names[:nv]) and \
            all(s.startswith("v:") for s in model.state_names[nv:]):
        Kq, Kv = gain[:, :nv], gain[:, nv:]
        second = {"M": model.M, "C_damp": model.C_damp + model.Bu @ Kv,
                  "K": model.K + model.Bu @ Kq, "Bu": model.Bu}
    info = {**model.info, "closed_loop": f"u = -K x + r, K of shape {gain.shape}"}
    return LinearModel(model.A - model.B @ gain, model.B, model.C - model.D @ gain, model.D,
                       model.state_names, model.input_names, model.output_names,
                       G=model.G, operating_point=model.operating_point,
                       name=model.name, info=info, f0=model.f0, dt=model.dt, **second)


__all__ = ["closed_loop", "gain_matrix"]
