"""Trajectories and batches: ``pinlin.linearize_trajectory`` and ``TrajectoryModel``.

References: ``.at(k)`` against ``pinlin.linearize`` at the same state (a consistency check of
the batch kernel against the general path), and a few points against central differences of
the continuous dynamics in the chart built from Pinocchio's own functions (no pinlin code):

    f(dq, v, u) = [dDifference(q0, q, ARG1) v; aba(q, v, S u - k (q - q_rest) - c v)],
    q = integrate(q0, dq).
"""

from __future__ import annotations

import dataclasses
import sys
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg as sla
from conftest import URDF_DIR

import pinlin
from pinlin import batch, batch_screen, parallel
from pinlin.chart import kinematic_block
from pinlin.cli import main

#: Central differences with h = 1e-6 (see tests/test_moving_state.py for the error budget).
FD_TOL = 1e-7

_INERTIAL = ('<inertial><origin xyz="0.1 0 -0.3"/><mass value="1.5"/><inertia ixx="0.1" '
             'ixy="0" ixz="0" iyy="0.12" iyz="0" izz="0.08"/></inertial>')


def _chain(*joints: tuple[str, str]) -> str:
    """A URDF chain of (name, type) joints, each link with a physical inertia."""
    parts = ['<?xml version="1.0"?><robot name="chain"><link name="base"/>']
    parent = "base"
    for k, (name, kind) in enumerate(joints):
        limit = ('<limit lower="-3" upper="3" effort="10" velocity="10"/>'
                 if kind in ("revolute", "prismatic") else "")
        axis = "0 0 1" if kind == "planar" else "0 1 0"
        parts.append(f'<link name="l{k}">{_INERTIAL}</link><joint name="{name}" type="{kind}">'
                     f'<parent link="{parent}"/><child link="l{k}"/><axis xyz="{axis}"/>'
                     f'{limit}</joint>')
        parent = f"l{k}"
    return "".join(parts) + "</robot>"


def states(scene: pinlin.Scene, N: int, seed: int):
    """N random states: configurations integrate(neutral, dq), dq in [-1.5, 1.5] (rotated
    floating bases), velocities in [-2, 2], inputs in [-5, 5]."""
    system = scene.system
    model, rng = system.model, np.random.default_rng(seed)
    neutral = pin.neutral(model)
    q = np.array([pin.integrate(model, neutral, rng.uniform(-1.5, 1.5, model.nv))
                  for _ in range(N)])
    return q, rng.uniform(-2, 2, (N, system.nv)), rng.uniform(-5, 5, (N, len(system.actuated)))


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """Planar, continuous (with a spring) and floating joints, damped: every chart case but
    the spherical joint, and a spring on an angle stored as (cos, sin)."""
    folder = tmp_path_factory.mktemp("mixed")
    (folder / "robot.urdf").write_text(_chain(("slide", "planar"), ("elbow", "continuous"),
                                              ("float", "floating"), ("wrist", "revolute")))
    (folder / "scene.toml").write_text(
        'urdf = "robot.urdf"\n[effects]\ngravity = true\n'
        'springs = { elbow = { stiffness = 30.0, rest = 2.8 }, wrist = { stiffness = 5.0 } }\n'
        'damping = { elbow = 0.7, wrist = 0.2 }\n[outputs]\nframes = ["l3"]\n'
        'joints = ["elbow", "v:wrist"]\n')
    return pinlin.Scene.load(folder / "scene.toml")


SCENES = {
    "ur5": lambda: pinlin.Scene.from_robot("ur5"),
    "solo12": lambda: pinlin.Scene.from_robot("solo12"),
    "talos": lambda: pinlin.Scene.from_robot("talos"),
    "talos_full": lambda: pinlin.Scene.from_robot("talos_full"),  # nv = 50: blocked product
    "ur5_arm": lambda: pinlin.Scene.load(URDF_DIR / "ur5_arm.toml"),  # springs, damping, frame
    "rotating": lambda: pinlin.Scene.load(URDF_DIR / "rotating_double_pendulum.toml"),
}


def _assert_same_model(got: pinlin.LinearModel, ref: pinlin.LinearModel) -> None:
    for key in ("A", "B", "C", "D", "f0"):
        a, b = getattr(got, key), getattr(ref, key)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * max(1.0, np.abs(b).max()),
                                   err_msg=key)
    assert got.state_names == ref.state_names and got.input_names == ref.input_names
    assert got.output_names == ref.output_names and got.dt == ref.dt
    op, ref_op = got.operating_point, ref.operating_point
    for key in ("q", "v", "u"):
        np.testing.assert_array_equal(getattr(op, key), getattr(ref_op, key))
    np.testing.assert_allclose(op.a, ref_op.a, rtol=0, atol=1e-12 * np.abs(ref_op.a).max())
    np.testing.assert_allclose(op.y, ref_op.y, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name, path", [("ur5", "batch"), ("solo12", "batch"),
                                        ("talos", "batch"), ("talos_full", "batch"),
                                        ("ur5_arm", "batch"),
                                        ("rotating", "per point")])
def test_each_point_is_the_model_linearize_gives(name, path):
    scene = SCENES[name]()
    q, v, u = states(scene, 4, seed=len(name))
    traj = pinlin.linearize_trajectory(scene, q, v, u, t=np.arange(4) * 0.1)
    assert traj.info["path"] == path and len(traj) == 4
    for k in range(4):
        _assert_same_model(traj.at(k), pinlin.linearize(scene, q=q[k], v=v[k], u=u[k]))
    assert traj.at(-1).info["point"] == 3 and traj.at(2).info["t"] == pytest.approx(0.2)


