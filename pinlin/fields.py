"""Checked values from scene files and dicts: each reader returns the value or raises a
:class:`~pinlin.exceptions.SceneError` naming the source and the dotted field.

The readers take the source (a scene file, or None for a scene built in Python) and the field
name for their messages, and check type, finiteness and range: numbers (:func:`number`,
:func:`number_list`, :func:`direction`), booleans (:func:`flag`), tables (:func:`table`,
:func:`check_keys`), strings and names (:func:`string`, :func:`name_list`), values per joint
(:func:`joint_table`, :func:`joint_values`, :func:`joint_position`). :func:`read_toml` reads a
scene file's TOML text.

Integers too large for a float (TOML allows any number of digits), non-finite values, booleans
where numbers are expected, names with control characters (they would break one-line error
messages) and lists nested where a number is expected are refused; :func:`show` renders any
user value, however large or deep, for a one-line message.

Ranges. Every number is an SI value and must be finite; magnitudes are bounded so that nothing
a scene asks for can overflow float64 (max 1.8e308) anywhere downstream:

- positions and angles: ``|x| <= POSITION_LIMIT`` = 1e6 [m or rad]. The spacing of float64
  numbers near x is |x| * 2.2e-16, 2.2e-10 at the limit: five decades below the smallest default
  finite-difference step (1e-5), so a linearization there still resolves its perturbations.
  Beyond 2.8e16 the spacing exceeds 2 pi and an angle has no digit left at all (sin(1e300) is
  noise).
- coefficients (gravity [m/s^2], damping, stiffness, armature, inputs [N*m or N]):
  ``|x| <= COEFFICIENT_LIMIT`` = 1e12. The entries of a linear model are such a coefficient
  times at most a mass, a length squared or an inverse inertia of the robot (K ~ m g L, k;
  C ~ c; M ~ m L^2 + armature; A = M^-1 K), and the eigen-analysis squares them (|lam|^2 = K/M,
  K + K^T, norms). With coefficients <= 1e12 and a physical robot (masses and lengths within
  1e-6..1e6 in SI) every entry stays below ~1e30 and its square below ~1e60: more than 200
  decades from overflow, room left for ill-conditioned mass matrices. 1e12 also covers physics:
  the surface gravity of a neutron star is ~1e12 m/s^2, the stiffest structural joints
  ~1e10 N*m/rad.
- a steady rotation rate [rad/s]: ``|rate| <= RATE_LIMIT`` = 1e6, because it enters squared
  (centrifugal stiffness m rate^2 L^2): rate^2 <= 1e12 keeps it in the coefficients' range
  (fast ultracentrifuges spin at ~1e4 rad/s).

Which scene field has which range is listed in :mod:`pinlin.scene`.
"""

from __future__ import annotations

import math
import os
import re
import reprlib
import sys
import tomllib
import unicodedata
from collections.abc import Callable, Mapping
from numbers import Real
from pathlib import Path
from typing import Any

import numpy as np

from .exceptions import ArgumentError, SceneError

#: Largest |position| or |angle| a scene may give [m or rad] (see the module docstring).
POSITION_LIMIT = 1e6
#: Largest |coefficient| a scene may give: gravity [m/s^2], damping, stiffness, armature and
#: inputs in SI units (see the module docstring).
COEFFICIENT_LIMIT = 1e12
#: Largest |rate| of a steady rotation [rad/s] (it enters squared).
RATE_LIMIT = 1e6

#: Where a value comes from, for messages: a scene file, or None for a scene built in Python.
Source = str | Path | None


# ------------------------------------------------------------------------------------------------
# Showing user values in one-line messages.

_REPR = reprlib.Repr()
_REPR.maxlevel = 3
_REPR.maxstring = _REPR.maxother = 60
_REPR.maxlong = 40
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_BREAKING = ("Cc", "Cs", "Zl", "Zp")  # control, lone surrogate, line and paragraph separators


def written_float(text: str) -> float:
    """The number a person or a CSV writer means by ``text``: what ``float`` reads, but for
    the underscores and non-ASCII digits it also takes ("1_0" is 10 and "\u0663" is 3 to
    ``float``), which raise ValueError here as ``float``'s own refusals do."""
    if "_" in text or not text.isascii():
        raise ValueError(f"could not convert string to float: {text!r}")
    return float(text)


