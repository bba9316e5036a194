"""Constrained systems at moving states, many points at once: the model of
:mod:`pinlin.formulations.motion` (eqs. 9.8-9.11 with every velocity term, independent
coordinates, partitioned basis) for a stack of N states sharing one partition.

Per point only Pinocchio runs from Python: one ``computeJointJacobians`` and a frame Jacobian
per closure frame, ``crba``, ``nonLinearEffects`` at the projected velocity and
``computeRNEADerivatives`` at the constrained acceleration (4 + F calls, F the closure
frames). Everything else is numpy on (N, ...) stacks: the loop Jacobian, the velocity
projection, gamma and its derivative d gamma / dq, Phi_qq[v, .], Phi_qq[a, .] and the
geometric stiffness lam^T Phi_qq from the frame Jacobians (:mod:`pinlin.loop_kernels`,
analytic: no finite differences), the two KKT solves (``np.linalg.solve`` on stacks: LAPACK
``gesv`` per point, as a single call does) and R, W and the state matrices.

The math is :mod:`pinlin.formulations.motion`'s, step for step::

    v = v0 - G^T (G G^T)^-1 G v0
    [[M, -G^T], [G, 0]] [a; lam] = [S u + tau_spring - D v - b(q, v); -gamma]
    [[M, -G^T], [G, 0]] [F_q F_v F_u; .] = [[-K, -C, S], [-c_q, -c_v, 0]]
    K = d rnea/dq + diag(k) - lam^T Phi_qq,   C = d rnea/dv + diag(c)
    c_q = Phi_qq[a, .] + d gamma/dq,   c_v = 2 Phi_qq[v, .]
    R = [I; -G_d^-1 G_z],   W[dep] = -G_d^-1 Phi_qq[v, .] R,   W[z] = 0
    A = [[0, I], [(F_q R + F_v W)[z], (F_v R)[z]]],   B = [[0], [F_u[z]]],   f0 = [v[z]; a[z]]

(G: the partition's independent rows of Phi_q; z, dep: independent and dependent
coordinates). :func:`pinlin.linearize` at a single moving state runs the same code with
N = 1, so a trajectory's point equals the single model to rounding. It applies where
:func:`pinlin.loop_kernels.plan` does (no steady rotation, point closures on 1-DoF joints);
elsewhere motion.py's per-point path runs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from .. import loop_kernels as lk
from ..assembly import unit_factors


class Stack(NamedTuple):
    """Constrained states at N points (stacks, point first).

    Attributes:
        q: (N, nq) assembled configurations [m, rad].
        v: (N, nv) velocities projected onto the nullspace of Phi_q [rad/s or m/s].
        correction: (N, nv) what the projection removed from the given velocities.
        a: (N, nv) accelerations [rad/s^2 or m/s^2].
        lam: (N, m) constraint forces, zero on dropped rows [N or N*m].
        J: (N, F, 6, nv) LOCAL_WORLD_ALIGNED Jacobians of the closure frames.
        jac: (N, m, nv) Phi_q, all rows.
        M: (N, nv, nv) mass matrices [kg, kg*m^2].
        Jv: (N, m, nv) Phi_qq[v, .] at the projected v.
        dgamma: (N, m, nv) d gamma / dq at the projected v.
    """

    q: np.ndarray
    v: np.ndarray
    correction: np.ndarray
    a: np.ndarray
    lam: np.ndarray
    J: np.ndarray
    jac: np.ndarray
    M: np.ndarray
    Jv: np.ndarray
    dgamma: np.ndarray


def _symmetric(M: np.ndarray) -> np.ndarray:
    """The symmetric matrices whose upper triangles are those of ``M`` (N, n, n)."""
    n = M.shape[-1]
    upper = np.triu(np.ones((n, n)))
    return M * upper + (M * (upper - np.eye(n))).transpose(0, 2, 1)


def _kkt(M: np.ndarray, G: np.ndarray) -> np.ndarray:
    N, m, nv = G.shape
    out = np.zeros((N, nv + m, nv + m))
    out[:, :nv, :nv] = M
    out[:, :nv, nv:] = -G.transpose(0, 2, 1)
    out[:, nv:, :nv] = G
    return out


def applied(system, Q: np.ndarray, V: np.ndarray, U: np.ndarray) -> np.ndarray:
    """S u + tau_spring(q) - D v per point (N, nv) [N*m or N]."""
    from ..batch import generalized_forces

    return generalized_forces(system, Q, V, U)


def states(system, plan: lk.ClosurePlan, Q: np.ndarray, V: np.ndarray, U: np.ndarray,
           rows: np.ndarray, J: np.ndarray | None = None) -> Stack:
    """Project the velocities and solve the constrained dynamics at N assembled
    configurations ``Q`` (N, nq) with given velocities ``V`` (N, nv) [rad/s or m/s] and
    inputs ``U`` (N, nu) [N*m or N]; ``rows``: the independent constraint rows; ``J``: the
    closure frames' Jacobians at ``Q`` (N, F, 6, nv, :func:`pinlin.loop_kernels.frame_jacobians`)
    when the caller has them (the assembly's last kinematics pass), else computed here.

    Raises:
        numpy.linalg.LinAlgError: a KKT matrix is singular (at some point of the stack).
    """
    model, data = system.model, system.data
    N, nv = V.shape
    M = np.empty((N, nv, nv))
    if J is None:
        J = np.zeros((N, len(plan.frames), 6, nv))
        for k in range(N):
            lk.frame_jacobians(model, data, Q[k], plan.frames, J[k])
            M[k] = pin.crba(model, data, Q[k])
    else:
        for k in range(N):
            M[k] = pin.crba(model, data, Q[k])
    M = _symmetric(M)
    jac = lk.jacobian(plan, J)
    G = jac[:, rows]
    GT = G.transpose(0, 2, 1)
    if len(rows):   # closest in one unit, as motion.project_velocity
        factors = unit_factors(system)
        Gc, GcT = (G, GT) if factors is None else (G * factors[1], GT * factors[1][:, None])
        corr = (GcT @ np.linalg.solve(Gc @ GcT, G @ V[:, :, None]))[..., 0]
        if factors is not None:
            corr *= factors[1]
    else:
        corr = np.zeros_like(V)
    v = V - corr
    b = np.empty((N, nv))
    for k in range(N):
        b[k] = pin.nonLinearEffects(model, data, Q[k], v[k])
    Jv, gamma, dgamma = lk.bias_terms(plan, J, v)
    rhs = np.concatenate([applied(system, Q, v, U) - b, -gamma[:, rows]], axis=1)
    sol = np.linalg.solve(_kkt(M, G), rhs[:, :, None])[..., 0]
    lam = np.zeros((N, jac.shape[1]))
    lam[:, rows] = sol[:, nv:]
    return Stack(Q, v, corr, sol[:, :nv], lam, J, jac, M, Jv, dgamma)


def given(system, plan: lk.ClosurePlan, q: np.ndarray, v: np.ndarray, a: np.ndarray,
          lam: np.ndarray) -> Stack:
    """The :class:`Stack` of one state whose projected velocity ``v``, acceleration ``a`` and
    constraint forces ``lam`` are known (a single model's operating point)."""
    model, data = system.model, system.data
    J = np.zeros((1, len(plan.frames), 6, system.nv))
    lk.frame_jacobians(model, data, q, plan.frames, J[0])
    M = _symmetric(pin.crba(model, data, q)[None])
    Jv, _, dgamma = lk.bias_terms(plan, J, v[None])
    return Stack(q[None], v[None], np.zeros((1, system.nv)), a[None], lam[None], J,
                 lk.jacobian(plan, J), M, Jv, dgamma)


class Models(NamedTuple):
    """State-space matrices of N points (independent coordinates z).

    Attributes:
        A: (N, 2nz, 2nz); B: (N, 2nz, nu); f0: (N, 2nz).
        R: (N, nv, nz) the velocity projection; W: (N, nv, nz) its variation along v.
        frame_jacobians, frame_positions: (N, F, 6, nv) LOCAL_WORLD_ALIGNED Jacobians and
            (N, F, 3) positions [m] of the frames :func:`models` was asked for, else None.
    """

    A: np.ndarray
    B: np.ndarray
    f0: np.ndarray
    R: np.ndarray
    W: np.ndarray
    frame_jacobians: np.ndarray | None = None
    frame_positions: np.ndarray | None = None


def models(system, plan: lk.ClosurePlan, st: Stack, rows: np.ndarray, z: np.ndarray,
           dep: np.ndarray, frames: tuple[int, ...] = ()) -> Models:
    """The models at the states ``st`` (:func:`states`) in the partition (rows, z, dep)
    (module docstring); ``frames``: frame ids whose Jacobians and positions to read from the
    same kinematics (``computeRNEADerivatives`` leaves the joint Jacobians and placements of
    each point in the data: the numbers ``computeJointJacobians`` gives, bit for bit).

    Raises:
        numpy.linalg.LinAlgError: a KKT matrix or Phi_d is singular.
    """
    model, data = system.model, system.data
    N, nv = st.v.shape
    nz = len(z)
    K = np.empty((N, nv, nv))
    C = np.empty((N, nv, nv))
    Jf = np.empty((N, len(frames), 6, nv)) if frames else None
    pf = np.empty((N, len(frames), 3)) if frames else None
    for k in range(N):
        dq, dv, _ = pin.computeRNEADerivatives(model, data, st.q[k], st.v[k], st.a[k])
        K[k] = dq
        C[k] = dv
        for i, fid in enumerate(frames):
            Jf[k, i] = lk.frame_jacobian(model, data, fid)
            pf[k, i] = pin.updateFramePlacement(model, data, fid).translation
    diagonal = np.arange(nv)
    K[:, diagonal, diagonal] += system.stiffness
    C[:, diagonal, diagonal] += system.damping
    if np.any(st.lam):
        K -= lk.hessian(plan, st.J, st.lam)
    G = st.jac[:, rows]
    Jv = st.Jv[:, rows]
    c_q = lk.variation(plan, st.J, st.a)[:, rows] + st.dgamma[:, rows]
    S = system.input_matrix
    nu = S.shape[1]
    m = len(rows)
    rhs = np.zeros((N, nv + m, 2 * nv + nu))
    rhs[:, :nv, :nv] = -K
    rhs[:, :nv, nv:2 * nv] = -C
    rhs[:, :nv, 2 * nv:] = S
    rhs[:, nv:, :nv] = -c_q
    rhs[:, nv:, nv:2 * nv] = -2.0 * Jv
    Fm = np.linalg.solve(_kkt(st.M, G), rhs)[:, :nv]
    F_q, F_v, F_u = Fm[:, :, :nv], Fm[:, :, nv:2 * nv], Fm[:, :, 2 * nv:]
    R = np.zeros((N, nv, nz))
    R[:, z, np.arange(nz)] = 1.0
    W = np.zeros((N, nv, nz))
    if len(dep):
        Gd = G[:, :, dep]
        R[:, dep] = -np.linalg.solve(Gd, G[:, :, z])
        W[:, dep] = -np.linalg.solve(Gd, Jv @ R)
    A = np.zeros((N, 2 * nz, 2 * nz))
    A[:, np.arange(nz), nz + np.arange(nz)] = 1.0
    FvR = F_v @ R
    A[:, nz:, :nz] = (F_q @ R + F_v @ W)[:, z]
    A[:, nz:, nz:] = FvR[:, z]
    B = np.zeros((N, 2 * nz, nu))
    B[:, nz:] = F_u[:, z]
    f0 = np.concatenate([st.v[:, z], st.a[:, z]], axis=1)
    return Models(A, B, f0, R, W, Jf, pf)


def reduce_outputs(Cout: np.ndarray, R: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Output matrices in all coordinates (N, p, 2nv), y = h(q, v), to the independent ones
    (N, p, 2nz): dq = R dz, dv = R dz' + W dz."""
    nv = R.shape[1]
    Cq, Cv = Cout[:, :, :nv], Cout[:, :, nv:]
    return np.concatenate([Cq @ R + Cv @ W, Cv @ R], axis=2)


__all__ = ["Models", "Stack", "applied", "given", "models", "reduce_outputs", "states"]
