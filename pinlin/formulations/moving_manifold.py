"""Constrained systems at a moving state where the constraint's second derivatives are not
symmetric: floating bases (and any free-flyer, spherical or planar joint) standing on
contacts or closing loops, and weld loops and contacts.

The model is :mod:`pinlin.formulations.motion`'s (eqs. 9.8-9.11 with every velocity term,
independent coordinates z, partitioned basis), x = [dz; dz'] with dz = difference(q0, q)[z]
and z' = v[z]::

    [[M, -G^T], [G, 0]] [F_q R, F_v, F_u; .] = [[-K R, -C, S], [-c_q R, -c_v, 0]]
    A = [[(N R)[z], I], [(F_q R + F_v W)[z], (F_v R)[z]]],   B = [[0], [F_u[z]]]

with three differences from the revolute case, all from the non-commuting tangent coordinates
of Lie-group joints (X_j X_k Phi != X_k X_j Phi) and the weld rows' log3:

- The kinematic block N = d(Jexp(dq)^-1 v0)/d(dq) = -1/2 ad(v0) on Lie-group joints
  (:func:`pinlin.chart.kinematic_block`): d/dt dz = v[z] + (N R dz)[z].
- W: the velocity that keeps the constraints at q0 (+) R dz is v0 + R dz' + W dz with
  G W = -d(Phi_q v0)/dq R (the derivative *of* Phi_q applied to v0), not -Phi_qq[v0, .] R.
- c_q R = d(Phi_q a0 + gamma(q, v0))/dq R and c_v = d gamma/dv, whose two halves
  Phi_qq[., v0] and Phi_qq[v0, .] differ.

d(Phi_q v0)/dq R and c_q R are derivatives along the constraint manifold: five-point central
differences of the constraint velocity and acceleration
(:func:`pinlin.constraint_derivatives.motion_rows`: frame velocities and accelerations of one
``forwardKinematics(q, v0, a0)``) along the tangent lines q0 (+) s R e_i. The weld rows'
formula holds on the manifold only, but its error off the manifold vanishes there, so its
derivative along a tangent direction is zero: on the tangent line the differences give the
derivative along the manifold, with the usual truncation (measured: re-assembling each point
onto the manifold changes these terms by <= 3e-11 of their size, the differences' rounding).
c_v is exact by central differences in v: gamma is quadratic in v. K (with the geometric
stiffness -lam0^T Phi_qq, its Lie-group blocks exact), C and M are Pinocchio's analytic
derivatives (:func:`pinlin.derivatives.second_order_terms`).

Accuracy: truncation ~h^4 |f^(5)| / 30 and rounding ~eps |f| / h. Along column i the curve's
parameter moves q by s |R e_i|, so its step is :data:`STEP` / max(1, |R e_i|): no coordinate
moves by more than 1e-4 (near a singular position a dependent joint turns much faster than
z: 35x on two spatial branches welded tip to tip, whose model is then 1e-10..4e-10 of
max |A| from five-point differences of Pinocchio's dynamics, where a fixed step of 1e-4 in
s left truncation of ~5e-8). On the bundled mechanisms the path agrees with the analytic
kernels to 9e-15..1.5e-12 of max |A|. tests/test_moving_standing.py checks the model
against central differences of Pinocchio's ``constraintDynamics`` on the manifold in this
chart, and against the revolute path of :mod:`pinlin.formulations.motion` on mechanisms.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..assembly import Partition, projection
from ..chart import kinematic_block
from ..constraint_derivatives import motion_rows
from ..derivatives import second_order_terms
from ..operating_point import OperatingPoint

#: Step of the five-point differences along the constraint manifold [rad or m].
STEP = 1e-4


def applies(system) -> bool:
    """Whether a constrained system at a moving state takes this module's path: a Lie-group
    joint (a floating base) or a weld loop or contact."""
    cons = system.constraints
    return bool(cons._lie_blocks) or cons.has_welds


def manifold_derivatives(system, op: OperatingPoint, part: Partition, R: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(d(Phi_q v0)/dq R, d(Phi_q a0 + gamma)/dq R) (m x nz each) by five-point differences
    along the tangent lines of the constraint manifold (module docstring)."""
    cons, model = system.constraints, system.model
    nz = R.shape[1]
    dvel = np.zeros((cons.size, nz))
    dacc = np.zeros((cons.size, nz))
    weights = {-2: 1.0, -1: -8.0, 1: 8.0, 2: -1.0}
    for i in range(nz):
        # The curve's parameter moves q by s |R e_i|: the step moves no coordinate by more
        # than STEP (a dependent joint may turn 35x faster than z near a singular position).
        h = STEP / max(1.0, float(np.abs(R[:, i]).max()))
        for k, w in weights.items():
            q = pin.integrate(model, op.q, (k * h) * R[:, i])
            vel, acc = motion_rows(cons, q, op.v, op.a)
            dvel[:, i] += w * vel
            dacc[:, i] += w * acc
        dvel[:, i] /= 12 * h
        dacc[:, i] /= 12 * h
    return dvel, dacc


