"""pinlin.validity against references from outside the code under test: the pendulum's
amplitude-dependent period (T = T0 (1 + theta0^2/16 + ...)), a hand-written one-coordinate
ODE of the inverted pendulum integrated by scipy, and the orders of the error that a Taylor
expansion of the equations of motion predicts (odd nonlinearity: 3; quadratic terms: 2; a
point that is not an equilibrium: 1).
"""

from __future__ import annotations

import dataclasses
import importlib
import math

import numpy as np
import pytest
import scipy.linalg as sla
from conftest import REPO, URDF_DIR
from scipy.integrate import solve_ivp
from scipy.linalg import expm

import pinlin
from pinlin.graph import Graph
from pinlin.validity import Bound

#: The module (``pinlin.validity`` is the function): its constants and planted failures.
VM = importlib.import_module("pinlin.validity")
VS = importlib.import_module("pinlin.validity_sweep")   # the sweep: simulate, the order

G = 9.81
#: urdf/pendulum.urdf: 1 kg sphere (r = 0.05 m) 1 m below the hinge: J = 1 + 2/5 * 0.05^2.
L_EQ = 1.001
W0 = math.sqrt(G / L_EQ)
#: The pendulum's errors near its radius, well inside the default sweep (faster tests).
PENDULUM_AMPLITUDES = [0.01, 0.02, 0.04, 0.1, 0.2]


def pendulum_radius(tolerance: float, periods: float) -> float:
    """Hand estimate. T(a) = T0 (1 + a^2/16): after P periods the nonlinear motion lags by
    dphi = 2 pi P a^2/16. Released from rest, Dnl - Dlin = a (cos(w' t) - cos(w t)) has the
    envelope 2 a sin(dphi t / (2 P T0)) ~ a dphi t / (P T0): e_v = dphi (the velocity error's
    carrier peaks at t = P T0), e_q = dphi (1 - 1/(4P)) (a quarter period earlier), so
    e = max(e_q, e_v) = dphi = 2 pi P a^2/16 = tol at a = sqrt(8 tol / (pi P)).

    Neglected, relative to dphi at a ~ 0.07: the next period term 11 a^4/3072 (0.03%), the
    third harmonic a^3/192 (0.003%), 2 sin(dphi/2) vs dphi (0.002%), the sampled maximum
    (<= 0.05%); the radius lies within 3% / (p - 1) = 1.5% below the crossing (the secant
    stops at 0.97 tol <= e <= tol, e ~ a^2). Hence radius / estimate in [0.985, 1.001]."""
    return math.sqrt(8.0 * tolerance / (math.pi * periods))


@pytest.fixture(scope="module")
def pendulum():
    return pinlin.validity("pendulum", PENDULUM_AMPLITUDES)


# ------------------------------------------------------------------------------------------------
def test_pendulum_radius_matches_the_period_estimate(pendulum):
    case = pendulum.cases[0]
    expected = pendulum_radius(0.01, 5)
    assert case.bound is Bound.FOUND and case.kind == "undamped" and case.label == "mode 1"
    assert 0.985 <= case.radius / expected <= 1.001, (case.radius, expected)
    assert 0.97 * 0.01 <= case.error_at_radius <= 0.01
    assert case.horizon == pytest.approx(5 * 2 * math.pi / W0, rel=1e-12)
    np.testing.assert_allclose(case.excursions, [case.radius])
    assert pendulum.equilibrium and pendulum.drift == 0.0 and pendulum.notes == ()
    # The error at each tabulated amplitude follows dphi = 2 pi P a^2 / 16 (neglected terms as
    # above: < 0.1% at a <= 0.1, ~0.5% at a = 0.2 from 11 a^4/3072 over a^2/16).
    for a, e in zip(case.amplitudes, case.errors, strict=True):
        assert e == pytest.approx(2 * math.pi * 5 * a**2 / 16, rel=6e-3 if a > 0.15 else 2e-3)


