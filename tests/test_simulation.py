"""pinlin.simulate against references from outside the code under test: the exact period of
the pendulum (complete elliptic integral), a hand-written one-coordinate ODE, closed-form
responses to inputs, conservation laws (energy, angular momentum), the linear model's exact
response (expm) and MuJoCo's RK4 integration of the exported scene."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.integrate
import scipy.linalg as sla
from conftest import URDF_DIR
from scipy.special import ellipk

import pinlin
from pinlin import mjcf
from pinlin.mjcf_rollout import rollout

G = 9.81
#: urdf/pendulum.urdf: 1 kg sphere (r = 0.05 m) 1 m below the hinge: J = 1 + 2/5 * 0.05^2.
J_PENDULUM = 1.001
L_EQ = J_PENDULUM / (1.0 * 1.0)  # compound pendulum: theta'' = -(g / L_eq) sin(theta)


def crossings(t: np.ndarray, th: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Times where th crosses zero: the root of the cubic Hermite interpolant of (th, th')
    on the bracketing interval (error <= h^4/384 max|th''''| / |th'|, below 1e-13 s here)."""
    out = []
    for i in np.flatnonzero(np.sign(th[1:]) != np.sign(th[:-1])):
        h = t[i + 1] - t[i]
        p0, p1, m0, m1 = th[i], th[i + 1], w[i] * h, w[i + 1] * h
        s = p0 / (p0 - p1)
        for _ in range(30):
            f = ((2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * m0
                 + (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * m1)
            df = ((6 * s**2 - 6 * s) * p0 + (3 * s**2 - 4 * s + 1) * m0
                  + (-6 * s**2 + 6 * s) * p1 + (3 * s**2 - 2 * s) * m1)
            s -= f / df
        out.append(t[i] + s * h)
    return np.array(out)


# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("theta0", [0.1, 0.5, 1.0, 2.0, 2.5, 3.0])
def test_pendulum_period_is_exact(theta0):
    """T = 4 sqrt(L_eq/g) K(k), k = sin(theta0/2) (ellipk takes m = k^2), to 1e-8; the period
    is t3 - t1 of the first and third zero crossings."""
    exact = 4.0 * np.sqrt(L_EQ / G) * ellipk(np.sin(theta0 / 2.0) ** 2)
    t = np.arange(0.0, 1.3 * exact, 1e-3)
    sim = pinlin.simulate("pendulum", t, dx0=[theta0, 0.0])
    found = crossings(t, sim.x[:, 0], sim.x[:, 1])
    assert abs((found[2] - found[0]) - exact) / exact < 1e-8
    assert sim.info["method"] == "DOP853"
    assert np.ptp(sim.energy) < 1e-8 * G * (1.0 - np.cos(theta0))  # [J], m L = 1 kg*m


def test_pendulum_linear_period():
    """The linear model's period is 2 pi sqrt(L_eq/g); the simulated one tends to it as
    T(theta0) = T_lin (1 + theta0^2/16 + O(theta0^4))."""
    linear = 2.0 * np.pi * np.sqrt(L_EQ / G)
    lam = np.linalg.eigvals(pinlin.linearize("pendulum").A)
    assert 2.0 * np.pi / np.abs(lam).max() == pytest.approx(linear, rel=1e-12)
    theta0 = 1e-3
    t = np.arange(0.0, 1.3 * linear, 1e-3)
    sim = pinlin.simulate("pendulum", t, dx0=[theta0, 0.0])
    found = crossings(t, sim.x[:, 0], sim.x[:, 1])
    assert (found[2] - found[0]) / linear - 1.0 == pytest.approx(theta0**2 / 16, abs=1e-9)


MIMIC_URDF = """<?xml version="1.0"?>
<robot name="mimic_pair">
  <link name="base"/>
  <link name="a_link"><inertial><origin xyz="0 0 -0.7"/><mass value="1.0"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="b_link"><inertial><origin xyz="0 0 -0.4"/><mass value="0.5"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="a" type="revolute"><parent link="base"/><child link="a_link"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="b" type="revolute"><parent link="base"/><child link="b_link"/>
    <origin xyz="1 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/>
    <mimic joint="a" multiplier="2.0" offset="0"/></joint>
</robot>
"""


def test_mimic_pair_matches_its_one_coordinate_equation(tmp_path):
    """Point masses m1 at l1 on joint a and m2 at l2 on joint b = 2 a: by hand,
    (m1 l1^2 + 4 m2 l2^2) a'' = -g (m1 l1 sin a + 2 m2 l2 sin 2a), integrated by scipy."""
    urdf = tmp_path / "pair.urdf"
    urdf.write_text(MIMIC_URDF)
    scene = pinlin.Scene.from_urdf(urdf, effects={"gravity": [0, 0, -G], "mimic": True},
                                   inputs={"actuated": ["a"]})
    t = np.linspace(0.0, 3.0, 61)
    sim = pinlin.simulate(scene, t, dx0=[0.8, 0.0])
    m1, l1, m2, l2 = 1.0, 0.7, 0.5, 0.4

    def f(_, s):
        return [s[1], -G * (m1 * l1 * np.sin(s[0]) + 2 * m2 * l2 * np.sin(2 * s[0]))
                / (m1 * l1**2 + 4 * m2 * l2**2)]

    ref = scipy.integrate.solve_ivp(f, (0, 3), [0.8, 0.0], method="DOP853", t_eval=t,
                                    rtol=1e-12, atol=1e-14).y.T
    assert sim.independent_names == ("q:a", "v:a")
    np.testing.assert_allclose(sim.z, ref, atol=1e-8)
    np.testing.assert_allclose(sim.x[:, 1], 2 * sim.x[:, 0], atol=1e-13)  # b = 2 a
    assert sim.drift.max() < 1e-13
    assert np.ptp(sim.energy) < 1e-9 * G * (m1 * l1 + 2 * m2 * l2)  # [J], swing ~ 1 J


# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, amplitude, omega", [("four_bar", 0.3, 4.8065),
                                                    ("delta", 0.05, 24.477)])
