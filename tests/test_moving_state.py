"""Linearization at any state (v0 != 0, u0 given): A, B and f0 against central differences of
the continuous dynamics in pinlin's chart, x = [difference(q0, q); v],

    f(dq, v, u) = [dDifference(q0, integrate(q0, dq)) v; aba(integrate(q0, dq), v, S u)],

built here from Pinocchio's own functions (no pinlin code in the reference), and the
discretizations against their definitions."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.chart import kinematic_block

ROTATED = {"root_joint": {"position": [0.1, -0.2, 0.6], "rpy": [0.3, -0.4, 0.8]}}
#: Central differences with h = 1e-6: rounding ~eps |f| / h ~ 2e-10 |f| dominates; the
#: truncation h^2 / 6 times a third derivative (~1e2 at these velocities) is ~2e-11.
TOL = 1e-7


def _reference(scene: pinlin.Scene, q0, v0, u0, h: float = 1e-6):
    system = scene.system
    model, data = system.model, system.model.createData()
    S = system.input_matrix
    nv = model.nv

    def f(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        q = pin.integrate(model, q0, x[:nv])
        v = x[nv:]
        qdot = pin.dDifference(model, q0, q, pin.ArgumentPosition.ARG1) @ v
        return np.concatenate([qdot, pin.aba(model, data, q, v, S @ u)])

    x0 = np.concatenate([np.zeros(nv), v0])
    A = np.array([(f(x0 + h * e, u0) - f(x0 - h * e, u0)) / (2 * h)
                  for e in np.eye(2 * nv)]).T
    B = np.array([(f(x0, u0 + e) - f(x0, u0 - e)) / 2.0 for e in np.eye(len(u0))]).T
    return A, B, f(x0, u0)


def _moving_state(scene: pinlin.Scene, seed: int):
    system = scene.system
    rng = np.random.default_rng(seed)
    q0 = pinlin.operating_point(scene, allow_non_equilibrium=True).q
    v0 = rng.uniform(-2.0, 2.0, system.nv)
    u0 = rng.uniform(-5.0, 5.0, len(system.actuated))
    return q0, v0, u0


@pytest.mark.parametrize("robot, seed", [("ur5", 0), ("panda", 1), ("solo12", 2),
                                         ("talos", 3)])
def test_moving_state_matches_differences_of_the_dynamics(robot, seed):
    over = {"operating_point": {"q": ROTATED}} if robot in ("solo12", "talos") else {}
    scene = pinlin.Scene.from_robot(robot, **over)
    q0, v0, u0 = _moving_state(scene, seed)
    model = pinlin.linearize(scene, v=v0, u=u0)
    A_ref, B_ref, f_ref = _reference(scene, q0, v0, u0)
    scale = np.abs(A_ref).max()
    np.testing.assert_allclose(model.A, A_ref, rtol=0, atol=TOL * scale)
    np.testing.assert_allclose(model.B, B_ref, rtol=0, atol=1e-10 * np.abs(B_ref).max())
    np.testing.assert_allclose(model.f0, f_ref, rtol=0, atol=1e-10 * np.abs(f_ref).max())
    op = model.operating_point
    assert not op.equilibrium and np.array_equal(op.v, v0) and np.array_equal(op.u, u0)
    if robot in ("solo12", "talos"):  # the Lie-group block is really there
        assert np.abs(model.A[:6, :6]).max() > 0.1


def test_kinematic_block_matches_differences_of_ddifference():
    """-1/2 ad(v0) on free-flyer, spherical and planar joints (pinlin.chart), zero on the
    others, against central differences of Pinocchio's dDifference."""
    path = URDF_DIR / "pendulum.urdf"  # any URDF: the joints below are added in Python
    m = pin.Model()
    parent = 0
    for name, joint in [("ff", pin.JointModelFreeFlyer()), ("sph", pin.JointModelSpherical()),
                        ("pl", pin.JointModelPlanar()), ("rz", pin.JointModelRZ()),
                        ("cont", pin.JointModelRUBZ())]:
        parent = m.addJoint(parent, joint, pin.SE3.Identity(), name)
        m.appendBodyToJoint(parent, pin.Inertia.Random(), pin.SE3.Identity())
    assert path.exists()
    rng = np.random.default_rng(4)
    q0 = pin.randomConfiguration(m, -np.ones(m.nq), np.ones(m.nq))
    v0 = rng.standard_normal(m.nv)

    class _Joints:  # what kinematic_block reads of a System
        nv = m.nv
        joints = {m.names[j]: type("J", (), {"kind": m.joints[j].shortname(),
                                               "idx_v": m.joints[j].idx_v,
                                               "nv": m.joints[j].nv})()
                  for j in range(1, m.njoints)}

    def g(dq):
        return pin.dDifference(m, q0, pin.integrate(m, q0, dq), pin.ArgumentPosition.ARG1) @ v0

    h = 1e-6
    ref = np.array([(g(h * e) - g(-h * e)) / (2 * h) for e in np.eye(m.nv)]).T
    np.testing.assert_allclose(kinematic_block(_Joints, v0), ref, rtol=0, atol=1e-8)
    assert kinematic_block(_Joints, np.zeros(m.nv)) is None


