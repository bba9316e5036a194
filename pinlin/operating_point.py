"""Operating points: the configuration q0 a scene asks for and the inputs u0 that hold it.

For ``solve = "inputs"`` the system is at rest (v = 0, v' = 0) and the actuators must supply the
generalized force tau = g(q0) - tau_spring(q0), g being Pinocchio's generalized gravity. The
actuated coordinates take their share as u0; what falls on unactuated coordinates is the
residual. A non-zero residual means q0 is not an equilibrium: pinlin refuses to linearize there
unless the scene opts in with ``allow_non_equilibrium``, in which case the model describes the
motion about the state (q0, v = 0), whose acceleration a0 = -M^-1 residual is reported.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from .coordinates import FREE_FLYER, SPHERICAL, JointInfo, joint_vector, one_dof_configuration
from .exceptions import EquilibriumError, SceneError
from .system import System


@dataclass(frozen=True, eq=False)
class OperatingPoint:
    """The point a linear model is taken about.

    Attributes:
        q: Configuration, size nq (Pinocchio convention; quaternions as [x, y, z, w]).
        v: Velocity, size nv [rad/s or m/s].
        u: Inputs, generalized forces on the actuated coordinates [N*m or N].
        a: Acceleration at (q, v, u), size nv: zero at an equilibrium.
        residual: Generalized force the inputs cannot supply, per coordinate [N*m or N]; None
            where it was not computed (the points of a linearized trajectory).
        equilibrium: Whether the residual is zero within ``tolerance``.
        tolerance: Residual tolerance used [N*m or N].
        y: Output values at the point (frame positions [m], joint values).
        lam: Constraint forces per constraint row (loops: force [N] and torque [N*m] applied to
            frame1's body in the world frame; contacts: what the world applies to the robot at
            the contact frame's origin, world frame; mimic: generalized force [N*m or N]); zero
            on dropped redundant rows; None without constraints. :attr:`contact_forces` groups
            the contacts' rows.
        lam_names: Names of the constraint rows, matching ``lam``.
        notes: Human-readable remarks (e.g. an opted-in non-equilibrium).
    """

    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    a: np.ndarray
    residual: np.ndarray | None
    equilibrium: bool
    tolerance: float
    y: np.ndarray | None = None
    lam: np.ndarray | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    lam_names: tuple[str, ...] = ()

    @classmethod
    def trusted(cls, **fields: Any) -> OperatingPoint:
        """A point from code that built every field itself (all fields given): skips the
        frozen dataclass's per-field ``__setattr__``, a few microseconds per linearization."""
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    def with_outputs(self, y: np.ndarray) -> OperatingPoint:
        """The same point with output values ``y`` (a field copy: every other field is the
        same object, already checked when this point was made)."""
        obj = object.__new__(OperatingPoint)
        fields = obj.__dict__
        fields.update(self.__dict__)
        fields["y"] = y
        return obj

    @property
    def contact_forces(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Contact name -> (force [N], torque [N*m]), each of size 3, in the world frame: what
        the world applies to the robot at the contact frame's origin (a point contact's torque
        is zero). Read from :attr:`lam` and :attr:`lam_names` (rows ``contact:<name>.x`` ...),
        so a saved and reloaded point has them too; empty without contacts."""
        from .contacts import contact_forces

        return contact_forces(self.lam, self.lam_names)

    def as_dict(self) -> dict[str, Any]:
        """Plain-Python form (lists) for JSON export (``contact_forces`` as
        ``{name: {"force": [...], "torque": [...]}}``, derived from ``lam``)."""
        out: dict[str, Any] = {}
        for key in ("q", "v", "u", "a", "residual", "y", "lam"):
            val = getattr(self, key)
            out[key] = None if val is None else np.asarray(val).tolist()
        out.update(equilibrium=self.equilibrium, tolerance=self.tolerance, notes=list(self.notes),
                   lam_names=list(self.lam_names))
        forces = self.contact_forces
        if forces:
            out["contact_forces"] = {name: {"force": f.tolist(), "torque": t.tolist()}
                                     for name, (f, t) in forces.items()}
        return out


def configuration(system: System, spec: Mapping[str, Any] | None = None) -> np.ndarray:
    """q0: the reference posture with the scene's joint positions applied.

    Raises:
        SceneError: unknown joint, wrong number of values, non-unit quaternion.
    """
    if spec is None:  # the scene's own: built once per system (rpy, quaternions), then copied
        return system.scene_configuration.copy()
    return _configuration_from(system, spec)


def _configuration_from(system: System, spec: Mapping[str, Any]) -> np.ndarray:
    """:func:`configuration` for a given ``spec``, computed."""
    q = system.q_ref.copy()
    for name, value in spec.items():
        fld = f"operating_point.q.{name}"
        j = system.joint(name, fld)
        q[j.idx_q:j.idx_q + j.nq] = _joint_configuration(system, j, value, q, fld)
    _check_wound_springs(system, spec, q)
    return q


def _check_wound_springs(system: System, spec: Mapping[str, Any], q: np.ndarray) -> None:
    """Refuse a spring on a continuous joint whose deflection q0 - rest lies beyond pi: the
    joint's configuration (cos, sin) has no winding count, so the spring acts on the angle
    difference wrapped to (-pi, pi] (pinocchio's difference), which differs from
    -k (q - rest) exactly there (rest = 10 rad at q0 = 0 gave 20 (10 - 4 pi) instead of 200)."""
    for name, spring in (system.scene.effects.springs or {}).items():
        j = system.joints.get(name)
        if j is None or not j.continuous:
            continue
        value = spec.get(name)
        angle = (float(value) if isinstance(value, float | int) else
                 math.atan2(q[j.idx_q + 1], q[j.idx_q]))
        if abs(angle - spring.rest) > math.pi:
            raise SceneError(system.scene.source, f"effects.springs.{name}.rest",
                             f"joint '{name}' is continuous: its angle is known modulo 2 pi, "
                             f"so its spring acts on q - rest wrapped to (-pi, pi], and "
                             f"q0 - rest = {angle - spring.rest:.6g} rad lies beyond pi; give "
                             "a rest within pi of q0, or make the joint revolute for a wound "
                             "spring")


def _joint_configuration(system: System, j: JointInfo, value: Any, q: np.ndarray,
                         fld: str) -> np.ndarray:
    src = system.scene.source
    current = q[j.idx_q:j.idx_q + j.nq].copy()
    if isinstance(value, float | int):
        if j.nv != 1:
            raise SceneError(src, fld, f"joint '{j.name}' ({j.kind}) has {j.nq} configuration "
                                       f"values; give a list of {j.nq} or a table")
        return one_dof_configuration(j, float(value))
    if isinstance(value, tuple):
        if len(value) != j.nq:
            raise SceneError(src, fld, f"joint '{j.name}' ({j.kind}) has {j.nq} configuration "
                                       f"values, got {len(value)}")
        raw = np.array(value, dtype=float)
        quat = _quaternion_slice(j)
        if quat is not None and abs(np.linalg.norm(raw[quat]) - 1.0) > 1e-6:
            raise SceneError(src, fld, "the quaternion part [x, y, z, w] must have unit norm, "
                                       f"got {np.linalg.norm(raw[quat]):.6g}")
        if j.continuous and abs(np.hypot(*raw) - 1.0) > 1e-6:
            raise SceneError(src, fld, "a continuous joint's (cos, sin) pair must have unit norm")
        return raw
    # A table: position / rpy / quaternion for free-flyer or spherical joints.
    quat_slice = _quaternion_slice(j)
    if quat_slice is None:
        raise SceneError(src, fld, f"a table (position, rpy, quaternion) needs a free-flyer or "
                                   f"spherical joint; '{j.name}' is {j.kind}")
    if "position" in value:
        if j.kind != FREE_FLYER:
            raise SceneError(src, f"{fld}.position", "only a free-flyer joint has a position")
        current[:3] = value["position"]
    if "rpy" in value:
        rot = pin.rpy.rpyToMatrix(*value["rpy"])
        current[quat_slice] = pin.Quaternion(rot).coeffs()
    elif "quaternion" in value:
        current[quat_slice] = value["quaternion"]
    return current


def _quaternion_slice(j: JointInfo) -> slice | None:
    if j.kind == FREE_FLYER:
        return slice(3, 7)
    if j.kind == SPHERICAL:
        return slice(0, 4)
    return None


def residual_tolerance(tau_scale: float) -> float:
    """Residual below which a generalized force counts as zero [N*m or N]: 1e-9 of
    ``tau_scale``, the largest of the terms in balance (gravity, centrifugal, springs, inputs,
    constraint forces; :meth:`pinlin.System.static_scale`), not of their sum, which vanishes
    at a balance. Relative only: the same robot scaled to millimetres or to tonnes keeps its
    verdict (an absolute floor of 1e-9 N*m once called a 3 mm pendulum accelerating at
    7000 rad/s^2 an equilibrium)."""
    return 1e-9 * tau_scale


def force_scale(*terms: np.ndarray) -> float:
    """The largest |entry| over the given generalized forces [N*m or N] (0 for none)."""
    return max((float(np.abs(t).max(initial=0.0)) for t in terms), default=0.0)


def hold_at_rest(system: System, q0: np.ndarray, *, allow_non_equilibrium: bool = False,
                 mass_inverse: np.ndarray | None = None, allow_ill_conditioned: bool = False
                 ) -> OperatingPoint:
    """Inputs u0 that hold q0 at rest (``solve = "inputs"``).

    Args:
        q0: A finite configuration (as :func:`configuration` and ``pinlin.linearize`` give).
        mass_inverse: M(q0)^-1 when the caller has it (needed only off equilibrium).
        allow_ill_conditioned: Accept an M(q0) singular to working precision when M^-1 is
            needed (see :meth:`pinlin.System.mass_inverse`).

    Raises:
        EquilibriumError: some unactuated coordinate carries a generalized force the inputs
            cannot cancel and ``allow_non_equilibrium`` is False. The message names the worst
            coordinate and the residual.
        ModelError: off equilibrium, M(q0) is singular (see :meth:`pinlin.System.mass_inverse`).
    """
    nv = system.nv
    gravity = system.static_force(q0)
    spring = system.spring_torque(q0) if system.has_springs else None
    tau = gravity if spring is None else gravity - spring
    u0 = tau[system.actuated_columns]
    residual = np.zeros(nv)
    tol = residual_tolerance(system.static_scale(q0, gravity, spring))
    free_at = system.unactuated
    worst, equilibrium = 0, True
    if free_at.size:
        free = tau[free_at]
        residual[free_at] = free
        k = int(np.abs(free).argmax())
        worst, equilibrium = int(free_at[k]), bool(abs(free[k]) <= tol)
    if equilibrium:
        return OperatingPoint.trusted(q=q0, v=np.zeros(nv), u=u0, a=np.zeros(nv),
                                      residual=residual, equilibrium=True, tolerance=tol, y=None,
                                      lam=None, notes=(), lam_names=())
    name = system.coordinate_names[worst]
    if not allow_non_equilibrium:
        raise EquilibriumError(
            f"scene '{system.scene.name}': q0 is not an equilibrium: the inputs cannot "
            f"supply {residual[worst]:.6g} N or N*m along '{name}' (largest unactuated "
            f"residual, tolerance {tol:.1e}); actuate it, change q0, or set "
            "operating_point.allow_non_equilibrium = true (--allow-non-equilibrium on the "
            "command line)",
            residual, system.coordinate_names)
    # M a0 + g = S u0 + tau_spring and S u0 = g - tau_spring - residual: a0 = -M^-1 residual.
    if mass_inverse is None:
        mass_inverse = system.mass_inverse(q0, allow_ill_conditioned=allow_ill_conditioned)
    a0 = -(mass_inverse @ residual)
    notes = (f"not an equilibrium (opted in): residual {float(residual[worst]):.6g} along "
             f"'{name}', the model describes the motion about (q0, v = 0) with "
             f"|a0| = {math.sqrt(a0 @ a0):.6g}",)
    return OperatingPoint.trusted(q=q0, v=np.zeros(nv), u=u0, a=a0, residual=residual,
                                  equilibrium=False, tolerance=tol, y=None, lam=None,
                                  notes=notes, lam_names=())


def velocity_vector(system: System, values: Mapping[str, Any], fld: str = "operating_point.v"
                    ) -> np.ndarray:
    """Joint velocities from a {joint: value} table as a vector over the nv coordinates
    [rad/s or m/s], zero for joints not named: a number for a 1-DoF joint, a list of the
    joint's nv values otherwise (a free flyer: [vx, vy, vz, wx, wy, wz] in its own frame).

    Raises:
        SceneError: unknown joint, a number for a multi-DoF joint, or the wrong count.
    """
    for name, value in values.items():
        j = system.joint(name, f"{fld}.{name}")
        if not isinstance(value, tuple) and j.nv != 1:
            raise SceneError(system.scene.source, f"{fld}.{name}",
                             f"joint '{name}' ({j.kind}) has {j.nv} velocity coordinates; "
                             f"give a list of {j.nv} numbers")
    return joint_vector(system, values, fld)


def at_state(system: System, q0: np.ndarray, v0: np.ndarray, u0: np.ndarray, *,
             mass_inverse: np.ndarray | None = None) -> OperatingPoint:
    """The operating point at a given state (``solve = "none"``): nothing is solved for.

    The acceleration is the scene's forward dynamics there,
    a0 = M(q0)^-1 (S u0 + tau_spring(q0) - D v0 - b(q0, v0)) [rad/s^2 or m/s^2], with b the
    bias forces (gravity, Coriolis and centrifugal; the rotating frame's too when the scene
    spins). ``residual`` holds the unbalanced force M a0 [N*m or N]; the point is an
    equilibrium only when v0 and a0 vanish.

    Args:
        q0: Configuration (nq, checked by the caller), v0: velocity (nv) [rad/s or m/s],
            u0: inputs (nu) [N*m or N].
        mass_inverse: M(q0)^-1 when the caller has it.
    """
    nv = system.nv
    held = system.input_matrix @ u0
    bias = system.rnea(q0, v0, np.zeros(nv))
    tau = held - bias
    spring = system.spring_torque(q0) if system.has_springs else None
    if spring is not None:
        tau += spring
    if system.has_damping:
        tau -= system.damping * v0
    Minv = system.mass_inverse(q0) if mass_inverse is None else mass_inverse
    a0 = Minv @ tau
    # Measured against the terms (inputs, bias forces, springs), not against their sum tau.
    tol = residual_tolerance(max(force_scale(held), system.static_scale(q0, bias, spring)))
    moving = bool(np.any(v0))
    equilibrium = not moving and bool(np.abs(tau).max(initial=0.0) <= tol)
    note = (f"state given (solve = \"none\"): |v0| = {np.sqrt(v0 @ v0):.6g}, "
            f"|a0| = {np.sqrt(a0 @ a0):.6g}; the model is affine, x' = f0 + A x + B u with "
            "f0 = [v0; a0]" if not equilibrium else
            "state given (solve = \"none\"): an equilibrium")
    return OperatingPoint.trusted(q=q0, v=v0, u=u0, a=a0, residual=tau, equilibrium=equilibrium,
                                  tolerance=tol, y=None, lam=None, notes=(note,), lam_names=())
