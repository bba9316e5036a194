"""Dynamic response (García de Jalón & Bayo, section 9.3): modal decoupling with left and right
eigenvectors, time responses, frequency responses and modal energy.

References from outside the code under test: numpy/scipy eigensolvers and direct solves,
scipy.integrate.solve_ivp, closed-form oscillator solutions, a hand-derived Jordan-block
exponential and the hand-derived kinetic energy of a double pendulum's two rods.
"""

from __future__ import annotations

import functools
import math
import tomllib
import warnings

import numpy as np
import pytest
import scipy.linalg as sla
from conftest import REPO, URDF_DIR
from scipy.integrate import solve_ivp
from scipy.optimize import linear_sum_assignment
from scipy.signal import lsim

import pinlin
from pinlin.graph import Graph

EPS = np.finfo(float).eps
MODELS = ("double_pendulum", "ur5_arm", "four_bar")


@functools.cache
def _model(name: str) -> pinlin.LinearModel:
    return pinlin.linearize(pinlin.Scene.load(URDF_DIR / f"{name}.toml"))


@functools.cache
def _solo12_zero_g() -> pinlin.LinearModel:
    """Free-floating quadruped, no gravity, servo springs: six rigid-body Jordan pairs."""
    probe = pinlin.Scene.from_robot("solo12")
    joints = [n for n in probe.system.joints if n != "root_joint"]
    return pinlin.linearize(pinlin.Scene.from_robot("solo12", effects={
        "springs": {j: {"stiffness": 5.0} for j in joints}}))


def _oscillator(m: float, c: float, k: float) -> pinlin.LinearModel:
    """m x'' + c x' + k x = u, state [x; x'], output x."""
    return pinlin.LinearModel(
        A=[[0.0, 1.0], [-k / m, -c / m]], B=[[0.0], [1.0 / m]], C=[[1.0, 0.0]], D=[[0.0]],
        state_names=["q:x", "v:x"], input_names=["u:x"], output_names=["x"],
        M=[[m]], C_damp=[[c]], K=[[k]], Bu=[[1.0]], name="oscillator",
        info={"velocity_terms": c != 0})


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def _inputs(model: pinlin.LinearModel, t: np.ndarray):
    m = model.n_inputs
    rng = np.random.default_rng(3)
    a = rng.normal(size=m)
    return {
        "free": None,
        "signal": (pinlin.step(a) + pinlin.harmonic(rng.normal(size=m), w=4.0, phase=0.3)
                   + pinlin.impulse(rng.normal(size=m))),
        "samples": rng.normal(size=(len(t), m)),
    }


# --------------------------------------------------------------------------------------------
# Modal superposition = matrix exponential
@pytest.mark.parametrize("name", MODELS)
def test_modal_superposition_equals_matrix_exponential(name):
    model = _model(name)
    t = np.linspace(0.0, 6.0, 1201)
    x0 = 0.05 * np.random.default_rng(1).normal(size=model.n_states)
    for label, u in _inputs(model, t).items():
        modal = pinlin.response(model, t, x0, u, method="modal")
        exact = pinlin.response(model, t, x0, u, method="exact")
        assert modal.method == "modal" and exact.method == "exact"
        # Measured 2e-15 .. 7e-14; 1e-10 is the promise (modal_coordinates.COND_LIMIT).
        assert _rel(modal.x, exact.x) <= 1e-10, label
        assert _rel(modal.y, exact.y) <= 1e-10, label


def test_modal_superposition_with_drift_off_equilibrium():
    """A double pendulum linearized while it swings (v0 != 0): f0 != 0, velocity terms make
    A non-symmetric (general eigensolver), one mode grows."""
    model = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"),
                             q=[0.3, -0.2], v=[1.0, 0.5])
    assert model.f0 is not None and np.any(model.f0)
    modes = pinlin.modal(model)
    assert modes.method == "general" and not modes.is_stable
    t = np.linspace(0.0, 5.0, 501)
    u = pinlin.harmonic({"shoulder": 0.4}, w=2.0)
    modal = pinlin.response(model, t, [0.01, 0.0, 0.0, -0.02], u, modes=modes)
    exact = pinlin.response(model, t, [0.01, 0.0, 0.0, -0.02], u, method="exact")
    assert _rel(modal.x, exact.x) <= 1e-10   # measured 3e-14


def test_rigid_jordan_pairs_symmetric_and_schur_forms():
    """Solo12 floating in zero gravity: the symmetric eigensolver's Jordan chains give six 2x2
    blocks [[0, 1], [0, 0]]; the general eigensolver's nearly parallel vectors (condition
    ~1e22) fall back to the block Schur form. Both responses grow like t^2 under a constant
    force and equal the matrix exponential's."""
    model = _solo12_zero_g()
    t = np.linspace(0.0, 3.0, 301)
    u = pinlin.step(np.linspace(-1.0, 1.0, model.n_inputs)) + pinlin.harmonic(
        np.ones(model.n_inputs), w=6.0)
    x0 = 0.01 * np.random.default_rng(2).normal(size=model.n_states)
    exact = pinlin.response(model, t, x0, u, method="exact")
    scale = np.abs(model.A).max()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        general = pinlin.modal(model, method="general")
    for modes, kind in ((pinlin.modal(model), "jordan"), (general, "schur")):
        dec = modes.decoupling
        assert dec.kind == kind and not dec.diagonal
        assert ("Jordan pair" if kind == "jordan" else "Schur form") in dec.note
        big = [(s, e) for s, e in dec.blocks if e - s > 1]
        if kind == "jordan":
            assert len(big) == 6
            for s, _ in big:   # [[0, 1], [-w2, 0]], w2 = phi^T K phi = 0 to rounding
                np.testing.assert_allclose(dec.matrix[s:s + 2, s:s + 2], [[0, 1], [0, 0]],
                                           atol=1e-12 * scale)
        else:
            assert sum(e - s for s, e in big) == 12   # the twelve zero eigenvalues together
        # Blocks leave no coupling but rounding, ~ kappa(T) eps = 3e-14 of |A| (measured 6e-16
        # and 6e-15).
        assert dec.residual <= 1e-12
        response = pinlin.response(model, t, x0, u, modes=modes)
        # Measured 3e-13 (jordan) and 3e-11 (schur: the Schur form's backward error eps |A|,
        # |A| = 1.3e4, acting on a response that grows like t^2).
        assert _rel(response.x, exact.x) <= 1e-10


