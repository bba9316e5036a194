"""Checks of :func:`pinlin.linearize_trajectory`'s arguments: the scene, the (N, width) arrays
of states and inputs, normalized configurations, times, counts. Each refusal names the
argument and, for arrays, the first bad row."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from concurrent.futures import Executor

import numpy as np
import pinocchio as pin

from .arrays import non_numbers
from .derivatives import BACKENDS, resolve_steps
from .exceptions import ArgumentError, ResourceError, ShapeError
from .fields import show
from .resources import check_memory
from .system import System

#: A configuration's unit-norm parts (quaternions, (cos, sin) pairs) may be off by this.
NORM_TOLERANCE = 1e-6


def points(name: str, value: object, width: int, what: str, points: int | None,
          limit: float) -> np.ndarray:
    """``value`` as a C-ordered (N, width) float64 copy: finite, |x| <= limit, N rows (or
    ``points`` rows when given)."""
    expected = f"an (N, {width}) array ({what}, one row per point)"
    bad = non_numbers(value)
    if bad:
        raise ArgumentError(name, f"expected real numbers ({what}), got {bad}")
    shape = getattr(value, "shape", None)
    if isinstance(shape, tuple) and all(isinstance(d, int) for d in shape):
        # the float64 copy, checked before it is made (a broadcast view or a compressed
        # file's array can be far larger than the memory it arrives in)
        check_memory(8 * math.prod(shape), f"argument '{name}' ({what})",
                     f"a float64 copy of shape {shape}")
    try:
        arr = np.array(value, dtype=float, order="C")
    except (TypeError, ValueError, OverflowError):
        raise ArgumentError(name, f"expected {expected}, got {value!r:.80}") from None
    except MemoryError:
        raise ResourceError(f"argument '{name}' ({what}) does not fit in memory as float64 "
                            "numbers; give fewer points") from None
    if arr.ndim == 1 and width == 0 and points is not None and arr.size == 0:
        arr = arr.reshape(points, 0)
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ShapeError(f"argument '{name}' must have shape (N, {width}) ({what}, one row "
                         f"per point), got shape {arr.shape}")
    if points is not None and arr.shape[0] != points:
        raise ShapeError(f"argument '{name}' has {arr.shape[0]} rows, argument 'q' has "
                         f"{points}: one row per point in each")
    if arr.shape[0] == 0:
        raise ArgumentError(name, "expected at least one point (row), got none")
    finite = np.isfinite(arr)
    if not finite.all():
        k, j = (int(i) for i in np.argwhere(~finite)[0])
        raise row_error(name, k, (j,), "has NaN or inf")
    big = np.abs(arr) > limit
    if big.any():
        k, j = (int(i) for i in np.argwhere(big)[0])
        raise row_error(name, k, (j,), f"has an entry of size {abs(arr[k, j]):.3g}",
                        f"; {what} are limited to |x| <= {limit:g}")
    return arr


def row_error(name: str, row: int, columns: tuple[int, ...], detail: str, tail: str = ""
              ) -> ArgumentError:
    """ArgumentError "row k <detail> (column j)<tail>" on argument ``name``, carrying
    ``row``, ``columns`` (indices into the array) and ``detail`` and ``tail`` as attributes, so
    that a caller that read the array from a file can name the file's line and columns
    instead."""
    where = (f"column {columns[0]}" if len(columns) == 1 else
             f"columns {columns[0]}-{columns[-1]}")
    exc = ArgumentError(name, f"row {row} {detail} ({where}){tail}")
    exc.row, exc.columns, exc.detail, exc.tail = row, columns, detail, tail
    return exc


def check_normalized(system: System, q: np.ndarray) -> None:
    """Every row's unit-norm parts (quaternions of free-flyer and spherical joints, (cos, sin)
    of continuous and planar joints) within :data:`NORM_TOLERANCE`, vectorized; other joints
    whose configuration is not a vector space row by row with ``pin.isNormalized``."""
    model = system.model
    other = False
    for j in system.joints.values():
        if j.nq == j.nv:
            continue
        start = {"JointModelFreeFlyer": 3, "JointModelSpherical": 0,
                 "JointModelPlanar": 2}.get(j.kind, 0 if j.continuous else None)
        if start is None:
            other = True
            continue
        part = q[:, j.idx_q + start:j.idx_q + j.nq]
        norms = np.sqrt(np.einsum("ij,ij->i", part, part))
        bad = np.abs(norms - 1.0) > NORM_TOLERANCE
        if bad.any():
            k = int(np.argmax(bad))
            kind = "quaternion" if part.shape[1] == 4 else "(cos, sin) pair"
            raise row_error("q", k, tuple(range(j.idx_q + start, j.idx_q + j.nq)),
                            f"is not normalized: the {kind} of joint '{j.name}'",
                            f" has norm {norms[k]:.9g}; it must have unit norm (pinlin never "
                            "normalizes for you)")
    if other:
        for k, row in enumerate(q):
            if not pin.isNormalized(model, row, NORM_TOLERANCE):
                raise ArgumentError("q", f"row {k} is not normalized (pin.isNormalized)")


def times(t: object, points: int) -> np.ndarray | None:
    if t is None:
        return None
    bad = non_numbers(t)
    if bad:
        raise ArgumentError("t", f"expected real times [s], got {bad}")
    try:
        arr = np.array(t, dtype=float).reshape(-1) if np.ndim(t) <= 1 else None
    except (TypeError, ValueError, OverflowError):
        arr = None
    if arr is None or arr.shape != (points,):
        raise ArgumentError("t", f"expected {points} times [s] (one per point), got "
                                 f"{show(t)}")
    if not np.isfinite(arr).all():
        raise ArgumentError("t", f"entry {int(np.argmin(np.isfinite(arr)))} is NaN or inf")
    step = np.diff(arr)
    if (step <= 0).any():
        k = int(np.argmax(step <= 0)) + 1
        raise ArgumentError("t", f"times must increase strictly: t[{k}] = {arr[k]:.9g} s "
                                 f"after t[{k - 1}] = {arr[k - 1]:.9g} s")
    arr.setflags(write=False)
    return arr


#: Worker processes allowed per CPU available to this process: a pool starts all of them at
#: once, each with its own copy of the models, so an unbounded count can exhaust the machine.
WORKERS_PER_CPU = 4


def max_workers() -> int:
    """The largest ``workers`` accepted: :data:`WORKERS_PER_CPU` times the CPUs this process
    may run on."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        cpus = os.cpu_count() or 1
    return WORKERS_PER_CPU * max(cpus, 1)


