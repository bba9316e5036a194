"""``pinlin.simulate``: the scene's nonlinear motion about its operating point, in time.

The equations of motion hold exactly the scene's effects; their coordinates (a re-centred
chart for floating bases and other Lie-group joints, independent coordinates with the loops
closed at every evaluation for mechanisms) are in :mod:`pinlin.simulation_ode`. They are
integrated by one of the solvers of scipy's ``solve_ivp`` (its ``OdeSolver`` classes, stepped
here one accepted step at a time, so that the coordinates can change between steps and held
inputs switch exactly at their sample times; the solver restarts there with its step size).
Outputs come from each step's dense output (no step is shortened to hit an output time).

Method. ``method=None`` chooses by a stated criterion: with rho = max(-Re lambda) the fastest
decay rate of the ODE's Jacobian at the initial state (central differences; the linear model
there), the problem is stiff when rho T > :data:`STIFF_LIMIT` for the horizon T: an explicit
method would spend more than ~STIFF_LIMIT / 5 steps on stability alone (|h lambda| < ~5 for
DOP853), steps an implicit one does not need, and when rho exceeds :data:`STIFF_RATIO` times
the rate of the motion that every method must resolve: each mode's oscillation or growth
over the part of the horizon it lasts (a pendulum near upright has lambda = +-3.13 1/s,
whose decay half is no reason for an implicit method: with rho T alone, 400 s of it took
Radau 41 s against DOP853's 1 s; a fast oscillation damped away within milliseconds is,
and leaves only stability to limit an explicit method's steps). Stiff:
``"Radau"`` (implicit, order 5); else ``"DOP853"`` (explicit, order 8). Undamped fast
oscillations do not count: every method must resolve them. A horizon of more than
:data:`MAX_CYCLES` periods of the fastest oscillation or growth is refused.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from .arrays import read_only, real_array, sample_times
from .coordinates import characteristic_length, linear_coordinates
from .exceptions import ArgumentError, ModelError
from .formulations.constrained import constrained_effects
from .linearization import _system, operating_point
from .operating_point import OperatingPoint
from .scene import COEFFICIENT_LIMIT, POSITION_LIMIT, Scene
from .simulation_inputs import Inputs
from .simulation_ode import (
    CHART_LIMIT,
    Mechanism,
    OpenChain,
    continuous_angles,
    spring_wraps,
)
from .system import System

#: rho * T above this is stiff (rho: fastest decay rate [1/s], T: horizon [s]) ...
STIFF_LIMIT = 1e3
#: ... when rho also exceeds this many times the rate of the motion every method must
#: resolve (oscillations and growth, each over the part of the horizon it lasts): below, an
#: explicit method's steps for accuracy (~10 a period) already keep it stable.
STIFF_RATIO = 10.0
#: A mode decaying at d [1/s] lasts PERSIST / d (e^-50 ~ 2e-22 of itself: gone to rounding).
PERSIST = 50.0
METHODS = ("DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA")


@dataclass(frozen=True, eq=False)
class Simulation:
    """A simulated trajectory (read-only arrays, one row per output time).

    Attributes:
        t: (N,) times [s].
        x: (N, 2nv) state in the linear model's coordinates about the operating point,
            x = [difference(q0, q); v - v0] (all coordinates, dependent ones included), a
            continuous joint's angle followed in turns (difference wraps it at pi; a free
            flyer's, spherical or planar joint's rotation stays in the log map, wrapping).
        z: (N, 2nz) the independent coordinates' part of ``x``, [dz; dz'] (the state of the
            linear model of a mechanism); equal to ``x`` for an open chain.
        q: (N, nq) configurations (Pinocchio convention, quaternions [x, y, z, w]).
        v: (N, nv) velocities [rad/s or m/s] (a free flyer's in its own frame).
        u: (N, nu) inputs applied, u0 + du (the feedback's share included) [N*m or N]. A
            feedback law reads x with every rotation wrapped (log map), a continuous joint's
            too: past pi its u is u0 - K x' with x' that wrapped x, not with ``x``.
        y: (N, p) outputs: the linear model's y plus its ``operating_point.y``, i.e. frame
            positions in the world [m], joint values ``difference(neutral, q)`` and
            velocities; the state (``x``, or ``z`` for a mechanism) when the scene names none.
        drift: (N, 2) constraint residuals max |Phi(q)| [m or rad] and max |Phi_q v|
            [m/s or rad/s] (zeros without constraints).
        energy: (N,) total mechanical energy [J]: kinetic 1/2 v^T M v (armature included) +
            gravity + springs, minus the work of the constant inputs u0, u0 . dq on their
            1-DoF joints (dq from ``x``: in turns for a continuous joint); constant without
            damping, non-increasing with it. None
            when not defined: a rotating scene (a non-inertial frame), inputs du given, or u0
            on a multi-DoF joint, feedback (``info["energy"]`` says why).
        operating_point: The point simulated about (q0, v0, u0).
        state_names, independent_names, input_names, output_names: Column names of x, z, u, y.
        info: solver, method and why, rtol, atol (and atol_linear [m, m/s] where the default
            was scaled by the robot's length), nfev, njev, nlu, steps (accepted),
            restarts (chart, partition, input), stiffness (rho * T), coordinates, energy
            (what it holds, or why it is None), feedback (none, a gain of shape (nu, n) or a
            callable), effects, notes, spring_wraps (the notes on springs of continuous
            joints that passed their wrap, q - rest beyond pi, where their force reverses).
    """

    t: np.ndarray
    x: np.ndarray
    z: np.ndarray
    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    y: np.ndarray
    drift: np.ndarray
    energy: np.ndarray | None
    operating_point: OperatingPoint
    state_names: tuple[str, ...]
    independent_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    info: dict[str, Any] = field(default_factory=dict)


#: Periods of the fastest oscillation or growth (max(|Im lambda|, Re lambda) / 2 pi of the
#: Jacobian at the start, times the part of the horizon T the mode lasts, min(T,
#: PERSIST / decay rate)) beyond which a horizon is refused: any integrator, implicit too,
#: takes ~10 steps a period to follow it, so 1e5 periods are ~1e6 steps of a Python
#: right-hand side (minutes); beyond, a typo in t (1e9 s for 1e-9) would run for days.
MAX_CYCLES = 1e5


def _choose_method(dyn: Any, s0: np.ndarray, inputs: Inputs, t: np.ndarray
                   ) -> tuple[str, float, str]:
    """(method, rho * T, why) by the stiffness criterion of the module docstring."""
    t0, T = float(t[0]), float(t[-1] - t[0])
    n = s0.size
    J = np.zeros((n, n))
    u = inputs.at(t0)

    def rhs(s: np.ndarray) -> np.ndarray:   # with feedback: the closed loop's Jacobian
        return dyn.rhs(t0, s, inputs.total(t0, lambda: dyn.model_state(s), u))

    for k in range(n):
        h = 1e-6 * max(1.0, abs(s0[k]))
        e = np.zeros(n)
        e[k] = h
        J[:, k] = (rhs(s0 + e) - rhs(s0 - e)) / (2 * h)
    dyn.state(s0)  # back to the initial configuration (mechanisms warm-start from it)
    lam = np.linalg.eigvals(J) if n else np.zeros(0)
    # The motion every method must resolve, mode by mode: its oscillation or growth rate,
    # over the part of the horizon it lasts (a mode decaying at d fades below e^-PERSIST
    # after PERSIST / d; a growing one, a pendulum near upright, turns into swings of about
    # its rate and lasts). cycles: the most periods any mode asks for.
    decay = -lam.real
    rates = np.maximum(np.abs(lam.imag), np.maximum(lam.real, 0.0))
    lasts = np.where(decay > 0.0, np.minimum(T, PERSIST / np.where(decay > 0, decay, 1.0)), T)
    cycles = float((rates * lasts).max(initial=0.0)) / (2.0 * np.pi)
    if not cycles <= MAX_CYCLES:
        k = int(np.argmax(rates * lasts))
        what = "oscillation" if abs(lam[k].imag) >= lam[k].real else "growing motion"
        closed = inputs.feedback is not None
        raise ArgumentError("feedback" if closed else "t",
                            f"the horizon {T:.3g} s spans {cycles:.3g} periods of the fastest "
                            f"{what} ({rates[k]:.3g} rad/s at the start"
                            f"{', of the closed loop' if closed else ''}): more than "
                            f"{MAX_CYCLES:g}, which an integrator must resolve step by step "
                            "(~10 steps a period); simulate a shorter horizon"
                            + (" or lower the gain" if closed else ""))
    rho = max(0.0, float(decay.max(initial=0.0)))
    stiff = rho * T
    resolve = 2.0 * np.pi * cycles / T if T > 0 else 0.0   # the rate those periods average
    if stiff > STIFF_LIMIT and rho > STIFF_RATIO * resolve:
        method, verdict = "Radau", f"> {STIFF_LIMIT:g} and {rho:.3g} > {STIFF_RATIO:g} x "
    else:
        method, verdict = "DOP853", f"<= {STIFF_LIMIT:g} or {rho:.3g} <= {STIFF_RATIO:g} x "
    why = (f"fastest decay rate {rho:.3g} 1/s times the horizon {T:.3g} s = {stiff:.3g} "
           f"{verdict}the rate of the motion to resolve ({resolve:.3g} 1/s): "
           f"{'stiff' if method == 'Radau' else 'not stiff'}")
    return method, stiff, why


def _integrate(dyn: Any, inputs: Inputs, t: np.ndarray, s0: np.ndarray, method: str,
               rtol: float, atol: float | Callable[[Any], np.ndarray]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """(q, v, the chart coordinates travelled from q0 (dyn.travelled)) at the times t, and the
    solver statistics. The solver is restarted (with its last step size) where the
    coordinates change (dyn.after_step) or a held input changes.
    ``atol``: a number, or a function of dyn giving one per state entry (taken at every
    start: a mechanism's independent coordinates may have changed)."""
    import scipy.integrate  # here: it costs ~0.3 s to import, which only simulate pays

    solver_class = getattr(scipy.integrate, method)
    N = t.size
    q0, v0 = dyn.state(s0)
    Q, V, C = np.zeros((N, q0.size)), np.zeros((N, v0.size)), np.zeros((N, v0.size))
    Q[0], V[0] = q0, v0
    C[0] = dyn.travelled(s0)
    stats = {"nfev": 0, "njev": 0, "nlu": 0, "steps": 0,
             "restarts": {"chart": 0, "partition": 0, "input": 0}}
    k, ts, s, h = 1, float(t[0]), s0, None
    while k < N:
        later = inputs.breaks[inputs.breaks > ts]
        t_end = float(later[0]) if later.size else float(t[-1])
        u_held = inputs.at(ts) if inputs.function is None else None

        def fun(tt: float, ss: np.ndarray, u_held: np.ndarray | None = u_held) -> np.ndarray:
            return dyn.rhs(tt, ss, inputs.total(tt, lambda: dyn.model_state(ss), u_held))

        options: dict[str, Any] = {"rtol": rtol, "atol": atol(dyn) if callable(atol) else atol}
        if h is not None:
            options["first_step"] = min(h, t_end - ts)
        with np.errstate(over="ignore", invalid="ignore"):   # simulate refuses non-finite
            solver = solver_class(fun, ts, s, t_end, **options)
        restart = None
        while solver.status == "running" and restart is None:
            try:
                with np.errstate(over="ignore", invalid="ignore"):
                    message = solver.step()
            except ValueError as exc:     # scipy's own check of its Jacobian or LU
                if "infs or NaNs" not in str(exc):
                    raise
                raise ModelError(f"the integration failed at t = {solver.t:.6g} s ({method}): "
                                 "the dynamics overflowed (inf or NaN in the solver's "
                                 "Jacobian)") from None
            if solver.status == "failed":
                raise ModelError(f"the integration failed at t = {solver.t:.6g} s ({method}): "
                                 f"{message}")
            stats["steps"] += 1
            j = int(np.searchsorted(t, solver.t, side="right"))
            if j > k:
                dense = solver.dense_output() if t[k] != solver.t else None
                for i in range(k, j):
                    state = solver.y if t[i] == solver.t else dense(t[i])
                    Q[i], V[i] = dyn.state(state)
                    C[i] = dyn.travelled(state)
                k = j
            restart = dyn.after_step(solver.y)
        for key in ("nfev", "njev", "nlu"):
            stats[key] += int(getattr(solver, key, 0))
        h = float(getattr(solver, "h_abs", None) or solver.step_size or 0.0) or None
        ts = float(solver.t)
        if restart is not None:
            s = restart[0]
            stats["restarts"][restart[1]] += 1
        else:
            s = solver.y
            if k < N:
                stats["restarts"]["input"] += 1
    return Q, V, C, stats


def _outputs(system: System, Q: np.ndarray, V: np.ndarray) -> np.ndarray | None:
    """Absolute outputs (frame positions [m], joint values and velocities), or None when the
    scene names none."""
    spec = system.outputs
    if spec is None:
        return None
    model, neutral = system.model, pin.neutral(system.model)
    Y = np.zeros((Q.shape[0], len(spec.names)))
    kin, kd = system.kin_model, system.kin_data
    for i, (q, v) in enumerate(zip(Q, V, strict=True)):
        x = np.concatenate([pin.difference(model, neutral, q), v])
        for row, col in spec.state_rows:
            Y[i, row] = x[col]
        if spec.frames:
            pin.framesForwardKinematics(kin, kd, system.kin_q(q))
            for row, fid in spec.frames:
                Y[i, row:row + 3] = kd.oMf[fid].translation
    return Y


def _energy(system: System, op: OperatingPoint, Q: np.ndarray, V: np.ndarray,
            DQ: np.ndarray, inputs: Inputs) -> tuple[np.ndarray | None, str]:
    """Total mechanical energy [J] (Simulation.energy) and what it contains or why it is
    undefined; ``DQ``: the motion from q0 (N, nv), continuous joints' angles in turns (u0's
    work grows with every turn)."""
    if system.rotation is not None:
        return None, "undefined: the scene rotates (a non-inertial frame)"
    if inputs.samples is not None or inputs.function is not None:
        return None, "undefined: inputs du(t) do work that is not a potential"
    if inputs.feedback is not None:
        return None, "undefined: the feedback's inputs do work that is not a potential"
    loaded = np.flatnonzero(op.u)
    joint_nv = np.zeros(system.nv, dtype=int)
    for j in system.joints.values():
        joint_nv[j.idx_v:j.idx_v + j.nv] = j.nv
    if np.any(joint_nv[system.actuated[loaded]] != 1):
        return None, "undefined: u0 acts on a multi-DoF joint (its work is path dependent)"
    model, data = system.model, system.data
    E = np.zeros(Q.shape[0])
    for i, (q, v) in enumerate(zip(Q, V, strict=True)):
        E[i] = 0.5 * v @ system.mass_matrix(q) @ v + pin.computePotentialEnergy(model, data, q)
        if system.has_springs:
            E[i] += 0.5 * system.stiffness @ pin.difference(model, system.q_rest, q) ** 2
        if loaded.size:
            E[i] -= op.u @ DQ[i, system.actuated]
    terms = ["kinetic"] + ["gravity"] * (system.scene.effects.gravity is not None) \
        + ["springs"] * system.has_springs
    what = " + ".join(terms) + (" - work of u0" if loaded.size else "") \
        + (" (damped: non-increasing)" if system.has_damping else "")
    return E, what


def atol_length(system: System, q: np.ndarray) -> float | None:
    """L [m] by which the default absolute tolerance of a length is :data:`ATOL` L (the robot's
    characteristic length at ``q``), or None where the system has no linear coordinate."""
    if not linear_coordinates(system).any():
        return None
    return characteristic_length(system, q)[0]


def _time_grid(t: object) -> np.ndarray:
    """:func:`pinlin.arrays.sample_times`, at most :data:`MAX_SAMPLES` of them."""
    grid = sample_times(t)
    if grid.size > MAX_SAMPLES:
        raise ArgumentError("t", f"{grid.size} output times; at most {MAX_SAMPLES} (each is "
                                 f"a nonlinear state turned into the model's coordinates): "
                                 f"space them wider or split the horizon")
    return grid


#: Most output times one simulation returns (the CLI's limit too): each costs a few
#: microseconds of Python (chart difference, outputs) after the integration.
MAX_SAMPLES = 1_000_000


#: The default absolute tolerance: per radian of an angle and per rad/s of a rate; per L
#: metres of a length and per L m/s of a linear velocity, L the robot's characteristic length
#: (:func:`pinlin.coordinates.characteristic_length`), so that a robot made smaller or larger
#: is integrated to the same relative accuracy.
ATOL = 1e-12
#: The smallest relative tolerance scipy's solvers honour (100 x machine epsilon).
RTOL_MIN = 100 * np.finfo(float).eps


def _tolerance(name: str, value: object) -> float:
    if isinstance(value, bool | np.bool_) or \
            not isinstance(value, int | float | np.integer | np.floating):
        raise ArgumentError(name, f"expected a number, got {type(value).__name__}")
    try:
        value = float(value)
    except OverflowError:
        value = math.inf
    if not (math.isfinite(value) and value > 0.0):
        raise ArgumentError(name, f"expected a finite number > 0, got {value!r}")
    if name == "atol" and value >= 1.0:
        raise ArgumentError(name, f"{value:g} allows absolute errors of a radian or a metre (a "
                                  "radian or a metre per second) per step, as large as the "
                                  "motion itself; an absolute tolerance is below 1 (the "
                                  "default is 1e-12 per radian)")
    if name == "rtol" and value < RTOL_MIN:   # scipy would raise it with a warning
        raise ArgumentError(name, f"{value:g} is below {RTOL_MIN:.3g} (100 x machine "
                                  f"epsilon), the smallest relative tolerance the solvers "
                                  f"honour")
    if name == "rtol" and value >= 1.0:
        raise ArgumentError(name, f"{value:g} allows errors as large as the state itself; a "
                                  "relative tolerance is below 1 (the default is 1e-10)")
    return float(value)


def simulate(scene: Scene | System | str, t: object, dx0: object = None, u: object = None, *,
             feedback: object = None, q0: np.ndarray | None = None,
             v0: np.ndarray | None = None,
             rtol: float = 1e-10, atol: float | None = None, method: str | None = None
             ) -> Simulation:
    """The scene's nonlinear motion about its operating point (module docstring).

    Args:
        scene: A :class:`Scene`, its :class:`System`, or a scene file / URDF / bundled scene /
            robot name.
        t: Output times [s], strictly increasing; the motion starts at t[0].
        dx0: Initial deviation in the linear model's coordinates, x = [difference(q0, q);
            v - v0] (2 nv); for a mechanism also 2 nz (its independent coordinates, the state
            of its linear model); given in all coordinates, the independent part is kept, the
            loops closed and v = R z'. Default zero.
        u: Input deviations added to u0 [N*m or N]: a callable u(t) -> (nu,) (nu finite real
            numbers; an exception it raises reaches the caller unchanged), an (N, nu)
            array, row k held from t[k] to t[k+1], or a :class:`~pinlin.Signal` of steps
            and sinusoids (``pinlin.step``, ``pinlin.harmonic``; an impulse is refused: it
            is a jump of the initial velocities). Default none.
        feedback: State feedback added to the inputs (:mod:`pinlin.simulation_inputs`): a
            gain matrix K, du = -K x with x the state of the linear model about the point
            simulated (shape (nu, 2 nv); for a mechanism (nu, 2 nz) on its independent
            coordinates [dz; dz'], or (nu, 2 nv) on all), as ``control.lqr(model.A,
            model.B, Q, R)[0]`` returns it; or a callable feedback(t, x) -> (nu,) [N*m or N]
            of the time [s] and that state (2 nz for a mechanism); or a pair (K, model), the
            gain with the model it was designed on, whose state names, size and operating
            point are checked (a canonical model's [p; q], an orthonormal basis or a gain
            designed about another point are refused). x is measured from the point
            simulated, (q0, v0): with v0 given the law steers back to that state; a rotation
            of more than pi from q0 wraps (the log map). The integrator calls a callable at
            trial states too (its stages, rejected steps, the stiffness test), not in time
            order: make it a pure function of (t, x). Its first call is made before the
            integration (an error there is refused naming ``feedback``); an exception it
            raises later reaches the caller unchanged.
        q0, v0: The point to simulate about instead of the scene's, resolved as
            ``pinlin.operating_point(scene, q=q0, v=v0)``: q0 alone (nq) keeps the scene's
            ``solve`` (u0 holds q0 at rest); with v0 (nv) [rad/s or m/s] the state is given
            and u0 is the scene's ``u`` (else zero), e.g. a floating base in free fall.
        rtol, atol: Solver tolerances: relative; absolute in the state's units [rad, m, rad/s,
            m/s]. Default atol: :data:`ATOL` per radian (rad/s) and ATOL L per metre (m/s), L
            the robot's characteristic length at the operating point (a slider of a 61 um
            mechanism held to 1e-12 m would be integrated 1e4 times looser than its angles).
        method: One of ``METHODS`` (scipy's names); None chooses DOP853 or Radau by the
            stiffness criterion (module docstring).

    Raises:
        ArgumentError, ShapeError: a bad argument.
        EquilibriumError: as :func:`pinlin.operating_point`, the scene's q0 cannot be held
            by its inputs (give the state with ``v0`` to simulate from it anyway).
        ModelError: a singular mass matrix; the mechanism reaching a position where its
            loops do not close; a failed step.
    """
    system = _system(scene)
    grid = _time_grid(t)
    rtol = _tolerance("rtol", rtol)
    atol = None if atol is None else _tolerance("atol", atol)
    if method is not None and method not in METHODS:
        raise ArgumentError("method", f"expected one of {', '.join(METHODS)} or None, got "
                                      f"{method!r}")
    op = operating_point(system, q=q0, v=v0)
    dyn: OpenChain | Mechanism = Mechanism(system, op) if system.constraints else \
        OpenChain(system, op)
    nv = system.nv
    deviation = np.zeros(2 * nv) if dx0 is None else \
        real_array(dx0, "dx0", f"{2 * nv} real numbers")
    if deviation.ndim != 1:
        raise ArgumentError("dx0", f"expected a vector of {2 * nv} numbers, got shape "
                                   f"{deviation.shape}")
    if not np.all(np.isfinite(deviation)):
        raise ArgumentError("dx0", "contains NaN or inf")
    if deviation.size % 2 == 0:  # 2 nv or 2 nz (a wrong size is the initial state's to refuse)
        half = deviation.size // 2
        for part, limit, what in ((deviation[:half], POSITION_LIMIT, "positions [m or rad]"),
                                  (deviation[half:], COEFFICIENT_LIMIT, "velocities")):
            if part.size and np.abs(part).max() > limit:
                raise ArgumentError("dx0", f"has an entry of size {np.abs(part).max():.3g}; "
                                           f"its {what} are limited to |x| <= {limit:g}")
    s0, notes = dyn.initial_state(deviation)
    inputs = Inputs(u, grid, op.u, system.input_names)
    cols = dyn.columns if isinstance(dyn, Mechanism) else np.arange(nv)
    if feedback is not None:
        inputs.close_loop(feedback, cols, nv, dyn.model_state(s0), system.state_names, op)
    chosen, stiffness, why = _choose_method(dyn, s0, inputs, grid)  # refuses endless ones
    if method is None:
        method = chosen
    else:
        stiffness, why = float("nan"), "given"
    length = None
    if atol is None:
        atol, length = ATOL, atol_length(system, op.q)
    Q, V, C, stats = _integrate(dyn, inputs, grid, s0, method, rtol,
                                atol if length is None else
                                lambda d: np.where(d.linear_state(), atol * length, atol))
    finite = np.isfinite(Q).all(axis=1) & np.isfinite(V).all(axis=1)
    if not finite.all():
        raise ModelError(f"the integration overflowed ({method}): the state is not finite "
                         f"from t = {grid[int(np.argmin(finite))]:.6g} s")

    X = np.hstack([np.array([pin.difference(system.model, op.q, q) for q in Q]), V - op.v])
    # What a feedback law read during the integration: x with rotations wrapped (log map).
    X_read = X.copy()
    # A continuous joint's angle as it travelled, in turns (difference wraps it at pi).
    turning = continuous_angles(system)
    X[:, turning] = C[:, turning]
    wraps = spring_wraps(system, op.q, X, grid)
    notes = [*notes, *wraps]
    Z = np.hstack([X[:, cols], X[:, nv + cols]])
    drift = np.array([dyn.drift(q, v) for q, v in zip(Q, V, strict=True)]) \
        if isinstance(dyn, Mechanism) else np.zeros((grid.size, 2))
    names = [system.coordinate_names[i] for i in cols]
    independent = tuple([f"q:{n}" for n in names] + [f"v:{n}" for n in names])
    Y = _outputs(system, Q, V)
    out_names = system.outputs.names if system.outputs is not None else independent
    if Y is None:
        Y = Z
    energy, energy_note = _energy(system, op, Q, V, X[:, :nv], inputs)
    U = np.array([inputs.total(float(ti), lambda x=x: x) for ti, x in
                  zip(grid, X_read, strict=True)]).reshape(grid.size, op.u.size)
    info = {"solver": f"scipy.integrate.{method}", "method": method, "method_reason": why,
            "stiffness": stiffness, "rtol": rtol, "atol": atol,
            **({} if length is None else {"atol_linear": atol * length}), **stats,
            "coordinates": ("independent (dz, z'), loops closed by Newton at every evaluation"
                            if isinstance(dyn, Mechanism) else
                            "chart (dq, v) about a reference re-centred past "
                            f"{CHART_LIMIT:g} rad" if system.nq != nv else "(dq, v)"),
            "energy": energy_note, "notes": notes, "spring_wraps": tuple(wraps),
            "feedback": inputs.feedback_note,
            "effects": constrained_effects(system)}
    return Simulation(
        t=read_only(grid), x=read_only(X), z=read_only(Z), q=read_only(Q), v=read_only(V),
        u=read_only(U), y=read_only(np.array(Y)), drift=read_only(drift),
        energy=None if energy is None else read_only(energy), operating_point=op,
        state_names=system.state_names, independent_names=independent,
        input_names=system.input_names, output_names=tuple(out_names), info=info)


__all__ = ["METHODS", "Simulation", "simulate"]