def test_defective_matrix_against_its_closed_form():
    """A 3x3 Jordan block J = lam I + N (N^3 = 0) has exp(J t) = e^{lam t} (I + N t + N^2 t^2/2);
    no eigenvector basis exists, the Schur fallback must still be exact."""
    lam = -0.7
    A = lam * np.eye(3) + np.diag([1.0, 1.0], 1)
    model = pinlin.LinearModel(A=A, B=np.zeros((3, 1)), C=np.eye(3), D=np.zeros((3, 1)),
                               state_names=["a", "b", "c"], input_names=["u"],
                               output_names=["a", "b", "c"], name="jordan3")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        modes = pinlin.modal(model)
    assert modes.decoupling.kind == "schur"
    assert [e - s for s, e in modes.decoupling.blocks] == [3]
    t = np.linspace(0.0, 4.0, 81)
    x0 = np.array([0.3, -0.2, 1.0])
    N = np.diag([1.0, 1.0], 1)
    ref = np.array([np.exp(lam * tk) * (np.eye(3) + N * tk + N @ N * tk**2 / 2) @ x0
                    for tk in t])
    for method in ("modal", "exact"):
        x = pinlin.response(model, t, x0, method=method, modes=modes if method == "modal"
                            else None).x
        assert _rel(x, ref) <= 1e-13   # measured 1.2e-15: exp of a 3x3 block, a few eps


def test_nearly_defective_pair_shares_a_block():
    """A = [[lam, 1], [0, lam + d]] with d = 1e-9 is diagonalizable, but its eigenvectors are
    1e-9 apart (condition ~1e9): split into two 1x1 blocks the coupling X = 1/d = 1e9 would
    cost 9 digits, so the Schur form keeps one 2x2 block. Closed form:
    x1 = e^{lam t} x1(0) + x2(0) e^{lam t} (e^{d t} - 1) / d, x2 = e^{(lam + d) t} x2(0)."""
    lam, d = -0.4, 1e-9
    model = pinlin.LinearModel(A=[[lam, 1.0], [0.0, lam + d]], B=np.zeros((2, 1)),
                               C=np.eye(2), D=np.zeros((2, 1)), state_names=["a", "b"],
                               input_names=["u"], output_names=["a", "b"], name="near")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        modes = pinlin.modal(model)
    assert modes.decoupling.kind == "schur"
    assert [e - s for s, e in modes.decoupling.blocks] == [2]
    t = np.linspace(0.0, 5.0, 51)
    x0 = np.array([0.2, 1.0])
    ref = np.column_stack([np.exp(lam * t) * (x0[0] + x0[1] * np.expm1(d * t) / d),
                           np.exp((lam + d) * t) * x0[1]])
    x = pinlin.response(model, t, x0, modes=modes).x
    assert _rel(x, ref) <= 1e-12   # measured 4e-16


@pytest.mark.parametrize("delta", [6e-10, 1e-8, 1e-6])
def test_a_mode_damped_near_critical_keeps_its_digits(delta):
    """q'' + 4 (1 + delta) q' + 4 q = 0: a pair 4 sqrt(2 delta) apart (the bundled pendulum
    with its damping set to critical (1 + 6e-10) did the same). At delta = 6e-10 the
    eigenvector matrix's condition (9.96e4) passed COND_LIMIT alone, and the diagonal form
    lost 8 digits (4.7e-8); its eigenvalue condition (~1e5) now sends it to the Schur form.
    Reference: the closed form of the overdamped oscillator, evaluated with expm1 (no
    cancellation), q = q0 e^{s1 t} (1 + s1 (1 - e^{(s2 - s1) t}) / (s2 - s1)) with s1 > s2."""
    k, c = 4.0, 4.0 * (1.0 + delta)
    A = np.array([[0.0, 1.0], [-k, -c]])
    model = pinlin.LinearModel(A=A, B=np.zeros((2, 0)), C=np.eye(2), D=np.zeros((2, 0)),
                               state_names=["q:x", "v:x"], input_names=[],
                               output_names=["q", "v"], name="critical")
    root = math.sqrt(c * c / 4.0 - k)
    s1, s2 = -c / 2.0 + root, -c / 2.0 - root
    t = np.linspace(0.0, 5.0, 26)
    q0 = 0.1
    # q = q0 (s2 e^{s1 t} - s1 e^{s2 t}) / (s2 - s1) = q0 e^{s1 t} (1 - s1 (1 - e^{-d t}) / d)
    # with d = s1 - s2 > 0 (v0 = 0); v = q' = q0 s1 s2 (e^{s1 t} - e^{s2 t}) / (s2 - s1).
    d = s1 - s2
    q = q0 * np.exp(s1 * t) * (1.0 + s1 * np.expm1(-d * t) / d)
    v = -q0 * s1 * s2 * np.exp(s1 * t) * (-np.expm1(-d * t)) / d
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        x = pinlin.response(model, t, [q0, 0.0]).x
    assert _rel(x, np.column_stack([q, v])) <= 1e-10


# --------------------------------------------------------------------------------------------
# Left and right eigenvectors
@pytest.mark.parametrize("name", [*MODELS, "solo12_zero_g"])
def test_decoupled_equations(name):
    model = _solo12_zero_g() if name == "solo12_zero_g" else _model(name)
    modes = pinlin.modal(model)
    dec = modes.decoupling
    n = model.n_states
    T, kappa = dec.right, dec.condition
    # Biorthogonality L^H R = I, relative to |I| = 1. T^-1 comes from an LU solve (general path)
    # or the closed form l = [M phi / 2; M phi / (2 lam)^*] (symmetric path); either way the
    # residual is rounding, at most ~ n eps kappa(T): 7e-15 (double pendulum), 2.6e-13 (ur5),
    # 9.7e-13 (solo12, n = 36, kappa = 122), all within 1e-12. Measured 2e-16 .. 3e-14.
    bound = n * EPS * kappa
    assert bound <= 1e-12
    assert np.abs(dec.left.conj().T @ T - np.eye(n)).max() <= bound
    # The blocks reproduce A's eigenvalues (numpy's, an independent solver), each to its
    # first-order rounding bound 10 kappa_i eps |A|_F, or sqrt(eps) |A|_F for defective ones.
    ours, ref = dec.eigenvalues, np.linalg.eigvals(model.A)
    rows, cols = linear_sum_assignment(np.abs(ours[:, None] - ref[None, :]))
    norm = np.linalg.norm(model.A)
    bound = np.where(np.isfinite(modes.condition), 10 * modes.condition * EPS,
                     10 * np.sqrt(EPS)) * norm
    assert np.all(np.abs(ours[rows] - ref[cols]) <= bound.max())
    # The modal equations are the model's: T (Lam r + B_r u + f_r) = A x + B u (+ f0).
    rng = np.random.default_rng(0)
    x, u = rng.normal(size=n), rng.normal(size=model.n_inputs)
    r = dec.to_modal(x)
    np.testing.assert_allclose(dec.from_modal(r), x, atol=1e-13 * np.abs(x).max())
    lhs = dec.from_modal(dec.derivative(r, u))
    rhs = model.A @ x + model.B @ u
    assert _rel(lhs, rhs) <= 1e-12


