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

    [operating_point]
    q = { shoulder = 0.3 }               # [rad] or [m]; others: reference posture or neutral
    independent = ["shoulder"]           # with loops: coordinates held during assembly = z
    solve = "inputs"                     # u0 that holds q0 at rest; "positions": passive q0
    u = { shoulder = 0.0 }               # inputs for solve = "positions" [N*m or N]
    allow_non_equilibrium = false        # true: linearize even if q0 cannot be held

    [inputs]
    actuated = "all"                     # or a list of joint names

    [outputs]                            # absent: the whole state is the output
    frames = ["tip"]                     # frame positions in the world frame [m]
    joints = ["shoulder", "q:elbow", "v:elbow"]   # name: position and velocity

Ranges. Every number is an SI value and must be finite; magnitudes are bounded so that nothing
a scene asks for can overflow float64 (max 1.8e308) anywhere downstream:

- positions and angles (``operating_point.q``, spring ``rest``, free-flyer ``position`` and
  ``rpy``): ``|x| <= POSITION_LIMIT`` = 1e6 [m or rad]. The spacing of float64 numbers near x is
  |x| * 2.2e-16, 2.2e-10 at the limit: five decades below the smallest default finite-difference
  step (1e-5), so a linearization there still resolves its perturbations. Beyond 2.8e16 the
  spacing exceeds 2 pi and an angle has no digit left at all (sin(1e300) is noise).
- coefficients (``gravity`` [m/s^2], ``damping``, spring ``stiffness``, ``armature``,
  ``operating_point.u`` [N*m or N]): ``|x| <= COEFFICIENT_LIMIT`` = 1e12. The entries of a
  linear model are such a coefficient times at most a mass, a length squared or an inverse
  inertia of the robot (K ~ m g L, k; C ~ c; M ~ m L^2 + armature; A = M^-1 K), and the
  eigen-analysis squares them (|lam|^2 = K/M, K + K^T, norms). With coefficients <= 1e12 and a
  physical robot (masses and lengths within 1e-6..1e6 in SI) every entry stays below ~1e30 and
  its square below ~1e60: more than 200 decades from overflow, room left for ill-conditioned
  mass matrices. 1e12 also covers physics: the surface gravity of a neutron star is ~1e12 m/s^2,
  the stiffest structural joints ~1e10 N*m/rad.
- the steady rotation ``rate`` [rad/s]: ``|rate| <= RATE_LIMIT`` = 1e6, because it enters
  squared (centrifugal stiffness m rate^2 L^2): rate^2 <= 1e12 keeps it in the coefficients'
  range (fast ultracentrifuges spin at ~1e4 rad/s).

