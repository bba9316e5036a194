"""Trajectories of mechanisms (pinlin.trajectory_loops): every point assembled and linearized in
the independent coordinates of point 0, equal to a single ``pinlin.linearize`` at that state,
right against Pinocchio's own constrained dynamics, the same with workers and executors, and
refused (never NaN) where the frozen coordinates stop parametrizing the mechanism."""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR
from test_moving_loops import ConstrainedDynamics

import pinlin
from pinlin import trajectory_assembly
from pinlin.assembly import ASSEMBLY_TOL, assemble

EPS = np.finfo(float).eps


def sweep(scene: pinlin.Scene, N: int, seed: int, span: float = 1.0):
    """N states whose independent coordinates follow z0 + span * sin (one per coordinate,
    random phases), the dependent ones left at the scene's rest values (so every point but the
    first needs assembling), random velocities [rad/s] and inputs [N*m]."""
    system = scene.system
    rest = pinlin.linearize(scene)
    z = np.array([system.coordinate_names.index(c) for c in rest.info["independent"]])
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 0.9, N)
    Q = np.tile(rest.operating_point.q, (N, 1))
    phase = rng.uniform(0, 2 * np.pi, len(z))
    Q[:, z] += span * (np.sin(2 * np.pi * s[:, None] + phase) - np.sin(phase))
    V = rng.uniform(-2.0, 2.0, (N, system.nv))
    U = rng.uniform(-1.0, 1.0, (N, len(system.actuated)))
    return Q, V, U, z


def kkt_condition(system, q: np.ndarray, rows: list[int]) -> float:
    G = system.constraints.jacobian(q)[rows]
    M = system.mass_matrix(q)
    m = len(rows)
    return float(np.linalg.cond(np.block([[M, -G.T], [G, np.zeros((m, m))]])))