def test_scene_file_with_a_given_state(write_scene):
    path = write_scene('robot = "ur5"\n[effects]\ngravity = true\n[operating_point]\n'
                       'solve = "none"\nv = { shoulder_pan_joint = 1.5, elbow_joint = -0.5 }\n'
                       'u = { elbow_joint = 3.0 }\n')
    scene = pinlin.Scene.load(path)
    model = pinlin.linearize(scene)
    names = scene.system.coordinate_names
    v0 = np.zeros(6)
    v0[names.index("shoulder_pan_joint")], v0[names.index("elbow_joint")] = 1.5, -0.5
    u0 = np.zeros(6)
    u0[names.index("elbow_joint")] = 3.0
    op = model.operating_point
    np.testing.assert_array_equal(op.v, v0)
    np.testing.assert_array_equal(op.u, u0)
    same = pinlin.linearize(pinlin.Scene.from_robot("ur5"), v=v0, u=u0)
    np.testing.assert_array_equal(model.A, same.A)
    assert any("state given" in n for n in op.notes)


@pytest.mark.parametrize("text, words", [
    ('[operating_point]\nv = { hinge = 1.0 }\n', "velocities are given only with solve"),
    ('[operating_point]\nsolve = "none"\nv = { hinge = [1.0, 2.0] }\n',
     "has 1 velocity coordinates"),
    ('[operating_point]\nsolve = "none"\nv = { elbow = 1.0 }\n', "'elbow' is not a joint"),
])
def test_bad_given_states(write_scene, text, words):
    path = write_scene('urdf = "robot.urdf"\n' + text,
                       robot__urdf=(URDF_DIR / "pendulum.urdf").read_text())
    with pytest.raises(pinlin.SceneError, match=words):
        pinlin.linearize(pinlin.Scene.load(path))


def test_bad_state_arguments():
    with pytest.raises(pinlin.ArgumentError, match="argument 'v'"):
        pinlin.linearize("pendulum", v=[1.0, 2.0])
    with pytest.raises(pinlin.ArgumentError, match="argument 'u'"):
        pinlin.linearize("pendulum", u=["a"])
    with pytest.raises(pinlin.ModelError, match="not supported yet"):
        pinlin.linearize("ur5", v=np.zeros(6), formulation="penalty")


def test_zero_order_hold_integrates_the_linear_model():
    """ZOH: x(dt) of x' = f0 + A x + B u with u held, integrated by solve_ivp (rtol 1e-12)."""
    from scipy.integrate import solve_ivp

    scene = pinlin.Scene.from_robot("ur5")
    q0, v0, u0 = _moving_state(scene, 5)
    model = pinlin.linearize(scene, v=v0, u=u0)
    dt = 0.01
    disc = model.discretize(dt)
    rng = np.random.default_rng(6)
    x, u = rng.standard_normal(12) * 0.1, rng.standard_normal(6)
    sol = solve_ivp(lambda t, y: model.f0 + model.A @ y + model.B @ u, (0.0, dt), x,
                    rtol=1e-12, atol=1e-14)
    expected = sol.y[:, -1]
    np.testing.assert_allclose(disc.f0 + disc.A @ x + disc.B @ u, expected, rtol=0,
                               atol=1e-9 * np.abs(expected).max())
    assert disc.dt == dt and disc.info["discretization"]["method"] == "zoh"


def test_semi_implicit_euler_step():
    """'euler': v+ = v + dt v', then dq+ = dq + dt (d(dq)/dt at v+), stepped here by hand on
    the continuous model."""
    scene = pinlin.Scene.from_robot("solo12", operating_point={"q": ROTATED})
    q0, v0, u0 = _moving_state(scene, 7)
    model = pinlin.linearize(scene, v=v0, u=u0)
    dt = 1e-3
    disc = model.discretize(dt, "euler")
    n = model.A.shape[0] // 2
    rng = np.random.default_rng(8)
    x, u = rng.standard_normal(2 * n) * 0.1, rng.standard_normal(len(u0))
    xdot = model.f0 + model.A @ x + model.B @ u
    v_next = x[n:] + dt * xdot[n:]
    x_mid = np.concatenate([x[:n], v_next])
    qdot = (model.f0 + model.A @ x_mid)[:n]
    expected = np.concatenate([x[:n] + dt * qdot, v_next])
    np.testing.assert_allclose(disc.f0 + disc.A @ x + disc.B @ u, expected, rtol=0,
                               atol=1e-12 * np.abs(expected).max())


