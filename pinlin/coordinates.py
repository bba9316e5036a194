"""A robot's joints and coordinates, and a scene's per-joint fields placed on them.

A scene names joints; the model works in coordinates: nq configuration and nv velocity entries,
each joint owning a slice of both (:class:`JointInfo`). This module turns the scene's per-joint
fields into per-coordinate quantities of the model and checks them against the robot:

- damping, spring stiffness and armature: vectors over the nv velocity coordinates
  (:func:`damping_vector`, :func:`spring_vectors`, :func:`apply_armature`), also when they come
  from the robot's own files (``effects.* = true``: URDF ``<dynamics>``, SRDF rotor parameters);
- the inputs: the velocity indices the actuated joints drive (:func:`input_indices`);
- the outputs: which state entries and frames make up y (:func:`output_map`);
- the configuration lists of ``operating_point.q`` (:func:`check_configuration_spec`) and the
  robot's names (:func:`check_model_names`).

The functions take the :class:`~pinlin.system.System` being built (anything with the
attributes of :class:`JointIndex`) and raise a :class:`~pinlin.exceptions.SceneError` naming the
scene's field.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin

from .exceptions import SceneError
from .fields import COEFFICIENT_LIMIT, clean, show
from .scene import JointValues, Scene, Spring

FREE_FLYER = "JointModelFreeFlyer"
SPHERICAL = "JointModelSpherical"


@dataclass(frozen=True)
class JointInfo:
    """Where a joint sits in the configuration and velocity vectors.

    Attributes:
        name: Joint name.
        id: Pinocchio joint index.
        kind: Pinocchio short name, e.g. ``JointModelRZ``.
        idx_q, nq: Slice of the configuration vector.
        idx_v, nv: Slice of the velocity (tangent) vector.
    """

    name: str
    id: int
    kind: str
    idx_q: int
    nq: int
    idx_v: int
    nv: int

    @property
    def continuous(self) -> bool:
        """A revolute joint without limits stored as (cos, sin): nq = 2, nv = 1."""
        return self.nq == 2 and self.nv == 1

    def coordinate_names(self) -> list[str]:
        """Names of the joint's velocity coordinates: ``name`` or ``name[i]``."""
        return [self.name] if self.nv == 1 else [f"{self.name}[{i}]" for i in range(self.nv)]


@dataclass(frozen=True)
class OutputMap:
    """How outputs are read from the state.

    Attributes:
        state_rows: (output row, state column) pairs for joint positions/velocities.
        frames: (first output row, frame id) for frame positions, 3 rows each.
        names: Output names.
    """

    state_rows: tuple[tuple[int, int], ...]
    frames: tuple[tuple[int, int], ...]
    names: tuple[str, ...]


class JointIndex(Protocol):
    """What the functions here need of a :class:`~pinlin.system.System`."""

    scene: Scene
    model: pin.Model
    joints: Mapping[str, JointInfo]
    coordinate_names: Sequence[str]
    base_joint: str | None

    @property
    def nv(self) -> int: ...

    def joint(self, name: str, field: str | None = None) -> JointInfo: ...

    def frame_id(self, name: str, field: str | None = None) -> int: ...


def one_dof_configuration(j: JointInfo, value: float) -> np.ndarray:
    """Configuration entries of a 1-DoF joint at position ``value`` [rad or m]."""
    if j.continuous:
        return np.array([np.cos(value), np.sin(value)])
    return np.array([value])


# ------------------------------------------------------------------------------------------------
# Coefficients per velocity coordinate.


def joint_vector(system: JointIndex, values: JointValues, fld: str) -> np.ndarray:
    """Per-joint values (a number, or one per velocity coordinate of the joint) as a vector
    over the nv velocity coordinates, zero for the joints not named."""
    out = np.zeros(system.model.nv)
    for name, value in values.items():
        j = system.joint(name, f"{fld}.{name}")
        if isinstance(value, tuple) and len(value) != j.nv:
            raise SceneError(system.scene.source, f"{fld}.{name}",
                             f"joint '{name}' has {j.nv} velocity coordinates; expected a "
                             f"number or {j.nv} numbers, got {len(value)}")
        out[j.idx_v:j.idx_v + j.nv] = value
    return out


