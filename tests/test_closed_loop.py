"""LinearModel.closed_loop (u = -K x + r) and pinlin.validity of a closed loop, against
references from outside the code under test: the poles a gain was placed at (scipy's
place_poles), eig(A - B K) formed by hand, the closed loop's exact response (expm), and the
odd nonlinearity of the inverted pendulum (error order 3)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.signal import place_poles

import pinlin


def _sorted(lam: np.ndarray) -> np.ndarray:
    return lam[np.lexsort((lam.imag, lam.real))]


@pytest.mark.parametrize("name, formulation", [("ur5_arm", "independent"),
                                               ("four_bar", "independent"),
                                               ("four_bar", "penalty"),
                                               ("delta", "independent")])
def test_closed_loop_is_a_minus_b_k_with_its_second_order_form(name, formulation):
    """A - B K and C - D K exactly; the stiffness K + Bu K_q and damping C_damp + Bu K_v that
    the model's constructor checks against A; modal's eigenvalues those of A - B K (eig by
    hand); the response the matrix exponential's."""
    model = pinlin.linearize(name, formulation=formulation)
    n, m = model.n_states, model.n_inputs
    K = np.random.default_rng(1).uniform(-2.0, 2.0, (m, n))
    loop = model.closed_loop(K)
    np.testing.assert_array_equal(loop.A, model.A - model.B @ K)
    np.testing.assert_array_equal(loop.C, model.C - model.D @ K)
    np.testing.assert_array_equal(loop.B, model.B)
    nv = n // 2
    np.testing.assert_array_equal(loop.K, model.K + model.Bu @ K[:, :nv])
    np.testing.assert_array_equal(loop.C_damp, model.C_damp + model.Bu @ K[:, nv:])
    expected = np.linalg.eigvals(model.A - model.B @ K)
    found = pinlin.modal(loop).eigenvalues
    if formulation == "penalty":   # the constraint modes sit decades above: compare relatively
        scale = np.abs(expected).max()
    else:
        scale = max(1.0, float(np.abs(expected).max()))
    np.testing.assert_allclose(_sorted(found), _sorted(expected), rtol=0, atol=1e-9 * scale)
    t = np.linspace(0.0, 0.5, 6)
    x0 = np.linspace(-1e-2, 1e-2, n)
    res = pinlin.response(loop, t, x0=x0, method="exact")
    exact = np.array([sla.expm((model.A - model.B @ K) * ti) @ x0 for ti in t])
    np.testing.assert_allclose(res.x, exact, rtol=0, atol=1e-10 * np.abs(exact).max())
    assert loop.info["closed_loop"] == f"u = -K x + r, K of shape ({m}, {n})"


def test_a_canonical_model_keeps_its_a_and_drops_the_second_order_form():
    model = pinlin.linearize("ur5_arm", formulation="canonical")
    K = np.ones((6, 12))
    loop = model.closed_loop(K)
    assert loop.M is None and loop.K is None
    np.testing.assert_array_equal(loop.A, model.A - model.B @ K)


@pytest.mark.parametrize("K, error, match", [
    (np.ones((6, 11)), pinlin.ArgumentError, r"shape \(6, 12\).*got shape \(6, 11\)"),
    (np.full((6, 12), np.nan), pinlin.ArgumentError, "NaN or inf"),
    ([["a"] * 12] * 6, pinlin.ArgumentError, "got text"),
])
def test_bad_gains(K, error, match):
    with pytest.raises(error, match=match):
        pinlin.linearize("ur5_arm").closed_loop(K)


def test_a_model_without_inputs_or_with_input_derivatives_is_refused():
    with pytest.raises(pinlin.ArgumentError, match="no inputs to feed back to"):
        pinlin.linearize("standing_box").closed_loop(np.zeros((0, 12)))
    A, B = np.array([[-1.0]]), np.array([[1.0]])
    with_e = pinlin.LinearModel(A, B, np.eye(1), np.zeros((1, 1)), ("x",), ("u",), ("y",),
                                E=np.array([[0.5]]), name="lead")
    with pytest.raises(pinlin.ModelError, match="input-derivative terms"):
        with_e.closed_loop([[1.0]])
    with_e.standard_form().closed_loop([[1.0]])   # what the message says to do