@pytest.mark.parametrize("name, seed", [("four_bar", 0), ("slider_crank", 1), ("delta", 2)])
def test_each_point_is_the_single_model_at_its_state(name, seed):
    """Point k against ``linearize(q=traj.q[k], v=v[k], u=u[k])``. Both run the same
    computation (solves with the KKT matrix of the point); a backward-stable solve in float64
    is exact to ~n eps kappa(KKT) relative, which bounds any difference of rounding. The
    assembled configurations keep the independent coordinates given and close the loops."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    system = scene.system
    N = 12
    Q, V, U, z = sweep(scene, N, seed)
    traj = pinlin.linearize_trajectory(scene, Q, V, U, t=np.arange(N) * 0.1)
    nz = len(z)
    assert traj.A.shape == (N, 2 * nz, 2 * nz) and traj.lam.shape == (N, system.constraints.size)
    rows = [system.constraints.row_names.index(r) for r in traj.info["constraint_rows"]]
    np.testing.assert_array_equal(traj.q[:, z], Q[:, z])  # z held by the assembly
    moved = traj.info["loops"]["position_correction"]
    assert moved[0] == 0.0 and min(moved[1:]) > 0.0  # the given points 1.. were not closed
    for k in range(N):
        assert np.abs(system.constraints.residual(traj.q[k])).max() <= 1e3 * ASSEMBLY_TOL
        single = pinlin.linearize(scene, q=traj.q[k], v=V[k], u=U[k])
        assert single.state_names == traj.state_names
        n = 2 * system.nv + len(rows)
        tol = n * EPS * kkt_condition(system, traj.q[k], rows)
        for key in ("A", "B", "C", "f0"):
            ours, ref = getattr(traj, key)[k], getattr(single, key)
            np.testing.assert_allclose(ours, ref, rtol=0, atol=tol * max(np.abs(ref).max(), 1))
        op = single.operating_point
        # Output values: frame positions and joint values from the same kinematics, exactly.
        np.testing.assert_allclose(traj.y[k], op.y, rtol=0, atol=1e-15 * np.abs(op.y).max())
        np.testing.assert_allclose(traj.v[k], op.v, rtol=0, atol=tol * np.abs(V[k]).max())
        np.testing.assert_allclose(traj.a[k], op.a, rtol=0, atol=tol * np.abs(op.a).max())
        np.testing.assert_allclose(traj.lam[k], op.lam, rtol=0,
                                   atol=tol * np.abs(op.lam).max())
        at = traj.at(k)
        assert at.f0 is not None and at.operating_point.lam_names == op.lam_names
        assert at.info["condition"]["constraint_jacobian"] == pytest.approx(
            single.info["condition"]["constraint_jacobian"], rel=1e-9)
        # The projection: J v = 0, and the correction reported is the one applied.
        J = system.constraints.jacobian(traj.q[k])
        assert np.abs(J @ traj.v[k]).max() <= 1e-12 * np.abs(V[k]).max()
        assert traj.info["loops"]["velocity_correction"][k] == pytest.approx(
            np.linalg.norm(V[k] - traj.v[k]), rel=1e-12, abs=1e-15)


def test_points_that_close_their_loops_are_kept_as_given():
    """A trajectory of closed configurations (the assembled ones of another call) comes back
    with the same q to the bit and zero position corrections; velocities already in the
    nullspace are not moved (to rounding)."""
    scene = pinlin.Scene.resolve("four_bar")
    Q, V, U, _ = sweep(scene, 8, 3)
    first = pinlin.linearize_trajectory(scene, Q, V, U)
    again = pinlin.linearize_trajectory(scene, first.q, first.v, U)
    np.testing.assert_array_equal(again.q, first.q)
    assert max(again.info["loops"]["position_correction"]) == 0.0
    assert max(again.info["loops"]["velocity_correction"]) <= 1e-14 * np.abs(V).max()
    np.testing.assert_allclose(again.A, first.A, rtol=0, atol=1e-12 * np.abs(first.A).max())


@pytest.mark.parametrize("name, seed, points", [("four_bar", 4, (1, 6)),
                                                ("slider_crank", 5, (2, 7)),
                                                ("delta", 6, (3,))])
def test_points_match_the_constrained_dynamics(name, seed, points):
    """A, B, f0 at moving points of a trajectory against central differences of Pinocchio's
    constrained forward dynamics (tests/test_moving_loops.py: h = 1e-5, difference ~h^2,
    measured 6e-11 to 1.3e-10 of max |A|; tolerance 1e-8 as there)."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    Q, V, U, z = sweep(scene, 9, seed)
    traj = pinlin.linearize_trajectory(scene, Q, V, U)
    ref = ConstrainedDynamics(scene)
    nz, h = len(z), 1e-5
    zero = np.zeros(nz)
    for k in points:
        q0, u0, zdot0 = traj.q[k], traj.u[k], traj.v[k][z]
        np.testing.assert_allclose(ref.velocity(q0, z, zdot0), traj.v[k], rtol=0,
                                   atol=1e-12 * np.abs(zdot0).max())
        lower = ref.lower_rows(q0, z, zdot0, u0, h)
        np.testing.assert_allclose(traj.A[k, nz:], lower, rtol=0,
                                   atol=1e-8 * np.abs(lower).max())
        B = np.array([(ref.zdd(q0, z, zero, zdot0, u0 + e)
                       - ref.zdd(q0, z, zero, zdot0, u0 - e)) / 2.0
                      for e in np.eye(len(u0))]).T
        np.testing.assert_allclose(traj.B[k, nz:], B, rtol=0, atol=1e-8 * np.abs(B).max())
        a0 = ref.zdd(q0, z, zero, zdot0, u0)
        np.testing.assert_allclose(traj.f0[k], np.concatenate([zdot0, a0]), rtol=0,
                                   atol=1e-9 * np.abs(a0).max())


@pytest.mark.parametrize("name", ["four_bar", "delta"])
def test_workers_and_executors_give_the_same_arrays(name):
    scene = pinlin.Scene.resolve(name)
    Q, V, U, _ = sweep(scene, 40, 7)
    one = pinlin.linearize_trajectory(scene, Q, V, U)
    two = pinlin.linearize_trajectory(scene, Q, V, U, workers=2, chunk=7)
    with ThreadPoolExecutor(2) as pool:
        ex = pinlin.linearize_trajectory(scene, Q, V, U, executor=pool, chunk=9)
    for other in (two, ex):
        for key in ("A", "B", "C", "D", "f0", "q", "v", "u", "a", "lam", "y"):
            np.testing.assert_array_equal(getattr(other, key), getattr(one, key), err_msg=key)
        assert other.state_names == one.state_names and other.info == one.info


def test_save_load_and_discretize_keep_the_mechanism(tmp_path):
    scene = pinlin.Scene.resolve("slider_crank")
    Q, V, U, _ = sweep(scene, 6, 8)
    traj = pinlin.linearize_trajectory(scene, Q, V, U)
    for suffix in (".npz", ".mat"):
        back = pinlin.TrajectoryModel.load(traj.save(tmp_path / f"m{suffix}"))
        np.testing.assert_array_equal(back.lam, traj.lam)
        assert back.at(2).operating_point.lam_names == traj.at(2).operating_point.lam_names
    d = traj.discretize(1e-3, "euler")
    single = traj.at(4).discretize(1e-3, "euler")
    np.testing.assert_allclose(d.A[4], single.A, rtol=0, atol=1e-15 * np.abs(single.A).max())


