"""MuJoCo's linearization of a scene exported by :func:`pinlin.mjcf.build`, expressed in
pinlin's coordinates (the coordinate maps are described in :mod:`pinlin.mjcf`).

MuJoCo's Euler step v+ = v + dt (M + dt D)^-1 f(q, v) gives the continuous bottom block row
of A exactly from the one-step Jacobian of ``mjd_transitionFD``:
[da/dq, da/dv] = M^-1 (M + dt D) (A_d[nv:] - [0, I]) / dt. Its eigenvalues are MuJoCo's
continuous-time eigenvalues with no time-step bias; log(z)/dt of A_d's eigenvalues z carries an
O(dt^2) bias for undamped modes (symplectic Euler), O(dt) for damped ones, and loses the
position rows' information to rounding when dt is small.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .mjcf import MujocoError, MujocoScene, _base_rotation, set_state


def transition_matrix(ms: MujocoScene, system, op, eps: float = 1e-6, centered: bool = True
                      ) -> np.ndarray:
    """The one-step Jacobian A_d of ``mjd_transitionFD`` at ``op`` (MuJoCo coordinates)."""
    m, d = ms.model, ms.data
    nv = system.nv
    tau = system.input_matrix @ op.u
    if ms.free and np.any(tau[:6]):
        raise MujocoError("a floating base with applied base forces is not supported")
    set_state(ms, system, op.q, op.v, tau)
    A_d = np.zeros((2 * nv + m.na, 2 * nv + m.na))
    mujoco.mjd_transitionFD(m, d, eps, centered, A_d, None, None, None)
    mujoco.mj_forward(m, d)  # derived quantities (qM, qacc) are left stale by the differencing
    return A_d


def recover_continuous(ms: MujocoScene, A_d: np.ndarray) -> np.ndarray:
    """The continuous A (MuJoCo coordinates) from the Euler one-step Jacobian A_d, exactly:
    its velocity rows are [0, I] + dt (M + dt D)^-1 M [da/dq, da/dv]; the top block row of the
    continuous A is [0, I]. Needs ``ms.data`` at the state A_d was taken at."""
    m, d = ms.model, ms.data
    nv = m.nv
    bottom = A_d[nv:2 * nv, :2 * nv].copy()
    bottom[:, nv:] -= np.eye(nv)
    bottom /= ms.dt
    if np.any(m.dof_damping):
        M = np.zeros((nv, nv))
        mujoco.mj_fullM(m, d, M)
        bottom = np.linalg.solve(M, (M + ms.dt * np.diag(m.dof_damping)) @ bottom)
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    A[nv:] = bottom
    return A


def continuous_state_matrix(ms: MujocoScene, system, op, eps: float = 1e-6,
                            centered: bool = True) -> np.ndarray:
    """MuJoCo's linearization at ``op`` as a continuous A in pinlin's state [dq; v].

    The operating point's inputs are applied as generalized forces (``qfrc_applied``); the
    base of a floating robot is not actuated.
    """
    A_d = transition_matrix(ms, system, op, eps, centered)
    return to_pinlin_coordinates(ms, system, op, recover_continuous(ms, A_d))


def to_pinlin_coordinates(ms: MujocoScene, system, op, A_c: np.ndarray) -> np.ndarray:
    """MuJoCo's continuous A (its dof order, free-joint conventions) in pinlin's [dq; v]."""
    nv = system.nv
    bottom = A_c[nv:]
    # MuJoCo dof order -> pinlin order.
    idx = ms.dof
    dadq = bottom[np.ix_(idx, idx)]
    dadv = bottom[np.ix_(idx, nv + idx)]
    if ms.free:
        R = _base_rotation(system, op.q)
        T = np.eye(nv)
        T[:3, :3] = R
        Tinv = T.copy()
        Tinv[:3, :3] = R.T
        corr = np.zeros((nv, nv))
        a_lin = op.a[:3]
        corr[:3, 3:6] = -R @ _skew(a_lin)
        dadq = Tinv @ (dadq @ T - corr)
        dadv = Tinv @ dadv @ T
    A = np.zeros((2 * nv, 2 * nv))
    A[:nv, nv:] = np.eye(nv)
    A[nv:, :nv] = dadq
    A[nv:, nv:] = dadv
    return A


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def euler_step_jacobians(ms: MujocoScene, system, op, eps: float = 3e-4
                         ) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's one Euler step linearized at ``op`` (any state), in pinlin's [dq; v] and
    inputs: A_d from ``mjd_transitionFD``, centered at ``eps`` and 2 ``eps`` and combined by
    Richardson (the O(eps^2) truncation cancels; rounding, eps_mach |x| / eps, stays ~1e-13
    even where positions reach 100 m, which single differences at 1e-6 let through at 2e-8
    on tiago), B_d by differencing
    ``mj_step`` in the applied generalized forces (linear in them: a 1 N*m step is exact to
    rounding). Fixed-base models (a free joint's frames would need converting at a moving
    state).

    Raises:
        MujocoError: a floating base.
    """
    if ms.free:
        raise MujocoError("MuJoCo's step at a moving state is compared for fixed-base models "
                          "only")
    m, d = ms.model, ms.data
    nv = system.nv
    idx = np.concatenate([ms.dof, nv + ms.dof])
    A_1 = transition_matrix(ms, system, op, eps=eps, centered=True)[:2 * nv, :2 * nv]
    A_2 = transition_matrix(ms, system, op, eps=2 * eps, centered=True)[:2 * nv, :2 * nv]
    A_d = ((4.0 * A_1 - A_2) / 3.0)[np.ix_(idx, idx)]
    S = system.input_matrix
    tau0 = S @ op.u

    def step(tau: np.ndarray) -> np.ndarray:
        set_state(ms, system, op.q, op.v, tau)
        q_start = d.qpos.copy()
        mujoco.mj_step(m, d)
        dq = np.zeros(m.nv)
        mujoco.mj_differentiatePos(m, dq, 1.0, q_start, d.qpos)
        return np.concatenate([dq[ms.dof], d.qvel[ms.dof]])

    B_d = np.array([(step(tau0 + S[:, k]) - step(tau0 - S[:, k])) / 2.0
                    for k in range(S.shape[1])]).T
    set_state(ms, system, op.q, op.v, tau0)
    return A_d, B_d.reshape(2 * nv, S.shape[1])
