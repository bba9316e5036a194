"""A trajectory's points on several cores (worker processes) or machines (an executor).

**Worker processes** (``linearize_trajectory(..., workers=k)``): a pool of k processes, kept
for the life of the program (starting one costs more than a small trajectory) until a call asks
for another number of workers while it is idle (a sweep over workers = 2..8 keeps one pool,
not 35 idle processes; threads that use different numbers at once keep theirs), shares one
memory segment with the caller: the inputs q, v, u and every result array (:class:`Layout`)
live in a file on ``/dev/shm`` (POSIX shared memory; a temporary folder where there is none or
it is too small) that each worker maps, fills for its points and unmaps; nothing but the
pickled scene and two indices travels per task, and the caller's arrays are the segment itself
(no copy back). The segment's name is removed as soon as the work ends; its memory lives as
long as the arrays. A caller killed by a signal removes nothing: its segment is no longer
locked, and the next call removes it. Workers ignore
Ctrl-C (the caller's to handle: an interrupted call ends its pool) and end when their parent
does. ``multiprocessing.shared_memory.SharedMemory`` is that same /dev/shm file,
but its ``close()`` refuses while numpy views exist and, in Python < 3.13, a worker that
attaches one registers it with its resource tracker, which unlinks it when the worker exits;
mapping the file directly has neither problem.

Cost on the project's 2-core VM (validation/reports/bench_trajectory.md): a fresh shared page
costs several times an anonymous huge page to hand out (~3 us per 4 kB page against ~0.5 us
per 4 kB of a 2 MB page), which for Talos (65 kB of results a point) is as much as the kernel
itself; two workers gain only where that cost does not dominate. A persistent shared arena
reused across calls would remove it (not done).

The pool is forked where that is safe (Linux, no other Python thread running when it starts
but those of pinlin's own pool): workers then start in milliseconds and inherit the caller's
built systems. Otherwise it uses ``forkserver`` (or ``spawn``), whose workers import pinlin
once.

**Executors** (``executor=``; a Dask cluster's ``client.get_executor()``):
:mod:`pinlin.parallel_executors`, with the pickled scenes, errors and task collection of this
module.

Each process runs one Pinocchio workspace per thread (:attr:`pinlin.System.data`); the batch
kernel's one BLAS call per point is cut into products small enough for OpenBLAS to run on the
calling thread (:func:`pinlin.batch._product_rows`), so workers do not start BLAS threads
that would oversubscribe the cores.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import mmap
import multiprocessing as mp
import multiprocessing.connection as mp_connection
import multiprocessing.util as mp_util
import os
import pickle
import signal
import sys
import tempfile
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any

try:
    import fcntl
except ImportError:  # not POSIX: no locks, orphans are not removed
    fcntl = None  # type: ignore[assignment]

import numpy as np

from . import exceptions
from .batch import Layout, Options, fill
from .exceptions import ArgumentError, PinlinError
from .point_warnings import recording, warn_again
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
#: Start of a segment's file name.
SEGMENT_PREFIX = "pinlin-trajectory-"
#: Age [s] below which an unlocked segment is not taken for an orphan (:func:`_remove_orphans`).
ORPHAN_AGE = 60.0

_scenes: OrderedDict[str, Scene] = OrderedDict()
_scenes_lock = threading.Lock()
_pools: dict[int, ProcessPoolExecutor] = {}
_pools_lock = threading.Lock()
#: Calls running on the pool of each size (:func:`_using_pool`).
_users: dict[int, int] = {}


# --------------------------------------------------------------------------------------------
# Scenes travel pickled (a few hundred bytes: a Scene leaves its System behind) and are built
# once per process.


def share(scene: Scene) -> tuple[bytes, str]:
    """The pickled scene and its key; the scene (with its built system) enters this process's
    cache, so that forked workers inherit it built. The key covers the URDF's content too:
    the pickle holds its path, and a URDF rewritten between two calls (a mass changed) gave
    the second call the first model from workers that had built it."""
    blob = pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL)
    digest = hashlib.sha256(blob)
    if scene.urdf is not None:
        with contextlib.suppress(OSError):
            digest.update(scene.urdf.read_bytes())
    key = digest.hexdigest()
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


def portable(exc: PinlinError) -> tuple[str, str, dict[str, Any]]:
    """(class name, message, fields): the fields (a residual, names) where they pickle."""
    fields = {}
    for name, value in exc.__dict__.items():
        try:
            pickle.loads(pickle.dumps(value))
        except Exception:  # noqa: BLE001 (a field that does not travel stays behind)
            continue
        fields[name] = value
    return type(exc).__name__, str(exc), fields


def rebuild(error: tuple[str, str, dict[str, Any]]) -> PinlinError:
    """The exception :func:`portable` described."""
    name, message, fields = error
    cls = getattr(exceptions, name, PinlinError)
    if not (isinstance(cls, type) and issubclass(cls, PinlinError)):
        cls = PinlinError
    exc = cls.__new__(cls)
    Exception.__init__(exc, message)
    exc.__dict__.update(fields)
    return exc


def chunks(points: int, chunk: int) -> list[tuple[int, int]]:
    return [(lo, min(points, lo + chunk)) for lo in range(0, points, chunk)]


# --------------------------------------------------------------------------------------------
# Worker processes on shared memory.


class _Segment:
    """A shared-memory file mapped here; removed by :meth:`unlink`, mapped until the arrays
    that view it are gone. Its creator holds a shared lock on it (``flock``) until then: a
    segment nobody holds is an orphan (:func:`_remove_orphans`)."""

    def __init__(self, size: int) -> None:
        folder = SHM_FOLDER if _room(SHM_FOLDER, size) else tempfile.gettempdir()
        _remove_orphans(folder)
        fd, self.path = tempfile.mkstemp(prefix=SEGMENT_PREFIX, suffix=".bin", dir=folder)
        self.fd: int | None = fd
        try:
            if fcntl is not None:
                fcntl.flock(fd, fcntl.LOCK_SH)
            os.ftruncate(fd, size)
            self.map = mmap.mmap(fd, size)
        except BaseException:
            self.unlink()
            raise
        self.size = size

    def unlink(self) -> None:
        with contextlib.suppress(OSError):
            os.unlink(self.path)
        if self.fd is not None:
            os.close(self.fd)   # (the lock goes with it)
            self.fd = None


def _remove_orphans(folder: str) -> None:
    """Remove the segments in ``folder`` that no process holds (a caller killed by a signal,
    SIGTERM or SIGKILL, runs no cleanup: its segment stayed, 16 MB for 8000 ur5 points).
    A segment in use is locked by its creator, whatever its PID namespace (a pid in the name
    could not tell: another container sharing /dev/shm has other pids); one younger than
    :data:`ORPHAN_AGE` is left alone (its creator may not have locked it yet). POSIX only."""
    if fcntl is None:
        return
    try:
        names = os.listdir(folder)
    except OSError:
        return
    now = time.time()
    for name in names:
        if not name.startswith(SEGMENT_PREFIX):
            continue
        path = os.path.join(folder, name)
        try:
            if now - os.stat(path).st_mtime < ORPHAN_AGE:
                continue
            fd = os.open(path, os.O_RDONLY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)   # fails while someone holds it
            os.unlink(path)
        except OSError:
            pass
        finally:
            os.close(fd)


def _room(folder: str, size: int) -> bool:
    try:
        stat = os.statvfs(folder)
    except (OSError, AttributeError):
        return False
    return stat.f_bavail * stat.f_frsize >= 1.25 * size + (64 << 20)


def _segment_task(blob: bytes, key: str, path: str, size: int, layout: Layout, lo: int,
                  hi: int, options: Options, caller: int) -> tuple[tuple | None, list]:
    """In a worker: fill points lo:hi of the segment at ``path``; returns (the error as
    :func:`portable` gives it, or None; the warnings recorded, ``caller``: the caller's
    pid)."""
    recorded: list = []
    try:
        system = cached_system(blob, key)
        with open(path, "r+b") as fh:
            segment = mmap.mmap(fh.fileno(), size)
        try:
            arrays = layout.views(segment)
            recorded = recording(lambda: fill(system, arrays, lo, hi, options), caller)
        finally:
            arrays = None  # the views go before the map closes
            segment.close()
    except PinlinError as exc:
        return portable(exc), recorded
    except OSError as exc:   # the segment gone (removed by another process?)
        return portable(PinlinError(f"the shared segment {path} could not be opened: "
                                    f"{exc.strerror or exc}")), recorded
    return None, recorded


def _worker_start() -> None:
    """In each worker as it starts: Ctrl-C is the caller's to handle (a second one during
    the pool's shutdown left the caller waiting on workers forever), and the worker ends
    when its parent does (a caller killed by SIGTERM or ended by os._exit left its workers
    waiting forever). The parent's sentinel tells (its pid would not: a forkserver worker's
    parent is the fork server, which outlives the caller while workers hold its pipe)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = mp.parent_process()
    if parent is None:
        return

    def watch() -> None:
        mp_connection.wait([parent.sentinel])
        os._exit(1)

    threading.Thread(target=watch, name="pinlin-parent-watch", daemon=True).start()


