"""Operating points of constrained systems (loops, contacts, mimic couplings) and passive
equilibria.

At rest the residual form of the equations of motion is::

    H(q) = f(q) - tau_spring(q) - S u - Phi_q^T lam = 0,    Phi(q) = 0

with f the generalized force at rest (gravity; centrifugal in a rotating scene) and lam the
constraint forces (the force [N] and torque [N*m] the closure applies to frame1's body, world
frame; for a contact, what the world applies to the robot). Every coordinate takes part,
a floating base's six included: for a standing robot the base's rows say that the contact
forces carry the weight.

- ``solve = "inputs"`` assembles q0 with the independent coordinates z held and solves
  [S, Phi_q^T] [u0; lam] = f - tau_spring in the least-squares sense; what remains is the
  residual. When the columns are dependent (two feet on the ground, or redundant actuation) the
  solution is a family: the least-norm member is taken and a note says how many directions
  the family has. The norm is taken in one unit (:func:`statics_split`): each force [N]
  times a length L, each moment [N*m] as it is, with L the robot's radius of gyration about
  its centre of mass at q0 (:func:`pinlin.coordinates.characteristic_length`). A norm that
  added N to N*m would pick a split that depends on the robot's size (the same robot scaled
  picked another split, and its model differed by 1e-3); this one scales with the robot and
  does not depend on where it stands.
- ``solve = "forces"`` holds the inputs at the scene's ``u`` and solves
  Phi_q^T lam = f - tau_spring - S u for lam alone (unique: the independent rows of Phi_q are
  kept, unless the contacts themselves are redundant: then the least-norm forces, in the
  same unit), the user's own split; a residual left over (inputs that cannot balance the
  robot) is refused with its largest entry.
- ``solve = "positions"`` holds the inputs and finds q0 by Newton on the reduced residual
  R^T (f - tau_spring - S u) over z, whose Jacobian is the reduced stiffness
  R^T (K - lam^T Phi_qq) R of the linear model.

With contacts the notes give each contact's force (:mod:`pinlin.contacts`) and the total
vertical force against the weight, and a point contact that pulls gets a ContactWarning.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from .assembly import (
    Partition,
    assemble,
    assemble_guess,
    cached_assembly,
    named_independent,
    partition,
    projection,
)
from .contacts import statics_notes
from .coordinates import characteristic_length, linear_coordinates
from .exceptions import EquilibriumError, SceneError
from .lapack_direct import lstsq_rank
from .operating_point import OperatingPoint, force_scale, residual_tolerance


@dataclass(frozen=True)
class ConstrainedPoint:
    """What the formulations need besides the operating point.

    Attributes:
        partition: Independent rows and coordinates at q0.
        jacobian: The independent rows of Phi_q at q0 (m x nv).
        stack: At a moving state solved by the stacked kernels, their one-point
            :class:`pinlin.formulations.moving_batch.Stack` (frame Jacobians, M, the velocity
            terms), which the model reuses; else None.
    """

    partition: Partition
    jacobian: np.ndarray
    stack: Any = None


def input_vector(system, values) -> np.ndarray:
    """Inputs u (size nu) from a {joint: value} table, zeros elsewhere [N*m or N]."""
    u = np.zeros(len(system.actuated))
    where = {int(i): k for k, i in enumerate(system.actuated)}
    for name, value in values.items():
        j = system.joint(name, f"operating_point.u.{name}")
        vals = np.atleast_1d(np.asarray(value, dtype=float))
        if not any(j.idx_v + k in where for k in range(j.nv)):
            raise SceneError(system.scene.source, f"operating_point.u.{name}",
                             f"joint '{name}' is not actuated (see inputs.actuated)")
        if vals.size != j.nv:
            raise SceneError(system.scene.source, f"operating_point.u.{name}",
                             f"joint '{name}' has {j.nv} inputs, got {vals.size}")
        for k in range(j.nv):
            if j.idx_v + k not in where:
                raise SceneError(system.scene.source, f"operating_point.u.{name}",
                                 f"joint '{name}' is not actuated (see inputs.actuated)")
            u[where[j.idx_v + k]] = vals[k]
    return u


def static_stiffness(system, q: np.ndarray, lam: np.ndarray | None) -> np.ndarray:
    """dH/d(dq) at rest: K of the open tree plus springs, minus lam^T Phi_qq (analytic)."""
    z = np.zeros(system.nv)
    K, _, _ = system.rnea_derivatives(q, z, z)
    K.flat[::system.nv + 1] += system.stiffness
    if lam is not None and system.constraints:
        K -= system.constraints.hessian(q, lam)
    return K


def _moved_positions(system, given: Mapping[str, Any], q_guess: np.ndarray,
                     q0: np.ndarray) -> str:
    """The 1-DoF joints ``given`` names whose position the assembly moved (beyond 1e-9 rad or
    m), with the change, or "" [rad or m]."""
    diff = pin.difference(system.model, q_guess, q0)
    out = []
    for name in given:
        j = system.joints.get(name)
        if j is not None and j.nv == 1 and abs(diff[j.idx_v]) > 1e-9:
            out.append(f"{name} by {diff[j.idx_v]:+.6g}")
    return ", ".join(out)


def solve_constrained(system, q_guess: np.ndarray, *, allow_non_equilibrium: bool = False,
                      allow_ill_conditioned: bool = False
                      ) -> tuple[OperatingPoint, ConstrainedPoint]:
    """Operating point of a scene with constraints and/or ``solve = "positions"`` or
    ``"forces"`` (``allow_ill_conditioned``: accept an M(q0) singular to working precision
    where the acceleration off equilibrium needs M^-1, see
    :meth:`pinlin.System.mass_inverse`)."""
    spec = system.scene.operating_point
    cons = system.constraints
    notes: list[str] = []
    jac = None
    if cons and spec.independent:
        # A guess solved before comes back from the assembly cache, bit for bit (its
        # partition passed then: it depends on the guess alone).
        found = cached_assembly(system, q_guess, named_independent(system)[0])
        if found is not None:
            q0, jac = found
    if jac is None:
        if cons:
            q0, jac, part = assemble_guess(system, q_guess)
        else:
            q0, part = q_guess, partition(system, q_guess, check=False)
    else:
        part = None
    if spec.solve == "positions":
        u0 = input_vector(system, spec.u)
        if part is None:
            part = partition(system, q_guess, check=False)
        q0, part = _passive_equilibrium(system, q0, part, u0)
        jac = None
        moved = float(np.abs(pin.difference(system.model, q_guess, q0)).max(initial=0.0))
        notes.append(f"solve = \"positions\": q0 is the equilibrium Newton found from the "
                     f"given q (the starting guess), {moved:.3g} rad or m away from it at "
                     f"most; a linearization at q itself needs solve = \"inputs\" or a "
                     f"given state (solve = \"none\")")
    if jac is None:
        jac = cons.jacobian(q0)
    part = partition(system, q0, jac)
    G = jac[part.rows]
    static = system.static_force(q0)
    spring = system.spring_torque(q0) if system.has_springs else None
    f = static if spring is None else static - spring
    S = system.input_matrix
    # The statics use every row that can carry a force: the independent rows, and redundant
    # rows that are not identically zero (two feet holding one body: the split among them is
    # then a family, and the least-norm member over all of them is reported).
    kept = set(int(r) for r in part.rows)
    extra = [r for r in range(jac.shape[0]) if r not in kept and np.any(jac[r])]
    rows = np.concatenate([np.asarray(part.rows, dtype=int), np.array(extra, dtype=int)])
    Gs = jac[rows] if extra else G
    free = 0
    if spec.solve in ("positions", "forces"):
        if spec.solve == "forces":
            u0 = input_vector(system, spec.u)
        if len(rows):
            lam_k, rank, length = statics_split(system, q0, Gs.T, f - S @ u0, rows,
                                                inputs=False)
            free = len(rows) - rank
        else:
            lam_k = np.zeros(0)
        if free:
            notes.append(f"the constraint forces that hold q0 with these inputs are not unique "
                         f"(redundant rows: a family of {free} dimension"
                         f"{'s' if free > 1 else ''}): the least-norm split is reported"
                         f"{_in_one_unit(length)}")
    else:
        SG = np.hstack([S, Gs.T])
        sol, rank, length = statics_split(system, q0, SG, f, rows)  # rank as matrix_rank's
        u0, lam_k = sol[:S.shape[1]], sol[S.shape[1]:]
        free = S.shape[1] + len(rows) - rank
        if free:
            why = ("redundant support" if cons.contacts and len(part.rows) > 0 else
                   "redundant actuation")
            notes.append(f"the inputs and constraint forces that hold q0 are not unique "
                         f"({why}: a family of {free} dimension{'s' if free > 1 else ''}): the "
                         f"least-norm [u0; lam] is reported{_in_one_unit(length)}; give your "
                         "own split with "
                         "operating_point.solve = \"forces\" and the inputs u")
    held = S @ u0
    supported = Gs.T @ lam_k
    residual = f - held - supported
    lam = np.zeros(cons.size)
    lam[rows] = lam_k
    # The terms' size, not their sum f (which a passive equilibrium cancels to rounding).
    scale = max(system.static_scale(q0, static, spring), force_scale(held, supported))
    tol = residual_tolerance(scale)
    worst = int(np.argmax(np.abs(residual))) if residual.size else 0
    equilibrium = bool(residual.size == 0 or abs(residual[worst]) <= tol)
    if not equilibrium:
        name = system.coordinate_names[worst]
        if cons or not allow_non_equilibrium:
            if spec.solve == "forces":
                extra = ("; the inputs given (operating_point.u, zero for joints not named) "
                         "and the constraint forces cannot balance it: give inputs that do, or "
                         "let pinlin find them (solve = \"inputs\")")
            elif cons and allow_non_equilibrium:
                extra = " (with loops or contacts a non-equilibrium cannot be linearized)"
            else:
                extra = ("; actuate it, change q0, or set operating_point.allow_non_equilibrium "
                         "= true (--allow-non-equilibrium on the command line)")
            raise EquilibriumError(
                f"scene '{system.scene.name}': q0 is not an equilibrium: a generalized force "
                f"of {residual[worst]:.6g} N or N*m along '{name}' is left over (tolerance "
                f"{tol:.1e}){extra}", residual, system.coordinate_names)
    if cons:
        zn = (", ".join(system.coordinate_names[i] for i in part.independent)
              or "none (the constraints hold every coordinate)")
        notes.append(f"independent coordinates{' (chosen by pinlin)' if part.chosen else ''}: "
                     f"{zn}")
        if spec.solve != "positions":   # (that mode's note says how far q0 moved)
            moved = _moved_positions(system, spec.q, q_guess, q0)
            if moved:
                notes.append("joint positions the scene gives, moved to close the loops "
                             "(dependent coordinates: a given value is only their starting "
                             f"guess): {moved}")
        if part.dropped:
            notes.append(f"redundant constraint rows left out of the coordinates: "
                         f"{', '.join(part.dropped)}"
                         + (" (they still carry their share of the least-norm forces)"
                            if extra else ""))
        if part.condition > 1e6:
            notes.append(f"near a singular position: the dependent-coordinate Jacobian has "
                         f"condition {part.condition:.3g}")
        notes.extend(statics_notes(system, lam, scale))
    a0 = np.zeros(system.nv)
    if not equilibrium:  # open chain, opted in
        a0 = -(system.mass_inverse(q0, allow_ill_conditioned=allow_ill_conditioned) @ residual)
        notes.append(f"not an equilibrium (opted in): residual {residual[worst]:.6g} along "
                     f"'{system.coordinate_names[worst]}'")
    op = OperatingPoint(q=q0, v=np.zeros(system.nv), u=u0, a=a0, residual=residual,
                        equilibrium=equilibrium, tolerance=tol,
                        lam=lam if cons else None, notes=tuple(notes),
                        lam_names=cons.row_names)
    return op, ConstrainedPoint(part, G)


def unknown_is_force(system, rows: np.ndarray, inputs: bool = True) -> np.ndarray:
    """Which unknowns of the statics [u0; lam[rows]] (or lam[rows] alone, ``inputs`` False)
    are forces [N]; the others are moments [N*m]: an input along a linear coordinate
    (:func:`pinlin.coordinates.linear_coordinates`), the multiplier of a row that is a length
    (:attr:`ConstraintSet.linear_rows`)."""
    lam = system.constraints.linear_rows[np.asarray(rows, dtype=int)]
    if not inputs:
        return lam
    return np.concatenate([linear_coordinates(system)[system.actuated], lam])


def statics_split(system, q: np.ndarray, a: np.ndarray, b: np.ndarray, rows: np.ndarray,
                  inputs: bool = True
                  ) -> tuple[np.ndarray, int, tuple[float, str] | None]:
    """(x, rank, (L, what L is)): the least-squares solution of the statics a x = b
    (a = [S, G^T] with ``inputs``, else G^T; ``rows``: the constraint rows of G), and where
    its columns are dependent the member of the family that the module docstring describes,
    with the length L [m] its norm used (:func:`pinlin.coordinates.characteristic_length`;
    None where the solution is unique, or all unknowns share one unit: the plain least-norm
    is then that member).

    The family is solved through y = W x, W = L for a force and 1 for a moment
    (:func:`unknown_is_force`), with each equation along a linear coordinate times L too
    (N*m like the others; a consistent system's solutions do not change, and the scaled
    columns stay balanced at any size), ``lstsq_rank``'s minimum |y| = |W x|."""
    x, rank = lstsq_rank(a, b)
    if rank >= a.shape[1]:
        return x, rank, None
    force = unknown_is_force(system, rows, inputs)
    if force.all() or not force.any():
        return x, rank, None
    length, what = characteristic_length(system, q)
    weights, lever = statics_scales(system, force, length)
    y, rank = lstsq_rank(lever[:, None] * a / weights, lever * b)
    return y / weights, rank, (length, what)