def test_discretize_refuses_what_it_cannot_do():
    model = pinlin.linearize("pendulum")
    for bad in (0.0, -1.0, float("nan"), "0.1", True):
        with pytest.raises(pinlin.ArgumentError, match="argument 'dt'"):
            model.discretize(bad)
    with pytest.raises(pinlin.ArgumentError, match="argument 'method'"):
        model.discretize(0.01, "tustin")
    disc = model.discretize(0.01)
    with pytest.raises(pinlin.ArgumentError, match="already discrete"):
        disc.discretize(0.01)
    with pytest.raises(pinlin.ArgumentError, match="is discrete"):
        pinlin.modal(disc)
    # A finite dt whose matrices overflow: named, refused (an unstable mode, sigma = sqrt(10)
    # 1/s, over 300 s: exp(949); Euler's powers of dt at 1e300 s).
    unstable = pinlin.LinearModel(A=[[0.0, 1.0], [10.0, 0.0]], B=[[0.0], [1.0]], C=np.eye(2),
                                  D=np.zeros((2, 1)), state_names=["q:x", "v:x"],
                                  input_names=["u:x"], output_names=["y1", "y2"], name="up")
    with pytest.raises(pinlin.ModelError, match=r"dt = 300 s .* overflows"):
        unstable.discretize(300.0)
    with pytest.raises(pinlin.ModelError, match=r"dt = 1e\+300 s .* overflows"):
        model.discretize(1e300, "euler")
    # A hold whose rounding estimate eps ||A||_1 dt reaches 1 keeps no correct digit
    # (the undamped pendulum over 1e15 s: |eig(A_d)| came back 0.55 for 1): refused.
    with pytest.raises(pinlin.ModelError, match=r"dt = 1e\+15 s .*no correct digit"):
        model.discretize(1e15)
    # ... unless every mode decays below rounding within the step: a damped pendulum
    # (lambda = -1 +- 2.97i) over 1e15 s is the steady state, A_d = 0, B_d = -A^-1 B,
    # computed to working precision, without a word.
    damped = pinlin.LinearModel(A=[[0.0, 1.0], [-9.81, -2.0]], B=[[0.0], [1.0]], C=np.eye(2),
                                D=np.zeros((2, 1)), state_names=["q:x", "v:x"],
                                input_names=["u:x"], output_names=["y1", "y2"], name="damped")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        held = damped.discretize(1e15)
    assert np.abs(held.A).max() == 0.0
    np.testing.assert_allclose(held.B, [[1 / 9.81], [0.0]], rtol=1e-14, atol=1e-15)
    for dt in (5e-324, np.nextafter(np.finfo(float).tiny, 0)):   # subnormal: few bits
        with pytest.raises(pinlin.ArgumentError, match="argument 'dt'.*subnormal"):
            model.discretize(dt)
    canon = pinlin.linearize("four_bar", formulation="canonical")
    with pytest.raises(pinlin.ArgumentError, match="use 'zoh'"):
        canon.discretize(0.01, "euler")


def test_zero_order_hold_warns_where_rounding_eats_the_digits():
    """An undamped oscillator (w = 3.125 rad/s) held over dt = 2^40 s ~ 1.1e12 s (w and dt
    binary-exact, so the phase w dt is exact and math.cos/sin give the closed form
    [[cos, sin/w], [-w sin, cos]] to an ulp): pinlin's matrix exponential differs by ~2e-4
    relative (its squarings alone), and finite nonsense came back silently (at 1e16 s an
    undamped pendulum's discrete eigenvalues had |z| = 1e33). An AccuracyWarning now says so
    from eps ||A|| dt > 1e-6; an ordinary dt stays silent."""
    import math
    import warnings

    w, dt = 3.125, 2.0 ** 40
    A = np.array([[0.0, 1.0], [-w * w, 0.0]])
    model = pinlin.LinearModel(A=A, B=np.zeros((2, 0)), C=np.eye(2), D=np.zeros((2, 0)),
                               state_names=("q:x", "v:x"), input_names=(),
                               output_names=("q:x", "v:x"), name="oscillator")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.discretize(0.01)
        model.discretize(1e6)
    with pytest.warns(pinlin.AccuracyWarning, match=r"dt = 1.09951e\+12 s .* may reach 2.4e-03"):
        A_d = model.discretize(dt).A
    phase = w * dt
    exact = np.array([[math.cos(phase), math.sin(phase) / w],
                      [-w * math.sin(phase), math.cos(phase)]])
    assert np.abs(A_d - exact).max() / np.abs(exact).max() > 1e-6   # the warning is due
    trajectory = pinlin.linearize_trajectory("pendulum", np.zeros((2, 1)))
    with pytest.warns(pinlin.AccuracyWarning, match="zero-order hold"):
        trajectory.discretize(1e12)