def test_pendulum_error_is_third_order_and_the_radius_grows_with_the_tolerance(pendulum):
    """sin(theta) is odd: no quadratic terms, the error in rad is a * dphi ~ a^3 (order 3,
    not the generic 2). e ~ a^2, so the radius scales as sqrt(tolerance): x4 gives x2 (each
    radius within [0.985, 1] of its crossing: ratio within 1.5%)."""
    assert pendulum.slope[0] == pytest.approx(3.0, abs=0.1)
    assert "third order" in pendulum.cases[0].diagnosis
    loose = pinlin.validity("pendulum", PENDULUM_AMPLITUDES, tolerance=0.04)
    assert loose.radius[0] > pendulum.radius[0]
    assert loose.radius[0] / pendulum.radius[0] == pytest.approx(2.0, rel=0.016)


def test_four_bar_error_is_second_order():
    """A linkage at a generic posture has quadratic terms (M(q), gravity and spring torques
    vary to first order): the error in rad is ~ a^2 at small a."""
    result = pinlin.validity("four_bar", [1e-3, 2e-3, 4e-3, 8e-3])
    assert result.slope[0] == pytest.approx(2.0, abs=0.1)
    assert "second order" in result.cases[0].diagnosis
    assert result.cases[0].bound is Bound.FOUND
    # The loop stays closed: the simulated motions are those of the mechanism's z = crank.
    assert result.cases[0].nonlinear.shape[1] == 2


def test_non_equilibrium_point_gives_first_order_error_and_says_so():
    """Released from rest at 0.5 rad (v given: u0 = 0 does not hold it), the affine model
    x' = f0 + A x about that state misses how the tangent dynamics change along the swing:
    the deviations differ at first order, error in rad ~ a (order 1)."""
    result = pinlin.validity("pendulum", [1e-3, 2e-3, 4e-3], q=np.array([0.5]),
                                      v=np.array([0.0]))
    assert not result.equilibrium
    assert result.drift == pytest.approx(G * math.sin(0.5) / L_EQ, rel=1e-9)  # [rad/s^2]
    assert result.slope[0] == pytest.approx(1.0, abs=0.1)
    assert "first order" in result.cases[0].diagnosis
    assert any(n.startswith("not an equilibrium") for n in result.notes)
    case = result.cases[0]
    assert case.bound is Bound.BELOW_RANGE
    # The linear deviation is a e^{At} d, without the drift f0 (matrix exponential by scipy).
    expected = np.array([expm(result.model.A * t) @ (case.radius * case.direction)
                         for t in case.t[::50]])
    np.testing.assert_allclose(case.linear[::50], expected, atol=1e-12 * case.radius)


def test_perturbed_u0_gives_first_order_error_at_small_amplitudes():
    """u0 = 0.05 N*m on the hanging pendulum (it should be 0): the unperturbed motion swings
    about 0.005 rad; at amplitudes below that the error is first order."""
    scene = pinlin.Scene.load(URDF_DIR / "pendulum.toml")
    point = dataclasses.replace(scene.operating_point, solve="none", u={"hinge": 0.05})
    result = pinlin.validity(dataclasses.replace(scene, operating_point=point),
                                      [1e-3, 2e-3, 4e-3])
    assert not result.equilibrium and result.slope[0] < VS.FIRST_ORDER
    assert result.cases[0].reference_drift > 1e-3   # the unperturbed motion [rad, rad/s]


def test_inverted_pendulum_against_a_hand_written_ode():
    """theta'' = (g / L_eq) sin(theta) about the top, modes lambda = +-W0. The unstable mode
    starts at (a, W0 a) and is compared over T = 2 / W0 (growth e^2); the error at the radius
    recomputed from scipy's solution of the hand-written ODE (rtol 1e-12) and a e^{W0 t}."""
    result = pinlin.validity("pendulum", [0.01, 0.03, 0.1], q=np.array([math.pi]))
    kinds = {c.kind: c for c in result.cases}
    assert set(kinds) == {"unstable", "real"}
    up = kinds["unstable"]
    assert up.horizon == pytest.approx(2.0 / W0, rel=1e-12)
    assert up.peak == pytest.approx(math.e**2 * up.radius, rel=0.05)   # grows by ~e^2
    a, t = up.radius, up.t
    sol = solve_ivp(lambda _, s: [s[1], W0**2 * math.sin(s[0])], (0.0, t[-1]), [a, W0 * a],
                    t_eval=t, rtol=1e-12, atol=1e-14, method="DOP853").y.T
    lin = a * np.exp(W0 * t)[:, None] * np.array([1.0, W0])
    e = max(np.abs(sol[:, k] - lin[:, k]).max() / np.abs(lin[:, k]).max() for k in (0, 1))
    assert up.error_at_radius == pytest.approx(e, rel=1e-6)
    assert up.slope == pytest.approx(3.0, abs=0.1)
    assert kinds["real"].radius > up.radius   # the decaying motion stays near the top


