"""Linear models along a trajectory: ``pinlin.linearize_trajectory`` and ``TrajectoryModel``.

A trajectory is N states (q_k, v_k, u_k), optionally at times t_k. Its model is the stack of
the N affine models of :func:`pinlin.linearize` at those states (independent formulation;
mechanisms in the independent coordinates of their first point, :mod:`pinlin.trajectory_loops`)::

    x' = f0_k + A_k x + B_k u,   y = C_k x + D_k u,   x = [dq; v] about (q_k, v_k), u about u_k

stored as arrays with the point first: ``A`` (N, n, n), ``B`` (N, n, m), ``C`` (N, p, n),
``D`` (N, p, m), ``f0`` (N, n); ``model.at(k)`` is the k-th :class:`~pinlin.LinearModel`.
How the stack is computed (per point ``pin.aba``, ``pin.computeMinverse``,
``pin.computeRNEADerivatives`` and one product, or :func:`pinlin.linearize` per point where
those kernels do not apply) is in :mod:`pinlin.batch`
(mechanisms: assembled and linearized point by point, :mod:`pinlin.trajectory_loops`);
worker processes and executors (Dask) in :mod:`pinlin.parallel`; files in
:mod:`pinlin.trajectory_files`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from . import trajectory_buffers as buffers
from . import trajectory_loops as loops
from .batch import Layout, Options, batch_path, check, constant_outputs, fill
from .derivatives import resolve_steps
from .exceptions import ArgumentError
from .linearization import _system
from .resources import check_memory
from .rest_schedule import (
    holding_inputs,
    needs_single_calls,
    rest_info,
    rest_options,
    sensitivity,
)
from .rest_schedule import single_calls as schedule_by_single_calls
from .scene import COEFFICIENT_LIMIT, POSITION_LIMIT, Scene
from .system import System
from .trajectory_inputs import check_normalized, check_options, points, times
from .trajectory_model import _SECOND_ORDER, TrajectoryModel

#: Points per progress report (and per vectorized block) when one process does the work.
SERIAL_BLOCK = 256


def linearize_trajectory(scene: Scene | System | str | Path, q: np.ndarray,
                         v: np.ndarray | None = None, u: np.ndarray | None = None,
                         t: np.ndarray | None = None, *, workers: int = 1,
                         executor: Executor | None = None, derivatives: str = "analytic",
                         chunk: int | None = None,
                         step: float | Mapping[str, float] | None = None,
                         progress: Callable[[int, int], None] | None = None,
                         second_order: bool = False,
                         allow_non_equilibrium: bool | None = None,
                         out: TrajectoryModel | None = None) -> TrajectoryModel:
    """Linear models of a scene at N states, stacked (see :class:`TrajectoryModel`).

    Point k is the model :func:`pinlin.linearize` gives at ``q=q[k], v=v[k], u=u[k]``
    (independent formulation). With analytic derivatives and no steady rotation the stack of
    an open chain comes from Pinocchio's kernels per point (``aba``, ``computeMinverse``,
    ``computeRNEADerivatives``) written straight into the arrays (:mod:`pinlin.batch`);
    otherwise from :func:`pinlin.linearize` per point.

    A mechanism (loops, mimic couplings, contacts; weld loops, Lie-group joints and a
    standing robot's floating base, and fd3/fd5, point by point) is assembled point by
    point, each from the one before where q[k] does not close its loops, its velocities
    projected onto the nullspace of Phi_q, and
    every point is linearized in the independent coordinates chosen at point 0
    (:mod:`pinlin.trajectory_loops`): point k is what :func:`pinlin.linearize` gives at
    ``q=model.q[k], v=v[k], u=u[k]`` (the assembled configuration) whenever that call chooses
    the same coordinates (always when the scene names them). Contacts stay anchored where
    the scene's posture puts their frames, for every point: a moving trajectory holds them.

    Without ``v`` and ``u`` the points are a *gain schedule* of rest points: point k is the
    model :func:`pinlin.linearize` gives at ``q=q[k]`` (``solve = "inputs"``: at rest, the
    holding inputs u0 and constraint forces solved at every point; a mechanism's at its
    assembled configuration), to rounding; ``model.u`` holds those inputs, ``model.a`` is
    zero at every equilibrium (:mod:`pinlin.rest_schedule`). A mechanism is assembled from
    point to point, so the schedule stays on the assembly branch of its first point (and
    point k is the single call at ``q=model.q[k]`` whenever that call chooses the same
    coordinates). Scenes with contacts (anchored where each q[k] puts their frames, as a
    single call anchors them), weld loops, a floating base, or a mechanism's numerical
    derivatives are scheduled by single calls, one per point, in this process.

    Args:
        scene: A :class:`Scene`, its :class:`System`, or a scene file / URDF / bundled scene /
            robot name.
        q: (N, nq) configurations (normalized quaternions and (cos, sin) pairs) [m, rad].
        v: (N, nv) velocities [rad/s or m/s]; None (with ``u``): a schedule of rest points.
        u: (N, nu) inputs [N*m or N], in the order of the model's ``input_names``; None (with
            ``v``): solved at every point (a schedule of rest points).
        t: (N,) times [s], strictly increasing, kept with the models; or None.
        workers: Processes sharing the work on this machine (>= 1); they write into shared
            memory (:mod:`pinlin.parallel`). Where other threads run, the pool is started by
            ``forkserver``, which imports the main script: guard it with
            ``if __name__ == "__main__":`` as multiprocessing requires.
        executor: A ``concurrent.futures.Executor`` (a Dask cluster's
            ``client.get_executor()``) that runs chunks of points where it likes; not with
            ``workers > 1``.
        derivatives: ``"analytic"``, ``"fd3"`` or ``"fd5"``.
        chunk: Points per task for workers and executors (default: about 4 tasks per worker,
            16 tasks for an executor).
        step: Finite-difference step(s) for fd3/fd5, as for :func:`pinlin.linearize`.
        progress: Called as ``progress(done, total)`` [points] as the work advances. A
            mechanism's points are assembled one after the other first (in this process),
            then linearized: its total is 2N, the first N steps the points assembled, the
            next N the points linearized.
        second_order: Also store M, C_damp, K (N, nv, nv) and Bu of every point, so that
            ``at(k)`` carries the second-order matrices :func:`pinlin.linearize` gives there
            (open chains; on the batch path three copies more per point,
            :mod:`pinlin.batch`). A mechanism's schedule of rest points has them in its
            independent coordinates (nz x nz; by single calls); its given-state trajectory
            refuses them: a single model at a moving state of a mechanism has none.
        allow_non_equilibrium: A schedule of rest points only: accept open-chain points that
            the inputs cannot hold (their models describe the motion about (q, v = 0)); None:
            the scene's ``operating_point.allow_non_equilibrium``.
        out: A model an earlier call returned for this scene (open chain, same number of
            points and options, this process): the new models are written into its arrays
            and it is returned, updated, as NumPy's ``out=`` (:mod:`pinlin.trajectory_buffers`:
            no fresh pages per call). If the call fails after it began writing, ``out``'s
            matrices are NaN and it cannot be reused.

    Raises:
        ShapeError: an array of the wrong shape (the message names the argument).
        ArgumentError: NaN, inf or out-of-range entries, configurations that are not
            normalized (naming the argument and the first bad row), or a bad option
            (``second_order=True`` on a mechanism; v without u or u without v; workers or an
            executor for a schedule scheduled by single calls).
        SceneError: a schedule of rest points of a scene whose ``operating_point.solve`` is
            not ``"inputs"``.
        EquilibriumError: a point of a schedule of rest points that the inputs (and a
            mechanism's constraint forces) cannot hold, naming it.
        ModelError: a point where the model cannot be built (a singular mass matrix; for a
            mechanism, a point where the independent coordinates of point 0 cannot
            parametrize it), naming the first such point; a mechanism with what
            :func:`pinlin.linearize` does not support at a moving state (fd3/fd5, welds, a
            floating base).
        AssemblyError: a mechanism's loops do not close at a point, naming it.
        ResourceError: the stacked models would exceed the memory limit
            (:func:`pinlin.set_memory_limit`).
    """
    system = _system(scene)
    allow = rest_options(system, v, u, allow_non_equilibrium)
    workers, chunk, second_order = check_options(system, derivatives, step, workers, chunk,
                                                executor, progress, second_order,
                                                allow is not None)
    nu = len(system.actuated)
    Q = points("q", q, system.nq, "configurations", None, POSITION_LIMIT)
    N = Q.shape[0]
    rest = allow is not None  # a schedule of rest points: v = 0, u solved (rest_schedule)
    V = np.zeros((N, system.nv)) if rest else points("v", v, system.nv, "velocities", N,
                                                     COEFFICIENT_LIMIT)
    U = np.zeros((N, nu)) if rest else points("u", u, nu, "inputs", N, COEFFICIENT_LIMIT)
    check_normalized(system, Q)
    T = times(t, N)
    if rest and needs_single_calls(system, derivatives, second_order):  # in this process
        if out is not None:
            raise ArgumentError("out", f"scene '{system.scene.name}' is scheduled by single "
                                       "calls (contacts, weld loops, a floating base, or a "
                                       "mechanism's numerical derivatives): no arrays to reuse")
        return TrajectoryModel.trusted(**schedule_by_single_calls(
            system, Q, derivatives=derivatives, step=step, allow=bool(allow),
            parallel=workers > 1 or executor is not None, progress=progress,
            second_order=second_order), t=T, dt=0.0)

    inputs = {"q": Q, "v": V, "u": U}
    frozen = moved = None
    if system.constraints:  # a mechanism: pinlin.trajectory_loops
        loops.refuse(system, derivatives)
        check_memory(Q.nbytes, f"scene '{system.scene.name}': the assembled configurations "
                               f"of {N} points", "8 bytes a number")
        inputs["q"], frozen, inputs["cond"], moved, jacobians = loops.close_loops(
            system, Q, None if progress is None else loops.first_pass(progress, N))
        if jacobians is not None:  # the assembly's last kinematics pass, for the models
            inputs["J"] = jacobians
        progress = None if progress is None else loops.second_pass(progress, N)
    options = Options(derivatives, step, frozen, second_order)
    layout = Layout.of(system, N, None if frozen is None else len(frozen.independent),
                       second_order, inputs["J"].shape[1] if "J" in inputs else 0)
    check_memory(layout.offsets()[1], f"scene '{system.scene.name}': the models of {N} points",
                 "A, B, f0 (and M, C_damp, K) stacked, 8 bytes a number")
    reused = None
    if out is not None:
        if frozen is not None:
            raise ArgumentError("out", "reuses an open chain's arrays; a mechanism's come from "
                                       "its assembly, point by point")
        reused = buffers.reusable(out, system, layout, workers, executor)
    if rest:
        inputs["u"], at_rest, family, lam = holding_inputs(system, inputs["q"], bool(allow),
                                                           inputs.get("J"))
    if executor is not None:
        from .parallel_executors import run_executor

        arrays = run_executor(system, layout, inputs, options, executor, chunk, progress)
        check(system, arrays)
    elif workers > 1:
        from .parallel import run_processes

        arrays = run_processes(system, layout, inputs, options, workers, chunk, progress)
        check(system, arrays)
    else:
        arrays = {**(layout.allocate() if reused is None else reused), **inputs}
        try:
            if reused is not None:
                buffers.writable(reused)
            for lo in range(0, N, SERIAL_BLOCK):
                hi = min(N, lo + SERIAL_BLOCK)
                fill(system, arrays, lo, hi, options)
                if progress is not None:
                    progress(hi, N)
            check(system, arrays)
        except BaseException:
            if out is not None:   # its arrays hold part of this call's models now
                buffers.invalidate(out)
            raise
    if rest:  # a0 = 0 at an equilibrium, as a single call reports it (not rounding noise)
        arrays["f0"][at_rest] = 0.0
        if frozen is not None:  # and the least-norm forces a single call reports
            arrays["acc"][at_rest] = 0.0
            arrays["lam"][:] = lam
    model = (TrajectoryModel.trusted(**loops.stacked_fields(system, arrays, layout, frozen,
                                                            moved, derivatives, step),
                                     t=T, dt=0.0)
             if frozen is not None else _assemble(system, arrays, layout, T, options))
    if rest:
        loops_info = model.info.get("loops") or {}
        model.info.update(rest_info(at_rest, family, system, model.q,
                                    loops_info.get("condition")))
    elif frozen is not None and inputs["cond"].max(initial=0.0) <= loops.WARN_CONDITION:
        # a moving mechanism: the point nearest a fold, as a single call (above WARN_CONDITION
        # the assembly has warned about that point already)
        checked = sensitivity(system, model.q, inputs["cond"], model.v, model.u, stacklevel=3)
        if checked is not None:
            model.info["operating_point_sensitivity"] = checked
    if frozen is None and workers == 1 and executor is None:
        buffers.attach(model, system, layout, arrays)
        if out is not None:
            return buffers.adopt(out, model)
    return model


def _assemble(system: System, arrays: Mapping[str, np.ndarray], layout: Layout,
              t: np.ndarray | None, options: Options) -> TrajectoryModel:
    N, nv, p, nu = layout.points, layout.nv, layout.p, layout.nu
    Q, V = arrays["q"], arrays["v"]
    C = arrays.get("C")
    if C is None:
        C0, _ = constant_outputs(system, Q[0], V[0])
        C = np.broadcast_to(C0, (N, p, 2 * nv))
    D = np.broadcast_to(np.zeros((p, nu)), (N, p, nu))
    y = arrays.get("y")
    if y is None:
        y = np.broadcast_to(np.zeros(p), (N, p))
    for arr in (arrays["A"], arrays["B"], arrays["f0"], Q, V, arrays["u"], C, y):
        arr.setflags(write=False)
    spec = system.outputs
    info: dict[str, Any] = {
        "formulation": "independent",
        "derivatives": options.derivatives,
        "effects": list(system.effects_in_play),
        "base": "free" if system.base_joint else "fixed",
        "points": N,
        "path": "batch" if batch_path(system, options) else "per point",
    }
    if options.derivatives != "analytic":
        info["step"] = resolve_steps(options.derivatives, options.step)
    second = dict.fromkeys(_SECOND_ORDER)
    if options.second_order:
        second = {key: arrays[key] for key in ("M", "C_damp", "K")}
        second["Bu"] = np.broadcast_to(system.input_matrix, (N, nv, nu))
        for arr in second.values():
            arr.setflags(write=False)
    return TrajectoryModel.trusted(
        **second,
        A=arrays["A"], B=arrays["B"], C=C, D=D, f0=arrays["f0"], q=Q, v=V, u=arrays["u"],
        a=arrays["f0"][:, nv:], t=t, y=y, state_names=system.state_names,
        input_names=system.input_names,
        output_names=system.state_names if spec is None else spec.names,
        name=system.scene.name, info=info, dt=0.0)


__all__ = ["TrajectoryModel", "linearize_trajectory"]