def test_mixed_joints_springs_on_an_angle_and_frame_outputs(mixed):
    q, v, u = states(mixed, 5, seed=3)
    traj = pinlin.linearize_trajectory(mixed, q, v, u)
    assert traj.info["path"] == "batch" and traj.C.strides[0] != 0  # frame outputs vary
    for k in range(5):
        _assert_same_model(traj.at(k), pinlin.linearize(mixed, q=q[k], v=v[k], u=u[k]))


@pytest.mark.parametrize("backend", ["fd3", "fd5"])
def test_numerical_derivatives_take_the_per_point_path(backend):
    scene = pinlin.Scene.from_robot("ur5")
    q, v, u = states(scene, 3, seed=5)
    traj = pinlin.linearize_trajectory(scene, q, v, u, derivatives=backend)
    assert traj.info["path"] == "per point" and traj.info["derivatives"] == backend
    for k in range(3):
        ref = pinlin.linearize(scene, q=q[k], v=v[k], u=u[k], derivatives=backend)
        np.testing.assert_array_equal(traj.A[k], ref.A)


def _reference(system: pinlin.System, q0, v0, u0, h: float = 1e-6):
    """(A, B, f0) by central differences of the chart dynamics, from Pinocchio alone."""
    model, data = system.model, system.model.createData()
    S, nv = system.input_matrix, model.nv

    def f(x, u):
        q = pin.integrate(model, q0, x[:nv])
        v = x[nv:]
        dq = pin.difference(model, system.q_rest, q)
        tau = S @ u - system.stiffness * dq - system.damping * v
        qdot = pin.dDifference(model, q0, q, pin.ArgumentPosition.ARG1) @ v
        return np.concatenate([qdot, pin.aba(model, data, q, v, tau)])

    x0 = np.concatenate([np.zeros(nv), v0])
    A = np.array([(f(x0 + h * e, u0) - f(x0 - h * e, u0)) / (2 * h)
                  for e in np.eye(2 * nv)]).T
    B = np.array([(f(x0, u0 + e) - f(x0, u0 - e)) / 2.0 for e in np.eye(len(u0))]).T
    return A, B, f(x0, u0)


@pytest.mark.parametrize("name", ["talos", "ur5_arm", "mixed"])
def test_points_match_differences_of_the_dynamics(name, mixed):
    scene = mixed if name == "mixed" else SCENES[name]()
    q, v, u = states(scene, 2, seed=7)
    traj = pinlin.linearize_trajectory(scene, q, v, u)
    for k in range(2):
        A, B, f0 = _reference(scene.system, q[k], v[k], u[k])
        np.testing.assert_allclose(traj.A[k], A, rtol=0, atol=FD_TOL * np.abs(A).max())
        np.testing.assert_allclose(traj.B[k], B, rtol=0, atol=1e-10 * np.abs(B).max())
        np.testing.assert_allclose(traj.f0[k], f0, rtol=0, atol=1e-10 * np.abs(f0).max())
    if name == "talos":  # the floating base's Lie-group block is really there
        assert np.abs(traj.A[:, :6, :6]).max() > 0.1


def test_kinematic_rows_match_the_chart_on_every_lie_group_joint():
    """The vectorized -1/2 ad(v) blocks against pinlin.chart.kinematic_block (itself tested
    against differences of dDifference) on free-flyer, spherical, planar, revolute joints."""
    m = pin.Model()
    parent = 0
    for name, joint in [("ff", pin.JointModelFreeFlyer()), ("sph", pin.JointModelSpherical()),
                        ("pl", pin.JointModelPlanar()), ("rz", pin.JointModelRZ())]:
        parent = m.addJoint(parent, joint, pin.SE3.Identity(), name)
    joints = {m.names[j]: SimpleNamespace(kind=m.joints[j].shortname(), idx_v=m.joints[j].idx_v,
                                          idx_q=m.joints[j].idx_q, nv=m.joints[j].nv,
                                          nq=m.joints[j].nq, continuous=False)
              for j in range(1, m.njoints)}
    fake = SimpleNamespace(nv=m.nv, joints=joints, stiffness=np.zeros(m.nv),
                           damping=np.zeros(m.nv))
    v = np.random.default_rng(8).standard_normal((3, m.nv))
    A = np.zeros((3, 2 * m.nv, 2 * m.nv))
    batch.kinematic_rows(A, v, batch._plan(fake))
    for k in range(3):
        np.testing.assert_array_equal(A[k, :m.nv, :m.nv], kinematic_block(fake, v[k]))
        np.testing.assert_array_equal(A[k, :m.nv, m.nv:], np.eye(m.nv))


def test_state_outputs_cost_no_memory_per_point():
    scene = pinlin.Scene.from_robot("ur5")
    traj = pinlin.linearize_trajectory(scene, *states(scene, 50, seed=9))
    for key in ("C", "D", "y"):
        arr = getattr(traj, key)
        assert arr.strides[0] == 0 and not arr.flags.writeable
    for key in ("A", "B", "f0", "q", "v", "u", "a"):
        with pytest.raises(ValueError):
            getattr(traj, key)[0] = 1.0


# --------------------------------------------------------------------------------------------
# Processes and executors