def test_damped_mode_starts_from_the_real_part_of_its_shape():
    """UR5 (servo springs and dampers): d = [Re(phi); Re(lambda phi)] with phi the mode shape
    of pinlin.modal (largest entry 1); the error is second order; the horizon is 5 damped
    periods (over which the envelope decays by e^-2.7 only: the e^-DECAY cap is not reached)."""
    result = pinlin.validity("ur5_arm", [1e-3, 2e-3, 4e-3], modes=[0])
    case, ma = result.cases[0], result.modes
    phi, lam = ma.shapes[:, 0], ma.eigenvalues[0]
    assert case.kind == "oscillatory" and lam.real < 0
    np.testing.assert_allclose(case.direction, np.concatenate([phi.real, (lam * phi).real]),
                               rtol=1e-12, atol=1e-12)
    assert case.horizon == pytest.approx(5 * 2 * math.pi / lam.imag, rel=1e-12)
    assert case.slope == pytest.approx(2.0, abs=0.1)
    assert case.bound is Bound.ABOVE_RANGE and case.radius == 4e-3


@pytest.mark.parametrize("lam, expected", [
    (2j, (5 * math.pi, math.pi, "5 periods")),                       # undamped
    (0.01 + 2j, (5 * math.pi, math.pi, "5 periods")),                # slow growth: e^0.16
    (1.0 + 2j, (2.0, math.pi, "growth e^2 (unstable)")),             # e^2 before 5 periods
    (-1.0 + 2j, (10.0, math.pi, "decay e^-10")),                     # e^-10 before 5 periods
    (-4.0 + 0j, (0.5, 0.0, "2 time constants (decay e^-2)")),
    (4.0 + 0j, (0.5, 0.0, "2 time constants (growth e^2)")),
    (1e-5 + 0j, (1000 * 2 * math.pi / 2.0, 0.0, "1000 periods of the fastest mode (a slow "
                                                  "real mode)")),
])
def test_horizon_rules(lam, expected):
    """The rules of the module docstring, for periods = 5 and time_constants = 2 [s]: the mode
    lam of a model whose fastest mode is +-2j rad/s (rigid_tol 1e-6)."""
    block = [[lam.real, lam.imag], [-lam.imag, lam.real]] if lam.imag else [[lam.real]]
    A = sla.block_diag(block, [[0.0, 2.0], [-2.0, 0.0]])
    n = A.shape[0]
    model = pinlin.LinearModel(A, np.zeros((n, 1)), np.eye(n), np.zeros((n, 1)),
                               [f"x{k}" for k in range(n)], ["u"], [f"y{k}" for k in range(n)])
    ma = pinlin.modal(model, rigid_tol=1e-6)
    index = int(np.argmin(np.abs(ma.eigenvalues - lam)))
    T, period, rule = VM._mode_horizon(index, ma, 5.0, 2.0)
    assert (T, period) == pytest.approx(expected[:2], rel=1e-12) and rule == expected[2]


