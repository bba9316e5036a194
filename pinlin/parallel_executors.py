"""A trajectory's points on an executor: any ``concurrent.futures.Executor``, such as a Dask
cluster's ``client.get_executor()`` (``linearize_trajectory(..., executor=...)``).

Chunks of points go out with the pickled scene (:func:`pinlin.parallel.share`); each worker
process builds the scene's System once (a per-process cache keyed by the pickled scene) and
sends back the chunk's stacked arrays, which the caller copies into the result. Errors come
back as (class name, message, fields) and are raised again for the earliest failed point;
warnings recorded in a worker are raised again in the caller.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from concurrent.futures import Executor, Future
from dataclasses import replace
from typing import Any

import numpy as np

from .batch import Layout, Options, fill
from .exceptions import ArgumentError, PinlinError
from .parallel import (
    EXECUTOR_TASKS,
    MIN_CHUNK,
    cached_system,
    chunks,
    collect,
    portable,
    rebuild,
    share,
)
from .point_warnings import recording, shift, warn_again
from .system import System


def _chunk_task(blob: bytes, key: str, layout: Layout, inputs: dict[str, np.ndarray],
                options: Options, caller: int) -> dict[str, Any]:
    """On an executor's worker: the stacked arrays of one chunk (inputs not sent back), or
    ``{"error": (class name, message, fields)}``; with ``"warnings"``, those it recorded
    (``caller``: the caller's pid)."""
    recorded: list = []
    try:
        system = cached_system(blob, key)
        points = inputs["q"].shape[0]
        arrays = {**layout.allocate(points), **inputs}
        recorded = recording(lambda: fill(system, arrays, 0, points, options), caller)
    except PinlinError as exc:
        return {"error": portable(exc), "warnings": recorded}
    out = {k: val for k, val in arrays.items() if k not in layout.inputs}
    out["warnings"] = recorded
    return out


def run_executor(system: System, layout: Layout, inputs: Mapping[str, np.ndarray],
                 options: Options, executor: Executor, chunk: int | None,
                 progress: Callable[[int, int], None] | None) -> dict[str, np.ndarray]:
    """Fill the stack with chunks run by ``executor``; ``inputs`` as for
    :func:`pinlin.parallel.run_processes`."""
    N = layout.points
    chunk = chunk or max(MIN_CHUNK, math.ceil(N / EXECUTOR_TASKS))
    blob, key = share(system.scene)
    arrays = {**layout.allocate(), **{name: inputs[name] for name in layout.inputs}}
    part = replace(layout, points=0)  # the chunk's size comes with its rows
    futures: dict[Future, tuple[int, int]] = {}
    try:
        for lo, hi in chunks(N, chunk):
            futures[executor.submit(_chunk_task, blob, key, part,
                                    {name: inputs[name][lo:hi] for name in layout.inputs},
                                    options, os.getpid())] = (lo, hi)
    except BaseException as exc:   # the chunks already out are of no use now
        for future in futures:
            future.cancel()
        if isinstance(exc, RuntimeError):   # "cannot schedule new futures after shutdown"
            raise ArgumentError("executor", f"cannot take work: {exc}") from None
        raise

    def take(result: dict[str, Any], lo: int, hi: int) -> None:
        warn_again(result.pop("warnings", []), lo)
        if "error" in result:
            error = result["error"]
            raise rebuild((error[0], shift(error[1], lo), error[2]))
        for name, value in result.items():
            arrays[name][lo:hi] = value

    collect(futures, N, progress, take)
    return arrays


__all__ = ["run_executor"]