@pytest.mark.parametrize("name", ["talos", "ur5_arm", "rotating"])
def test_worker_processes_give_the_serial_arrays(name):
    scene = SCENES[name]()
    q, v, u = states(scene, 150 if name == "talos" else 60, seed=11)
    serial = pinlin.linearize_trajectory(scene, q, v, u)
    seen = []
    shared = pinlin.linearize_trajectory(scene, q, v, u, workers=2, chunk=17,
                                         progress=lambda done, total: seen.append(done))
    for key in ("A", "B", "C", "D", "f0", "a", "y"):
        np.testing.assert_array_equal(getattr(shared, key), getattr(serial, key), err_msg=key)
    assert seen[-1] == len(q) and seen == sorted(seen)


def test_worker_processes_started_while_threads_run():
    """With another thread alive the pool is not forked (forkserver); same arrays."""
    parallel.shutdown()
    stop = threading.Event()
    thread = threading.Thread(target=stop.wait, daemon=True)
    thread.start()
    try:
        assert parallel._start_method() != "fork"
        scene = pinlin.Scene.from_robot("solo12")
        q, v, u = states(scene, 40, seed=12)
        shared = pinlin.linearize_trajectory(scene, q, v, u, workers=2)
    finally:
        stop.set()
        parallel.shutdown()
    np.testing.assert_array_equal(shared.A, pinlin.linearize_trajectory(scene, q, v, u).A)


def test_a_thread_executor_gives_the_serial_arrays():
    scene = pinlin.Scene.load(URDF_DIR / "ur5_arm.toml")
    q, v, u = states(scene, 70, seed=13)
    with ThreadPoolExecutor(max_workers=3) as executor:
        threaded = pinlin.linearize_trajectory(scene, q, v, u, executor=executor, chunk=9)
    serial = pinlin.linearize_trajectory(scene, q, v, u)
    for key in ("A", "B", "C", "f0", "y"):
        np.testing.assert_array_equal(getattr(threaded, key), getattr(serial, key))


def test_errors_in_workers_name_the_point(tmp_path):
    """A point whose mass matrix is singular, met inside a worker process (per-point path)
    and in the batch's final check: the first bad point is named either way."""
    (tmp_path / "robot.urdf").write_text(_chain(("a", "revolute"), ("b", "revolute")).replace(
        '<mass value="1.5"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.12" iyz="0" izz="0.08"/>',
        '<mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>', 2))
    scene = pinlin.Scene.from_urdf(tmp_path / "robot.urdf")
    q, v, u = states(scene, 6, seed=14)
    for kwargs in ({}, {"workers": 2}, {"derivatives": "fd3", "workers": 2}):
        with pytest.raises(pinlin.ModelError, match=r"trajectory point 0: .*carries no inertia"):
            pinlin.linearize_trajectory(scene, q, v, u, **kwargs)


def test_the_final_check_names_the_first_bad_point():
    scene = pinlin.Scene.from_robot("ur5")
    system = scene.system
    q, v, u = states(scene, 6, seed=15)
    layout = batch.Layout.of(system, 6)
    arrays = {**layout.allocate(), "q": q, "v": v, "u": u}
    batch.fill(system, arrays, 0, 6, batch.Options())
    batch.check(system, arrays)
    arrays["A"][4, 9, 2] = np.nan
    arrays["B"][3, 7, 1] = np.inf
    arrays["A"][1, 2, 3] = np.nan  # upper rows: kinematic, finite by construction, not summed
    batch_screen.screen(system, arrays, 0, 6, np.zeros(6, dtype=bool))
    assert arrays["bad"].tolist() == [0, 0, 0, 1, 1, 0]
    with pytest.raises(pinlin.ModelError, match="trajectory point 3: .* NaN or inf in B"):
        batch.check(system, arrays)


@pytest.fixture(scope="module")
def dask_cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        yield cluster, client


def test_a_dask_cluster_gives_the_serial_arrays(dask_cluster):
    _, client = dask_cluster
    scene = pinlin.Scene.load(URDF_DIR / "ur5_arm.toml")
    q, v, u = states(scene, 120, seed=16)
    remote = pinlin.linearize_trajectory(scene, q, v, u, executor=client.get_executor())
    serial = pinlin.linearize_trajectory(scene, q, v, u)
    for key in ("A", "B", "C", "D", "f0", "y"):
        np.testing.assert_array_equal(getattr(remote, key), getattr(serial, key))


def test_cli_on_a_dask_cluster(dask_cluster, tmp_path, capfd):
    cluster, _ = dask_cluster
    scene = pinlin.Scene.from_robot("ur5")
    q, v, u = states(scene, 30, seed=17)
    np.savez(tmp_path / "traj.npz", q=q, v=v, u=u)
    out = tmp_path / "models.npz"
    assert main(["trajectory", "ur5", str(tmp_path / "traj.npz"), "--dask",
                 cluster.scheduler_address, "--out", str(out)]) == 0
    assert "Dask at tcp://" in capfd.readouterr().out
    np.testing.assert_array_equal(pinlin.TrajectoryModel.load(out).A,
                                  pinlin.linearize_trajectory(scene, q, v, u).A)