def coordinate_derivatives(system, op: OperatingPoint) -> tuple[np.ndarray, np.ndarray]:
    """(d(Phi_q v0)/dq, d(Phi_q a0 + gamma)/dq) (m x nv each) along every tangent coordinate
    (the penalty formulation, which moves off the manifold): five-point differences of
    :func:`~pinlin.constraint_derivatives.motion_rows` along q0 (+) s e_j, step :data:`STEP`.
    Point rows only (a weld's formula holds on the manifold alone)."""
    cons, model = system.constraints, system.model
    dvel = np.zeros((cons.size, system.nv))
    dacc = np.zeros((cons.size, system.nv))
    e = np.zeros(system.nv)
    for j in range(system.nv):
        for k, w in ((-2, 1.0), (-1, -8.0), (1, 8.0), (2, -1.0)):
            e[j] = k * STEP
            vel, acc = motion_rows(cons, pin.integrate(model, op.q, e), op.v, op.a)
            dvel[:, j] += w * vel
            dacc[:, j] += w * acc
        e[j] = 0.0
    return dvel / (12 * STEP), dacc / (12 * STEP)


def velocity_derivative(system, op: OperatingPoint) -> np.ndarray:
    """c_v = d gamma/dv at (q0, v0) (m x nv): central differences, exact for gamma, which is
    quadratic in v (the a0 part cancels), with the step max(1, |v0|) so that rounding stays
    at eps relative to the terms at any speed."""
    cons = system.constraints
    out = np.zeros((cons.size, system.nv))
    h = max(1.0, float(np.abs(op.v).max(initial=0.0)))
    e = np.zeros(system.nv)
    for j in range(system.nv):
        e[j] = h
        out[:, j] = (motion_rows(cons, op.q, op.v + e, op.a)[1]
                     - motion_rows(cons, op.q, op.v - e, op.a)[1]) / (2.0 * h)
        e[j] = 0.0
    return out


def model(system, op: OperatingPoint, part: Partition, G: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, f0, R, W, S) of the independent-coordinate model at a moving state (module
    docstring); ``G``: the partition's rows of Phi_q at op.q."""
    rows, z, dep = part.rows, part.independent, part.dependent
    nv, nz, m = system.nv, len(z), len(rows)
    terms = second_order_terms(system, op, "analytic")
    S = system.input_matrix
    R = projection(G, part)
    dvel, dacc = manifold_derivatives(system, op, part, R)
    c_v = velocity_derivative(system, op)[rows]
    C = np.zeros((nv, nv)) if terms.C is None else terms.C
    kkt = np.zeros((nv + m, nv + m))
    kkt[:nv, :nv] = terms.M
    kkt[:nv, nv:] = -G.T
    kkt[nv:, :nv] = G
    rhs = np.vstack([np.hstack([-(terms.K @ R), -C, S]),
                     np.hstack([-dacc[rows], -c_v, np.zeros((m, S.shape[1]))])])
    F = np.linalg.solve(kkt, rhs)[:nv]
    FqR, F_v, F_u = F[:, :nz], F[:, nz:nz + nv], F[:, nz + nv:]
    W = np.zeros((nv, nz))
    if len(dep):
        W[dep] = -np.linalg.solve(G[:, dep], dvel[rows])
    A = np.zeros((2 * nz, 2 * nz))
    N = kinematic_block(system, op.v)
    if N is not None:
        A[:nz, :nz] = (N @ R)[z]
    A[:nz, nz:] = np.eye(nz)
    A[nz:, :nz] = (FqR + F_v @ W)[z]
    A[nz:, nz:] = (F_v @ R)[z]
    B = np.zeros((2 * nz, S.shape[1]))
    B[nz:] = F_u[z]
    f0 = np.concatenate([op.v[z], op.a[z]])
    return A, B, f0, R, W, S


__all__ = ["STEP", "applies", "coordinate_derivatives", "manifold_derivatives", "model",
           "velocity_derivative"]