def _start_method() -> str:
    """"fork" where that is safe: Linux, and no Python thread running but the main one and
    those of pinlin's own (stopped) pools; else "forkserver" (or "spawn")."""
    methods = mp.get_all_start_methods()
    ours = {t for pool in (*_pools.values(), *_retired) for t in _pool_threads(pool)}
    others = [t for t in threading.enumerate()
              if t is not threading.main_thread() and t not in ours and t.is_alive()]
    if "fork" in methods and sys.platform.startswith("linux") and not others:
        return "fork"
    return "forkserver" if "forkserver" in methods else "spawn"


def _pool_threads(pool: ProcessPoolExecutor) -> list[threading.Thread]:
    """The threads a ProcessPoolExecutor runs in the caller (its manager, its queue's
    feeder): they are not the caller's, and forking beside them is as safe as before them."""
    threads = [getattr(pool, "_executor_manager_thread", None),
               getattr(getattr(pool, "_call_queue", None), "_thread", None)]
    return [t for t in threads if isinstance(t, threading.Thread)]


@contextlib.contextmanager
def _using_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """The pool of ``workers`` processes for one call (:func:`_pool`). The pools of other
    sizes that no call is using stop first (their processes end, and their threads, so that
    the new pool may fork: :func:`_start_method`); one in use is left to its calls."""
    with _pools_lock:
        _users[workers] = _users.get(workers, 0) + 1
        idle = [_pools.pop(w) for w in list(_pools) if w != workers and not _users.get(w)]
    try:
        for old in idle:
            old.shutdown(wait=True)
        yield _pool(workers)
    finally:
        with _pools_lock:
            _users[workers] -= 1


