"""Independent coordinates (chapter 9.1.1) for open chains, where R = I and z = q.

With H_z = K, H_z' = C and H_z'' = M (eqs. 9.8-9.11 with R = I), eq. 9.57 in Rowell's form is::

    x = [dq; v],   A = [[0, I], [-M^-1 K, -M^-1 C]],   B = [[0], [M^-1 S]]

M^-1 comes from ``pin.computeMinverse`` (one recursion, no factorization), so one matrix
product gives the whole lower block row. At v = 0 the upper block row is exactly [0 I] also on
Lie groups (d/dt of ``difference(q0, q)`` equals v at q = q0); at a moving state the Lie-group
joints add -1/2 ad(v0) to its first block (:mod:`pinlin.chart`), and the model is affine,
x' = f0 + A x + B u with f0 = [v0; a0].
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pinocchio as pin

from ..arrays import read_only
from ..chart import kinematic_block
from ..conditioning import trace_condition, warn_if_ill_conditioned
from ..derivatives import error_estimate, propagated_noise, second_order_terms
from ..linear_model import LinearModel
from ..loop_kernels import frame_jacobian
from ..operating_point import OperatingPoint
from ..system import System


def output_matrices(system: System, op: OperatingPoint) -> tuple[np.ndarray, np.ndarray,
                                                                  tuple[str, ...], np.ndarray]:
    """C, D, output names and output values y0 at the operating point.

    Joint outputs read the state; frame outputs are world positions whose Jacobian is the linear
    part of the LOCAL_WORLD_ALIGNED frame Jacobian. y0 holds frame positions [m] and, for joint
    coordinates, ``difference(neutral, q0)`` (the joint value for 1-DoF joints) and v0.
    """
    nv, nu = system.nv, len(system.actuated)
    spec = system.outputs
    if spec is None:
        return (*system.state_output, system.state_names, np.zeros(2 * nv))
    p = len(spec.names)
    C = np.zeros((p, 2 * nv))
    y0 = np.zeros(p)
    x0 = np.concatenate([pin.difference(system.model, pin.neutral(system.model), op.q), op.v])
    for row, col in spec.state_rows:
        C[row, col] = 1.0
        y0[row] = x0[col]
    if spec.frames:
        model, data = system.kin_model, system.kin_data
        pin.computeJointJacobians(model, data, system.kin_q(op.q))
        pin.updateFramePlacements(model, data)
        for row, fid in spec.frames:
            J = frame_jacobian(model, data, fid)[:, system.kin_columns]
            C[row:row + 3, :nv] = J[:3]
            y0[row:row + 3] = data.oMf[fid].translation
    return C, np.zeros((p, nu)), spec.names, y0


def output_stack(system: System, Q: np.ndarray, V: np.ndarray, frame_jacobians: np.ndarray,
                 frame_positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`output_matrices`' C and y0 at N points (N, p, 2nv) and (N, p) from the output
    frames' LOCAL_WORLD_ALIGNED Jacobians (N, F, 6, nv) and positions (N, F, 3) [m] there, in
    the order of ``system.outputs.frames`` (the same numbers, computed by the caller's own
    kinematics pass)."""
    spec = system.outputs
    N, nv = V.shape
    C = np.zeros((N, len(spec.names), 2 * nv))
    y = np.zeros((N, len(spec.names)))
    if spec.state_rows:
        model, neutral = system.model, pin.neutral(system.model)
        X = np.concatenate([np.array([pin.difference(model, neutral, q) for q in Q]), V],
                           axis=1)
        for row, col in spec.state_rows:
            C[:, row, col] = 1.0
            y[:, row] = X[:, col]
    for i, (row, _) in enumerate(spec.frames):
        C[:, row:row + 3, :nv] = frame_jacobians[:, i, :3]
        y[:, row:row + 3] = frame_positions[:, i]
    return C, y


def linearize_independent(system: System, op: OperatingPoint, *, derivatives: str = "analytic",
                          step: float | Mapping[str, float] | None = None,
                          mass_inverse: np.ndarray | None = None, estimate_error: bool = True,
                          check_mass: bool | None = None) -> LinearModel:
    """Linear model of an open chain about ``op`` in independent (joint) coordinates.

    ``mass_inverse`` is M(q0)^-1 when the caller has it already; ``check_mass`` not None says
    it is unchecked (:meth:`System.unchecked_mass_inverse`): it is checked here against the M
    of the derivatives, allowing an ill-conditioned M when True.
    """
    nv = system.nv
    terms = second_order_terms(system, op, derivatives, step, estimate_error)
    if mass_inverse is None:
        Minv = system.mass_inverse(op.q)
    elif check_mass is not None:
        Minv = system.check_mass_inverse(op.q, terms.M, mass_inverse,
                                         allow_ill_conditioned=check_mass)
    else:
        Minv = mass_inverse
    A = system.kinematic_rows.copy()
    moving = kinematic_block(system, op.v)
    if moving is not None:  # Lie-group joints at a moving state (pinlin.chart)
        A[:nv, :nv] = moving
    if terms.C is None:
        A[nv:, :nv] = -(Minv @ terms.K)
        C_damp = system.zero_velocity_terms
    else:
        A[nv:] = -(Minv @ np.hstack([terms.K, terms.C]))
        C_damp = terms.C
    B = np.zeros((2 * nv, len(system.actuated)))
    B[nv:] = Minv[:, system.actuated_columns] if terms.Bu is None else Minv @ terms.Bu
    C, D, out_names, y0 = output_matrices(system, op)
    op_with_y = op.with_outputs(y0)
    condition = trace_condition(terms.M, Minv)
    warn_if_ill_conditioned("mass matrix", condition, system.scene.name, size=nv)
    info = {
        "formulation": "independent",
        "derivatives": terms.backend,
        "effects": list(system.effects_in_play),
        "velocity_terms": terms.C is not None,
        "base": "free" if system.base_joint else "fixed",
        "notes": list(op.notes),
        "condition": {"mass_matrix": condition},
    }
    if terms.steps is not None:
        info["step"] = dict(terms.steps)
    if terms.alt is not None:
        K_alt, C_alt = terms.alt
        A_alt = A.copy()
        A_alt[nv:, :nv] = -(Minv @ K_alt)
        if C_alt is not None:
            A_alt[nv:, nv:] = -(Minv @ C_alt)
        # A's lower block row is -M^-1 [K, C]: rounding in K and C is amplified by M^-1.
        sigma_K, sigma_C = terms.rounding
        rounding = max(propagated_noise(Minv, sigma_K), propagated_noise(Minv, sigma_C))
        info.update(error_estimate(A, A_alt, rounding))
    f0 = None
    if np.count_nonzero(op.v) or np.count_nonzero(op.a):  # off equilibrium: x' = f0 + A x + B u
        f0 = read_only(np.concatenate([op.v, op.a]))
    return LinearModel.assembled(
        f0=f0, dt=0.0,
        A=read_only(A), B=read_only(B), C=read_only(C), D=read_only(D),
        state_names=system.state_names, input_names=system.input_names, output_names=out_names,
        E=None, F=None, G=None, M=read_only(terms.M), C_damp=read_only(C_damp),
        K=read_only(terms.K), Bu=system.input_matrix, operating_point=op_with_y,
        name=system.scene.name, info=info)
