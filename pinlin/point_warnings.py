"""Warnings of a trajectory's points: named by point, once per kind, and carried back from
worker processes.

The per-point path of :func:`pinlin.linearize_trajectory` (numerical derivatives, rotating
scenes) runs :func:`pinlin.linearize` at each point, whose warnings said nothing of the point
and came once per point; :class:`PointWarnings` counts them and raises each kind once,
naming the first point and how many more. Raised in a worker process or on an executor's
machine, a warning stayed there (the caller saw none): :func:`recording` collects them as
(category name, message, condition) and :func:`warn_again` raises them in the caller.
"""

from __future__ import annotations

import builtins
import warnings
from collections.abc import Callable

from .conditioning import AccuracyWarning

#: A recorded warning: (category name, message, the AccuracyWarning's condition or None).
Recorded = tuple[str, str, float | None]


class PointWarnings:
    """The warnings of points lo:hi, by category: (first point, its warning, count)."""

    def __init__(self) -> None:
        self.seen: dict[type, tuple[int, Warning, int]] = {}

    def add(self, k: int, caught: list[warnings.WarningMessage]) -> None:
        """Count the warnings ``caught`` at point ``k``."""
        for w in caught:
            first, message, count = self.seen.get(w.category, (k, w.message, 0))
            self.seen[w.category] = (first, message, count + 1)

    def raise_all(self, lo: int, hi: int) -> None:
        """Raise each kind once: "trajectory point k: <message> (n later points of points
        lo-(hi-1) too)"."""
        for category, (k, message, count) in self.seen.items():
            more = f" ({count - 1} later points of points {lo}-{hi - 1} too)" if count > 1 \
                else ""
            text = f"trajectory point {k}: {message}{more}"
            warnings.warn(AccuracyWarning(text, message.condition)
                          if isinstance(message, AccuracyWarning) else category(text),
                          stacklevel=5)


def recording(run: Callable[[], None]) -> list[Recorded]:
    """Run ``run`` and return the warnings it raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run()
    return [(w.category.__name__, str(w.message), getattr(w.message, "condition", None))
            for w in caught]


def warn_again(recorded: list[Recorded], lo: int = 0) -> None:
    """Raise here the warnings a worker recorded (an executor's chunk that starts at point
    ``lo``: its "trajectory point k" becomes the trajectory's lo + k)."""
    for name, message, condition in recorded:
        message = shift(message, lo)
        if name == "AccuracyWarning":
            warnings.warn(AccuracyWarning(message, condition if condition is not None else 0.0),
                          stacklevel=5)
            continue
        category = getattr(builtins, name, UserWarning)
        if not (isinstance(category, type) and issubclass(category, Warning)):
            category = UserWarning
        warnings.warn(message, category, stacklevel=5)


def shift(message: str, lo: int) -> str:
    """A chunk's "trajectory point k" as the whole trajectory's point lo + k."""
    prefix = "trajectory point "
    if message.startswith(prefix):
        head, _, rest = message[len(prefix):].partition(":")
        if head.isdigit():
            return f"{prefix}{int(head) + lo}:{rest}"
    return message


__all__ = ["PointWarnings", "Recorded", "recording", "shift", "warn_again"]
