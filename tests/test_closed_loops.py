"""Closed loops, mimic couplings, steady rotation and the three formulations of chapter 9.1.

Expected values come from outside pinlin: single-crank-angle models written from the geometry
(tests/minimal_models.py, exact derivatives by hyper-dual numbers), hand-derived formulas for the
rotating double pendulum, the chapter's natural-coordinate model of Example 9.2 assembled here
in numpy, and Pinocchio's own constrained forward dynamics differenced on the mechanism.
"""

from __future__ import annotations

import math
import warnings

import minimal_models as mm
import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR
from statics_reference import radius_of_gyration, weighted_orthogonality

import pinlin
from pinlin.assembly import ASSEMBLY_TOL, assemble

# ---------------------------------------------------------------------------------------------
# Four-bar and slider-crank against single-coordinate models


@pytest.mark.parametrize("name, minimal", [("four_bar", mm.four_bar),
                                           ("slider_crank", mm.slider_crank)])
def test_one_dof_mechanisms_match_single_crank_models(name, minimal):
    """u0, the physical eigenvalue and B of the independent-coordinate model equal those of a
    crank-angle model written from the geometry alone, to 1e-10. The slider-crank's loop joins
    two moving bodies (connecting rod and slider): the case where Pinocchio 4.1's
    computeConstraintDynamicsDerivatives returns a wrong column (19 % off in frequency). pinlin
    does not use it, and this test would catch any inherited error."""
    model = pinlin.linearize(URDF_DIR / f"{name}.toml")
    theta = model.operating_point.q[0]
    m, dV, ddV = minimal(theta)
    assert model.operating_point.u[0] == pytest.approx(dV, rel=1e-10)
    lam2 = np.linalg.eigvals(model.A)
    expected = np.sqrt(complex(-ddV / m))
    assert np.sort(lam2.imag)[-1] == pytest.approx(expected.imag, rel=1e-10)
    assert np.abs(lam2.real).max() <= 1e-10 * abs(expected)
    assert model.B[1, 0] == pytest.approx(1.0 / m, rel=1e-10)


def test_four_bar_branch_and_geometric_stiffness():
    """The assembled rocker angle is the minimal model's; without the geometric stiffness
    lam^T Phi_qq the frequency would be wrong by far more than the tolerance above."""
    model = pinlin.linearize(URDF_DIR / "four_bar.toml")
    q = model.operating_point.q
    a, b, c, d = 0.2, 0.5, 0.4, 0.45
    bx, bz = a * math.cos(q[0]), a * math.sin(q[0])
    px, pz = bx - d, bz
    e = math.hypot(px, pz)
    psi = math.atan2(pz, px) - math.acos((c * c + e * e - b * b) / (2 * c * e))
    assert q[2] == pytest.approx(psi, abs=1e-10)
    system = model_system = pinlin.Scene.load(URDF_DIR / "four_bar.toml").system
    op = model.operating_point
    geometric = system.constraints.hessian(op.q, op.lam)
    R = np.array(model.info["R"])
    assert abs(R.T @ geometric @ R).max() > 1e-2 * abs(model.K).max()
    del model_system


# ---------------------------------------------------------------------------------------------
# Examples 9.1 and 9.2: the rotating double pendulum

ELL, G = 0.5, 9.81


