"""Warnings of a trajectory's points, carried back from worker processes.

The per-point path of :func:`pinlin.linearize_trajectory` (numerical derivatives, rotating
scenes) runs :func:`pinlin.linearize` at each point. Raised in a worker process, its warnings
stayed there (the caller saw none): :func:`recording` collects them as (category name,
message, condition) and :func:`warn_again` raises them in the caller. Recording swaps the
process's warning filters (``warnings.catch_warnings``), which is safe only where no other
thread runs: the main thread of a process that is not the caller's (:func:`may_record`);
elsewhere (a thread pool, Dask's worker threads) the warnings are left as they are.
"""

from __future__ import annotations

import builtins
import os
import sys
import threading
import warnings
from collections.abc import Callable

from . import exceptions
from .conditioning import AccuracyWarning

#: A recorded warning: (category name, message, the AccuracyWarning's condition or None).
Recorded = tuple[str, str, float | None]


def may_record(caller: int) -> bool:
    """Whether this code runs in the main thread of a process other than ``caller`` (a pid),
    where recording cannot disturb another thread's warnings."""
    return os.getpid() != caller and threading.current_thread() is threading.main_thread()


def recording(run: Callable[[], None], caller: int) -> list[Recorded]:
    """Run ``run`` and return the warnings it raised, where :func:`may_record` holds for
    ``caller`` (a pid); elsewhere run it with the warnings left as they are (none returned)."""
    if not may_record(caller):
        run()
        return []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run()
    return [(w.category.__name__, str(w.message), getattr(w.message, "condition", None))
            for w in caught]


_PACKAGE = os.path.dirname(os.path.abspath(__file__))


def _outside_level() -> int:
    """The ``stacklevel`` that points :func:`warn_again`'s warnings at the first frame
    outside pinlin (the caller's line, as the serial path's warnings do)."""
    level, frame = 1, sys._getframe(1)
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    return level


def warn_again(recorded: list[Recorded], lo: int = 0) -> None:
    """Raise here the warnings a worker recorded (an executor's chunk that starts at point
    ``lo``: its "trajectory point k" becomes the trajectory's lo + k), at the caller's line."""
    if not recorded:
        return
    level = _outside_level()
    for name, message, condition in recorded:
        message = shift(message, lo)
        if name == "AccuracyWarning":
            warnings.warn(AccuracyWarning(message, condition if condition is not None else 0.0),
                          stacklevel=level)
            continue
        category = getattr(exceptions, name, None) or getattr(builtins, name, UserWarning)
        if not (isinstance(category, type) and issubclass(category, Warning)):
            category = UserWarning
        warnings.warn(message, category, stacklevel=level)


def shift(message: str, lo: int) -> str:
    """A chunk's "trajectory point k" as the whole trajectory's point lo + k."""
    prefix = "trajectory point "
    if message.startswith(prefix):
        head, _, rest = message[len(prefix):].partition(":")
        if head.isdigit():
            return f"{prefix}{int(head) + lo}:{rest}"
    return message


__all__ = ["Recorded", "may_record", "recording", "shift", "warn_again"]
