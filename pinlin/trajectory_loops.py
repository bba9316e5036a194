"""Trajectories of mechanisms: loops (and mimic couplings) along ``linearize_trajectory``.

Point k of a mechanism's trajectory is the model :func:`pinlin.linearize` gives at
``q=q[k], v=v[k], u=u[k]`` (independent coordinates, partitioned basis, eqs. 9.8-9.11 with
every velocity term: :mod:`pinlin.formulations.motion`), with one difference that a trajectory
needs: **every point has the same coordinates.** The partition (independent constraint rows
and independent coordinates z) is chosen once, at point 0, exactly as :func:`pinlin.linearize`
chooses it there (the scene's ``operating_point.independent``, else pinlin's pivoted QR), and
frozen; so are the state names ``q:<z>``, ``v:<z>``. A time-varying LQR, an iLQR pass or a
Riccati recursion chains the points' models, which only makes sense in one set of
coordinates: pinlin never re-partitions along a trajectory.

Two passes:

1. :func:`close_loops` (serial, in the calling process: each point starts from the one
   before): point k is assembled (Newton on the dependent coordinates, z held,
   :func:`pinlin.assembly.assemble`) from the given q[k] when it closes the loops already
   (max |Phi| <= :data:`~pinlin.assembly.ASSEMBLY_TOL`: it is kept as given, as
   ``linearize`` keeps it), else from q[k]'s independent coordinates with the dependent ones
   of point k-1's solution (the warm start: it keeps the branch the trajectory is on). There
   the frozen partition is checked: the 2-norm condition of Phi_d, the Jacobian block of the
   dependent coordinates, above :data:`REFUSE_CONDITION` (the limit at which ``linearize``
   refuses a partition) raises a :class:`~pinlin.ModelError` naming the point; above
   :data:`WARN_CONDITION` one :class:`~pinlin.AccuracyWarning` names the worst point.
2. :func:`fill` (any process: :mod:`pinlin.batch`, :mod:`pinlin.parallel`): at each
   assembled point, the velocity projected onto the nullspace of Phi_q
   (:func:`~pinlin.formulations.motion.project_velocity`; the projected v is the model's
   ``v``, the size of the correction is reported), the constrained dynamics and the model
   (:func:`~pinlin.formulations.motion.state_at`,
   :func:`~pinlin.formulations.motion.linearize_moving`). A point depends only on its own
   assembled state, so workers and executors give the same arrays as one process.

What a trajectory model of a mechanism carries besides A, B, C, D, f0: ``q`` the assembled
configurations, ``v`` the projected velocities, ``a`` (N, nv) the accelerations of all
coordinates, ``lam`` (N, m) the constraint forces (names in ``info["lam_names"]``), and
``info["loops"]``: the per-point ``condition`` of Phi_d, ``position_correction`` (the norm of
``difference(q given, q assembled)``) and ``velocity_correction`` (the norm of the projection's
correction).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from . import loop_kernels as lk
from . import trajectory_assembly
from .assembly import ASSEMBLY_TOL, Partition, assemble, in_one_unit, partition
from .batch_screen import at_point
from .conditioning import AccuracyWarning
from .derivatives import resolve_steps
from .exceptions import ModelError, PinlinError
from .formulations import moving_batch
from .formulations.constrained import constrained_effects
from .formulations.independent import output_stack
from .formulations.motion import linearize_moving, refuse_unsupported, singular_dynamics, state_at
from .system import System

#: Condition of Phi_d at which a trajectory's frozen partition is refused (the limit at which
#: :func:`pinlin.assembly.partition` refuses one for a single model).
REFUSE_CONDITION = 1e12
#: Condition of Phi_d above which an AccuracyWarning names the worst point (the level at which
#: a single model's notes say "near a singular position").
WARN_CONDITION = 1e6
#: Points per stacked block of :func:`fill` (bounds the temporaries: the delta's block of
#: third-derivative terms is 64 x 6 x 12 x 3 numbers per array).
BLOCK = 64
#: Points assembled between two progress reports of the serial assembly pass.
REPORT_EVERY = 256


@dataclass(frozen=True)
class FrozenPartition:
    """The partition chosen at a trajectory's point 0, used at every point (picklable: it
    travels to worker processes).

    Attributes:
        rows: Indices of the independent constraint rows.
        dropped: Names of the redundant rows dropped.
        independent: Velocity indices of the independent coordinates z.
        dependent: Velocity indices of the others.
        chosen: Whether pinlin chose z (True) or the scene named it.
    """

    rows: tuple[int, ...]
    dropped: tuple[str, ...]
    independent: tuple[int, ...]
    dependent: tuple[int, ...]
    chosen: bool

    @classmethod
    def of(cls, part: Partition) -> FrozenPartition:
        return cls(tuple(int(i) for i in part.rows), tuple(part.dropped),
                   tuple(int(i) for i in part.independent),
                   tuple(int(i) for i in part.dependent), bool(part.chosen))

    def at(self, condition: float) -> Partition:
        """The :class:`~pinlin.assembly.Partition` at a point where Phi_d has ``condition``."""
        return Partition(np.array(self.rows, dtype=int), self.dropped,
                         np.array(self.independent, dtype=int),
                         np.array(self.dependent, dtype=int), self.chosen, float(condition))

    def state_names(self, system: System) -> tuple[str, ...]:
        coords = [system.coordinate_names[i] for i in self.independent]
        return tuple([f"q:{c}" for c in coords] + [f"v:{c}" for c in coords])


def refuse(system: System, derivatives: str) -> None:
    """What a mechanism's trajectory cannot do (what :func:`pinlin.linearize` cannot do at a
    moving state: a floating base, weld loops and contacts). With fd3/fd5 its points are
    linearized one by one (:mod:`pinlin.formulations.moving_fd`).

    Raises:
        ModelError: naming the scene and what is not supported.
    """
    refuse_unsupported(system, "independent", None, derivatives)


def first_pass(progress: Callable[[int, int], None], N: int) -> Callable[[int], None]:
    """``report(k)`` for :func:`close_loops`: ``progress(k, 2N)``, k points assembled (a
    mechanism's progress counts N assembled points, then N linearized ones)."""
    return lambda done: progress(done, 2 * N)


def second_pass(progress: Callable[[int, int], None], N: int) -> Callable[[int, int], None]:
    """``progress`` for the linearization pass of a mechanism of N points: ``done`` points
    linearized are step N + done of 2N."""
    return lambda done, total: progress(N + done, N + total)


def close_loops(system: System, Q: np.ndarray, report: Callable[[int], None] | None = None
                ) -> tuple[np.ndarray, FrozenPartition, np.ndarray, np.ndarray,
                           np.ndarray | None]:
    """Assemble every point (module docstring, pass 1) and check the frozen partition there.

    Args:
        system: A system with loops or mimic couplings.
        Q: (N, nq) configurations as given [m, rad] (normalized).
        report: Called as ``report(k)`` with the number of points assembled, every
            :data:`REPORT_EVERY` points and at the end.

    Returns:
        (Q assembled (N, nq), the partition of point 0, the condition of Phi_d at each point
        (N,), the norm of difference(q given, q assembled) at each point (N,) [m or rad],
        the closure frames' Jacobians at the assembled points (N, F, 6, nv) where the stacked
        assembly computed them, else None).

    Raises:
        AssemblyError: the loops do not close at some point (the message starts with
            "trajectory point k: ").
        SceneError: the scene's independent coordinates cannot parametrize the mechanism at
            point 0.
        ModelError: the partition of point 0 is singular (Phi_d's condition above
            :data:`REFUSE_CONDITION`) at a later point, naming it.
    """
    cons, model = system.constraints, system.model
    N = Q.shape[0]
    out = np.empty_like(Q)
    condition = np.empty(N)
    moved = np.empty(N)
    try:  # point 0 exactly as pinlin.linearize (formulations.motion.moving_point) does it
        guess = partition(system, Q[0], check=False)
        q = assemble(system, Q[0], guess.independent)
        part = partition(system, q, cons.jacobian(q))
    except PinlinError as exc:
        raise at_point(exc, 0) from None
    if not len(part.independent):
        raise ModelError(f"trajectory point 0: scene '{system.scene.name}': the constraints hold "
                         "every coordinate (no independent coordinate moves), so its models "
                         "have no state; a single pinlin.linearize gives that (0 x 0) model")
    frozen = FrozenPartition.of(part)
    out[0], condition[0] = q, part.condition
    plan = lk.plan(system)
    J = None
    if plan is not None and len(part.dependent) and plan.frames:
        J = _close_stacked(system, plan, Q, frozen, out, condition, report)
    else:
        _close_per_point(system, Q, frozen, out, condition, report)
    if report is not None:
        report(N)
    for k in range(N):
        moved[k] = np.linalg.norm(pin.difference(model, Q[k], out[k]))
    worst = int(np.argmax(condition))
    if condition[worst] > WARN_CONDITION:
        warnings.warn(AccuracyWarning(
            f"scene '{system.scene.name}': near a singular position at trajectory point "
            f"{worst}: the Jacobian of the dependent coordinates (independent coordinates "
            f"{_names(system, frozen)}) has condition {condition[worst]:.3g}; about "
            f"{max(16 - np.log10(condition[worst]), 0):.0f} significant digits of that "
            "point's model are reliable", float(condition[worst])), stacklevel=3)
    return out, frozen, condition, moved, J


def _close_stacked(system: System, plan: lk.ClosurePlan, Q: np.ndarray,
                   frozen: FrozenPartition, out: np.ndarray, condition: np.ndarray,
                   report: Callable[[int], None] | None = None) -> np.ndarray:
    """Points 1.. by :func:`pinlin.trajectory_assembly.close`, the conditions of Phi_d in
    one stacked SVD; the first singular point (before a point that failed to assemble) is
    refused, as :func:`_close_per_point` does. Returns the closure frames' Jacobians at the
    assembled points (N, F, 6, nv), for the model pass."""
    rows = np.array(frozen.rows, dtype=int)
    dep = np.array(frozen.dependent, dtype=int)
    z = np.array(frozen.independent, dtype=int)
    solved, J, failed, exc = trajectory_assembly.close(system, plan, Q, out[0], rows, z, dep,
                                                       report, REPORT_EVERY)
    last = len(Q) if failed is None else failed
    Gd = in_one_unit(system, lk.jacobian(plan, J[1:last])[:, rows][:, :, dep], rows, dep)
    with np.errstate(all="ignore"):
        condition[1:last] = np.linalg.cond(Gd) if len(Gd) else ()
    bad = np.flatnonzero(~(condition[:last] <= REFUSE_CONDITION))
    if bad.size:
        k = int(bad[0])
        raise ModelError(_singular_message(system, frozen, k, condition[k]))
    if failed is not None:
        if isinstance(exc, PinlinError):
            raise at_point(exc, failed) from None
        raise exc
    out[:] = solved
    return J


def _close_per_point(system: System, Q: np.ndarray, frozen: FrozenPartition,
                     out: np.ndarray, condition: np.ndarray,
                     report: Callable[[int], None] | None = None) -> None:
    """Points 1.. one by one: :func:`pinlin.assembly.assemble` from the previous point's
    dependent coordinates, the condition of Phi_d checked at each."""
    cons, model, N = system.constraints, system.model, len(Q)
    rows = np.array(frozen.rows, dtype=int)
    z, dep = np.array(frozen.independent, dtype=int), np.array(frozen.dependent, dtype=int)
    for k in range(1, N):
        q = Q[k]
        if cons.closure_error(cons.residual(q)) > ASSEMBLY_TOL:
            step = pin.difference(model, q, out[k - 1])  # warm start: the dependent
            step[z] = 0.0                                 # coordinates of point k-1
            try:
                q = assemble(system, pin.integrate(model, q, step), z)
            except PinlinError as exc:
                raise at_point(exc, k) from None
        else:
            q = q.copy()
        G = cons.jacobian(q)[rows]
        condition[k] = (float(np.linalg.cond(in_one_unit(system, G[:, dep], rows, dep)))
                        if len(dep) else 1.0)
        if not condition[k] <= REFUSE_CONDITION:  # NaN too
            raise ModelError(_singular_message(system, frozen, k, condition[k]))
        out[k] = q
        if report is not None and (k + 1) % REPORT_EVERY == 0:
            report(k + 1)


def _names(system: System, frozen: FrozenPartition) -> str:
    return "[" + ", ".join(system.coordinate_names[i] for i in frozen.independent) + "]"


def _singular_message(system: System, frozen: FrozenPartition, k: int, cond: float) -> str:
    how = "chosen by pinlin at point 0" if frozen.chosen else \
        "named by the scene's operating_point.independent"
    return (f"trajectory point {k}: scene '{system.scene.name}': the independent coordinates "
            f"{_names(system, frozen)} ({how}) cannot parametrize the mechanism here: the "
            f"Jacobian of the dependent coordinates is singular (condition {cond:.3g}, limit "
            f"{REFUSE_CONDITION:g}); every point of a trajectory has the same coordinates, so "
            "pinlin does not re-partition: split the trajectory at this point, or name "
            "independent coordinates that stay valid along it (operating_point.independent)")


def fill(system: System, arrays: Mapping[str, np.ndarray], lo: int, hi: int,
         frozen: FrozenPartition, derivatives: str = "analytic", step: Any = None) -> None:
    """The models of points lo:hi (module docstring, pass 2) into ``arrays``
    (:class:`pinlin.batch.Layout` of a mechanism: inputs q (assembled), v, u, cond; results
    A, B, f0, vp, acc, lam, dv and, with outputs, C and y); ``derivatives`` "fd3"/"fd5"
    (``step``): numerical derivatives, point by point.

    Raises:
        PinlinError: from the model of a point, its message starting with the point's index.
    """
    plan = lk.plan(system) if derivatives == "analytic" else None
    if plan is not None:
        for start in range(lo, hi, BLOCK):
            stop = min(hi, start + BLOCK)
            try:
                _fill_block(system, plan, arrays, start, stop, frozen)
            except np.linalg.LinAlgError:  # a singular point: find it and say why
                _fill_points(system, arrays, start, stop, frozen)
        return
    _fill_points(system, arrays, lo, hi, frozen, derivatives, step)


def _fill_block(system: System, plan: lk.ClosurePlan, arrays: Mapping[str, np.ndarray],
                lo: int, hi: int, frozen: FrozenPartition) -> None:
    """Points lo:hi at once (:mod:`pinlin.formulations.moving_batch`)."""
    rows = np.array(frozen.rows, dtype=int)
    z = np.array(frozen.independent, dtype=int)
    dep = np.array(frozen.dependent, dtype=int)
    Q, V = arrays["q"][lo:hi], arrays["v"][lo:hi]
    J = arrays.get("J")  # the closure frames' Jacobians from the assembly, when it had them
    st = moving_batch.states(system, plan, Q, V, arrays["u"][lo:hi], rows,
                             None if J is None else J[lo:hi])
    C, y = arrays.get("C"), arrays.get("y")
    frames = tuple(fid for _, fid in system.outputs.frames) if y is not None else ()
    mats = moving_batch.models(system, plan, st, rows, z, dep, frames)
    arrays["A"][lo:hi] = mats.A
    arrays["B"][lo:hi] = mats.B
    arrays["f0"][lo:hi] = mats.f0
    arrays["vp"][lo:hi] = st.v
    arrays["acc"][lo:hi] = st.a
    arrays["lam"][lo:hi] = st.lam
    arrays["dv"][lo:hi] = np.linalg.norm(st.correction, axis=1)
    if y is not None:  # the output frames from the models' kinematics (output_matrices')
        Cout, y[lo:hi] = output_stack(system, st.q, st.v, mats.frame_jacobians,
                                      mats.frame_positions)
        if C is not None:
            C[lo:hi] = moving_batch.reduce_outputs(Cout, mats.R, mats.W)
    bad = np.zeros(hi - lo, dtype=bool)
    for key in ("A", "B", "f0", "C"):
        stack = arrays.get(key)
        if stack is not None:
            bad |= ~np.isfinite(stack[lo:hi].reshape(hi - lo, -1).sum(axis=1))
    if bad.any():
        k = lo + int(np.flatnonzero(bad)[0])
        raise ModelError(f"trajectory point {k}: scene '{system.scene.name}': the linear "
                         "model has NaN or inf; a model with NaN or inf is never returned")


def _fill_points(system: System, arrays: Mapping[str, np.ndarray], lo: int, hi: int,
                 frozen: FrozenPartition, derivatives: str = "analytic",
                 step: Any = None) -> None:
    """Points lo:hi one by one (:func:`~pinlin.formulations.motion.state_at`,
    :func:`~pinlin.formulations.motion.linearize_moving`)."""
    cons = system.constraints
    Q, V, U, cond = arrays["q"], arrays["v"], arrays["u"], arrays["cond"]
    A, B, f0 = arrays["A"], arrays["B"], arrays["f0"]
    vp, acc, lam, dv = arrays["vp"], arrays["acc"], arrays["lam"], arrays["dv"]
    C, y = arrays.get("C"), arrays.get("y")
    for k in range(lo, hi):
        try:
            op, cp = state_at(system, Q[k], V[k], U[k], frozen.at(cond[k]), cons.jacobian(Q[k]))
            model = linearize_moving(system, op, cp, derivatives=derivatives, step=step,
                                     estimate_error=False)
        except PinlinError as exc:
            raise at_point(exc, k) from None
        except np.linalg.LinAlgError:
            raise at_point(singular_dynamics(system), k) from None
        A[k] = model.A
        B[k] = model.B
        f0[k] = model.f0
        vp[k] = op.v
        acc[k] = op.a
        lam[k] = op.lam
        dv[k] = np.linalg.norm(V[k] - op.v)
        if C is not None:
            C[k] = model.C
        if y is not None:
            y[k] = model.operating_point.y


def stacked_fields(system: System, arrays: Mapping[str, np.ndarray], layout,
                   frozen: FrozenPartition, moved: np.ndarray, derivatives: str = "analytic",
                   step: Any = None) -> dict[str, Any]:
    """The fields of a mechanism's :class:`pinlin.TrajectoryModel` (all but ``t`` and
    ``dt``) from its stacked arrays (read-only; C and D broadcast where constant)."""
    N, n, p, nu = layout.points, layout.n, layout.p, layout.nu
    states = frozen.state_names(system)
    C = arrays.get("C")
    if C is None:
        C = np.broadcast_to(np.eye(n), (N, n, n))
    y = arrays.get("y")
    if y is None:
        y = np.broadcast_to(np.zeros(p), (N, p))
    fields = {"A": arrays["A"], "B": arrays["B"], "C": C, "f0": arrays["f0"],
              "q": arrays["q"], "v": arrays["vp"], "u": arrays["u"], "a": arrays["acc"],
              "lam": arrays["lam"], "y": y}
    for arr in fields.values():
        arr.setflags(write=False)
    return {**fields, "D": np.broadcast_to(np.zeros((p, nu)), (N, p, nu)),
            "state_names": states, "input_names": system.input_names,
            "output_names": states if system.outputs is None else system.outputs.names,
            "name": system.scene.name,
            "info": info(system, frozen, arrays, moved, derivatives, step)}


def info(system: System, frozen: FrozenPartition, arrays: Mapping[str, np.ndarray],
         moved: np.ndarray, derivatives: str = "analytic", step: Any = None
         ) -> dict[str, Any]:
    """The metadata of a mechanism's trajectory model (module docstring); with fd3/fd5, the
    backend and its steps, as the open chains' record them."""
    cons = system.constraints
    extra = {} if derivatives == "analytic" else {"step": resolve_steps(derivatives, step)}
    return {
        **extra,
        "formulation": "independent", "derivatives": derivatives, "basis": "partitioned",
        "effects": constrained_effects(system), "velocity_terms": True,
        "base": "free" if system.base_joint else "fixed", "points": int(len(moved)),
        "path": "per point (loops)",
        "independent": [system.coordinate_names[i] for i in frozen.independent],
        "independent_chosen": frozen.chosen,
        "constraint_rows": [cons.row_names[i] for i in frozen.rows],
        "dropped_rows": list(frozen.dropped), "lam_names": list(cons.row_names),
        "loops": {"condition": arrays["cond"].tolist(),
                  "position_correction": moved.tolist(),
                  "velocity_correction": arrays["dv"].tolist()},
    }


__all__ = ["REFUSE_CONDITION", "REPORT_EVERY", "WARN_CONDITION", "FrozenPartition",
           "close_loops", "fill", "first_pass", "info", "refuse", "second_pass",
           "stacked_fields"]
