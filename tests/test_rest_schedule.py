"""Gain schedules: ``linearize_trajectory(scene, q)`` without v and u linearizes every point at
rest with its holding inputs solved (pinlin.rest_schedule). Each point must be the single static
model ``linearize(scene, q=q[k])``, a second formulation (reduced second-order model, RNEA
derivatives) against the batch's (ABA derivatives, KKT solves at a given state); the inputs
must be what Pinocchio's own generalized gravity says; points that cannot be held are refused,
naming them."""

from __future__ import annotations

import tomllib

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR
from test_trajectory_loops import kkt_condition

import pinlin
from pinlin.exceptions import ArgumentError, EquilibriumError

EPS = np.finfo(float).eps


def schedule(scene: pinlin.Scene, N: int, span: float, seed: int) -> np.ndarray:
    """N configurations: the scene's, each independent coordinate swept by span*sin [rad] with
    a random phase, the others left at the scene's values (so a mechanism's points need
    assembling)."""
    system = scene.system
    rest = pinlin.linearize(scene)
    z = [system.coordinate_names.index(c) for c in rest.info.get("independent",
                                                                  system.coordinate_names)]
    idx_q = [system.model.joints[system.model.getJointId(system.coordinate_names[i])].idx_q
             for i in z]
    rng = np.random.default_rng(seed)
    Q = np.tile(rest.operating_point.q, (N, 1))
    phase = rng.uniform(0, 2 * np.pi, len(z))
    s = np.linspace(0.0, 1.0, N)
    Q[:, idx_q] += span * (np.sin(2 * np.pi * s[:, None] + phase) - np.sin(phase))
    return Q


