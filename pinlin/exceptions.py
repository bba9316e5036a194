"""Exceptions raised by pinlin for bad input.

Every error a user can cause derives from :class:`PinlinError`. Subclasses carry the offending
file, field or name as attributes and compose a one-line message that says what was expected,
so that the CLI can print it verbatim and exit with status 2.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from pathlib import Path


class PinlinError(Exception):
    """Root of every error pinlin raises for bad input or an impossible request."""


def _where(source: str | Path | None, field: str | None) -> str:
    parts = []
    if source is not None:
        parts.append(str(source))
    if field:
        parts.append(f"field '{field}'")
    return ": ".join(parts) + ": " if parts else ""


class SceneError(PinlinError):
    """A scene file (or the equivalent Python dict) is malformed or inconsistent.

    Attributes:
        source: Scene file path, or None for scenes built in Python.
        field: Dotted name of the offending field, e.g. ``effects.damping.elbow``.
        reason: What was expected and what was found.
    """

    def __init__(self, source: str | Path | None, field: str | None, reason: str) -> None:
        self.source = source
        self.field = field
        self.reason = reason
        super().__init__(f"{_where(source, field)}{reason}")


class UnknownNameError(SceneError):
    """A joint or frame name does not exist in the robot model.

    Attributes:
        name: The name that was not found.
        kind: ``"joint"`` or ``"frame"``.
        known: The valid names.
    """

    def __init__(
        self,
        source: str | Path | None,
        field: str | None,
        name: str,
        kind: str,
        known: Sequence[str],
    ) -> None:
        self.name = name
        self.kind = kind
        self.known = list(dict.fromkeys(known))   # a name in two sources, once
        close = difflib.get_close_matches(name, self.known, n=3)
        hint = (f"did you mean {', '.join(repr(c) for c in close)}?" if close
                else _listing(self.known))
        super().__init__(source, field, f"'{name}' is not a {kind} of the robot; {hint}")


def _listing(names: Iterable[str], limit: int = 12) -> str:
    names = list(names)
    shown = ", ".join(names[:limit])
    more = f", ... ({len(names)} in all)" if len(names) > limit else ""
    return f"known: {shown}{more}" if names else "the robot has none"


class UrdfError(PinlinError):
    """A URDF file is missing, malformed, or describes a physically impossible body.

    Attributes:
        path: The URDF file.
        reason: What is wrong with it.
    """

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}")


class UnknownRobotError(PinlinError):
    """A name is neither a scene file, a URDF, a bundled scene nor an example-robot-data robot."""

    def __init__(self, name: str, known: Sequence[str]) -> None:
        self.name = name
        self.known = list(dict.fromkeys(known))   # a name in two sources, once
        close = difflib.get_close_matches(name, self.known, n=3)
        hint = (f"did you mean {', '.join(repr(c) for c in close)}?" if close
                else _listing(self.known))
        super().__init__(
            f"'{name}' is not a scene file, a URDF, a bundled scene or a robot that loads; {hint}"
        )


class RobotLoadError(PinlinError):
    """An example-robot-data robot exists but its loader fails on this installation."""

    def __init__(self, name: str, reason: str) -> None:
        self.name = name
        self.reason = reason
        super().__init__(f"robot '{name}' does not load: {reason}")


class ModelError(PinlinError):
    """The assembled model cannot be linearized (e.g. a singular mass matrix)."""


class EquilibriumError(PinlinError):
    """The requested operating point is not an equilibrium and cannot be made one.

    Attributes:
        residual: Generalized force [N or N*m] per velocity coordinate that the inputs cannot
            supply.
        names: Velocity-coordinate names matching ``residual``.
    """

    def __init__(self, message: str, residual=None, names: Sequence[str] = ()) -> None:
        self.residual = residual
        self.names = list(names)
        super().__init__(message)


class AssemblyError(EquilibriumError):
    """The loops of a mechanism cannot be closed from the given configuration.

    Attributes:
        residual: Constraint residual per row [m or rad].
        names: Constraint row names matching ``residual``.
    """


class ShapeError(PinlinError):
    """Matrices or vectors handed to pinlin have inconsistent sizes."""


class ModelFileError(PinlinError):
    """A linear model cannot be written to or read from a file."""

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}")


class ArgumentError(PinlinError):
    """A Python argument or command-line option has the wrong type or value, or does not apply
    to the request (an option that the chosen formulation or backend would ignore).

    Attributes:
        argument: The argument or option name, e.g. ``step`` or ``--basis``.
        reason: What was expected and what was found.
    """

    def __init__(self, argument: str, reason: str) -> None:
        self.argument = argument
        self.reason = reason
        super().__init__(f"argument '{argument}': {reason}")


class ResourceError(PinlinError):
    """A request would need more memory (or another resource) than the limit allows.

    Attributes:
        needed: Estimated amount [bytes].
        limit: The limit in force [bytes].
    """

    def __init__(self, message: str, needed: float = 0.0, limit: float = 0.0) -> None:
        self.needed = needed
        self.limit = limit
        super().__init__(message)
