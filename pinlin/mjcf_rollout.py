"""MuJoCo's motion of a scene in pinlin's coordinates: the second engine ``pinlin.simulate`` is
checked against.

:func:`pinlin.mjcf.build` exports the scene with exactly its effects (Euler integrator, the
linearization's choice); :func:`rollout` switches the compiled model to another integrator
(RK4 by default: explicit, order 4, no implicit damping), writes pinlin's state with
:func:`pinlin.mjcf.set_state` (constant generalized forces in ``qfrc_applied``), steps
``mj_step`` and reads the state back at the requested times. MuJoCo's loop and mimic
equalities stay soft (see :mod:`pinlin.mjcf`): their leak is a model difference that no time
step removes, measured by comparing two impedances.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .exceptions import ArgumentError
from .mjcf import MujocoScene, _base_rotation, set_state

INTEGRATORS = {"RK4": mujoco.mjtIntegrator.mjINT_RK4, "Euler": mujoco.mjtIntegrator.mjINT_EULER,
               "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
               "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}


def use_integrator(ms: MujocoScene, integrator: str = "RK4") -> None:
    """Switch the compiled model's integrator (``ms.model.opt.integrator``) in place."""
    if integrator not in INTEGRATORS:
        raise ArgumentError("integrator", f"expected one of {', '.join(INTEGRATORS)}, got "
                                          f"{integrator!r}")
    ms.model.opt.integrator = INTEGRATORS[integrator]


def read_state(ms: MujocoScene, system) -> tuple[np.ndarray, np.ndarray]:
    """pinlin's (q, v) from MuJoCo's data: joints by name, a free joint's quaternion
    (w, x, y, z) -> (x, y, z, w) and its linear velocity world -> base frame, a continuous
    joint's angle -> (cos, sin)."""
    m, d = ms.model, ms.data
    q = np.zeros(system.nq)
    for name, j in system.joints.items():
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        adr = m.jnt_qposadr[jid]
        if m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_FREE:
            w, x, y, z = d.qpos[adr + 3:adr + 7] / np.linalg.norm(d.qpos[adr + 3:adr + 7])
            q[j.idx_q:j.idx_q + 7] = [*d.qpos[adr:adr + 3], x, y, z, w]
        elif j.continuous:
            q[j.idx_q:j.idx_q + 2] = [np.cos(d.qpos[adr]), np.sin(d.qpos[adr])]
        else:
            q[j.idx_q] = d.qpos[adr]
    v = d.qvel[ms.dof].copy()
    if ms.free:
        v[:3] = _base_rotation(system, q).T @ v[:3]
    return q, v


def rollout(ms: MujocoScene, system, q0: np.ndarray, v0: np.ndarray, tau: np.ndarray,
            t: np.ndarray, integrator: str = "RK4") -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's motion from (q0, v0) under the constant generalized force ``tau`` [N*m or N]
    at the times ``t`` [s] (t[0] the start; every interval a whole number of ``ms.dt``).

    Returns:
        (q (N, nq), v (N, nv)) in pinlin's coordinates.

    Raises:
        ArgumentError: an interval of ``t`` that is not a whole number of time steps.
    """
    t = np.asarray(t, dtype=float)
    steps = np.diff(t) / ms.dt
    counts = np.rint(steps).astype(int)
    if np.any(np.abs(steps - counts) > 1e-6) or np.any(counts < 1):
        raise ArgumentError("t", f"every interval must be a whole number of time steps "
                                 f"(dt = {ms.dt:g} s)")
    use_integrator(ms, integrator)
    set_state(ms, system, q0, v0, tau)
    Q, V = np.zeros((t.size, system.nq)), np.zeros((t.size, system.nv))
    Q[0], V[0] = read_state(ms, system)
    for k, n in enumerate(counts, start=1):
        for _ in range(n):
            mujoco.mj_step(ms.model, ms.data)
        Q[k], V[k] = read_state(ms, system)
    return Q, V


__all__ = ["INTEGRATORS", "read_state", "rollout", "use_integrator"]