def scene_file(name: str, **changes) -> pinlin.Scene:
    path = URDF_DIR / f"{name}.toml"
    data = tomllib.loads(path.read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    data.update(changes)
    return pinlin.Scene.from_dict(data)


@pytest.mark.parametrize("name, seed", [("four_bar", 0), ("slider_crank", 1), ("delta", 2),
                                        ("five_bar", 3)])
def test_each_mechanism_point_is_the_single_static_model(name, seed):
    """Point k against ``linearize(scene, q=traj.q[k])`` (the static path: Newton finds nothing
    to correct at an assembled q, the least-norm statics, R^T (K - lam Phi_qq) R). Two
    backward-stable computations of the same model: each is exact to ~n eps kappa relative
    (kappa of the point's KKT matrix, which bounds those of Phi_d and of the reduced mass
    matrix), so they agree to twice that. The holding inputs are checked against the
    statics written out here: S u0 + G^T lam = g - tau_spring (Pinocchio's gravity)."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    system = scene.system
    N = 10
    traj = pinlin.linearize_trajectory(scene, schedule(scene, N, 0.4, seed))
    assert traj.info["at_rest"] is True
    rows = [system.constraints.row_names.index(r) for r in traj.info["constraint_rows"]]
    np.testing.assert_array_equal(traj.v, 0.0)
    np.testing.assert_array_equal(traj.a, 0.0)
    np.testing.assert_array_equal(traj.f0, 0.0)
    for k in range(N):
        single = pinlin.linearize(scene, q=traj.q[k])
        assert single.state_names == traj.state_names
        n = 2 * system.nv + len(rows)
        tol = 2 * n * EPS * kkt_condition(system, traj.q[k], rows)
        for key in ("A", "B", "C"):
            ours, ref = getattr(traj, key)[k], getattr(single, key)
            np.testing.assert_allclose(ours, ref, rtol=0, atol=tol * max(np.abs(ref).max(), 1))
        op = single.operating_point
        np.testing.assert_allclose(traj.u[k], op.u, rtol=0, atol=tol * np.abs(op.u).max())
        np.testing.assert_allclose(traj.lam[k], op.lam, rtol=0,
                                   atol=tol * np.abs(op.lam).max())
        # the statics, from Pinocchio directly
        q = traj.q[k]
        g = pin.computeGeneralizedGravity(system.model, system.model.createData(), q)
        held = g - system.spring_torque(q) if system.has_springs else g
        G = system.constraints.jacobian(q)
        force = system.input_matrix @ traj.u[k] + G.T @ traj.lam[k]
        np.testing.assert_allclose(force, held, rtol=0, atol=tol * np.abs(g).max())
        at = traj.at(k)
        assert at.operating_point.equilibrium and at.f0 is None
        assert "schedule of rest points" in at.operating_point.notes[0]


def test_a_mechanism_schedule_stays_on_its_branch():
    """A full turn of the four-bar's crank from the scene's (open) assembly: every point is
    assembled from the one before, so the coupler never jumps to the crossed branch (the
    rocker angle moves continuously: no step larger than a few times the crank's)."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    system = scene.system
    q0 = pinlin.linearize(scene).operating_point.q
    crank = system.model.joints[system.model.getJointId("crank")].idx_q
    rocker = system.model.joints[system.model.getJointId("rocker")].idx_q
    N = 73
    Q = np.tile(q0, (N, 1))
    Q[:, crank] += np.linspace(0.0, 2 * np.pi, N)
    traj = pinlin.linearize_trajectory(scene, Q)
    step = np.diff(traj.q[:, rocker])
    assert np.abs(step).max() < 3 * (2 * np.pi / (N - 1))
    dependent = [i for i in range(system.nq) if i != crank]  # back where it began
    np.testing.assert_allclose(traj.q[-1, dependent], traj.q[0, dependent], rtol=0, atol=1e-9)
    # The sweep can tell: single calls assembled from these guesses land on the crossed
    # branch at some crank angles (their rocker angle differs beyond a multiple of 2 pi).
    flipped = 0
    for k in range(2, N, 4):
        q = pinlin.operating_point(scene, q=Q[k]).q
        wrapped = (q[rocker] - traj.q[k, rocker] + np.pi) % (2 * np.pi) - np.pi
        flipped += abs(wrapped) > 1e-6
    assert flipped > 0


def test_open_chain_schedule_holds_with_gravity_and_matches_single_calls():
    """ur5 (every joint actuated): u0 is Pinocchio's generalized gravity at each point, and
    point k equals ``linearize(scene, q=q[k])`` (RNEA derivatives and M^-1 there, ABA
    derivatives here: equal to ~nv eps kappa(M) relative)."""
    scene = pinlin.Scene.from_robot("ur5")
    system = scene.system
    rng = np.random.default_rng(4)
    N = 8
    Q = np.array([pin.randomConfiguration(system.model) for _ in range(N)])
    Q[:, :] = np.clip(Q, -3.0, 3.0) + 0.0 * rng.normal(size=Q.shape)
    traj = pinlin.linearize_trajectory(scene, Q)
    data = system.model.createData()
    for k in range(N):
        g = pin.computeGeneralizedGravity(system.model, data, Q[k])
        np.testing.assert_allclose(traj.u[k], g, rtol=0, atol=8 * EPS * np.abs(g).max())
        single = pinlin.linearize(scene, q=Q[k])
        M = pin.crba(system.model, data, Q[k])
        tol = 4 * system.nv * EPS * np.linalg.cond(np.triu(M) + np.triu(M, 1).T)
        for key in ("A", "B"):
            ref = getattr(single, key)
            np.testing.assert_allclose(getattr(traj, key)[k], ref, rtol=0,
                                       atol=tol * np.abs(ref).max())
    np.testing.assert_array_equal(traj.a, 0.0)


def test_a_floating_base_is_refused_or_falls_when_allowed():
    """solo12 on a free base cannot be held by its joints: the schedule names point 0; opted
    in, each point's acceleration is Pinocchio's forward dynamics at (q, 0, S u0) and its
    model is the single call's."""
    scene = pinlin.Scene.from_robot("solo12")
    system = scene.system
    q0 = pinlin.operating_point(scene, allow_non_equilibrium=True).q
    Q = np.tile(q0, (3, 1))
    legs = slice(7, None)
    Q[:, legs] += np.linspace(0.0, 0.3, 3)[:, None]
    with pytest.raises(EquilibriumError, match="trajectory point 0: .*not an equilibrium"):
        pinlin.linearize_trajectory(scene, Q)
    traj = pinlin.linearize_trajectory(scene, Q, allow_non_equilibrium=True)
    assert traj.info["non_equilibrium_points"] == [0, 1, 2]
    data = system.model.createData()
    for k in range(3):
        tau = np.zeros(system.nv)
        tau[system.actuated] = traj.u[k]
        a = pin.aba(system.model, data, Q[k], np.zeros(system.nv), tau)
        np.testing.assert_allclose(traj.a[k], a, rtol=0, atol=64 * EPS * np.abs(a).max())
        single = pinlin.linearize(scene, q=Q[k], allow_non_equilibrium=True)
        np.testing.assert_allclose(traj.A[k], single.A, rtol=0,
                                   atol=1e-10 * np.abs(single.A).max())


def test_a_mechanism_that_cannot_be_held_is_refused_naming_the_point():
    """The four-bar without its motor: the loop forces alone cannot hold the coupler."""
    scene = scene_file("four_bar", inputs={"actuated": []})
    Q = schedule(pinlin.Scene.load(URDF_DIR / "four_bar.toml"), 4, 0.3, 5)
    with pytest.raises(EquilibriumError, match="trajectory point 0: scene 'four_bar': q is not "
                                               "an equilibrium.*along 'coupler'"):
        pinlin.linearize_trajectory(scene, Q)


def test_workers_give_the_same_schedule():
    scene = pinlin.Scene.load(URDF_DIR / "delta.toml")
    Q = schedule(scene, 40, 0.3, 6)
    one = pinlin.linearize_trajectory(scene, Q)
    two = pinlin.linearize_trajectory(scene, Q, workers=2, chunk=10)
    for key in ("A", "B", "C", "u", "lam", "q", "f0"):
        np.testing.assert_array_equal(getattr(two, key), getattr(one, key))


def test_a_saved_schedule_keeps_its_points_at_rest(tmp_path):
    scene = pinlin.Scene.load(URDF_DIR / "slider_crank.toml")
    traj = pinlin.linearize_trajectory(scene, schedule(scene, 5, 0.3, 7))
    back = pinlin.TrajectoryModel.load(traj.save(tmp_path / "schedule.npz"))
    assert back.info["at_rest"] is True
    assert back.at(2).operating_point.equilibrium and back.at(2).f0 is None
    np.testing.assert_array_equal(back.at(2).A, traj.at(2).A)


@pytest.mark.parametrize("kwargs, argument, words", [
    ({"v": np.zeros((3, 6))}, "u", "give both v and u"),
    ({"u": np.zeros((3, 6))}, "v", "give both v and u"),
    ({"v": np.zeros((3, 6)), "u": np.zeros((3, 6)), "allow_non_equilibrium": True},
     "allow_non_equilibrium", "applies to a schedule of rest points"),
    ({"allow_non_equilibrium": "yes"}, "allow_non_equilibrium", "expected True or False"),
])
def test_bad_schedule_arguments_are_refused(kwargs, argument, words):
    scene = pinlin.Scene.from_robot("ur5")
    Q = np.tile(pin.neutral(scene.system.model), (3, 1))
    with pytest.raises(ArgumentError, match=words) as info:
        pinlin.linearize_trajectory(scene, Q, **kwargs)
    assert info.value.argument == argument


def test_a_schedule_needs_a_scene_that_solves_its_inputs():
    scene = scene_file("four_bar", operating_point={
        "q": {"crank": 1.0, "coupler": -0.6, "rocker": 1.6}, "independent": ["crank"],
        "solve": "forces", "u": {"crank": 0.5}})
    Q = np.tile(pinlin.operating_point(pinlin.Scene.load(URDF_DIR / "four_bar.toml")).q, (2, 1))
    with pytest.raises(ArgumentError, match='solve = "forces".*give v and u'):
        pinlin.linearize_trajectory(scene, Q)


# --------------------------------------------------------------------------------------------
# Command line: a state file with configurations alone is a schedule of rest points


def test_cli_writes_the_schedule_of_an_npz_of_configurations(tmp_path, capfd):
    from pinlin.cli import main

    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    Q = schedule(scene, 12, 0.4, 8)
    np.savez(tmp_path / "poses.npz", q=Q)
    out = tmp_path / "schedule.npz"
    assert main(["trajectory", "four_bar", str(tmp_path / "poses.npz"), "--out", str(out),
                 "--no-progress"]) == 0
    assert "schedule of rest points of 'four_bar': 12 points" in capfd.readouterr().out
    back = pinlin.TrajectoryModel.load(out)
    ref = pinlin.linearize_trajectory(scene, Q)
    for key in ("A", "B", "u", "q", "lam"):
        np.testing.assert_array_equal(getattr(back, key), getattr(ref, key))


def test_cli_reads_a_csv_of_configurations_and_opts_in_to_falling_points(tmp_path, capfd):
    from pinlin.cli import main

    scene = pinlin.Scene.from_robot("solo12")
    q0 = pinlin.operating_point(scene, allow_non_equilibrium=True).q
    Q = np.tile(q0, (4, 1))
    Q[:, 8] += np.linspace(0.0, 0.3, 4)
    columns = pinlin.trajectory_columns(scene.system)[0]
    path = tmp_path / "poses.csv"
    path.write_text(",".join(columns) + "\n" + "\n".join(",".join(repr(float(x)) for x in row)
                                                         for row in Q) + "\n")
    out = tmp_path / "falling.npz"
    assert main(["trajectory", "solo12", str(path), "--out", str(out), "--no-progress"]) == 2
    err = capfd.readouterr().err
    assert "trajectory point 0: scene 'solo12': q is not an equilibrium" in err
    assert err.count("\n") == 1 and not out.exists()
    assert main(["trajectory", "solo12", str(path), "--out", str(out), "--no-progress",
                 "--allow-non-equilibrium"]) == 0
    back = pinlin.TrajectoryModel.load(out)
    ref = pinlin.linearize_trajectory(scene, Q, allow_non_equilibrium=True)
    np.testing.assert_array_equal(back.A, ref.A)
    assert back.info["non_equilibrium_points"] == [0, 1, 2, 3]


def test_cli_refuses_the_opt_in_for_given_states(tmp_path, capfd):
    from pinlin.cli import main

    np.savez(tmp_path / "traj.npz", q=np.zeros((2, 6)), v=np.zeros((2, 6)),
             u=np.zeros((2, 6)))
    out = tmp_path / "m.npz"
    assert main(["trajectory", "ur5", str(tmp_path / "traj.npz"), "--out", str(out),
                 "--allow-non-equilibrium"]) == 2
    err = capfd.readouterr().err
    assert "argument '--allow-non-equilibrium': applies to a schedule of rest points" in err
    assert err.count("\n") == 1 and not out.exists()
