"""Cases where linearizers break. Each test states the property that must hold:

- finite results (no NaN or inf);
- eigenvalue errors within the bound set by the reported condition estimate
  (|d lam| <= C kappa |dA|, kappa from pinlin.modal's left and right vectors);
- no spurious instability: an undamped (conservative) model has a Hamiltonian spectrum
  (lam and -lam together; oscillatory modes on the imaginary axis), a dissipative one no
  eigenvalue right of the imaginary axis beyond tolerance;
- a warning carrying the condition estimate whenever accuracy is at risk, and real
  instabilities reported as such.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR, aba_jacobians

import pinlin

EPS = np.finfo(float).eps


def _finite(model: pinlin.LinearModel) -> None:
    for key in ("A", "B", "C", "D"):
        assert np.all(np.isfinite(getattr(model, key))), key


def _hamiltonian(modes: pinlin.ModalAnalysis, rtol: float = 1e-8) -> None:
    """Undamped mechanical model: the spectrum is symmetric under lam -> -lam and oscillatory
    modes have no real part beyond rounding (no invented growth or decay). Only meaningful on
    the general eigensolver's output: the symmetric path returns +-i wn by construction."""
    assert modes.method == "general", "the symmetric path is Hamiltonian by construction"
    lam = modes.eigenvalues
    scale = max(1.0, float(np.abs(lam).max()))
    for x in lam:
        assert np.min(np.abs(lam + x)) <= rtol * scale, x
    osc = np.abs(lam.imag) > modes.rigid_tol
    assert np.all(np.abs(lam[osc].real) <= rtol * scale)


def model_terms(scene: pinlin.Scene, op) -> tuple[np.ndarray, np.ndarray]:
    """(M, K) in all coordinates at a loaded point: Pinocchio's crba, and central differences
    of gravity - springs - Phi_q^T lam (lam held) on the manifold."""
    system = scene.system
    model = system.model
    data = model.createData()
    M = pin.crba(model, data, op.q)
    M = np.triu(M) + np.triu(M, 1).T

    def held(q: np.ndarray) -> np.ndarray:
        tau = pin.computeGeneralizedGravity(model, data, q) - system.spring_torque(q)
        return tau - system.constraints.jacobian(q).T @ op.lam

    h = 1e-6
    K = np.array([(held(pin.integrate(model, op.q, h * e)) - held(pin.integrate(model, op.q,
                                                                                -h * e)))
                  / (2 * h) for e in np.eye(model.nv)]).T
    return M, K


def _fd_reference(scene: pinlin.Scene, model: pinlin.LinearModel) -> np.ndarray:
    """A from central differences of pin.aba on the manifold (tests/conftest.py)."""
    system = scene.system
    op = model.operating_point
    A, _ = aba_jacobians(system.model, op.q, system.input_matrix @ op.u, system.input_matrix,
                         lambda q, v: system.spring_torque(q))
    return A


def test_stretched_arm_at_a_kinematic_singularity():
    """UR5 stretched straight up (shoulder lift -pi/2, all else 0): the tool Jacobian loses
    rank and the joints about vertical axes carry no gravity stiffness. The model stays finite,
    matches finite differences of aba, the upright arm held by constant torques is reported as
    unstable (a real saddle pair), and its spectrum is Hamiltonian (no spurious growth)."""
    scene = pinlin.Scene.from_robot("ur5", operating_point={"q": {
        "shoulder_lift_joint": -math.pi / 2, "elbow_joint": 0.0, "wrist_1_joint": 0.0,
        "wrist_2_joint": 0.0, "wrist_3_joint": 0.0, "shoulder_pan_joint": 0.0}},
        outputs={"frames": ["tool0"]})
    model = pinlin.linearize(scene)
    _finite(model)
    np.testing.assert_allclose(model.A, _fd_reference(scene, model), rtol=0,
                               atol=1e-7 * np.abs(model.A).max())
    modes = pinlin.modal(model, method="general")
    _hamiltonian(modes)
    assert modes.unstable.any() and all(modes.kind(i).startswith("unstable")
                                        for i in np.flatnonzero(modes.unstable))