def test_a_feedthrough_enters_the_outputs():
    """y = C x + D u with u = -K x + r: C - D K (a direct feedthrough D = 2, by hand)."""
    model = pinlin.LinearModel(np.array([[-1.0, 0.0], [1.0, -2.0]]), np.array([[1.0], [0.0]]),
                               np.array([[0.0, 1.0]]), np.array([[2.0]]), ("x1", "x2"), ("u",),
                               ("y",), name="feedthrough")
    loop = model.closed_loop([[3.0, 5.0]])
    np.testing.assert_array_equal(loop.C, [[-6.0, -9.0]])
    np.testing.assert_array_equal(loop.A, [[-4.0, -5.0], [1.0, -2.0]])


def test_validity_of_the_inverted_pendulum_held_by_its_gain():
    """Upright, the pendulum's linear model holds only to 0.054 rad along its unstable mode
    (its growth ends every comparison: a fall). Under a gain placing the poles at -3 and -4
    the closed loop's modes are those poles (place_poles' target, to 1e-9) and its linear
    model holds to ~0.6 rad (1 % error over two time constants), the error of third order
    (the odd sin(theta): no quadratic term with a linear law)."""
    upright = pinlin.linearize("pendulum", q=[np.pi])
    K = place_poles(upright.A, upright.B, [-3.0, -4.0]).gain_matrix
    held = pinlin.validity("pendulum", q=[np.pi], feedback=K)
    poles = sorted(c.eigenvalue.real for c in held.cases)
    np.testing.assert_allclose(poles, [-4.0, -3.0], rtol=0, atol=1e-9)
    assert all(c.kind == "real" for c in held.cases)
    assert all(abs(c.slope - 3.0) < 0.05 for c in held.cases)
    assert min(c.radius for c in held.cases) > 0.3
    alone = pinlin.validity("pendulum", q=[np.pi], modes=[0])
    assert alone.cases[0].kind == "unstable" and alone.cases[0].radius < 0.1
    assert "closed loop u = -K x + r" in held.table().splitlines()[0]
    with pytest.raises(pinlin.ArgumentError, match="a callable has none to compare"):
        pinlin.validity("pendulum", q=[np.pi], feedback=lambda t, x: -K @ x)
    with pytest.raises(pinlin.ArgumentError, match=r"argument 'feedback'.*shape \(1, 2\)"):
        pinlin.validity("pendulum", q=[np.pi], feedback=np.ones((1, 3)))


def test_validity_of_a_mechanism_under_lqr_is_second_order():
    """The four-bar under LQR (python-control): its closed-loop linear model holds with a
    quadratic remainder (order 2, as open loop: the mechanism's geometry is not odd)."""
    control = pytest.importorskip("control")
    model = pinlin.linearize("four_bar")
    K = control.lqr(model.A, model.B, np.eye(2), np.eye(1))[0]
    held = pinlin.validity("four_bar", feedback=K)
    closed = np.linalg.eigvals(model.A - model.B @ K)
    for c in held.cases:   # each case's eigenvalue is one of A - B K's (eig by hand)
        assert np.abs(closed - c.eigenvalue).min() <= 1e-9 * abs(c.eigenvalue)
    assert all(abs(c.slope - 2.0) < 0.1 for c in held.cases)


def test_the_upright_double_pendulum_under_lqr_is_third_order():
    """Gravity is odd about upright and the law linear: no quadratic term, order 3. Its
    smallest amplitude's error (1.3e-7 at a = 1e-3) sits beside DOP853's noise there (130 atol
    / a: long steps, sampled through their dense output), which the noise floor once left in
    the fit (order 2.40)."""
    control = pytest.importorskip("control")
    upright = pinlin.linearize("double_pendulum", q=[np.pi, 0.0])
    K = control.lqr(upright.A, upright.B, np.eye(4), np.eye(2))[0]
    case = pinlin.validity("double_pendulum", q=[np.pi, 0.0], feedback=K, modes=[0]).cases[0]
    assert abs(case.slope - 3.0) < 0.05, case.diagnosis


