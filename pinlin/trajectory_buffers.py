"""Reusing a trajectory model's memory: ``linearize_trajectory(..., out=previous)``.

An iterative optimizer (iLQR, DDP, SQP) re-linearizes the same horizon every iteration. Each
call's stacks are fresh memory, which the operating system hands out and zeroes page by page
on first touch: for floating-base Talos, 1000 points are 66 MB. With ``out=`` the new models
are written into the arrays of a model an earlier call returned, and that same object is
returned, updated, as NumPy's ``out=`` does. What that saves depends on the memory system:
from nothing to a fifth of the call in the runs of ``validation/bench_trajectory.py`` on this
project's two-core VM.

What makes the arrays safe to reuse: :func:`pinlin.batch.fill` writes every entry that is not
a structural zero (the upper half of B, A's upper-left block off the Lie-group joints) at every
point, and those zeros were zero since the arrays were allocated by :meth:`Layout.allocate`;
so only a model that this process built, for the same system and the same :class:`Layout`
(points, outputs, second-order stacks), is accepted. Its record (:class:`Arena`) is kept in
the model's ``__dict__`` and not pickled. A call that fails after it began writing leaves
``out``'s matrices NaN and takes its record away: the previous models are gone, and a model
of NaN cannot be mistaken for them or reused.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from .batch import Layout
from .exceptions import ArgumentError
from .system import System
from .trajectory_model import ARENA, register_reusable


class Arena(NamedTuple):
    """Where a trajectory model's stacks came from."""

    system: weakref.ReferenceType
    layout: Layout
    arrays: dict[str, np.ndarray]


def reusable(out: object, system: System, layout: Layout, workers: int,
             executor: object) -> dict[str, np.ndarray]:
    """The result arrays of ``out`` for a call with ``layout`` on ``system`` (read-only until
    :func:`writable`: a call refused before it writes leaves ``out`` as it was).

    Raises:
        ArgumentError: ``out`` is not a trajectory model this process's
            ``linearize_trajectory`` returned for the same system and layout (the message says
            which), or the call runs in other processes (workers > 1, an executor).
    """
    from .trajectory_model import TrajectoryModel

    if not isinstance(out, TrajectoryModel):
        raise ArgumentError("out", f"expected a TrajectoryModel that linearize_trajectory "
                                   f"returned, got {type(out).__name__}")
    if workers > 1 or executor is not None:
        raise ArgumentError("out", "reuses memory of this process: not with workers > 1 or an "
                                   "executor (their results arrive in memory of their own)")
    arena = out.__dict__.get(ARENA)
    if arena is None:
        raise ArgumentError("out", f"trajectory model '{out.name}' was not computed by "
                                   "linearize_trajectory in this process on an open chain (it "
                                   "was loaded, discretized, unpickled, built by hand, of a "
                                   "mechanism, or invalidated by a call that failed): its "
                                   "arrays are not pinlin's to overwrite")
    if arena.system() is not system:
        raise ArgumentError("out", f"holds the models of another system (scene "
                                   f"'{out.name}'); give a model of scene "
                                   f"'{system.scene.name}' computed from this Scene object")
    if any(arr.flags.writeable for arr in arena.arrays.values()):
        raise ArgumentError("out", f"trajectory model '{out.name}' has arrays made writeable "
                                   "after the call that returned it: they may hold edits in "
                                   "entries a call does not write; pass a model as returned")
    if arena.layout != layout:
        def text(lay: Layout) -> str:
            return f"{lay.points} points {'with' if lay.second_order else 'without'} " \
                   "second-order stacks"

        raise ArgumentError("out", f"holds {text(arena.layout)}; this call makes "
                                   f"{text(layout)}: give a model of the same number of "
                                   "points and options")
    return arena.arrays


def writable(arrays: Mapping[str, np.ndarray]) -> None:
    """Make the reused arrays writeable (they own their memory: np.zeros)."""
    for arr in arrays.values():
        arr.setflags(write=True)


def attach(model: Any, system: System, layout: Layout, arrays: Mapping[str, np.ndarray]
           ) -> None:
    """Record in ``model`` that its stacks are ``arrays`` of ``layout`` on ``system``."""
    owned = {k: arrays[k] for k in layout.shapes() if k not in layout.inputs}
    for arr in owned.values():   # (the screening's own "bad" too: none is the user's to edit)
        arr.setflags(write=False)
    register_reusable(owned.values())
    model.__dict__[ARENA] = Arena(weakref.ref(system), layout, owned)


def adopt(out: Any, model: Any) -> Any:
    """``out`` made the new ``model`` (the same arrays): NumPy's ``out=`` contract."""
    out.__dict__.clear()
    out.__dict__.update(model.__dict__)
    return out


def invalidate(out: Any) -> None:
    """After a failed call that wrote into ``out``'s arrays: NaN there, no record."""
    arena = out.__dict__.pop(ARENA, None)
    if arena is None:
        return
    for arr in arena.arrays.values():
        arr.setflags(write=True)
        arr.fill(np.nan)
        arr.setflags(write=False)


__all__ = ["ARENA", "Arena", "adopt", "attach", "invalidate", "reusable", "writable"]
