"""Linear models along a trajectory: ``pinlin.linearize_trajectory`` and ``TrajectoryModel``.

A trajectory is N states (q_k, v_k, u_k), optionally at times t_k. Its model is the stack of
the N affine models of :func:`pinlin.linearize` at those states (independent formulation;
mechanisms in the independent coordinates of their first point, :mod:`pinlin.trajectory_loops`)::

    x' = f0_k + A_k x + B_k u,   y = C_k x + D_k u,   x = [dq; v] about (q_k, v_k), u about u_k

stored as arrays with the point first: ``A`` (N, n, n), ``B`` (N, n, m), ``C`` (N, p, n),
``D`` (N, p, m), ``f0`` (N, n); ``model.at(k)`` is the k-th :class:`~pinlin.LinearModel`.
How the stack is computed (one pass of ``pin.computeABADerivatives`` per point, or
:func:`pinlin.linearize` per point where that kernel does not apply) is in :mod:`pinlin.batch`
(mechanisms: assembled and linearized point by point, :mod:`pinlin.trajectory_loops`);
worker processes and executors (Dask) in :mod:`pinlin.parallel`; files in
:mod:`pinlin.trajectory_files`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import trajectory_loops as loops
from .arrays import real_array
from .batch import Layout, Options, batch_path, check, constant_outputs, fill
from .derivatives import resolve_steps
from .exceptions import ArgumentError, ModelError, ShapeError
from .linear_model import LinearModel
from .linearization import _system
from .operating_point import OperatingPoint
from .resources import check_memory
from .rest_schedule import holding_inputs, needs_single_calls, rest_info, rest_options
from .rest_schedule import single_calls as schedule_by_single_calls
from .scene import COEFFICIENT_LIMIT, POSITION_LIMIT, Scene
from .system import System
from .trajectory_inputs import check_normalized, check_options, points, times

#: Points per progress report (and per vectorized block) when one process does the work.
SERIAL_BLOCK = 256
_SECOND_ORDER = ("M", "C_damp", "K", "Bu")


@dataclass(frozen=True, eq=False)
class TrajectoryModel:
    """The linear models of N points of a trajectory, stacked along the first axis.

    Attributes:
        A, B, C, D: (N, n, n), (N, n, m), (N, p, n), (N, p, m). C and D are broadcast views of
            one matrix (no memory per point) when the outputs do not depend on the state.
        f0: (N, n): the drift at each point, x' = f0 + A x + B u (discrete: the state change
            over one step); zeros at an equilibrium.
        q: (N, nq) configurations; v: (N, nv) velocities [rad/s or m/s]; u: (N, m) inputs
            [N*m or N]; a: (N, nv) accelerations at the points [rad/s^2 or m/s^2].
        t: (N,) times [s], or None.
        y: (N, p) output values at the points (zeros when the output is the state, as for a
            single model).
        state_names, input_names, output_names: Signal names (n, m, p).
        name: Scene name.
        info: Metadata: formulation, derivatives, effects, base, points, path ("batch": one
            ``computeABADerivatives`` per point; "per point": :func:`pinlin.linearize`); a
            schedule of rest points (:mod:`pinlin.rest_schedule`) adds ``at_rest`` (True),
            ``notes``, and where they apply ``non_equilibrium_points``,
            ``least_norm_points`` and ``operating_point_sensitivity``.
        dt: Sample time [s] of discrete models; 0 for continuous ones.
        lam: (N, m) constraint forces of a mechanism [N or N*m] (names in
            ``info["lam_names"]``; :mod:`pinlin.trajectory_loops`), else None. A mechanism's
            states are its independent coordinates z (``info["independent"]``), the same at
            every point; its ``q`` are the assembled configurations, ``v`` the velocities
            projected onto the constraint nullspace, ``a`` the accelerations of all nv
            coordinates.
        M, C_damp, K: (N, n/2, n/2) mass [kg, kg*m^2], velocity (damping and gyroscopic)
            and stiffness matrices of every point, Bu: (N, n/2, m) input matrix: the
            second-order model M dq'' + C_damp dq' + K dq = Bu du of :class:`LinearModel`,
            with ``linearize_trajectory(..., second_order=True)`` (open chains: n/2 = nv, Bu
            one matrix broadcast; a mechanism's schedule of rest points: its independent
            coordinates); else None.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    f0: np.ndarray
    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    a: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    t: np.ndarray | None = None
    y: np.ndarray | None = None
    name: str = ""
    info: Mapping[str, Any] = field(default_factory=dict)
    dt: float = 0.0
    lam: np.ndarray | None = None
    M: np.ndarray | None = None
    C_damp: np.ndarray | None = None
    K: np.ndarray | None = None
    Bu: np.ndarray | None = None

    def __post_init__(self) -> None:
        names = {}
        for key in ("state_names", "input_names", "output_names"):
            value = getattr(self, key)
            if isinstance(value, str) or not isinstance(value, Sequence | np.ndarray) or \
                    not all(isinstance(s, str) for s in value):
                raise ArgumentError(key, "expected a sequence of names (strings)")
            names[key] = tuple(value)
            if len(set(names[key])) != len(names[key]):
                raise ModelError(f"trajectory model '{self.name}': {key} are not distinct")
            object.__setattr__(self, key, names[key])
        n, m, p = (len(names[k]) for k in ("state_names", "input_names", "output_names"))
        N = np.shape(self.A)[0] if np.ndim(self.A) == 3 else -1
        nv = np.shape(self.v)[-1] if np.ndim(self.v) == 2 else -1
        half = n // 2  # second-order: the coordinates of the states (a mechanism's z)
        shapes = {"A": (N, n, n), "B": (N, n, m), "C": (N, p, n), "D": (N, p, m),
                  "f0": (N, n), "v": (N, nv), "u": (N, m), "a": (N, nv), "t": (N,),
                  "y": (N, p), "q": (N, np.shape(self.q)[-1] if np.ndim(self.q) == 2 else -1),
                  "lam": (N, np.shape(self.lam)[-1] if np.ndim(self.lam) == 2 else -1),
                  "M": (N, half, half), "C_damp": (N, half, half), "K": (N, half, half),
                  "Bu": (N, half, m)}
        given = [key for key in _SECOND_ORDER if getattr(self, key) is not None]
        if given and len(given) < len(_SECOND_ORDER):
            raise ArgumentError(given[0], "the second-order matrices M, C_damp, K, Bu come "
                                          "together: give all four or none")
        for key, shape in shapes.items():
            value = getattr(self, key)
            if value is None and key in ("t", "y", "lam", *_SECOND_ORDER):
                continue
            arr = _stack(key, value, shape)
            object.__setattr__(self, key, arr)
        if self.t is not None and np.any(np.diff(self.t) <= 0):
            raise ArgumentError("t", "times must increase strictly (one per point, as "
                                     "linearize_trajectory takes them)")
        if not isinstance(self.name, str):
            raise ArgumentError("name", f"expected a str, got {type(self.name).__name__}")
        dt = self.dt
        if isinstance(dt, bool) or not isinstance(dt, int | float | np.floating) \
                or not (math.isfinite(dt) and dt >= 0):
            raise ArgumentError("dt", f"expected a sample time >= 0 [s], got {dt!r}")
        object.__setattr__(self, "dt", float(dt))
        if not isinstance(self.info, Mapping):
            raise ArgumentError("info", f"expected a mapping, got {type(self.info).__name__}")
        object.__setattr__(self, "info", dict(self.info))

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickling: the fields as pickled, the arrays read-only again (pickle hands numpy
        arrays back writeable)."""
        self.__dict__.update(state)
        for value in state.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    @classmethod
    def trusted(cls, **fields: Any) -> TrajectoryModel:
        """A model from code that built every field consistent (read-only float64 arrays,
        tuples of distinct names): no checks."""
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    # ----------------------------------------------------------------------------------------
    def __len__(self) -> int:
        return self.A.shape[0]

    def __repr__(self) -> str:
        kind = f"discrete dt = {self.dt:g} s" if self.dt else "continuous"
        return (f"TrajectoryModel({self.name!r}: {len(self)} points, {len(self.state_names)} "
                f"states, {len(self.input_names)} inputs, {len(self.output_names)} outputs, "
                f"{kind})")

    @property
    def is_discrete(self) -> bool:
        return self.dt > 0

    def at(self, k: int) -> LinearModel:
        """The model of point ``k`` (negative: from the end) as a :class:`LinearModel`: what
        :func:`pinlin.linearize` gives at (q[k], v[k], u[k]) (a schedule of rest points: at
        q[k], an equilibrium with f0 None, or a falling point opted in with its f0), to
        rounding, with the
        second-order matrices M, C_damp, K, Bu where the trajectory has them
        (``second_order=True``), else None. Its operating point carries q, v, u, a and y;
        its ``residual`` (M a0) is None.

        Raises:
            ArgumentError: ``k`` is not an integer in [-N, N).
        """
        N = len(self)
        if isinstance(k, bool) or not isinstance(k, int | np.integer):
            raise ArgumentError("k", f"expected a point index (an integer), got "
                                     f"{type(k).__name__}")
        if not -N <= k < N:
            raise ArgumentError("k", f"expected a point index in [0, {N}) (or from the end, "
                                     f"down to -{N}), got {k}")
        k = int(k) % N
        q, v, u, a = self.q[k], self.v[k], self.u[k], self.a[k]
        rest = bool(self.info.get("at_rest"))  # a schedule of rest points (rest_schedule)
        moving = bool(v.any() or a.any()) or (self.lam is not None and not rest)
        when = f" (t = {self.t[k]:.6g} s)" if self.t is not None else ""
        note = (f"point {k} of {N} of a schedule of rest points{when}: the inputs that hold q "
                "were solved; the residual is not kept in a batch" if rest else
                f"point {k} of {N} of a trajectory{when}: the state is given; the residual "
                "M a0 is not computed in a batch (a0 is operating_point.a)")
        info = {**self.info, "point": k}
        loop_info = info.pop("loops", None)
        if loop_info is not None:  # a mechanism: its point's diagnostics, as linearize's
            info["condition"] = {"constraint_jacobian": loop_info["condition"][k]}
            info["velocity_correction"] = loop_info["velocity_correction"][k]
            info["position_correction"] = loop_info["position_correction"][k]
        op = OperatingPoint.trusted(
            q=q, v=v, u=u, a=a, residual=None, equilibrium=not moving, tolerance=0.0,
            y=None if self.y is None else self.y[k],
            lam=None if self.lam is None else self.lam[k],
            lam_names=tuple(self.info.get("lam_names", ())) if self.lam is not None else (),
            notes=(note,))
        if self.t is not None:
            info["t"] = float(self.t[k])
        return LinearModel.assembled(
            A=self.A[k], B=self.B[k], C=self.C[k], D=self.D[k], state_names=self.state_names,
            input_names=self.input_names, output_names=self.output_names, E=None, F=None,
            operating_point=op, G=None, name=self.name, info=info,
            f0=self.f0[k] if moving else None, dt=self.dt,
            **{key: None if getattr(self, key) is None else getattr(self, key)[k]
               for key in _SECOND_ORDER})

    def discretize(self, dt: float, method: str = "zoh") -> TrajectoryModel:
        """The discrete models over sample time ``dt`` [s], point by point, as
        :meth:`LinearModel.discretize` gives them (:mod:`pinlin.discretization`), vectorized:
        ``"zoh"`` by batched matrix exponentials, ``"euler"`` (semi-implicit: v, then dq with
        the new v) by batched products. C, D, the states and ``a`` are unchanged; the
        second-order matrices describe the continuous model and are left out (None), as
        :meth:`LinearModel.discretize` leaves them out.

        Raises:
            ArgumentError: ``dt`` not a positive finite number [s], an unknown method, or
                models that are already discrete.
            ModelError: ``dt`` so long that a discrete matrix overflows (naming the point).
        """
        from .discretization import (
            check_step,
            refuse_overflow,
            stacked_euler,
            stacked_zoh,
            warn_if_inaccurate,
        )

        dt = check_step(dt, method)
        if self.dt:
            raise ArgumentError("model", f"trajectory model '{self.name}' is already discrete "
                                         f"(dt = {self.dt:g} s)")
        with np.errstate(over="ignore", invalid="ignore"):  # refused below, naming dt
            A_d, B_d, f_d = (stacked_zoh if method == "zoh" else stacked_euler)(
                self.A, self.B, self.f0, dt)
        refuse_overflow(self.name, dt, method, A_d, B_d, f_d)
        if method == "zoh":
            warn_if_inaccurate(self.name, dt, self.A)
        for arr in (A_d, B_d, f_d):
            arr.setflags(write=False)
        return TrajectoryModel.trusted(**{
            **self.__dict__, "A": A_d, "B": B_d, "f0": f_d, "dt": dt,
            **dict.fromkeys(_SECOND_ORDER),
            "info": {**self.info, "discretization": {"method": method, "dt": dt}}})

    # ----------------------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the models as ``.npz`` or MATLAB ``.mat`` (atomically: a temporary file beside
        it, renamed into place). :meth:`load` reads it back; nothing in it is a pickle.

        Raises:
            ArgumentError: ``path`` is not a path.
            ModelFileError: another suffix, or the file cannot be written.
        """
        from .trajectory_files import save_trajectory_model

        return save_trajectory_model(self, path)

    @classmethod
    def load(cls, path: str | Path) -> TrajectoryModel:
        """Read models written by :meth:`save` (never unpickles anything).

        Raises:
            ArgumentError: ``path`` is not a path.
            ModelFileError: missing file, unknown suffix, or content that is not a trajectory
                model pinlin wrote (the message names the file and what is wrong).
        """
        from .trajectory_files import load_trajectory_model

        return load_trajectory_model(path, cls)