def test_left_vectors_not_transposed_right_ones():
    """Eqs. 9.62-9.66 as printed (v_i^T A v_j) do not uncouple a non-symmetric problem: for the
    damped ur5, R^T A R has off-diagonal entries of order |A|, while L^H A R is diagonal to
    rounding. L^H from R^-1 equals LAPACK's separately computed left eigenvectors."""
    model = _model("ur5_arm")
    modes = pinlin.modal(model)
    dec = modes.decoupling
    assert modes.method == "general" and dec.kind == "diagonal"
    R = dec.right
    book = R.T @ model.A @ R
    off = np.abs(book - np.diag(np.diag(book))).max() / np.abs(book).max()
    assert off > 1e-2
    ours = dec.left.conj().T @ model.A @ R
    assert np.abs(ours - np.diag(np.diag(ours))).max() <= 1e-12 * np.abs(model.A).max()
    # LAPACK's left vectors, scaled to l^H r = 1 (modes.left_vectors): the same (simple
    # eigenvalues), to kappa eps (kappa <= 1e2 here).
    np.testing.assert_allclose(dec.left, modes.left_vectors, atol=1e-11)


# --------------------------------------------------------------------------------------------
# The exact response against outside references
def test_exact_response_against_solve_ivp():
    """x' = f0 + A x + B u with a sinusoidal input (a Signal) and with held samples (each
    interval integrated on its own), against DOP853 at rtol 1e-12."""
    model = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"),
                             q=[0.3, -0.2], v=[1.0, 0.5])
    A, B, f0 = model.A, model.B, model.f0
    x0 = np.array([0.01, -0.02, 0.03, 0.0])
    t = np.linspace(0.0, 3.0, 61)
    a, w, phase = np.array([0.4, -0.3]), 2.5, 0.7

    def rhs(tk, x):
        return f0 + A @ x + B @ (a * np.sin(w * tk + phase))

    ref = solve_ivp(rhs, (t[0], t[-1]), x0, method="DOP853", t_eval=t, rtol=1e-12,
                    atol=1e-14).y.T
    for method in ("exact", "modal"):
        x = pinlin.response(model, t, x0, pinlin.harmonic(a, w, phase), method=method).x
        # DOP853's global error at rtol 1e-12 over ~4 periods of the 7 rad/s mode, with a
        # mode growing as e^{0.1 t}: ~1e-11 relative; measured 1.5e-12.
        assert _rel(x, ref) <= 1e-9, method
    U = np.random.default_rng(5).normal(size=(len(t), 2))
    xs = [x0]
    for k in range(len(t) - 1):
        sol = solve_ivp(lambda _, x, k=k: f0 + A @ x + B @ U[k], (t[k], t[k + 1]), xs[-1],
                        method="DOP853", rtol=1e-12, atol=1e-14)
        xs.append(sol.y[:, -1])
    x = pinlin.response(model, t, x0, U, method="exact").x
    assert _rel(x, np.array(xs)) <= 1e-9   # measured 9e-14 (short intervals)


@pytest.mark.parametrize("method", ["modal", "exact"])
def test_single_oscillator_closed_forms(method):
    """m x'' + c x' + k x = u by hand: damped free + step response, and the undamped one
    driven off and at resonance (the secular term t cos wt)."""
    m, c, k = 2.0, 0.6, 50.0
    wn, zeta = np.sqrt(k / m), c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta**2)
    t = np.linspace(0.0, 8.0, 801)
    x0, v0, F = 0.1, -0.4, 3.0
    decay = np.exp(-zeta * wn * t)
    free = decay * (x0 * np.cos(wd * t) + (v0 + zeta * wn * x0) / wd * np.sin(wd * t))
    forced = F / k * (1 - decay * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta**2)
                                   * np.sin(wd * t)))
    res = pinlin.response(_oscillator(m, c, k), t, [x0, v0], pinlin.step(F), method=method)
    # Closed form and response both evaluate exponentials of arguments up to wn t ~ 40:
    # ~10 eps * 40 relative; measured 5e-15.
    assert _rel(res.y[:, 0], free + forced) <= 1e-12
    assert _rel(res.state("q:x"), free + forced) <= 1e-12
    undamped = _oscillator(1.0, 0.0, wn**2)
    a = 0.8
    for drive in (0.6 * wn, wn):
        if drive == wn:    # resonance: x = a / (2 w^2) (sin wt - w t cos wt)
            ref = a / (2 * wn**2) * (np.sin(wn * t) - wn * t * np.cos(wn * t))
        else:              # x = a / (w^2 - W^2) (sin Wt - W / w sin wt), W = drive
            ref = a / (wn**2 - drive**2) * (np.sin(drive * t) - drive / wn * np.sin(wn * t))
        res = pinlin.response(undamped, t, None, pinlin.harmonic(a, drive), method=method)
        assert _rel(res.y[:, 0], ref) <= 1e-12, drive


def test_impulse_is_a_jump_of_b_times_the_area():
    """x(t0+) = x0 + B a, then the free response: against the free response from there."""
    model = _model("ur5_arm")
    t = np.linspace(0.0, 2.0, 201)
    a = {"shoulder_lift_joint": 2.0, "u:wrist_3_joint": -1.0}   # with and without 'u:'
    kick = pinlin.response(model, t, None, pinlin.impulse(a))
    vec = np.zeros(model.n_inputs)
    vec[[1, 5]] = 2.0, -1.0
    free = pinlin.response(model, t, model.B @ vec, method="exact")
    assert _rel(kick.x, free.x) <= 1e-10   # modal against exact; measured 2e-15
    assert any("impulse" in note for note in kick.notes)