def clean(text: str) -> bool:
    """Whether ``text`` can appear in a one-line message: no control characters, line or
    paragraph separators, or lone surrogates (which no terminal encoding can print)."""
    return not any(unicodedata.category(c) in _BREAKING for c in text)


def show(x: Any) -> str:
    """A short one-line representation of a user's value for an error message: bounded in
    length and depth (a list nested a million deep, a megabyte string), no conversion of
    integers too long for ``str()``, control characters escaped."""
    if isinstance(x, int) and not isinstance(x, bool) and x.bit_length() > 128:
        return f"an integer of about {int(x.bit_length() * math.log10(2)) + 1} digits"
    if isinstance(x, np.ndarray) and (x.ndim > 1 or x.size > 6):   # repr: lines, or long
        return f"an array of shape {x.shape} ({x.dtype})"
    try:
        text = _REPR.repr(x)
    except Exception:  # a failing __repr__, a huge integer inside a container, ...
        text = f"a {type(x).__name__}"
    if not clean(text):
        text = text.encode("unicode_escape", "backslashreplace").decode("ascii")
    return text


# ------------------------------------------------------------------------------------------------
# Field readers. Each takes the source (for messages) and the dotted field name.


def is_number(x: Any) -> bool:
    """Whether ``x`` is a real number (Python or numpy), booleans excluded."""
    return isinstance(x, Real) and not isinstance(x, bool | np.bool_)


def is_sequence(x: Any) -> bool:
    """Whether ``x`` is a list, a tuple or a 1-D numpy array."""
    return isinstance(x, list | tuple) or (isinstance(x, np.ndarray) and x.ndim == 1)


def number(src: Source, fld: str, x: Any, *, limit: float, minimum: float | None = None,
           unit: str = "") -> float:
    """A finite float with ``minimum <= x`` and ``|x| <= limit`` (``unit`` for messages)."""
    if not is_number(x):
        raise SceneError(src, fld, f"expected a number{unit}, got {show(x)}")
    try:
        value = float(x)
    except (OverflowError, ValueError, TypeError):
        raise SceneError(src, fld, f"expected a number{unit} with |value| <= {limit:g}, got "
                                   f"{show(x)}, too large for a float") from None
    if not math.isfinite(value):
        raise SceneError(src, fld, f"expected a finite number{unit}, got {show(x)}")
    if minimum is not None and value < minimum:
        raise SceneError(src, fld, f"expected a number >= {minimum:g}{unit}, got {value:.6g}")
    if abs(value) > limit:
        raise SceneError(src, fld, f"expected a number{unit} with |value| <= {limit:g}, got "
                                   f"{value:.6g} (beyond pinlin's range for this quantity; see "
                                   "pinlin.scene)")
    return value


def number_list(src: Source, fld: str, x: Any, *, limit: float, length: int | None = None,
                unit: str = "", minimum: float | None = None) -> tuple[float, ...]:
    """A list of :func:`number` values (entries named ``fld[i]``), of ``length`` if given."""
    if not is_sequence(x):
        raise SceneError(src, fld, f"expected a list of numbers{unit}, got {show(x)}")
    if length is not None and len(x) != length:
        raise SceneError(src, fld, f"expected {length} numbers{unit}, got {len(x)}")
    return tuple(number(src, f"{fld}[{i}]", v, limit=limit, minimum=minimum, unit=unit)
                 for i, v in enumerate(x))


def table(src: Source, fld: str | None, x: Any) -> Mapping[str, Any]:
    """``x`` if it is a table (a mapping)."""
    if not isinstance(x, Mapping):
        raise SceneError(src, fld, f"expected a table, got {show(x)}")
    return x


def dotted(fld: str | None, key: Any) -> str:
    """``fld.key``, the key shown safely when it is not a clean non-empty string."""
    shown = key if isinstance(key, str) and key and clean(key) else show(key)
    return f"{fld}.{shown}" if fld else shown


