"""Numerical derivatives (chapter 9.2) of a mechanism's model at a moving state.

The independent-coordinate model of :func:`pinlin.formulations.motion.linearize_moving` is
built at the state (q0, v0, a0, lam0) from

- K = dH/dq (lam held, q moved on the manifold by ``pin.integrate``), C = dH/dv, Bu = -dH/du
  and M, with H = rnea(q, v, a0) - tau_spring(q) + D v - Phi_q(q)^T lam0 - S u: the fd3/fd5
  backend of :func:`pinlin.derivatives.second_order_terms`, as for every other model;
- c_q = d(Phi_q a0 + gamma)/dq and c_v = d gamma/dv, the derivatives of the constraint
  acceleration Phi_q a + gamma(q, v) (a held), by the same formula and steps (gamma is
  quadratic in v: central differences give c_v exactly but for rounding);

then the same solve as the analytic model::

    [[M, -G^T], [G, 0]] [F; L] = [[-K, -C, Bu], [-c_q, -c_v, 0]]   (G: independent rows)
    A = [[0, I], [(F_q R + F_v W)_z, (F_v R)_z]],   B = [[0], [(F_u)_z]],
    W = -Phi_d^-1 (c_v / 2) R   (Phi_qq[v0, .] = c_v / 2).

The error estimate (``estimate_error``) is built as for the other numerical models
(:func:`pinlin.derivatives.error_estimate`): the companion formula's K, C, c_q, c_v pushed
through the same solve (truncation), plus the measured rounding noise of H and of the
constraint acceleration (:func:`pinlin.derivatives.computational_noise`) pushed through the
rows z of the KKT inverse and through R and W.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from ..assembly import Partition, projection
from ..derivatives import (
    _PLANS,
    _difference,
    computational_noise,
    entry_noise,
    error_estimate,
    propagated_noise,
    resolve_steps,
    second_order_terms,
)
from ..operating_point import OperatingPoint


def numerical_moving(system, op: OperatingPoint, part: Partition, G: np.ndarray, backend: str,
                     step: float | Mapping[str, float] | None, estimate: bool
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                np.ndarray, dict[str, Any]]:
    """(A, B, f0, R, W, Bu, info) of the moving model with ``backend`` ("fd3" or "fd5")
    derivatives (module docstring); ``info``: the steps and, with ``estimate``, the error
    estimate (``error_estimate``, ``error_estimate_rounding``)."""
    from .motion import _kkt, kkt_model

    cons, model = system.constraints, system.model
    rows, z, dep = part.rows, part.independent, part.dependent
    nv = system.nv
    steps = resolve_steps(backend, step)
    terms = second_order_terms(system, op, backend, step, estimate)
    Bu = terms.Bu if terms.Bu is not None else system.input_matrix

    def c_of_q(d: np.ndarray) -> np.ndarray:
        q = pin.integrate(model, op.q, d)
        return cons.jacobian(q)[rows] @ op.a + cons.bias_acceleration(q, op.v)[rows]

    def c_of_v(d: np.ndarray) -> np.ndarray:
        return cons.bias_acceleration(op.q, op.v + d)[rows]

    c_q, c_q_alt, scale_q = _difference(c_of_q, nv, steps["q"], backend, estimate)
    c_v, c_v_alt, scale_v = _difference(c_of_v, nv, steps["v"], backend, estimate)
    kkt = _kkt(terms.M, G)
    R = projection(G, part)

    def build(K: np.ndarray, C: np.ndarray | None, cq: np.ndarray, cv: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return kkt_model(kkt, K, C, Bu, cq, cv, 0.5 * cv, G, part, R)  # Phi_qq[v0] = c_v / 2

    A, B, W, F_v = build(terms.K, terms.C, c_q, c_v)
    info: dict[str, Any] = {"step": dict(steps)}
    if estimate:
        weight = _PLANS[backend][2]
        K_est, C_est = terms.alt
        A_alt = build(K_est, C_est, c_q + weight * (c_q_alt - c_q),
                      c_v + weight * (c_v_alt - c_v))[0]
        # Rounding: each differenced entry's noise, through the rows z of KKT^-1 (the
        # accelerations A reads) and the projections R (positions) and [R, W] (velocities);
        # c_v's also through W = -Phi_d^-1 (c_v / 2) R, which A reads as F_v W.
        inverse = np.linalg.inv(kkt)[z]
        sigma_K, sigma_C = terms.rounding
        sigma_cq = entry_noise(computational_noise(c_of_q, nv, steps["q"]), scale_q, backend,
                               steps["q"])
        sigma_cv = entry_noise(computational_noise(c_of_v, nv, steps["v"]), scale_v, backend,
                               steps["v"])
        RW = np.hstack([R, W])
        noise = (propagated_noise(inverse[:, :nv], sigma_K, R)
                 + propagated_noise(inverse[:, :nv], sigma_C, RW)
                 + propagated_noise(inverse[:, nv:], sigma_cq, R)
                 + propagated_noise(inverse[:, nv:], sigma_cv, RW))
        if len(dep):
            through_w = -0.5 * np.linalg.solve(G[:, dep].T, F_v[z][:, dep].T).T
            noise += propagated_noise(through_w, sigma_cv, R)
        info.update(error_estimate(A, A_alt, noise))
    return A, B, np.concatenate([op.v[z], op.a[z]]), R, W, Bu, info


__all__ = ["numerical_moving"]