def positive_int(name: str, value: object, allow_none: bool = False) -> int | None:
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ArgumentError(name, f"expected a whole number >= 1, got {value!r}")
    return int(value)


def check_options(system: System, derivatives: object,
                  step: float | Mapping[str, float] | None, workers: object, chunk: object,
                  executor: object, progress: Callable[[int, int], None] | None,
                  second_order: object, rest: bool = False) -> tuple[int, int | None, bool]:
    """The options of :func:`pinlin.linearize_trajectory` checked: (workers, chunk,
    second_order); ``rest``: a schedule of rest points (a mechanism's single static models
    do have second-order matrices).

    Raises:
        ArgumentError: naming the option: an unknown backend, a step with analytic
            derivatives, counts below 1, an executor that is not one (or with workers > 1),
            a progress that is not callable, a second_order that is not a bool or that asks
            a mechanism (loops, mimic couplings) for what a single model of it at a moving
            state does not have.
    """
    if not isinstance(derivatives, str) or derivatives not in BACKENDS:
        raise ArgumentError("derivatives", f"expected one of "
                                           f"{', '.join(map(repr, BACKENDS))}, got "
                                           f"{derivatives!r}")
    if step is not None:
        if derivatives == "analytic":
            raise ArgumentError("step", "a finite-difference step applies to derivatives "
                                        "'fd3' and 'fd5'; the analytic derivatives take none")
        resolve_steps(derivatives, step)
    n_workers = positive_int("workers", workers)
    assert n_workers is not None
    limit = max_workers()
    if n_workers > limit:
        raise ArgumentError("workers", f"expected at most {limit} processes "
                                       f"({WORKERS_PER_CPU} per CPU this process may use; more "
                                       f"only contend for the cores and memory), got "
                                       f"{n_workers}")
    n_chunk = positive_int("chunk", chunk, allow_none=True)
    if executor is not None and not isinstance(executor, Executor):
        raise ArgumentError("executor", "expected a concurrent.futures.Executor (for Dask: "
                                        f"client.get_executor()), got {type(executor).__name__}")
    if executor is not None and n_workers > 1:
        raise ArgumentError("executor", "give workers > 1 (processes on this machine) or an "
                                        "executor, not both")
    if progress is not None and not callable(progress):
        raise ArgumentError("progress", "expected a function progress(done, total)")
    if not isinstance(second_order, bool | np.bool_):
        raise ArgumentError("second_order", f"expected True or False, got {second_order!r}")
    if second_order and system.constraints and not rest:
        raise ArgumentError("second_order", f"scene '{system.scene.name}' has constraints "
                                            "(loops, contacts or mimic couplings): "
                                            "pinlin.linearize at a given state of a "
                                            "constrained system gives no M, C_damp, K, Bu, so "
                                            "its trajectory has none (a schedule of its rest "
                                            "points, v and u left out, has them); leave "
                                            "second_order out (A, B are in its independent "
                                            "coordinates)")
    return n_workers, n_chunk, bool(second_order)


__all__ = ["NORM_TOLERANCE", "check_normalized", "check_options", "max_workers", "points",
           "positive_int", "row_error", "times"]
