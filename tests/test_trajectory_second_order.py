"""Second-order matrices along a trajectory: ``linearize_trajectory(..., second_order=True)``.

Reference: ``pinlin.linearize(scene, q=q[k], v=v[k], u=u[k])``, whose M, C_damp, K come from
``pin.computeRNEADerivatives`` at (q, v, a0 = M^-1 tau) and whose Bu is S. The batch takes
M, K and C_damp from ``computeRNEADerivatives`` at (q, v, ddq), ddq from ``pin.aba`` (no
product M A is formed). a0 and ddq agree to rounding, and so do the terms built on them.
The terms of K include the inertial forces of
the acceleration, dM/dq a (about |M| |a|; |a| reaches 9e3 rad/s^2 at these random states
with springs), those of C_damp the Coriolis terms (about |M| |v|), those of M are at most
|M|: the tolerance is nv eps (max|K| + max|M| max|a|) for K, nv eps (max|C_damp| + max|M|
max|v|) for C_damp and nv eps max|M| for M (observed: below 1.3e-12 absolute on ur5_arm,
whose K reaches 830 N*m/rad; Talos below 1e-12 against a bound of 2e-9). Bu is the same
array.

Also: the stacks through worker processes and files, their refusal on a mechanism, and the
progress of a mechanism's serial assembly pass.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from conftest import URDF_DIR
from test_trajectory import SCENES, states
from test_trajectory_loops import sweep

import pinlin
from pinlin.cli import main

EPS = np.finfo(float).eps
SECOND = ("M", "C_damp", "K", "Bu")


def _assert_second_order(got: pinlin.LinearModel, ref: pinlin.LinearModel) -> None:
    """The tolerance of the module docstring, per matrix."""
    nv = ref.M.shape[0]
    op = ref.operating_point
    m = np.abs(ref.M).max()
    scale = {"M": m, "K": np.abs(ref.K).max() + m * np.abs(op.a).max(),
             "C_damp": np.abs(ref.C_damp).max() + m * np.abs(op.v).max()}
    for key, size in scale.items():
        a, b = getattr(got, key), getattr(ref, key)
        assert a is not None and a.shape == b.shape, key
        np.testing.assert_allclose(a, b, rtol=0, atol=nv * EPS * size, err_msg=key)
    np.testing.assert_array_equal(got.Bu, ref.Bu)
    assert np.array_equal(got.M, got.M.T)  # mirrored exactly: symmetric M


@pytest.mark.parametrize("name, path", [("ur5", "batch"), ("talos", "batch"),
                                        ("ur5_arm", "batch"), ("rotating", "per point")])
def test_each_point_carries_the_second_order_matrices_of_linearize(name, path):
    """Random moving states (Talos: floating base, rotated), one point at rest, where C_damp
    is exactly zero without damping as a single model's is; springs and damping (ur5_arm)."""
    scene = SCENES[name]()
    q, v, u = states(scene, 5, seed=31 + len(name))
    v[3] = 0.0
    traj = pinlin.linearize_trajectory(scene, q, v, u, second_order=True)
    assert traj.info["path"] == path
    nv, nu = scene.system.nv, len(scene.system.actuated)
    assert traj.M.shape == traj.K.shape == traj.C_damp.shape == (5, nv, nv)
    assert traj.Bu.shape == (5, nv, nu) and traj.Bu.strides[0] == 0  # one matrix
    for k in range(5):
        got, ref = traj.at(k), pinlin.linearize(scene, q=q[k], v=v[k], u=u[k])
        _assert_second_order(got, ref)
        np.testing.assert_allclose(got.A, ref.A, rtol=0, atol=1e-12 * np.abs(ref.A).max())
    if not scene.system.has_damping and path == "batch":
        assert not traj.C_damp[3].any() and traj.C_damp[2].any()
    for key in ("M", "C_damp", "K", "Bu"):
        with pytest.raises(ValueError):
            getattr(traj, key)[0, 0, 0] = 1.0


def test_numerical_derivatives_copy_the_single_models():
    scene = pinlin.Scene.from_robot("ur5")
    q, v, u = states(scene, 2, seed=32)
    traj = pinlin.linearize_trajectory(scene, q, v, u, derivatives="fd3", second_order=True)
    for k in range(2):
        ref = pinlin.linearize(scene, q=q[k], v=v[k], u=u[k], derivatives="fd3")
        for key in SECOND:
            np.testing.assert_array_equal(getattr(traj.at(k), key), getattr(ref, key))