# --------------------------------------------------------------------------------------------
# Singular positions


def _rocker_scene(tmp_path) -> pinlin.Scene:
    """The four-bar with the rocker as independent coordinate: at the rocker's extreme
    positions (crank and coupler collinear) the crank cannot follow it (Phi_d singular)."""
    text = (URDF_DIR / "four_bar.toml").read_text()
    text = text.replace('independent = ["crank"]', 'independent = ["rocker"]')
    text = text.replace('urdf = "four_bar.urdf"', f'urdf = "{URDF_DIR / "four_bar.urdf"}"')
    path = tmp_path / "four_bar_rocker.toml"
    path.write_text(text)
    return pinlin.Scene.load(path)


def _toggle(scene: pinlin.Scene) -> tuple[np.ndarray, np.ndarray, float]:
    """(q at the toggle, a closed q 0.3 rad of crank before it, crank angle of the toggle):
    the crank angle where det Phi_d(crank, coupler) changes sign, by bisection on closed
    configurations (crank held)."""
    system = scene.system
    rows = [0, 2]  # x and z: the y row of this planar loop is redundant
    crank = np.linspace(1.0, 1.0 + 2 * np.pi, 73)
    base = pinlin.linearize(scene).operating_point.q
    closed, q = [], base
    for c in crank:
        guess = q.copy()
        guess[0] = c
        q = assemble(system, guess, np.array([0]))
        closed.append(q)
    det = [np.linalg.det(system.constraints.jacobian(q)[rows][:, [0, 1]]) for q in closed]
    i = next(i for i in range(len(det) - 1) if det[i] * det[i + 1] < 0)
    lo, hi, qlo = crank[i], crank[i + 1], closed[i]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        guess = qlo.copy()
        guess[0] = mid
        qm = assemble(system, guess, np.array([0]))
        d = np.linalg.det(system.constraints.jacobian(qm)[rows][:, [0, 1]])
        if d * det[i] > 0:
            lo, qlo = mid, qm
        else:
            hi = mid
    before = qlo.copy()
    before[0] -= 0.3
    before = assemble(system, before, np.array([0]))
    return qlo, before, lo


def test_a_point_where_the_frozen_coordinates_fail_is_refused_by_index(tmp_path):
    scene = _rocker_scene(tmp_path)
    crank_scene = pinlin.Scene.resolve("four_bar")
    q_toggle, q_before, _ = _toggle(crank_scene)
    Q = np.array([q_before, q_before, q_toggle, q_before])
    V, U = np.zeros((4, 3)), np.zeros((4, 1))
    with pytest.raises(pinlin.ModelError, match=r"^trajectory point 2: .*\[rocker\].*cannot "
                                                r"parametrize.*split the trajectory"):
        pinlin.linearize_trajectory(scene, Q, V, U)


def test_near_a_singular_position_it_warns_and_stays_finite(tmp_path):
    """1e-8 rad of crank from the toggle: Phi_d's condition ~1e4 / sqrt(1e-8)... above 1e6;
    the model is finite and the warning names the point."""
    scene = _rocker_scene(tmp_path)
    crank_scene = pinlin.Scene.resolve("four_bar")
    q_toggle, q_before, _ = _toggle(crank_scene)
    near = q_toggle.copy()
    near[0] -= 1e-8
    near = assemble(crank_scene.system, near, np.array([0]))
    Q = np.array([q_before, near, q_before])
    V = np.zeros((3, 3))
    V[:, 2] = 0.5
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = pinlin.linearize_trajectory(scene, Q, V, np.zeros((3, 1)))
    messages = [str(w.message) for w in caught if issubclass(w.category, pinlin.AccuracyWarning)]
    assert len(messages) == 1 and "trajectory point 1" in messages[0], messages
    assert traj.info["loops"]["condition"][1] > 1e6
    for key in ("A", "B", "C", "f0", "v", "a", "lam"):
        assert np.isfinite(getattr(traj, key)).all(), key


def test_a_trajectory_whose_loops_cannot_close_names_the_point(tmp_path):
    """The four-bar driven by its rocker: 2 rad beyond its range at point 2 no crank angle
    closes the loop."""
    scene = _rocker_scene(tmp_path)
    Q, V, U, z = sweep(scene, 4, 10, span=0.05)
    assert list(z) == [2]
    Q[2, 2] += 2.0
    with pytest.raises(pinlin.AssemblyError, match=r"^trajectory point 2: .*do not close"):
        pinlin.linearize_trajectory(scene, Q, V, U)