# --------------------------------------------------------------------------------------------
# Files and discretization


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_models_round_trip(suffix, tmp_path):
    scene = pinlin.Scene.load(URDF_DIR / "ur5_arm.toml")
    q, v, u = states(scene, 8, seed=18)
    traj = pinlin.linearize_trajectory(scene, q, v, u, t=np.linspace(0.0, 0.7, 8))
    for model in (traj, traj.discretize(0.01)):
        back = pinlin.TrajectoryModel.load(model.save(tmp_path / f"m{suffix}"))
        for key in ("A", "B", "C", "D", "f0", "q", "v", "u", "a", "t", "y"):
            np.testing.assert_array_equal(getattr(back, key), getattr(model, key), err_msg=key)
        assert back.state_names == model.state_names and back.dt == model.dt
        assert back.output_names == model.output_names and back.info == model.info
        assert back.D.strides[0] == 0  # stored once, broadcast again
        _assert_same_model(back.at(5), model.at(5))


def test_model_files_are_not_mixed_up(tmp_path):
    scene = pinlin.Scene.from_robot("ur5")
    traj = pinlin.linearize_trajectory(scene, *states(scene, 3, seed=19))
    single = traj.at(0)
    traj.save(tmp_path / "traj.npz")
    single.save(tmp_path / "one.npz")
    with pytest.raises(pinlin.ModelFileError, match="load it with pinlin.TrajectoryModel.load"):
        pinlin.LinearModel.load(tmp_path / "traj.npz")
    with pytest.raises(pinlin.ModelFileError, match="not a pinlin trajectory model file"):
        pinlin.TrajectoryModel.load(tmp_path / "one.npz")
    with pytest.raises(pinlin.ModelFileError, match="expected .npz or .mat"):
        traj.save(tmp_path / "traj.json")
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(pinlin.ModelFileError, match="bad.npz"):
        pinlin.TrajectoryModel.load(tmp_path / "bad.npz")
    # hand edits of a saved file: times reversed, a member pinlin does not write
    with np.load(tmp_path / "traj.npz") as z:
        members = {k: z[k] for k in z.files}
    for edit, words in (({"t": np.array([2.0, 1.0, 0.0])}, "increase strictly"),
                        ({"extra": np.ones(3)}, "unknown member 'extra'")):
        np.savez(tmp_path / "edited.npz", **{**members, **edit})
        with pytest.raises(pinlin.ModelFileError, match=words):
            pinlin.TrajectoryModel.load(tmp_path / "edited.npz")


@pytest.mark.parametrize("method", ["zoh", "euler"])
def test_discretize_is_the_per_point_discretization(method):
    scene = pinlin.Scene.from_robot("solo12")
    q, v, u = states(scene, 5, seed=20)
    traj = pinlin.linearize_trajectory(scene, q, v, u)
    disc = traj.discretize(0.004, method)
    assert disc.dt == 0.004 and len(disc) == 5
    for k in range(5):
        _assert_same_model(disc.at(k), traj.at(k).discretize(0.004, method))
    with pytest.raises(pinlin.ArgumentError, match="already discrete"):
        disc.discretize(0.01)
    for bad in (0.0, -1.0, float("nan"), "0.1", True):
        with pytest.raises(pinlin.ArgumentError, match="argument 'dt'"):
            traj.discretize(bad)
    # A finite dt whose matrices overflow: refused (a saved file would not load back); the
    # zero-order hold is refused before, as keeping no correct digit (eps ||A||_1 dt >= 1).
    refusal = (r"dt = 1e\+300 s .* at trajectory point 0" if method == "euler" else
               r"dt = 1e\+300 s .*no correct digit")
    with pytest.raises(pinlin.ModelError, match=refusal):
        traj.discretize(1e300, method)


def test_euler_refuses_stacks_that_are_not_mechanical():
    """As LinearModel.discretize does: states other than [q:...; v:...], or inputs on the
    position rows (before, eye(1) was broadcast over a 2 x 2 block of x' = -x: couplings of
    1.0 out of nothing, and the position rows of B dropped)."""
    N = 3
    plain = pinlin.TrajectoryModel(
        A=np.tile(-np.eye(3), (N, 1, 1)), B=np.ones((N, 3, 1)), C=np.tile(np.eye(3), (N, 1, 1)),
        D=np.zeros((N, 3, 1)), f0=np.zeros((N, 3)), q=np.zeros((N, 1)), v=np.zeros((N, 1)),
        u=np.zeros((N, 1)), a=np.zeros((N, 1)), state_names=("x1", "x2", "x3"),
        input_names=("u1",), output_names=("y1", "y2", "y3"), name="plain")
    with pytest.raises(pinlin.ArgumentError, match="model 'plain' needs states"):
        plain.discretize(0.1, "euler")
    np.testing.assert_allclose(plain.discretize(0.1).A[0], np.exp(-0.1) * np.eye(3),
                               rtol=1e-14)
    scene = pinlin.Scene.resolve("double_pendulum")
    q, v, u = states(scene, 3, seed=4)
    traj = pinlin.linearize_trajectory(scene, q, v, u)
    B = np.array(traj.B)
    B[:, 0, 0] = 1.0                     # an input on a position row
    pushed = dataclasses.replace(traj, B=B)
    with pytest.raises(pinlin.ArgumentError, match="acting on the velocities only"):
        pushed.discretize(0.01, "euler")


# --------------------------------------------------------------------------------------------
# Bad arguments