def _stack(key: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a read-only float64 array of ``shape`` (-1: free), finite."""
    if type(value) is np.ndarray and value.dtype == np.float64:
        arr = value   # shared when read-only (below), as the model's own arrays are
    else:
        arr = real_array(value, key, "an array of real numbers")
    want = tuple(arr.shape[i] if s == -1 and i < arr.ndim else s for i, s in enumerate(shape))
    if arr.shape != want or any(s < 0 for s in want):
        raise ShapeError(f"{key} must have shape {_shape_text(shape)}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ModelError(f"{key} has NaN or inf; a trajectory model with NaN or inf is never "
                         "built")
    if arr is not value or arr.flags.writeable:  # the model owns its arrays
        arr = arr.copy()
        arr.setflags(write=False)
    return arr


def _shape_text(shape: tuple[int, ...]) -> str:
    return "(" + ", ".join("?" if s < 0 else str(s) for s in shape) + ")"


# --------------------------------------------------------------------------------------------
# linearize_trajectory


def linearize_trajectory(scene: Scene | System | str | Path, q: np.ndarray,
                         v: np.ndarray | None = None, u: np.ndarray | None = None,
                         t: np.ndarray | None = None, *, workers: int = 1,
                         executor: Executor | None = None, derivatives: str = "analytic",
                         chunk: int | None = None,
                         step: float | Mapping[str, float] | None = None,
                         progress: Callable[[int, int], None] | None = None,
                         second_order: bool = False,
                         allow_non_equilibrium: bool | None = None) -> TrajectoryModel:
    """Linear models of a scene at N states, stacked (see :class:`TrajectoryModel`).

    Point k is the model :func:`pinlin.linearize` gives at ``q=q[k], v=v[k], u=u[k]``
    (independent formulation). With analytic derivatives and no steady rotation the stack of
    an open chain comes from one ``pin.computeABADerivatives`` per point written straight
    into the arrays (:mod:`pinlin.batch`); otherwise from :func:`pinlin.linearize` per point.

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
            (open chains; on the batch path one ``pin.crba`` more per point,
            :mod:`pinlin.batch`). A mechanism's schedule of rest points has them in its
            independent coordinates (nz x nz; by single calls); its given-state trajectory
            refuses them: a single model at a moving state of a mechanism has none.
        allow_non_equilibrium: A schedule of rest points only: accept open-chain points that
            the inputs cannot hold (their models describe the motion about (q, v = 0)); None:
            the scene's ``operating_point.allow_non_equilibrium``.

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
    if rest:
        inputs["u"], at_rest, family, lam = holding_inputs(system, inputs["q"], bool(allow),
                                                           inputs.get("J"))
    if executor is not None:
        from .parallel import run_executor

        arrays = run_executor(system, layout, inputs, options, executor, chunk, progress)
    elif workers > 1:
        from .parallel import run_processes

        arrays = run_processes(system, layout, inputs, options, workers, chunk, progress)
    else:
        arrays = {**layout.allocate(), **inputs}
        for lo in range(0, N, SERIAL_BLOCK):
            hi = min(N, lo + SERIAL_BLOCK)
            fill(system, arrays, lo, hi, options)
            if progress is not None:
                progress(hi, N)
    check(system, arrays)
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
