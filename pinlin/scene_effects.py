"""The physical effects a scene calls for (its ``[effects]`` table): gravity, armature,
viscous damping, joint springs, a steady rotation and URDF mimic couplings.

Only the effects listed are simulated (:class:`Effects`); :func:`parse_effects` reads and checks
the table (types, finiteness and ranges as :mod:`pinlin.fields` says). The field reference is
in :mod:`pinlin.scene`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .exceptions import SceneError
from .fields import (
    COEFFICIENT_LIMIT,
    POSITION_LIMIT,
    RATE_LIMIT,
    Source,
    check_keys,
    direction,
    flag,
    joint_table,
    joint_values,
    number,
    number_list,
    show,
    table,
)

#: Gravity for ``gravity = true`` [m/s^2].
STANDARD_GRAVITY = (0.0, 0.0, -9.81)
EFFECT_KEYS = ("gravity", "armature", "damping", "springs", "rotation", "mimic")


@dataclass(frozen=True)
class Spring:
    """A linear joint spring: torque = -stiffness * (q - rest).

    Attributes:
        stiffness: [N*m/rad] for rotational joints, [N/m] for prismatic ones; >= 0.
        rest: Rest position [rad] or [m].
    """

    stiffness: float
    rest: float = 0.0

    def __post_init__(self) -> None:   # a Spring built in Python is checked as the file's
        number(None, "effects.springs.stiffness", self.stiffness, minimum=0.0,
               unit=" [N*m/rad or N/m]", limit=COEFFICIENT_LIMIT)
        number(None, "effects.springs.rest", self.rest, unit=" [rad or m]",
               limit=POSITION_LIMIT)


JointValues = Mapping[str, float | tuple[float, ...]]


@dataclass(frozen=True)
class Rotation:
    """Steady rotation of the whole scene about a world axis through the origin.

    Attributes:
        axis: Unit axis in the world frame.
        rate: Angular rate [rad/s] (sign by the right-hand rule about ``axis``).
    """

    axis: tuple[float, float, float]
    rate: float

    def __post_init__(self) -> None:
        axis = direction(None, "effects.rotation.axis", self.axis)
        if max(abs(a - b) for a, b in zip(axis, self.axis, strict=True)) > 1e-12:
            raise SceneError(None, "effects.rotation.axis", f"expected a unit vector (the rate "
                                                            f"gives the speed), got "
                                                            f"{show(self.axis)}")
        number(None, "effects.rotation.rate", self.rate, unit=" [rad/s]", limit=RATE_LIMIT)


@dataclass(frozen=True)
class Effects:
    """The physical effects a scene calls for; anything absent is not simulated.

    Attributes:
        gravity: Gravity vector in the world frame [m/s^2], or None for no gravity.
        armature: Rotor inertia added to the diagonal of M, per joint [kg*m^2] or [kg]; True takes
            it from the robot's SRDF rotor parameters; None: no armature.
        damping: Viscous joint damping per joint [N*m*s/rad] or [N*s/m]; True takes the URDF
            ``<dynamics damping>`` values; None: no damping.
        springs: Joint springs by joint name; None: no springs.
        rotation: Steady rotation of the scene, or None.
        mimic: Whether the URDF's ``<mimic>`` tags couple their joints (holonomic constraints
            q_mimic = multiplier * q_joint + offset); False: mimic joints move freely.
    """

    gravity: tuple[float, float, float] | None = None
    armature: JointValues | bool | None = None
    damping: JointValues | bool | None = None
    springs: Mapping[str, Spring] | None = None
    rotation: Rotation | None = None
    mimic: bool = False

    def __post_init__(self) -> None:
        """Check the fields as the scene file's are checked (an Effects built in Python, or
        changed with ``dataclasses.replace``, gets the same refusals)."""
        flag(None, "effects.mimic", self.mimic)
        if self.gravity is not None:   # stored as the file's parser does: a tuple of floats
            object.__setattr__(self, "gravity", number_list(
                None, "effects.gravity", self.gravity, length=3, unit=" [m/s^2]",
                limit=COEFFICIENT_LIMIT))
        for key, unit in (("armature", " [kg*m^2 or kg]"), ("damping", " [N*m*s/rad or N*s/m]")):
            value = getattr(self, key)
            if value is not None and value is not False:
                object.__setattr__(self, key, _per_joint(None, f"effects.{key}", value, unit))
        if self.springs is not None:
            joint_table(None, "effects.springs", self.springs)
            for joint, spring in self.springs.items():
                if not isinstance(spring, Spring):
                    raise SceneError(None, f"effects.springs.{joint}", f"expected a Spring, got "
                                                                       f"{show(spring)}")
        if self.rotation is not None and not isinstance(self.rotation, Rotation):
            raise SceneError(None, "effects.rotation", f"expected a Rotation or None, got "
                                                       f"{show(self.rotation)}")

    def in_play(self) -> list[str]:
        """Names of the effects present, in a fixed order."""
        return [k for k in EFFECT_KEYS if getattr(self, k) not in (None, False, {})]


def _per_joint(src: Source, fld: str, x: Any, unit: str) -> JointValues | bool:
    """A per-joint coefficient table (>= 0) or True (take the values from the robot's files)."""
    if x is True:
        return True
    return joint_values(src, fld, x, unit=unit, minimum=0.0, limit=COEFFICIENT_LIMIT)


def parse_effects(src: Source, x: Any) -> Effects:
    """The ``[effects]`` table, checked (see :mod:`pinlin.scene` for the fields and ranges)."""
    tbl = table(src, "effects", x)
    check_keys(src, "effects", tbl, EFFECT_KEYS)
    gravity = None
    if "gravity" in tbl:
        g = tbl["gravity"]
        if g is True:
            gravity = STANDARD_GRAVITY
        elif g is not False:
            gravity = number_list(src, "effects.gravity", g, length=3, unit=" [m/s^2]",
                                  limit=COEFFICIENT_LIMIT)
    armature = damping = None
    if "armature" in tbl and tbl["armature"] is not False:
        armature = _per_joint(src, "effects.armature", tbl["armature"], " [kg*m^2 or kg]")
    if "damping" in tbl and tbl["damping"] is not False:
        damping = _per_joint(src, "effects.damping", tbl["damping"], " [N*m*s/rad or N*s/m]")
    springs = None
    if "springs" in tbl:
        springs = {}
        for joint, spec in joint_table(src, "effects.springs", tbl["springs"]).items():
            f = f"effects.springs.{joint}"
            spec = table(src, f, spec)
            check_keys(src, f, spec, ("stiffness", "rest"))
            if "stiffness" not in spec:
                raise SceneError(src, f"{f}.stiffness", "missing; expected a number >= 0")
            springs[joint] = Spring(
                number(src, f"{f}.stiffness", spec["stiffness"], minimum=0.0,
                       unit=" [N*m/rad or N/m]", limit=COEFFICIENT_LIMIT),
                number(src, f"{f}.rest", spec.get("rest", 0.0), unit=" [rad or m]",
                       limit=POSITION_LIMIT),
            )
    rotation = None
    if "rotation" in tbl and tbl["rotation"] is not False:
        f = "effects.rotation"
        spec = table(src, f, tbl["rotation"])
        check_keys(src, f, spec, ("axis", "rate"))
        for key in ("axis", "rate"):
            if key not in spec:
                raise SceneError(src, f"{f}.{key}", "missing")
        rotation = Rotation(direction(src, f"{f}.axis", spec["axis"]),
                            number(src, f"{f}.rate", spec["rate"], unit=" [rad/s]",
                                   limit=RATE_LIMIT))
    mimic = flag(src, "effects.mimic", tbl.get("mimic", False))
    return Effects(gravity, armature, damping, springs, rotation, mimic)