def test_slow_modes_beside_a_fast_one_keep_their_kind():
    """A mode far slower than the fastest (rigid_tol 10 beside -1e7) keeps its imaginary
    part and its sign of growth: -100 +- 5j oscillates (5 periods, capped by the decay),
    +5 +- 100j grows (not 'undamped'), and the model is unstable."""
    for block, kind in (([[-100.0, 5.0], [-5.0, -100.0]], "oscillatory"),
                        ([[5.0, 100.0], [-100.0, 5.0]], "unstable osc.")):
        A = sla.block_diag(block, [[-1e7]])
        model = pinlin.LinearModel(A, np.zeros((3, 1)), np.eye(3), np.zeros((3, 1)),
                                   ["x0", "x1", "x2"], ["u"], ["y0", "y1", "y2"])
        ma = pinlin.modal(model)
        assert ma.rigid_tol == pytest.approx(10.0)
        assert [ma.kind(i) for i in range(3)] == [kind, kind, "real"]
        assert ma.modes() == [0, 2] and ma.oscillates(0) and not ma.oscillates(2)
        assert list(ma.unstable) == [kind == "unstable osc."] * 2 + [False]
        assert ma.is_stable == (kind == "oscillatory")
        assert "+- 5j" in ma.table() or "+- 100j" in ma.table()
        T, period, rule = VM._mode_horizon(0, ma, 5.0, 2.0)
        if kind == "oscillatory":   # 5 periods of 2 pi / 5 s = 6.3 s, decay e^-10 at 0.1 s
            assert (T, rule) == (pytest.approx(10.0 / 100.0), "decay e^-10")
        else:                       # growth e^2 at 0.4 s, before 5 periods (0.31 s)
            assert (T, rule) == (pytest.approx(5 * 2 * math.pi / 100.0), "5 periods")
        assert period == pytest.approx(2 * math.pi / abs(ma.eigenvalues[0].imag))


def test_direction_and_velocity_kick_match_the_mode():
    """On one coordinate the direction 'hinge' is the mode's initial state (a, 0); a velocity
    kick w a reaches the same motion a quarter period earlier, so over the same horizon its
    radius [rad/s] is ~W0 times the mode's [rad] (not exactly: the horizons are shifted)."""
    result = pinlin.validity("pendulum", [0.05, 0.1, 0.2], periods=2, modes=[0],
                                      direction="hinge")
    mode, direction = result.cases
    assert direction.label == "direction q:hinge" and direction.kind == "direction"
    assert direction.radius == pytest.approx(mode.radius, rel=1e-12)
    kick = pinlin.validity("pendulum", [0.2, 0.4, 0.8], periods=2, direction=[0, 1])
    assert kick.cases[0].unit == "rad/s or m/s"
    assert kick.radius[0] / W0 == pytest.approx(mode.radius, rel=0.1)


def test_order_leaves_out_integration_noise_and_saturated_errors():
    """At a = 1e-7 and 1e-6 the pendulum's true e (2e-14, 2e-12) is far below the integration
    noise (~atol / a: 1e-5, 1e-6), at 0.5 the motions have parted (e = 0.47 > SATURATION):
    the order comes from 2e-3 and 4e-3 alone, still 3."""
    result = pinlin.validity("pendulum", [1e-7, 1e-6, 2e-3, 4e-3, 0.5],
                                      tolerance=0.9)     # no refinement: e < 0.9 everywhere
    case = result.cases[0]
    assert case.bound is Bound.ABOVE_RANGE
    assert case.errors[0] > 1e3 * 2 * math.pi * 5 * 1e-14 / 16    # noise, not the error
    assert case.errors[-1] > VS.SATURATION
    assert case.slope == pytest.approx(3.0, abs=0.02)
    assert "from a = 0.002, 0.004)" in case.diagnosis


def test_failed_simulations_count_as_beyond_tolerance(monkeypatch):
    """A mechanism can leave its assembly branch at large amplitudes: simulate raises
    ModelError, the amplitude counts as beyond the tolerance and the note names it."""
    real = VS.simulate

    def failing(system, t, dx0=None, **options):
        if dx0 is not None and np.abs(dx0).max() > 0.06:
            raise pinlin.ModelError("the loops do not close (planted)")
        return real(system, t, dx0=dx0, **options)

    monkeypatch.setattr(VS, "simulate", failing)
    result = pinlin.validity("pendulum", [0.01, 0.02, 0.04, 0.1])
    case = result.cases[0]
    assert case.bound is Bound.FOUND and case.radius <= 0.06
    assert np.isinf(case.errors[-1]) and "planted" in case.failures[-1]
    assert any("failed" in n and "planted" in n for n in result.notes)


