"""Second derivatives of the constraints Phi(q) = 0 of a :class:`~pinlin.constraints.ConstraintSet`:
the geometric stiffness d(Phi_q^T lam)/d(dq) (batched for point closures on 1-DoF joints, and
by one Jacobian time variation per support coordinate for any closure), the bias acceleration
Phi_qq[v, v] and the Jacobian variation Phi_qq[w, .] at a moving state. The formulas are derived
in :mod:`pinlin.constraints`; the class's methods of the same names call these functions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from .loop_kernels import frame_jacobian, frame_jacobian_variation

if TYPE_CHECKING:
    from .constraints import ConstraintSet

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def bias_acceleration(cons: ConstraintSet, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:meth:`ConstraintSet.bias_acceleration` of ``cons`` (documented there, in
    :mod:`pinlin.constraints`)."""
    out = np.zeros(cons.size)
    if not cons._closures:
        return out
    if cons.has_welds:
        return motion_rows(cons, q, v, np.zeros(cons.system.nv))[1]
    sysm = cons.system
    kin, kd = sysm.kin_model, sysm.kin_data
    pin.forwardKinematics(kin, kd, sysm.kin_q(q), sysm.kin_v(v, spin=False),
                          np.zeros(kin.nv))
    pin.updateFramePlacements(kin, kd)
    for _, f1, f2, row, _ in cons._closures:
        out[row:row + 3] = pin.getFrameClassicalAcceleration(kin, kd, f1, LWA).linear
        if f2 is not None:
            out[row:row + 3] -= pin.getFrameClassicalAcceleration(kin, kd, f2, LWA).linear
    return out


def motion_rows(cons: ConstraintSet, q: np.ndarray, v: np.ndarray, a: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(Phi_q v, Phi_q a + Phi_qq[v, v]) (m each) at an assembled configuration q: the first
    and second time derivatives of Phi along a motion through q with velocity v [1/s] and
    acceleration a [1/s^2], from one ``forwardKinematics(q, v, a)``. Point rows: the frames'
    linear velocities and classical accelerations (LOCAL_WORLD_ALIGNED), frame 1's minus
    frame 2's (the world's: zero). Weld rotation rows, at E = R1 R2^T = I where
    d/dt log3(E) = w1 - w2 and d/dt (Jlog3(E) E^T) = -1/2 [w1 - w2]x: w1 - w2 and
    al1 - al2 - (w1 - w2) x w2 (w, al: the frames' world angular velocities and
    accelerations; the last term vanishes at a consistent state, w1 = w2, and so does its first
    variation along consistent motions: it never reaches a model, but keeps these rows the
    exact second derivative). Mimic rows: 0 (linear in q). Not for a rotating scene's
    frame."""
    sysm = cons.system
    vel, acc = np.zeros(cons.size), np.zeros(cons.size)
    if not cons._closures:
        return vel, acc
    kin, kd = sysm.kin_model, sysm.kin_data
    pin.forwardKinematics(kin, kd, sysm.kin_q(q), sysm.kin_v(v, spin=False),
                          sysm.kin_v(a, spin=False))
    pin.updateFramePlacements(kin, kd)
    zero = np.zeros(3)
    for kind, f1, f2, row, _ in cons._closures:
        v1 = pin.getFrameVelocity(kin, kd, f1, LWA)
        vel[row:row + 3] = v1.linear
        acc[row:row + 3] = pin.getFrameClassicalAcceleration(kin, kd, f1, LWA).linear
        w2 = al2 = zero
        if f2 is not None:
            v2 = pin.getFrameVelocity(kin, kd, f2, LWA)
            vel[row:row + 3] -= v2.linear
            acc[row:row + 3] -= pin.getFrameClassicalAcceleration(kin, kd, f2, LWA).linear
            w2 = v2.angular
            al2 = pin.getFrameAcceleration(kin, kd, f2, LWA).angular
        if kind == "weld":
            d = v1.angular - w2
            vel[row + 3:row + 6] = d
            acc[row + 3:row + 6] = (pin.getFrameAcceleration(kin, kd, f1, LWA).angular - al2
                                    - _cross(d, w2))
    return vel, acc


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors (np.cross costs ~30x more at this size)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def jacobian_variation(cons: ConstraintSet, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """:meth:`ConstraintSet.jacobian_variation` of ``cons`` (documented there, in
    :mod:`pinlin.constraints`)."""
    sysm = cons.system
    out = np.zeros((cons.size, sysm.nv))
    if not cons._closures:
        return out
    cons._refuse_welds()
    kin, kd = sysm.kin_model, sysm.kin_data
    pin.computeJointJacobiansTimeVariation(kin, kd, sysm.kin_q(q), sysm.kin_v(w, spin=False))
    cols = sysm.kin_columns
    for _, f1, f2, row, _ in cons._closures:
        out[row:row + 3] = frame_jacobian_variation(kin, kd, f1)[:3, cols]
        if f2 is not None:
            out[row:row + 3] -= frame_jacobian_variation(kin, kd, f2)[:3, cols]
    return out


def hessian(cons: ConstraintSet, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """:meth:`ConstraintSet.hessian` of ``cons`` (documented there, in
    :mod:`pinlin.constraints`)."""
    nv = cons.system.nv
    if not cons._closures or not np.any(lam[:cons._loop_rows()]):
        return np.zeros((nv, nv))
    if cons._batched_hessian:
        return cons._point_hessian(q, lam)
    return cons.hessian_by_time_variation(q, lam)


def _point_hessian(cons: ConstraintSet, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """:meth:`ConstraintSet.hessian` of point loops and contacts on 1-DoF joints, batched: one
    ``computeJointJacobians`` and two frame Jacobians per closure.

    On a chain of 1-DoF joints with constant motion axes (revolute, prismatic, continuous,
    helical) the world twist S_k of joint k moves only with its ancestors, dS_k/dq_j =
    S_j x S_k, and a point p of the frame moves as dp/dq_j = Jp_j. Together (Jacobi
    identity) d(Jp_k)/dq_j = w_a x Jp_b with a the ancestor of the pair (j, k) and b the
    other, w the angular and Jp the point's linear Jacobian columns (LOCAL_WORLD_ALIGNED);
    both are zero off the frame's support. Velocity indices grow from root to leaf, so in
    X[j, k] = lam . (w_j x Jp_k) = -w_j . ([lam]x Jp_k) the pair's ancestor is the
    smaller index: the Hessian is triu(X) + triu(X, 1)^T, summed over every frame (signed
    +1 for frame1, -1 for frame2) in one product of stacked 3-row blocks.
    """
    sysm = cons.system
    kin, kd = sysm.kin_model, sysm.kin_data
    pin.computeJointJacobians(kin, kd, sysm.kin_q(q))
    frames, lam_rows, skew_at, skew_sign = cons._hessian_plan
    J = np.concatenate([frame_jacobian(kin, kd, fid) for fid in frames])
    if sysm.rotation is not None:
        J = J[:, sysm.kin_columns]
    n = J.shape[0] // 2  # 3 rows per frame
    # Block-diagonal -s [lam]x per frame: Y = Jp x (s lam) for each frame's 3 rows.
    skew = np.zeros(n * n)
    skew[skew_at] = skew_sign * lam[lam_rows]
    point = J.reshape(-1, 2, 3, J.shape[1])  # (frame, linear | angular, xyz, nv)
    X = point[:, 1].reshape(n, -1).T @ (skew.reshape(n, n) @ point[:, 0].reshape(n, -1))
    upper, strict = cons._triangles
    return X * upper + (X * strict).T


def _hessian_plan(cons: ConstraintSet) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray]:
    """For :func:`_point_hessian`: the closure frames, and where the signed entries of lam
    go in the block-diagonal matrix of -s [lam]x (flat index into 3F x 3F, the lam row
    each reads, and the sign s times the cross-product sign)."""
    frames, rows, at, sign = [], [], [], []
    # -[l]x = [[0, l_z, -l_y], [-l_z, 0, l_x], [l_y, -l_x, 0]]
    pattern = ((0, 1, 2, 1.0), (0, 2, 1, -1.0), (1, 0, 2, -1.0), (1, 2, 0, 1.0),
               (2, 0, 1, 1.0), (2, 1, 0, -1.0))
    n = 3 * len(cons._signed_frames)
    for i, (fid, s, row) in enumerate(cons._signed_frames):
        frames.append(fid)
        for r, c, axis, sg in pattern:
            at.append((3 * i + r) * n + 3 * i + c)
            rows.append(row + axis)
            sign.append(s * sg)
    return frames, np.array(rows), np.array(at), np.array(sign)


def _triangles(cons: ConstraintSet) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the upper triangle of an nv x nv matrix, with and without the diagonal
    (np.triu builds its mask on every call)."""
    nv = cons.system.nv
    upper = np.triu(np.ones((nv, nv)))
    return upper, upper - np.eye(nv)


