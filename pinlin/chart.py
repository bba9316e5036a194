"""The chart of the state x = [dq; v] about q0, and its kinematic block row at a moving state.

pinlin's state is dq = ``pin.difference(q0, q)`` (the tangent-space deviation) and the joint
velocity v, so a configuration is q = ``pin.integrate(q0, dq)`` and the kinematics read

    d(dq)/dt = J(dq) v,   J(dq) = d difference(q0, q) / dq  at q = integrate(q0, dq)

(``pin.dDifference(model, q0, q, ARG1)``), with J(0) = I. Linearized about (dq = 0, v0)::

    d(dq)/dt ~ v0 + (dJ/d(dq) v0) dq + (v - v0)

The first block, zero at rest and on vector-space joints (revolute, prismatic, continuous
joints as well: SO(2) is commutative), is -1/2 ad(v0) on the Lie-group joints, the first-order
term of the inverse right Jacobian of the exponential map, J(dq) = I - 1/2 ad(dq) + ...:

- free flyer (SE(3), v = [linear; angular] in the joint frame): -1/2 [[w^, u^], [0, w^]]
  with u, w the linear and angular parts of v0 (Pinocchio's ``Motion(v).action``);
- spherical (SO(3)): -1/2 w^;
- planar (SE(2), v = [vx, vy, wz]): -1/2 [[0, -wz, vy], [wz, 0, -vx], [0, 0, 0]].

tests/test_moving_state.py checks these against central differences of ``pin.dDifference``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .coordinates import FREE_FLYER, SPHERICAL

PLANAR = "JointModelPlanar"


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def kinematic_block(system, v0: np.ndarray) -> np.ndarray | None:
    """d(d(dq)/dt)/d(dq) at (dq = 0, v0) (nv x nv), or None when it is zero (v0 = 0, or no
    Lie-group joint moves)."""
    if not np.count_nonzero(v0):  # (np.any costs ~5x more on a small vector)
        return None
    block = None
    for j in system.joints.values():
        if j.kind not in (FREE_FLYER, SPHERICAL, PLANAR):
            continue
        vj = v0[j.idx_v:j.idx_v + j.nv]
        if not np.count_nonzero(vj):
            continue
        if block is None:
            block = np.zeros((system.nv, system.nv))
        if j.kind == FREE_FLYER:
            ad = pin.Motion(vj).action
        elif j.kind == SPHERICAL:
            ad = _skew(vj)
        else:
            vx, vy, wz = vj
            ad = np.array([[0.0, -wz, vy], [wz, 0.0, -vx], [0.0, 0.0, 0.0]])
        block[j.idx_v:j.idx_v + j.nv, j.idx_v:j.idx_v + j.nv] = -0.5 * ad
    return block


__all__ = ["kinematic_block"]