def test_mechanism_stays_on_manifold_and_conserves_energy(name, amplitude, omega):
    """100 periods of the lowest mode: |Phi(q)| and |Phi_q v| stay at rounding level (no
    growth), and the energy, kinetic + gravity + springs - u0 . (q - q0)[actuated] (u0 the
    equilibrium inputs, held), is constant to 1e3 rtol of the peak kinetic energy (DOP853's
    global error over ~2500 steps)."""
    periods = 100
    t = np.linspace(0.0, periods * 2 * np.pi / omega, 10 * periods + 1)
    model = pinlin.linearize(name)
    dx0 = np.zeros(model.n_states)
    dx0[0] = amplitude
    sim = pinlin.simulate(name, t, dx0=dx0)
    system = pinlin.Scene.resolve(name).system
    kinetic = max(0.5 * v @ system.mass_matrix(q) @ v for q, v in zip(sim.q, sim.v, strict=True))
    speed = np.abs(sim.v).max()
    assert sim.drift[:, 0].max() < 1e-13                       # [m]
    assert sim.drift[:, 1].max() < 1e-14 * max(1.0, speed)     # [m/s]
    tenth = len(t) // 10
    assert sim.drift[-tenth:].max() <= 10 * max(sim.drift[:tenth].max(), 1e-15)
    assert "work of u0" in sim.info["energy"]
    assert np.abs(sim.energy - sim.energy[0]).max() < 1e3 * sim.info["rtol"] * kinetic
    assert sim.info["restarts"]["partition"] == 0


def test_mechanism_through_a_singular_position_of_its_coordinates():
    """The four-bar parametrized by its rocker, whose extreme positions (crank and coupler in
    line) are singular for that choice: pinlin re-chooses z on the way and follows the same
    motion as the crank-parametrized simulation (at rtol 1e-12)."""
    scene = pinlin.Scene.resolve("four_bar")
    spec = dataclasses.replace(scene.operating_point, independent=("rocker",))
    by_rocker = dataclasses.replace(scene, operating_point=spec)
    t = np.linspace(0.0, 3.0, 31)
    ref = pinlin.simulate(scene, t, dx0=[0.0, 8.0], rtol=1e-12, atol=1e-14)
    sim = pinlin.simulate(by_rocker, t, q0=ref.q[0], v0=ref.v[0], u=lambda _: ref.u[0])
    assert sim.independent_names == ("q:rocker", "v:rocker")
    assert np.ptp(ref.x[:, 2]) > 1.0 and sim.info["restarts"]["partition"] >= 1
    assert np.all(np.array(_difference(scene.system, sim.q, sim.v, ref.q, ref.v)) < [1e-8, 1e-7])
    assert sim.drift.max() < 1e-13


@pytest.mark.parametrize("name", ["ur5_arm", "four_bar", "delta", "standing_box",
                                  "solo12_standing", "g1_standing", "talos_standing"])