def test_the_default_path_is_unchanged():
    scene = pinlin.Scene.from_robot("talos")
    q, v, u = states(scene, 40, seed=33)
    plain = pinlin.linearize_trajectory(scene, q, v, u)
    full = pinlin.linearize_trajectory(scene, q, v, u, second_order=True)
    for key in ("A", "B", "f0", "a"):
        np.testing.assert_array_equal(getattr(full, key), getattr(plain, key), err_msg=key)
    assert all(getattr(plain, key) is None for key in SECOND)
    assert all(getattr(plain.at(3), key) is None for key in SECOND)
    discrete = full.discretize(0.01)  # second order describes the continuous model
    assert all(getattr(discrete, key) is None for key in SECOND)
    assert discrete.at(0).M is None


@pytest.mark.parametrize("name", ["talos", "ur5_arm"])
def test_worker_processes_and_executors_give_the_serial_stacks(name):
    scene = SCENES[name]()
    q, v, u = states(scene, 90, seed=34)
    serial = pinlin.linearize_trajectory(scene, q, v, u, second_order=True)
    shared = pinlin.linearize_trajectory(scene, q, v, u, workers=2, chunk=13,
                                         second_order=True)
    with ThreadPoolExecutor(max_workers=2) as executor:
        threaded = pinlin.linearize_trajectory(scene, q, v, u, executor=executor, chunk=11,
                                               second_order=True)
    for other in (shared, threaded):
        for key in ("A", "B", "f0", *SECOND):
            np.testing.assert_array_equal(getattr(other, key), getattr(serial, key),
                                          err_msg=key)


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
@pytest.mark.parametrize("scene_file, N", [("ur5_arm.toml", 6), ("pendulum.toml", 4),
                                           ("ur5_arm.toml", 1)])
def test_second_order_stacks_round_trip(suffix, scene_file, N, tmp_path):
    """Also nv = 1 (M is N x 1 x 1) and a single point, where MATLAB's shapes are tested."""
    scene = pinlin.Scene.load(URDF_DIR / scene_file)
    q, v, u = states(scene, N, seed=35)
    traj = pinlin.linearize_trajectory(scene, q, v, u, t=np.arange(N) * 0.1,
                                       second_order=True)
    back = pinlin.TrajectoryModel.load(traj.save(tmp_path / f"m{suffix}"))
    for key in ("A", "B", "f0", *SECOND):
        np.testing.assert_array_equal(getattr(back, key), getattr(traj, key), err_msg=key)
    if N > 1:
        assert back.Bu.strides[0] == 0  # stored once, broadcast again
    _assert_second_order(back.at(N - 1), traj.at(N - 1))
    plain = pinlin.linearize_trajectory(scene, q, v, u)
    assert pinlin.TrajectoryModel.load(plain.save(tmp_path / f"p{suffix}")).M is None


def test_second_order_matrices_come_together():
    scene = pinlin.Scene.from_robot("ur5")
    traj = pinlin.linearize_trajectory(scene, *states(scene, 3, seed=36), second_order=True)
    fields = {k: getattr(traj, k) for k in ("A", "B", "C", "D", "f0", "q", "v", "u", "a")}
    names = {k: getattr(traj, k) for k in ("state_names", "input_names", "output_names")}
    with pytest.raises(pinlin.ArgumentError, match="give all four or none"):
        pinlin.TrajectoryModel(**fields, **names, M=traj.M)
    with pytest.raises(pinlin.ShapeError, match=r"K must have shape \(3, 6, 6\)"):
        pinlin.TrajectoryModel(**fields, **names, M=traj.M, C_damp=traj.C_damp, K=traj.K[:, :5],
                               Bu=traj.Bu)


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_a_file_whose_second_order_matrices_disagree_with_a_is_refused(suffix, tmp_path):
    """pinlin.modal reads M, K and C_damp in place of A: a trajectory file whose K was
    changed (x3 at the last point) loaded, and modal gave that point other eigenvalues than
    A has (4.96 and 11.7 against 2.86 and 6.78 rad/s), while the single model saved from it
    was refused by LinearModel.load. The same check now runs at every point."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    traj = pinlin.linearize_trajectory(scene, np.array([[0.1, 0.2], [0.3, 0.1]]),
                                       second_order=True)
    path = traj.save(tmp_path / f"good{suffix}")
    assert pinlin.TrajectoryModel.load(path).K is not None
    fields = {k: getattr(traj, k) for k in ("A", "B", "C", "D", "f0", "q", "v", "u", "a",
                                            "state_names", "input_names", "output_names",
                                            *SECOND)}
    K = np.array(traj.K)
    K[1] *= 3.0
    with pytest.raises(pinlin.ModelError, match=r"point 1 of 2: .*second-order matrices "
                                                r"describe other dynamics.*M A\[nv:, :nv\] \+ K"):
        pinlin.TrajectoryModel(**{**fields, "K": K})
    bad = pinlin.TrajectoryModel.trusted(**{**traj.__dict__, "K": K})
    with pytest.raises(pinlin.ModelFileError, match=r"bad\.\w+: inconsistent trajectory "
                                                    r"model: point 1 of 2: "):
        pinlin.TrajectoryModel.load(bad.save(tmp_path / f"bad{suffix}"))


def test_a_drift_at_a_point_at_rest_is_refused(tmp_path):
    """At a point at rest (v = 0, a = 0) TrajectoryModel.at gives an equilibrium, without
    f0: a drift there in a file (edited by hand) was dropped, and the response from that
    point stayed at 0 where f0 = 5 rad/s^2 moves it."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    traj = pinlin.linearize_trajectory(scene, np.array([[0.1, 0.2], [0.3, 0.1]]))
    assert not np.any(traj.f0) and traj.at(0).f0 is None
    f0 = np.array(traj.f0)
    f0[:, 3] = 5.0
    bad = pinlin.TrajectoryModel.trusted(**{**traj.__dict__, "f0": f0})
    with pytest.raises(pinlin.ModelFileError, match=r"argument 'f0': point 0 is at rest .*"
                                                    r"\(max \|f0\| = 5, 2 such point"):
        pinlin.TrajectoryModel.load(bad.save(tmp_path / "bad.npz"))
    # A moving point keeps its drift (x' = f0 + A x + B u).
    moving = pinlin.linearize_trajectory(scene, np.array([[0.1, 0.2]]), np.array([[0.5, 0.0]]),
                                         np.zeros((1, 2)))
    back = pinlin.TrajectoryModel.load(moving.save(tmp_path / "moving.npz"))
    np.testing.assert_array_equal(back.at(0).f0, moving.f0[0])