def test_input_derivative_terms_by_the_standard_form():
    """The lead-lag network (Rowell eqs. 87-89) has x' = A x + B u + E u', y = C x + D u + F u';
    against solve_ivp of exactly that, with u = a sin(wt) and u' = a w cos(wt) by hand."""
    model = Graph.load(REPO / "validation" / "graphs" / "lead_lag.toml").linearize()
    assert np.any(model.E) and np.any(model.F)
    A, B, C, D, E, F = (getattr(model, k) for k in "ABCDEF")
    a, w = 2.0, 30.0
    t = np.linspace(0.0, 0.5, 201)
    ref = solve_ivp(lambda tk, x: A @ x + B[:, 0] * a * np.sin(w * tk)
                    + E[:, 0] * a * w * np.cos(w * tk), (0.0, 0.5), [0.1], method="DOP853",
                    t_eval=t, rtol=1e-12, atol=1e-14).y.T
    y_ref = ref @ C.T + np.outer(a * np.sin(w * t), D[:, 0]) + np.outer(a * w * np.cos(w * t),
                                                                       F[:, 0])
    for method in ("modal", "exact"):
        res = pinlin.response(model, t, [0.1], pinlin.harmonic(a, w), method=method)
        # DOP853 at rtol 1e-12 (as above); measured 1.2e-11 (x) and 3e-12 (y).
        assert _rel(res.x, ref) <= 1e-9
        assert _rel(res.y, y_ref) <= 1e-9
    # With a drift too (x' = f0 + ...): the standard form keeps f0.
    drifting = pinlin.LinearModel(A=A, B=B, C=C, D=D, E=E, F=F, f0=[5.0],
                                  state_names=model.state_names, input_names=model.input_names,
                                  output_names=model.output_names, name="lead_lag_drift")
    ref = solve_ivp(lambda tk, x: 5.0 + A @ x + B[:, 0] * a * np.sin(w * tk)
                    + E[:, 0] * a * w * np.cos(w * tk), (0.0, 0.5), [0.1], method="DOP853",
                    t_eval=t, rtol=1e-12, atol=1e-14).y.T
    for method in ("modal", "exact"):
        res = pinlin.response(drifting, t, [0.1], pinlin.harmonic(a, w), method=method)
        assert _rel(res.x, ref) <= 1e-9
    with pytest.raises(pinlin.ModelError, match="F u'"):
        pinlin.response(model, t, [0.1], np.ones(len(t)))


def test_a_step_through_e_starts_from_the_state_before_it():
    """Two springs in series driven by a force source (E = [0, 1/3]): a step switched on at
    t0 jumps the spring force by E u through the E u' impulse, as an impulse jumps x by B a.
    From rest (x0 = 0 before the step) the response is the step response of the transfer
    function: scipy's lsim of the standard form xs' = A xs + (B + A E) u from xs = 0, with
    x = xs + E u, y = C xs + (D + C E) u. The response had started from x(t0+) = x0 instead,
    leaving v:B1 at 0 throughout (a different initial state, xs = -E u)."""
    model = Graph.load(REPO / "validation" / "graphs" / "two_springs.toml").linearize()
    assert np.any(model.E) and not np.any(model.F)
    std = model.standard_form()
    t = np.linspace(0.0, 2.0, 41)
    amplitude = 1.5
    _, _, xs = lsim((std.A, std.B, std.C, std.D), np.full(len(t), amplitude), t)
    x_ref = xs + amplitude * model.E[:, 0]
    y_ref = xs @ std.C.T + amplitude * std.D[:, 0]
    for method in ("modal", "exact"):
        res = pinlin.response(model, t, np.zeros(2), pinlin.step(amplitude), method=method)
        # lsim's own matrix exponential per step (rounding ~1e-15 of the state); 1e-12.
        np.testing.assert_allclose(res.x, x_ref, rtol=0, atol=1e-12 * np.abs(x_ref).max())
        np.testing.assert_allclose(res.y, y_ref, rtol=0, atol=1e-12 * np.abs(y_ref).max())
        assert res.x[0] == pytest.approx(amplitude * model.E[:, 0], abs=1e-15)
    # Held samples have no value before t[0]: x[0] is x0, their first sample applied.
    held = pinlin.response(model, t, np.zeros(2), np.full(len(t), amplitude))
    np.testing.assert_array_equal(held.x[0], np.zeros(2))


def test_discrete_model_steps_its_difference_equation():
    """The ZOH-discretized model, stepped, equals the continuous response to the held input."""
    model = _model("ur5_arm")
    dt = 0.01
    t = dt * np.arange(300)
    U = np.random.default_rng(4).normal(size=(len(t), model.n_inputs))
    x0 = np.full(model.n_states, 0.01)
    disc = pinlin.response(model.discretize(dt), t, x0, U)
    cont = pinlin.response(model, t, x0, U)
    assert disc.method == "difference"
    assert _rel(disc.x, cont.x) <= 1e-10   # measured 2e-14 (300 steps of rounding)
    with pytest.raises(pinlin.ArgumentError, match="t\\[0\\] \\+ k dt"):
        pinlin.response(model.discretize(dt), t * 1.5, x0)


# --------------------------------------------------------------------------------------------
# Frequency response
def _direct_frf(model, w):
    """C (jwI - A)^-1 (B + jw E) + D + jw F by a dense solve at each frequency."""
    n = model.n_states
    E = model.E if model.E is not None else np.zeros_like(model.B)
    F = model.F if model.F is not None else np.zeros_like(model.D)
    return np.stack([model.C @ np.linalg.solve(1j * wk * np.eye(n) - model.A,
                                               model.B + 1j * wk * E) + model.D + 1j * wk * F
                     for wk in w])


@pytest.mark.parametrize("name", [*MODELS, "solo12_zero_g", "lead_lag"])
def test_frequency_response_against_a_direct_solve(name):
    if name == "lead_lag":
        model = Graph.load(REPO / "validation" / "graphs" / "lead_lag.toml").linearize()
    else:
        model = _solo12_zero_g() if name == "solo12_zero_g" else _model(name)
    w = np.logspace(-1, 2.5, 97)
    fr = pinlin.frequency_response(model, w)
    assert fr.H.shape == (len(w), model.n_outputs, model.n_inputs)
    ref = _direct_frf(model, w)
    # Each is backward stable: the direct solve's relative error at w_k is ~ cond(jw_k I - A)
    # eps, the modal sum's the same times kappa(T) (x = T r, r = T^-1 x): bound
    # 100 kappa(T) cond_k eps (100 for n and the sum of the modes' terms). Measured at most
    # 49 cond_k eps (ur5, kappa(T) = 97); 4.6e-11 for solo12 at w = 0.1, where its rigid poles
    # make cond(jw I - A) = 1.5e6.
    cond = np.array([np.linalg.cond(1j * wk * np.eye(model.n_states) - model.A) for wk in w])
    kappa = pinlin.modal(model.standard_form()).decoupling.condition
    err = np.abs(fr.H - ref).max(axis=(1, 2)) / np.abs(ref).max(axis=(1, 2))
    assert np.all(err <= 100 * kappa * cond * EPS)
    if model.n_inputs > 1:
        sub = pinlin.frequency_response(model, w, inputs=[model.input_names[1]],
                                        outputs=model.output_names[:1])
        np.testing.assert_array_equal(sub.H[:, 0, 0], fr.H[:, 0, 1])
        np.testing.assert_array_equal(sub.gain(model.output_names[0], model.input_names[1]),
                                      fr.H[:, 0, 1])


def test_discrete_frequency_response():
    model = _model("double_pendulum").discretize(0.02)
    w = np.linspace(0.1, 100.0, 50)
    z = np.exp(1j * w * model.dt)
    ref = np.stack([model.C @ np.linalg.solve(zk * np.eye(4) - model.A, model.B) + model.D
                    for zk in z])
    assert _rel(pinlin.frequency_response(model, w).H, ref) <= 1e-10


