"""Gain schedules: ``linearize_trajectory(scene, q)`` without v and u linearizes every point at
rest with its holding inputs solved (pinlin.rest_schedule). Each point must be the single static
model ``linearize(scene, q=q[k])``, a second formulation (reduced second-order model, RNEA
derivatives) against the batch's (ABA derivatives, KKT solves at a given state); the inputs
must be what Pinocchio's own generalized gravity says; points that cannot be held are refused,
naming them."""

from __future__ import annotations

import tomllib
import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR
from test_trajectory_loops import kkt_condition

import pinlin
from pinlin.exceptions import ArgumentError, EquilibriumError, SceneError

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
    """ur5 (every joint actuated): u0 is the torque that holds each posture, here from
    Pinocchio's RNEA at rest (another recursion than the generalized gravity pinlin calls:
    each sums at most nv body terms, so they differ by a few nv eps times the largest joint
    torque, bounded by nv^2 eps max|g|), and point k equals ``linearize(scene, q=q[k])``
    (RNEA derivatives and M^-1 there, ABA derivatives here: equal to ~nv eps kappa(M)
    relative)."""
    scene = pinlin.Scene.from_robot("ur5")
    system = scene.system
    rng = np.random.default_rng(4)
    N = 8
    Q = rng.uniform(-3.0, 3.0, (N, system.nq))
    traj = pinlin.linearize_trajectory(scene, Q)
    data = system.model.createData()
    zero = np.zeros(system.nv)
    for k in range(N):
        g = pin.rnea(system.model, data, Q[k], zero, zero)
        np.testing.assert_allclose(traj.u[k], g, rtol=0,
                                   atol=system.nv ** 2 * EPS * np.abs(g).max())
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
        # pin.aba and the ABA derivatives' forward dynamics: both backward stable, so they
        # agree to ~nv eps kappa(M) relative; so do A of the single call (M^-1 K) and ours.
        M = pin.crba(system.model, data, Q[k])
        tol = 4 * system.nv * EPS * np.linalg.cond(np.triu(M) + np.triu(M, 1).T)
        tau = np.zeros(system.nv)
        tau[system.actuated] = traj.u[k]
        a = pin.aba(system.model, data, Q[k], np.zeros(system.nv), tau)
        np.testing.assert_allclose(traj.a[k], a, rtol=0, atol=tol * np.abs(a).max())
        single = pinlin.linearize(scene, q=Q[k], allow_non_equilibrium=True)
        np.testing.assert_allclose(traj.A[k], single.A, rtol=0,
                                   atol=tol * np.abs(single.A).max())


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


@pytest.mark.parametrize("call", [
    lambda s: pinlin.linearize_trajectory(s, np.zeros((2, 6)) + 1j),
    lambda s: pinlin.linearize_trajectory(s, np.zeros((2, 6)), np.zeros((2, 6)) + 0j,
                                          np.zeros((2, 6))),
    lambda s: pinlin.linearize_trajectory(s, np.zeros((2, 6)), t=np.array([0.0, 1.0]) + 0j),
    lambda s: pinlin.linearize(s, q=np.zeros(6) + 1j),
    lambda s: pinlin.linearize(s, v=np.zeros(6), u=np.zeros(6) + 0j),
], ids=["trajectory_q", "trajectory_v", "trajectory_t", "linearize_q", "linearize_u"])
def test_complex_numbers_are_refused_not_truncated(call):
    """float() of a complex array drops the imaginary parts with a mere warning: refused."""
    with pytest.raises(ArgumentError, match="got complex entries"):
        call(pinlin.Scene.from_robot("ur5"))


def test_a_schedule_needs_a_scene_that_solves_its_inputs():
    scene = scene_file("four_bar", operating_point={
        "q": {"crank": 1.0, "coupler": -0.6, "rocker": 1.6}, "independent": ["crank"],
        "solve": "forces", "u": {"crank": 0.5}})
    Q = np.tile(pinlin.operating_point(pinlin.Scene.load(URDF_DIR / "four_bar.toml")).q, (2, 1))
    with pytest.raises(SceneError, match="'operating_point.solve': .*asks for \"forces\".*give v "
                                         'and u'):
        pinlin.linearize_trajectory(scene, Q)