def test_small_perturbations_follow_the_linear_model(name):
    """x_nl - expm(A t) x0 is the quadratic remainder: slope 2 on log-log over 3 amplitudes.
    The horizon is 1 s, or less where the fastest unstable mode (a standing robot's) would
    grow more than 10-fold in it (ln 10 / max Re lambda), so that the remainder stays a
    remainder."""
    model = pinlin.linearize(name)
    growth = max(float(np.linalg.eigvals(model.A).real.max()), 0.0)
    T = min(1.0, np.log(10.0) / growth) if growth > 0.0 else 1.0
    direction = np.random.default_rng(3).standard_normal(model.n_states)
    direction /= np.abs(direction).max()
    t = np.linspace(0.0, T, 41)
    amplitudes = np.array([1e-3, 2e-3, 4e-3])
    errors = []
    for a in amplitudes:
        sim = pinlin.simulate(name, t, dx0=a * direction)
        linear = np.array([sla.expm(model.A * ti) @ (a * direction) for ti in t])
        errors.append(np.abs(sim.z - linear).max())
    slope = np.polyfit(np.log(amplitudes), np.log(errors), 1)[0]
    assert 1.95 < slope < 2.05
    assert errors[0] > 1e3 * 1e-10  # the remainder, not the integrator, is measured


# ------------------------------------------------------------------------------------------------
def _difference(system, Q1, V1, Q2, V2) -> tuple[float, float]:
    """max |difference(q1, q2)| [rad or m] and max |v1 - v2| [rad/s or m/s] over time."""
    dq = max(np.abs(pin.difference(system.model, a, b)).max() for a, b in zip(Q1, Q2, strict=True))
    return float(dq), float(np.abs(V1 - V2).max())


def _mujoco(system, sim, dt, **solver) -> tuple[np.ndarray, np.ndarray]:
    ms = mjcf.build(system, dt=dt, visual=False, **solver.pop("build", {}))
    if "timeconst" in solver:
        ms.model.eq_solref[:, 0] = solver["timeconst"]
    ms.model.opt.tolerance, ms.model.opt.iterations = 1e-15, 50  # converged, 12x faster
    tau = system.input_matrix @ sim.operating_point.u
    return rollout(ms, system, sim.q[0], sim.v[0], tau, sim.t)


def _solo12(gravity):
    scene = pinlin.Scene.from_robot("solo12", base="free",
                                    effects={} if gravity is None else {"gravity": gravity})
    nv = scene.system.nv  # (q0, v0 = 0) given below: no inputs, a free fall under gravity
    dx0 = np.zeros(2 * nv)
    dx0[3:6] = [0.4, -0.3, 0.5]                                    # a rotated base
    dx0[nv:nv + 6] = [0.3, -0.2, 0.1, 2.0, -1.5, 1.0]               # base twist (base frame)
    dx0[nv + 6:] = np.linspace(-3.0, 3.0, 12)
    return scene, dx0


@pytest.mark.parametrize("case", ["ur5_arm", "solo12_free_fall"])
def test_open_chains_match_mujoco_rk4(case):
    """MuJoCo RK4 at dt = 1e-4 s from the same state: agreement within 3x the sum of the two
    integrators' errors, each estimated from its order: RK4 by halving dt
    (|x(2dt) - x(dt)| / 15), pinlin by rerunning at 100x the tolerance."""
    if case == "ur5_arm":
        scene = pinlin.Scene.resolve("ur5_arm")
        dx0 = np.r_[0.1 * np.ones(6), 0.5 * np.ones(6)]
    else:
        scene, dx0 = _solo12([0.0, 0.0, -G])
    system = scene.system
    given = {} if case == "ur5_arm" else {"v0": np.zeros(system.nv)}  # the state, u0 = 0
    t = np.linspace(0.0, 0.5, 11)
    sim = pinlin.simulate(scene, t, dx0=dx0, rtol=1e-12, atol=1e-14, **given)
    loose = pinlin.simulate(scene, t, dx0=dx0, rtol=1e-10, atol=1e-12, **given)
    Q1, V1 = _mujoco(system, sim, 1e-4)
    Q2, V2 = _mujoco(system, sim, 2e-4)
    rk4 = np.array(_difference(system, Q1, V1, Q2, V2)) / 15
    own = np.array(_difference(system, sim.q, sim.v, loose.q, loose.v)) / 100
    error = np.array(_difference(system, sim.q, sim.v, Q1, V1))
    assert np.all(error <= 3 * (rk4 + own) + 1e-13), (error, rk4, own)
    assert np.all(error < [1e-9, 1e-8])