def test_table_and_plots(pendulum, tmp_path):
    text = pendulum.table()
    assert "mode 1" in text and "<- radius" in text and "third order" in text
    assert str(pendulum).count("\n") < text.count("\n")
    paths = pendulum.plot(tmp_path, "pend")
    assert [p.name for p in paths] == ["pend_histories.png", "pend_errors.png"]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)
    assert pendulum.case("mode 1") is pendulum.cases[0]
    with pytest.raises(pinlin.ArgumentError, match="no case 'mode 9'"):
        pendulum.case("mode 9")


def test_result_is_read_only(pendulum):
    with pytest.raises(dataclasses.FrozenInstanceError):
        pendulum.tolerance = 0.5
    with pytest.raises(ValueError, match="read-only"):
        pendulum.cases[0].errors[0] = 0.0


# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, error, message", [
    ({"tolerance": -0.01}, pinlin.ArgumentError,
     r"tolerance.*expected a finite number > 0 and < 1 \(relative error\), got -0.01"),
    ({"tolerance": 0.0}, pinlin.ArgumentError, r"tolerance.*> 0 and < 1"),
    ({"periods": 1e9}, pinlin.ArgumentError, "argument 'periods': expected at most 100000 periods"),
    ({"tolerance": 1.5}, pinlin.ArgumentError, r"tolerance.*> 0 and < 1"),
    ({"tolerance": True}, pinlin.ArgumentError, r"tolerance.*expected a number.*got bool"),
    ({"amplitudes": []}, pinlin.ArgumentError,
     r"amplitudes.*expected at least one amplitude \[rad, or L for a length\], got an empty "
     r"sequence"),
    ({"amplitudes": [0.1, -0.1]}, pinlin.ArgumentError, r"amplitudes.*> 0"),
    ({"amplitudes": [0.1, math.nan]}, pinlin.ArgumentError, r"amplitudes.*finite"),
    ({"amplitudes": "0.1"}, pinlin.ArgumentError, r"amplitudes.*got text"),
    ({"amplitudes": [True]}, pinlin.ArgumentError, r"amplitudes.*got booleans"),
    ({"amplitudes": [0.1, 2e6]}, pinlin.ArgumentError,
     r"amplitudes.*<= 1e\+06 .*got \[2000000\.\]"),
    # solver tolerances whose noise (1e3 rtol + 1e3 atol / a) reaches the 1 % tolerance: the
    # "radius" would be the solver's (atol = 1e10 gave 0.001 rad for the pendulum's 0.159)
    ({"atol": 1e10}, pinlin.ArgumentError, r"argument 'atol'.*or atol <= 1e-09"),
    ({"rtol": 1e-3}, pinlin.ArgumentError, r"argument 'rtol'.*tolerance above 1 or rtol <= 1e-06"),
    ({"periods": 0}, pinlin.ArgumentError, r"periods.*> 0"),
    ({"time_constants": -1.0}, pinlin.ArgumentError, r"time_constants.*> 0"),
    ({"horizon": math.inf}, pinlin.ArgumentError, r"horizon.*finite number > 0 \[s\]"),
    ({"modes": [5]}, pinlin.ArgumentError, r"modes.*no mode 5: expected one of \[0\]"),
    ({"modes": []}, pinlin.ArgumentError, r"modes.*at least one eigenvalue index \(one of "
                                          r"\[0\]\) or a direction=, got none"),
    ({"modes": ["1"]}, pinlin.ArgumentError, r"modes.*eigenvalue indices \(ints\)"),
    ({"modes": "0"}, pinlin.ArgumentError, r"modes.*eigenvalue indices \(ints\), got str"),
    ({"direction": "elbow"}, pinlin.ArgumentError,
     r"direction.*no coordinate 'elbow'; expected one of q:hinge, v:hinge"),
    ({"direction": [0.0, 0.0]}, pinlin.ArgumentError, r"direction.*not all zero"),
    ({"direction": [1.0, 0.0, 0.0]}, pinlin.ArgumentError, r"direction.*1 positions or 2"),
])
def test_bad_arguments(kwargs, error, message):
    with pytest.raises(error, match=message):
        pinlin.validity("pendulum", **kwargs)


