"""Second and third derivatives of point-loop closures from frame Jacobians, for stacks of
points: Phi_qq[w, .], the bias acceleration gamma = Phi_qq[v, v], its derivative
d gamma / dq (a third derivative of Phi) and the geometric stiffness lam^T Phi_qq.

Every point-loop or point-contact row is +-p, p the world position of a frame. When every
joint that moves a closure frame is a 1-DoF joint with a constant motion axis (revolute,
prismatic, helical, continuous: :attr:`pinlin.constraints.ConstraintSet` calls these
closures *batched*), all the derivatives below are polynomials in the columns of the frame's
LOCAL_WORLD_ALIGNED Jacobian at q, with w_j the angular and J_j the linear column of joint j
(zero off the frame's support):

- the world axis of joint j turns only with its ancestors: d w_j / dq_i = w_i x w_j for
  i < j (velocity indices grow from root to leaf along a support path; i = j gives 0), and
  d J_k / dq_i = w_min(i,k) x J_max(i,k) (the constraints module's Jacobi identity);
- so Phi_qq[w, .] column k (the Jacobian's variation along a velocity w, what Pinocchio's
  ``getFrameJacobianTimeVariation`` gives) is::

      D_k(w) = O_k x J_k + w_k x V_k,   O_k = sum_{j<k} w_j w_j,   V_k = sum_{j>=k} w_j J_j

  (O_k: the angular velocity of the body before joint k; V_k the point's velocity due to
  joint k and its descendants), two cumulative sums and two cross products per column;
- gamma = D(v) v (the frame's classical acceleration at zero joint acceleration);
- p(q) is a smooth function on R^nv, so its third partials p_ijk are symmetric and
  d gamma / dq_i = sum_jk v_j v_k p_ijk = sum_j v_j d D_i(v) / dq_j: the derivative of
  D_i(v) along v with v held. Along v, w_j' = E_j = O_j x w_j and J_j' = D_j (by the
  rules above), hence O_k' = sum_{j<k} v_j E_j, V_k' = sum_{j>=k} v_j D_j and::

      d gamma / dq_k = O_k' x J_k + O_k x D_k + E_k x V_k + w_k x V_k'

  O(nv) per column, no finite differences. (This is the *classical* acceleration's
  derivative: Pinocchio's ``getFrameAccelerationDerivatives`` differentiates the spatial
  acceleration, whose linear part differs from the classical one by omega x v; its
  q-derivative needs the chain rule with the velocity derivatives as well.)
- the geometric stiffness (lam^T Phi_qq)[j, k] = lam . (w_j x J_k) for j <= k, symmetric
  (:meth:`pinlin.constraints.ConstraintSet.hessian`, batched form).

Arrays: frame Jacobians stacked as ``J`` (N, F, 6, nv) in Pinocchio's row order (linear,
angular), F the moving closure frames in :class:`ClosurePlan` order; results are
(N, m, nv) over the constraint set's m rows (mimic rows: zero, they are linear). Units:
Phi_qq[w, .] [m/s per rad or 1/s], gamma [m/s^2], d gamma / dq [m/s^2 per rad or per m].
tests/test_loop_kernels.py checks each against Pinocchio (time variation, classical
acceleration, the constraints' Hessian) and d gamma / dq against central differences.
"""

from __future__ import annotations

import functools
import weakref
from typing import NamedTuple

import numpy as np
import pinocchio as pin

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class ClosurePlan(NamedTuple):
    """What the stacked kernels need of a constraint set, fixed for it.

    Attributes:
        frames: Kinematic-model frame ids of the moving closure frames (F).
        P: (m, 3F) signed map from the stacked frame positions to the rows (+1 frame1,
            -1 frame2; mimic rows zero).
        mimic: (m, nv) the constant Jacobian of the mimic rows (zero elsewhere).
        signs: (F,) +1 or -1 per frame.
        rows: (F,) first constraint row of each frame's closure.
    """

    frames: tuple[int, ...]
    P: np.ndarray
    mimic: np.ndarray
    signs: np.ndarray
    rows: np.ndarray


def plan(system) -> ClosurePlan | None:
    """The plan of ``system``'s constraints, or None where the stacked kernels do not apply:
    a steady rotation, weld closures, or a closure moved by a joint that is not 1-DoF with a
    constant axis (those go through Pinocchio point by point)."""
    return _plan(system.constraints) if system.rotation is None else None


def _plan(cons) -> ClosurePlan | None:
    if cons not in _PLANS:
        _PLANS[cons] = _build(cons)
    return _PLANS[cons]


_PLANS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _build(cons) -> ClosurePlan | None:
    if not cons._batched_hessian:
        return None
    nv = cons.system.nv
    signed = cons._signed_frames
    frames = tuple(int(f) for f, _, _ in signed)
    P = np.zeros((cons.size, 3 * len(frames)))
    for i, (_, s, row) in enumerate(signed):
        P[row:row + 3, 3 * i:3 * i + 3] = s * np.eye(3)
    mimic = np.zeros((cons.size, nv))
    first = cons.size - len(cons._mimic_rows)
    for k, (iv_m, iv_j, mult, _, _, _) in enumerate(cons._mimic_rows):
        mimic[first + k, iv_m] += 1.0
        mimic[first + k, iv_j] -= mult
    signs = np.array([s for _, s, _ in signed])
    rows = np.array([r for _, _, r in signed], dtype=int)
    for arr in (P, mimic, signs, rows):
        arr.setflags(write=False)
    return ClosurePlan(frames, P, mimic, signs, rows)