def test_bode_writes_a_png(tmp_path):
    model = _model("ur5_arm")
    path = tmp_path / "bode.png"
    fr = pinlin.bode(model, np.logspace(0, 2, 100), path, inputs=["elbow_joint"])
    assert path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert fr.input_names == ("u:elbow_joint",)
    assert not list(tmp_path.glob(".*"))          # no temporary file left behind
    with pytest.raises(pinlin.ArgumentError, match="ending in .png"):
        pinlin.bode(model, [1.0, 2.0], tmp_path / "bode.pdf")
    with pytest.raises(pinlin.ArgumentError, match="inputs"):
        pinlin.bode(model, [1.0, 2.0], path, inputs=["no_such_joint"])


# --------------------------------------------------------------------------------------------
# Modal energy
@pytest.mark.parametrize("name", MODELS)
def test_energy_shares_sum_to_one(name):
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    modes = pinlin.modal(pinlin.linearize(scene))
    energy = modes.energy(scene)
    count = len(modes.modes())
    assert energy.kinetic.shape == (count, len(energy.joint_names))
    for rows in (energy.kinetic, energy.potential, energy.body_kinetic):
        np.testing.assert_allclose(rows.sum(axis=1), 1.0, rtol=1e-12)
    assert np.all(energy.body_kinetic >= 0)       # a body's kinetic energy is >= 0
    assert str(energy).count("\n") == count


def test_stiff_spring_holds_the_high_mode_potential_energy():
    source = URDF_DIR / "double_pendulum.toml"
    data = tomllib.loads(source.read_text())
    data["effects"]["springs"] = {"elbow": {"stiffness": 400.0, "rest": 0.0}}
    scene = pinlin.Scene.from_dict(data, source=source)
    modes = pinlin.modal(pinlin.linearize(scene))
    energy = modes.energy(scene)
    high = int(np.argmax(np.abs(energy.eigenvalues)))
    elbow = energy.joint_names.index("elbow")
    # Measured 0.9995: the 100 rad/s mode bends the elbow against the spring.
    assert energy.potential[high, elbow] > 0.9


def test_potential_shares_are_the_springs_energies():
    """No gravity: K = diag(k) (joint springs only), so a mode's potential energy in joint i is
    the spring's, k_i |phi_i|^2 / 2 averaged over a cycle (by hand, no coupling). Strong
    damping makes the kinetic split differ (it equals the potential split only for an
    undamped mode, where K phi = w^2 M phi)."""
    source = URDF_DIR / "double_pendulum.toml"
    data = tomllib.loads(source.read_text())
    k = {"shoulder": 30.0, "elbow": 4.0}
    data["effects"] = {"springs": {j: {"stiffness": v} for j, v in k.items()},
                       "damping": {"shoulder": 2.0, "elbow": 0.5}}
    scene = pinlin.Scene.from_dict(data, source=source)
    modes = pinlin.modal(pinlin.linearize(scene))
    energy = modes.energy(scene)
    stiffness = np.array([k[j] for j in energy.joint_names])
    for row, i in enumerate(energy.index):
        spring = stiffness * np.abs(modes.right_vectors[:2, i]) ** 2
        np.testing.assert_allclose(energy.potential[row], spring / spring.sum(), rtol=1e-10)
    assert np.abs(energy.kinetic - energy.potential).max() > 1e-2


def test_body_kinetic_energy_by_hand():
    """Hanging double pendulum (rods L1 = 1, m1 = 1; L2 = 0.8, m2 = 0.6, centres at mid-length):
    for angle rates (p1, p2) the upper rod turns about the shoulder, T1 = I_O1 p1^2 / 2 with
    I_O1 = m1 L1^2 / 3; the forearm's centre moves at L1 p1 + (L2/2)(p1 + p2) (horizontal),
    T2 = (m2 v2^2 + I_c2 (p1 + p2)^2) / 2 with I_c2 = m2 L2^2 / 12."""
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    modes = pinlin.modal(pinlin.linearize(scene))
    energy = modes.energy(scene)
    assert energy.body_names == ("upper_arm", "forearm")
    for k, i in enumerate(energy.index):
        p1, p2 = modes.right_vectors[:2, i].real
        T1 = (1.0 / 3.0) * p1**2
        T2 = 0.6 * (p1 + 0.4 * (p1 + p2)) ** 2 + 0.6 * 0.8**2 / 12 * (p1 + p2) ** 2
        np.testing.assert_allclose(energy.body_kinetic[k], [T1 / (T1 + T2), T2 / (T1 + T2)],
                                   rtol=1e-12)


def test_energy_of_rigid_modes_and_graph_models():
    model = _solo12_zero_g()
    energy = pinlin.modal(model).energy()
    assert energy.rigid.sum() == 6
    assert np.all(np.isnan(energy.potential[energy.rigid]))
    assert not np.any(np.isnan(energy.potential[~energy.rigid]))
    np.testing.assert_allclose(energy.kinetic.sum(axis=1), 1.0, rtol=1e-12)
    # A free flyer is one joint of six coordinates: its share adds them.
    root = energy.joint_names.index("root_joint")
    np.testing.assert_allclose(energy.kinetic[:, root],
                               energy.coordinate_kinetic[:, :6].sum(axis=1), rtol=1e-12)
    graph = Graph.load(REPO / "validation" / "graphs" / "series_rlc.toml").linearize()
    with pytest.raises(pinlin.ModelError, match="mechanical model"):
        pinlin.modal(graph).energy()


# --------------------------------------------------------------------------------------------
# Arguments
def test_bad_arguments_are_named():
    model = _oscillator(1.0, 0.1, 4.0)
    t = np.linspace(0, 1, 11)
    cases = [
        (dict(method="euler"), pinlin.ArgumentError, "method"),
        (dict(t=[0.0, 0.0, 1.0]), pinlin.ArgumentError, "strictly increasing"),
        (dict(x0=[1.0, 2.0, 3.0]), pinlin.ShapeError, "x0 must have shape \\(2,\\)"),
        (dict(u=np.ones((11, 2))), pinlin.ShapeError, "u must have shape \\(11, 1\\)"),
        (dict(u=pinlin.step({"u:y": 1.0})), pinlin.ArgumentError, "no input named 'u:y'"),
        (dict(u=lambda tk: [1.0, 2.0]), pinlin.ArgumentError, "u\\(t\\) must return 1"),
        (dict(u=pinlin.step(1e308) + pinlin.step(1e308)), pinlin.ArgumentError,
         "add up beyond float64's range"),
        (dict(u=pinlin.impulse(1e308) + pinlin.impulse(1e308)), pinlin.ArgumentError,
         "add up beyond float64's range"),
    ]
    for kwargs, exc, message in cases:
        args = {"t": t, **kwargs}
        with pytest.raises(exc, match=message):
            pinlin.response(model, **args)
    with pytest.raises(pinlin.ArgumentError, match="LinearModel"):
        pinlin.response("model", t)
    with pytest.raises(pinlin.ArgumentError, match="single-input"):
        pinlin.response(_model("double_pendulum"), t, u=pinlin.step(1.0))