def _pool(workers: int) -> ProcessPoolExecutor:
    """The persistent pool of ``workers`` processes (started on first use)."""
    with _pools_lock:
        pool = _pools.get(workers)
        if pool is None:
            method = _start_method()
            context = mp.get_context(method)
            if method == "forkserver":
                context.set_forkserver_preload(["pinlin.parallel"])
            pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_worker_start)
            _pools[workers] = pool
            _stop_at_exit()
        return pool


_finalizer: Any = None
#: Pools given up (after an interrupt or a broken pool), whose threads may still run a moment.
_retired: weakref.WeakSet = weakref.WeakSet()


def _after_fork_in_child() -> None:
    """A forked child starts with no pool (its parent's executors have no threads here) and
    fresh locks (one held at the fork would never be released here)."""
    global _pools_lock, _scenes_lock, _finalizer, _retired
    _pools.clear()
    _users.clear()
    _pools_lock = threading.Lock()
    _scenes_lock = threading.Lock()
    _finalizer = None
    _retired = weakref.WeakSet()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def _stop_at_exit() -> None:
    """Stop the pool as a process that uses it ends, before multiprocessing waits for that
    process's children: inside a multiprocessing child (a user's Process or pool worker), the
    interpreter's own hook came after that wait, which then waited forever."""
    global _finalizer
    if _finalizer is None:
        _finalizer = mp_util.Finalize(None, shutdown, exitpriority=100)


def shutdown() -> None:
    """Stop the worker pools (they are also stopped when the program exits)."""
    with _pools_lock:
        pools = list(_pools.values())
        _pools.clear()
    for pool in pools:   # (cancelling would leave another thread's call waiting forever)
        pool.shutdown(wait=True)