def _bad_cases():
    ur5 = pinlin.Scene.from_robot("ur5")
    q, v, u = states(ur5, 5, seed=21)
    solo = pinlin.Scene.from_robot("solo12")
    qs, vs, us = states(solo, 5, seed=22)
    nan_v = v.copy()
    nan_v[3, 2] = np.nan
    big_u = u.copy()
    big_u[1, 0] = 1e13
    denorm = qs.copy()
    denorm[2, 3:7] *= 1.01
    return {
        "q_shape": ((ur5, q[:, :5], v, u), {}, pinlin.ShapeError,
                    r"argument 'q' must have shape \(N, 6\)"),
        "v_rows": ((ur5, q, v[:4], u), {}, pinlin.ShapeError,
                   "argument 'v' has 4 rows, argument 'q' has 5"),
        "no_points": ((ur5, q[:0], v[:0], u[:0]), {}, pinlin.ArgumentError,
                      "at least one point"),
        "not_numbers": ((ur5, q, v, [["a"] * 6] * 5), {}, pinlin.ArgumentError,
                        "argument 'u': expected real numbers .inputs., got text"),
        "nan": ((ur5, q, nan_v, u), {}, pinlin.ArgumentError,
                r"argument 'v': row 3 has NaN or inf \(column 2\)"),
        "too_big": ((ur5, q, v, big_u), {}, pinlin.ArgumentError,
                    "argument 'u': row 1 has an entry of size 1e"),
        "denormalized": ((solo, denorm, vs, us), {}, pinlin.ArgumentError,
                         "argument 'q': row 2 is not normalized: the quaternion of joint "
                         "'root_joint'"),
        "t_order": ((ur5, q, v, u, [0.0, 0.1, 0.1, 0.2, 0.3]), {}, pinlin.ArgumentError,
                    r"argument 't': times must increase strictly: t\[2\]"),
        "t_size": ((ur5, q, v, u, [0.0, 0.1]), {}, pinlin.ArgumentError,
                   "argument 't': expected 5 times"),
        "workers": ((ur5, q, v, u), {"workers": 0}, pinlin.ArgumentError,
                    "argument 'workers'"),
        # An unbounded count would fork that many processes at once.
        "workers_many": ((ur5, q, v, u), {"workers": 10**9}, pinlin.ArgumentError,
                         "argument 'workers': expected at most"),
        "chunk": ((ur5, q, v, u), {"chunk": 2.5}, pinlin.ArgumentError, "argument 'chunk'"),
        "executor_type": ((ur5, q, v, u), {"executor": "dask"}, pinlin.ArgumentError,
                          "concurrent.futures.Executor"),
        "both": ((ur5, q, v, u), {"workers": 2, "executor": ThreadPoolExecutor(1)},
                 pinlin.ArgumentError, "not both"),
        "derivatives": ((ur5, q, v, u), {"derivatives": "fd7"}, pinlin.ArgumentError,
                        "argument 'derivatives'"),
        "step": ((ur5, q, v, u), {"step": 1e-4}, pinlin.ArgumentError,
                 "analytic derivatives take none"),
        "standing": (("standing_box", np.tile([0.0, 0, 0.5, 0, 0, 0, 1], (2, 1)),
                      np.zeros((2, 6)), np.zeros((2, 0))), {"derivatives": "fd5"},
                     pinlin.ModelError, "analytic derivatives only"),
        "scene": ((42, q, v, u), {}, pinlin.ArgumentError, "argument 'scene'"),
    }


BAD = _bad_cases()


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_arguments(case):
    args, kwargs, cls, words = BAD[case]
    with pytest.raises(cls, match=words):
        pinlin.linearize_trajectory(*args, **kwargs)


def test_the_memory_limit_holds_for_stacks():
    scene = pinlin.Scene.from_robot("ur5")
    q, v, u = states(scene, 400, seed=27)
    previous = pinlin.set_memory_limit("256K")
    try:
        with pytest.raises(pinlin.ResourceError, match="the models of 400 points"):
            pinlin.linearize_trajectory(scene, q, v, u)
    finally:
        pinlin.resources.restore_memory_limit(previous)


def test_at_refuses_a_bad_index():
    scene = pinlin.Scene.from_robot("ur5")
    traj = pinlin.linearize_trajectory(scene, *states(scene, 3, seed=23))
    for bad in (3, -4, 1.0, True):
        with pytest.raises(pinlin.ArgumentError, match="argument 'k'"):
            traj.at(bad)


# --------------------------------------------------------------------------------------------
# Command line