def frame_jacobian(model: pin.Model, data: pin.Data, frame: int) -> np.ndarray:
    """The LOCAL_WORLD_ALIGNED frame Jacobian (6, nv), also where nv = 1 (eigenpy returns a
    6x1 matrix as a vector); the joint Jacobians must be computed."""
    return pin.getFrameJacobian(model, data, frame, LWA).reshape(6, -1)


def frame_jacobian_variation(model: pin.Model, data: pin.Data, frame: int) -> np.ndarray:
    """Its time variation dJ/dt (6, nv), as :func:`frame_jacobian`; the joint Jacobians' time
    variation must be computed."""
    return pin.getFrameJacobianTimeVariation(model, data, frame, LWA).reshape(6, -1)


def frame_jacobians(model: pin.Model, data: pin.Data, q: np.ndarray, frames: tuple[int, ...],
                    out: np.ndarray) -> None:
    """One ``computeJointJacobians(q)`` and a LOCAL_WORLD_ALIGNED ``getFrameJacobian`` per
    frame, into ``out`` (F, 6, nv)."""
    pin.computeJointJacobians(model, data, q)
    for i, fid in enumerate(frames):
        out[i] = frame_jacobian(model, data, fid)


def _columns(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(linear, angular) columns as (N, F, nv, 3) vectors."""
    return J[:, :, :3, :].transpose(0, 1, 3, 2), J[:, :, 3:, :].transpose(0, 1, 3, 2)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (numpy's ``cross`` without its axis bookkeeping)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


@functools.lru_cache(maxsize=32)
def _sums(nv: int) -> tuple[np.ndarray, np.ndarray]:
    """(strictly lower, upper with diagonal) triangles of ones: sum_{j<k} and sum_{j>=k} as
    matrix products over the column axis."""
    ones = np.ones((nv, nv))
    lower, upper = np.tril(ones, -1), np.triu(ones)
    lower.setflags(write=False)
    upper.setflags(write=False)
    return lower, upper


def _exclusive(x: np.ndarray) -> np.ndarray:
    """sum_{j<k} x_j along axis 2 of (N, F, nv, 3)."""
    return _sums(x.shape[2])[0] @ x


def _from_k(x: np.ndarray) -> np.ndarray:
    """sum_{j>=k} x_j along axis 2 of (N, F, nv, 3)."""
    return _sums(x.shape[2])[1] @ x


def _variation(lin: np.ndarray, ang: np.ndarray, w: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(D(w), O, V) per frame (module docstring), all (N, F, nv, 3)."""
    wb = w[:, None, :, None]
    Om = _exclusive(wb * ang)
    V = _from_k(wb * lin)
    return _cross(Om, lin) + _cross(ang, V), Om, V


def to_rows(plan_: ClosurePlan, X: np.ndarray) -> np.ndarray:
    """Per-frame column vectors X (N, F, nv, 3) mapped to the constraint rows (N, m, nv)."""
    N, F, nv, _ = X.shape
    return plan_.P @ X.transpose(0, 1, 3, 2).reshape(N, 3 * F, nv)


def jacobian(plan_: ClosurePlan, J: np.ndarray) -> np.ndarray:
    """Phi_q (N, m, nv) from the frame Jacobians (mimic rows included)."""
    N, F, _, nv = J.shape
    return plan_.P @ J[:, :, :3, :].reshape(N, 3 * F, nv) + plan_.mimic


def variation(plan_: ClosurePlan, J: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Phi_qq[w, .] (N, m, nv): the variation of Phi_q along velocities w (N, nv)."""
    lin, ang = _columns(J)
    return to_rows(plan_, _variation(lin, ang, w)[0])


def bias_terms(plan_: ClosurePlan, J: np.ndarray, v: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Phi_qq[v, .], gamma = Phi_qq[v, v], d gamma / dq at v held): (N, m, nv), (N, m),
    (N, m, nv) [module docstring]."""
    lin, ang = _columns(J)
    D, Om, V = _variation(lin, ang, v)
    vb = v[:, None, :, None]
    E = _cross(Om, ang)
    dO = _exclusive(vb * E)
    dV = _from_k(vb * D)
    dgamma = _cross(dO, lin) + _cross(Om, D) + _cross(E, V) + _cross(ang, dV)
    Jv = to_rows(plan_, D)
    gamma = (Jv @ v[:, :, None])[..., 0]
    return Jv, gamma, to_rows(plan_, dgamma)


def hessian(plan_: ClosurePlan, J: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """lam^T Phi_qq (N, nv, nv), symmetric, for constraint forces lam (N, m) [N or N*m]."""
    lin, ang = _columns(J)
    lam_f = lam[:, plan_.rows[:, None] + np.arange(3)] * plan_.signs[:, None]  # (N, F, 3)
    Y = _cross(lin, lam_f[:, :, None, :])  # J_k x lam per frame
    X = np.einsum("nfjc,nfkc->njk", ang, Y)
    nv = X.shape[-1]
    upper = np.triu(np.ones((nv, nv)))
    strict = upper - np.eye(nv)
    return X * upper + (X * strict).transpose(0, 2, 1)


__all__ = ["ClosurePlan", "bias_terms", "frame_jacobians", "hessian", "jacobian", "plan",
           "to_rows", "variation"]
