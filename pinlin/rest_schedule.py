"""Gain schedules: the inputs that hold each of N configurations at rest.

``pinlin.linearize_trajectory(scene, q)`` without velocities and inputs linearizes a
*schedule* of static operating points, as a gain schedule over a grid of postures needs: point
k is the model :func:`pinlin.linearize` gives at ``q=q[k]`` (the scene's ``solve =
"inputs"``), the holding inputs solved at every point. This module solves them, for all points
before any model is built, so that the stacked kernels of :mod:`pinlin.batch` and
:mod:`pinlin.trajectory_loops` then linearize at the given states (q_k, 0, u0_k), which is the
same model (at rest the acceleration vanishes and the velocity terms with it).

At rest the residual form of the equations of motion is H = f(q) - S u - Phi_q^T lam = 0, with
f the generalized gravity (and centrifugal force in a rotating scene) minus the springs:

- **Open chain:** u0 = f on the actuated coordinates (S is a selection); what falls on the
  unactuated ones is the residual, as :func:`pinlin.operating_point.hold_at_rest` computes it.
  A point that is not an equilibrium (residual above 1e-9 max(1, |g|)) is refused, naming it,
  unless the scene or the caller allows it; the model then describes the motion about
  (q_k, v = 0) with a0 = -M^-1 residual, as for a single call.
- **Mechanism** (at its assembled configurations, :mod:`pinlin.trajectory_loops`): the
  least-norm [u0; lam] (its norm in N*m where the unknowns mix N and N*m, as
  :func:`pinlin.equilibrium.statics_split` takes it) of [S, G^T] [u0; lam] = f over every
  constraint row that is not identically zero there
  (:func:`pinlin.equilibrium.solve_constrained` takes the same rows: the independent ones and
  the redundant ones that can carry a force). A residual left over is
  refused: a mechanism off equilibrium cannot be linearized at rest.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from . import loop_kernels as lk
from .batch import Layout, at_point
from .conditioning import AccuracyWarning
from .coordinates import characteristic_length
from .equilibrium import statics_scales, unknown_is_force
from .exceptions import ArgumentError, EquilibriumError, ModelError, PinlinError, SceneError
from .linearization import _flag
from .operating_point import residual_tolerance
from .resources import check_memory
from .system import System

_EPS = float(np.finfo(float).eps)


def rest_options(system: System, v: object, u: object, allow: object) -> bool | None:
    """Whether a schedule of rest points allows points off equilibrium (v and u both omitted:
    the scene's ``allow_non_equilibrium`` unless ``allow`` is given), or None when the states
    are given (v and u both passed).

    Raises:
        ArgumentError: one of v and u without the other, ``allow`` not a bool or given with
            the states.
        SceneError: a schedule of a scene whose ``operating_point.solve`` is not
            ``"inputs"``.
    """
    if (v is None) != (u is None):
        missing = "u" if u is None else "v"
        raise ArgumentError(missing, "give both v and u (states), or neither (a schedule of "
                                     "rest points whose holding inputs are solved)")
    allow = _flag("allow_non_equilibrium", allow)
    if v is not None:
        if allow is not None:
            raise ArgumentError("allow_non_equilibrium", "applies to a schedule of rest points "
                                                         "(v and u omitted); the given states "
                                                         "are linearized as they are")
        return None
    spec = system.scene.operating_point
    if spec.solve != "inputs":
        raise SceneError(system.scene.source, "operating_point.solve",
                         f"a schedule of rest points (v and u omitted) solves the holding "
                         f"inputs, as solve = \"inputs\" does; scene '{system.scene.name}' "
                         f"asks for \"{spec.solve}\": set solve = \"inputs\", or give v and u "
                         "to linearize at given states")
    return bool(spec.allow_non_equilibrium if allow is None else allow)


def rest_info(equilibrium: np.ndarray, family: list[int], system: System | None = None,
              Q: np.ndarray | None = None, condition: Sequence[float] | None = None) -> dict:
    """The metadata a schedule adds to its model's ``info``: ``at_rest`` (True), the points
    off equilibrium (opted in) and those whose inputs are a least-norm choice, with notes; for
    a mechanism's stack (``system``, its assembled ``Q`` and the condition of Phi_d at each
    point), the check of :func:`sensitivity` at its point nearest a singular position."""
    info: dict = {"at_rest": True, "notes": []}
    if system is not None and Q is not None and condition is not None:
        checked = sensitivity(system, Q, np.asarray(condition))
        if checked is not None:
            info["operating_point_sensitivity"] = checked
    off = [int(k) for k in np.flatnonzero(~equilibrium)]
    if off:
        info["non_equilibrium_points"] = off
        info["notes"].append(f"{len(off)} point(s) are not equilibria (opted in; the first is "
                             f"point {off[0]}): their models describe the motion about "
                             "(q, v = 0), a = -M^-1 residual")
    if family:
        info["least_norm_points"] = list(family)
        info["notes"].append(f"at {len(family)} point(s) (the first is point {family[0]}) "
                             "the inputs and constraint forces that hold q are not unique: "
                             "the least-norm split is reported, as a single call reports it")
    return info


def holding_inputs(system: System, Q: np.ndarray, allow_non_equilibrium: bool,
                   J: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, list[int], np.ndarray | None]:
    """The inputs that hold each configuration of ``Q`` (N, nq) at rest (module docstring);
    ``J``: a mechanism's closure-frame Jacobians at ``Q`` (N, F, 6, nv) when the assembly
    computed them (:func:`pinlin.loop_kernels.jacobian` makes Phi_q of them).

    Returns:
        (U (N, nu) [N*m or N], equilibrium (N,) booleans, the points whose split of inputs and
        constraint forces is not unique (redundant actuation or rows; the least-norm one is
        taken, as a single call takes it), a mechanism's constraint forces (N, m) [N, N*m]
        (that least-norm split, zero on rows that vanish; None for an open chain)).

    Raises:
        EquilibriumError: the first point that is not an equilibrium (a mechanism's always; an
            open chain's unless ``allow_non_equilibrium``), its message starting with
            "trajectory point k: " and naming the coordinate and the residual.
    """
    if system.constraints:
        return _mechanism(system, Q, J)
    return (*_open_chain(system, Q, allow_non_equilibrium), None)


def _held_force(system: System, Q: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gravity (N, nv), gravity minus springs (N, nv), the statics' scale (N,)) at every
    configuration [N*m or N]; the scale as :meth:`pinlin.System.static_scale` gives it (its
    force reference included, which the schedule's tolerance had left out: a point the
    single call accepted was refused)."""
    N, nv = Q.shape[0], system.nv
    gravity = np.empty((N, nv))
    for k in range(N):
        gravity[k] = system.static_force(Q[k])
    if system.rotation is not None:
        scale = np.array([system.static_scale(Q[k], gravity[k]) for k in range(N)])
    else:   # static_scale without rotation, for all points at once
        scale = np.maximum(system.force_reference, np.abs(gravity).max(axis=1, initial=0.0))
    if not system.has_springs:
        return gravity, gravity, scale
    held = gravity.copy()
    for k in range(N):
        held[k] -= system.spring_torque(Q[k])
    if system.rotation is None:
        scale = np.maximum(scale, np.abs(gravity - held).max(axis=1, initial=0.0))
    return gravity, held, scale


def _tolerances(scale: np.ndarray) -> np.ndarray:
    """The residual tolerance of each point, as :func:`residual_tolerance` gives it for the
    scale of its terms in balance."""
    return np.array([residual_tolerance(float(s)) for s in scale])


def _open_chain(system: System, Q: np.ndarray, allow: bool
                ) -> tuple[np.ndarray, np.ndarray, list[int]]:
    _, held, scale = _held_force(system, Q)
    U = np.ascontiguousarray(held[:, system.actuated_columns])
    N = Q.shape[0]
    free_at = system.unactuated
    if not free_at.size:
        return U, np.ones(N, dtype=bool), []
    free = np.abs(held[:, free_at])
    worst = free.argmax(axis=1)
    equilibrium = free[np.arange(N), worst] <= _tolerances(scale)
    if not allow and not equilibrium.all():
        k = int(np.flatnonzero(~equilibrium)[0])
        i = int(free_at[worst[k]])
        residual = np.zeros(system.nv)
        residual[free_at] = held[k, free_at]
        raise at_point(EquilibriumError(
            f"scene '{system.scene.name}': q is not an equilibrium: the inputs cannot supply "
            f"{held[k, i]:.6g} N or N*m along '{system.coordinate_names[i]}' (largest "
            f"unactuated residual, tolerance {_tolerances(scale[k:k + 1])[0]:.1e}); actuate "
            "it, or pass allow_non_equilibrium=True (--allow-non-equilibrium on the command "
            "line) to linearize about the falling state", residual,
            system.coordinate_names), k)
    return U, equilibrium, []


def _mechanism(system: System, Q: np.ndarray, frame_jacobians: np.ndarray | None
               ) -> tuple[np.ndarray, np.ndarray, list[int], np.ndarray]:
    """The least-norm [u0; lam] of every point at once: one batched SVD of the stacked
    [S, G_k^T], singular values below eps max(rows, columns) s_max dropped, as
    ``np.linalg.lstsq`` (LAPACK ``dgelsd``, what a single call uses) drops them. G_k holds
    the rows that are not identically zero at some point; a row that vanishes at point k adds
    a zero column there, which the least-norm solution leaves at zero and the rank count
    leaves out, as the single call's row selection does."""
    cons = system.constraints
    _, held, scale = _held_force(system, Q)
    S = system.input_matrix
    N, nv, nu = Q.shape[0], system.nv, S.shape[1]
    plan = None if frame_jacobians is None else lk.plan(system)
    if plan is not None:
        J = lk.jacobian(plan, frame_jacobians)
    else:
        J = np.empty((N, cons.size, nv))
        for k in range(N):
            J[k] = cons.jacobian(Q[k])
    present = J.any(axis=2)  # (N, m): rows not identically zero at each point
    rows = np.flatnonzero(present.any(axis=0))
    SG = np.concatenate([np.broadcast_to(S, (N, nv, nu)), J[:, rows].transpose(0, 2, 1)],
                        axis=2)
    columns = nu + present[:, rows].sum(axis=1)
    solution, keep = _least_norm(SG, held, columns)
    # Where the solution is a family and its unknowns mix N and N*m, the member whose norm is
    # in N*m, as a single call picks it (pinlin.equilibrium.statics_split).
    force = unknown_is_force(system, rows)
    mixed = np.flatnonzero(keep.sum(axis=1) < columns) if force.any() and not force.all() \
        else np.zeros(0, dtype=int)
    if mixed.size:
        length = np.array([characteristic_length(system, Q[k])[0] for k in mixed])
        weights, lever = statics_scales(system, force, length[:, None])
        scaled, keep[mixed] = _least_norm(lever[:, :, None] * SG[mixed] / weights[:, None, :],
                                          lever * held[mixed], columns[mixed])
        solution[mixed] = scaled / weights
    # As solve_constrained: the residual against the terms in balance (the statics', the
    # inputs' and the constraint forces'), not against their sum.
    inputs = np.einsum("kij,kj->ki", SG[:, :, :nu], solution[:, :nu])
    supported = np.einsum("kij,kj->ki", SG[:, :, nu:], solution[:, nu:])
    tolerance = _tolerances(np.maximum(scale, np.abs(np.concatenate([inputs, supported], axis=1))
                                       .max(axis=1, initial=0.0)))
    residual = held - np.einsum("kij,kj->ki", SG, solution)
    worst = np.abs(residual).argmax(axis=1) if nv else np.zeros(N, dtype=int)
    bad = np.flatnonzero(np.abs(residual[np.arange(N), worst]) > tolerance) if nv else []
    if len(bad):
        k = int(bad[0])
        i = int(worst[k])
        raise at_point(EquilibriumError(
            f"scene '{system.scene.name}': q is not an equilibrium: a generalized force "
            f"of {residual[k, i]:.6g} N or N*m along '{system.coordinate_names[i]}' is left "
            f"over (tolerance {tolerance[k]:.1e}); with loops a non-equilibrium cannot be "
            "linearized", residual[k], system.coordinate_names), k)
    family = [int(k) for k in np.flatnonzero(keep.sum(axis=1) < columns)]
    lam = np.zeros((N, cons.size))
    lam[:, rows] = solution[:, nu:]
    return np.ascontiguousarray(solution[:, :nu]), np.ones(N, dtype=bool), family, lam


def _least_norm(SG: np.ndarray, b: np.ndarray, columns: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(the least-norm least-squares solutions of SG_k x = b_k (N, columns), which singular
    values each kept (N, columns)): one batched SVD, singular values below
    eps max(rows, ``columns``) s_max dropped (``columns``: each point's columns that are not
    identically zero), as LAPACK ``dgelsd`` drops them."""
    left, sv, right = np.linalg.svd(SG, full_matrices=False)
    keep = sv > (_EPS * np.maximum(SG.shape[1], columns) * sv[:, 0])[:, None]
    inverse = np.divide(1.0, sv, out=np.zeros_like(sv), where=keep)
    coefficients = inverse * np.einsum("kij,ki->kj", left, b)
    return np.einsum("kji,kj->ki", right, coefficients), keep


def sensitivity(system: System, Q: np.ndarray, condition: np.ndarray,
                V: np.ndarray | None = None, U: np.ndarray | None = None,
                stacklevel: int = 4) -> dict | None:
    """What a single call checks near a singular position (Phi_d's condition above
    SENSITIVITY_CHECK, where a single call starts to check;
    :func:`pinlin.formulations.constrained.assembly_sensitivity`, at a moving state ``V``,
    ``U`` :func:`pinlin.formulations.motion.moving_sensitivity`), at the trajectory's point
    of largest condition and, with ``V``, at its moving point of largest condition (a moving
    point near a fold can be 1e4 times as sensitive as one at rest): the relative change of A
    between configurations the assembly cannot tell apart, with an AccuracyWarning naming
    the point above SENSITIVITY_WARN, as the single call warns. Returns {"point", "change"}
    of the larger, or None where no point is that close."""
    from .formulations.constrained import SENSITIVITY_CHECK, SENSITIVITY_WARN
    from .linearization import linearize

    condition = np.asarray(condition, dtype=float)
    if not len(condition):
        return None
    candidates = [int(np.argmax(condition))]
    if V is not None:   # a moving point can be far more sensitive than a point at rest
        moving = np.flatnonzero(np.abs(V).max(axis=1) > 0.0)
        if moving.size:
            candidates.append(int(moving[np.argmax(condition[moving])]))
    found: list[tuple[float, int]] = []
    for k in dict.fromkeys(candidates):
        if not condition[k] > SENSITIVITY_CHECK:
            continue
        with warnings.catch_warnings():  # its warnings are re-issued below, naming the point
            warnings.simplefilter("ignore", AccuracyWarning)
            model = (linearize(system, q=Q[k]) if V is None else
                     linearize(system, q=Q[k], v=V[k], u=U[k]))
        change = model.info["condition"].get("operating_point_sensitivity")
        if change is not None:
            found.append((float(change), k))
    if not found:
        return None
    change, k = max(found)
    if change > SENSITIVITY_WARN:
        warnings.warn(AccuracyWarning(
            f"scene '{system.scene.name}': trajectory point {k}, the "
            f"{'schedule' if V is None else 'trajectory'}'s point nearest a singular "
            f"position of the mechanism (condition {condition[k]:.3g}): "
            f"configurations the assembly cannot tell apart give state matrices {change:.1e} "
            "(relative) apart; the model there is not reliable (move the trajectory away from "
            "the limit, or name other independent coordinates)", 1.0 / change),
            stacklevel=stacklevel)
    return {"point": k, "change": change}


def _single_call(system: System, k: int, q: np.ndarray, models: list, warned: dict,
                 derivatives: str, step: object, allow: bool):
    """``linearize(system, q=q)`` as point k of a schedule (:func:`single_calls`), its
    warnings recorded in ``warned``: (category, text without its numbers) -> (first point,
    warning, points)."""
    from .linearization import linearize

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model = linearize(system, q=q, derivatives=derivatives, step=step,
                              allow_non_equilibrium=allow, estimate_error=False)
    except PinlinError as exc:
        raise at_point(exc, k) from None
    finally:
        for record in caught:
            key = (record.category, _NUMBER.sub("#", str(record.message)))
            warned.setdefault(key, (k, record.message, set()))[2].add(k)
    if models and model.state_names != models[0].state_names:
        raise ModelError(
            f"trajectory point {k}: scene '{system.scene.name}': pinlin chose other "
            f"independent coordinates here ({', '.join(model.info['independent'])}) than at "
            f"point 0 ({', '.join(models[0].info['independent'])}); every point of a "
            "schedule has the same states: name them in operating_point.independent")
    return model


#: Numbers in a warning's text: one warning of the same text at several points, numbers aside.
_NUMBER = re.compile(r"[-+]?\d+(\.\d*)?([eE][-+]?\d+)?")


def _reissue(warned: dict) -> None:
    """Each warning the single calls gave (its text, numbers aside), once: the first point's,
    naming it and how many more points warned so."""
    for first, message, points in warned.values():
        again = type(message).__new__(type(message))  # its own fields, not its __init__'s
        again.__dict__.update(message.__dict__)
        count = len(points)
        more = f" (and {count - 1} more point{'s' if count > 2 else ''})" if count > 1 else ""
        text = str(message.args[0]) if message.args else str(message)
        again.args = (f"trajectory point {first}{more}: {text}", *message.args[1:])
        warnings.warn(again, stacklevel=4)


def needs_single_calls(system: System, derivatives: str, second_order: bool = False) -> bool:
    """Whether a schedule of ``system`` is linearized point by point with single static calls
    (:func:`single_calls`): contacts (anchored where each configuration puts their frames, as
    ``linearize(scene, q=q[k])`` anchors them) and what the stacked mechanism path does not
    cover (weld loops, a floating base, a mechanism's numerical derivatives or second-order
    matrices)."""
    cons = system.constraints
    if not cons:
        return False
    return bool(cons.contacts) or cons.has_welds or system.base_joint is not None \
        or derivatives != "analytic" or second_order


def single_calls(system: System, Q: np.ndarray, *, derivatives: str, step: object,
                 allow: bool, parallel: bool = False,
                 progress: Callable[[int, int], None] | None = None,
                 second_order: bool = False) -> dict:
    """A schedule by :func:`pinlin.linearize` at each ``q=Q[k]`` (:func:`needs_single_calls`):
    every point assembled from its own configuration, its contacts anchored there, its
    statics solved. Returns the fields of a :class:`pinlin.TrajectoryModel` (stacked,
    read-only) but ``t`` and ``dt``; with ``second_order``, each point's M, C_damp, K, Bu
    (a mechanism's: in its independent coordinates, nz x nz).

    Raises:
        ArgumentError: ``parallel`` (workers or an executor were asked for): this path runs
            in this process.
        ResourceError: the stacked models would exceed the memory limit.
        PinlinError: a point's own error, its message starting with "trajectory point k: ";
            ModelError where a point's independent coordinates (chosen by pinlin) differ from
            point 0's: every point of a stack has the same states.
    """

    if parallel:
        raise ArgumentError("workers", f"scene '{system.scene.name}' (contacts, weld loops, a "
                                       "floating base, or a mechanism's numerical derivatives "
                                       "or second-order matrices) has its schedule of rest "
                                       "points linearized point by point in this process; "
                                       "leave out workers and executor")
    check_memory(Layout.of(system, len(Q), second_order=second_order).offsets()[1],
                 f"scene '{system.scene.name}': the models of {len(Q)} points",
                 "A, B, f0 (and M, C_damp, K) stacked, 8 bytes a number")

    models: list = []
    warned: dict[tuple[type, str], tuple[int, Warning, set[int]]] = {}
    try:
        for k, q in enumerate(Q):
            models.append(_single_call(system, k, q, models, warned, derivatives, step, allow))
            if progress is not None:
                progress(k + 1, len(Q))
    finally:  # what the points before a refused one warned of is said too
        _reissue(warned)
    first = models[0]
    ops = [m.operating_point for m in models]
    n = first.A.shape[0]
    fields = {
        "A": np.stack([m.A for m in models]), "B": np.stack([m.B for m in models]),
        "C": np.stack([m.C for m in models]), "D": np.stack([m.D for m in models]),
        "f0": np.stack([np.zeros(n) if m.f0 is None else m.f0 for m in models]),
        "q": np.stack([op.q for op in ops]), "v": np.stack([op.v for op in ops]),
        "u": np.stack([op.u for op in ops]), "a": np.stack([op.a for op in ops]),
        "y": np.stack([op.y for op in ops]),
        "lam": np.stack([op.lam for op in ops]) if first.operating_point.lam is not None
        else None}
    for key in ("M", "C_damp", "K", "Bu"):
        fields[key] = np.stack([getattr(m, key) for m in models]) if second_order else None
    for arr in fields.values():
        if arr is not None:
            arr.setflags(write=False)
    keep = ("formulation", "derivatives", "basis", "effects", "velocity_terms", "base",
            "independent", "constraint_rows", "dropped_rows", "step")
    info = {key: first.info[key] for key in keep if key in first.info}
    info.update(points=len(models), path="per point (single calls at rest)")
    if first.operating_point.lam is not None:
        info["lam_names"] = list(first.operating_point.lam_names)
        info["loops"] = {
            "condition": [m.info["condition"].get("constraint_jacobian", 1.0) for m in models],
            "position_correction": [float(np.linalg.norm(pin.difference(system.model, q,
                                                                         op.q)))
                                    for q, op in zip(Q, ops, strict=True)],
            "velocity_correction": [0.0] * len(models)}
    equilibrium = np.array([op.equilibrium for op in ops])
    family = [k for k, op in enumerate(ops) if any("not unique" in note for note in op.notes)]
    info.update(rest_info(equilibrium, family))
    return {**fields, "state_names": first.state_names, "input_names": first.input_names,
            "output_names": first.output_names, "name": first.name, "info": info}


__all__ = ["holding_inputs", "needs_single_calls", "rest_info", "rest_options", "single_calls"]