def statics_scales(system, force: np.ndarray, length: float | np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(W, lever) of :func:`statics_split`: each unknown's weight, L for a force (``force``,
    :func:`unknown_is_force`) and 1 for a moment, and each equation's, L along a linear
    coordinate and 1 along an angular one. ``length``: L [m], or a column (N, 1) of them for
    N points at once."""
    return (np.where(force, length, 1.0),
            np.where(linear_coordinates(system), length, 1.0))


def _in_one_unit(length: tuple[float, str] | None) -> str:
    """The note's words on the norm of a least-norm split (:func:`statics_split`)."""
    if length is None:
        return ""
    value, what = length
    if value == 1.0 and what.startswith("1 m"):
        return f" (the norm in N*m: forces times {what})"
    return f" (the norm in N*m: forces times {what}, {value:.4g} m)"


def _held_force(system, q: np.ndarray) -> np.ndarray:
    """Generalized force the inputs and constraints must supply at rest: gravity (and
    centrifugal) minus the springs [N*m or N]."""
    f = system.static_force(q)
    if system.has_springs:
        f -= system.spring_torque(q)
    return f


def _passive_equilibrium(system, q: np.ndarray, part: Partition, u0: np.ndarray,
                         max_iter: int = 60) -> tuple[np.ndarray, Partition]:
    """Newton over z on the reduced static residual, re-assembling after every step."""
    cons = system.constraints
    S = system.input_matrix

    def reduced(qc: np.ndarray) -> tuple[np.ndarray, np.ndarray, Partition, np.ndarray]:
        jac = cons.jacobian(qc)
        pc = partition(system, qc, jac)
        G = jac[pc.rows]
        f = _held_force(system, qc) - S @ u0
        lam = np.zeros(cons.size)
        if len(pc.rows):
            lam[pc.rows] = np.linalg.lstsq(G.T, f, rcond=None)[0]
        R = projection(G, pc)
        return R.T @ f, R, pc, lam

    rz, R, part, lam = reduced(q)
    # As the final check's tolerance (:func:`residual_tolerance`): relative to the terms.
    scale = max(system.static_scale(q, system.static_force(q)), force_scale(S @ u0))
    for _ in range(max_iter):
        if np.abs(rz).max(initial=0.0) <= 1e-11 * scale:
            return q, part
        Kz = R.T @ static_stiffness(system, q, lam) @ R
        step = np.linalg.lstsq(Kz, -rz, rcond=None)[0]
        for damp in (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125):
            trial = pin.integrate(system.model, q, damp * (R @ step))
            if cons:
                trial = assemble(system, trial, part.independent)
            rz_t, R_t, part_t, lam_t = reduced(trial)
            if np.abs(rz_t).max(initial=0.0) < np.abs(rz).max(initial=0.0):
                q, rz, R, part, lam = trial, rz_t, R_t, part_t, lam_t
                break
        else:
            break
    if np.abs(rz).max(initial=0.0) <= 1e-8 * scale:
        return q, part
    worst = int(np.argmax(np.abs(rz)))
    raise EquilibriumError(f"scene '{system.scene.name}': no passive equilibrium found from the "
                           f"given q (reduced residual {rz[worst]:.3g} N or N*m on independent "
                           f"coordinate '{system.coordinate_names[part.independent[worst]]}'); "
                           "try another starting q", rz, ())