def check_model_coefficients(system: JointIndex, values: np.ndarray, fld: str, origin: str,
                             unit: str) -> None:
    """Per-coordinate coefficients the robot's files give (``effects.* = true``) obey the
    same rule as a scene's: finite, >= 0 and <= COEFFICIENT_LIMIT [``unit``]."""
    ok = np.isfinite(values) & (values >= 0.0) & (values <= COEFFICIENT_LIMIT)
    if not np.all(ok):
        k = int(np.argmin(ok))
        raise SceneError(system.scene.source, fld,
                         f"true takes the values of the {origin}, which give coordinate "
                         f"'{system.coordinate_names[k]}' {values[k]:.6g}; expected a finite "
                         f"number in [0, {COEFFICIENT_LIMIT:g}] [{unit}] (give a table "
                         "{joint = value} instead)")


def apply_armature(system: JointIndex, armature: JointValues | bool | None) -> None:
    """Set ``system.model.armature`` [kg*m^2 or kg] as ``effects.armature`` says: True keeps
    the SRDF rotor inertias the robot was loaded with, a table sets them, None zeroes them."""
    model = system.model
    if armature is True:
        if not np.any(model.armature):
            raise SceneError(system.scene.source, "effects.armature",
                             "true takes the rotor inertias from the robot's SRDF, and this "
                             "robot has none; give a table {joint = value} [kg*m^2]")
        check_model_coefficients(system, np.asarray(model.armature, dtype=float),
                                 "effects.armature", "SRDF rotor parameters", "kg*m^2 or kg")
    elif armature:
        model.armature = joint_vector(system, armature, "effects.armature")
    else:
        model.armature = np.zeros(model.nv)


def damping_vector(system: JointIndex, damping: JointValues | bool | None) -> np.ndarray:
    """Viscous damping per velocity coordinate [N*m*s/rad or N*s/m] as ``effects.damping``
    says: True takes the URDF ``<dynamics damping>`` values; None: zeros."""
    if damping is True:
        values = np.array(system.model.damping, dtype=float).copy()
        if not np.any(values):   # as for armature = true: no values to take is an error
            raise SceneError(system.scene.source, "effects.damping",
                             "true takes the damping from the URDF's <dynamics damping>, and "
                             "this robot has none; give a table {joint = value} "
                             "[N*m*s/rad or N*s/m]")
        check_model_coefficients(system, values, "effects.damping", "URDF <dynamics damping>",
                                 "N*m*s/rad or N*s/m")
        return values
    if damping:
        return joint_vector(system, damping, "effects.damping")
    return np.zeros(system.model.nv)