BOX_URDF = """<?xml version="1.0"?>
<robot name="box"><link name="box"><inertial><mass value="1.0"/>
  <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link></robot>
"""


def test_rigid_mode_index_is_refused(tmp_path):
    """A free-floating box without gravity has only rigid modes: nothing oscillates."""
    (tmp_path / "box.urdf").write_text(BOX_URDF)
    scene = pinlin.Scene.from_urdf(tmp_path / "box.urdf", base="free", effects={})
    with pytest.raises(pinlin.ModelError, match="no non-rigid mode .*give direction= and "
                                                "horizon="):
        pinlin.validity(scene)
    with pytest.raises(pinlin.ArgumentError, match=r"modes.*mode 0 is rigid"):
        pinlin.validity(scene, modes=[0])
    with pytest.raises(pinlin.ArgumentError, match=r"horizon.*no non-rigid mode to set the "
                                                   r"direction's horizon"):
        pinlin.validity(scene, direction="root_joint[0]")


def test_graphs_and_linear_models_are_refused():
    graph = REPO / "validation" / "graphs" / "series_rlc.toml"
    with pytest.raises(pinlin.ModelError, match="'series_rlc' is a linear graph: it has no "
                                                "nonlinear multibody motion"):
        pinlin.validity(Graph.load(graph).linearize())
    with pytest.raises(pinlin.ModelError, match="a linear graph has no nonlinear"):
        pinlin.validity(Graph.load(graph))
    with pytest.raises(pinlin.ArgumentError, match="got the LinearModel 'pendulum'.*pass the "
                                                   "scene"):
        pinlin.validity(pinlin.linearize("pendulum"))


def test_cli_modes_are_the_mode_table_rows(capsys):
    """--modes K is row K of the printed mode table (it was taken as an eigenvalue index:
    --modes 0 and 1 both ran row 1, --modes 3 ran row 2); repeats and rows beyond the table
    are refused, and the library's argument names become the command's options."""
    from pinlin.cli import main

    assert main(["validity", "double_pendulum", "--periods", "1", "--modes", "2",
                 "--amplitudes", "0.001", "0.002", "0.004"]) == 0
    out = capsys.readouterr().out
    assert "mode 2 " in out and "mode 1 " not in out and "0 +- 7.04j" in out
    for args, message in ((["--modes", "0"], "argument '--modes': no mode 0: the mode table "
                                             "of 'double_pendulum' has rows 1 to 2"),
                          (["--modes", "3"], "no mode 3"),
                          (["--modes", "1", "1"], "argument '--modes': names a mode twice"),
                          (["--tolerance", "1e-8"], "argument '--tolerance': the tolerance "
                                                    "1e-08 is within the integration noise"),
                          (["--amplitudes", "2e6"], "argument '--amplitudes': expected")):
        assert main(["validity", "double_pendulum", *args]) == 2
        captured = capsys.readouterr()
        assert message in captured.err and captured.out == ""


def test_plots_leave_out_cases_whose_simulation_failed(monkeypatch, tmp_path):
    """A case whose every nonlinear run failed has no motion to draw (the plot raised
    TypeError on it)."""
    real = VS.simulate

    def failing(system, t, dx0=None, **options):
        if np.any(dx0):     # the unperturbed reference runs, every perturbed one fails
            raise pinlin.ModelError("the loops do not close (planted)")
        return real(system, t, dx0=dx0, **options)

    monkeypatch.setattr(VS, "simulate", failing)
    result = pinlin.validity("pendulum", [0.01, 0.02])
    assert result.cases[0].nonlinear is None
    paths = result.plot(tmp_path, "failed")
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in paths)