def test_discrete_and_affine_models_round_trip(tmp_path):
    scene = pinlin.Scene.from_robot("ur5")
    q0, v0, u0 = _moving_state(scene, 9)
    disc = pinlin.linearize(scene, v=v0, u=u0).discretize(0.005)
    for suffix in (".npz", ".mat", ".json"):
        back = pinlin.LinearModel.load(disc.save(tmp_path / f"m{suffix}"))
        assert back.dt == 0.005
        np.testing.assert_array_equal(back.f0, disc.f0)
        np.testing.assert_array_equal(back.A, disc.A)


@pytest.mark.parametrize("backend", ["fd3", "fd5"])
def test_numerical_derivatives_at_a_moving_state(backend):
    """The velocity terms (Coriolis) are differenced too; the result lies within the error
    bound reported with it."""
    scene = pinlin.Scene.from_robot("solo12", operating_point={"q": ROTATED})
    q0, v0, u0 = _moving_state(scene, 10)
    exact = pinlin.linearize(scene, v=v0, u=u0)
    approx = pinlin.linearize(scene, v=v0, u=u0, derivatives=backend)
    true = np.abs(approx.A - exact.A).max() / np.abs(exact.A).max()
    assert true <= approx.info["error_estimate"] < 1e-7
    np.testing.assert_array_equal(approx.f0, exact.f0)


@pytest.mark.parametrize("robot, seed", [("ur5", 12), ("panda", 13)])
def test_euler_discretization_matches_mujoco_at_a_moving_state(robot, seed):
    """pinlin's Euler-discretized model against MuJoCo's own step at the same moving state:
    A_d from mjd_transitionFD (centered at 3e-4 and 6e-4, Richardson-combined: O(eps^4) +
    eps_mach |x| / eps, ~1e-13 of A_d's O(1) entries), B_d from differences of mj_step in the
    applied forces. No damping: MuJoCo integrates it implicitly, pinlin's step explicitly."""
    from pinlin import mjcf

    scene = pinlin.Scene.from_robot(robot)
    q0, v0, u0 = _moving_state(scene, seed)
    model = pinlin.linearize(scene, v=v0, u=u0)
    ms = mjcf.build(scene.system, visual=False)
    A_mj, B_mj = mjcf.euler_step_jacobians(ms, scene.system, model.operating_point)
    disc = model.discretize(ms.dt, "euler")
    np.testing.assert_allclose(disc.A, A_mj, rtol=0, atol=1e-8)
    np.testing.assert_allclose(disc.B, B_mj, rtol=0, atol=1e-10 * np.abs(B_mj).max())


def test_a_drift_that_is_not_the_points_velocity_is_refused(tmp_path):
    """x = [dq; v - v0] gives dq' = v0 at the point, so a moving model's f0 begins with v0
    (pinlin copies it). A model file whose f0 was edited there loaded, and its response and
    the simulation it is compared with (from operating_point.v) described other motions."""
    scene = pinlin.Scene.from_robot("ur5")
    rng = np.random.default_rng(71)
    q, v, u = rng.uniform(-1.0, 1.0, (3, 6))
    model = pinlin.linearize(scene, q=q, v=v, u=u)
    np.testing.assert_array_equal(model.f0[:6], model.operating_point.v)
    back = pinlin.LinearModel.load(model.save(tmp_path / "good.npz"))
    np.testing.assert_array_equal(back.f0, model.f0)
    fields = dict(np.load(tmp_path / "good.npz", allow_pickle=False))
    f0 = fields["f0"].copy()      # stored as a column
    f0.reshape(-1)[2] += 0.5
    fields["f0"] = f0
    np.savez(tmp_path / "bad.npz", **fields)
    with pytest.raises(pinlin.ModelFileError, match=r"bad\.npz: .*upper half of f0 is dq' = "
                                                    r"v0 .* differs from operating_point\.v "
                                                    r"by 0\.5"):
        pinlin.LinearModel.load(tmp_path / "bad.npz")
