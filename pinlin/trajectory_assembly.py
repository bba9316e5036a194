"""Assembly of a trajectory's points, one after the other, for mechanisms whose closures the
stacked kernels cover (:func:`pinlin.loop_kernels.plan`): the fast path of
:func:`pinlin.trajectory_loops.close_loops`.

Point k (k >= 1) is kept as given when its loops close there (max |Phi| <=
:data:`~pinlin.assembly.ASSEMBLY_TOL`), as before (checked for all points first, from the
frame positions alone). Otherwise its dependent coordinates are
solved by Newton, z held, from a start *predicted* along the mechanism: the previous point's
solution moved by the tangent of the constraint manifold,
dq_d = -Phi_d^-1 Phi_z (z_k - z_{k-1}) (Phi_d, Phi_z: the previous point's Jacobian blocks on
the frozen independent rows), plus the curvature the step before showed where the new step
continues it (:func:`curvature`). The plain warm start's error is first order in the step of
z, the tangent's second order, with the curvature third order: each order saves about one
Newton iteration per point (on a smooth 200-point sweep one Newton step then closes the
loops), and the start stays on the branch the trajectory is on. Each iteration is one
``computeJointJacobians`` and a frame Jacobian per closure frame (the frame placements come
with it), a square solve on the independent rows (LAPACK ``gesv``) and ``pin.integrate``; it
stops at max |Phi| <= ASSEMBLY_TOL over all rows. Where this lean Newton does not converge within
:data:`MAX_ITER` steps (the residual grows, or Phi_d is singular), the point is assembled
exactly as before: :func:`pinlin.assembly.assemble` (Newton with backtracking) from q_k with
the previous point's dependent coordinates, which raises the usual AssemblyError.

The frame Jacobians at each final point come back too: the condition of Phi_d and the
predictor need them, and so does the model of the point.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from . import loop_kernels as lk
from .assembly import ASSEMBLY_TOL, assemble

#: Iterations of the lean Newton before a point falls back to the assembly with backtracking.
MAX_ITER = 6


class _Closures:
    """Phi and the frame Jacobians of one configuration, from one kinematics pass (few numpy
    calls: at these sizes each costs about as much as a Pinocchio kinematics pass)."""

    def __init__(self, system, plan: lk.ClosurePlan, rows: np.ndarray) -> None:
        cons = system.constraints
        self.plan, self.cons = plan, cons
        self.model, self.data = system.model, system.data
        point_plan = cons._point_plan
        self.anchor = point_plan[2] if point_plan is not None else np.zeros(cons.size)
        self.has_mimic = bool(cons._mimic_rows)
        F = len(plan.frames)
        self.positions = np.zeros(3 * F)
        # P on the rows of the flattened (F, 6, nv) Jacobians (angular rows: zero columns)
        P6 = np.zeros((cons.size, F, 6))
        P6[:, :, :3] = plan.P.reshape(cons.size, F, 3)
        self.P6 = P6.reshape(cons.size, 6 * F)
        self.P6_rows = self.P6[rows]
        self.mimic_rows = plan.mimic[rows]
        self.row_index = rows
        self.inverse_scale = (1.0 / cons.row_scale).tolist()  # closure_error's, per row

    def __call__(self, q: np.ndarray, J: np.ndarray) -> tuple[np.ndarray, float]:
        """(Phi(q) (m), its closure error, max |Phi_i| / row scale (as
        ``ConstraintSet.closure_error``)); the frame Jacobians into ``J`` (F, 6, nv)."""
        model, data = self.model, self.data
        pin.computeJointJacobians(model, data, q)
        pos = self.positions
        for i, fid in enumerate(self.plan.frames):
            J[i] = lk.frame_jacobian(model, data, fid)
            pos[3 * i:3 * i + 3] = pin.updateFramePlacement(model, data, fid).translation
        phi = np.dot(self.plan.P, pos)
        phi -= self.anchor
        if self.has_mimic:
            self.cons._mimic_residual(q, phi)
        return phi, max((abs(p) * s for p, s in zip(phi.tolist(), self.inverse_scale,
                                                    strict=True)), default=0.0)

    def closed(self, Q: np.ndarray) -> np.ndarray:
        """Whether each configuration of ``Q`` (N, nq) closes the loops (max |Phi| <=
        ASSEMBLY_TOL, relative to the row scales): positions only, one ``forwardKinematics``
        and a frame placement per closure frame per point, the residuals stacked."""
        model, data, frames = self.model, self.data, self.plan.frames
        pos = np.empty((len(Q), 3 * len(frames)))
        for k, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            for i, fid in enumerate(frames):
                pos[k, 3 * i:3 * i + 3] = pin.updateFramePlacement(model, data, fid).translation
        phi = pos @ self.plan.P.T - self.anchor
        if self.has_mimic:
            for k, q in enumerate(Q):
                self.cons._mimic_residual(q, phi[k])
        return (np.abs(phi) / self.cons.row_scale).max(axis=1, initial=0.0) <= ASSEMBLY_TOL

    def rows(self, J: np.ndarray) -> np.ndarray:
        """Phi_q on the independent rows (r x nv) from the frame Jacobians ``J``."""
        return np.dot(self.P6_rows, J.reshape(self.P6.shape[1], -1)) + self.mimic_rows


def close(system, plan: lk.ClosurePlan, Q: np.ndarray, q0: np.ndarray, rows: np.ndarray,
          z: np.ndarray, dep: np.ndarray, report: Callable[[int], None] | None = None,
          every: int = 256) -> tuple[np.ndarray, np.ndarray, int | None, Exception | None]:
    """Assemble points 1.. of ``Q`` (N, nq) [m, rad] after point 0's solution ``q0`` (module
    docstring), in the frozen partition (rows, z, dep); ``report(k)`` is called with the
    number of points assembled every ``every`` points.

    Returns:
        (Q assembled (N, nq), the frame Jacobians there (N, F, 6, nv), the index of the point
        whose assembly failed or None, and its exception). The points after a failed one are
        not assembled.
    """
    model = system.model
    N, nv = Q.shape[0], system.nv
    evaluate = _Closures(system, plan, rows)
    out = np.empty_like(Q)
    J = np.zeros((N, len(plan.frames), 6, nv))
    out[0] = q0
    evaluate(q0, J[0])
    step = np.zeros(nv)
    closed = evaluate.closed(Q)
    for k in range(1, N):
        q = Q[k]
        if closed[k]:
            out[k] = q
            evaluate(q, J[k])
            if report is not None and (k + 1) % every == 0:
                report(k + 1)
            continue
        # Start: point k-1's dependent coordinates moved along the manifold's tangent, and
        # along its curvature where the step continues the previous one.
        back = pin.difference(model, q, out[k - 1])
        step[:] = back
        step[z] = 0.0
        Gr = evaluate.rows(J[k - 1])
        past = pin.difference(model, out[k - 1], out[k - 2]) if k >= 2 else np.zeros(nv)
        rhs = np.dot(Gr[:, z], np.stack([back[z], past[z]], axis=1))
        _, _, x, info = lapack.dgesv(Gr[:, dep], rhs)
        if info == 0:   # (no previous step at k = 1: past = 0, no curvature term)
            step[dep] += x[:, 0] + curvature(back[z], past[z]) * (past[dep] + x[:, 1])
        solved = _newton(evaluate, model, pin.integrate(model, q, step), J[k], dep)
        if solved is None:  # as before: Newton with backtracking from the plain warm start
            step[:] = back
            step[z] = 0.0
            try:
                solved = assemble(system, pin.integrate(model, q, step), z)
            except Exception as exc:  # noqa: BLE001 (the caller decides what to raise)
                return out, J, k, exc
            evaluate(solved, J[k])
        out[k] = solved
        if report is not None and (k + 1) % every == 0:
            report(k + 1)
    return out, J, None, None


#: How far the step of z may leave the line of the previous step (relative) for the
#: curvature of the previous step to be extrapolated (:func:`curvature`).
CURVATURE_ALIGNMENT = 0.25


def curvature(back: np.ndarray, past: np.ndarray) -> float:
    """The weight alpha^2 of the previous step's curvature term in the start of the next
    point, 0 where it does not apply (``back``, ``past``: the z parts of the tangent vectors
    difference(q_k, q_{k-1}) and difference(q_{k-1}, q_{k-2}), the guess k and the two points
    before it).

    Along the manifold the dependent coordinates follow d(z) = d_{k-1} + T dz +
    1/2 H[dz, dz] + O(dz^3) about point k-1 (T: the tangent -Phi_d^-1 Phi_z there). Point
    k-2 lies at dz = p = ``past``, so its dependent coordinates minus the tangent's
    prediction there measure c = 1/2 H[p, p] + O(p^3). The new step dz = -``back``, with
    ``back`` = alpha p + o (o normal to p), has 1/2 H[dz, dz] = alpha^2 c + alpha H[p, o] +
    1/2 H[o, o]: with alpha^2 c added the predictor's error drops from 1/2 H[dz, dz] to the
    terms in o and O(dz^3), and one Newton step then usually closes the loops to
    ASSEMBLY_TOL where two were needed (a smooth trajectory turns slowly: |o| ~ 5 % of |dz|
    on the delta's 200-point sweep). A step that turns further (|o| above
    :data:`CURVATURE_ALIGNMENT` of |dz|) or is more than 4x as long as the previous one gets
    no curvature term: the tangent alone, as for the first step."""
    pp = float(np.dot(past, past))
    if pp == 0.0:
        return 0.0
    alpha = float(np.dot(back, past)) / pp
    off = back - alpha * past
    if abs(alpha) > 4.0 or float(np.dot(off, off)) > CURVATURE_ALIGNMENT ** 2 * float(
            np.dot(back, back)):
        return 0.0
    return alpha * alpha


def _newton(evaluate: _Closures, model: pin.Model, q: np.ndarray, J: np.ndarray,
            dep: np.ndarray) -> np.ndarray | None:
    """Newton on the independent rows over the dependent coordinates from ``q``: q with
    max |Phi| <= ASSEMBLY_TOL (its frame Jacobians left in ``J``), or None (no convergence
    in :data:`MAX_ITER` steps, a growing residual, a singular Phi_d)."""
    step = np.zeros(model.nv)
    best = np.inf
    for _ in range(MAX_ITER):
        phi, worst = evaluate(q, J)
        if worst <= ASSEMBLY_TOL:
            return q
        if not worst < best:  # growing (or NaN): leave it to the assembly with backtracking
            return None
        best = worst
        _, _, x, info = lapack.dgesv(evaluate.rows(J)[:, dep], -phi[evaluate.row_index])
        if info != 0:
            return None
        step[dep] = x
        q = pin.integrate(model, q, step)
    return None


__all__ = ["MAX_ITER", "close"]
