"""Modal analysis: chosen wn and zeta come back; the symmetric and general paths agree."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import URDF_DIR
from scipy.optimize import linear_sum_assignment

import pinlin


def _model_from_modes(wn, zeta) -> pinlin.LinearModel:
    """Decoupled second-order model M = I, C = diag(2 zeta wn), K = diag(wn^2), mixed by a
    random orthogonal change of coordinates so that nothing is diagonal."""
    n = len(wn)
    rng = np.random.default_rng(7)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    K = Q @ np.diag(np.square(wn)) @ Q.T
    C = Q @ np.diag(2 * np.asarray(zeta) * wn) @ Q.T
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -C]])
    B = np.vstack([np.zeros((n, 1)), np.ones((n, 1))])
    names = [f"c{i}" for i in range(n)]
    return pinlin.LinearModel(
        A=A, B=B, C=np.eye(2 * n), D=np.zeros((2 * n, 1)),
        state_names=[f"q:{s}" for s in names] + [f"v:{s}" for s in names],
        input_names=["u"], output_names=[f"y{i}" for i in range(2 * n)],
        M=np.eye(n), C_damp=C, K=K, Bu=np.ones((n, 1)), name="chosen",
        info={"velocity_terms": bool(np.any(zeta))})


def test_chosen_wn_and_zeta_come_back():
    wn = np.array([0.5, 3.0, 40.0, 250.0])
    zeta = np.array([0.02, 0.3, 0.7, 0.05])
    model = _model_from_modes(wn, zeta)
    modes = pinlin.modal(model)
    assert modes.method == "general"
    idx = modes.modes()
    # Each eigenvalue to its first-order rounding bound, kappa eps |A|_2 (10x), relative to
    # wn: the 0.5 rad/s mode shares A with a 250 rad/s one (|A|_2 = 6e4).
    bound = 10 * modes.condition[idx] * np.finfo(float).eps * np.linalg.norm(model.A, 2) / wn
    assert np.all(np.abs(modes.wn[idx] - wn) / wn <= bound)
    assert np.all(np.abs(modes.zeta[idx] - zeta) <= bound)
    # Each pair: lam = -zeta wn +- i wn sqrt(1 - zeta^2).
    lam = modes.eigenvalues[idx]
    assert np.all(np.abs(lam.imag - wn * np.sqrt(1 - zeta**2)) <= bound * wn)


def test_overdamped_and_unstable_modes_are_classified():
    wn = np.array([2.0, 5.0])
    zeta = np.array([2.0, -0.1])           # overdamped; negatively damped (unstable)
    modes = pinlin.modal(_model_from_modes(wn, zeta))
    kinds = sorted(modes.kind(i) for i in modes.modes())
    assert "unstable osc." in kinds and kinds.count("real") == 2
    assert not modes.is_stable
    over = np.sort(modes.eigenvalues[np.abs(modes.eigenvalues.imag) < 1e-9].real)
    root = np.sqrt(zeta[0] ** 2 - 1)
    np.testing.assert_allclose(over, np.sort(-wn[0] * (zeta[0] + np.array([root, -root]))),
                               rtol=1e-11)


def _undamped_scenes():
    servo = pinlin.Scene.from_robot(
        "ur5", effects={"gravity": [0, 0, -9.81], "springs": {
            j: {"stiffness": 300.0, "rest": 0.0} for j in
            ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]}})
    floating = pinlin.Scene.from_robot("talos", effects={"armature": True, "springs": {
        f"arm_left_{i}_joint": {"stiffness": 50.0} for i in range(1, 8)}})
    return {"double_pendulum": pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"),
            "ur5_servo": servo, "talos_floating_zero_g": floating}


@pytest.mark.parametrize("name", ["double_pendulum", "ur5_servo", "talos_floating_zero_g"])
def test_symmetric_and_general_paths_agree(name):
    model = pinlin.linearize(_undamped_scenes()[name])
    sym = pinlin.modal(model)
    gen = pinlin.modal(model, method="general")
    assert sym.method == "symmetric" and gen.method == "general"
    np.testing.assert_array_equal(sym.rigid, gen.rigid)
    scale = max(1.0, np.abs(sym.eigenvalues).max())
    rows, cols = linear_sum_assignment(np.abs(sym.eigenvalues[:, None] - gen.eigenvalues[None]))
    assert np.abs(sym.eigenvalues[rows] - gen.eigenvalues[cols]).max() <= 1e-9 * scale
    # Right and left vectors of the symmetric path are eigenvectors (or Jordan chains) of A,
    # biorthonormal: L^H R = I.
    A, R, L = model.A, sym.right_vectors, sym.left_vectors
    J = np.diag(sym.eigenvalues)
    pairs = np.flatnonzero(sym.rigid)[::2]
    J[pairs, pairs + 1] = 1.0                       # Jordan blocks of the rigid modes
    np.testing.assert_allclose(A @ R, R @ J, atol=1e-9 * scale)
    np.testing.assert_allclose(L.conj().T @ A, J @ L.conj().T, atol=1e-9 * scale)
    np.testing.assert_allclose(L.conj().T @ R, np.eye(len(J)), atol=1e-9)


def test_floating_base_has_six_rigid_modes():
    model = pinlin.linearize(_undamped_scenes()["talos_floating_zero_g"])
    modes = pinlin.modal(model)
    # Six base DoF, and the joints without springs are free too: all rigid, each a Jordan pair.
    n_free_joints = model.M.shape[0] - 6 - 7
    assert modes.rigid.sum() == 2 * (6 + n_free_joints)
    assert np.all(np.isnan(modes.zeta[modes.rigid])) and np.all(modes.wn[modes.rigid] == 0)
    assert np.all(np.isfinite(modes.zeta[~modes.rigid]))
    assert "rigid" in modes.table()


def test_general_left_vectors_are_biorthonormal_and_condition_is_reported():
    model = pinlin.linearize(URDF_DIR / "ur5_arm.toml")     # damped: general path
    modes = pinlin.modal(model)
    assert modes.method == "general"
    L, R = modes.left_vectors, modes.right_vectors
    lam, A = modes.eigenvalues, model.A
    scale = np.abs(A).max()
    # Right and left eigenvectors each (a swap of L and R keeps L^H R = I but fails these).
    np.testing.assert_allclose(A @ R, R * lam, atol=1e-10 * scale)
    np.testing.assert_allclose(L.conj().T @ A, lam[:, None] * L.conj().T, atol=1e-10 * scale)
    np.testing.assert_allclose(L.conj().T @ R, np.eye(R.shape[0]), atol=1e-8)
    assert np.all(modes.condition >= 1.0 - 1e-9) and np.all(np.isfinite(modes.condition))
    assert modes.is_stable


def test_shapes_are_normalized_and_named():
    modes = pinlin.modal(pinlin.linearize(URDF_DIR / "double_pendulum.toml"))
    np.testing.assert_allclose(np.abs(modes.shapes).max(axis=0), 1.0)
    assert modes.coordinate_names == ("shoulder", "elbow")
    # First mode: both links swing in phase; second: out of phase.
    first, second = modes.modes()
    assert np.all(modes.shapes[:, first].real > 0)
    assert np.prod(modes.shapes[:, second].real) < 0
    assert modes.dominant(second)[0] == "elbow"


def test_symmetric_method_refused_with_damping():
    with pytest.raises(pinlin.PinlinError, match="general"):
        pinlin.modal(pinlin.linearize(URDF_DIR / "ur5_arm.toml"), method="symmetric")
