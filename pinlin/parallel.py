"""A trajectory's points on several cores (worker processes) or machines (an executor).

**Worker processes** (``linearize_trajectory(..., workers=k)``): a pool of k processes, kept
for the life of the program (starting one costs more than a small trajectory), shares one
memory segment with the caller: the inputs q, v, u and every result array (:class:`Layout`)
live in a file on ``/dev/shm`` (POSIX shared memory; a temporary folder where there is none or
it is too small) that each worker maps, fills for its points and unmaps; nothing but the
pickled scene and two indices travels per task, and the caller's arrays are the segment itself
(no copy back). The segment's name is removed as soon as the work ends; its memory lives as
long as the arrays. ``multiprocessing.shared_memory.SharedMemory`` is that same /dev/shm file,
but its ``close()`` refuses while numpy views exist and, in Python < 3.13, a worker that
attaches one registers it with its resource tracker, which unlinks it when the worker exits;
mapping the file directly has neither problem.

Cost on the project's 2-core VM (validation/reports/bench_trajectory.md): a fresh shared page
costs several times an anonymous huge page to hand out (~3 us per 4 kB page against ~0.5 us
per 4 kB of a 2 MB page), which for Talos (65 kB of results a point) is as much as the kernel
itself; two workers gain only where that cost does not dominate. A persistent shared arena
reused across calls would remove it (not done).

The pool is forked where that is safe (Linux, no other Python thread running when it starts):
workers then start in milliseconds and inherit the caller's built systems. Otherwise it uses
``forkserver`` (or ``spawn``), whose workers import pinlin once.

**Executors** (``executor=``; a Dask cluster's ``client.get_executor()``): chunks of points go
out with the pickled scene; each worker process builds the scene's System once (a per-process
cache keyed by the pickled scene) and sends back the chunk's stacked arrays.

Each process runs one Pinocchio workspace per thread (:attr:`pinlin.System.data`); the batch
kernel makes no BLAS call, so BLAS threads need no limit here.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import mmap
import multiprocessing as mp
import os
import pickle
import sys
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from typing import Any

import numpy as np

from . import exceptions
from .batch import Layout, Options, fill
from .exceptions import ArgumentError, PinlinError
from .scene import Scene
from .system import System

#: Scenes each process keeps built, keyed by their pickle's digest (least recently used out).
CACHE_SIZE = 8
#: Tasks per worker process by default (load balance against per-task overhead).
TASKS_PER_WORKER = 4
#: Tasks of an executor by default, and the fewest points in a task by default.
EXECUTOR_TASKS, MIN_CHUNK = 16, 16
#: Folder of the shared segments, when it exists and has room.
SHM_FOLDER = "/dev/shm"

_scenes: OrderedDict[str, Scene] = OrderedDict()
_scenes_lock = threading.Lock()
_pools: dict[int, ProcessPoolExecutor] = {}
_pools_lock = threading.Lock()


# --------------------------------------------------------------------------------------------
# Scenes travel pickled (a few hundred bytes: a Scene leaves its System behind) and are built
# once per process.


def share(scene: Scene) -> tuple[bytes, str]:
    """The pickled scene and its key; the scene (with its built system) enters this process's
    cache, so that forked workers inherit it built."""
    blob = pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL)
    key = hashlib.sha256(blob).hexdigest()
    _remember(key, scene)
    return blob, key


def _remember(key: str, scene: Scene) -> None:
    with _scenes_lock:
        _scenes[key] = scene
        _scenes.move_to_end(key)
        while len(_scenes) > CACHE_SIZE:
            _scenes.popitem(last=False)


def cached_system(blob: bytes, key: str) -> System:
    """The system of the pickled scene ``blob``, built once in this process."""
    with _scenes_lock:
        scene = _scenes.get(key)
        if scene is not None:
            _scenes.move_to_end(key)
    if scene is None:
        scene = pickle.loads(blob)  # our own caller's pickle, never a file's
        _remember(key, scene)
    return scene.system


# --------------------------------------------------------------------------------------------
# Errors cross process boundaries as (class name, message): pinlin's exceptions take several
# constructor fields, which pickle cannot restore.


def _portable(exc: PinlinError) -> tuple[str, str]:
    return type(exc).__name__, str(exc)


def _rebuild(error: tuple[str, str]) -> PinlinError:
    name, message = error
    cls = getattr(exceptions, name, PinlinError)
    if not (isinstance(cls, type) and issubclass(cls, PinlinError)):
        cls = PinlinError
    exc = cls.__new__(cls)
    Exception.__init__(exc, message)
    return exc


def _chunks(points: int, chunk: int) -> list[tuple[int, int]]:
    return [(lo, min(points, lo + chunk)) for lo in range(0, points, chunk)]


# --------------------------------------------------------------------------------------------
# Worker processes on shared memory.


class _Segment:
    """A shared-memory file mapped here; removed by :meth:`unlink`, mapped until the arrays
    that view it are gone."""

    def __init__(self, size: int) -> None:
        folder = SHM_FOLDER if _room(SHM_FOLDER, size) else tempfile.gettempdir()
        fd, self.path = tempfile.mkstemp(prefix="pinlin-trajectory-", suffix=".bin",
                                         dir=folder)
        try:
            os.ftruncate(fd, size)
            self.map = mmap.mmap(fd, size)
        except BaseException:
            os.close(fd)
            self.unlink()
            raise
        os.close(fd)
        self.size = size

    def unlink(self) -> None:
        with contextlib.suppress(OSError):
            os.unlink(self.path)


def _room(folder: str, size: int) -> bool:
    try:
        stat = os.statvfs(folder)
    except (OSError, AttributeError):
        return False
    return stat.f_bavail * stat.f_frsize >= 1.25 * size + (64 << 20)


def _segment_task(blob: bytes, key: str, path: str, size: int, layout: Layout, lo: int,
                  hi: int, options: Options) -> tuple[str, str] | None:
    """In a worker: fill points lo:hi of the segment at ``path``; an error comes back as
    (class name, message)."""
    try:
        system = cached_system(blob, key)
        with open(path, "r+b") as fh:
            segment = mmap.mmap(fh.fileno(), size)
        try:
            arrays = layout.views(segment)
            fill(system, arrays, lo, hi, options)
        finally:
            arrays = None  # the views go before the map closes
            segment.close()
    except PinlinError as exc:
        return _portable(exc)
    return None


def _start_method() -> str:
    methods = mp.get_all_start_methods()
    if "fork" in methods and sys.platform.startswith("linux") and \
            threading.active_count() == 1:
        return "fork"
    return "forkserver" if "forkserver" in methods else "spawn"


def _pool(workers: int) -> ProcessPoolExecutor:
    """The persistent pool of ``workers`` processes (started on first use)."""
    with _pools_lock:
        pool = _pools.get(workers)
        if pool is None:
            method = _start_method()
            context = mp.get_context(method)
            if method == "forkserver":
                context.set_forkserver_preload(["pinlin.parallel"])
            pool = ProcessPoolExecutor(workers, mp_context=context)
            _pools[workers] = pool
        return pool


def shutdown() -> None:
    """Stop the worker pools (they are also stopped when the program exits)."""
    with _pools_lock:
        pools = list(_pools.values())
        _pools.clear()
    for pool in pools:
        pool.shutdown(wait=True, cancel_futures=True)


def run_processes(system: System, layout: Layout, inputs: Mapping[str, np.ndarray],
                  options: Options, workers: int, chunk: int | None,
                  progress: Callable[[int, int], None] | None) -> dict[str, np.ndarray]:
    """Fill the stack with ``workers`` processes on one shared segment; the returned arrays
    are views of it. ``inputs``: the arrays named by ``layout.inputs`` (q, v, u, ...)."""
    N = layout.points
    _, size = layout.offsets()
    chunk = chunk or max(MIN_CHUNK, math.ceil(N / (TASKS_PER_WORKER * workers)))
    blob, key = share(system.scene)
    segment = _Segment(size)
    try:
        arrays = layout.views(segment.map)
        for name in layout.inputs:
            arrays[name][:] = inputs[name]
        try:
            _run_pool(_pool(workers), blob, key, segment, layout, options, chunk, progress)
        except BrokenProcessPool:  # a worker died (killed, out of memory): one fresh try
            with _pools_lock:
                broken = _pools.pop(workers, None)
            if broken is not None:
                broken.shutdown(wait=False, cancel_futures=True)
            _run_pool(_pool(workers), blob, key, segment, layout, options, chunk, progress)
    finally:
        segment.unlink()
    return arrays


def _run_pool(pool: ProcessPoolExecutor, blob: bytes, key: str, segment: _Segment,
              layout: Layout, options: Options, chunk: int,
              progress: Callable[[int, int], None] | None) -> None:
    N = layout.points
    futures = {pool.submit(_segment_task, blob, key, segment.path, segment.size, layout, lo,
                           hi, options): (lo, hi) for lo, hi in _chunks(N, chunk)}
    _collect(futures, N, progress, lambda result, lo, hi: _raise_if(result))


def _raise_if(result: tuple[str, str] | None) -> None:
    if result is not None:
        raise _rebuild(result)


def _collect(futures: Mapping[Future, tuple[int, int]], total: int,
             progress: Callable[[int, int], None] | None,
             take: Callable[[Any, int, int], None]) -> None:
    """Wait for the tasks in completion order and hand each result to ``take``. An error
    cancels the tasks of later points; the error of the earliest point is raised once the
    tasks before it are done (the same point whatever the order of completion)."""
    done, first = 0, None  # first: (lo, error) of the earliest failed chunk
    try:
        for future in as_completed(futures):
            lo, hi = futures[future]
            if future.cancelled() or (first is not None and lo > first[0]):
                continue
            try:
                take(future.result(), lo, hi)
            except PinlinError as exc:
                first = (lo, exc)
                for other, (start, _) in futures.items():
                    if start > lo:
                        other.cancel()
                continue
            done += hi - lo
            if progress is not None:
                progress(done, total)
    except BaseException:
        for future in futures:
            future.cancel()
        raise
    if first is not None:
        raise first[1]


# --------------------------------------------------------------------------------------------
# Executors (Dask and any concurrent.futures.Executor).


def _chunk_task(blob: bytes, key: str, layout: Layout, inputs: dict[str, np.ndarray],
                options: Options) -> dict[str, Any]:
    """On an executor's worker: the stacked arrays of one chunk (inputs not sent back), or
    ``{"error": (class name, message)}``."""
    try:
        system = cached_system(blob, key)
        points = inputs["q"].shape[0]
        arrays = {**layout.allocate(points), **inputs}
        fill(system, arrays, 0, points, options)
    except PinlinError as exc:
        return {"error": _portable(exc)}
    return {k: val for k, val in arrays.items() if k not in layout.inputs}


def run_executor(system: System, layout: Layout, inputs: Mapping[str, np.ndarray],
                 options: Options, executor: Executor, chunk: int | None,
                 progress: Callable[[int, int], None] | None) -> dict[str, np.ndarray]:
    """Fill the stack with chunks run by ``executor``; ``inputs`` as for
    :func:`run_processes`."""
    N = layout.points
    chunk = chunk or max(MIN_CHUNK, math.ceil(N / EXECUTOR_TASKS))
    blob, key = share(system.scene)
    arrays = {**layout.allocate(), **{name: inputs[name] for name in layout.inputs}}
    part = replace(layout, points=0)  # the chunk's size comes with its rows
    try:
        futures = {executor.submit(_chunk_task, blob, key, part,
                                   {name: inputs[name][lo:hi] for name in layout.inputs},
                                   options): (lo, hi) for lo, hi in _chunks(N, chunk)}
    except RuntimeError as exc:   # "cannot schedule new futures after shutdown"
        raise ArgumentError("executor", f"cannot take work: {exc}") from None

    def take(result: dict[str, Any], lo: int, hi: int) -> None:
        if "error" in result:
            error = result["error"]
            raise _rebuild((error[0], _shift(error[1], lo)))
        for name, value in result.items():
            arrays[name][lo:hi] = value

    _collect(futures, N, progress, take)
    return arrays


def _shift(message: str, lo: int) -> str:
    """A chunk's "trajectory point k" as the whole trajectory's point lo + k."""
    prefix = "trajectory point "
    if message.startswith(prefix):
        head, _, rest = message[len(prefix):].partition(":")
        if head.isdigit():
            return f"{prefix}{int(head) + lo}:{rest}"
    return message


__all__ = ["cached_system", "run_executor", "run_processes", "share", "shutdown"]