def assert_single_calls(scene, traj, Q=None, **kwargs):
    """Point k against ``linearize(scene, q=...)`` at the schedule's configuration (or at
    ``Q[k]``): a second computation of the same model, to ~1e-9 relative (the worst kappa of
    these scenes' KKT matrices is ~1e5: n eps kappa ~ 1e-10)."""
    for k in range(len(traj)):
        single = pinlin.linearize(scene, q=traj.q[k] if Q is None else Q[k], **kwargs)
        assert single.state_names == traj.state_names
        for key in ("A", "B", "C"):
            ref = getattr(single, key)
            np.testing.assert_allclose(getattr(traj, key)[k], ref, rtol=0,
                                       atol=1e-9 * max(np.abs(ref).max(initial=0.0), 1.0))
        op = single.operating_point
        np.testing.assert_allclose(traj.u[k], op.u, rtol=0,
                                   atol=1e-9 * max(np.abs(op.u).max(initial=0.0), 1.0))
        if op.lam is not None:
            np.testing.assert_allclose(traj.lam[k], op.lam, rtol=0,
                                       atol=1e-9 * max(np.abs(op.lam).max(), 1.0))


def test_a_redundant_row_carries_its_least_norm_force(tmp_path):
    """The four-bar turned 0.5 rad about z: its planar loop's out-of-plane row no longer
    vanishes, it is redundant, and the inputs and forces that hold the linkage are a family.
    The schedule reports the least-norm split over every row, as the single call does (the
    independent rows alone would leave the redundant one at zero), and says so."""
    text = (URDF_DIR / "four_bar.urdf").read_text()
    turned = text.replace('<origin xyz="0.45 0 0" rpy="0 0 0"/>',
                          '<origin xyz="0.3949121528506678 0.21574149237189136 0" '
                          'rpy="0 0 0.5"/>', 1)
    turned = turned.replace('<origin xyz="0 0 0" rpy="0 0 0"/>',
                            '<origin xyz="0 0 0" rpy="0 0 0.5"/>', 1)
    assert turned.count('rpy="0 0 0.5"') == 2
    path = tmp_path / "turned_four_bar.urdf"
    path.write_text(turned)
    scene = scene_file("four_bar", urdf=str(path))
    single = pinlin.linearize(scene)
    assert any("not unique" in note for note in single.operating_point.notes)
    traj = pinlin.linearize_trajectory(scene, schedule(scene, 6, 0.3, 9))
    assert traj.info["least_norm_points"] == list(range(6))
    assert "not unique" in traj.info["notes"][0]
    assert np.all(np.abs(traj.lam).min(axis=1) > 0.1)  # every row carries force
    assert_single_calls(scene, traj)


def test_a_redundantly_actuated_schedule_splits_as_single_calls_do():
    """The four-bar with crank and rocker both driven, at six crank angles: the inputs and
    loop forces are a family at every point, mixing N*m (the inputs) and N (the forces), and
    the stacked statics must pick each point's split as the single call does, its norm in
    N*m (forces times the links' radius of gyration at that point)."""
    scene = scene_file("four_bar", inputs={"actuated": ["crank", "rocker"]})
    traj = pinlin.linearize_trajectory(scene, schedule(scene, 6, 0.3, 9))
    assert traj.info["least_norm_points"] == list(range(6))
    assert_single_calls(scene, traj)