def hessian_by_time_variation(cons: ConstraintSet, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """:meth:`ConstraintSet.hessian_by_time_variation` of ``cons`` (documented there, in
    :mod:`pinlin.constraints`)."""
    sysm = cons.system
    nv = sysm.nv
    out = np.zeros((nv, nv))  # out[j, k] = lam . d(Phi_q e_k)/d(dq_j)
    if not cons._closures or not np.any(lam[:cons._loop_rows()]):
        return out
    kin, kd = sysm.kin_model, sysm.kin_data
    qk = sysm.kin_q(q)
    cols = sysm.kin_columns
    pin.computeJointJacobians(kin, kd, qk)
    pin.updateFramePlacements(kin, kd)
    zero = np.zeros((3, nv))
    angular = {}  # weld rows: (w1 - w2, w2), world angular-velocity Jacobians (3 x nv)
    for kind, f1, f2, row, _ in cons._closures:
        if kind == "weld":
            w1 = frame_jacobian(kin, kd, f1)[3:, cols]
            w2 = zero if f2 is None else frame_jacobian(kin, kd, f2)[3:, cols]
            angular[row] = (w1 - w2, w2)
    e = np.zeros(nv)
    for j in cons._support:
        e[j] = 1.0
        pin.computeJointJacobiansTimeVariation(kin, kd, qk, sysm.kin_v(e, spin=False))
        for kind, f1, f2, row, _ in cons._closures:
            dJ = frame_jacobian_variation(kin, kd, f1)[:, cols]
            if f2 is not None:
                dJ = dJ - frame_jacobian_variation(kin, kd, f2)[:, cols]
            out[j] += lam[row:row + 3] @ dJ[:3]
            if kind == "weld":
                lr = lam[row + 3:row + 6]
                d, w2 = angular[row]
                out[j] += lr @ dJ[3:]
                out[j] -= lr @ (0.5 * np.cross(d[:, j], d.T).T + np.cross(d[:, j], w2.T).T)
        e[j] = 0.0
    sym = 0.5 * (out + out.T)
    for block in cons._lie_blocks:
        sym[block, block] = out.T[block, block]
    return sym