def test_four_bar_matches_mujoco_within_its_soft_constraint_leak():
    """MuJoCo's loop is soft: it leaks a fraction 1 - d of the unconstrained acceleration
    (impedance d = 0.9999) and corrects the violation with a time constant tau = 2 dt, both
    first-order model errors; MuJoCo's own runs measure them: tau doubled (|x(2tau) - x(tau)|),
    1 - d times ten (|x(0.999) - x(0.9999)| / 9), plus RK4's error (dt halved, / 15). pinlin
    must agree within 3x that estimate (a planted error, e.g. a missing spring, is ~1e-3)."""
    system = pinlin.Scene.resolve("four_bar").system
    t = np.linspace(0.0, 0.5, 11)
    sim = pinlin.simulate("four_bar", t, dx0=[0.3, 1.0], rtol=1e-12, atol=1e-14)
    dt = 1e-4
    A = _mujoco(system, sim, dt, timeconst=2 * dt)
    B = _mujoco(system, sim, dt, timeconst=4 * dt)
    C = _mujoco(system, sim, dt, timeconst=2 * dt, build={"impedance": 0.999})
    D = _mujoco(system, sim, 2 * dt, timeconst=4 * dt)
    leak = (np.array(_difference(system, *A, *B)) + np.array(_difference(system, *A, *C)) / 9
            + np.array(_difference(system, *B, *D)) / 15)
    error = np.array(_difference(system, sim.q, sim.v, *A))
    assert np.all(error <= 3 * leak), (error, leak)
    assert np.all(error < [1e-8, 1e-6])


def test_floating_base_conserves_angular_momentum():
    """solo12 in zero gravity with an initial twist: the centroidal momentum (Pinocchio's
    computeCentroidalMomentum) is constant to 100 rtol; the chart is re-centred on the way."""
    scene, dx0 = _solo12(None)
    model = scene.system.model
    data = model.createData()
    sim = pinlin.simulate(scene, np.linspace(0.0, 3.0, 31), dx0=dx0)
    h = np.array([pin.computeCentroidalMomentum(model, data, q, v).vector.copy()
                  for q, v in zip(sim.q, sim.v, strict=True)])
    assert np.abs(h - h[0]).max() < 100 * sim.info["rtol"] * np.abs(h[0]).max()
    assert sim.info["restarts"]["chart"] > 0
    np.testing.assert_allclose(np.linalg.norm(sim.q[:, 3:7], axis=1), 1.0, atol=1e-15)


# ------------------------------------------------------------------------------------------------
def _free_rotor():
    """urdf/pendulum.urdf without gravity: J theta'' = u, J = 1.001 kg*m^2."""
    return pinlin.Scene.from_urdf(URDF_DIR / "pendulum.urdf", effects={})


def test_held_and_callable_inputs_give_the_exact_motion():
    t = np.linspace(0.0, 2.0, 41)
    samples = np.where(t >= 0.5, 1.0, 0.0)[:, None]               # a step, held
    held = pinlin.simulate(_free_rotor(), t, u=samples)
    exact = np.where(t >= 0.5, (t - 0.5) ** 2 / (2 * J_PENDULUM), 0.0)
    np.testing.assert_allclose(held.x[:, 0], exact, atol=1e-12)
    np.testing.assert_array_equal(held.u, samples)
    assert held.info["restarts"]["input"] == 1
    assert held.energy is None and "inputs" in held.info["energy"]
    smooth = pinlin.simulate(_free_rotor(), t, u=lambda s: [np.sin(s)])
    np.testing.assert_allclose(smooth.x[:, 0], (t - np.sin(t)) / J_PENDULUM, atol=1e-10)


def test_stiff_scene_is_integrated_implicitly():
    """A heavily damped pendulum (c = 50 N*m*s/rad: decay rates 50 and 0.2 1/s) over 30 s:
    rho T = 1500 > 1e3 chooses Radau, which agrees with DOP853 (forced) at fewer evaluations."""
    scene = pinlin.Scene.from_urdf(URDF_DIR / "pendulum.urdf",
                                   effects={"gravity": [0, 0, -G], "damping": {"hinge": 50.0}})
    t = np.linspace(0.0, 30.0, 31)
    stiff = pinlin.simulate(scene, t, dx0=[1.0, 0.0], rtol=1e-8, atol=1e-10)
    explicit = pinlin.simulate(scene, t, dx0=[1.0, 0.0], rtol=1e-8, atol=1e-10,
                               method="DOP853")
    assert stiff.info["method"] == "Radau" and explicit.info["method"] == "DOP853"
    assert stiff.info["stiffness"] > 1e3
    np.testing.assert_allclose(stiff.x, explicit.x, atol=1e-7)
    assert stiff.info["nfev"] < explicit.info["nfev"]
    assert np.all(np.diff(stiff.energy) <= 1e-12)  # damping only dissipates