def _abandon(workers: int) -> None:
    """Drop the pool of ``workers`` processes and end them now (after an interrupt: their
    tasks are of no use to anyone)."""
    with _pools_lock:
        pool = _pools.pop(workers, None)
    if pool is None:
        return
    _retired.add(pool)   # its threads end soon; meanwhile they are not the caller's
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for process in processes:   # first: the broken pool then fails what is pending itself
        with contextlib.suppress(Exception):
            process.terminate()
    pool.shutdown(wait=False)


def run_processes(system: System, layout: Layout, inputs: Mapping[str, np.ndarray],
                  options: Options, workers: int, chunk: int | None,
                  progress: Callable[[int, int], None] | None) -> dict[str, np.ndarray]:
    """Fill the stack with ``workers`` processes on one shared segment; the returned arrays
    are views of it. ``inputs``: the arrays named by ``layout.inputs`` (q, v, u, ...)."""
    if mp.current_process().daemon:
        raise ArgumentError("workers", f"workers={workers} from a daemonic process (a worker of "
                                       "a multiprocessing Pool), which may not start "
                                       "processes of its own; use workers=1 there")
    N = layout.points
    _, size = layout.offsets()
    chunk = chunk or max(MIN_CHUNK, math.ceil(N / (TASKS_PER_WORKER * workers)))
    blob, key = share(system.scene)
    segment = _Segment(size)
    try:
        arrays = layout.views(segment.map)
        for name in layout.inputs:
            arrays[name][:] = inputs[name]
        with _using_pool(workers) as pool:
            try:
                _run_twice(pool, workers, blob, key, segment, layout, options, chunk, progress)
            except (KeyboardInterrupt, SystemExit):  # in either try: the pool ends with it
                _abandon(workers)
                raise
    finally:
        segment.unlink()
    return arrays


def _run_twice(pool: ProcessPoolExecutor, workers: int, blob: bytes, key: str,
               segment: _Segment, layout: Layout, options: Options, chunk: int,
               progress: Callable[[int, int], None] | None) -> None:
    """:func:`_run_pool`, and once more on a fresh pool if a worker died (killed, out of
    memory)."""
    try:
        _run_pool(pool, blob, key, segment, layout, options, chunk, progress)
    except BrokenProcessPool:
        _abandon(workers)
        try:
            _run_pool(_pool(workers), blob, key, segment, layout, options, chunk, progress)
        except BrokenProcessPool as exc:
            _abandon(workers)
            raise PinlinError(f"the worker processes died twice ({exc}): killed, out of "
                              "memory, or started by a script without 'if __name__ == "
                              "\"__main__\":' (workers that are not forked import it)? Run "
                              "with fewer workers, or workers=1") from None


def _run_pool(pool: ProcessPoolExecutor, blob: bytes, key: str, segment: _Segment,
              layout: Layout, options: Options, chunk: int,
              progress: Callable[[int, int], None] | None) -> None:
    N = layout.points
    futures = {pool.submit(_segment_task, blob, key, segment.path, segment.size, layout, lo,
                           hi, options, os.getpid()): (lo, hi) for lo, hi in chunks(N, chunk)}
    collect(futures, N, progress, lambda result, lo, hi: _raise_if(*result),
            cancel_on_interrupt=False)  # an interrupt ends the pool (_abandon)


def _raise_if(error: tuple | None, recorded: list) -> None:
    warn_again(recorded)
    if error is not None:
        raise rebuild(error)


def collect(futures: Mapping[Future, tuple[int, int]], total: int,
            progress: Callable[[int, int], None] | None,
            take: Callable[[Any, int, int], None], cancel_on_interrupt: bool = True) -> None:
    """Wait for the tasks in completion order and hand each result to ``take``. An error
    cancels the tasks of later points; the error of the earliest point is raised once the
    tasks before it are done (the same point whatever the order of completion). An interrupt
    (Ctrl-C, SystemExit) cancels the tasks left unless ``cancel_on_interrupt`` is False: a
    process pool the caller then ends fails them itself, and Python 3.11's pool, failing a
    cancelled one, printed an InvalidStateError traceback from its thread."""
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
    except BaseException as exc:
        if cancel_on_interrupt or not isinstance(exc, (KeyboardInterrupt, SystemExit)):
            for future in futures:
                future.cancel()
        raise
    if first is not None:
        raise first[1]


__all__ = ["EXECUTOR_TASKS", "MIN_CHUNK", "cached_system", "chunks", "collect", "portable",
           "rebuild", "run_processes", "share", "shutdown"]
