"""Scenes: a robot plus the physical effects, operating point, inputs and outputs in play.

A scene is read from TOML (:meth:`Scene.load`), built for an example-robot-data robot
(:meth:`Scene.from_robot`) or for a bare URDF (:meth:`Scene.from_urdf`). Only the effects a scene
lists are simulated. Every field is checked here for type, finiteness and range; names of joints
and frames are checked against the robot when the :class:`~pinlin.system.System` is built.

File format (paths relative to the scene file)::

    name = "double_pendulum"
    urdf = "double_pendulum.urdf"        # or: robot = "ur5"
    base = "fixed"                       # or "free"

    [effects]                            # only what is listed is simulated
    gravity = [0.0, 0.0, -9.81]          # [m/s^2], or true for standard gravity along -z
    armature = { shoulder = 0.01 }       # [kg*m^2] or [kg]; true: from the robot's SRDF
    damping = { shoulder = 0.5 }         # viscous [N*m*s/rad] or [N*s/m]; true: URDF <dynamics>
    springs = { shoulder = { stiffness = 20.0, rest = 0.0 } }   # [N*m/rad], [rad]
    rotation = { axis = [0, 0, 1], rate = 3.0 }   # whole scene spins steadily [rad/s]
    mimic = true                         # URDF <mimic> joints become couplings

    [[loops]]                            # closures the URDF tree cannot express
    name = "closure"
    type = "point"                       # point (3 rows) | weld (6 rows)
    frame1 = "coupler_tip"
    frame2 = "rocker_tip"

    [[contacts]]                         # a frame held where the posture puts it in the world
    name = "left_foot"                   # unique among loops and contacts
    frame = "left_sole_link"
    type = "weld"                        # point (3 rows) | weld (6 rows: a flat foot)

    [operating_point]
    q = { shoulder = 0.3 }               # [rad] or [m]; others: reference posture or neutral
    independent = ["shoulder"]           # with loops: coordinates held during assembly = z
    solve = "inputs"                     # u0 that holds q0 at rest; "positions": passive q0;
                                         # "forces": u held, constraint forces solved
    u = { shoulder = 0.0 }               # inputs for solve = "positions"/"forces" [N*m or N]
    allow_non_equilibrium = false        # true: linearize even if q0 cannot be held

    [inputs]
    actuated = "all"                     # or a list of joint names

    [outputs]                            # absent: the whole state is the output
    frames = ["tip"]                     # frame positions in the world frame [m]
    joints = ["shoulder", "q:elbow", "v:elbow"]   # name: position and velocity

Contacts. A ``[[contacts]]`` entry holds its frame at the place the scene's posture puts it
(``operating_point.q`` applied to the reference posture, before any assembly): that world
placement is the contact's anchor, fixed for the scene (``pinlin.linearize(scene, q=...)``
anchors the contacts where that configuration puts them instead). Assembly then closes the
loops with every contact held at its anchor. A ``point`` contact keeps the frame's origin (a
foot's tip; its force is reported, and a warning is given when it pulls the robot towards the
ground), a ``weld`` the whole frame (a flat foot; force and torque about the frame's origin).
Contacts on a floating base make a standing robot: at rest the inputs and contact forces must
balance gravity, ``[S, Phi_q^T] [u0; lam] = g(q0)``. With two feet or four legs that split is
not unique; pinlin then reports the least-norm [u0; lam], its norm in N*m (forces times the
robot's radius of gyration, :func:`pinlin.equilibrium.statics_split`), and says so in the
operating point's notes. ``solve = "forces"`` instead holds the inputs at ``u`` (zero for
joints not named) and solves the contact (and loop) forces alone, which are then unique: a
user's own split. If the inputs given cannot balance the robot (the base's own six equations,
or an unactuated joint), pinlin refuses with the force left over. The forces come back as
``OperatingPoint.contact_forces``: contact name -> (force [N], torque [N*m]), in the world
frame, applied by the world to the robot.

Ranges. Every number is an SI value and must be finite; magnitudes are bounded so that nothing
a scene asks for can overflow float64 anywhere downstream (the reasoning behind each limit is in
:mod:`pinlin.fields`):

- positions and angles (``operating_point.q``, spring ``rest``, free-flyer ``position`` and
  ``rpy``): ``|x| <= POSITION_LIMIT`` = 1e6 [m or rad];
- coefficients (``gravity`` [m/s^2], ``damping``, spring ``stiffness``, ``armature``,
  ``operating_point.u`` [N*m or N]): ``|x| <= COEFFICIENT_LIMIT`` = 1e12;
- the steady rotation ``rate`` [rad/s]: ``|rate| <= RATE_LIMIT`` = 1e6 (it enters squared).

Integers too large for a float (TOML allows any number of digits), non-finite values, booleans
where numbers are expected, names with control characters (they would break one-line error
messages) and lists nested where a number is expected are refused with a :class:`SceneError`
naming the file and the field.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .exceptions import ArgumentError, SceneError, UnknownRobotError
from .fields import (  # noqa: F401  (RATE_LIMIT: importable from here)
    COEFFICIENT_LIMIT,
    POSITION_LIMIT,
    RATE_LIMIT,
    check_keys,
    clean,
    flag,
    joint_position,
    joint_table,
    joint_values,
    name_list,
    path_argument,
    read_toml,
    show,
    string,
    table,
)
from .scene_closures import (  # noqa: F401  (LOOP_TYPES, CONTACT_TYPES: importable from here)
    CONTACT_TYPES,
    LOOP_TYPES,
    Contact,
    Loop,
    parse_contacts,
    parse_loops,
)
from .scene_effects import (  # noqa: F401  (Rotation, STANDARD_GRAVITY: importable from here)
    STANDARD_GRAVITY,
    Effects,
    JointValues,
    Rotation,
    Spring,
    parse_effects,
)
from .scene_operating_point import OperatingPointSpec, parse_operating_point

# The range limits (POSITION_LIMIT, ...) are defined in pinlin.fields and importable from here.
# The helpers' old private names here, for code that imported them before pinlin.fields existed:
_clean, _show = clean, show

_TOP_KEYS = ("name", "urdf", "robot", "base", "effects", "operating_point", "inputs", "outputs",
             "loops", "contacts")


@dataclass(frozen=True)
class Outputs:
    """Requested outputs.

    Attributes:
        frames: Frame names whose world position [m] is an output (3 rows each).
        joints: ``"name"`` (position and velocity), ``"q:name"`` or ``"v:name"``.
    """

    frames: tuple[str, ...] = ()
    joints: tuple[str, ...] = ()

    def __post_init__(self) -> None:   # Outputs built in Python are checked as the file's
        for key in ("frames", "joints"):
            value = getattr(self, key)
            if isinstance(value, str):   # tuple("tool0") would be its letters
                raise SceneError(None, f"outputs.{key}", f"expected a list of names, got "
                                                         f"{show(value)}")
            object.__setattr__(self, key, name_list(
                None, f"outputs.{key}", list(value) if isinstance(value, np.ndarray) else value))
        if not self.frames and not self.joints:
            raise SceneError(None, "outputs", "is empty; name frames or joints, or leave the "
                                              "outputs out (None) for the whole state")


@dataclass(frozen=True, eq=False)
class Scene:
    """A robot and everything needed to linearize it. Build with :meth:`load`,
    :meth:`from_robot`, :meth:`from_urdf` or :meth:`from_dict`.

    Attributes:
        name: Scene name, used for reports and default file names.
        urdf: URDF file (absolute), or None when ``robot`` is given.
        robot: example-robot-data robot name, or None.
        base: ``"fixed"`` or ``"free"`` (floating base, 6 velocity coordinates in the base frame).
        effects: Effects in play.
        operating_point: Operating point specification.
        inputs: ``"all"`` (every joint except a floating base) or the actuated joint names.
        outputs: Requested outputs, or None for the full state.
        loops: Loop closures.
        contacts: Frames held at their place in the world at the scene's posture.
        source: Scene file the scene came from, for error messages; None if built in Python.
    """

    name: str
    urdf: Path | None = None
    robot: str | None = None
    base: str | None = None
    effects: Effects = field(default_factory=Effects)
    operating_point: OperatingPointSpec = field(default_factory=OperatingPointSpec)
    inputs: str | tuple[str, ...] = "all"
    outputs: Outputs | None = None
    loops: tuple[Loop, ...] = ()
    source: Path | None = None
    contacts: tuple[Contact, ...] = ()

    def __post_init__(self) -> None:
        """The fields a Python caller can get wrong without a parser to refuse them (a Scene
        built directly or changed with ``dataclasses.replace``)."""
        src = self.source
        string(src, "name", self.name)
        if self.base not in (None, "fixed", "free"):
            raise SceneError(src, "base", f"expected \"fixed\" or \"free\", got "
                                          f"{show(self.base)}")
        if (self.urdf is None) == (self.robot is None):
            raise SceneError(src, "urdf", "give exactly one of 'urdf' (a file) or 'robot' (an "
                                          "example-robot-data name)")
        if self.robot is not None:
            string(src, "robot", self.robot)
        elif not isinstance(self.urdf, Path):
            raise SceneError(src, "urdf", f"expected a pathlib.Path, got {show(self.urdf)}")
        for key, kind in (("effects", Effects), ("operating_point", OperatingPointSpec)):
            if not isinstance(getattr(self, key), kind):
                raise SceneError(src, key, f"expected a {kind.__name__}, got "
                                           f"{show(getattr(self, key))}")
        inputs = self.inputs
        if isinstance(inputs, str):
            string(src, "inputs.actuated", inputs, ("all",))
        else:
            if isinstance(inputs, np.ndarray):
                inputs = inputs.tolist()
            object.__setattr__(self, "inputs", name_list(src, "inputs.actuated", inputs))
        if self.outputs is not None and not isinstance(self.outputs, Outputs):
            raise SceneError(src, "outputs", f"expected an Outputs or None, got "
                                             f"{show(self.outputs)}")
        taken: set[str] = set()
        for key, kind in (("loops", Loop), ("contacts", Contact)):
            items = getattr(self, key)
            if not isinstance(items, tuple | list) or \
                    not all(isinstance(item, kind) for item in items):
                raise SceneError(src, key, f"expected a tuple of {kind.__name__} objects, got "
                                           f"{show(items)}")
            for item in items:
                if item.name in taken:
                    raise SceneError(src, key, f"name '{item.name}' is used twice; loops and "
                                               "contacts need distinct names")
                taken.add(item.name)
            object.__setattr__(self, key, tuple(items))

    # ----------------------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path) -> Scene:
        """Read a scene TOML file.

        Raises:
            ArgumentError: ``path`` is not a path (str or os.PathLike).
            SceneError: missing or unreadable file, malformed TOML (also: arrays nested too
                deeply, integers with more digits than Python converts), unknown key or bad
                value (the message names the file and the field).
        """
        path = path_argument("path", path)
        if not path.suffix and not path.exists() and str(path) in bundled_scenes():
            raise SceneError(path, None, f"scene file not found; '{path}' is a bundled scene: "
                                         f"pinlin.Scene.resolve('{path}') loads it")
        data = read_toml(path, lambda shortened: _parse_scene(shortened, path))
        return cls.from_dict(data, source=path)

    @classmethod
    def from_robot(cls, name: str, /, **overrides: Any) -> Scene:
        """Scene for an example-robot-data robot: gravity, and armature where its loader sets it.

        Args:
            name: Robot name as in ``example_robot_data`` (``pinlin robots`` lists them).
            **overrides: Top-level scene fields in the TOML's dict form (``base``, ``effects``,
                ``operating_point``, ``inputs``, ``outputs``, ``name``, ``loops``,
                ``contacts``); each replaces the whole default field.

        Raises:
            ArgumentError: ``name`` is not a robot name; an override that is not one of those
                fields (``robot``, ``urdf``: the model is ``name``).
        """
        from .robots import load_robot

        if not isinstance(name, str) or not name or not clean(name):
            raise ArgumentError("name", "expected an example-robot-data robot name (a "
                                        f"non-empty string), got {show(name)}")
        effects: dict[str, Any] = {"gravity": list(STANDARD_GRAVITY)}
        if np.any(load_robot(name).model.armature):
            effects["armature"] = True
        data: dict[str, Any] = {"name": name, "robot": name, "effects": effects}
        data.update(_overrides(overrides, "robot"))
        return cls.from_dict(data)

    @classmethod
    def from_urdf(cls, path: str | Path, /, **overrides: Any) -> Scene:
        """Scene for a URDF file: fixed base, standard gravity, all joints actuated;
        ``overrides`` as for :meth:`from_robot`.

        Raises:
            ArgumentError: ``path`` is not a path (str or os.PathLike); an override that is not
                a scene field (``robot``, ``urdf``: the model is ``path``).
        """
        path = path_argument("path", path).resolve()
        data: dict[str, Any] = {
            "name": path.stem,
            "urdf": str(path),
            "effects": {"gravity": list(STANDARD_GRAVITY)},
        }
        data.update(_overrides(overrides, "urdf"))
        return cls.from_dict(data)

    @classmethod
    def resolve(cls, target: str | Path) -> Scene:
        """Scene for a scene file, a URDF file, a bundled scene name or a robot name.

        Raises:
            ArgumentError: ``target`` is not a str or os.PathLike.
        """
        path = path_argument("target", target)
        if path.suffix == ".toml":
            return cls.load(path)
        if path.suffix == ".urdf":
            return cls.from_urdf(path)
        bundled = bundled_scenes()
        if str(target) in bundled:
            return cls.load(bundled[str(target)])
        from .robots import robot_names

        if str(target) in robot_names():
            return cls.from_robot(str(target))
        raise UnknownRobotError(str(target), sorted(bundled) + robot_names())

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str | Path | None = None) -> Scene:
        """Build a scene from the TOML's dict form; ``source`` is used in error messages and to
        resolve a relative ``urdf`` path.

        Raises:
            ArgumentError: ``data`` is not a mapping or ``source`` not a path.
            SceneError: unknown key or bad value (the message names the field).
        """
        if not isinstance(data, Mapping):
            raise ArgumentError("data", "expected a table (dict) of scene fields, got "
                                        f"{show(data)}")
        return _parse_scene(data, path_argument("source", source) if source is not None
                            else None)

    # ----------------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its built :attr:`system` (a Pinocchio model and its data, ~100x
        the scene): a scene sent to another process rebuilds it there on first use."""
        state = dict(self.__dict__)
        state.pop("system", None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)

    @functools.cached_property
    def system(self):
        """The :class:`~pinlin.system.System` for this scene, built once and reused."""
        from .system import System

        return System.build(self)