def test_a_saddle_is_not_stiff_and_its_horizon_counts_its_growth():
    """The pendulum released 0.04 rad from upright: the Jacobian's lambda = +-3.13 1/s. Its
    decay half is no stiffness (rho T = 1250 over 400 s chose Radau: 121 290 steps, 41 s,
    against DOP853's 1 s), and its growth is a rate to resolve: 1e7 s (5e6 periods of it)
    is refused before integrating (it ran for days, since only Im lambda was counted)."""
    t = np.linspace(0.0, 400.0, 401)
    sim = pinlin.simulate("pendulum", t, dx0=[3.1, 0.0])
    assert sim.info["method"] == "DOP853" and sim.info["stiffness"] > 1e3, sim.info
    with pytest.raises(pinlin.ArgumentError, match="periods of the fastest growing motion"):
        pinlin.simulate("pendulum", [0.0, 1e7], dx0=[3.1, 0.0])


def test_a_fast_oscillation_damped_away_is_stiff():
    """A pendulum on a stiff, strongly damped servo (lambda = -6993 +- 7141i 1/s) over 20 s:
    its oscillation is gone within 7 ms, after which only stability limits an explicit
    method's steps: Radau (0.7 s), where counting that oscillation over the whole horizon
    chose DOP853 (19 s)."""
    scene = pinlin.Scene.from_urdf(URDF_DIR / "pendulum.urdf", effects={
        "gravity": [0, 0, -G], "damping": {"hinge": 14000.0},
        "springs": {"hinge": {"stiffness": 1e8}}})
    sim = pinlin.simulate(scene, np.linspace(0.0, 20.0, 6), dx0=[0.01, 0.0])
    assert sim.info["method"] == "Radau", sim.info


def test_outputs_and_names():
    sim = pinlin.simulate("four_bar", [0.0, 0.1], dx0=[0.1, 0.0])
    model = pinlin.linearize("four_bar")
    assert sim.output_names == model.output_names
    np.testing.assert_allclose(sim.y[0], model.operating_point.y + model.C @ [0.1, 0.0],
                               atol=1e-2)
    assert sim.x.shape == (2, 6) and sim.z.shape == (2, 2) and sim.u.shape == (2, 1)
    assert sim.independent_names == model.state_names
    assert not sim.x.flags.writeable


@pytest.mark.parametrize("kwargs, error, match", [
    ({"t": [0.0, 0.0]}, pinlin.ArgumentError, "strictly increasing"),
    ({"t": [0.0, 1.0], "dx0": [1.0]}, pinlin.ShapeError, "2 nv = 2"),
    ({"t": [0.0, 1.0], "u": np.zeros((3, 1))}, pinlin.ArgumentError, r"\(2, 1\)"),
    ({"t": [0.0, 1.0], "method": "Euler"}, pinlin.ArgumentError, "DOP853"),
    ({"t": [0.0, 1.0], "rtol": 0.0}, pinlin.ArgumentError, "> 0"),
    ({"t": [0.0, 1.0], "rtol": 1e-15}, pinlin.ArgumentError, "below 2.22e-14"),
    ({"t": np.arange(1_000_001) * 1e-6}, pinlin.ArgumentError,
     "1000001 output times; at most 1000000"),
    # read as numbers by np.array, or beyond what a float resolves: refused, not simulated
    ({"t": [0.0, 1.0], "dx0": ["0.1", "0"]}, pinlin.ArgumentError, "got text"),
    ({"t": [0.0, 1.0], "dx0": [True, False]}, pinlin.ArgumentError, "got booleans"),
    ({"t": [0.0, 1.0], "dx0": [1e300, 0.0]}, pinlin.ArgumentError,
     r"positions \[m or rad\] are limited"),
    ({"t": [0.0, 1.0], "dx0": [0.0, 1e13]}, pinlin.ArgumentError, "velocities are limited"),
    # 1e9 s of a 3.1 rad/s pendulum: 5e8 periods (an integrator would run for days)
    ({"t": [0.0, 1e9], "dx0": [0.1, 0.0]}, pinlin.ArgumentError,
     r"spans 4.9\d+e\+08 periods of the fastest oscillation \(3.1\d rad/s"),
    ({"t": [0.0, 1e9], "dx0": [0.1, 0.0], "method": "Radau"}, pinlin.ArgumentError,
     "simulate a shorter horizon"),
])
def test_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        pinlin.simulate("pendulum", **kwargs)