def test_closed_loop_records_its_gain_and_what_it_changed():
    """The gain in info (each one, when closed twice), velocity terms once a velocity gain
    damps the model, (K, model) pairs checked, a discrete model without a second-order form."""
    model = pinlin.linearize("pendulum")
    assert model.info["velocity_terms"] is False
    loop = model.closed_loop([[0.0, 2.0]])
    assert loop.info["velocity_terms"] is True
    np.testing.assert_array_equal(loop.C_damp, [[2.0]])
    assert loop.info["closed_loop_gains"] == [[[0.0, 2.0]]]
    twice = loop.closed_loop((np.array([[1.0, 0.0]]), loop))
    assert twice.info["closed_loop_gains"] == [[[0.0, 2.0]], [[1.0, 0.0]]]
    assert "closed 2 times" in twice.info["closed_loop"]
    other = pinlin.linearize("pendulum", formulation="canonical")
    with pytest.raises(pinlin.ArgumentError, match=r"whose states \(p:hinge, q:hinge\) are not"):
        model.closed_loop(([[1.0, 0.0]], other))
    discrete = pinlin.LinearModel(
        np.eye(2), np.array([[0.0], [0.01]]), np.eye(2), np.zeros((2, 1)), ("q:a", "v:a"),
        ("u:a",), ("q:a", "v:a"), M=np.eye(1), C_damp=np.zeros((1, 1)), K=np.eye(1),
        Bu=np.eye(1), dt=0.01, name="hand_built")
    assert discrete.closed_loop([[1.0, 1.0]]).M is None   # A_d - B_d K: no M v' + ... form
    with pytest.raises(pinlin.ArgumentError, match=r"argument 'feedback'.*no inputs"):
        pinlin.validity("standing_box", feedback=np.zeros((1, 6)))
    lead = pinlin.LinearModel(np.array([[-1.0]]), np.eye(1), np.eye(1), np.zeros((1, 1)),
                              ("x",), ("u",), ("y",), F=np.eye(1), name="with_f")
    with pytest.raises(pinlin.ModelError, match="output term F u'"):
        lead.closed_loop([[1.0]])


def test_a_mechanisms_gain_over_all_coordinates():
    """A gain on the four-bar's 3 coordinates ([K_q, K_v], 1 x 6): on the model's state
    [dz; dz'] it is [K_q R, K_v R] (dq = R dz, v = R dz' to first order; R by hand from the
    loop's velocity constraint Phi_q R = 0 with R[crank] = 1), and validity compares it with
    simulate applying the wide law itself: a quadratic remainder (order 2)."""
    model = pinlin.linearize("four_bar")
    system = pinlin.Scene.resolve("four_bar").system
    G = system.constraints.jacobian(model.operating_point.q)
    crank = system.coordinate_names.index("crank")
    others = [k for k in range(3) if k != crank]
    R = np.zeros(3)
    R[crank] = 1.0
    R[others] = np.linalg.lstsq(G[:, others], -G[:, crank], rcond=None)[0]
    wide = np.array([[4.0, -1.0, 2.0, 0.5, 0.3, -0.2]])
    narrow = np.array([[wide[0, :3] @ R, wide[0, 3:] @ R]])
    np.testing.assert_allclose(model.closed_loop(wide).A, model.closed_loop(narrow).A,
                               rtol=1e-12, atol=1e-12)
    held = pinlin.validity("four_bar", feedback=wide, modes=[0])
    assert abs(held.cases[0].slope - 2.0) < 0.1
    # One input: a vector is a (1, 6) gain, as simulate takes it.
    np.testing.assert_array_equal(model.closed_loop(wide[0]).A, model.closed_loop(wide).A)
