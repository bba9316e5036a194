"""The ``[operating_point]`` table of a scene: where to linearize (:class:`OperatingPointSpec`),
checked as the file's (:func:`parse_operating_point`) or as built in Python."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .exceptions import SceneError
from .fields import (
    COEFFICIENT_LIMIT,
    check_keys,
    flag,
    joint_position,
    joint_table,
    joint_values,
    name_list,
    show,
    string,
    table,
)
from .scene_effects import JointValues

_OP_KEYS = ("q", "v", "independent", "solve", "u", "allow_non_equilibrium")
_SOLVE_MODES = ("inputs", "positions", "none", "forces")
_U_WITH_INPUTS = ("inputs are given only with solve = \"positions\", \"forces\" or \"none\" "
                  "(with \"inputs\" pinlin finds them)")
_V_NOT_NONE = ("velocities are given only with solve = \"none\" (the other modes find a point "
               "at rest)")


@dataclass(frozen=True)
class OperatingPointSpec:
    """Where to linearize.

    Attributes:
        q: Joint positions by joint name: a number ([rad] or [m]; for a continuous joint the
            angle), a list of the joint's raw configuration values, or for a free-flyer or
            spherical joint a table ``{position = [x, y, z], rpy = [r, p, y]}`` /
            ``{quaternion = [x, y, z, w]}``. Joints not named keep the reference posture.
        independent: With loops, contacts or mimic couplings: the joints held at their ``q``
            values during assembly, used as independent coordinates z; empty: pinlin chooses.
        solve: ``"inputs"``: find the inputs u0 that hold q0 at rest (with the constraint
            forces; the least-norm [u0; lam] when they are not unique); ``"positions"``: find
            the passive equilibrium q0 (``q`` is the starting guess) for the inputs ``u``;
            ``"forces"``: hold the inputs at ``u`` and solve the constraint (contact, loop)
            forces that keep q0 at rest; ``"none"``: take the state (q0, v0, u0) as given,
            moving or not (the model is affine, x' = f0 + A x + B u, with the acceleration a0
            reported).
        u: Input values by joint name for ``solve = "positions"``, ``"forces"`` or ``"none"``
            [N*m or N]; others zero.
        v: Joint velocities by joint name for ``solve = "none"``: a number for a 1-DoF joint
            [rad/s or m/s], a list of the joint's nv values (a free flyer: [vx, vy, vz, wx,
            wy, wz] in the base frame); others zero.
        allow_non_equilibrium: Linearize about (q0, v = 0, u0) even when u0 cannot hold q0.
    """

    q: Mapping[str, Any] = field(default_factory=dict)
    independent: tuple[str, ...] = ()
    solve: str = "inputs"
    u: JointValues = field(default_factory=dict)
    allow_non_equilibrium: bool = False
    v: JointValues = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Check the fields as the scene file's are checked, and store them as the file's
        parser does (numbers as floats, lists as tuples, names as a tuple): a spec built in
        Python or changed with ``dataclasses.replace`` reads like one from a file (a numpy
        array or list for a free flyer's q was otherwise taken for a table and ignored)."""
        flag(None, "operating_point.allow_non_equilibrium", self.allow_non_equilibrium)
        q = {j: joint_position(None, f"operating_point.q.{j}", x)
             for j, x in joint_table(None, "operating_point.q", self.q).items()}
        if isinstance(self.independent, str):   # list("crank") would be its letters
            raise SceneError(None, "operating_point.independent",
                             f"expected a list of joint names, got {show(self.independent)}")
        independent = name_list(None, "operating_point.independent",
                                self.independent if isinstance(self.independent, list | tuple)
                                else list(self.independent))
        u = joint_values(None, "operating_point.u", self.u, unit=" [N*m or N]",
                         limit=COEFFICIENT_LIMIT)
        v = joint_values(None, "operating_point.v", self.v, unit=" [rad/s or m/s]",
                         limit=COEFFICIENT_LIMIT)
        if not isinstance(self.solve, str) or self.solve not in _SOLVE_MODES:
            raise SceneError(None, "operating_point.solve",
                             f"expected one of {', '.join(repr(c) for c in _SOLVE_MODES)}, "
                             f"got {show(self.solve)}")
        if u and self.solve == "inputs":
            raise SceneError(None, "operating_point.u", _U_WITH_INPUTS)
        if v and self.solve != "none":
            raise SceneError(None, "operating_point.v", _V_NOT_NONE)
        for key, value in (("q", q), ("independent", independent), ("u", u), ("v", v)):
            object.__setattr__(self, key, value)


def parse_operating_point(src, x: Any) -> OperatingPointSpec:
    """The ``[operating_point]`` table ``x`` of scene file ``src`` (None: built in Python)."""
    tbl = table(src, "operating_point", x)
    check_keys(src, "operating_point", tbl, _OP_KEYS)
    q = {j: joint_position(src, f"operating_point.q.{j}", v)
         for j, v in joint_table(src, "operating_point.q", tbl.get("q", {})).items()}
    independent = name_list(src, "operating_point.independent", tbl.get("independent", []))
    if "independent" in tbl and not independent:
        raise SceneError(src, "operating_point.independent",
                         "expected the names of the independent joints, got an empty list; "
                         "leave the key out to let pinlin choose them")
    solve = string(src, "operating_point.solve", tbl.get("solve", "inputs"), _SOLVE_MODES)
    u = joint_values(src, "operating_point.u", tbl.get("u", {}), unit=" [N*m or N]",
                     limit=COEFFICIENT_LIMIT)
    if u and solve == "inputs":
        raise SceneError(src, "operating_point.u", _U_WITH_INPUTS)
    v = joint_values(src, "operating_point.v", tbl.get("v", {}), unit=" [rad/s or m/s]",
                     limit=COEFFICIENT_LIMIT)
    if v and solve != "none":
        raise SceneError(src, "operating_point.v", _V_NOT_NONE)
    allow = flag(src, "operating_point.allow_non_equilibrium",
                 tbl.get("allow_non_equilibrium", False))
    return OperatingPointSpec(q, independent, solve, u, allow, v)