def test_velocities_are_projected_and_numerical_derivatives_go_point_by_point():
    """fd3 along a mechanism's trajectory: each point is the single fd3 call at its state,
    the same computation (bit for bit: the estimate, left out here, changes nothing in A)."""
    scene = pinlin.Scene.resolve("four_bar")
    Q, V, U, _ = sweep(scene, 4, 11)
    fd = pinlin.linearize_trajectory(scene, Q, V, U, derivatives="fd3")
    assert fd.info["derivatives"] == "fd3" and fd.info["step"]["q"] == 1e-5
    for k in range(4):
        single = pinlin.linearize(scene, q=fd.q[k], v=V[k], u=U[k], derivatives="fd3",
                                  estimate_error=False)
        np.testing.assert_array_equal(fd.A[k], single.A)
        np.testing.assert_array_equal(fd.B[k], single.B)
    traj = pinlin.linearize_trajectory(scene, Q, V, U)
    assert min(traj.info["loops"]["velocity_correction"]) > 0.0
    assert pin.isNormalized(scene.system.model, traj.q[2])


def test_the_curvature_term_applies_along_the_previous_step_only():
    """alpha^2 for a step along the previous one (either way, up to 4x as long), 0 where the
    step turns by more than the alignment allows or there is no previous step."""
    past = np.array([1.0, 2.0, -0.5])
    assert trajectory_assembly.curvature(1.5 * past, past) == pytest.approx(2.25, rel=1e-15)
    assert trajectory_assembly.curvature(-0.5 * past, past) == pytest.approx(0.25, rel=1e-15)
    assert trajectory_assembly.curvature(5.0 * past, past) == 0.0
    normal = np.array([2.0, -1.0, 0.0])                 # normal to past
    tilt = trajectory_assembly.CURVATURE_ALIGNMENT
    assert trajectory_assembly.curvature(past + 0.9 * tilt * normal * np.sqrt(5.25 / 5),
                                         past) > 0.0
    assert trajectory_assembly.curvature(past + 1.1 * tilt * normal * np.sqrt(5.25 / 5),
                                         past) == 0.0
    assert trajectory_assembly.curvature(past, np.zeros(3)) == 0.0


def test_a_smooth_sweep_closes_each_point_in_one_newton_step(monkeypatch):
    """With the curvature of the previous step in the start, the four-bar's predicted start is
    off by O(dz^3) (dz <= 0.014 rad here): one Newton step closes its loop to ASSEMBLY_TOL, so
    each point after the second costs two kinematics passes (the start, the check), where the
    tangent alone (error O(dz^2)) needed three. Counted, not timed."""
    scene = pinlin.Scene.resolve("four_bar")
    Q, V, U, _ = sweep(scene, 200, 7, span=0.5)
    passes = []
    evaluate = trajectory_assembly._Closures.__call__

    def counted(self, q, J):
        out = evaluate(self, q, J)
        passes.append(out[1])
        return out

    monkeypatch.setattr(trajectory_assembly._Closures, "__call__", counted)
    traj = pinlin.linearize_trajectory(scene, Q, V, U)
    closed = [k for k, worst in enumerate(passes) if worst <= ASSEMBLY_TOL]
    per_point = np.diff(closed)
    assert len(closed) == 200 and per_point[1:].max() == 2, per_point
    single = pinlin.linearize(scene, q=traj.q[100], v=traj.v[100], u=U[100])
    np.testing.assert_allclose(traj.at(100).A, single.A, rtol=0, atol=1e-9 * np.abs(single.A).max())


def test_a_point_open_by_ten_assembly_tolerances_is_closed_not_kept():
    """A point given a few assembly tolerances open is closed, not kept as given."""
    scene = pinlin.Scene.resolve("four_bar")
    system = scene.system
    cons = system.constraints
    Q, V, U, z = sweep(scene, 6, 3)
    first = pinlin.linearize_trajectory(scene, Q, V, U)
    dep = [i for i in range(system.nv) if i not in set(z.tolist())]
    Q2 = first.q.copy()
    Q2[3, dep[0]] += 2e-11
    opened = cons.closure_error(cons.residual(Q2[3]))
    assert 5 * ASSEMBLY_TOL < opened < 100 * ASSEMBLY_TOL
    again = pinlin.linearize_trajectory(scene, Q2, first.v, U)
    assert cons.closure_error(cons.residual(again.q[3])) <= ASSEMBLY_TOL