def _write_csv(path, scene, q, v, u, t=None, columns=None):
    qc, vc, uc = pinlin.trajectory_columns(scene.system)
    header = ([] if t is None else ["t"]) + qc + vc + uc
    rows = np.hstack(([] if t is None else [t[:, None]]) + [q, v, u])
    order = list(range(len(header)))[::-1]  # any column order
    lines = [",".join(header[i] if columns is None else columns[i] for i in order)]
    lines += [",".join(repr(float(r[i])) for i in order) for r in rows]
    path.write_text("# a trajectory\n" + "\n".join(lines) + "\n")


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_cli_reads_both_state_formats(suffix, tmp_path, capfd, monkeypatch):
    import pinlin.cli

    monkeypatch.setattr(pinlin.cli_motion, "PROGRESS_AFTER", 0.0)
    scene = pinlin.Scene.load(URDF_DIR / "ur5_arm.toml")
    q, v, u = states(scene, 600, seed=24)
    t = np.arange(600) * 0.002
    states_file = tmp_path / f"traj{suffix}"
    if suffix == ".npz":
        np.savez(states_file, q=q, v=v, u=u, t=t)
    else:
        _write_csv(states_file, scene, q, v, u, t)
    out = tmp_path / "models.mat"
    assert main(["trajectory", str(URDF_DIR / "ur5_arm.toml"), str(states_file), "--out",
                 str(out), "--workers", "2", "--dt", "0.002"]) == 0
    captured = capfd.readouterr()
    assert "600 points" in captured.out and "2 processes" in captured.out
    assert "600/600 points" in captured.err  # the progress bar
    back = pinlin.TrajectoryModel.load(out)
    ref = pinlin.linearize_trajectory(scene, q, v, u, t).discretize(0.002)
    np.testing.assert_array_equal(back.A, ref.A)
    np.testing.assert_array_equal(back.t, t)


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_cli_takes_states_without_inputs_for_a_scene_without_inputs(suffix, tmp_path, capfd):
    """A scene without inputs (a box balanced on its tip) has no u columns in a .csv; its
    .npz was refused for a missing 'u' unless it held an array of shape (N, 0). Both forms
    now read, and give what the API gives."""
    scene = pinlin.Scene.resolve("standing_box")
    q = np.tile(pinlin.operating_point(scene).q, (3, 1))
    v = 0.01 * np.arange(18.0).reshape(3, 6)
    states_file = tmp_path / f"traj{suffix}"
    if suffix == ".npz":
        np.savez(states_file, q=q, v=v)
    else:
        _write_csv(states_file, scene, q, v, np.zeros((3, 0)))
    out = tmp_path / "models.npz"
    code = main(["trajectory", "standing_box", str(states_file), "--out", str(out)])
    assert code == 0, capfd.readouterr().err
    ref = pinlin.linearize_trajectory(scene, q, v, np.zeros((3, 0)))
    np.testing.assert_array_equal(pinlin.TrajectoryModel.load(out).A, ref.A)


@pytest.mark.parametrize("edit, words", [
    (lambda h: h.replace("v:elbow_joint", "v:elbow"), "unknown column 'v:elbow' for scene "
                                                      "'ur5_arm'; did you mean 'v:elbow_joint'"),
    (lambda h: h.replace("u:wrist_1_joint,", ""), "missing column u:wrist_1_joint"),
])
def test_cli_refuses_bad_csv_headers(edit, words, tmp_path, capfd):
    scene = pinlin.Scene.load(URDF_DIR / "ur5_arm.toml")
    q, v, u = states(scene, 3, seed=25)
    path = tmp_path / "traj.csv"
    _write_csv(path, scene, q, v, u)
    lines = path.read_text().splitlines()
    header = edit(lines[1])
    if header.count(",") != lines[1].count(","):  # a column gone: drop its values too
        gone = lines[1].split(",").index("u:wrist_1_joint")
        lines[2:] = [",".join(c for i, c in enumerate(r.split(",")) if i != gone)
                     for r in lines[2:]]
    path.write_text("\n".join([lines[0], header, *lines[2:]]) + "\n")
    out = tmp_path / "m.npz"
    assert main(["trajectory", str(URDF_DIR / "ur5_arm.toml"), str(path), "--out",
                 str(out)]) == 2
    err = capfd.readouterr().err
    assert words in err and err.count("\n") == 1 and not out.exists()


@pytest.mark.parametrize("text, words", [
    ("", "empty"),
    ("q:a,q:b\n", "unknown column 'q:a'"),
    ("{header}\n1,2\n", "line 3: 2 values, the header names 18 columns"),
    ("{header}\n{bad}\n", "line 3, column 'q:shoulder_pan_joint': 'x' is not a number"),
    ("{header}\n{nan}\n", "line 3, column 'q:shoulder_pan_joint': 'nan' is not a finite "
                           "number"),
    ("{header}\n", "no data"),
    ("{header}\n{underscore}\n", "line 3, column 'q:shoulder_pan_joint': '1_0' is not a number"),
    # (float() read an Arabic-Indic three as 3.0 and a full-width zero as 0)
    ("{header}\n{arabic}\n", "line 3, column 'q:shoulder_pan_joint': '\u0663' is not a number"),
    # Values the file held, refused by the checks of linearize_trajectory: in the file's terms
    ("{header}\n{zero}\n\n{huge}\n", "line 5, column 'v:shoulder_lift_joint': point 1 has "
                                       "an entry of size 1e+300; velocities are limited"),
])
def test_cli_refuses_bad_csv_rows(text, words, tmp_path, capfd):
    qc, vc, uc = pinlin.trajectory_columns(pinlin.Scene.from_robot("ur5").system)
    header = ",".join(qc + vc + uc)
    bad = ",".join(["x"] + ["0"] * 17)
    nan = ",".join(["nan"] + ["0"] * 17)
    zero = ",".join(["0"] * 18)
    underscore = ",".join(["1_0"] + ["0"] * 17)
    arabic = ",".join(["\u0663"] + ["0"] * 17)
    huge = ",".join(["0"] * 7 + ["1e300"] + ["0"] * 10)
    path = tmp_path / "traj.csv"
    path.write_text("# comment\n" + text.format(header=header, bad=bad, nan=nan, zero=zero,
                                                 huge=huge, underscore=underscore,
                                                 arabic=arabic), encoding="utf-8")
    assert main(["trajectory", "ur5", str(path), "--out", str(tmp_path / "m.npz")]) == 2
    err = capfd.readouterr().err
    assert words in err and err.count("\n") == 1