def test_signal_input_is_the_same_function_of_time():
    """``u=pinlin.step(...) + pinlin.harmonic(...)`` drives the same motion as the callable
    a + b sin(w t) written out by hand (before, a TypeError); an impulse is refused."""
    t = np.linspace(0.0, 2.0, 101)
    signal = pinlin.step({"hinge": 1e-3}) + pinlin.harmonic({"hinge": 2e-3}, 3.0)
    by_signal = pinlin.simulate("pendulum", t, u=signal)
    by_hand = pinlin.simulate("pendulum", t,
                              u=lambda tk: np.array([1e-3 + 2e-3 * np.sin(3.0 * tk)]))
    # The two u(t) differ by rounding (~1e-19 N*m): the same steps, or at worst runs that each
    # meet atol = 1e-12 per step over ~100 steps (measured: identical).
    np.testing.assert_allclose(by_signal.z, by_hand.z, rtol=0, atol=1e-10)
    assert np.abs(by_signal.z).max() > 1e-4
    with pytest.raises(pinlin.ArgumentError, match="impulse is a jump of the velocities"):
        pinlin.simulate("pendulum", t, u=pinlin.impulse({"hinge": 1.0}))


def _held_double_pendulum(robot: str, axis: str | None, folder) -> pinlin.Scene:
    """example-robot-data's double pendulum ``robot`` held at joint1 = 1 by its inputs, its
    joints' axes ``axis`` (None: as given, +x)."""
    data = {"name": "held", "base": "fixed", "effects": {"gravity": [0.0, 0.0, -9.81]},
            "operating_point": {"q": {"joint1": 1.0}, "solve": "inputs"},
            "inputs": {"actuated": "all"}}
    if axis is None:
        return pinlin.Scene.from_dict({**data, "robot": robot})
    import re

    from pinlin.robots import load_robot

    text = Path(load_robot(robot).urdf_path).read_text()
    text = re.sub(r"<visual>.*?</visual>|<collision>.*?</collision>", "", text, flags=re.S)
    urdf = folder / f"{robot}.urdf"
    urdf.write_text(re.sub(r'<axis\s+xyz="1 0 0"\s*/>', f'<axis xyz="{axis}"/>', text))
    return pinlin.Scene.from_urdf(urdf, **data)


@pytest.mark.parametrize("axis", [None, "-1 0 0"], ids=["axis_x", "axis_minus_x"])
@pytest.mark.parametrize("dx0", [[0.0, 0.0, 15.0, 0.0], [4.0, 0.0, 0.0, 0.0]],
                         ids=["spinning", "started_beyond_pi"])
def test_a_continuous_joint_is_followed_in_turns(dx0, axis, tmp_path):
    """example-robot-data's double pendulum with continuous joints (cos, sin) and its
    revolute twin have the same dynamics, so the same motion: the reference. Measured through
    difference(q0, q) the continuous angle wrapped at pi: the history read -2.28 where the
    user started it at 4 rad, and the energy jumped by 2 pi u0 = 3.96 J at every turn of a
    spinning joint held by u0 (the revolute twin: 1e-12 J). An axis other than +x, +y or +z
    makes Pinocchio's unaligned joint (JointModelRevoluteUnboundedUnaligned): followed alike."""
    t = np.linspace(0.0, 1.0, 101)
    twin = pinlin.simulate(_held_double_pendulum("double_pendulum", axis, tmp_path), t,
                           dx0=dx0)
    scene = _held_double_pendulum("double_pendulum_continuous", axis, tmp_path)
    kinds = {j.kind for j in scene.system.joints.values()}
    assert kinds == ({"JointModelRUBX"} if axis is None else
                     {"JointModelRevoluteUnboundedUnaligned"})
    sim = pinlin.simulate(scene, t, dx0=dx0)
    assert sim.state_names == twin.state_names
    np.testing.assert_allclose(sim.x, twin.x, rtol=0, atol=1e-7 * np.abs(twin.x).max())
    assert sim.x[0, 0] == dx0[0]
    assert np.ptp(sim.energy) <= 1e-8 * np.abs(sim.energy).max()