def check_keys(src: Source, fld: str | None, tbl: Mapping[str, Any], known: tuple[str, ...],
               planned: tuple[str, ...] = ()) -> None:
    """Every key of ``tbl`` is one of ``known`` (``planned`` keys: not supported yet)."""
    for key in tbl:
        name = dotted(fld, key)
        if key in planned:
            raise SceneError(src, name, "is not supported by this version of pinlin")
        if key not in known:
            raise SceneError(src, name, f"unknown key; expected one of {', '.join(known)}")


def string(src: Source, fld: str, x: Any, choices: tuple[str, ...] | None = None) -> str:
    """A non-empty string without control characters, one of ``choices`` if given."""
    if not isinstance(x, str) or not x:
        raise SceneError(src, fld, f"expected a non-empty string, got {show(x)}")
    if not clean(x):
        raise SceneError(src, fld, f"expected a string without control characters or line "
                                   f"breaks, got {show(x)}")
    if choices is not None and x not in choices:
        raise SceneError(src, fld, f"expected one of {', '.join(repr(c) for c in choices)}, "
                                   f"got {show(x)}")
    return x


def name_list(src: Source, fld: str, x: Any) -> tuple[str, ...]:
    """A list of distinct non-empty names."""
    if not isinstance(x, list | tuple):
        raise SceneError(src, fld, f"expected a list of names, got {show(x)}")
    names = tuple(string(src, f"{fld}[{i}]", n) for i, n in enumerate(x))
    seen: set[str] = set()
    for n in names:
        if n in seen:
            raise SceneError(src, fld, f"name '{n}' is listed twice")
        seen.add(n)
    return names


def joint_table(src: Source, fld: str, x: Any) -> Mapping[str, Any]:
    """A table keyed by joint names (non-empty strings without control characters)."""
    tbl = table(src, fld, x)
    for key in tbl:
        if not isinstance(key, str) or not key or not clean(key):
            raise SceneError(src, fld, "expected joint names (non-empty strings without control "
                                       f"characters) as keys, got {show(key)}")
    return tbl


def direction(src: Source, fld: str, x: Any) -> tuple[float, float, float]:
    """The unit vector along ``x``, any finite non-zero list of 3 numbers [-]."""
    # Scaled by its largest entry before the norm so that neither 1e300 nor 1e-300 entries
    # overflow or underflow.
    axis = np.array(number_list(src, fld, x, length=3, limit=math.inf))
    largest = float(np.abs(axis).max())
    if largest == 0.0:
        raise SceneError(src, fld, "expected a non-zero vector")
    axis = axis / largest
    axis = axis / np.linalg.norm(axis)
    return (float(axis[0]), float(axis[1]), float(axis[2]))


def flag(src: Source, fld: str, x: Any) -> bool:
    """``x`` if it is True or False (no other value reads as a boolean)."""
    if not isinstance(x, bool):
        raise SceneError(src, fld, f"expected true or false, got {show(x)}")
    return x


def joint_values(src: Source, fld: str, x: Any, *, limit: float, unit: str = "",
                 minimum: float | None = None) -> dict[str, float | tuple[float, ...]]:
    """A table ``{joint: value}``, each value a :func:`number` or a :func:`number_list` (one
    number per velocity coordinate of the joint; the count is checked against the joint when
    the system is built)."""
    out: dict[str, float | tuple[float, ...]] = {}
    for joint, value in joint_table(src, fld, x).items():
        f = f"{fld}.{joint}"
        out[joint] = (number_list(src, f, value, limit=limit, unit=unit, minimum=minimum)
                      if is_sequence(value)
                      else number(src, f, value, limit=limit, unit=unit, minimum=minimum))
    return out