@pytest.mark.parametrize("arrays, argv, words", [
    ({"q": np.zeros((2, 6)), "v": np.zeros((2, 6))}, [], "missing 'u'"),
    # (a t of shape (N, 1) was flattened, which linearize_trajectory itself refuses)
    ({"q": np.zeros((2, 6)), "v": np.zeros((2, 6)), "u": np.zeros((2, 6)),
      "t": np.zeros((2, 1))}, [], "member 't' must be a list of times (N,), got shape (2, 1)"),
    ({"q": np.zeros((2, 6)), "v": np.zeros((2, 6)), "u": np.zeros((2, 6)),
      "w": np.zeros(2)}, [], "unknown member 'w'"),
    ({"q": np.zeros((2, 5)), "v": np.zeros((2, 6)), "u": np.zeros((2, 6))}, [],
     "traj.npz: 'q' must have shape (N, 6)"),
    ({"q": np.full((2, 6), np.nan), "v": np.zeros((2, 6)), "u": np.zeros((2, 6))}, [],
     "traj.npz: q: row 0 has NaN or inf"),
    ({"q": np.zeros((2, 6)), "v": np.zeros((2, 6)), "u": np.zeros((2, 6))},
     ["--workers", "0"], "argument '--workers'"),
    ({"q": np.zeros((2, 6)), "v": np.zeros((2, 6)), "u": np.zeros((2, 6))},
     ["--discretization", "euler"], "argument '--discretization': applies with --dt"),
    ({"q": np.zeros((2, 6)), "v": np.zeros((2, 6)), "u": np.zeros((2, 6))},
     ["--dask", "tcp://x:1", "--workers", "2"], "leave out --workers"),
])
def test_cli_refuses_bad_state_files_and_options(arrays, argv, words, tmp_path, capfd):
    np.savez(tmp_path / "traj.npz", **arrays)
    out = tmp_path / "m.npz"
    assert main(["trajectory", "ur5", str(tmp_path / "traj.npz"), "--out", str(out),
                 *argv]) == 2
    err = capfd.readouterr().err
    assert words in err and err.count("\n") == 1 and not out.exists()


def test_cli_never_unpickles_a_state_file(tmp_path, capfd):
    objects = np.empty(2, dtype=object)
    np.savez(tmp_path / "traj.npz", q=objects, v=np.zeros((2, 6)), u=np.zeros((2, 6)))
    assert main(["trajectory", "ur5", str(tmp_path / "traj.npz"), "--out",
                 str(tmp_path / "m.npz")]) == 2
    assert "pickle" in capfd.readouterr().err


@pytest.mark.skipif(sys.platform != "linux", reason="shared segments live in /dev/shm")
def test_no_shared_segment_is_left_behind():
    from pathlib import Path

    before = set(Path(parallel.SHM_FOLDER).glob("pinlin-trajectory-*"))
    scene = pinlin.Scene.from_robot("ur5")
    pinlin.linearize_trajectory(scene, *states(scene, 40, seed=26), workers=2)
    assert set(Path(parallel.SHM_FOLDER).glob("pinlin-trajectory-*")) == before


def test_cli_names_the_csv_columns_of_an_unnormalized_quaternion(tmp_path, capfd):
    scene = pinlin.Scene.from_robot("solo12")
    qc, vc, uc = pinlin.trajectory_columns(scene.system)
    q = np.r_[0, 0, 0.3, 0, 0, 0, 1, np.zeros(12)]
    rows = [np.r_[q, np.zeros(len(vc) + len(uc))] for _ in range(2)]
    rows[1][3:7] *= 2.0
    path = tmp_path / "traj.csv"
    path.write_text(",".join(qc + vc + uc) + "\n"
                    + "\n".join(",".join(map(repr, map(float, r))) for r in rows) + "\n")
    assert main(["trajectory", "solo12", str(path), "--out", str(tmp_path / "m.npz")]) == 2
    err = capfd.readouterr().err
    assert ("line 3, columns 'q:root_joint[3]'-'q:root_joint[6]': point 1 is not normalized: "
            "the quaternion of joint 'root_joint' has norm 2") in err, err


def test_a_model_built_by_hand_with_times_out_of_order_is_refused():
    """What save writes, load reads: the constructor refuses the t that load refuses (before,
    such a model saved fine and then would not load)."""
    traj = pinlin.linearize_trajectory(pinlin.Scene.from_robot("ur5"),
                                       *states(pinlin.Scene.from_robot("ur5"), 2, seed=3))
    fields = {k: getattr(traj, k) for k in ("A", "B", "C", "D", "f0", "q", "v", "u", "a",
                                             "state_names", "input_names", "output_names")}
    with pytest.raises(pinlin.ArgumentError, match="times must increase strictly"):
        pinlin.TrajectoryModel(**fields, t=np.array([1.0, 0.5]))


def test_a_trajectory_too_large_to_copy_is_a_resource_error():
    """A broadcast view of 1e9 points (19 numbers each: 142 GiB as float64) raised numpy's
    MemoryError from the copy; the copy's size is now checked against the memory limit first."""
    import pinocchio as pin

    scene = pinlin.Scene.from_robot("solo12")
    q = np.broadcast_to(pin.neutral(scene.system.model), (10**9, scene.system.nq))
    with pytest.raises(pinlin.ResourceError, match=r"argument 'q' .* shape \(1000000000, 19\)"):
        pinlin.linearize_trajectory(scene, q)