def test_rotating_mechanisms_schedule_and_trajectory_point_by_point():
    """A spinning four-bar: the stacked kernels do not cover a steady rotation, so its points
    are assembled and linearized one by one; both a schedule and a given-state trajectory
    equal the single calls."""
    scene = scene_file("four_bar", effects={
        "gravity": [0.0, 0.0, -9.81], "springs": {"crank": {"stiffness": 2.0, "rest": 1.0}},
        "rotation": {"axis": [0.0, 0.0, 1.0], "rate": 5.0}})
    Q = schedule(scene, 4, 0.3, 10)
    assert_single_calls(scene, pinlin.linearize_trajectory(scene, Q))
    rng = np.random.default_rng(11)
    V, U = rng.uniform(-1, 1, (4, 3)), rng.uniform(-1, 1, (4, 1))
    traj = pinlin.linearize_trajectory(scene, Q, V, U)
    for k in range(4):
        single = pinlin.linearize(scene, q=traj.q[k], v=V[k], u=U[k])
        np.testing.assert_allclose(traj.A[k], single.A, rtol=0,
                                   atol=1e-9 * np.abs(single.A).max())


def test_contacts_are_anchored_at_each_posture_as_single_calls_anchor_them():
    """ur5 holding a point with its tool (a fixed-base contact), the shoulder swept: each
    posture anchors the contact where it puts the tool, as ``linearize(scene, q=q[k])`` does,
    so the schedule's postures are the ones given (not dragged back to the scene's)."""
    data = tomllib.loads((URDF_DIR / "ur5_arm.toml").read_text())  # robot = "ur5"
    data["contacts"] = [{"name": "touch", "frame": "tool0", "type": "point"}]
    data["operating_point"]["independent"] = ["wrist_1_joint", "wrist_2_joint",
                                              "wrist_3_joint"]
    scene = pinlin.Scene.from_dict(data)
    q0 = pinlin.operating_point(scene).q
    Q = np.tile(q0, (3, 1))
    Q[:, 1] += [0.0, 0.1, 0.2]
    with warnings.catch_warnings(record=True) as caught:  # as the single calls warn, once
        warnings.simplefilter("always")
        traj = pinlin.linearize_trajectory(scene, Q)
    assert [str(w.message)[:47] for w in caught] == [
        "trajectory point 1 (and 1 more point): scene 'u"]
    assert "pulls" in str(caught[0].message) and caught[0].filename == __file__
    np.testing.assert_allclose(traj.q, Q, rtol=0, atol=1e-12)
    assert traj.info["path"] == "per point (single calls at rest)"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.ContactWarning)
        assert_single_calls(scene, traj, Q)
    with pytest.raises(ArgumentError, match="point by point in this process"):
        pinlin.linearize_trajectory(scene, Q, workers=2)


def test_each_distinct_warning_of_the_single_calls_is_said_once_with_its_points():
    """Two contacts that both pull at points 1 and 2: two ContactWarnings (one per contact,
    numbers aside), each naming its first point and the count of the others."""
    data = tomllib.loads((URDF_DIR / "ur5_arm.toml").read_text())
    data["contacts"] = [{"name": "touch", "frame": "tool0", "type": "point"},
                        {"name": "elbow", "frame": "wrist_2_link", "type": "point"}]
    data["operating_point"].pop("independent", None)
    scene = pinlin.Scene.from_dict(data)
    Q = np.tile(pinlin.operating_point(scene).q, (3, 1))
    Q[:, 1] += [0.0, 0.1, 0.2]
    expected = set()
    for k in range(3):  # what the single calls say, point by point
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pinlin.linearize(scene, q=Q[k])
        expected |= {(w.category, str(w.message).split(" pulls")[0], k) for w in caught
                     if w.category is pinlin.ContactWarning}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pinlin.linearize_trajectory(scene, Q)
    said = [str(w.message) for w in caught if w.category is pinlin.ContactWarning]
    for contact in ("touch", "elbow"):
        points = sorted(k for _, text, k in expected if f"'{contact}'" in text)
        assert points == [1, 2]
        assert [t for t in said if f"'{contact}'" in t][0].startswith(
            "trajectory point 1 (and 1 more point): ")
    assert len(said) == 2


