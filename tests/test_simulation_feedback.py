"""pinlin.simulate with state feedback (``feedback=K`` or a callable of (t, x)) against
references from outside the code under test: a hand-written ODE of the inverted pendulum under
the same control law (solve_ivp), the linear closed loop expm((A - B K) t) x0 for small
motions (the nonlinear remainder quadratic in the amplitude), and the stiffness a high-gain
loop adds (which the open loop does not have)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import scipy.integrate
import scipy.linalg as sla
from conftest import URDF_DIR, deadline
from scipy.signal import place_poles

import pinlin
from pinlin.scene import bundled_scenes

G = 9.81
#: urdf/pendulum.urdf: 1 kg sphere (r = 0.05 m) 1 m below the hinge: J = 1 + 2/5 * 0.05^2.
J_PENDULUM = 1.001
MGL = 1.0 * G * 1.0   # [N*m]: m g l


def _pendulum() -> pinlin.Scene:
    return pinlin.Scene.from_urdf(URDF_DIR / "pendulum.urdf",
                                  effects={"gravity": [0.0, 0.0, -G]})


def _remainder(scene, t, direction, K, closed, amplitudes, states):
    """(log-log slope, errors): max |simulate(feedback=K)'s ``states`` - expm(closed t) x0|
    for x0 = a ``direction`` at each amplitude a."""
    errors = []
    for a in amplitudes:
        sim = pinlin.simulate(scene, t, dx0=a * direction, feedback=K)
        linear = np.array([sla.expm(closed * ti) @ (a * direction) for ti in t])
        errors.append(np.abs(getattr(sim, states) - linear).max())
    return np.polyfit(np.log(amplitudes), np.log(errors), 1)[0], errors


def _gain(model: pinlin.LinearModel, poles: list[float]) -> np.ndarray:
    """A state-feedback gain placing the closed loop's poles (scipy's place_poles: u = -K x)."""
    return place_poles(model.A, model.B, poles).gain_matrix


def test_inverted_pendulum_held_up_by_its_gain_as_by_hand():
    """Upright (q0 = pi, an unstable equilibrium: lambda = +-3.13 1/s) and 0.6 rad off, the
    pendulum is brought back by du = -K x with K placing the poles at -3 and -4. Reference:
    J x'' = m g l sin(x) + du, du = -K [x, x'], by solve_ivp at tolerances 1e-12. Agreement
    to 1e-8 rad: both integrate at rtol 1e-10 over a motion that decays (no error growth),
    with the same law; a missing or mis-signed feedback falls over (x reaches pi)."""
    scene = _pendulum()
    model = pinlin.linearize(scene, q=[np.pi])
    K = _gain(model, [-3.0, -4.0])
    t = np.linspace(0.0, 4.0, 81)
    sim = pinlin.simulate(scene, t, dx0=[0.6, 0.0], q0=[np.pi], feedback=K)

    def rhs(_, s):
        du = -(K @ s)[0]
        return [s[1], (MGL * np.sin(s[0]) + du) / J_PENDULUM]

    ref = scipy.integrate.solve_ivp(rhs, (0.0, 4.0), [0.6, 0.0], t_eval=t, method="DOP853",
                                    rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(sim.x[:, 0], ref.y[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(sim.x[:, 1], ref.y[1], rtol=0, atol=1e-8)
    assert abs(sim.x[-1, 0]) < 0.02                               # held up
    # u records the law: u0 + du at every output time (u0 = 0 upright, to rounding).
    np.testing.assert_allclose(sim.u[:, 0], -(sim.x @ K.T)[:, 0], rtol=0, atol=1e-12)
    assert sim.energy is None and "feedback" in sim.info["energy"]
    assert sim.info["feedback"] == "du = -K x, K of shape (1, 2)"
    # The same law as a callable: the same right-hand side, the same steps.
    by_hand = pinlin.simulate(scene, t, dx0=[0.6, 0.0], q0=[np.pi],
                              feedback=lambda tk, x: -K @ x)
    np.testing.assert_array_equal(by_hand.x, sim.x)
    # Without it, the pendulum falls.
    fallen = pinlin.simulate(scene, t[:41], dx0=[0.6, 0.0], q0=[np.pi])
    assert np.abs(fallen.x[:, 0]).max() > 2.0


def test_time_varying_law_and_open_loop_inputs_add_up():
    """A gain switched on at t = 1 s (a callable of t) plus a constant open-loop torque: the
    motion is the hand-written ODE's under the same sum."""
    scene = _pendulum()
    K = np.array([[30.0, 8.0]])
    t = np.linspace(0.0, 3.0, 61)

    def law(tk, x):
        return -(K @ x) * (tk >= 1.0)

    sim = pinlin.simulate(scene, t, dx0=[0.3, 0.0], u=lambda tk: [0.5], feedback=law,
                          rtol=1e-11, atol=1e-13)

    def rhs(tk, s):
        du = 0.5 - (K @ s)[0] * (tk >= 1.0)
        return [s[1], (-MGL * np.sin(s[0]) + du) / J_PENDULUM]

    # The switch at t = 1 s is inside a step of either integrator: integrate the two pieces.
    a = scipy.integrate.solve_ivp(rhs, (0.0, 1.0), [0.3, 0.0], method="DOP853", rtol=1e-12,
                                  atol=1e-14, dense_output=True)
    b = scipy.integrate.solve_ivp(rhs, (1.0, 3.0), a.y[:, -1], method="DOP853", rtol=1e-12,
                                  atol=1e-14, dense_output=True)
    ref = np.array([a.sol(tk) if tk <= 1.0 else b.sol(tk) for tk in t])
    # The switch is a jump of the acceleration inside one of pinlin's steps (its step size
    # control sees it as a local error and shrinks the step there): 1e-6 rad, not 1e-9.
    np.testing.assert_allclose(sim.x, ref, rtol=0, atol=1e-6)
    np.testing.assert_allclose(sim.u[:, 0], 0.5 - (sim.x @ K.T)[:, 0] * (t >= 1.0), atol=1e-12)


@pytest.mark.parametrize("name", ["ur5_arm", "four_bar", "delta"])
def test_small_motions_follow_the_linear_closed_loop(name):
    """x_nl - expm((A - B K) t) x0 is the quadratic remainder (slope 2 in the amplitude): the
    nonlinear robot under the gain designed on its linear model (LQR, python-control) follows
    the linear closed loop. For a mechanism x is [dz; dz'] (K of shape (nu, 2 nz)), and the
    same gain spread over all coordinates (zero on the dependent ones) drives the same
    motion."""
    control = pytest.importorskip("control")
    model = pinlin.linearize(name)
    n = model.n_states
    K = control.lqr(model.A, model.B, np.eye(n), 1e-2 * np.eye(model.B.shape[1]))[0]
    closed = model.A - model.B @ K
    direction = np.random.default_rng(5).standard_normal(n)
    direction /= np.abs(direction).max()
    t = np.linspace(0.0, 0.5, 21)
    amplitudes = np.array([1e-3, 2e-3, 4e-3])
    slope, errors = _remainder(name, t, direction, K, closed, amplitudes, "z")
    assert 1.9 < slope < 2.1
    # The remainder, not the integrator (rtol 1e-10 of |x| ~ 1e-3, atol 1e-12, over some
    # 50 steps: ~1e-10), is measured; the loop damps the motion, so the remainder is small.
    assert errors[0] > 1e2 * 1e-10
    system = pinlin.Scene.load(bundled_scenes()[name]).system
    nv = system.nv
    if n < 2 * nv:   # a mechanism: the gain over all coordinates
        cols = [system.coordinate_names.index(s.removeprefix("q:"))
                for s in model.state_names[:n // 2]]
        wide = np.zeros((K.shape[0], 2 * nv))
        wide[:, cols] = K[:, :n // 2]
        wide[:, [nv + c for c in cols]] = K[:, n // 2:]
        again = pinlin.simulate(name, t, dx0=amplitudes[0] * direction, feedback=wide)
        first = pinlin.simulate(name, t, dx0=amplitudes[0] * direction, feedback=K)
        # The same law; its sums run in another order (rounding), which moves the adaptive
        # steps: the two runs agree within the integrator's tolerance (~1e-10, as above).
        np.testing.assert_allclose(again.z, first.z, rtol=0, atol=1e-10)


def test_a_high_gain_loop_is_stiff():
    """A velocity gain of 500 N*m*s/rad makes the closed loop decay at ~500 1/s: over 10 s the
    stiffness criterion (rho T > 1e3) picks Radau, though the open loop (+-3.13j) is not stiff;
    the motion is the hand-written ODE's."""
    scene = _pendulum()
    K = np.array([[0.0, 500.0]])
    t = np.linspace(0.0, 10.0, 11)
    sim = pinlin.simulate(scene, t, dx0=[0.0, 1.0], feedback=K, rtol=1e-9, atol=1e-12)
    assert sim.info["method"] == "Radau", sim.info["method_reason"]

    def rhs(_, s):
        return [s[1], (-MGL * np.sin(s[0]) - 500.0 * s[1]) / J_PENDULUM]

    ref = scipy.integrate.solve_ivp(rhs, (0.0, 10.0), [0.0, 1.0], t_eval=t, method="Radau",
                                    rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(sim.x, ref.y.T, rtol=0, atol=1e-8)
    assert pinlin.simulate(scene, t, dx0=[0.0, 1.0]).info["method"] == "DOP853"


@pytest.mark.parametrize("feedback, match", [
    (np.zeros((1, 3)), r"shape \(1, 2\) \(inputs x states: u = -K x\), got shape \(1, 3\)"),
    (np.zeros((2, 2)), r"got shape \(2, 2\)"),
    (np.array([[np.nan, 0.0]]), "NaN or inf"),
    ([["1", "2"]], "got text"),
    (lambda t, x: [1.0, 2.0], r"must return 1 finite numbers, got array\(\[1\., 2\.\]\)"),
    (lambda t, x: [np.inf], "must return 1 finite numbers"),
    (np.zeros(3), r"got shape \(3,\)"),                       # the shape given, not reshaped
    (lambda t: [0.0], r"feedback\(t, x\) of the time .* raised TypeError"),
    (np.zeros, "calling it so raised TypeError"),              # callable by accident
    # 1e12 N*m/rad on a 1 kg*m^2 pendulum: 1e6 rad/s over 1e3 s, 1.6e8 periods
    (np.array([[1e12, 0.0]]), r"argument 'feedback'.*of the closed loop.*lower the gain"),
    (lambda t, x: [x[5]], r"state \(2 nv = 2 numbers\).*raised IndexError"),
])
def test_bad_feedback(feedback, match):
    with pytest.raises(pinlin.ArgumentError, match=match):
        pinlin.simulate("pendulum", [0.0, 1.0], dx0=[0.1, 0.0], feedback=feedback)


def test_bad_feedback_horizon():
    """The closed loop's speed is blamed on the gain, not on t (the open loop's 3.1 rad/s
    over 1e3 s is 500 periods: fine)."""
    with pytest.raises(pinlin.ArgumentError, match="argument 'feedback'"):
        pinlin.simulate("pendulum", [0.0, 1e3], dx0=[0.1, 0.0], feedback=[[1e12, 0.0]])


def test_a_scene_without_inputs_has_nothing_to_feed_back():
    with pytest.raises(pinlin.ArgumentError, match="no inputs to feed back to"):
        pinlin.simulate("standing_box", [0.0, 0.1], feedback=lambda t, x: [])


def test_a_gain_is_checked_against_the_model_it_was_designed_on():
    """(K, model): the default model's gain drives the same motion as K alone; a canonical
    model's ([p; q]: momenta first) or an orthonormal basis's (q:z[0]) is refused, where K
    alone, of the right shape, would be applied to the wrong states."""
    t = np.linspace(0.0, 1.0, 11)
    model = pinlin.linearize("ur5_arm")
    K = np.ones((6, 12))
    alone = pinlin.simulate("ur5_arm", t, dx0=1e-3 * np.ones(12), feedback=K)
    paired = pinlin.simulate("ur5_arm", t, dx0=1e-3 * np.ones(12), feedback=(K, model))
    np.testing.assert_array_equal(alone.x, paired.x)
    canonical = pinlin.linearize("ur5_arm", formulation="canonical")
    with pytest.raises(pinlin.ArgumentError, match=r"model 'ur5_arm', whose states \(p:"):
        pinlin.simulate("ur5_arm", t, feedback=(K, canonical))
    four_bar = pinlin.linearize("four_bar")
    dx0 = [0.01, 0.0]
    np.testing.assert_array_equal(
        pinlin.simulate("four_bar", t, dx0, feedback=(np.ones((1, 2)), four_bar)).z,
        pinlin.simulate("four_bar", t, dx0, feedback=np.ones((1, 2))).z)
    penalty = pinlin.linearize("four_bar", formulation="penalty")
    np.testing.assert_array_equal(
        pinlin.simulate("four_bar", t, dx0, feedback=(np.ones((1, 6)), penalty)).z,
        pinlin.simulate("four_bar", t, dx0, feedback=np.ones((1, 6))).z)
    with pytest.raises(pinlin.ArgumentError, match=r"shape \(1, 6\).*got shape \(1, 2\)"):
        pinlin.simulate("four_bar", t, feedback=(np.ones((1, 2)), penalty))   # K's width
    # About another point: the upright pendulum's gain used about the hanging one.
    upright = pinlin.linearize("pendulum", q=[np.pi])
    with pytest.raises(pinlin.ArgumentError, match="designed about another point"):
        pinlin.simulate("pendulum", t, [0.1, 0.0], feedback=(np.ones((1, 2)), upright))
    pinlin.simulate("pendulum", t, [0.1, 0.0], q0=[np.pi], feedback=(np.ones((1, 2)), upright))
    orthonormal = pinlin.linearize("four_bar", basis="orthonormal")
    with pytest.raises(pinlin.ArgumentError, match=r"states \(q:z\[0\]"):
        pinlin.simulate("four_bar", t, feedback=(np.ones((1, 2)), orthonormal))


def test_a_very_high_gain_about_a_far_point_is_resolved():
    """K = [1e12, 2e6] upright (q0 = pi, 0.6 rad off): a critically damped loop at 1e6 1/s.
    The feedback reads x from the integrator's chart centred at q0 (x = dq exactly): had the
    chart been centred at q0 + dx0 (x = dq + 0.6, |dq| -> 0.6), x would carry eps * 0.6
    rounding that the gain turns into 1e-4 rad/s^2 of noise, which stalled Radau at steps of
    1e-12 s. Reference: the hand-written ODE in x, solve_ivp Radau at tighter tolerances."""
    scene = _pendulum()
    K = np.array([[1e12, 2e6]])
    t = np.array([0.0, 1e-6, 2e-6, 5e-6, 1e-5, 1e-2])
    with deadline(120):   # the stall ran for hours: fail instead
        sim = pinlin.simulate(scene, t, dx0=[0.6, 0.0], q0=[np.pi], feedback=K)
    assert sim.info["method"] == "Radau" and sim.info["nfev"] < 1e5   # measured: 14 000

    def rhs(_, s):
        return [s[1], (MGL * np.sin(s[0]) - (K @ s)[0]) / J_PENDULUM]

    ref = scipy.integrate.solve_ivp(rhs, (0.0, t[-1]), [0.6, 0.0], t_eval=t, method="Radau",
                                    rtol=1e-12, atol=1e-15)
    # Positions to 1e-9 of the 0.6 rad start, velocities (up to 2e5 rad/s) to 1e-9 of theirs.
    np.testing.assert_allclose(sim.x[:, 0], ref.y[0], rtol=0, atol=1e-9 * 0.6)
    np.testing.assert_allclose(sim.x[:, 1], ref.y[1], rtol=0,
                               atol=1e-9 * np.abs(ref.y[1]).max())


def test_a_mechanisms_gain_sizes_are_named():
    """four_bar: nv = 3, nz = 1: a gain is (1, 2) or (1, 6)."""
    with pytest.raises(pinlin.ArgumentError, match=r"shape \(1, 2\) or \(1, 6\)"):
        pinlin.simulate("four_bar", [0.0, 1.0], feedback=np.zeros((1, 4)))


def test_tv_lqr_along_a_swing_follows_the_linear_time_varying_loop():
    """The time-varying LQR of a planned motion (what linearize_trajectory is for), closed
    around the nonlinear robot. The double pendulum swings along q_ref(t) = [0.8 sin 2t,
    -0.6 sin 3t] (u_ref by inverse dynamics, Pinocchio's RNEA); K_k comes from the discrete
    Riccati recursion on the ZOH discretizations of linearize_trajectory's models at 201
    points (dt = 10 ms), linear in t between them. Started off the reference, the robot under
    du = u_ref(t) - K(t) [q - q_ref(t); v - v_ref(t)] deviates from it as the linear
    time-varying loop dx' = (A(t) - B(t) K(t)) dx does, A(t) and B(t) from single
    linearize calls at the reference state at each t: the difference is the remainder,
    quadratic in the amplitude (slope 2), and the loop brings the deviation down."""
    scene = pinlin.Scene.resolve("double_pendulum")
    system = scene.system
    model, data = system.model, system.model.createData()
    amp, omega = np.array([0.8, -0.6]), np.array([2.0, 3.0])

    def reference(tk):
        q = amp * np.sin(omega * tk)
        v = amp * omega * np.cos(omega * tk)
        a = -amp * omega**2 * np.sin(omega * tk)
        return q, v, pin.rnea(model, data, q, v, a).copy()

    T, N = 2.0, 201
    grid = np.linspace(0.0, T, N)
    dt = grid[1] - grid[0]
    Q, V, U = (np.array(c) for c in zip(*(reference(tk) for tk in grid), strict=True))
    traj = pinlin.linearize_trajectory(scene, Q, V, U).discretize(dt)
    weight_x, weight_u = np.diag([100.0, 100.0, 1.0, 1.0]), 1e-2 * np.eye(2)
    P, gains = weight_x, np.zeros((N, 2, 4))
    for k in range(N - 1, -1, -1):          # backward Riccati on the discrete models
        Ad, Bd = traj.A[k], traj.B[k]
        gains[k] = np.linalg.solve(weight_u + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
        P = weight_x + Ad.T @ P @ (Ad - Bd @ gains[k])

    def gain(tk):
        s = min(tk / dt, N - 1.0)
        k = min(int(s), N - 2)
        return gains[k] + (s - k) * (gains[k + 1] - gains[k])

    q0, v0, _ = reference(0.0)

    def law(tk, x):                         # x = [q - q0; v - v0] (revolute joints)
        q_ref, v_ref, u_ref = reference(tk)
        dx = np.concatenate([q0 + x[:2] - q_ref, v0 + x[2:] - v_ref])
        return u_ref - gain(tk) @ dx        # u0 = 0 (v0 given, the scene names no u)

    def linear_loop(tk, dx):
        q_ref, v_ref, u_ref = reference(tk)
        m = pinlin.linearize(scene, q=q_ref, v=v_ref, u=u_ref)
        return (m.A - m.B @ gain(tk)) @ dx

    t = np.linspace(0.0, T, 41)
    direction = np.array([1.0, -0.5, 0.3, 0.8])
    amplitudes = np.array([1e-3, 2e-3, 4e-3])
    # The linear loop is linear: one solution, scaled by the amplitude (its error, ~1e-9 of
    # it, then ~1e-12 at a = 1e-3: far below the remainder's 1e-7).
    unit = scipy.integrate.solve_ivp(linear_loop, (0.0, T), direction, t_eval=t,
                                     method="DOP853", rtol=1e-9, atol=1e-12).y.T
    ref = np.array([np.concatenate(reference(tk)[:2]) for tk in t])
    errors = []
    for a in amplitudes:
        sim = pinlin.simulate(scene, t, dx0=a * direction, q0=q0, v0=v0, feedback=law)
        deviation = np.hstack([sim.q, sim.v]) - ref
        errors.append(np.abs(deviation - a * unit).max())
        assert np.abs(deviation[-1]).max() < 0.1 * a   # the loop holds the swing
    slope = np.polyfit(np.log(amplitudes), np.log(errors), 1)[0]
    assert 1.9 < slope < 2.1, (slope, errors)
    assert errors[0] > 1e2 * 1e-10


def test_a_floating_base_under_joint_feedback_follows_its_linear_closed_loop():
    """solo12 floating in zero gravity, its 12 joints under PD feedback (K_q = 20, K_v = 2
    N*m*s/rad; the base free): x includes the base's 6 chart coordinates (a Lie group), and
    small motions follow expm((A - B K) t) x0 up to the quadratic remainder (slope 2), the
    base's rigid modes included."""
    scene = pinlin.Scene.from_robot("solo12", base="free", effects={})
    model = pinlin.linearize(scene)
    nv = scene.system.nv
    K = np.zeros((12, 2 * nv))
    K[:, 6:nv] = 20.0 * np.eye(12)
    K[:, nv + 6:] = 2.0 * np.eye(12)
    closed = model.A - model.B @ K
    direction = np.random.default_rng(7).standard_normal(2 * nv)
    direction /= np.abs(direction).max()
    t = np.linspace(0.0, 0.5, 11)
    slope, errors = _remainder(scene, t, direction, K, closed, np.array([1e-3, 2e-3, 4e-3]),
                               "x")
    assert 1.9 < slope < 2.1, (slope, errors)
    assert errors[0] > 1e2 * 1e-10


@pytest.mark.parametrize("rotation", [0.3, 1.5])
def test_the_state_a_feedback_reads_is_the_difference_from_q0(rotation):
    """OpenChain.model_state against pin.difference(q0, q) of the configuration the chart
    state stands for: centred at q0 (a base rotated 0.3 rad: the chart coordinates
    themselves) and re-centred (1.5 rad, beyond the chart's 1 rad: through q), before and
    after a step of the chart."""
    from pinlin.simulation_ode import OpenChain

    scene = pinlin.Scene.from_robot("solo12", base="free", effects={})
    system = scene.system
    op = pinlin.operating_point(scene)
    dyn = OpenChain(system, op)
    nv = system.nv
    dx0 = np.zeros(2 * nv)
    dx0[3:6] = rotation * np.array([0.6, 0.0, 0.8])
    dx0[6:nv] = 0.1
    dx0[nv:] = 0.2
    s0, _ = dyn.initial_state(dx0)
    assert dyn.centred == (rotation < 1.0)
    for s in (s0, s0 + 0.05 * np.random.default_rng(2).standard_normal(s0.size)):
        q, v = dyn.state(s)
        expected = np.concatenate([pin.difference(system.model, op.q, q), v - op.v])
        np.testing.assert_allclose(dyn.model_state(s), expected, rtol=0, atol=1e-12)