def _hand_mass_stiffness(phi1: float, phi2: float, w: float
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Example 9.1 derived by hand (Lagrange, effective potential of the rotating frame).

    M = 4 l^2 [[2 (2 + cos phi2), 1 + cos phi2], [1 + cos phi2, 1]]  (the book prints sin phi2:
    a misprint), V = -6 g l cos phi1 - 2 g l cos(phi1 + phi2)
    - w^2 (4 l^2 sin^2 phi1 + 2 l^2 (sin phi1 + sin(phi1 + phi2))^2). K = Hess V: the book's B
    with both signs flipped (as printed, gravity would destabilize the hanging pendulum).
    Returns (M, K, grad V)."""
    s1, c1 = math.sin(phi1), math.cos(phi1)
    s12, c12 = math.sin(phi1 + phi2), math.cos(phi1 + phi2)
    l2 = ELL * ELL
    M = 4 * l2 * np.array([[2 * (2 + math.cos(phi2)), 1 + math.cos(phi2)],
                           [1 + math.cos(phi2), 1.0]])
    grav = 2 * G * ELL * np.array([[3 * c1 + c12, c12], [c12, c12]])
    rot = 4 * l2 * w * w * np.array([
        [3 * math.cos(2 * phi1) + math.cos(2 * phi1 + 2 * phi2) + 2 * math.cos(2 * phi1 + phi2),
         math.cos(2 * phi1 + phi2) + math.cos(2 * phi1 + 2 * phi2)],
        [math.cos(2 * phi1 + phi2) + math.cos(2 * phi1 + 2 * phi2),
         math.cos(2 * phi1 + 2 * phi2) - s1 * s12]])
    grad = np.array([
        6 * G * ELL * s1 + 2 * G * ELL * s12
        - w * w * (8 * l2 * s1 * c1 + 4 * l2 * (s1 + s12) * (c1 + c12)),
        2 * G * ELL * s12 - w * w * 4 * l2 * (s1 + s12) * c12])
    return M, grav - rot, grad


def _rotating(rate: float, guess: tuple[float, float]) -> pinlin.LinearModel:
    scene = pinlin.Scene.load(URDF_DIR / "rotating_double_pendulum.toml")
    data = {"urdf": str(scene.urdf), "name": f"rdp_{rate}",
            "effects": {"gravity": [0, 0, -G], "rotation": {"axis": [0, 0, 1], "rate": rate}},
            "operating_point": {"q": {"phi1": guess[0], "phi2": guess[1]},
                                "solve": "positions"},
            "inputs": {"actuated": "all"}}
    return pinlin.linearize(pinlin.Scene.from_dict(data))


def _critical_speed() -> float:
    """First critical speed of the hanging pendulum: K(0, w) singular (hand formulas)."""
    _, Kg, _ = _hand_mass_stiffness(0.0, 0.0, 0.0)
    _, K1, _ = _hand_mass_stiffness(0.0, 0.0, 1.0)
    Kc = Kg - K1  # K = Kg - w^2 Kc
    return float(math.sqrt(min(np.linalg.eigvals(np.linalg.solve(Kc, Kg)).real)))


@pytest.mark.parametrize("rate, guess", [(2.0, (0.3, -0.2)), (5.0, (0.8, 0.3))])
def test_rotating_double_pendulum_example_9_1(rate, guess):
    """Below the first critical speed the passive equilibrium is the hanging one; above, a bent
    equilibrium. Both match the hand-derived M, K and equilibrium condition to 1e-10."""
    wc = _critical_speed()
    model = _rotating(rate, guess)
    phi1, phi2 = model.operating_point.q
    M, K, grad = _hand_mass_stiffness(phi1, phi2, rate)
    assert abs(grad).max() <= 1e-9
    np.testing.assert_allclose(model.M, M, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(model.K, K, rtol=1e-10, atol=1e-10 * abs(K).max())
    if rate < wc:
        assert abs(phi1) < 1e-9 and abs(phi2) < 1e-9
    else:
        assert phi1 > 0.1  # bent
    assert pinlin.modal(model).is_stable


def test_hanging_pendulum_above_critical_speed_is_unstable():
    wc = _critical_speed()
    scene = pinlin.Scene.from_dict({
        "urdf": str(URDF_DIR / "rotating_double_pendulum.urdf"),
        "effects": {"gravity": [0, 0, -G], "rotation": {"axis": [0, 0, 1], "rate": 1.2 * wc}},
        "operating_point": {"q": {"phi1": 0.0, "phi2": 0.0}, "solve": "positions"}})
    modes = pinlin.modal(pinlin.linearize(scene))
    assert not modes.is_stable and modes.unstable.sum() == 1


def _example_9_2(x: np.ndarray, w: float, alpha: float, mu: float = 1.0, omega: float = 10.0
                 ) -> np.ndarray:
    """Example 9.2 in natural coordinates (x1, y1, x2, y2), y up, penalty formulation.

    Corrections to the printed example: Q_q = diag(2 w^2, 0, w^2, 0) (the centrifugal force on
    mass i is m_i w^2 x_i; the print has stray off-diagonal w^2), and at a loaded equilibrium the
    stiffness needs the constraint-force term sum lam_i Phi_i,qq, which the example leaves out.
    Returns the eigenvalues of the linearized penalty equations."""
    x1, y1, x2, y2 = x
    M = np.diag([2.0, 2.0, 1.0, 1.0])
    Phi_q = np.array([[x1, y1, 0, 0], [x1 - x2, y1 - y2, x2 - x1, y2 - y1]])
    Q = np.array([2 * w * w * x1, -2 * G, w * w * x2, -G])
    lam = np.linalg.lstsq(Phi_q.T, Q, rcond=None)[0]  # M q'' + Phi_q^T lam = Q at rest
    assert np.allclose(Phi_q.T @ lam, Q, atol=1e-9)
    H1 = np.diag([1.0, 1.0, 0, 0])
    H2 = np.block([[np.eye(2), -np.eye(2)], [-np.eye(2), np.eye(2)]])
    Qq = np.diag([2 * w * w, 0, w * w, 0])
    Mp = M + alpha * Phi_q.T @ Phi_q
    Cp = 2 * mu * omega * alpha * Phi_q.T @ Phi_q
    Kp = omega**2 * alpha * Phi_q.T @ Phi_q - Qq + lam[0] * H1 + lam[1] * H2
    A = np.block([[np.zeros((4, 4)), np.eye(4)],
                  [-np.linalg.solve(Mp, Kp), -np.linalg.solve(Mp, Cp)]])
    return np.linalg.eigvals(A)


@pytest.mark.parametrize("rate, guess", [(2.0, (0.3, -0.2)), (5.0, (0.8, 0.3))])
def test_example_9_2_natural_coordinates_converge_to_pinlin(rate, guess):
    """The chapter's dependent-coordinate model, built here in numpy, has physical eigenvalues
    that approach pinlin's independent-coordinate ones as O(1/alpha)."""
    model = _rotating(rate, guess)
    phi1, phi2 = model.operating_point.q
    x1, y1 = 2 * ELL * math.sin(phi1), -2 * ELL * math.cos(phi1)
    x = np.array([x1, y1, x1 + 2 * ELL * math.sin(phi1 + phi2),
                  y1 - 2 * ELL * math.cos(phi1 + phi2)])
    ours = np.sort(np.abs(np.linalg.eigvals(model.A).imag))[::2]
    errors = []
    for alpha in (1e4, 1e5, 1e6):
        lam = _example_9_2(x, rate, alpha)
        phys = np.sort(np.abs(lam[np.abs(lam.real) < 1.0].imag))[::2]
        errors.append(np.abs(phys - ours).max() / ours.max())
    assert errors[-1] < 1e-4
    # Shrinking like 1/alpha; hanging straight down the penalty springs are normal to the
    # physical motion and the physical eigenvalues are exact for every alpha.
    assert errors[0] <= 1e-12 or errors[0] / errors[-1] > 50


# ---------------------------------------------------------------------------------------------
# The three formulations agree


def _physical(model: pinlin.LinearModel) -> np.ndarray:
    modes = pinlin.modal(model)
    lam = modes.eigenvalues[~modes.constraint]
    return lam[np.argsort(lam.imag)]


@pytest.mark.parametrize("name", ["four_bar", "slider_crank", "five_bar"])
def test_penalty_converges_to_independent_as_one_over_alpha(name):
    exact = pinlin.linearize(URDF_DIR / f"{name}.toml")
    ref = np.linalg.eigvals(exact.A)
    ref = ref[np.argsort(ref.imag)]
    alphas = np.array([1e3, 1e4, 1e5, 1e6, 1e7])
    errors = []
    for alpha in alphas:
        lam = _physical(pinlin.linearize(URDF_DIR / f"{name}.toml", formulation="penalty",
                                         alpha=alpha))
        errors.append(np.abs(lam - ref).max() / np.abs(ref).max())
    slope = np.polyfit(np.log10(alphas), np.log10(errors), 1)[0]
    assert -1.1 < slope < -0.9, (slope, errors)


@pytest.mark.parametrize("name", ["four_bar", "slider_crank", "five_bar", "delta"])
def test_canonical_and_penalty_give_the_same_eigenvalues(name):
    kw = {"alpha": 1e5, "omega": 10.0, "mu": 0.5}
    import warnings

    pen = pinlin.linearize(URDF_DIR / f"{name}.toml", formulation="penalty", **kw)
    can = pinlin.linearize(URDF_DIR / f"{name}.toml", formulation="canonical", **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        mp, mc = pinlin.modal(pen, method="general"), pinlin.modal(can, method="general")
    a, b = mp.eigenvalues, mc.eigenvalues
    cost = np.abs(a[:, None] - b[None, :])
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(cost)
    # The same spectrum in exact arithmetic; each eigensolve moves eigenvalue i by at most
    # ~kappa_i eps |A|_2 (first-order bound, 10x).
    eps = np.finfo(float).eps
    bound = 10 * eps * (mp.condition[rows] * np.linalg.norm(pen.A, 2)
                        + mc.condition[cols] * np.linalg.norm(can.A, 2))
    assert np.all(cost[rows, cols] <= bound)
    assert mc.constraint.sum() == mp.constraint.sum()


@pytest.mark.parametrize("name", ["four_bar", "slider_crank", "delta"])
def test_canonical_model_solves_eq_9_53(name):
    """A, B and the output C of the canonical model against eq. 9.53 written out here:
    [[I, C_p], [0, M_p]] y' = [[0, -K_p], [I, 0]] y + [Bu; 0] u with y = [p; q], solved by LU
    at an alpha where that is accurate, from the penalty model's M_p, C_p, K_p (eqs.
    9.35-9.37); outputs read v = M_p^-1 p, so C_can [M_p v; q] = C_pen [q; v]."""
    kw = {"alpha": 1e3, "omega": 10.0, "mu": 0.5}
    pen = pinlin.linearize(URDF_DIR / f"{name}.toml", formulation="penalty", **kw)
    can = pinlin.linearize(URDF_DIR / f"{name}.toml", formulation="canonical", **kw)
    n = pen.M.shape[0]
    E = np.block([[np.eye(n), pen.C_damp], [np.zeros((n, n)), pen.M]])
    F = np.block([[np.zeros((n, n)), -pen.K], [np.eye(n), np.zeros((n, n))]])
    Gu = np.vstack([pen.Bu, np.zeros_like(pen.Bu)])
    np.testing.assert_allclose(can.A, np.linalg.solve(E, F), rtol=0,
                               atol=1e-10 * np.abs(can.A).max())
    np.testing.assert_allclose(can.B, np.linalg.solve(E, Gu), rtol=0, atol=1e-12)
    rng = np.random.default_rng(3)
    q, v = rng.standard_normal(n), rng.standard_normal(n)
    np.testing.assert_allclose(can.C @ np.concatenate([pen.M @ v, q]),
                               pen.C @ np.concatenate([q, v]), rtol=1e-10, atol=1e-12)


def test_canonical_model_refuses_an_alpha_it_cannot_hold():
    """The canonical A carries K_p = K + alpha Omega^2 G^T G: at alpha = 1e14 float64 loses
    the physical eigenvalues and invents growing modes (measured: relative error ~1, Re up to
    +1e2). pinlin compares the spectrum with the penalty model's and refuses."""
    with pytest.raises(pinlin.ArgumentError, match="argument 'alpha'.*canonical state matrix"):
        pinlin.linearize(URDF_DIR / "four_bar.toml", formulation="canonical", alpha=1e14)


@pytest.mark.parametrize("name", ["four_bar", "slider_crank", "five_bar", "delta"])
def test_canonical_model_is_never_silently_wrong(name):
    """At the default alpha the canonical spectrum matches the penalty one (measured gap
    <= 4e-8, refused above 1e-4, warned above 1e-6). At alpha = 1e10 and 1e12 (where rounding
    decides, differently on each machine) a model is refused, or returned with a warning
    exactly when its gap exceeds 1e-6, and then each physical eigenvalue lies within the
    reported gap of the penalty model's, which lies at its own O(1/alpha) distance from the
    independent model's: |can - ind| <= gap |pen| + |pen - ind| (the same eigensolver as the
    check, scipy's, so the bound is exact). No growth is invented beyond rounding: a decaying
    penalty mode's canonical real part stays below eps |A|_F, the backward error of any
    eigenvalue of A in float64 (K_p ~ alpha makes it ~1e-6 1/s at alpha = 1e10), where the
    sign of a real part is not determined."""
    import warnings

    import scipy.linalg as sla

    path = URDF_DIR / f"{name}.toml"
    exact = sla.eigvals(pinlin.linearize(path).A)
    model = pinlin.linearize(path, formulation="canonical")
    assert model.info["condition"]["canonical_vs_penalty_spectrum"] < 1e-6
    for alpha in (1e10, 1e12):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                model = pinlin.linearize(path, formulation="canonical", alpha=alpha)
            except pinlin.ArgumentError as exc:
                assert "canonical state matrix" in str(exc)
                continue
        gap = model.info["condition"]["canonical_vs_penalty_spectrum"]
        warned = any("canonical state matrix" in str(w.message) for w in caught
                     if issubclass(w.category, pinlin.AccuracyWarning))
        assert warned == (gap > 1e-6)
        pen = sla.eigvals(pinlin.linearize(path, formulation="penalty", alpha=alpha).A)
        lam = sla.eigvals(model.A)
        floor = np.finfo(float).eps * np.linalg.norm(model.A)
        for r in exact:
            p = pen[np.argmin(np.abs(pen - r))]
            nearest = lam[np.argmin(np.abs(lam - r))]
            assert abs(nearest - r) <= gap * abs(p) + abs(p - r) + 1e-12 * abs(r)
            assert nearest.real <= floor or p.real >= 0.0   # no invented growth


@pytest.mark.parametrize("name", ["four_bar", "five_bar", "delta"])
def test_partitioned_and_orthonormal_bases_agree(name):
    a = np.linalg.eigvals(pinlin.linearize(URDF_DIR / f"{name}.toml").A)
    b = np.linalg.eigvals(pinlin.linearize(URDF_DIR / f"{name}.toml", basis="orthonormal").A)
    np.testing.assert_allclose(a[np.argsort(a.imag)], b[np.argsort(b.imag)], rtol=0,
                               atol=1e-10 * np.abs(a).max())


@pytest.mark.parametrize("backend", ["fd3", "fd5"])
def test_numerical_derivatives_on_a_loop(backend):
    exact = pinlin.linearize(URDF_DIR / "five_bar.toml")
    approx = pinlin.linearize(URDF_DIR / "five_bar.toml", derivatives=backend)
    tol = 1e-7 if backend == "fd3" else 1e-9
    np.testing.assert_allclose(approx.A, exact.A, rtol=0, atol=tol * abs(exact.A).max())


# ---------------------------------------------------------------------------------------------
# Pinocchio's constrained forward dynamics, differenced on the mechanism


def _check_against_constraint_dynamics(scene: pinlin.Scene, h: float = 1e-5
                                       ) -> pinlin.LinearModel:
    """d z''/d z of pinlin's independent model equals central differences (step ``h``) of
    Pinocchio's constraintDynamics (its proximal solver, its own loop Jacobians) at
    re-assembled configurations around q0, inputs held at u0. Tolerance 1e-6 of the largest
    entry: the truncation error of the differences (h^2 times the third derivative of the
    dynamics along z) stays below 1e-7 at the steps used (measured: it falls as h^2, 1.2e-6
    at 1e-5 and 1.3e-8 at 1e-6 on the two-branch weld, which therefore uses 1e-6)."""
    system = scene.system
    model = pinlin.linearize(scene)
    op = model.operating_point
    z = np.array([system.coordinate_names.index(n) for n in model.info["independent"]])
    pm = system.model
    contacts = pin.StdVec_RigidConstraintModel()
    for loop in scene.loops:
        f1, f2 = pm.frames[pm.getFrameId(loop.frame1)], pm.frames[pm.getFrameId(loop.frame2)]
        kind = pin.ContactType.CONTACT_3D if loop.type == "point" else pin.ContactType.CONTACT_6D
        contacts.append(pin.RigidConstraintModel(kind, pm, f1.parentJoint, f1.placement,
                                                 f2.parentJoint, f2.placement,
                                                 pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
    datas = pin.StdVec_RigidConstraintData()
    for c in contacts:
        datas.append(c.createData())
    pd = pm.createData()
    pin.initConstraintDynamics(pm, pd, contacts, datas)
    prox = pin.ProximalSettings(1e-14, 1e-8, 200)
    tau0 = system.input_matrix @ op.u

    def zdd(dz: np.ndarray) -> np.ndarray:
        step = np.zeros(system.nv)
        step[z] = dz
        q = assemble(system, pin.integrate(pm, op.q, step), z)
        tau = tau0 + system.spring_torque(q)
        a = pin.constraintDynamics(pm, pd, q, np.zeros(system.nv), tau, contacts, datas, prox)
        return a[z]

    nz = len(z)
    fd = np.zeros((nz, nz))
    for k in range(nz):
        e = np.zeros(nz)
        e[k] = h
        fd[:, k] = (zdd(e) - zdd(-e)) / (2 * h)
    np.testing.assert_allclose(model.A[nz:, :nz], fd, rtol=0, atol=1e-6 * abs(fd).max())
    assert abs(zdd(np.zeros(nz))).max() < 1e-8  # u0 holds the mechanism
    return model


@pytest.mark.parametrize("name", ["five_bar", "delta"])
def test_reduced_stiffness_matches_constrained_forward_dynamics(name):
    _check_against_constraint_dynamics(pinlin.Scene.load(URDF_DIR / f"{name}.toml"))


def _planar_arm_urdf(q_star: np.ndarray, length: float = 0.3, mass: float = 0.5) -> str:
    """4R planar arm (hinges about -y) and a base frame 'anchor' at its tip pose for q_star."""
    links, joints = ['<link name="base"/>'], []
    inertia = (f'<inertia ixx="1e-5" ixy="0" ixz="0" iyy="{mass * length**2 / 12}" iyz="0" '
               f'izz="{mass * length**2 / 12}"/>')
    parent = "base"
    for i in range(4):
        links.append(f'<link name="l{i}"><inertial><origin xyz="{length / 2} 0 0"/>'
                     f'<mass value="{mass}"/>{inertia}</inertial></link>')
        origin = "0 0 0" if i == 0 else f"{length} 0 0"
        joints.append(f'<joint name="j{i}" type="revolute"><parent link="{parent}"/>'
                      f'<child link="l{i}"/><origin xyz="{origin}"/><axis xyz="0 -1 0"/>'
                      '<limit lower="-9" upper="9" effort="9" velocity="9"/></joint>')
        parent = f"l{i}"
    links += ['<link name="tip"/>', '<link name="anchor"/>']
    joints.append(f'<joint name="tip_fixed" type="fixed"><parent link="l3"/><child link="tip"/>'
                  f'<origin xyz="{length} 0 0"/></joint>')
    angles = np.cumsum(q_star)
    x = float(length * np.sum(np.cos(angles)))
    zc = float(length * np.sum(np.sin(angles)))
    joints.append(f'<joint name="anchor_fixed" type="fixed"><parent link="base"/>'
                  f'<child link="anchor"/><origin xyz="{x!r} 0 {zc!r}" '
                  f'rpy="0 {-float(angles[-1])!r} 0"/></joint>')
    return '<?xml version="1.0"?>\n<robot name="arm4">' + "".join(links + joints) + "</robot>"


def test_weld_loop_planar_arm(tmp_path):
    """A 4R planar arm whose tip is welded to a base frame: one degree of freedom left, three
    of the six weld rows (y, rx, rz) redundant; checked against Pinocchio's 6-D constraint
    dynamics."""
    q_star = np.array([0.3, 0.4, -0.5, 0.2])
    (tmp_path / "arm4.urdf").write_text(_planar_arm_urdf(q_star))
    guess = q_star + np.array([0.0, 0.05, -0.04, 0.03])
    scene = pinlin.Scene.from_dict({
        "urdf": str(tmp_path / "arm4.urdf"),
        "effects": {"gravity": [0, 0, -G],
                    "springs": {f"j{i}": {"stiffness": 5.0, "rest": float(q_star[i])}
                                for i in range(4)}},
        "loops": [{"name": "grip", "type": "weld", "frame1": "tip", "frame2": "anchor"}],
        "operating_point": {"q": {f"j{i}": float(guess[i]) for i in range(4)},
                            "independent": ["j0"]},
        "inputs": {"actuated": ["j0"]}})
    model = _check_against_constraint_dynamics(scene)
    assert model.n_states == 2
    assert sorted(model.info["dropped_rows"]) == ["grip.rx", "grip.rz", "grip.y"]
    np.testing.assert_allclose(model.operating_point.q, q_star, atol=1e-10)


def _two_branch_urdf(tip_b: pin.SE3 | None) -> str:
    """Two spatial 4R branches from one base (axes z, y, x, y; rods 0.3 m of 0.5 kg along x),
    the second starting at (0.5, 0.2, 0); frame 'tip_a' at the first branch's end and
    'tip_b' on the second's last link at ``tip_b`` (identity when None)."""
    axes = ("0 0 1", "0 1 0", "1 0 0", "0 1 0")
    inertia = '<inertia ixx="2e-4" ixy="0" ixz="0" iyy="4e-3" iyz="0" izz="4e-3"/>'
    links, joints = ['<link name="base"/>'], []
    for branch, origin in (("a", "0 0 0"), ("b", "0.5 0.2 0")):
        parent = "base"
        for i, axis in enumerate(axes):
            links.append(f'<link name="{branch}{i}"><inertial><origin xyz="0.15 0 0"/>'
                         f'<mass value="0.5"/>{inertia}</inertial></link>')
            xyz = origin if i == 0 else "0.3 0 0"
            joints.append(f'<joint name="{branch}{i}" type="revolute"><parent link="{parent}"/>'
                          f'<child link="{branch}{i}"/><origin xyz="{xyz}"/><axis xyz="{axis}"/>'
                          '<limit lower="-9" upper="9" effort="9" velocity="9"/></joint>')
            parent = f"{branch}{i}"
    tip_b = pin.SE3.Identity() if tip_b is None else tip_b
    rpy = pin.rpy.matrixToRpy(tip_b.rotation)
    links += ['<link name="tip_a"/>', '<link name="tip_b"/>']
    joints.append('<joint name="tip_a_fixed" type="fixed"><parent link="a3"/>'
                  '<child link="tip_a"/><origin xyz="0.3 0 0"/></joint>')
    joints.append('<joint name="tip_b_fixed" type="fixed"><parent link="b3"/><child link="tip_b"/>'
                  f'<origin xyz="{" ".join(repr(float(x)) for x in tip_b.translation)}" '
                  f'rpy="{" ".join(repr(float(x)) for x in rpy)}"/></joint>')
    return '<?xml version="1.0"?>\n<robot name="two_branches">' + "".join(links + joints) + \
        "</robot>"


def test_spatial_weld_between_two_moving_branches(tmp_path):
    """Two spatial 4R branches welded tip to tip (8 joints - 6 rows = 2 DoF), loaded by gravity
    and springs: the weld's force and moment both load the geometric stiffness, whose
    rotation rows need the full (symmetric) Hessian - the planar bundled loops cannot tell.
    Checked against Pinocchio's 6-D constraint dynamics differenced on the mechanism."""
    q_star = np.array([0.3, -0.5, 0.4, 0.9, 2.6, 0.4, -0.3, -0.8])
    path = tmp_path / "two_branches.urdf"
    path.write_text(_two_branch_urdf(None))
    pm = pin.buildModelFromUrdf(str(path))
    pd = pm.createData()
    pin.framesForwardKinematics(pm, pd, q_star)
    # Place tip_b so that it coincides with tip_a at q_star.
    on_b3 = pd.oMf[pm.getFrameId("tip_b")].inverse() * pd.oMf[pm.getFrameId("tip_a")]
    path.write_text(_two_branch_urdf(on_b3))
    names = [f"a{i}" for i in range(4)] + [f"b{i}" for i in range(4)]
    guess = q_star + 0.02 * np.array([0, 1, -1, 1, 0, 1, -1, 1])
    scene = pinlin.Scene.from_dict({
        "urdf": str(path),
        "effects": {"gravity": [0, 0, -G],
                    "springs": {n: {"stiffness": 3.0, "rest": float(q) + 0.1}
                                for n, q in zip(names, q_star, strict=True)}},
        "loops": [{"name": "weld", "type": "weld", "frame1": "tip_a", "frame2": "tip_b"}],
        "operating_point": {"q": {n: float(g) for n, g in zip(names, guess, strict=True)},
                            "independent": ["a0", "b0"]},
        "inputs": {"actuated": "all"}})
    model = _check_against_constraint_dynamics(scene, h=1e-6)
    assert model.n_states == 4 and not model.info["dropped_rows"]
    lam = model.operating_point.lam
    assert np.abs(lam[:3]).max() > 0.5 and np.abs(lam[3:]).max() > 0.05  # force and moment


# ---------------------------------------------------------------------------------------------
# Operating points, notes, mimic


def test_redundant_row_is_dropped_and_reported():
    model = pinlin.linearize(URDF_DIR / "four_bar.toml")
    assert model.info["dropped_rows"] == ["closure.y"]
    assert any("redundant" in n for n in model.operating_point.notes)
    op = model.operating_point
    assert op.lam_names == ("closure.x", "closure.y", "closure.z") and op.lam[1] == 0.0


def test_redundant_actuation_reports_the_least_norm_inputs():
    """Crank and rocker both driven: the inputs and loop forces that hold q0 form a family;
    pinlin reports that and the least-norm member with the norm in N*m (the loop's forces
    times the radius of gyration of the links, from their inertias here; the input torques
    as they are): W x orthogonal to W times the family's directions (the nullspace of
    [S, Phi_q^T] from an SVD). With the crank alone the note is absent."""
    import scipy.linalg as sla

    single = pinlin.linearize(URDF_DIR / "four_bar.toml")
    assert not any("not unique" in n for n in single.operating_point.notes)
    import tomllib

    data = tomllib.loads((URDF_DIR / "four_bar.toml").read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    data["inputs"]["actuated"] = ["crank", "rocker"]
    scene = pinlin.Scene.from_dict(data)
    model = pinlin.linearize(scene)
    op = model.operating_point
    assert any("not unique" in n for n in op.notes)
    system = scene.system
    G = system.constraints.jacobian(op.q)[[0, 2]]  # closure.y is the redundant row
    SG = np.hstack([system.input_matrix, G.T])
    x = np.concatenate([op.u, op.lam[[0, 2]]])
    f = pin.computeGeneralizedGravity(system.model, system.model.createData(), op.q) \
        - system.spring_torque(op.q)
    np.testing.assert_allclose(SG @ x, f, atol=1e-9)
    null = sla.null_space(SG)
    assert null.shape[1] == 1
    L = radius_of_gyration(system.model, op.q)
    assert weighted_orthogonality(null, x, np.array([1.0, 1.0, L, L])) < 1e-9
    assert any(f"the radius of gyration, {L:.4g} m" in n for n in op.notes)


def test_constraint_forces_balance_the_statics():
    """f - tau_spring = S u0 + Phi_q^T lam, with Phi_q from finite differences of the frame
    positions (a second route to the loop Jacobian)."""
    scene = pinlin.Scene.load(URDF_DIR / "slider_crank.toml")
    system = scene.system
    op = pinlin.linearize(scene).operating_point
    pm, pd = system.model, system.model.createData()
    f1, f2 = pm.getFrameId("rod_tip"), pm.getFrameId("slider_pin")

    def gap(q):
        pin.framesForwardKinematics(pm, pd, q)
        return pd.oMf[f1].translation - pd.oMf[f2].translation

    J = np.zeros((3, system.nv))
    for k in range(system.nv):
        e = np.zeros(system.nv)
        e[k] = 1e-6
        J[:, k] = (gap(pin.integrate(pm, op.q, e)) - gap(pin.integrate(pm, op.q, -e))) / 2e-6
    f = pin.computeGeneralizedGravity(pm, pd, op.q) - system.spring_torque(op.q)
    np.testing.assert_allclose(system.input_matrix @ op.u + J.T @ op.lam, f, atol=1e-8)


MIMIC_URDF = """<?xml version="1.0"?>
<robot name="mimic_pair">
  <link name="base"/>
  <link name="a_link"><inertial><origin xyz="0 0 -{l1}"/><mass value="{m1}"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="b_link"><inertial><origin xyz="0 0 -{l2}"/><mass value="{m2}"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="a" type="revolute"><parent link="base"/><child link="a_link"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="b" type="revolute"><parent link="base"/><child link="b_link"/>
    <origin xyz="1 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/>
    <mimic joint="a" multiplier="{r}" offset="0"/></joint>
</robot>
"""


def test_mimic_coupling_reduces_to_one_coordinate(tmp_path):
    """Two point-mass pendulums side by side, b = r a: M_z = m1 l1^2 + r^2 m2 l2^2 and
    K_z = g (m1 l1 + r^2 m2 l2) by hand; without effects.mimic the joints are free."""
    m1, l1, m2, l2, r = 1.0, 0.7, 0.5, 0.4, 2.0
    urdf = tmp_path / "pair.urdf"
    urdf.write_text(MIMIC_URDF.format(m1=m1, l1=l1, m2=m2, l2=l2, r=r))
    coupled = pinlin.linearize(pinlin.Scene.from_urdf(
        urdf, effects={"gravity": [0, 0, -G], "mimic": True}, inputs={"actuated": ["a"]}))
    assert coupled.state_names == ("q:a", "v:a")
    assert coupled.M[0, 0] == pytest.approx(m1 * l1**2 + r * r * m2 * l2**2, rel=1e-12)
    assert coupled.K[0, 0] == pytest.approx(G * (m1 * l1 + r * r * m2 * l2), rel=1e-12)
    free = pinlin.linearize(pinlin.Scene.from_urdf(urdf))
    assert free.n_states == 4


def test_panda_fingers_mimic():
    scene = pinlin.Scene.from_robot("panda", effects={"gravity": True, "mimic": True})
    model = pinlin.linearize(scene)
    assert model.n_states == 2 * (scene.system.nv - 1)
    assert "mimic:panda_finger_joint2" in model.operating_point.lam_names


SPHERICAL_URDF = """<?xml version="1.0"?>
<robot name="gimbal_pendulum">
  <link name="base"/>
  <link name="ring"/>
  <link name="bob"><inertial><origin xyz="0 0 -{L}"/><mass value="{m}"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="roll" type="revolute"><parent link="base"/><child link="ring"/>
    <axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="pitch" type="revolute"><parent link="ring"/><child link="bob"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


@pytest.mark.parametrize("rate", [0.7, -1.3])
def test_steady_rotation_coriolis(tmp_path, rate):
    """A point-mass pendulum free in two directions, in a frame spinning at rate W about the
    vertical: x'' - 2 W y' + (g/L - W^2) x = 0 and y'' + 2 W x' + (g/L - W^2) y = 0, whose
    eigenvalues are +-i (w0 + W) and +-i (w0 - W) with w0 = sqrt(g/L) (Foucault). The gyroscopic
    coupling is in C_damp, so the general eigensolver is used."""
    L, m = 0.8, 1.5
    urdf = tmp_path / "gimbal.urdf"
    urdf.write_text(SPHERICAL_URDF.format(L=L, m=m))
    scene = pinlin.Scene.from_urdf(urdf, effects={
        "gravity": [0, 0, -G], "rotation": {"axis": [0, 0, 1], "rate": rate}})
    model = pinlin.linearize(scene)
    w0 = math.sqrt(G / L)
    expected = np.array([w0 + rate, w0 - rate, -(w0 + rate), -(w0 - rate)])
    modes = pinlin.modal(model)
    assert modes.method == "general"
    np.testing.assert_allclose(np.abs(modes.eigenvalues.real), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.sort(modes.eigenvalues.imag), np.sort(expected), rtol=1e-12)
    C = model.C_damp
    assert C[0, 1] == pytest.approx(-C[1, 0]) and abs(C[0, 1]) == pytest.approx(
        2 * abs(rate) * m * L * L, rel=1e-12)


@pytest.mark.parametrize("options", [{"mu": 1e15}, {"alpha": 1.0, "omega": 1e8}])
def test_penalty_spectra_float64_cannot_hold_are_warned_not_called_rigid(options):
    """Omega and mu put the constraint modes at ~Omega and ~2 mu Omega: 1e16 times the
    four-bar's 4.8066 rad/s (the independent model's) is beyond float64, and the physical pair
    comes out wrong (3.45 +- 3.44j, 5.42j). modal must warn, and must not call the physical
    modes rigid by a threshold set by the constraint modes (it did: no warning at all)."""
    model = pinlin.linearize("four_bar", formulation="penalty", **options)
    with pytest.warns(pinlin.AccuracyWarning, match="rounding in A alone may move it"):
        modes = pinlin.modal(model)
    physical = [i for i in range(len(modes.eigenvalues)) if not modes.constraint[i]]
    assert physical and not any(modes.rigid[i] for i in physical)
    # At the defaults (alpha = 1e7, Omega = 10, mu = 1) the same analysis is quiet and equal
    # to the independent model's to the penalty error c / alpha (2.8e-8 for the four-bar,
    # validation/reports/penalty_conditioning.md; 1e-5 leaves a wide margin).
    reference = np.abs(np.linalg.eigvals(pinlin.linearize("four_bar").A)).max()
    with warnings.catch_warnings():
        warnings.simplefilter("error", pinlin.AccuracyWarning)
        quiet = pinlin.modal(pinlin.linearize("four_bar", formulation="penalty"))
    kept = [i for i in range(len(quiet.eigenvalues)) if not quiet.constraint[i]]
    np.testing.assert_allclose(np.abs(quiet.eigenvalues[kept]), reference, rtol=1e-5)


def test_a_given_position_that_the_assembly_moved_is_noted():
    """The four-bar's scene gives coupler and rocker angles as starting guesses; pinlin keeps
    the crank and closes the loop by moving them. The model said which coordinates it kept,
    not that the given values had moved: now a note names each with its change, and the
    changes are the differences between the scene's q and the assembled q0."""
    from pinlin.operating_point import configuration

    scene = pinlin.Scene.resolve("four_bar")
    model = pinlin.linearize(scene)
    q0 = model.operating_point.q
    q_given = configuration(scene.system)
    diff = pin.difference(scene.system.model, q_given, q0)
    note = next(n for n in model.operating_point.notes if n.startswith("joint positions"))
    for name in ("coupler", "rocker"):
        j = scene.system.joints[name]
        assert f"{name} by {diff[j.idx_v]:+.6g}" in note and abs(diff[j.idx_v]) > 1e-3
    assert "crank" not in note


def test_a_guess_near_a_singular_position_assembles_within_a_turn_of_it():
    """The five-bar from 300 guesses of its distal angles within +-pi (cranks at the scene's
    values): near straight elbows Phi_d is nearly singular and Newton jumps far; it
    assembled at angles up to 468 rad, 74 turns from the guess. Now every revolute angle
    lies within pi of its guess and the loop is closed (whole turns move no frame)."""
    scene = pinlin.Scene.load(URDF_DIR / "five_bar.toml")
    system = scene.system
    base = pinlin.linearize(scene).operating_point.q
    rng = np.random.default_rng(0)
    frames = [system.kin_model.getFrameId(f) for f in ("left_tip", "right_tip")]
    data = system.kin_model.createData()
    closed = 0
    for _ in range(300):
        guess = base.copy()
        guess[[1, 3]] = rng.uniform(-np.pi, np.pi, 2)
        try:
            q = pinlin.operating_point(scene, q=guess).q
        except pinlin.AssemblyError:    # 2 of 300 do not close from their guess
            continue
        assert np.abs(q - guess).max() <= np.pi, (guess, q)
        pin.framesForwardKinematics(system.kin_model, data, q)
        tips = [data.oMf[f].translation.copy() for f in frames]
        # closed to the assembly's tolerance, relative to the mechanism's size
        assert np.abs(tips[0] - tips[1]).max() <= ASSEMBLY_TOL * system.constraints.length_scale
        closed += 1
    assert closed >= 290