def test_standing_robots_weld_loops_and_numerical_derivatives_schedule_by_single_calls(
        tmp_path):
    """What the stacked mechanism path leaves out at rest: a floating base standing on its
    contacts and numerical derivatives of a loop; each point is the single static call."""
    box = pinlin.Scene.resolve("standing_box")
    Q = np.tile(pinlin.operating_point(box).q, (3, 1))
    Q[:, 2] += [0.0, 0.01, 0.02]  # the box raised: its contacts anchored higher
    traj = pinlin.linearize_trajectory(box, Q)
    assert traj.at(1).operating_point.equilibrium
    assert_single_calls(box, traj, Q)
    back = pinlin.TrajectoryModel.load(traj.save(tmp_path / "box.mat"))  # no inputs: (N, p, 0)
    np.testing.assert_array_equal(back.A, traj.A)
    assert back.D.shape == traj.D.shape
    four_bar = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    Q = schedule(four_bar, 3, 0.3, 12)
    traj = pinlin.linearize_trajectory(four_bar, Q, derivatives="fd3")
    assert traj.info["derivatives"] == "fd3"
    for k in range(3):  # the same computation as the single call, point for point
        single = pinlin.linearize(four_bar, q=Q[k], derivatives="fd3", estimate_error=False)
        np.testing.assert_array_equal(traj.A[k], single.A)


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_a_mechanism_schedule_carries_its_second_order_matrices(suffix, tmp_path):
    """``second_order=True`` on a mechanism's schedule: each point's M, C_damp, K, Bu in its
    independent coordinates, those of the single static call (the same computation, point
    by point), so that the symmetric modal path applies; they survive a file."""
    scene = pinlin.Scene.load(URDF_DIR / "delta.toml")
    Q = schedule(scene, 3, 0.2, 13)
    traj = pinlin.linearize_trajectory(scene, Q, second_order=True)
    nz = len(traj.state_names) // 2
    assert traj.M.shape == (3, nz, nz) and traj.Bu.shape == (3, nz, 3)
    for k in range(3):
        single = pinlin.linearize(scene, q=Q[k])
        for key in ("M", "C_damp", "K", "Bu", "A"):
            np.testing.assert_array_equal(getattr(traj.at(k), key), getattr(single, key))
    assert pinlin.modal(traj.at(1)).method == "symmetric"
    back = pinlin.TrajectoryModel.load(traj.save(tmp_path / f"schedule{suffix}"))
    np.testing.assert_array_equal(back.K, traj.K)
    with pytest.raises(ArgumentError, match="a schedule of its rest points"):
        pinlin.linearize_trajectory(scene, Q, np.zeros((3, 12)), np.zeros((3, 3)),
                                    second_order=True)


def test_a_mimic_coupling_without_loops_follows_the_schedule(tmp_path):
    """A double pendulum whose elbow mimics the shoulder (no closure frame): each point is
    assembled from the one before and equals the single call."""
    text = (URDF_DIR / "double_pendulum.urdf").read_text()
    anchor = '<joint name="elbow" type="revolute">'
    assert anchor in text
    text = text.replace(anchor, anchor + '\n    <mimic joint="shoulder" multiplier="0.5" '
                                         'offset="0.1"/>', 1)
    (tmp_path / "mimic.urdf").write_text(text)
    scene = pinlin.Scene.from_dict({
        "name": "mimic_pendulum", "urdf": str(tmp_path / "mimic.urdf"),
        "effects": {"gravity": [0.0, 0.0, -9.81], "mimic": True},
        "operating_point": {"q": {"shoulder": 0.3, "elbow": 0.25}},
        "inputs": {"actuated": ["shoulder"]}})
    Q = np.tile(pinlin.operating_point(scene).q, (3, 1))
    Q[:, 0] += [0.0, 0.1, 0.2]  # the elbow left behind: assembled at each point
    traj = pinlin.linearize_trajectory(scene, Q)
    np.testing.assert_allclose(traj.q[:, 1], 0.5 * traj.q[:, 0] + 0.1, rtol=0, atol=1e-12)
    assert_single_calls(scene, traj)