def bundled_folder() -> Path:
    """The folder of bundled models: the installed ``pinlin.urdf`` package, or ``urdf/`` beside
    the ``pinlin/`` source folder when pinlin is imported from a checkout."""
    try:
        return Path(str(resources.files("pinlin.urdf")))
    except ModuleNotFoundError:
        return Path(__file__).resolve().parent.parent / "urdf"


def bundled_scenes() -> dict[str, Path]:
    """Scenes shipped in ``urdf/``, by scene file stem."""
    return {p.stem: p for p in sorted(bundled_folder().glob("*.toml"))}


#: The top-level fields ``Scene.from_robot`` and ``Scene.from_urdf`` take as overrides (the
#: model itself is the method's argument).
_OVERRIDES = ("name", "base", "effects", "operating_point", "inputs", "outputs", "loops",
              "contacts")


def _overrides(overrides: Mapping[str, Any], what: str) -> Mapping[str, Any]:
    """``overrides`` if each key is a scene field a constructor may override, else an
    ArgumentError naming the first that is not (``robot`` and ``urdf`` are the model, given as
    the constructor's own argument: overriding it silently built another robot)."""
    for key in overrides:
        if key not in _OVERRIDES:
            raise ArgumentError(key, f"not a scene field this constructor overrides; expected "
                                     f"one of {', '.join(_OVERRIDES)} (the {what} is the "
                                     "first argument)")
    return overrides