def test_mechanisms_refuse_second_order():
    """A single model of a mechanism at a moving state has no M, C_damp, K, Bu."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    Q, V, U, _ = sweep(scene, 3, seed=37)
    single = pinlin.linearize(scene, q=Q[0], v=V[0], u=U[0])
    assert single.M is None and single.K is None
    with pytest.raises(pinlin.ArgumentError,
                       match="second_order.*has constraints.*gives no M") as exc:
        pinlin.linearize_trajectory(scene, Q, V, U, second_order=True)
    assert exc.value.argument == "second_order"
    with pytest.raises(pinlin.ArgumentError, match="expected True or False"):
        pinlin.linearize_trajectory(pinlin.Scene.from_robot("ur5"), np.zeros((1, 6)),
                                    np.zeros((1, 6)), np.zeros((1, 6)), second_order="yes")


@pytest.mark.parametrize("name, workers", [("four_bar", 1), ("four_bar", 2), ("delta", 1)])
def test_progress_reports_the_assembly_pass_of_a_mechanism(name, workers):
    """2N steps: the N points assembled (serial, in this process), then the N linearized."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    N = 600
    Q, V, U, _ = sweep(scene, N, seed=38)
    seen: list[tuple[int, int]] = []
    pinlin.linearize_trajectory(scene, Q, V, U, workers=workers,
                                progress=lambda done, total: seen.append((done, total)))
    done = [d for d, _ in seen]
    assert {t for _, t in seen} == {2 * N} and done == sorted(done) and done[-1] == 2 * N
    assert [d for d in done if d <= N][:3] == [256, 512, N]  # during the assembly pass


def test_cli_second_order(tmp_path, capfd):
    scene = pinlin.Scene.load(URDF_DIR / "ur5_arm.toml")
    q, v, u = states(scene, 20, seed=39)
    np.savez(tmp_path / "traj.npz", q=q, v=v, u=u)
    out = tmp_path / "models.npz"
    target = str(URDF_DIR / "ur5_arm.toml")
    assert main(["trajectory", target, str(tmp_path / "traj.npz"), "--out", str(out),
                 "--second-order"]) == 0
    assert "M, C_damp, K, Bu stored" in capfd.readouterr().out
    ref = pinlin.linearize_trajectory(scene, q, v, u, second_order=True)
    back = pinlin.TrajectoryModel.load(out)
    for key in SECOND:
        np.testing.assert_array_equal(getattr(back, key), getattr(ref, key))
    assert main(["trajectory", target, str(tmp_path / "traj.npz"), "--out", str(out),
                 "--second-order", "--dt", "0.01"]) != 0
    assert "--second-order" in capfd.readouterr().err
    loops = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    Q, V, U, _ = sweep(loops, 3, seed=40)
    np.savez(tmp_path / "loops.npz", q=Q, v=V, u=U)
    assert main(["trajectory", str(URDF_DIR / "four_bar.toml"), str(tmp_path / "loops.npz"),
                 "--out", str(out), "--second-order"]) != 0
    assert "argument '--second-order': scene 'four_bar' has constraints" in \
        capfd.readouterr().err