def test_states_archive_with_a_member_twice_is_refused(tmp_path, capfd):
    """zip allows a name twice; the last q was taken silently."""
    import io
    import warnings
    import zipfile

    path = tmp_path / "traj.npz"
    np.savez(path, q=np.zeros((2, 6)), v=np.zeros((2, 6)), u=np.zeros((2, 6)))
    buf = io.BytesIO()
    np.save(buf, np.ones((2, 6)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)     # zipfile: "Duplicate name"
        with zipfile.ZipFile(path, "a") as z:
            z.writestr("q.npy", buf.getvalue())
    assert main(["trajectory", "ur5", str(path), "--out", str(tmp_path / "m.npz")]) == 2
    assert "member 'q' appears twice" in capfd.readouterr().err


def test_an_executor_already_shut_down_is_an_argument_error():
    """concurrent.futures raises RuntimeError on submit after shutdown; it came through raw."""
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(1)
    pool.shutdown()
    with pytest.raises(pinlin.ArgumentError, match="argument 'executor': cannot take work"):
        pinlin.linearize_trajectory("pendulum", np.zeros((3, 1)), np.zeros((3, 1)),
                                    np.zeros((3, 1)), executor=pool)


def test_dask_address_of_another_service(tmp_path, capfd):
    """An address where something else answers (an ssh banner, read by Dask as a frame length
    of 2.8 EiB) ended in numpy's MemoryError traceback."""
    import socket
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(5)
    port = server.getsockname()[1]

    def serve():
        try:
            while True:
                conn, _ = server.accept()
                conn.sendall(b"SSH-2.0-OpenSSH_9.6 banner text here\r\n")
                conn.close()
        except OSError:
            pass

    threading.Thread(target=serve, daemon=True).start()
    scene = pinlin.Scene.from_robot("ur5")
    q, v, u = states(scene, 3, seed=18)
    np.savez(tmp_path / "traj.npz", q=q, v=v, u=u)
    try:
        code = main(["trajectory", "ur5", str(tmp_path / "traj.npz"), "--dask",
                     f"tcp://127.0.0.1:{port}", "--out", str(tmp_path / "m.npz")])
    finally:
        server.close()
    err = capfd.readouterr().err
    assert code == 2 and "argument '--dask'" in err and "Traceback" not in err, err
    assert not (tmp_path / "m.npz").exists()


_SINGULAR = """<robot name="sing">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0 0 0"/><mass value="0"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0 0 1"/><mass value="1"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
</robot>
"""

#: A point mass on two parallel joints 0.5 m apart: at q2 = 0 both move it along one line
#: (M singular); near it M is nearly so, in any units (its condition scaled to unit
#: diagonal ~ 8e-2 / q2^2).
_COLLINEAR = """<robot name="collinear">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0 0 0"/><mass value="0"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><axis xyz="0 0 1"/>
    <origin xyz="0.5 0 0"/><limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
</robot>
"""


@pytest.mark.parametrize("workers", [1, 2])
def test_an_ill_conditioned_point_warns_as_the_single_call(tmp_path, workers):
    """A point mass on two parallel joints 0.5 m apart: where q2 = 0 both move it along the
    same line and M is singular. At q2 = 1e-5 and 1e-6 the single call warns (M scaled to
    unit diagonal: condition estimate 8e10, 8e12); the trajectory returned the same models
    without a word."""
    (tmp_path / "sing.urdf").write_text(_COLLINEAR)
    scene = pinlin.Scene.from_urdf(tmp_path / "sing.urdf")
    for q2 in (1e-5, 1e-6):
        q = np.array([[0.0, 0.5], [0.0, q2]])
        with pytest.warns(pinlin.AccuracyWarning, match="the mass matrix has condition"):
            single = pinlin.linearize(scene, q=q[1], v=np.zeros(2), u=np.zeros(2))
        with pytest.warns(pinlin.AccuracyWarning, match="the mass matrix at trajectory point 1 "
                                                        "has condition"):
            traj = pinlin.linearize_trajectory(scene, q, np.zeros((2, 2)), np.zeros((2, 2)),
                                               workers=workers)
        np.testing.assert_array_equal(traj.A[1], single.A)
    with warnings.catch_warnings():   # a well-conditioned point: no warning
        warnings.simplefilter("error", pinlin.AccuracyWarning)
        pinlin.linearize_trajectory(scene, np.array([[0.0, 0.5]]), np.zeros((1, 2)),
                                    np.zeros((1, 2)))


def test_trajectory_zoh_beyond_one_block_is_van_loans_exponential_at_every_point():
    """The stacked ZOH runs in blocks of 128 points: points 126-129 (both sides of the
    first block's end) against scipy's expm of the augmented [[A, B, f0], [0]] dt."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    N, nv = 130, scene.system.nv
    rng = np.random.default_rng(0)
    q0 = pinlin.linearize(scene).operating_point.q
    Q = q0 + rng.uniform(-0.5, 0.5, (N, q0.size))
    V = rng.uniform(-1.0, 1.0, (N, nv))
    U = rng.uniform(-1.0, 1.0, (N, len(scene.system.actuated)))
    traj = pinlin.linearize_trajectory(scene, Q, V, U)
    dt = 0.01
    disc = traj.discretize(dt)
    n, m = traj.B.shape[1:]
    for k in (0, 126, 127, 128, 129):
        aug = np.zeros((n + m + 1, n + m + 1))
        aug[:n, :n], aug[:n, n:n + m], aug[:n, -1] = traj.A[k], traj.B[k], traj.f0[k]
        phi = sla.expm(aug * dt)
        np.testing.assert_allclose(disc.A[k], phi[:n, :n], rtol=0, atol=1e-13)
        np.testing.assert_allclose(disc.B[k], phi[:n, n:n + m], rtol=0, atol=1e-13)
        np.testing.assert_allclose(disc.f0[k], phi[:n, -1], rtol=0, atol=1e-13)