def _parse_scene(data: Mapping[str, Any], src: Path | None) -> Scene:
    data = table(src, None, data)
    check_keys(src, None, data, _TOP_KEYS)
    has_urdf, has_robot = "urdf" in data, "robot" in data
    if has_urdf == has_robot:
        raise SceneError(src, "urdf", "give exactly one of 'urdf' (a file) or 'robot' "
                                      "(an example-robot-data name)")
    urdf = robot = None
    if has_urdf:
        urdf = Path(string(src, "urdf", data["urdf"]))
        if not urdf.is_absolute():
            urdf = (src.parent if src is not None else Path.cwd()) / urdf
        try:
            urdf = urdf.resolve()
            urdf.is_file()  # raises for paths the file system cannot take (name too long)
        except (OSError, RuntimeError, ValueError) as exc:
            reason = getattr(exc, "strerror", None) or show(str(exc))
            raise SceneError(src, "urdf", f"cannot use the path {show(str(urdf))}: {reason}") \
                from None
    else:
        robot = string(src, "robot", data["robot"])
    default_name = src.stem if src is not None else (robot or (urdf.stem if urdf else "scene"))
    name = string(src, "name", data.get("name", default_name))
    base = None
    if "base" in data:
        base = string(src, "base", data["base"], ("fixed", "free"))
    effects = parse_effects(src, data.get("effects", {}))
    op = parse_operating_point(src, data.get("operating_point", {}))
    inputs: str | tuple[str, ...] = "all"
    if "inputs" in data:
        tin = table(src, "inputs", data["inputs"])
        check_keys(src, "inputs", tin, ("actuated",))
        act = tin.get("actuated", "all")
        if isinstance(act, str):
            inputs = string(src, "inputs.actuated", act, ("all",))
        else:
            inputs = name_list(src, "inputs.actuated", act)
    outputs = None
    if "outputs" in data:
        tout = table(src, "outputs", data["outputs"])
        check_keys(src, "outputs", tout, ("frames", "joints"))
        outputs = Outputs(name_list(src, "outputs.frames", tout.get("frames", [])),
                          name_list(src, "outputs.joints", tout.get("joints", [])))
        if not outputs.frames and not outputs.joints:
            raise SceneError(src, "outputs", "is empty; name frames or joints, or leave the "
                                             "table out to output the whole state")
    loops = parse_loops(src, data["loops"]) if "loops" in data else ()
    contacts = parse_contacts(src, data["contacts"], loops) if "contacts" in data else ()
    return Scene(name=name, urdf=urdf, robot=robot, base=base, effects=effects,
                 operating_point=op, inputs=inputs, outputs=outputs, loops=loops, source=src,
                 contacts=contacts)