def test_callable_input_is_held_between_samples():
    model = _oscillator(1.0, 0.2, 9.0)
    t = np.linspace(0.0, 2.0, 41)
    by_call = pinlin.response(model, t, u=lambda tk: np.sin(3 * tk))
    by_samples = pinlin.response(model, t, u=np.sin(3 * t))
    np.testing.assert_array_equal(by_call.x, by_samples.x)
    assert any("zero-order hold" in note for note in by_call.notes)


@pytest.mark.parametrize("name", ["double_pendulum", "ur5_arm"])
def test_potential_energy_per_body_adds_up_to_the_stiffness(name):
    """Per body: the second derivative of each body's gravity potential along the mode
    (differences of -m g . c computed from Pinocchio's placements) plus its joint's springs;
    their sum equals phi^H K phi of the model's analytic stiffness (RNEA derivatives, another
    computation) to the differences' accuracy (~1e-8), so the shares sum to 1 with no
    remainder."""
    from pinlin import modal_energy

    scene = pinlin.Scene.resolve(name)
    model = pinlin.linearize(scene)
    modes = pinlin.modal(model)
    energy = modes.energy(scene)
    assert energy.body_potential is not None and "constraints" not in energy.body_potential_names
    nv = model.M.shape[0]
    phi = modes.right_vectors[:nv, modes.modes()]
    total = (phi.conj() * (0.5 * (model.K + model.K.T) @ phi)).real.sum(axis=0)
    shares, _ = modal_energy._body_potential(model, scene, phi, total)
    np.testing.assert_allclose(np.nansum(shares, axis=1), 1.0, rtol=1e-12)
    # The method itself: the bodies' potentials (all at once) plus the springs along each
    # mode equal the analytic stiffness's quadratic form.
    system = scene.system
    pm = system.model
    import pinocchio as pin

    data = pin.Data(pm)
    g = pm.gravity.linear

    def potential(q):
        pin.forwardKinematics(pm, data, q)
        return sum(-pm.inertias[j].mass * g @ (data.oMi[j] * pm.inertias[j].lever)
                   for j in range(1, pm.njoints))

    q0 = model.operating_point.q
    for k in range(phi.shape[1]):
        d = phi[:, k].real / np.abs(phi[:, k].real).max()
        h = 1e-3
        second = (potential(pin.integrate(pm, q0, h * d)) - 2 * potential(q0)
                  + potential(pin.integrate(pm, q0, -h * d))) / h**2
        springs = float((system.stiffness * d**2).sum())
        expected = float(d @ (0.5 * (model.K + model.K.T)) @ d)
        assert abs(second + springs - expected) <= 1e-6 * abs(expected)


def test_potential_energy_of_a_stiff_spring_lives_in_its_body():
    scene = pinlin.Scene.from_robot("double_pendulum", effects={
        "gravity": [0, 0, -9.81], "springs": {"joint2": {"stiffness": 500.0}}})
    modes = pinlin.modal(pinlin.linearize(scene))
    energy = modes.energy(scene)
    high = int(np.argmax(energy.eigenvalues.imag))
    column = energy.body_potential_names.index(
        next(n for n in energy.body_potential_names if n != energy.body_potential_names[0]))
    assert energy.body_potential[high, column] > 0.9


@pytest.mark.parametrize("method", ["modal", "exact", "discrete"])
def test_response_beyond_float64_is_refused_not_returned(method):
    """An unstable model over a long horizon: the inverted box (growth sqrt(m g l / (I + m l^2))
    = 3.817 1/s, see tests/test_contacts.py) from a 1e-2 tilt passes 1.8e308 near
    t = ln(1.8e310) / 3.817 = 187 s. Up to 150 s every sample is finite; to 400 s the
    response is refused naming the first sample that left float64's range."""
    model = pinlin.linearize("standing_box")
    if method == "discrete":
        model = model.discretize(0.01)
    x0 = np.zeros(model.n_states)
    x0[0] = 1e-2
    kind = "modal" if method == "discrete" else method
    short = pinlin.response(model, np.arange(0.0, 150.0, 0.01), x0=x0, method=kind)
    assert np.isfinite(short.x).all() and np.abs(short.x).max() > 1e200
    with pytest.raises(pinlin.ModelError, match=r"leaves float64's range at t = 1[89]\d"):
        pinlin.response(model, np.arange(0.0, 400.0, 0.01), x0=x0, method=kind)


