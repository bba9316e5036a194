"""Worker processes through their lives: a changed URDF, a caller that is itself a child
process or is killed, interrupted calls, leftover segments, warnings raised in workers, and
the start method and number of pools. Real processes, small trajectories."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time
import warnings
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
from conftest import REPO
from test_trajectory import _COLLINEAR

import pinlin
from pinlin import parallel

_PENDULUM = """<robot name="p">
  <link name="base"/>
  <link name="bob"><inertial><origin xyz="0 0 -1"/><mass value="{mass}"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="bob"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
</robot>
"""


def _states(N: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (N, 1)), rng.uniform(-1, 1, (N, 1)), rng.uniform(-1, 1, (N, 1))


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie child of the test would count: none here)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def _script(tmp_path, body: str) -> subprocess.CompletedProcess:
    path = tmp_path / "run.py"
    path.write_text(textwrap.dedent(body))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, str(path)], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path, env=env)


def test_a_urdf_rewritten_between_calls_is_rebuilt_in_the_workers(tmp_path):
    """The workers keep built scenes keyed by the scene; a URDF whose mass changed between two
    calls gave the second the first model (its pickle holds the path, not the file)."""
    urdf = tmp_path / "p.urdf"
    urdf.write_text(_PENDULUM.format(mass=1.0))
    q, v, u = _states(40)
    first = pinlin.linearize_trajectory(pinlin.Scene.from_urdf(urdf), q, v, u, workers=2)
    urdf.write_text(_PENDULUM.format(mass=5.0))
    scene = pinlin.Scene.from_urdf(urdf)
    again = pinlin.linearize_trajectory(scene, q, v, u, workers=2)
    serial = pinlin.linearize_trajectory(scene, q, v, u)
    assert np.abs(serial.B - first.B).max() > 0.1      # the mass changed the model
    np.testing.assert_array_equal(again.A, serial.A)
    np.testing.assert_array_equal(again.B, serial.B)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork: Linux only")
def test_the_pools_own_threads_do_not_make_the_next_pool_forkserver(tmp_path):
    """A pool's own threads (manager, queue feeder) made the next pool (another number of
    workers) forkserver, which re-ran unguarded scripts. In a fresh process: a thread another
    library leaves running in this one (Dask's offload thread, after a LocalCluster test)
    rightly makes it forkserver."""
    run = _script(tmp_path, """
        import numpy as np
        import pinlin
        from pinlin import parallel

        q = np.zeros((40, 1))
        for workers in (2, 3):
            pinlin.linearize_trajectory("pendulum", q, q, q, workers=workers)
            print(parallel._start_method(), flush=True)
    """)
    assert run.stdout.split() == ["fork", "fork"], run.stdout + run.stderr


@pytest.mark.parametrize("parent_first", [False, True], ids=["child", "child_after_parent"])
def test_workers_from_a_child_process_let_it_end(tmp_path, parent_first):
    """A multiprocessing child that used workers=2 printed its result and then waited
    forever: the pool was stopped only after multiprocessing's wait for the child's
    children. A child forked after its parent used workers=2 inherited the parent's pool,
    whose threads do not exist in the child: its own call waited forever."""
    parent = "pinlin.linearize_trajectory('pendulum', q, q, q, workers=2)" if parent_first \
        else "pass"
    run = _script(tmp_path, f"""
        import multiprocessing as mp
        import numpy as np
        import pinlin

        def child():
            q = np.zeros((40, 1))
            pinlin.linearize_trajectory("pendulum", q, q, q, workers=2)
            print("done", flush=True)

        if __name__ == "__main__":
            q = np.zeros((40, 1))
            {parent}
            p = mp.get_context("fork").Process(target=child)
            p.start()
            p.join(60)
            print("exit", p.exitcode, flush=True)
    """)
    assert run.stdout.split() == ["done", "exit", "0"], run.stdout + run.stderr


def test_workers_end_with_their_caller(tmp_path):
    """A caller that ends without cleanup (os._exit, or a signal's kill) left its workers
    waiting forever; each now sees its parent gone and ends."""
    run = _script(tmp_path, """
        import os
        import numpy as np
        import pinlin
        from pinlin import parallel

        q = np.zeros((40, 1))
        pinlin.linearize_trajectory("pendulum", q, q, q, workers=2)
        pool = next(iter(parallel._pools.values()))
        print(*pool._processes, flush=True)
        os._exit(0)
    """)
    pids = [int(p) for p in run.stdout.split()]
    assert len(pids) == 2, run.stdout + run.stderr
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and any(_alive(p) for p in pids):
        time.sleep(0.1)
    assert not any(_alive(p) for p in pids)


def test_an_orphaned_segment_is_removed_by_the_next_call():
    """A caller killed by SIGTERM or SIGKILL leaves its shared segment (16 MB for 8000 ur5
    points); the next call removes the segments that nobody holds (a live caller, in any PID
    namespace, holds a lock on its own), and none younger than ORPHAN_AGE."""
    import fcntl

    folder = parallel.SHM_FOLDER
    if not os.path.isdir(folder):
        pytest.skip("no /dev/shm")
    paths = {kind: os.path.join(folder, f"{parallel.SEGMENT_PREFIX}test-{kind}.bin")
             for kind in ("orphan", "held", "young")}
    old = time.time() - 2 * parallel.ORPHAN_AGE
    fds = []
    for kind, path in paths.items():
        with open(path, "wb") as fh:
            fh.write(b"x")
        if kind != "young":
            os.utime(path, (old, old))
        if kind == "held":
            fds.append(os.open(path, os.O_RDONLY))
            fcntl.flock(fds[-1], fcntl.LOCK_SH)
    try:
        q, v, u = _states(40)
        pinlin.linearize_trajectory("pendulum", q, v, u, workers=2)
        assert [os.path.exists(paths[k]) for k in ("orphan", "held", "young")] == \
            [False, True, True]
    finally:
        for fd in fds:
            os.close(fd)
        for path in paths.values():
            if os.path.exists(path):
                os.unlink(path)




@pytest.mark.parametrize("how", ["serial", "workers", "executor"])
def test_warnings_of_the_per_point_path_reach_the_caller(tmp_path, how):
    """A point mass on two parallel joints, M singular at q2 = 0, with numerical derivatives
    (the per-point path): points 3 and 5 near the singularity warn. In a worker process, or a
    process pool's, the warnings stayed there; now they reach the caller."""
    (tmp_path / "sing.urdf").write_text(_COLLINEAR)
    scene = pinlin.Scene.from_urdf(tmp_path / "sing.urdf")
    q = np.tile([0.0, 0.5], (8, 1))
    q[3, 1], q[5, 1] = 1e-6, 1e-6
    kwargs = {"serial": {}, "workers": {"workers": 2, "chunk": 3},
              "executor": {"executor": ProcessPoolExecutor(1), "chunk": 3}}[how]
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pinlin.linearize_trajectory(scene, q, np.zeros((8, 2)), np.zeros((8, 2)),
                                        derivatives="fd3", **kwargs)
    finally:
        if "executor" in kwargs:
            kwargs["executor"].shutdown()
    found = [w for w in caught if issubclass(w.category, pinlin.AccuracyWarning)]
    assert len(found) == 2 and all("mass matrix" in str(w.message) for w in found), found
    if how != "serial":   # raised again here: at the caller's line
        assert all(w.filename == __file__ for w in found), [w.filename for w in found]


def test_threads_of_an_executor_leave_the_warning_filters_alone(tmp_path):
    """Recording warnings swaps the process's filters (warnings.catch_warnings): from the
    threads of a ThreadPoolExecutor (or Dask's) that left every later warning of the process
    swallowed. Recording happens only in another process's main thread."""
    from concurrent.futures import ThreadPoolExecutor

    (tmp_path / "sing.urdf").write_text(_COLLINEAR)
    scene = pinlin.Scene.from_urdf(tmp_path / "sing.urdf")
    N = 128
    q = np.tile([0.0, 0.5], (N, 1))
    q[3::4, 1] = 1e-6
    before = (list(warnings.filters), warnings._showwarnmsg_impl)
    with ThreadPoolExecutor(4) as pool:
        for _ in range(3):   # (the test runs inside pytest's own catch_warnings)
            pinlin.linearize_trajectory(scene, q, np.zeros((N, 2)), np.zeros((N, 2)),
                                        derivatives="fd3", executor=pool, chunk=4)
            assert (list(warnings.filters), warnings._showwarnmsg_impl) == before


def test_workers_from_a_daemonic_process_are_an_argument_error():
    """A multiprocessing Pool's worker may not start processes (AssertionError from deep in
    multiprocessing before)."""
    import multiprocessing as mp

    with mp.get_context("fork").Pool(1) as pool:
        name, text = pool.apply(_in_pool_worker)
    assert name == "ArgumentError" and "daemonic" in text, text


def _in_pool_worker() -> tuple[str, str]:
    q = np.zeros((40, 1))
    try:
        pinlin.linearize_trajectory("pendulum", q, q, q, workers=2)
    except Exception as exc:  # noqa: BLE001
        return type(exc).__name__, str(exc)
    return "", ""


def test_a_new_number_of_workers_stops_the_idle_pool_of_the_old(tmp_path):
    """Pools were kept per number of workers: a sweep over workers = 2, 3, 4 left 9 idle
    processes for the life of the program. Asking for another number stops the idle pool of
    the old one (its processes end, the new pool still forks); the results are the serial
    ones throughout."""
    run = _script(tmp_path, """
        import os
        import numpy as np
        import pinlin
        from pinlin import parallel

        rng = np.random.default_rng(0)
        q, v, u = (rng.uniform(-1, 1, (60, 1)) for _ in range(3))
        serial = pinlin.linearize_trajectory("pendulum", q, v, u)
        before = None
        for workers in (2, 3, 2):
            traj = pinlin.linearize_trajectory("pendulum", q, v, u, workers=workers)
            assert np.array_equal(traj.A, serial.A) and np.array_equal(traj.B, serial.B)
            assert list(parallel._pools) == [workers], list(parallel._pools)
            pool = parallel._pools[workers]
            assert pool._mp_context.get_start_method() == "fork"
            if before is not None:   # the pool of the number asked for before has ended
                assert not set(before) & set(pool._processes)
                for pid in before:
                    try:
                        os.kill(pid, 0)
                        print("alive", pid)
                    except ProcessLookupError:
                        pass
            before = list(pool._processes)
            print(workers, len(before), flush=True)
    """)
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.split() == ["2", "2", "3", "3", "2", "2"], run.stdout


def test_an_interrupted_call_prints_no_thread_traceback(tmp_path):
    """Ctrl-C during workers=3: the call cancelled its pending tasks and then ended the pool,
    whose thread (Python 3.11) failed the cancelled tasks again and printed an
    InvalidStateError traceback, in about three runs of four. The next call works."""
    run = _script(tmp_path, """
        import numpy as np
        import pinlin

        rng = np.random.default_rng(0)
        scene = pinlin.Scene.from_robot("ur5")
        q, v, u = (rng.uniform(-1, 1, (4000, 6)) for _ in range(3))

        def stop(done, total):
            if done < total:
                raise KeyboardInterrupt

        if __name__ == "__main__":
            for _ in range(4):
                try:
                    pinlin.linearize_trajectory(scene, q, v, u, workers=3, chunk=50,
                                                progress=stop)
                except KeyboardInterrupt:
                    print("stopped", flush=True)
            pinlin.linearize_trajectory(scene, q[:100], v[:100], u[:100], workers=3)
            print("done", flush=True)
    """)
    assert run.stdout.split() == ["stopped"] * 4 + ["done"], run.stdout + run.stderr
    assert "Traceback" not in run.stderr, run.stderr


def test_an_interrupt_during_the_retry_ends_the_pool(tmp_path):
    """A worker died (the first run raised BrokenProcessPool) and Ctrl-C came during the
    retry on a fresh pool: that pool stayed registered with its pending tasks, which the next
    call waited behind. It ends with the interrupt now."""
    run = _script(tmp_path, """
        from concurrent.futures.process import BrokenProcessPool

        import numpy as np
        import pinlin
        from pinlin import parallel

        real, calls = parallel._run_pool, []

        def broken_once(pool, *args, **kwargs):
            calls.append(pool)
            if len(calls) == 1:
                raise BrokenProcessPool("a worker died")
            return real(pool, *args, **kwargs)

        def stop(done, total):
            if done < total:
                raise KeyboardInterrupt

        if __name__ == "__main__":
            parallel._run_pool = broken_once
            rng = np.random.default_rng(0)
            q, v, u = (rng.uniform(-1, 1, (4000, 6)) for _ in range(3))
            try:
                pinlin.linearize_trajectory("ur5", q, v, u, workers=2, chunk=20,
                                            progress=stop)
            except KeyboardInterrupt:
                print("stopped", len(calls), flush=True)
            print("pools", len(parallel._pools), flush=True)
            parallel._run_pool = real
            pinlin.linearize_trajectory("ur5", q[:40], v[:40], u[:40], workers=2)
            print("done", flush=True)
    """)
    assert run.stdout.split() == ["stopped", "2", "pools", "0", "done"], \
        run.stdout + run.stderr