def spring_vectors(system: JointIndex, springs: Mapping[str, Spring] | None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(stiffness per velocity coordinate [N*m/rad or N/m], the configuration at which every
    spring is relaxed (neutral for the other joints)) from ``effects.springs``."""
    model = system.model
    stiffness = np.zeros(model.nv)
    q_rest = pin.neutral(model)
    for name, spring in (springs or {}).items():
        fld = f"effects.springs.{name}"
        j = system.joint(name, fld)
        if j.nv != 1:
            raise SceneError(system.scene.source, fld,
                             f"springs act on 1-DoF joints; '{name}' has {j.nv}")
        stiffness[j.idx_v] = spring.stiffness
        q_rest[j.idx_q:j.idx_q + j.nq] = one_dof_configuration(j, spring.rest)
    return stiffness, q_rest


# ------------------------------------------------------------------------------------------------
# Names and configurations.


def check_model_names(system: JointIndex) -> None:
    """Joint and frame names must be printable on one line (they appear in messages and
    signal names), must not take the names of the steady rotation's extra joint and frame
    (``__spin__``, ``__spin_body__``), and the coordinate names must be distinct (a 1-DoF
    joint 'p[0]' beside a multi-DoF joint 'p' would give two coordinates the same name)."""
    scene = system.scene
    where = "urdf" if scene.urdf is not None else "robot"
    for kind, names in (("joint", system.joints),
                        ("frame", [f.name for f in system.model.frames])):
        for name in names:
            if not name or not clean(name):
                raise SceneError(scene.source, where,
                                 f"the robot has a {kind} named {show(name)}; pinlin needs "
                                 f"{kind} names without control characters or line breaks")
            if name.startswith("__spin") and scene.effects.rotation is not None:
                raise SceneError(scene.source, where,
                                 f"the robot has a {kind} named '{name}'; names starting "
                                 "with '__spin' are reserved for the steady rotation "
                                 "(effects.rotation)")
    seen: set[str] = set()
    for name in system.coordinate_names:
        if name in seen:
            raise SceneError(scene.source, where,
                             f"two joints give the coordinate name '{name}' (a 1-DoF joint "
                             "named like a coordinate of a multi-DoF joint); rename one")
        seen.add(name)


def check_configuration_spec(system: JointIndex) -> None:
    """Raw configuration lists in ``operating_point.q`` must already be normalized where the
    joint's configuration has a unit-norm part: a continuous joint's (cos, sin), a planar
    joint's (cos, sin) (entries 3-4), a spherical joint's quaternion and a free flyer's
    (entries 4-7). pinlin does not normalize them: (2, 0) is a typo, not an angle.

    Raises:
        SceneError: a list of the wrong length or not normalized, naming the joint.
    """
    src = system.scene.source
    for name, value in system.scene.operating_point.q.items():
        fld = f"operating_point.q.{name}"
        j = system.joint(name, fld)
        if not isinstance(value, tuple):
            continue
        if len(value) != j.nq:
            raise SceneError(src, fld, f"joint '{name}' ({j.kind}) has {j.nq} configuration "
                                       f"values, got {len(value)}")
        q = pin.neutral(system.model)
        q[j.idx_q:j.idx_q + j.nq] = value
        if pin.isNormalized(system.model, q, 1e-6):
            continue
        part, unit, instead = _unit_part(j)
        norm = float(np.linalg.norm(np.asarray(value)[unit])) if unit is not None else np.nan
        raise SceneError(src, fld, f"joint '{name}' ({j.kind}): {part} must have unit norm, "
                                   f"got norm {norm:.6g}; pinlin does not normalize a "
                                   f"configuration (give {instead})")


def _unit_part(j: JointInfo) -> tuple[str, slice | None, str]:
    """Description, slice (within the joint's values) of its unit-norm configuration part, and
    how to give the joint's position instead."""
    if j.kind == FREE_FLYER:
        return ("the quaternion [qx, qy, qz, qw] (entries 4-7)", slice(3, 7),
                "a table {position = [x, y, z], rpy = [r, p, y]} or a unit quaternion")
    if j.kind == SPHERICAL:
        return ("the quaternion [qx, qy, qz, qw]", slice(0, 4),
                "a table {rpy = [r, p, y]} or a unit quaternion")
    if j.kind == "JointModelPlanar":
        return ("the (cos, sin) pair (entries 3-4)", slice(2, 4),
                "[x, y, cos(theta), sin(theta)]")
    if j.continuous:
        return "the (cos, sin) pair", slice(0, 2), "the angle [rad] as a number"
    return "its unit-norm part", None, "normalized values"


# ------------------------------------------------------------------------------------------------
# Inputs and outputs.


def input_indices(system: JointIndex, inputs: str | Sequence[str]) -> np.ndarray:
    """The velocity indices the inputs drive, in input order: those of every joint but a
    floating base for ``"all"``, else those of the joints named."""
    if inputs == "all":
        names = [n for n in system.joints if n != system.base_joint]
    else:
        names = list(inputs)
    idx: list[int] = []
    for name in names:
        j = system.joint(name, "inputs.actuated")
        idx.extend(range(j.idx_v, j.idx_v + j.nv))
    return np.array(idx, dtype=int)


def _output_entry(system: JointIndex, entry: str) -> tuple[tuple[str, ...], JointInfo]:
    """Parts (``q``, ``v``) and joint of one ``outputs.joints`` entry.

    An entry is a joint name (position and velocity) or ``q:`` / ``v:`` followed by a joint
    name. Joint names may contain ':' (``q:arm:elbow`` is the position of joint
    ``arm:elbow``); an entry that reads both ways (joints ``q:x`` and ``x`` both exist) is
    refused as ambiguous.
    """
    src = system.scene.source
    prefix, sep, rest = entry.partition(":")
    as_part = bool(sep) and prefix in ("q", "v") and rest in system.joints
    if entry in system.joints:
        if as_part:
            what = "position" if prefix == "q" else "velocity"
            raise SceneError(src, "outputs.joints",
                             f"'{entry}' is ambiguous: it is a joint of the robot and the "
                             f"{what} of joint '{rest}'; rename one of the joints")
        return ("q", "v"), system.joints[entry]
    if sep and prefix in ("q", "v"):
        return (prefix,), system.joint(rest, "outputs.joints")
    if sep:
        raise SceneError(src, "outputs.joints",
                         f"'{entry}': expected 'name', 'q:name' or 'v:name' (no joint is "
                         f"named '{entry}')")
    return ("q", "v"), system.joint(entry, "outputs.joints")


def output_map(system: JointIndex) -> OutputMap | None:
    """The outputs the scene asks for (joint positions [rad or m] and velocities, frame
    positions in the world frame [m]), or None for the full state."""
    spec = system.scene.outputs
    if spec is None:
        return None
    rows: list[tuple[int, int]] = []
    names: list[str] = []
    origin: dict[str, str] = {}
    for entry in spec.joints:
        parts, j = _output_entry(system, entry)
        for part in parts:
            offset = 0 if part == "q" else system.nv
            for k, cname in enumerate(j.coordinate_names()):
                name = f"{part}:{cname}"
                if name in origin:
                    raise SceneError(system.scene.source, "outputs.joints",
                                     f"output '{name}' is requested twice (by '{origin[name]}' "
                                     f"and '{entry}'); list it once")
                origin[name] = entry
                rows.append((len(names), offset + j.idx_v + k))
                names.append(name)
    frames: list[tuple[int, int]] = []
    for fname in spec.frames:
        fid = system.frame_id(fname, "outputs.frames")
        frames.append((len(names), fid))
        names.extend(f"p:{fname}[{ax}]" for ax in "xyz")
    return OutputMap(tuple(rows), tuple(frames), tuple(names))


def characteristic_length(system, q: np.ndarray, *, own_data: bool = False
                          ) -> tuple[float, str]:
    """(L [m], what it is): the robot's own size, intrinsic to it and its posture at ``q``
    (not to where it stands). It turns a force into a moment in the norm of a least-norm
    statics split (:func:`pinlin.equilibrium.statics_split`) and a metre of a linear
    coordinate into a radian in the constraint Jacobian's partition and condition
    (:func:`pinlin.assembly.unit_factors`):

    - its radius of gyration sqrt(tr I_G / (2 m)), the root-mean-square distance of the
      bodies' mass from their common centre of mass (I_G: their composite inertia about it,
      ``pin.ccrba``);
    - where that vanishes (no mass, or all of it in one point), the root-mean-square
      distance of the joints' origins and the closure frames from their centroid;
    - 1 m where those coincide too (nothing in it has a size).

    ``own_data``: compute in fresh Pinocchio data, leaving the system's untouched (for a
    caller in the middle of other kinematics)."""
    data = system.model.createData() if own_data else system.data
    pin.ccrba(system.model, data, q, np.zeros(system.nv))
    mass = float(data.Ig.mass)
    spread = float(np.trace(data.Ig.inertia)) / (2.0 * mass) if mass > 0.0 else 0.0
    if spread > 0.0 and np.isfinite(spread):
        return float(np.sqrt(spread)), "the radius of gyration"
    kin = system.kin_model
    kd = kin.createData() if own_data else system.kin_data
    pin.framesForwardKinematics(kin, kd, system.kin_q(q))
    points = [kd.oMi[j].translation for j in range(1, kin.njoints)]
    points += [kd.oMf[f].translation for f in system.constraints.closure_frames()]
    P = np.array(points)
    spread = float(((P - P.mean(axis=0)) ** 2).sum(axis=1).mean()) if len(P) else 0.0
    if spread > 0.0 and np.isfinite(spread):
        return (float(np.sqrt(spread)), "the spread of its joints and closure frames (it has "
                                        "no radius of gyration)")
    return 1.0, "1 m (nothing in it has a size)"


def linear_coordinates(system: JointIndex) -> np.ndarray:
    """Which velocity coordinates (nv,) are lengths [m] rather than angles [rad]: those of
    prismatic and translation joints, a free flyer's first three (its linear velocity) and a
    planar joint's first two. A generalized force along a linear coordinate is in N, along an
    angular one in N*m."""
    linear = np.zeros(system.nv, dtype=bool)
    for j in system.joints.values():
        if slides_only(j.kind):
            linear[j.idx_v:j.idx_v + j.nv] = True
        elif j.kind == FREE_FLYER:
            linear[j.idx_v:j.idx_v + 3] = True
        elif j.kind == "JointModelPlanar":
            linear[j.idx_v:j.idx_v + 2] = True
    return linear


def slides_only(kind: str) -> bool:
    """Whether a Pinocchio joint of this kind (``shortname()``) only translates: prismatic
    (PX, PY, PZ, unaligned) or translation joints, whose coordinates are in metres."""
    return (kind.startswith(("JointModelP", "JointModelTranslation"))
            and not kind.startswith("JointModelPlanar"))