def test_report_response_plot_stops_before_noise_grows(tmp_path):
    """G1 standing: its first mode is slow (5 periods ~ 10^3 s) and others grow at ~10 1/s:
    the report's response plot ends before rounding in the growing modes reaches 1e-8 of the
    shape (before, it overflowed float64 and the report failed)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        path = pinlin.write_html_report("g1_standing", tmp_path / "g1.html", max_modes=2)
    assert "data:image/png;base64," in path.read_text()


def test_discretize_takes_any_real_sample_time_and_refuses_the_rest():
    """np.int64(1) is a sample time like 1.0 (it was refused); zero, booleans and text are
    not."""
    model = _model("pendulum")
    np.testing.assert_array_equal(model.discretize(np.int64(1)).A, model.discretize(1.0).A)
    for bad in (0.0, -1.0, True, "1", float("nan")):
        with pytest.raises(pinlin.ArgumentError, match="argument 'dt'"):
            model.discretize(bad)


def test_exact_steps_too_long_for_their_digits_warn_or_are_refused():
    """The undamped double pendulum in one step: its energy 1/2 v'Mv + 1/2 q'Kq came back at
    0.31x after 1e15 s with no word. As a zero-order hold over the step would: a warning from
    eps ||A||_1 h > 1e-6 (1e9 s), a refusal where no digit is left (1e15 s); the modal march
    (exact per mode) keeps the energy there."""
    model = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"))
    x0 = [0.01, 0.0, 0.0, 0.0]
    with pytest.warns(pinlin.AccuracyWarning, match="h = 1e\\+09 s"):
        pinlin.response(model, [0.0, 1e9], x0, method="exact")
    with pytest.raises(pinlin.ModelError, match="no correct digit.*method='modal'"):
        pinlin.response(model, [0.0, 1e15], x0, method="exact")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pinlin.response(model, np.linspace(0.0, 10.0, 101), x0, method="exact")

    def energy(x):
        q, v = x[:2], x[2:]
        return 0.5 * v @ model.M @ v + 0.5 * q @ model.K @ q

    far = pinlin.response(model, [0.0, 1e15], x0, method="modal").x[-1]
    assert abs(energy(far) / energy(np.array(x0)) - 1.0) <= 1e-6


def test_a_response_too_large_for_memory_is_refused_before_it_allocates():
    """2e7 samples of a 12-state model ran into numpy's MemoryError under a 4 GB limit; the
    response's arrays are now counted first (here 2e6 samples, ~2 GB, under a 100 MB limit):
    a ResourceError naming the samples, before the march allocates."""
    model = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "ur5_arm.toml"))
    t = np.arange(2_000_000, dtype=float) * 1e-4
    with pinlin.resources.memory_limit_override("100M"), \
            pytest.raises(pinlin.ResourceError, match="2000000 sample times"):
        pinlin.response(model, t, method="exact")


def test_rounding_is_not_called_growth():
    """A neutrally stable model overflowing over 1e308 s: eigvals gives Re(lam) ~ 3e-17 1/s,
    which is rounding; the message says so rather than naming a growth rate."""
    model = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"))
    with pytest.raises(pinlin.ModelError, match="no mode grows beyond rounding"):
        pinlin.response(model, [0.0, 1e308, 1.7e308], [0.01, 0.0, 0.0, 0.0])


def _dp_model():
    return pinlin.linearize(pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"))


def test_a_discrete_impulse_is_one_sample_of_height_area_over_dt():
    """A discrete model's impulse of area a is one input sample a / dt (the difference
    equation stepped by hand), the continuous impulse to O(dt)."""
    model = _dp_model()
    dt = 0.01
    disc = model.discretize(dt)
    t = dt * np.arange(20)
    a = np.array([0.3, -0.2])
    kick = pinlin.response(disc, t, None, pinlin.impulse(a))
    x = np.zeros(model.n_states)
    ref = [x]
    for k in range(len(t) - 1):           # the difference equation by hand, u[0] = a / dt
        x = disc.A @ x + (disc.B @ (a / dt) if k == 0 else 0.0)
        ref.append(x)
    np.testing.assert_allclose(kick.x, np.array(ref), rtol=1e-12, atol=1e-15)
    # and the pulse of area a is the continuous impulse to O(dt): x(dt) ~ e^{A dt} B a
    cont = sla.expm(model.A * dt) @ model.B @ a
    assert np.abs(kick.x[1] - cont).max() <= 0.05 * np.abs(cont).max()


def test_the_exact_march_judges_its_longest_step_not_its_shortest():
    """Uneven times: a step of 1e15 s after one of 1 s leaves no digit (eps |A| dt >= 1),
    refused before the march, naming that step h (the rounding check after the march would
    refuse too, but only once the 1e15 s exponential has been computed)."""
    model = _dp_model()
    with pytest.raises(pinlin.ModelError, match="h = 1e\\+15 s.*no correct digit"):
        pinlin.response(model, [0.0, 1.0, 1e15], [0.01, 0.0, 0.0, 0.0], method="exact")


def test_a_nearly_symmetric_stiffness_keeps_the_modal_response_exact():
    """K symmetric to 2e-8 (within the symmetric path's 1e-8 relative): the closed-form
    vectors leave a residual, which sends the response to the checked decomposition; the
    response against expm(A t) x0."""
    M = np.diag([1.0, 2.0])
    K = np.array([[3.0, -1.0], [-1.0 + 2e-8, 2.0]])   # skew 2e-8 < 1e-8 max|K|: (K, M) path
    Minv = np.linalg.inv(M)
    Bu = np.array([[1.0], [0.0]])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ K, np.zeros((2, 2))]])
    B = np.vstack([np.zeros((2, 1)), Minv @ Bu])
    model = pinlin.LinearModel(A, B, np.eye(4), np.zeros((4, 1)), ["q:a", "q:b", "v:a", "v:b"],
                               ["u:a"], ["y0", "y1", "y2", "y3"], M=M, C_damp=np.zeros((2, 2)),
                               K=K, Bu=Bu)
    assert pinlin.modal(model).method == "symmetric"
    t = np.linspace(0.0, 20.0, 401)
    x0 = np.array([0.1, -0.05, 0.0, 0.0])
    ref = np.array([sla.expm(A * tk) @ x0 for tk in t])
    x = pinlin.response(model, t, x0, method="modal").x
    assert np.abs(x - ref).max() <= 1e-10 * np.abs(ref).max()


def _expm_decimal(A: np.ndarray, h: float, digits: int = 60) -> np.ndarray:
    """exp(A h) in ``digits`` decimal digits (Python's decimal): the double A and h converted
    exactly, halved until ||A h||_1 <= 1/2, a 60-term Taylor series, squared back. Rounding
    of 1e-60 survives an amplification of 1e40 with every double digit intact."""
    from decimal import Decimal, localcontext
    n = A.shape[0]
    with localcontext() as ctx:
        ctx.prec = digits
        M = [[Decimal(float(a)) * Decimal(float(h)) for a in row] for row in A]
        norm, s = max(sum(abs(M[i][j]) for i in range(n)) for j in range(n)), 0
        while norm > Decimal("0.5"):
            norm, s = norm / 2, s + 1
        M = [[a / Decimal(2) ** s for a in row] for row in M]

        def mul(X, Y):
            return [[sum(X[i][k] * Y[k][j] for k in range(n)) for j in range(n)]
                    for i in range(n)]

        E = [[Decimal(int(i == j)) for j in range(n)] for i in range(n)]
        term = [row[:] for row in E]
        for k in range(1, 60):
            term = [[a / k for a in row] for row in mul(term, M)]
            E = [[E[i][j] + term[i][j] for j in range(n)] for i in range(n)]
        for _ in range(s):
            E = mul(E, E)
        return np.array([[float(a) for a in row] for row in E])


def _free_response_decimal(A: np.ndarray, t: np.ndarray, x0: np.ndarray) -> np.ndarray:
    return np.array([_expm_decimal(A, tk - t[0]) @ x0 for tk in t])


def test_an_exact_response_lost_to_non_normality_is_said_or_refused():
    """The canonical four-bar: ||A||_1 = 1e9 (penalty stiffness against momenta) with its
    eigenvalues near -10 and +-4.8i. Its free response from a crank momentum of 1e-3 came back
    5 % off a 60-digit exponential of the same A, with no word; under a random full-state
    gain, 20x off. The spread of a second march with A and B moved by one ulp now estimates
    that error: a warning that quotes it (within 100x of the error measured here: 3e-2
    against 5e-2), a refusal where no digit is left. Penalty and independent models of the
    same four-bar are normal enough: no warning, and 1e-12 of the 60-digit reference."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    t = np.linspace(0.0, 1.0, 11)
    canonical = pinlin.linearize(scene, formulation="canonical")
    x0 = np.zeros(canonical.n_states)
    x0[0] = 1e-3
    ref = _free_response_decimal(canonical.A, t, x0)
    with pytest.warns(pinlin.AccuracyWarning, match="exact response is sensitive to rounding"
                      ) as record:
        got = pinlin.response(canonical, t, x0, method="exact").x
    error = np.abs(got - ref).max() / np.abs(ref).max()
    assert error > 1e-6                                  # the warning is warranted
    estimate = 1.0 / next(w.message.condition for w in record
                          if "exact response" in str(w.message))
    assert error / 100 <= estimate <= 100 * error

    gain = np.random.default_rng(0).standard_normal((canonical.n_inputs, canonical.n_states))
    closed = canonical.closed_loop(gain)
    with pytest.raises(pinlin.ModelError, match="no correct digit.*method='modal'"):
        pinlin.response(closed, t, x0, method="exact")

    for formulation in ("penalty", "independent"):
        model = pinlin.linearize(scene, formulation=formulation)
        x0 = np.zeros(model.n_states)
        x0[model.n_states // 2] = 1e-3                  # a velocity (the crank's)
        ref = _free_response_decimal(model.A, t, x0)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = pinlin.response(model, t, x0, method="exact").x
        assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max(), formulation


def test_a_long_step_warning_does_not_hide_the_rounding_check():
    """t = [0, 5] s on the canonical four-bar under a stable random gain: eps ||A||_1 h just
    passes 1e-6, and that warning ("may reach 1.1e-06") used to be all that came with an
    x(5) of -1.4e15 for the 60-digit -4.7e-4. The spread check runs there too and refuses."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    canonical = pinlin.linearize(scene, formulation="canonical")
    gain = np.random.default_rng(0).standard_normal((canonical.n_inputs, canonical.n_states))
    closed = canonical.closed_loop(gain)
    assert np.linalg.eigvals(closed.A).real.max() < 0.0                # a stable loop
    x0 = np.zeros(canonical.n_states)
    x0[0] = 1e-3
    t = np.array([0.0, 5.0])
    ref = _free_response_decimal(closed.A, t, x0)
    plain = sla.expm(closed.A * 5.0) @ x0                # what the march computes
    assert np.abs(plain - ref[-1]).max() > np.abs(ref[-1]).max()      # no digit left
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)       # the step's own warning
        with pytest.raises(pinlin.ModelError, match="lost to rounding.*method='modal'"):
            pinlin.response(closed, t, x0, method="exact")


def test_the_rounding_checks_error_bounds_the_60_digit_error_of_random_loops():
    """Canonical four-bar, open and under random gains (scales 1e-4 to 10, stable loops
    only), random steps (1 ms to 3 s) and initial states: each exact response is either
    refused, or within 3x of the error it reports (its warning's estimate, or the promised
    1e-6 without one) against a 60-digit exponential of the same A. Measured: the error is
    at most 0.73 of the estimate over 35 warned cases (two samples, factor 10). A single
    unscaled sample had fallen 6.8x short here, and left trial 2's error of 5.6e-6 without a
    word."""
    canonical = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "four_bar.toml"),
                                 formulation="canonical")
    n = canonical.n_states
    rng = np.random.default_rng(7)
    checked = 0
    for trial in range(24):
        scale = 10.0 ** rng.uniform(-4, 1)
        loop = canonical.closed_loop(rng.standard_normal((1, n)) * scale) if trial % 3 \
            else canonical
        if np.linalg.eigvals(loop.A).real.max() > 0.5:
            continue
        h, N = 10.0 ** rng.uniform(-3, 0.5), int(rng.integers(2, 6))
        x0 = rng.standard_normal(n) * 10.0 ** rng.uniform(-4, 0, n)
        t = np.arange(N) * h
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                got = pinlin.response(loop, t, x0, method="exact").x
        except pinlin.ModelError:
            continue
        said = [1.0 / w.message.condition for w in caught
                if "exact response" in str(w.message)]
        ref = _free_response_decimal(loop.A, t, x0)
        error = np.abs(got - ref).max() / np.abs(ref).max()
        assert error <= 3.0 * max(said or [1e-6]), (trial, error, said)
        checked += 1
    assert checked >= 12


def test_a_step_warned_as_long_is_refused_where_the_check_finds_no_digit():
    """The undamped pendulum in one step of 3.7e14 s: eps ||A||_1 h = 0.8 warns ("may reach
    8.0e-01") and the exponential's x(T) came back -3361 rad for a true 1.5e-4, because the
    check let anything up to 10x the warning through. Where its own estimate reaches 1 it
    now refuses, warning or not. The true x(T) is 1e-3 cos(w T), |x(T)| <= 1e-3: the plain
    exponential's |x| beyond that has no digit left."""
    model = _model("pendulum")
    T = 0.8 / (EPS * np.abs(model.A).sum(axis=0).max())
    plain = sla.expm(model.A * T) @ np.array([1e-3, 0.0])
    assert abs(plain[0]) > 1e-3                  # what the march computes: not a cosine
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        with pytest.raises(pinlin.ModelError, match="lost to rounding"):
            pinlin.response(model, [0.0, T], [1e-3, 0.0], method="exact")


def test_a_frequency_response_too_large_for_memory_is_refused_before_it_allocates():
    """1e8 frequencies of the double pendulum raised numpy's MemoryError (8.9 GiB for H);
    H and its work arrays are counted first (here 2e6 frequencies of ur5, 4 outputs x 6
    inputs, ~3 GB, under a 100 MB limit): a ResourceError naming the frequencies."""
    model = pinlin.linearize(pinlin.Scene.load(URDF_DIR / "ur5_arm.toml"))
    w = np.linspace(0.1, 10.0, 2_000_000)
    with pinlin.resources.memory_limit_override("100M"), \
            pytest.raises(pinlin.ResourceError, match="2000000 frequencies"):
        pinlin.frequency_response(model, w)
    # Within the limit it runs: the estimate does not refuse what fits.
    with pinlin.resources.memory_limit_override("100M"):
        assert pinlin.frequency_response(model, w[:1000]).H.shape[0] == 1000


def test_a_subnormal_step_advances_by_the_series_of_phi1():
    """A time step of 1e-310 s (subnormal): e^{lam h} - 1 over lam h was inf / NaN there, and
    the modal response was refused as leaving float64's range. Over such a step the pendulum
    moves by its acceleration: v = A[1, 0] q0 h (closed form, h^2 terms far below)."""
    model = _model("pendulum")
    for h in (1e-310, 1e-300, 1e-9):
        for method in ("modal", "exact"):
            x = pinlin.response(model, [0.0, h], [0.1, 0.0], method=method).x[-1]
            assert x[0] == pytest.approx(0.1, rel=1e-15)
            # subnormals near 1e-310 keep ~13 digits
            assert x[1] == pytest.approx(model.A[1, 0] * 0.1 * h, rel=1e-9)
