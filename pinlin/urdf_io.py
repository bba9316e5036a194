"""Reading URDF files into Pinocchio models, with errors that name the file and the element.

urdfdom (the URDF reader inside Pinocchio) is lenient: a malformed number makes it print a
complaint on the C-level stderr and go on with a link's inertia zeroed, a broken ``<visual>`` is
complained about and dropped, and much that no robot can mean passes without a word (see
:mod:`pinlin.urdf_check`). :func:`load_urdf` therefore

1. checks the XML itself with the standard library (:func:`~pinlin.urdf_check.check_urdf`)
   before Pinocchio sees it, so that the message names the link or joint, the element, the
   attribute and what was expected, and
2. captures what urdfdom prints while it parses (:func:`quiet_stderr`) and turns *every*
   complaint (any ``Error:`` or ``Warning:`` line) into a :class:`~pinlin.exceptions.UrdfError`,
   as a backstop for whatever step 1 does not anticipate, also when the parse "succeeds".
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import pinocchio as pin

from .exceptions import UrdfError
from .urdf_check import (  # noqa: F401  (all but check_urdf: re-exported, defined here before)
    JOINT_NV,
    MAGNITUDE_LIMITS,
    MIN_AXIS_NORM,
    UrdfSummary,
    check_urdf,
)

_STDERR_FD = 2


def _flush_python_stderr() -> None:
    with contextlib.suppress(AttributeError, OSError, ValueError):
        sys.stderr.flush()


@contextlib.contextmanager
def quiet_stderr() -> Iterator[list[str]]:
    """Capture what C/C++ code writes to file descriptor 2 while the block runs.

    Always file descriptor 2, where urdfdom writes, whatever ``sys.stderr`` is: under pytest,
    Jupyter or an IDE ``sys.stderr`` is a Python object whose ``fileno()`` is another file or
    raises, and capturing that would let urdfdom's complaints through unseen.

    Yields a list that receives the captured text (one string) when the block exits.
    """
    captured: list[str] = []
    _flush_python_stderr()
    try:
        saved: int | None = os.dup(_STDERR_FD)
    except OSError:  # descriptor 2 closed: capture anyway, close it again afterwards
        saved = None
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), _STDERR_FD)
        try:
            yield captured
        finally:
            _flush_python_stderr()
            if saved is not None:
                os.dup2(saved, _STDERR_FD)
                os.close(saved)
            else:
                os.close(_STDERR_FD)
            tmp.seek(0)
            captured.append(tmp.read().decode(errors="replace"))


def urdfdom_complaints(text: str) -> list[str]:
    """The ``Error:``/``Warning:`` messages console_bridge printed in ``text``, one per
    complaint, on one line each, without the prefix and the ``at line N in file.cpp`` trailer."""
    out: list[str] = []
    for block in re.split(r"(?m)^(?=\s*(?:Error|Warning|Info|Debug):)", text):
        match = re.match(r"\s*(?:Error|Warning):(.*)", block, re.S)
        if match is None:
            continue
        message = re.sub(r"\s+at line \d+ in \S+\s*$", "", match.group(1))
        message = " ".join(message.split())
        if message and message not in out:
            out.append(message)
    return out


def complaint_summary(complaints: list[str]) -> str:
    """urdfdom's complaints as one line (innermost first, as urdfdom prints them)."""
    return "; ".join(complaints)


def build_model(path: str, *, free_flyer: bool
                ) -> tuple[pin.Model | None, Exception | None, list[str]]:
    """``pin.buildModelFromUrdf`` with what urdfdom prints captured.

    Args:
        path: URDF file.
        free_flyer: Add a free-flyer root joint named ``root_joint`` (floating base).

    Returns:
        The model (None when the build failed), the ValueError or RuntimeError the build failed
        with (else None), and urdfdom's complaints (:func:`urdfdom_complaints`): a caller
        reports the complaints first, they tell why a build failed.
    """
    model = failure = None
    with quiet_stderr() as captured:
        try:
            if free_flyer:
                model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
            else:
                model = pin.buildModelFromUrdf(path)
        except (ValueError, RuntimeError) as exc:
            failure = exc
    return model, failure, urdfdom_complaints(captured[0] if captured else "")


def load_urdf(path: str | Path, *, free_flyer: bool,
              check: Callable[[int, int], None] | None = None) -> pin.Model:
    """Build a Pinocchio model from a URDF file.

    Args:
        path: URDF file.
        free_flyer: Add a free-flyer root joint named ``root_joint`` (floating base).
        check: Called as ``check(nv, njoints)`` with the size of the model about to be built,
            after the XML checks and before Pinocchio parses the file; it raises to refuse
            (e.g. :func:`pinlin.resources.check_system_memory`).

    Raises:
        UrdfError: the file is missing, malformed or not a URDF, has a fault
            :func:`check_urdf` finds, or urdfdom complains while parsing it (every complaint
            is an error, even when the parse goes on).
    """
    path = Path(path)
    summary = check_urdf(path)
    if check is not None:
        check(summary.nv + (6 if free_flyer else 0), summary.njoints + (1 if free_flyer else 0))
    model, failure, complaints = build_model(str(path), free_flyer=free_flyer)
    if complaints:
        raise UrdfError(path, f"urdfdom reports: {complaint_summary(complaints)}")
    if failure is not None:
        detail = " ".join(str(failure).split()) or type(failure).__name__
        raise UrdfError(path, f"not a valid URDF model: {detail}")
    return model