Integers too large for a float (TOML allows any number of digits), non-finite values, booleans
where numbers are expected, names with control characters (they would break one-line error
messages) and lists nested where a number is expected are refused with a :class:`SceneError`
naming the file and the field.
"""

from __future__ import annotations

import functools
import math
import numbers
import os
import re
import reprlib
import sys
import tomllib
import unicodedata
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .exceptions import ArgumentError, SceneError, UnknownRobotError

STANDARD_GRAVITY = (0.0, 0.0, -9.81)
#: Largest |position| or |angle| a scene may give [m or rad] (see the module docstring).
POSITION_LIMIT = 1e6
#: Largest |coefficient| a scene may give: gravity [m/s^2], damping, stiffness, armature and
#: inputs in SI units (see the module docstring).
COEFFICIENT_LIMIT = 1e12
#: Largest |rate| of a steady rotation [rad/s] (it enters squared).
RATE_LIMIT = 1e6

_TOP_KEYS = ("name", "urdf", "robot", "base", "effects", "operating_point", "inputs", "outputs",
             "loops")
_EFFECT_KEYS = ("gravity", "armature", "damping", "springs", "rotation", "mimic")
_OP_KEYS = ("q", "independent", "solve", "u", "allow_non_equilibrium")
_SOLVE_MODES = ("inputs", "positions")
_LOOP_KEYS = ("name", "type", "frame1", "frame2")
LOOP_TYPES = ("point", "weld")


@dataclass(frozen=True)
class Spring:
    """A linear joint spring: torque = -stiffness * (q - rest).

    Attributes:
        stiffness: [N*m/rad] for rotational joints, [N/m] for prismatic ones; >= 0.
        rest: Rest position [rad] or [m].
    """

    stiffness: float
    rest: float = 0.0


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


@dataclass(frozen=True)
class Loop:
    """A loop closure between two frames of the URDF tree.

    Attributes:
        name: Loop name (used in constraint-force and note names).
        type: ``"point"``: the frame origins coincide (3 rows); ``"weld"``: the frames coincide
            (origins and orientations, 6 rows).
        frame1, frame2: URDF frame (link) names.
    """

    name: str
    type: str
    frame1: str
    frame2: str


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
        if not isinstance(self.mimic, bool):
            raise SceneError(None, "effects.mimic",
                             f"expected true or false, got {_show(self.mimic)}")

    def in_play(self) -> list[str]:
        """Names of the effects present, in a fixed order."""
        return [k for k in _EFFECT_KEYS if getattr(self, k) not in (None, False, {})]


@dataclass(frozen=True)
class OperatingPointSpec:
    """Where to linearize.

    Attributes:
        q: Joint positions by joint name: a number ([rad] or [m]; for a continuous joint the
            angle), a list of the joint's raw configuration values, or for a free-flyer or
            spherical joint a table ``{position = [x, y, z], rpy = [r, p, y]}`` /
            ``{quaternion = [x, y, z, w]}``. Joints not named keep the reference posture.
        independent: With loops or mimic couplings: the joints held at their ``q`` values
            during assembly, used as independent coordinates z; empty: pinlin chooses.
        solve: ``"inputs"``: find the inputs u0 that hold q0 at rest; ``"positions"``: find the
            passive equilibrium q0 (``q`` is the starting guess) for the inputs ``u``.
        u: Input values by joint name for ``solve = "positions"`` [N*m or N]; others zero.
        allow_non_equilibrium: Linearize about (q0, v = 0, u0) even when u0 cannot hold q0.
    """

    q: Mapping[str, Any] = field(default_factory=dict)
    independent: tuple[str, ...] = ()
    solve: str = "inputs"
    u: JointValues = field(default_factory=dict)
    allow_non_equilibrium: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.allow_non_equilibrium, bool):
            raise SceneError(None, "operating_point.allow_non_equilibrium",
                             f"expected true or false, got {_show(self.allow_non_equilibrium)}")
        if self.solve not in _SOLVE_MODES:
            raise SceneError(None, "operating_point.solve",
                             f"expected one of {', '.join(repr(c) for c in _SOLVE_MODES)}, "
                             f"got {_show(self.solve)}")


@dataclass(frozen=True)
class Outputs:
    """Requested outputs.

    Attributes:
        frames: Frame names whose world position [m] is an output (3 rows each).
        joints: ``"name"`` (position and velocity), ``"q:name"`` or ``"v:name"``.
    """

    frames: tuple[str, ...] = ()
    joints: tuple[str, ...] = ()


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
        path = _path_argument("path", path)
        try:
            found = path.is_file()
        except OSError as exc:  # e.g. a name too long for the file system
            raise SceneError(_short(path), None, f"cannot use the path: {exc.strerror}") \
                from None
        if not found:
            raise SceneError(path, None, "scene file not found")
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise SceneError(path, None, f"malformed TOML: not UTF-8 text ({exc.reason})") \
                from None
        except OSError as exc:
            raise SceneError(path, None, f"cannot read the file: {exc.strerror}") from None
        return cls.from_dict(_parse_toml(path, text), source=path)

    @classmethod
    def from_robot(cls, name: str, **overrides: Any) -> Scene:
        """Scene for an example-robot-data robot: gravity, and armature where its loader sets it.

        Args:
            name: Robot name as in ``example_robot_data`` (``pinlin robots`` lists them).
            **overrides: Top-level scene fields in the TOML's dict form (``base``, ``effects``,
                ``operating_point``, ``inputs``, ``outputs``, ``name``); each replaces the whole
                default field.
        """
        from .robots import load_robot

        if not isinstance(name, str) or not name or not _clean(name):
            raise ArgumentError("name", "expected an example-robot-data robot name (a "
                                        f"non-empty string), got {_show(name)}")
        effects: dict[str, Any] = {"gravity": list(STANDARD_GRAVITY)}
        if np.any(load_robot(name).model.armature):
            effects["armature"] = True
        data: dict[str, Any] = {"name": name, "robot": name, "effects": effects}
        data.update(overrides)
        return cls.from_dict(data)

    @classmethod
    def from_urdf(cls, path: str | Path, **overrides: Any) -> Scene:
        """Scene for a URDF file: fixed base, standard gravity, all joints actuated.

        Raises:
            ArgumentError: ``path`` is not a path (str or os.PathLike).
        """
        path = _path_argument("path", path).resolve()
        data: dict[str, Any] = {
            "name": path.stem,
            "urdf": str(path),
            "effects": {"gravity": list(STANDARD_GRAVITY)},
        }
        data.update(overrides)
        return cls.from_dict(data)

    @classmethod
    def resolve(cls, target: str | Path) -> Scene:
        """Scene for a scene file, a URDF file, a bundled scene name or a robot name.

        Raises:
            ArgumentError: ``target`` is not a str or os.PathLike.
        """
        path = _path_argument("target", target)
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
                                        f"{_show(data)}")
        return _parse_scene(data, _path_argument("source", source) if source is not None
                            else None)

    # ----------------------------------------------------------------------------------------
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


# ------------------------------------------------------------------------------------------------
# Arguments and the TOML text.


def _path_argument(argument: str, value: Any) -> Path:
    """``value`` as a Path, or an :class:`ArgumentError` naming ``argument``."""
    if not isinstance(value, str | os.PathLike):
        raise ArgumentError(argument, f"expected a file path (str or os.PathLike), got "
                                      f"{_show(value)}")
    try:
        path = Path(value)
    except TypeError:  # an os.PathLike whose __fspath__ returns bytes or junk
        raise ArgumentError(argument, f"expected a file path (str or os.PathLike), got "
                                      f"{_show(value)}") from None
    if not _clean(str(path)):
        raise ArgumentError(argument, f"expected a file path without control characters, got "
                                      f"{_show(str(path))}")
    return path


def _short(path: Path) -> str:
    """``path`` for a message, shortened when it is very long."""
    text = str(path)
    return text if len(text) <= 200 else f"{text[:100]}...{text[-60:]}"


def _parse_toml(path: Path, text: str) -> dict[str, Any]:
    """``tomllib.loads(text)`` with every failure turned into a :class:`SceneError`.

    tomllib recurses once per nesting level (RecursionError past Python's limit) and converts
    integers with ``int()``, which refuses more than ``sys.get_int_max_str_digits()`` digits
    (ValueError). For the latter the field is located by parsing again with every such run of
    digits replaced by 10^400 (no float either), so that the field checks name it.
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(path, None, f"malformed TOML: {exc}") from None
    except RecursionError:
        raise SceneError(path, None, "malformed TOML: arrays or tables nested too deeply "
                                     "(beyond Python's recursion limit)") from None
    except ValueError as exc:
        detail = str(exc).split(";")[0]
    limit = sys.get_int_max_str_digits()
    if limit:
        stand_in = 10 ** 400
        shortened = re.sub(f"[0-9][0-9_]{{{limit - 1},}}", str(stand_in), text)
        try:
            data = tomllib.loads(shortened)
        except (tomllib.TOMLDecodeError, RecursionError, ValueError):
            data = None
        if data is not None:
            try:
                _parse_scene(data, path)
            except SceneError as exc:  # names the field of the huge integer
                reason = exc.reason.replace(_show(stand_in),
                                            f"an integer of more than {limit} digits")
                raise SceneError(path, exc.field, reason) from None
    raise SceneError(path, None, f"malformed TOML: {detail}")


# ------------------------------------------------------------------------------------------------
# Parsing helpers. Each takes the source (for messages) and the dotted field name.

_REPR = reprlib.Repr()
_REPR.maxlevel = 3
_REPR.maxstring = _REPR.maxother = 60
_REPR.maxlong = 40
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_BREAKING = ("Cc", "Cs", "Zl", "Zp")  # control, lone surrogate, line and paragraph separators


def _clean(text: str) -> bool:
    """Whether ``text`` can appear in a one-line message: no control characters, line or
    paragraph separators, or lone surrogates (which no terminal encoding can print)."""
    return not any(unicodedata.category(c) in _BREAKING for c in text)


def _show(x: Any) -> str:
    """A short one-line representation of a user's value for an error message: bounded in
    length and depth (a list nested a million deep, a megabyte string), no conversion of
    integers too long for ``str()``, control characters escaped."""
    if isinstance(x, int) and not isinstance(x, bool) and x.bit_length() > 128:
        return f"an integer of about {int(x.bit_length() * math.log10(2)) + 1} digits"
    try:
        text = _REPR.repr(x)
    except Exception:  # a failing __repr__, a huge integer inside a container, ...
        text = f"a {type(x).__name__}"
    if not _clean(text):
        text = text.encode("unicode_escape", "backslashreplace").decode("ascii")
    return text


def _is_number(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool | np.bool_)


def _is_sequence(x: Any) -> bool:
    return isinstance(x, list | tuple) or (isinstance(x, np.ndarray) and x.ndim == 1)


def _number(src, fld: str, x: Any, *, limit: float, minimum: float | None = None,
            unit: str = "") -> float:
    """A finite float with ``minimum <= x`` and ``|x| <= limit`` (``unit`` for messages)."""
    if not _is_number(x):
        raise SceneError(src, fld, f"expected a number{unit}, got {_show(x)}")
    try:
        value = float(x)
    except (OverflowError, ValueError, TypeError):
        raise SceneError(src, fld, f"expected a number{unit} with |value| <= {limit:g}, got "
                                   f"{_show(x)}, too large for a float") from None
    if not math.isfinite(value):
        raise SceneError(src, fld, f"expected a finite number{unit}, got {_show(x)}")
    if minimum is not None and value < minimum:
        raise SceneError(src, fld, f"expected a number >= {minimum:g}{unit}, got {value:.6g}")
    if abs(value) > limit:
        raise SceneError(src, fld, f"expected a number{unit} with |value| <= {limit:g}, got "
                                   f"{value:.6g} (beyond pinlin's range for this quantity; see "
                                   "pinlin.scene)")
    return value


def _numbers(src, fld: str, x: Any, *, limit: float, length: int | None = None,
             unit: str = "", minimum: float | None = None) -> tuple[float, ...]:
    if not _is_sequence(x):
        raise SceneError(src, fld, f"expected a list of numbers{unit}, got {_show(x)}")
    if length is not None and len(x) != length:
        raise SceneError(src, fld, f"expected {length} numbers{unit}, got {len(x)}")
    return tuple(_number(src, f"{fld}[{i}]", v, limit=limit, minimum=minimum, unit=unit)
                 for i, v in enumerate(x))


def _table(src, fld: str | None, x: Any) -> Mapping[str, Any]:
    if not isinstance(x, Mapping):
        raise SceneError(src, fld, f"expected a table, got {_show(x)}")
    return x


def _field(fld: str | None, key: Any) -> str:
    """``fld.key``, the key shown safely when it is not a clean non-empty string."""
    shown = key if isinstance(key, str) and key and _clean(key) else _show(key)
    return f"{fld}.{shown}" if fld else shown


def _check_keys(src, fld: str | None, table: Mapping[str, Any], known: tuple[str, ...],
                planned: tuple[str, ...] = ()) -> None:
    for key in table:
        name = _field(fld, key)
        if key in planned:
            raise SceneError(src, name, "is not supported by this version of pinlin")
        if key not in known:
            raise SceneError(src, name, f"unknown key; expected one of {', '.join(known)}")


def _string(src, fld: str, x: Any, choices: tuple[str, ...] | None = None) -> str:
    if not isinstance(x, str) or not x:
        raise SceneError(src, fld, f"expected a non-empty string, got {_show(x)}")
    if not _clean(x):
        raise SceneError(src, fld, f"expected a string without control characters or line "
                                   f"breaks, got {_show(x)}")
    if choices is not None and x not in choices:
        raise SceneError(src, fld, f"expected one of {', '.join(repr(c) for c in choices)}, "
                                   f"got {_show(x)}")
    return x


def _names(src, fld: str, x: Any) -> tuple[str, ...]:
    """A list of distinct non-empty names."""
    if not isinstance(x, list | tuple):
        raise SceneError(src, fld, f"expected a list of names, got {_show(x)}")
    names = tuple(_string(src, f"{fld}[{i}]", n) for i, n in enumerate(x))
    seen: set[str] = set()
    for n in names:
        if n in seen:
            raise SceneError(src, fld, f"name '{n}' is listed twice")
        seen.add(n)
    return names


def _joint_table(src, fld: str, x: Any) -> Mapping[str, Any]:
    """A table keyed by joint names (non-empty strings without control characters)."""
    table = _table(src, fld, x)
    for key in table:
        if not isinstance(key, str) or not key or not _clean(key):
            raise SceneError(src, fld, "expected joint names (non-empty strings without control "
                                       f"characters) as keys, got {_show(key)}")
    return table


def _per_joint(src, fld: str, x: Any, unit: str) -> JointValues | bool:
    if x is True:
        return True
    table = _joint_table(src, fld, x)
    out: dict[str, float | tuple[float, ...]] = {}
    for joint, value in table.items():
        f = f"{fld}.{joint}"
        out[joint] = (_numbers(src, f, value, unit=unit, minimum=0.0, limit=COEFFICIENT_LIMIT)
                      if _is_sequence(value)
                      else _number(src, f, value, minimum=0.0, unit=unit,
                                   limit=COEFFICIENT_LIMIT))
    return out


def _parse_effects(src, x: Any) -> Effects:
    table = _table(src, "effects", x)
    _check_keys(src, "effects", table, _EFFECT_KEYS)
    gravity = None
    if "gravity" in table:
        g = table["gravity"]
        if g is True:
            gravity = STANDARD_GRAVITY
        elif g is not False:
            gravity = _numbers(src, "effects.gravity", g, length=3, unit=" [m/s^2]",
                               limit=COEFFICIENT_LIMIT)
    armature = damping = None
    if "armature" in table and table["armature"] is not False:
        armature = _per_joint(src, "effects.armature", table["armature"], " [kg*m^2 or kg]")
    if "damping" in table and table["damping"] is not False:
        damping = _per_joint(src, "effects.damping", table["damping"], " [N*m*s/rad or N*s/m]")
    springs = None
    if "springs" in table:
        springs = {}
        for joint, spec in _joint_table(src, "effects.springs", table["springs"]).items():
            f = f"effects.springs.{joint}"
            spec = _table(src, f, spec)
            _check_keys(src, f, spec, ("stiffness", "rest"))
            if "stiffness" not in spec:
                raise SceneError(src, f"{f}.stiffness", "missing; expected a number >= 0")
            springs[joint] = Spring(
                _number(src, f"{f}.stiffness", spec["stiffness"], minimum=0.0,
                        unit=" [N*m/rad or N/m]", limit=COEFFICIENT_LIMIT),
                _number(src, f"{f}.rest", spec.get("rest", 0.0), unit=" [rad or m]",
                        limit=POSITION_LIMIT),
            )
    rotation = None
    if "rotation" in table and table["rotation"] is not False:
        f = "effects.rotation"
        spec = _table(src, f, table["rotation"])
        _check_keys(src, f, spec, ("axis", "rate"))
        for key in ("axis", "rate"):
            if key not in spec:
                raise SceneError(src, f"{f}.{key}", "missing")
        # A direction: any finite non-zero vector, scaled by its largest entry before the norm
        # so that neither 1e300 nor 1e-300 entries overflow or underflow.
        axis = np.array(_numbers(src, f"{f}.axis", spec["axis"], length=3, limit=math.inf))
        largest = float(np.abs(axis).max())
        if largest == 0.0:
            raise SceneError(src, f"{f}.axis", "expected a non-zero vector")
        axis = axis / largest
        axis = axis / np.linalg.norm(axis)
        rotation = Rotation(tuple(float(a) for a in axis),
                            _number(src, f"{f}.rate", spec["rate"], unit=" [rad/s]",
                                    limit=RATE_LIMIT))
    mimic = table.get("mimic", False)
    if not isinstance(mimic, bool):
        raise SceneError(src, "effects.mimic", f"expected true or false, got {_show(mimic)}")
    return Effects(gravity, armature, damping, springs, rotation, mimic)


def _parse_loops(src, x: Any) -> tuple[Loop, ...]:
    if not isinstance(x, list | tuple):
        raise SceneError(src, "loops", "expected an array of tables ([[loops]])")
    loops: list[Loop] = []
    for i, entry in enumerate(x):
        fld = f"loops[{i}]"
        spec = _table(src, fld, entry)
        _check_keys(src, fld, spec, _LOOP_KEYS)
        for key in ("frame1", "frame2"):
            if key not in spec:
                raise SceneError(src, f"{fld}.{key}", "missing; expected a frame (link) name")
        name = _string(src, f"{fld}.name", spec.get("name", f"loop{i}"))
        if any(lp.name == name for lp in loops):
            raise SceneError(src, f"{fld}.name", f"loop name '{name}' is used twice")
        f1 = _string(src, f"{fld}.frame1", spec["frame1"])
        f2 = _string(src, f"{fld}.frame2", spec["frame2"])
        if f1 == f2:
            raise SceneError(src, f"{fld}.frame2", "must differ from frame1")
        loops.append(Loop(name, _string(src, f"{fld}.type", spec.get("type", "point"),
                                        LOOP_TYPES), f1, f2))
    return tuple(loops)


def _parse_joint_position(src, fld: str, x: Any) -> Any:
    """One entry of ``operating_point.q``: a number (the position [rad or m] of a 1-DoF joint;
    the angle of a continuous joint), a list (the joint's raw configuration values; unit-norm
    parts are checked against the joint when the system is built), or a table for a free-flyer
    or spherical joint (``position`` [m], and ``rpy`` [rad] or a unit ``quaternion``)."""
    if _is_number(x):
        return _number(src, fld, x, unit=" [rad or m]", limit=POSITION_LIMIT)
    if _is_sequence(x):
        return _numbers(src, fld, x, limit=POSITION_LIMIT)
    if isinstance(x, Mapping):
        _check_keys(src, fld, x, ("position", "rpy", "quaternion"))
        if not x:
            raise SceneError(src, fld, "empty table; expected position, rpy or quaternion")
        if "rpy" in x and "quaternion" in x:
            raise SceneError(src, fld, "give either 'rpy' or 'quaternion', not both")
        out: dict[str, tuple[float, ...]] = {}
        if "position" in x:
            out["position"] = _numbers(src, f"{fld}.position", x["position"], length=3,
                                       unit=" [m]", limit=POSITION_LIMIT)
        if "rpy" in x:
            out["rpy"] = _numbers(src, f"{fld}.rpy", x["rpy"], length=3, unit=" [rad]",
                                  limit=POSITION_LIMIT)
        if "quaternion" in x:
            quat = _numbers(src, f"{fld}.quaternion", x["quaternion"], length=4,
                            limit=math.inf)
            norm = math.hypot(*quat)  # no overflow or underflow for any finite entries
            if abs(norm - 1.0) > 1e-6:
                raise SceneError(src, f"{fld}.quaternion",
                                 f"expected a unit quaternion [x, y, z, w], got norm {norm:.6g}")
            out["quaternion"] = quat
        return out
    raise SceneError(src, fld, "expected a number, a list of numbers or a table, got "
                               f"{_show(x)}")


def _parse_operating_point(src, x: Any) -> OperatingPointSpec:
    table = _table(src, "operating_point", x)
    _check_keys(src, "operating_point", table, _OP_KEYS)
    q = {j: _parse_joint_position(src, f"operating_point.q.{j}", v)
         for j, v in _joint_table(src, "operating_point.q", table.get("q", {})).items()}
    independent = _names(src, "operating_point.independent", table.get("independent", []))
    solve = _string(src, "operating_point.solve", table.get("solve", "inputs"), _SOLVE_MODES)
    u: dict[str, float | tuple[float, ...]] = {}
    for joint, value in _joint_table(src, "operating_point.u", table.get("u", {})).items():
        f = f"operating_point.u.{joint}"
        u[joint] = (_numbers(src, f, value, unit=" [N*m or N]", limit=COEFFICIENT_LIMIT)
                    if _is_sequence(value)
                    else _number(src, f, value, unit=" [N*m or N]", limit=COEFFICIENT_LIMIT))
    if u and solve != "positions":
        raise SceneError(src, "operating_point.u", "inputs are given only with "
                                                   "solve = \"positions\" (with \"inputs\" "
                                                   "pinlin finds them)")
    allow = table.get("allow_non_equilibrium", False)
    if not isinstance(allow, bool):
        raise SceneError(src, "operating_point.allow_non_equilibrium",
                         f"expected true or false, got {_show(allow)}")
    return OperatingPointSpec(q, independent, solve, u, allow)


def _parse_scene(data: Mapping[str, Any], src: Path | None) -> Scene:
    data = _table(src, None, data)
    _check_keys(src, None, data, _TOP_KEYS)
    has_urdf, has_robot = "urdf" in data, "robot" in data
    if has_urdf == has_robot:
        raise SceneError(src, "urdf", "give exactly one of 'urdf' (a file) or 'robot' "
                                      "(an example-robot-data name)")
    urdf = robot = None
    if has_urdf:
        urdf = Path(_string(src, "urdf", data["urdf"]))
        if not urdf.is_absolute():
            urdf = (src.parent if src is not None else Path.cwd()) / urdf
        try:
            urdf = urdf.resolve()
            urdf.is_file()  # raises for paths the file system cannot take (name too long)
        except (OSError, RuntimeError, ValueError) as exc:
            reason = getattr(exc, "strerror", None) or _show(str(exc))
            raise SceneError(src, "urdf", f"cannot use the path {_show(str(urdf))}: {reason}") \
                from None
    else:
        robot = _string(src, "robot", data["robot"])
    default_name = src.stem if src is not None else (robot or (urdf.stem if urdf else "scene"))
    name = _string(src, "name", data.get("name", default_name))
    base = None
    if "base" in data:
        base = _string(src, "base", data["base"], ("fixed", "free"))
    effects = _parse_effects(src, data.get("effects", {}))
    op = _parse_operating_point(src, data.get("operating_point", {}))
    inputs: str | tuple[str, ...] = "all"
    if "inputs" in data:
        tin = _table(src, "inputs", data["inputs"])
        _check_keys(src, "inputs", tin, ("actuated",))
        act = tin.get("actuated", "all")
        if isinstance(act, str):
            inputs = _string(src, "inputs.actuated", act, ("all",))
        else:
            inputs = _names(src, "inputs.actuated", act)
    outputs = None
    if "outputs" in data:
        tout = _table(src, "outputs", data["outputs"])
        _check_keys(src, "outputs", tout, ("frames", "joints"))
        outputs = Outputs(_names(src, "outputs.frames", tout.get("frames", [])),
                          _names(src, "outputs.joints", tout.get("joints", [])))
        if not outputs.frames and not outputs.joints:
            raise SceneError(src, "outputs", "is empty; name frames or joints, or leave the "
                                             "table out to output the whole state")
    loops = _parse_loops(src, data["loops"]) if "loops" in data else ()
    return Scene(name=name, urdf=urdf, robot=robot, base=base, effects=effects,
                 operating_point=op, inputs=inputs, outputs=outputs, loops=loops, source=src)