def test_a_schedule_near_a_singular_position_warns_as_a_single_call_does():
    """The four-bar driven by its rocker to 1e-9 rad short of the rocker's limit (where the
    crank and coupler fold): the condition of Phi_d is only ~4e5, but configurations the
    assembly cannot tell apart give models ~5e-5 apart. The single call warns; so must the
    schedule, naming the point, with the same measured change."""
    scene = scene_file("four_bar", operating_point={
        "q": {"crank": 1.0, "coupler": -0.6, "rocker": 1.6}, "independent": ["rocker"]})
    q = pinlin.operating_point(scene).q
    rocker = scene.system.model.joints[scene.system.model.getJointId("rocker")].idx_q
    q[rocker] = 2.429420869352851 - 1e-9  # the limit, found by bisection on the assembly
    far = q.copy()
    far[rocker] -= 0.2
    with pytest.warns(pinlin.AccuracyWarning, match="trajectory point 1, the schedule's point "
                                                    "nearest a singular position"):
        traj = pinlin.linearize_trajectory(scene, np.array([far, q]))
    with pytest.warns(pinlin.AccuracyWarning, match="not reliable"):
        single = pinlin.linearize(scene, q=traj.q[1])
    change = single.info["condition"]["operating_point_sensitivity"]
    assert traj.info["operating_point_sensitivity"] == {"point": 1, "change": change}
    assert change > 1e-6


def test_a_mechanism_without_independent_coordinates_is_refused():
    """A double pendulum whose tip is held (a point contact on a fixed base): nothing moves,
    so a trajectory of it has no state; given states are refused, naming point 0."""
    data = tomllib.loads((URDF_DIR / "double_pendulum.toml").read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    data["contacts"] = [{"name": "wall", "frame": "tip", "type": "point"}]
    data["operating_point"] = {"q": {"shoulder": 0.3, "elbow": 0.4}, "solve": "inputs"}
    scene = pinlin.Scene.from_dict(data)
    Q = np.array([[0.3, 0.4], [0.5, 0.2]])
    with pytest.raises(pinlin.ModelError, match="trajectory point 0: .*hold every coordinate"):
        pinlin.linearize_trajectory(scene, Q, np.zeros((2, 2)), np.zeros((2, 2)))


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


def test_a_schedule_with_unique_holding_inputs_reports_no_least_norm_points():
    """The four-bar's holding input is unique: neither the single calls nor the schedule
    report a least-norm split."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    traj = pinlin.linearize_trajectory(scene, schedule(scene, 5, 0.4, 0))
    for k in range(5):
        single = pinlin.linearize(scene, q=traj.q[k])
        assert not any("not unique" in note for note in single.operating_point.notes)
    assert "least_norm_points" not in traj.info


def test_a_schedule_point_where_gravity_vanishes_keeps_the_single_calls_verdict():
    """The double pendulum hanging with its unactuated elbow 1e-12 rad off: gravity on it is
    2e-12 N*m, within 1e-9 of the most gravity can exert (the system's force reference), so
    the single call calls it an equilibrium. The schedule measured the residual against the
    gravity at the point alone (2e-12) and refused it."""
    scene = pinlin.Scene.from_dict({"urdf": str(URDF_DIR / "double_pendulum.urdf"),
                                    "effects": {"gravity": [0.0, 0.0, -9.81]},
                                    "inputs": {"actuated": ["shoulder"]}})
    q = np.array([0.0, 1e-12])
    single = pinlin.linearize(scene, q=q)
    assert single.operating_point.equilibrium
    traj = pinlin.linearize_trajectory(scene, q[None])
    assert traj.info["at_rest"]
    np.testing.assert_array_equal(traj.A[0], single.A)