def joint_position(src: Source, fld: str, x: Any) -> Any:
    """A joint's position: a number (the position [rad or m] of a 1-DoF joint; the angle of a
    continuous joint), a list (the joint's raw configuration values; unit-norm parts are
    checked against the joint when the system is built), or a table for a free-flyer or
    spherical joint (``position`` [m], and ``rpy`` [rad] or a unit ``quaternion``)."""
    if is_number(x):
        return number(src, fld, x, unit=" [rad or m]", limit=POSITION_LIMIT)
    if is_sequence(x):
        return number_list(src, fld, x, limit=POSITION_LIMIT)
    if isinstance(x, Mapping):
        check_keys(src, fld, x, ("position", "rpy", "quaternion"))
        if not x:
            raise SceneError(src, fld, "empty table; expected position, rpy or quaternion")
        if "rpy" in x and "quaternion" in x:
            raise SceneError(src, fld, "give either 'rpy' or 'quaternion', not both")
        out: dict[str, tuple[float, ...]] = {}
        if "position" in x:
            out["position"] = number_list(src, f"{fld}.position", x["position"], length=3,
                                          unit=" [m]", limit=POSITION_LIMIT)
        if "rpy" in x:
            out["rpy"] = number_list(src, f"{fld}.rpy", x["rpy"], length=3, unit=" [rad]",
                                     limit=POSITION_LIMIT)
        if "quaternion" in x:
            quat = number_list(src, f"{fld}.quaternion", x["quaternion"], length=4,
                               limit=math.inf)
            norm = math.hypot(*quat)  # no overflow or underflow for any finite entries
            if abs(norm - 1.0) > 1e-6:
                raise SceneError(src, f"{fld}.quaternion",
                                 f"expected a unit quaternion [x, y, z, w], got norm {norm:.6g}")
            out["quaternion"] = quat
        return out
    raise SceneError(src, fld, "expected a number, a list of numbers or a table, got "
                               f"{show(x)}")


# ------------------------------------------------------------------------------------------------
# Paths and the TOML text.


def path_argument(argument: str, value: Any) -> Path:
    """``value`` as a Path, or an :class:`ArgumentError` naming ``argument``."""
    if not isinstance(value, str | os.PathLike):
        raise ArgumentError(argument, f"expected a file path (str or os.PathLike), got "
                                      f"{show(value)}")
    try:
        path = Path(value)
    except TypeError:  # an os.PathLike whose __fspath__ returns bytes or junk
        raise ArgumentError(argument, f"expected a file path (str or os.PathLike), got "
                                      f"{show(value)}") from None
    if not str(value if isinstance(value, str) else os.fspath(value)):
        raise ArgumentError(argument, "expected a file path, got an empty one")
    if not clean(str(path)):
        raise ArgumentError(argument, f"expected a file path without control characters, got "
                                      f"{show(str(path))}")
    return path


def short_path(path: Path) -> str:
    """``path`` for a message, shortened when it is very long."""
    text = str(path)
    return text if len(text) <= 200 else f"{text[:100]}...{text[-60:]}"


def read_toml(path: Path, locate: Callable[[dict[str, Any]], object]) -> dict[str, Any]:
    """The TOML document in scene file ``path``, every failure a :class:`SceneError`.

    Args:
        path: The scene file.
        locate: Checks a parsed document, raising a :class:`SceneError` that names the bad
            field; used to name the field of an integer too long to convert (see
            :func:`parse_toml`).

    Raises:
        SceneError: missing or unreadable file, not UTF-8, malformed TOML.
    """
    try:
        found = path.is_file()
    except OSError as exc:  # e.g. a name too long for the file system
        raise SceneError(short_path(path), None, f"cannot use the path: {exc.strerror}") \
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
    return parse_toml(path, text, locate)


def parse_toml(path: Path, text: str,
               locate: Callable[[dict[str, Any]], object]) -> dict[str, Any]:
    """``tomllib.loads(text)`` with every failure turned into a :class:`SceneError`.

    tomllib recurses once per nesting level (RecursionError past Python's limit) and converts
    integers with ``int()``, which refuses more than ``sys.get_int_max_str_digits()`` digits
    (ValueError). For the latter the field is located by parsing again with every such run of
    digits replaced by 10^400 (no float either) and passing the result to ``locate``, so that
    the field checks name it.
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
                locate(data)
            except SceneError as exc:  # names the field of the huge integer
                reason = exc.reason.replace(show(stand_in),
                                            f"an integer of more than {limit} digits")
                raise SceneError(path, exc.field, reason) from None
    raise SceneError(path, None, f"malformed TOML: {detail}")