def _rocker_extreme() -> float:
    """Smallest rocker angle of the bundled four-bar (from +x): crank and coupler extended in
    line, |O2 C| = a + b (law of cosines in the triangle O2 O4 C)."""
    a, b, c, d = 0.2, 0.5, 0.4, 0.45
    e = a + b
    return math.pi - math.acos((c * c + d * d - e * e) / (2 * c * d))


def _matched(ref: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """lam reordered to pair with ref (linear assignment on |ref_i - lam_j|)."""
    from scipy.optimize import linear_sum_assignment

    _, cols = linear_sum_assignment(np.abs(ref[:, None] - lam[None, :]))
    return lam[cols]


@pytest.mark.parametrize("delta", [1e-2, 1e-6, 1e-12])
def test_four_bar_near_toggle(delta):
    """The rocker as independent coordinate near its extreme, where the crank and coupler align:
    Phi_d is near singular, R ill-conditioned. pinlin warns with the condition estimate when it
    exceeds 1e6, and the physical eigenvalue still equals the one from the well-conditioned
    parametrization (crank independent, same configuration) within a bound that grows with
    that condition number. Near the fold the condition grows like 1 / sqrt(delta), until the
    assembly's tolerance stops it: from delta ~ 1e-12 it floors at 1.8e6-2e6 (where Newton
    stops, ~4e-12 from the fold), which is why delta = 1e-12 exercises the warned branch
    (the warning and the assertion read the same number, so the switch cannot flip)."""
    psi = _rocker_extreme() + delta
    base = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    data = {"urdf": str(base.urdf), "effects": {"gravity": [0, 0, -9.81],
                                                "springs": {"crank": {"stiffness": 2.0,
                                                                      "rest": 1.0}}},
            "loops": [{"name": "closure", "frame1": "coupler_tip", "frame2": "rocker_tip"}],
            "inputs": {"actuated": ["crank"]}}
    guess = {"crank": 0.5, "coupler": -0.1, "rocker": psi}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        by_rocker = pinlin.linearize(pinlin.Scene.from_dict({
            **data, "operating_point": {"q": guess, "independent": ["rocker"]}}))
    cond = by_rocker.info["condition"]["constraint_jacobian"]
    warned = [w for w in caught if issubclass(w.category, pinlin.AccuracyWarning)]
    assert (cond > 1e6) == bool(warned)
    if warned:
        assert warned[0].message.condition == pytest.approx(cond)
    q = by_rocker.operating_point.q
    by_crank = pinlin.linearize(pinlin.Scene.from_dict({
        **data, "operating_point": {"q": {"crank": q[0], "coupler": q[1], "rocker": q[2]},
                                    "independent": ["crank"]}}))
    a = np.linalg.eigvals(by_rocker.A)
    b = np.linalg.eigvals(by_crank.A)
    assert np.all(np.isfinite(a))
    bound = 1e-12 * cond + 1e-12
    np.testing.assert_allclose(_matched(b, a), b, rtol=bound)
    assert cond > 0.1 / math.sqrt(delta)  # the estimate sees the singularity coming


def _non_grashof_four_bar(tmp_path) -> tuple[dict, float, float, float]:
    """A triple-rocker four-bar (a = 0.6, b = 0.4, c = 0.45, d = 0.3 m: s + l > p + q, so the
    crank cannot turn fully). Returns the scene data, the crank's limit angle (coupler and
    rocker in line: |A O4| = b + c, law of cosines) and the coupler and rocker angles there."""
    import sys

    sys.path.insert(0, str(URDF_DIR))
    import make_mechanisms as mk

    a, b, c, d = 0.6, 0.4, 0.45, 0.3
    parts = mk.four_bar_parts(a, b, c, d, {"crank": 0.4, "coupler": 1.0, "rocker": 0.8})
    path = tmp_path / "non_grashof.urdf"
    path.write_text('<?xml version="1.0"?>\n<robot name="non_grashof">\n' + "\n".join(parts)
                    + "\n</robot>\n")
    limit = math.acos((a * a + d * d - (b + c) ** 2) / (2 * a * d))
    ax, az = a * math.cos(limit), a * math.sin(limit)
    ux, uz = (ax - d) / (b + c), az / (b + c)
    rocker = math.atan2(uz, ux)
    coupler = math.atan2(-uz, -ux) - limit
    data = {"urdf": str(path), "effects": {"gravity": [0, 0, -9.81]},
            "loops": [{"name": "closure", "frame1": "coupler_tip", "frame2": "rocker_tip"}],
            "inputs": {"actuated": ["crank"]}}
    return data, limit, coupler, rocker


def test_crank_driven_to_its_limit_is_warned(tmp_path):
    """A non-Grashof four-bar whose crank is driven exactly to its limit: there the mechanism
    locks (the frequency grows like distance^-1/4 and is infinite at the limit), so any finite
    model is an artefact of where the assembly stopped. The geometry fixes both measures at a
    distance d from the limit: condition ~1.76 d^-1/2, sensitivity ~2.8e-11 d^-1/2. At
    d = 5e-11 the condition (2.3e5) stays 4x below the fixed 1e6 threshold while the
    sensitivity of A to configurations the assembly cannot tell apart (3.7e-6) is 3.7x above
    its 1e-6 warning: only the sensitivity warns. At d = 1e-7 (condition 5.6e3, measured
    because above 1e3) the sensitivity is 8.9e-8, 11x below, and nothing is warned. At the
    limit itself the model is finite and warned."""
    data, limit, coupler, rocker = _non_grashof_four_bar(tmp_path)
    guess = {"coupler": coupler, "rocker": rocker}
    results = {}
    for distance in (1e-2, 1e-4, 1e-6, 1e-7, 1e-9, 5e-11, 0.0):  # continuation to the limit
        point = {"q": {"crank": limit - distance, **guess}, "independent": ["crank"]}
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model = pinlin.linearize(pinlin.Scene.from_dict({**data, "operating_point": point}))
        guess = {"coupler": model.operating_point.q[1], "rocker": model.operating_point.q[2]}
        results[distance] = (model, [w for w in caught
                                     if issubclass(w.category, pinlin.AccuracyWarning)])
    near, near_warnings = results[1e-7]
    assert not near_warnings
    assert near.info["condition"]["operating_point_sensitivity"] < 1e-6
    close, close_warnings = results[5e-11]
    assert close.info["condition"]["constraint_jacobian"] < 1e6
    assert close.info["condition"]["operating_point_sensitivity"] > 1e-6
    assert [str(w.message) for w in close_warnings if "singular position" in str(w.message)]
    assert not [w for w in close_warnings if "condition number" in str(w.message)]
    at, at_warnings = results[0.0]
    assert at_warnings
    _finite(at)


def test_floating_base_upside_down():
    """A floating quadruped turned upside down (180 degrees about x, quaternion with w = 0)
    in free fall: A matches finite differences of aba on the manifold."""
    scene = pinlin.Scene.from_robot("solo12", operating_point={
        "allow_non_equilibrium": True,
        "q": {"root_joint": {"position": [0.0, 0.0, 0.4], "quaternion": [1.0, 0.0, 0.0, 0.0]}}})
    model = pinlin.linearize(scene)
    _finite(model)
    np.testing.assert_allclose(model.A, _fd_reference(scene, model), rtol=0,
                               atol=1e-7 * np.abs(model.A).max())


def test_humanoid_with_50_dof():
    """talos_full (nv = 50) floating in zero gravity, every joint servoed: symmetric and general
    eigensolvers agree, exactly six rigid-body DoF (12 zero eigenvalues), Hamiltonian spectrum."""
    probe = pinlin.Scene.from_robot("talos_full")
    joints = [n for n in probe.system.joints if n != "root_joint"]
    scene = pinlin.Scene.from_robot("talos_full", effects={
        "armature": True, "springs": {j: {"stiffness": 100.0} for j in joints}})
    model = pinlin.linearize(scene)
    assert scene.system.nv == 50
    sym = pinlin.modal(model, method="symmetric")
    gen = pinlin.modal(model, method="general")
    assert sym.rigid.sum() == gen.rigid.sum() == 12
    ok = ~sym.rigid
    bound = 10 * gen.condition[ok] * EPS * np.abs(model.A).max()
    pairs = _matched(gen.eigenvalues[ok], sym.eigenvalues[ok])
    assert np.all(np.abs(pairs - gen.eigenvalues[ok]) <= bound + 1e-12)
    _hamiltonian(gen, rtol=1e-7)


def test_continuous_joints_match_revolute():
    """example-robot-data's double pendulum with continuous joints (nq = 4, nv = 2) has the
    same eigenvalues as the revolute one."""
    a = pinlin.linearize(pinlin.Scene.from_robot("double_pendulum"))
    b = pinlin.linearize(pinlin.Scene.from_robot("double_pendulum_continuous"))
    assert b.operating_point.q.size == 4 and b.n_states == 4
    la, lb = np.linalg.eigvals(a.A), np.linalg.eigvals(b.A)
    np.testing.assert_allclose(np.sort_complex(la), np.sort_complex(lb), rtol=1e-12)


def test_mimic_fingers_penalty_and_independent():
    """Panda with its finger mimic coupling: independent and penalty physical eigenvalues agree
    to O(1/alpha); nothing is NaN."""
    scene = pinlin.Scene.from_robot("panda", effects={"gravity": True, "mimic": True})
    ind = pinlin.linearize(scene)
    pen = pinlin.linearize(scene, formulation="penalty", alpha=1e10)
    _finite(ind)
    _finite(pen)
    modes = pinlin.modal(pen)
    phys = modes.eigenvalues[~modes.constraint]
    ref = np.linalg.eigvals(ind.A)
    for x in ref:
        assert np.min(np.abs(phys - x)) <= 1e-6 * max(1.0, abs(x))


CHAIN = """<?xml version="1.0"?>
<robot name="ratio_chain"><link name="base"/>{links}{joints}</robot>"""


def _ratio_chain(masses: list[float]) -> str:
    links, joints, parent = "", "", "base"
    for i, m in enumerate(masses):
        inertia = m * 0.3**2 / 12
        links += (f'<link name="l{i}"><inertial><origin xyz="0.15 0 0"/><mass value="{m!r}"/>'
                  f'<inertia ixx="{inertia / 100!r}" ixy="0" ixz="0" iyy="{inertia!r}" iyz="0" '
                  f'izz="{inertia!r}"/></inertial></link>')
        origin = "0 0 0" if i == 0 else "0.3 0 0"
        joints += (f'<joint name="j{i}" type="revolute"><parent link="{parent}"/>'
                   f'<child link="l{i}"/><origin xyz="{origin}"/><axis xyz="0 1 0"/>'
                   '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>')
        parent = f"l{i}"
    return CHAIN.format(links=links, joints=joints)


@pytest.mark.parametrize("ratio", [1e-2, 1e-5])
def test_mass_ratio_along_a_chain(tmp_path, ratio):
    """Masses (and inertias) falling by ``ratio`` from link to link of a servoed chain: M spans
    up to 15 decades (down to 1e-15 kg: below eps, 2.2e-16 kg, Pinocchio's inertia arithmetic
    shrinks a link's centre-of-mass offset, and such URDFs are refused). pinlin warns, carrying
    the mass-matrix condition estimate, exactly when that estimate passes 1e10; the symmetric
    (K, M) eigensolver and the general one on A agree within 10 kappa eps |A| per eigenvalue,
    and nothing is NaN."""
    urdf = tmp_path / "chain.urdf"
    urdf.write_text(_ratio_chain([ratio**i for i in range(4)]))
    scene = pinlin.Scene.from_urdf(urdf, effects={
        "gravity": [0, 0, -9.81], "springs": {f"j{i}": {"stiffness": ratio**i}
                                              for i in range(4)}},
        operating_point={"q": {"j0": -math.pi / 2}})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = pinlin.linearize(scene)
    _finite(model)
    cond = model.info["condition"]["mass_matrix"]
    mass_warnings = [w for w in caught if "mass matrix" in str(w.message)]
    assert bool(mass_warnings) == (cond > 1e10)
    for w in mass_warnings:
        assert w.message.condition == pytest.approx(cond)
    sym = pinlin.modal(model, method="symmetric")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        gen = pinlin.modal(model, method="general")
    bound = 10 * gen.condition * EPS * np.abs(model.A).max()
    assert np.all(np.abs(_matched(gen.eigenvalues, sym.eigenvalues) - gen.eigenvalues) <= bound)
    _hamiltonian(gen, rtol=max(1e-8, float(bound.max()) / max(1.0, np.abs(gen.eigenvalues).max())))


def test_repeated_eigenvalues_of_a_symmetric_robot():
    """Solo12 on a fixed base with identical servos: mirrored legs give repeated eigenvalues.
    Right and left vectors still diagonalize A (A R = R L, L^H R = I) to rounding, and both
    eigensolvers agree."""
    probe = pinlin.Scene.from_robot("solo12")
    joints = [n for n in probe.system.joints if n != "root_joint"]
    model = pinlin.linearize(pinlin.Scene.from_robot("solo12", base="fixed", effects={
        "springs": {j: {"stiffness": 5.0} for j in joints}}))
    sym = pinlin.modal(model, method="symmetric")
    gen = pinlin.modal(model, method="general")
    lam = sym.eigenvalues
    wn = np.sort(sym.wn)
    assert np.any(np.isclose(wn[:-2], wn[2:], rtol=1e-9))  # a double pair
    R, L = sym.right_vectors, sym.left_vectors
    scale = np.abs(model.A).max()
    # Right vectors, left vectors (L^H A = lam L^H: swapping L and R fails here) and their
    # biorthonormality, to rounding.
    assert np.abs(model.A @ R - R * lam).max() <= 1e-10 * scale
    assert np.abs(L.conj().T @ model.A - lam[:, None] * L.conj().T).max() <= 1e-10 * scale
    assert np.abs(L.conj().T @ R - np.eye(len(lam))).max() <= 1e-9
    np.testing.assert_allclose(np.sort(np.abs(sym.eigenvalues)), np.sort(np.abs(gen.eigenvalues)),
                               rtol=1e-10)


def test_zero_eigenvalues_with_jordan_blocks():
    """A free-floating quadruped in zero gravity with servoed joints: six rigid-body DoF give
    six 2x2 Jordan blocks at zero, labelled rigid (zeta undefined, never 0/0), with Jordan chains
    A r1 = 0, A r2 = r1 from the symmetric path."""
    probe = pinlin.Scene.from_robot("solo12")
    joints = [n for n in probe.system.joints if n != "root_joint"]
    scene = pinlin.Scene.from_robot("solo12", effects={
        "springs": {j: {"stiffness": 5.0} for j in joints}})
    model = pinlin.linearize(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no division warnings
        modes = pinlin.modal(model)
        gen = pinlin.modal(model, method="general")
    assert modes.method == "symmetric"
    assert modes.rigid.sum() == gen.rigid.sum() == 12
    assert np.all(np.isnan(modes.zeta[modes.rigid]))
    assert all(modes.kind(i) == "rigid" for i in np.flatnonzero(modes.rigid))
    R = modes.right_vectors
    scale = np.abs(model.A).max()
    for k in np.flatnonzero(modes.rigid)[::2]:
        assert np.abs(model.A @ R[:, k]).max() <= 1e-10 * scale
        assert np.abs(model.A @ R[:, k + 1] - R[:, k]).max() <= 1e-10 * scale
    # Jordan blocks split by ~sqrt(eps) |A| in a general eigensolver: the tolerance for the
    # rigid pairs' symmetry (non-rigid modes hold to 1e-8 of the largest).
    _hamiltonian(gen, rtol=max(1e-8, 10 * np.sqrt(EPS) * scale
                               / max(1.0, np.abs(gen.eigenvalues).max())))


def test_redundant_constraint_row():
    """A planar loop closed with a 3-D point constraint: the out-of-plane row is dropped and
    reported, its force is zero, and dropping it changes nothing: its Jacobian row vanishes
    at q0 (the loop frames never leave the plane), so the kept rows span the same motions,
    and the model equals the one in an orthonormal nullspace basis of the full Jacobian (all
    three rows, computed here), whose eigenvalues do not depend on the choice of rows."""
    scene = pinlin.Scene.load(URDF_DIR / "five_bar.toml")
    model = pinlin.linearize(scene)
    assert model.info["dropped_rows"] == ["end_effector.y"]
    op = model.operating_point
    assert op.lam[op.lam_names.index("end_effector.y")] == 0.0
    assert any("redundant" in n for n in op.notes)
    _finite(model)
    full = scene.system.constraints.jacobian(op.q)
    row = scene.system.constraints.row_names.index("end_effector.y")
    assert np.abs(full[row]).max() <= 1e-12 * np.abs(full).max()
    import scipy.linalg as sla

    N = sla.null_space(full)  # all rows, the redundant one included
    assert N.shape[1] == model.n_states // 2
    M, K = model_terms(scene, op)
    Mz, Kz = N.T @ M @ N, N.T @ K @ N
    wn_full = np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(Mz, Kz)).real))
    lam = np.linalg.eigvals(model.A)
    wn = np.sort(lam.imag[lam.imag > 0])
    # K by central differences (h = 1e-6): rounding ~eps |tau| / h ~ 2e-10 relative.
    np.testing.assert_allclose(wn, wn_full, rtol=1e-8)