def test_atol_noise_is_judged_at_the_smallest_amplitude():
    """The solver's atol must stay far below the smallest amplitude it is asked about."""
    # 1e2 atol / a = 1e2 * 1e-6 / 1e-3 = 0.1 >= tolerance 0.01 (1e2 atol alone is 1e-4)
    with pytest.raises(pinlin.ArgumentError, match="argument 'atol'.*smallest amplitude"):
        pinlin.validity("pendulum", [1e-3], atol=1e-6, horizon=0.1)


def test_a_direction_horizon_ends_at_the_fastest_growth():
    """Two unstable modes (1 and 4 1/s) and an oscillation: the horizon is the faster
    growth's e^2, 2/4 s, and the period the oscillation's pi."""
    A = sla.block_diag([[1.0]], [[4.0]], [[0.0, 2.0], [-2.0, 0.0]])
    n = A.shape[0]
    model = pinlin.LinearModel(A, np.zeros((n, 1)), np.eye(n), np.zeros((n, 1)),
                               [f"x{k}" for k in range(n)], ["u"], [f"y{k}" for k in range(n)])
    ma = pinlin.modal(model, rigid_tol=1e-6)
    horizons = {i: VM._mode_horizon(i, ma, 5.0, 2.0) for i in ma.modes()
                if ma.kind(i) not in ("rigid", "constraint")}
    T, period, _ = VM._direction_horizon(ma, horizons, None)
    assert pytest.approx(2.0 / 4.0, rel=1e-12) == T  # e^2 of the mode growing at 4 1/s
    assert period == pytest.approx(math.pi, rel=1e-12)


WHEEL = """<?xml version="1.0"?>
<robot name="wheel">
  <link name="base"/>
  <link name="disk"><inertial><mass value="1.0"/>
    <inertia ixx="1.0" ixy="0" ixz="0" iyy="1.0" iyz="0" izz="1.0"/></inertial></link>
  <joint name="spin" type="continuous"><parent link="base"/><child link="disk"/>
    <axis xyz="0 0 1"/></joint>
</robot>"""


def test_a_spring_past_its_wrap_is_named_not_taken_for_a_first_order_error(tmp_path):
    """A disk (1 kg m^2) on a continuous joint with a 1 N*m/rad spring relaxed at 0, held at
    q0 = 3 rad: its linear model is exact (lambda = +-1j) until the deflection q - rest
    passes pi, where pinlin's spring (on the angle wrapped to (-pi, pi]) reverses. From rest
    at q0 + a the deflection is 3 + a at t = 0: beyond pi for a > pi - 3 = 0.1416. The
    simulation says so in its notes, and validity's radius lies between the default
    amplitudes that bracket pi - 3 (0.1 and 0.215), with the wrap named in its notes. The
    order used to be fitted to the parted motions alone and read "first order: the point is
    not an equilibrium", which it is."""
    urdf = tmp_path / "wheel.urdf"
    urdf.write_text(WHEEL)
    scene = pinlin.Scene.from_urdf(
        urdf, name="wheel", base="fixed",
        effects={"springs": {"spin": {"stiffness": 1.0, "rest": 0.0}}},
        operating_point={"q": {"spin": 3.0}, "solve": "inputs"})
    t = np.linspace(0.0, 1.0, 5)
    assert pinlin.simulate(scene, t, dx0=[0.1, 0.0]).info["spring_wraps"] == ()
    wraps = pinlin.simulate(scene, t, dx0=[0.2, 0.0]).info["spring_wraps"]
    assert len(wraps) == 1 and "continuous joint 'spin' passed its wrap: q - rest = 3.2 rad " \
                               "at t = 0 s" in wraps[0]
    result = pinlin.validity(scene, periods=1)
    case = result.cases[0]
    assert 0.1 <= case.radius <= np.pi - 3.0
    assert math.isnan(case.slope) and "order unknown" in case.diagnosis
    assert any("mode 1: from a = " in n and "passed its wrap" in n for n in result.notes)
    assert not any("first-order error" in n for n in result.notes)