def test_upright_double_pendulum_is_reported_unstable():
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    model = pinlin.linearize(scene, q=np.array([math.pi, 0.0]))
    modes = pinlin.modal(model)
    assert not modes.is_stable and modes.unstable.sum() == 2
    _hamiltonian(pinlin.modal(model, method="general"))


def test_rotating_pendulum_above_critical_speed_is_unstable():
    scene = pinlin.Scene.from_dict({
        "urdf": str(URDF_DIR / "rotating_double_pendulum.urdf"),
        "effects": {"gravity": [0, 0, -9.81], "rotation": {"axis": [0, 0, 1], "rate": 4.0}},
        "operating_point": {"q": {"phi1": 0.0, "phi2": 0.0}, "solve": "positions"}})
    modes = pinlin.modal(pinlin.linearize(scene))
    assert modes.unstable.sum() == 1 and not modes.is_stable


@pytest.mark.parametrize("name", ["four_bar", "slider_crank", "delta"])
def test_penalty_from_1e3_to_1e14(name):
    """Physical eigenvalues within the O(1/alpha) penalty error (c / alpha, c fitted at
    alpha = 1e3) plus rounding, for alpha up to 1e14, and never right of the imaginary axis."""
    ref = np.linalg.eigvals(pinlin.linearize(URDF_DIR / f"{name}.toml").A)
    c = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        for k in range(3, 15):
            alpha = 10.0 ** k
            model = pinlin.linearize(URDF_DIR / f"{name}.toml", formulation="penalty",
                                     alpha=alpha)
            _finite(model)
            modes = pinlin.modal(model)
            phys = modes.eigenvalues[~modes.constraint]
            err = max(np.min(np.abs(phys - x)) / abs(x) for x in ref)
            if c is None:
                c = err * alpha
            assert err <= 2 * c / alpha + 1e-13, (alpha, err)
            assert phys.real.max() <= 1e-12 * np.abs(ref).max(), (alpha, phys.real.max())


def test_pin_integrate_on_free_flyer_is_the_tangent_convention():
    """Guard for the tests above: the free-flyer tangent of pinlin's state is pin.difference."""
    scene = pinlin.Scene.from_robot("solo12", operating_point={"allow_non_equilibrium": True})
    m = scene.system.model
    q0 = pinlin.linearize(scene).operating_point.q
    dq = np.linspace(-0.1, 0.1, scene.system.nv)
    np.testing.assert_allclose(pin.difference(m, q0, pin.integrate(m, q0, dq)), dq, atol=1e-12)
