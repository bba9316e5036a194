"""Modal analysis: chosen wn and zeta come back; the symmetric and general paths agree."""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest
import scipy.linalg as sla
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


# ------------------------------------------------------------------------------------------
# What modal computes eagerly and what on first access (issue 18), and the accuracy warning
# decided from the right vectors alone.

def _lapack_warning(modes) -> tuple[bool, complex, float]:
    """The warning decision from LAPACK's left vectors (modes.condition), the reference the
    cheap decision must reproduce: (warn, worst eigenvalue, its kappa)."""
    ok = ~modes.rigid
    kappa = modes.condition[ok]
    risk = kappa * np.finfo(float).eps * np.abs(modes.model.A).max() / modes.wn[ok]
    worst = int(np.argmax(risk))
    return bool(risk[worst] > 1e-6), modes.eigenvalues[ok][worst], float(kappa[worst])


def _near_defective(delta: float, rigid: bool = False) -> pinlin.LinearModel:
    """One mode of 1 rad/s at damping ratio 1 - delta (a double root, defective, at
    delta = 0) beside a well separated one (and, with ``rigid``, a free coordinate: a 2x2
    Jordan block at 0, sorted first): kappa ~ 1 / sqrt(delta) grows as the pair closes."""
    if rigid:
        return _model_from_modes(np.array([0.0, 1.0, 40.0]), np.array([0.0, 1.0 - delta, 0.05]))
    return _model_from_modes(np.array([1.0, 40.0]), np.array([1.0 - delta, 0.05]))


#: Damping ratios 1 -+ delta around the threshold: kappa eps max|A| / |lam| crosses 1e-6
#: between delta = 1e-13 and 5e-14 (kappa ~ 3e6; max|A| = 1600).
DELTAS = [1e-2, 1e-8, *np.geomspace(3e-13, 1e-15, 9), -1e-8, *(-np.geomspace(3e-13, 1e-15, 5))]


@pytest.mark.parametrize("delta", DELTAS)
@pytest.mark.parametrize("margin", [None, 1e3])
@pytest.mark.parametrize("rigid", [False, True])
def test_warning_from_right_vectors_matches_lapack_condition_numbers(delta, margin, rigid,
                                                                      monkeypatch):
    """Across the threshold, the warning is given exactly when LAPACK's left vectors say it
    is due, naming the same eigenvalue and its condition number to the digits printed; with
    a wide margin (1e3) the cases near the threshold are settled by LAPACK's left vectors
    instead, with the same outcome."""
    if margin is not None:
        monkeypatch.setattr(importlib.import_module("pinlin.eigensolvers"), "RISK_MARGIN_MIN",
                            margin)
    model = _near_defective(delta, rigid)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        modes = pinlin.modal(model)
    warned = [w for w in caught if issubclass(w.category, pinlin.AccuracyWarning)]
    due, lam, kappa = _lapack_warning(modes)
    assert bool(warned) == due
    if warned:
        assert warned[0].message.condition == pytest.approx(kappa, rel=1e-3)
        assert f"{lam:.6g}" in str(warned[0].message)
        assert warned[0].filename == __file__          # points at the caller of modal


def test_condition_numbers_from_the_inverse_of_the_right_vectors():
    """kappa from the rows of V^-1 (pairs combined) equals LAPACK's left-vector kappa."""
    modal_module = importlib.import_module("pinlin.eigensolvers")
    rng = np.random.default_rng(3)
    for n in (2, 5, 12, 30):
        A = rng.normal(size=(n, n)) + np.diag(rng.uniform(0.5, 3.0, n))
        wr, wi, _, vr = modal_module.geev(A, left=False)
        inv = np.linalg.inv(vr)
        kappa = modal_module.pair_conditions(np.einsum("ij,ij->i", inv, inv), wi)
        lam, L, R = sla.eig(A, left=True, right=True)
        assert np.allclose(lam, wr + 1j * wi, rtol=0, atol=0)      # same dgeev, same order
        ref = np.linalg.norm(L, axis=0) * np.linalg.norm(R, axis=0) / np.abs(
            np.einsum("ij,ij->j", L.conj(), R))
        np.testing.assert_allclose(kappa, ref, rtol=1e-9)


def test_general_path_computes_no_left_vectors_unless_read():
    model = pinlin.linearize(URDF_DIR / "ur5_arm.toml")     # damped: general path
    modes = pinlin.modal(model)
    assert modes.method == "general"
    for lazy in ("left_vectors", "condition", "right_vectors", "shapes", "wn", "zeta"):
        assert lazy not in modes.__dict__, lazy
    # A warned model does not need them either: the warning comes from V^-1.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warned = pinlin.modal(_near_defective(1e-14))
    assert any(issubclass(w.category, pinlin.AccuracyWarning) for w in caught)
    assert "left_vectors" not in warned.__dict__
    assert _lapack_warning(warned)[0]


def test_symmetric_path_solves_for_vectors_on_first_access():
    """modal solves (K, M) for eigenvalues only; the shapes, computed later by a second solve
    with vectors, belong to those eigenvalues (A R = R J), and the eigenvalues equal
    scipy's eigh of the pencil to rounding."""
    model = pinlin.linearize(_undamped_scenes()["talos_floating_zero_g"])
    modes = pinlin.modal(model)
    assert modes.method == "symmetric" and "_phi" not in modes.__dict__
    K = 0.5 * (model.K + model.K.T)
    w2 = sla.eigh(K, model.M, eigvals_only=True, driver="gvd")
    scale = np.abs(w2).max()
    moving = ~modes.rigid[0::2]
    np.testing.assert_allclose(np.abs(modes.eigenvalues[0::2][moving]) ** 2,
                               np.sort(np.abs(w2))[moving], rtol=1e-12)   # by |w2|
    R = modes.right_vectors
    assert "_phi" in modes.__dict__
    J = np.diag(modes.eigenvalues)
    pairs = np.flatnonzero(modes.rigid)[::2]
    J[pairs, pairs + 1] = 1.0
    np.testing.assert_allclose(model.A @ R, R @ J, atol=1e-9 * max(1.0, scale))


def test_unstable_symmetric_pencil_keeps_vectors_matched():
    """Negative w2 (an inverted pendulum) reorders the pencil's eigenvalues by |w2|: the
    vectors computed on first access follow the same order."""
    wn2 = np.array([-4.0, 1.0, 9.0, -0.25])
    rng = np.random.default_rng(11)
    Q, _ = np.linalg.qr(rng.normal(size=(4, 4)))
    K = Q @ np.diag(wn2) @ Q.T
    K = 0.5 * (K + K.T)
    names = [f"c{i}" for i in range(4)]
    model = pinlin.LinearModel(
        A=np.block([[np.zeros((4, 4)), np.eye(4)], [-K, np.zeros((4, 4))]]),
        B=np.zeros((8, 1)), C=np.eye(8), D=np.zeros((8, 1)),
        state_names=[f"q:{s}" for s in names] + [f"v:{s}" for s in names],
        input_names=["u"], output_names=[f"y{i}" for i in range(8)],
        M=np.eye(4), C_damp=np.zeros((4, 4)), K=K, Bu=np.zeros((4, 1)), name="inverted",
        info={"velocity_terms": False})
    modes = pinlin.modal(model)
    assert modes.method == "symmetric" and not modes.is_stable
    R = modes.right_vectors
    np.testing.assert_allclose(model.A @ R, R * modes.eigenvalues, atol=1e-12)
    np.testing.assert_allclose(np.abs(modes.eigenvalues[0::2]), np.sqrt([0.25, 1, 4, 9]),
                               rtol=1e-14)


def test_repeated_complex_pairs_stay_paired():
    """Two identical damped oscillators (wn = 3 rad/s, zeta = 0.2), uncoupled: dgeev returns
    the pair -0.6 +- 2.939j twice, equal to the bit, which a plain sort by (|lam|, Re, -Im)
    orders +, +, -, -. Each +Im must be followed by its own conjugate: two modes, two table
    rows, A R = R Lambda, and the table prints the real part -0.6 (not the rounding rule's
    0: rounding cannot move this well-conditioned pair by 0.6)."""
    wn, zeta = 3.0, 0.2
    K, C = wn**2 * np.eye(2), 2 * zeta * wn * np.eye(2)
    names = ["a", "b"]
    model = pinlin.LinearModel(
        A=np.block([[np.zeros((2, 2)), np.eye(2)], [-K, -C]]), B=np.zeros((4, 1)),
        C=np.eye(4), D=np.zeros((4, 1)),
        state_names=[f"q:{s}" for s in names] + [f"v:{s}" for s in names],
        input_names=["u"], output_names=[f"y{i}" for i in range(4)], name="twins")
    modes = pinlin.modal(model, method="general")
    lam = modes.eigenvalues
    assert np.sum(lam == lam[0]) == 2          # the repeated pair, equal to the bit
    for k in range(0, 4, 2):
        assert lam[k].imag > 0 and lam[k + 1] == np.conj(lam[k])
    assert len(modes.modes()) == 2
    R = modes.right_vectors
    np.testing.assert_allclose(model.A @ R, R * lam, rtol=0, atol=1e-12)
    rows = [ln for ln in str(modes).splitlines()[3:] if ln.strip()]
    assert len(rows) == 2 and all("-0.6 +- 2.93939j" in ln for ln in rows)


def test_unresolved_eigenvalue_prints_as_computed():
    """The canonical standing box's constraint modes are a defective double root near -10
    (mu = 1: critically damped) with condition ~1e11: rounding may move the whole eigenvalue,
    so the table must not pretend its real part is 0 (it printed '0 +- 0.0045j', zeta 0,
    for an eigenvalue of -10)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        modes = pinlin.modal(pinlin.linearize("standing_box", formulation="canonical"))
    rows = [ln for ln in str(modes).splitlines() if "constraint" in ln]
    assert rows and all(ln.split()[1] == "-10" for ln in rows), rows


def _second_order(M, K) -> pinlin.LinearModel:
    """x = [q; q'], M q'' + K q = 0 written by hand (A = [[0, I], [-M^-1 K, 0]])."""
    M, K = np.array(M, dtype=float), np.array(K, dtype=float)
    n = len(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), np.zeros((n, n))]])
    return pinlin.LinearModel(A, np.zeros((2 * n, 1)), np.zeros((1, 2 * n)), np.zeros((1, 1)),
                              tuple(f"x{i}" for i in range(2 * n)), ("u",), ("y",), M=M, K=K,
                              C_damp=np.zeros((n, n)), Bu=np.zeros((n, 1)), name="by_hand")


@pytest.mark.parametrize("M", [[[1.0, 0.5], [0.0, 1.0]],     # not symmetric: dsygvd would
                               [[1.0, 0.0], [0.0, -1.0]]])   # read one triangle; indefinite
def test_hand_built_mass_matrix_that_the_pencil_cannot_take(M):
    """A non-symmetric M took the symmetric path (wrong eigenvalues), an indefinite one raised
    a raw LinAlgError: both go to the general eigensolver, which gives the eigenvalues of A
    (numpy's eigvals as the reference), and method='symmetric' says why it does not apply."""
    model = _second_order(M, [[2.0, 0.0], [0.0, 3.0]])
    modes = pinlin.modal(model)
    assert modes.method == "general"
    np.testing.assert_allclose(np.sort_complex(modes.eigenvalues),
                               np.sort_complex(np.linalg.eigvals(model.A)), atol=1e-14)
    with pytest.raises(pinlin.PinlinError, match="symmetric"):
        pinlin.modal(model, method="symmetric")


def _first_order(A) -> pinlin.LinearModel:
    A = np.array(A, dtype=float)
    n = len(A)
    return pinlin.LinearModel(A, np.zeros((n, 1)), np.eye(n), np.zeros((n, 1)),
                              tuple(f"x{i}" for i in range(n)), ("u",),
                              tuple(f"y{i}" for i in range(n)), name="by_hand")


@pytest.mark.parametrize("A", [
    [[-1e150, 0.5], [0.0, -1.0]],        # beyond dgeev's scaling bound 1.5e138
    [[-1e139, 0.0], [0.0, -1.0]],
    [[0.0, 1e-200], [-1e-200, 0.0]],     # below 6.7e-139: dgeev scaled it up, never back
    [[0.0, 1.0], [-1e140, 0.0]],         # a second-order model with K = 1e140 (general path)
])
def test_eigenvalues_of_huge_and_tiny_matrices(A):
    """scipy-openblas's dgeev scales a matrix whose largest entry lies outside ~[6.7e-139,
    1.5e138] and returned the eigenvalues of the scaled matrix (diag(-1e150, -1) gave -1.5e138
    and -1.5e-12); pinlin scales by a power of 2 itself. Reference: the eigenvalues of the
    triangular or 2x2 blocks in closed form (numpy's eigvals agrees)."""
    A = np.array(A)
    if A[1, 0] == 0.0:
        expected = np.diag(A).astype(complex)
    else:   # [[0, b], [-c, 0]]: +- i sqrt(b c)
        w = np.sqrt(A[0, 1]) * np.sqrt(-A[1, 0])
        expected = np.array([1j * w, -1j * w])
    with warnings.catch_warnings():   # rightly: rounding 1e150 moves -1 by up to 1e134
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        modes = pinlin.modal(_first_order(A), rigid_tol=0.0)
    np.testing.assert_allclose(np.sort_complex(modes.eigenvalues), np.sort_complex(expected),
                               rtol=1e-14, atol=0)
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(A)), np.sort_complex(expected),
                               rtol=1e-14)


def test_second_order_matrices_must_agree_with_the_state_matrix():
    """A hand-built model whose M, K describe other dynamics than its A was accepted and modal
    read the pencil (K, M): +-1j where A has +-2j. Refused now, naming the block; a model
    whose matrices agree to rounding is accepted (the symmetric path gives A's eigenvalues)."""
    eye, zero = np.eye(1), np.zeros((1, 1))
    args = (np.zeros((2, 1)), np.eye(2), np.zeros((2, 1)), ("q:a", "v:a"), ("u",), ("y1", "y2"))
    with pytest.raises(pinlin.ModelError, match=r"M A\[nv:, :nv\] \+ K is 3"):
        pinlin.LinearModel([[0, 1], [-4, 0]], *args, M=eye, K=eye, C_damp=zero, Bu=zero)
    with pytest.raises(pinlin.ModelError, match=r"M A\[nv:, nv:\] \+ C_damp is 1"):
        pinlin.LinearModel([[0, 1], [-1, 0]], *args, M=eye, K=eye, C_damp=eye, Bu=zero)
    with pytest.raises(pinlin.ModelError, match=r"A\[:nv, nv:\] \(the identity\)"):
        pinlin.LinearModel([[1, 0], [0, -1]], *args, M=eye, K=eye, C_damp=zero, Bu=zero)
    good = pinlin.LinearModel([[0, 1], [-4, 0]], *args, M=eye, K=4 * eye, C_damp=zero, Bu=zero)
    np.testing.assert_allclose(np.sort_complex(pinlin.modal(good).eigenvalues), [-2j, 2j])


def test_a_singular_mass_matrix_allows_any_second_order_residual():
    """A model linearized with allow_ill_conditioned has lower rows formed with an inverse of
    no correct digit, so a singular M allows any residual and the model loads. M = 0 made the
    allowance inf * 0 where a block had no scale (C_damp = 0): the model was refused as
    'above the nan rounding allows', with a RuntimeWarning from the product."""
    eye, zero = np.eye(1), np.zeros((1, 1))
    args = (np.zeros((2, 1)), np.eye(2), np.zeros((2, 1)), ("q:a", "v:a"), ("u",), ("y1", "y2"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = pinlin.LinearModel([[0, 1], [-4, 0]], *args, M=zero, K=eye, C_damp=zero,
                                   Bu=eye)
    np.testing.assert_allclose(np.sort_complex(pinlin.modal(model).eigenvalues), [-2j, 2j])


def test_info_does_not_turn_damping_off():
    """``info = {"velocity_terms": False}`` made modal skip its look at C_damp and solve the
    undamped pencil: +-1j for a damped oscillator whose A has -0.5 +- 0.866j."""
    A = [[0.0, 1.0], [-1.0, -1.0]]
    model = pinlin.LinearModel(A, np.zeros((2, 1)), np.eye(2), np.zeros((2, 1)),
                               ("q:a", "v:a"), ("u",), ("y1", "y2"), M=np.eye(1), K=np.eye(1),
                               C_damp=np.eye(1), Bu=np.zeros((1, 1)),
                               info={"velocity_terms": False})
    modes = pinlin.modal(model)
    assert modes.method == "general"
    np.testing.assert_allclose(np.sort_complex(modes.eigenvalues),
                               np.sort_complex([-0.5 - 0.75 ** 0.5 * 1j, -0.5 + 0.75 ** 0.5 * 1j]),
                               rtol=1e-14)


def test_subnormal_entries():
    """The scale for dgeev is 2^1029 here: applied by ldexp, not as a float that overflows."""
    modes = pinlin.modal(_first_order(np.diag([-1e-310, -2e-310])), rigid_tol=0.0)
    np.testing.assert_array_equal(np.sort(modes.eigenvalues.real), [-2e-310, -1e-310])


@pytest.mark.parametrize("name, state", [("talos", "rest"), ("go1", "rest"),
                                         ("double_pendulum", "moving")])
def test_kinds_and_stability_need_no_condition_numbers_on_robots(name, state):
    """Undamped modes on the general path have real parts of rounding size (below 10 n eps
    |A|_F, the least rounding level times the margin): kind, oscillates and unstable settle
    them without the condition numbers (a second dgeev, 2x the cost of modal)."""
    scene = (pinlin.Scene.resolve(name) if name == "double_pendulum" else
             pinlin.Scene.from_robot(name, operating_point={"allow_non_equilibrium": True}))
    v = np.full(scene.system.nv, 0.3) if state == "moving" else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        modes = pinlin.modal(pinlin.linearize(scene, v=v))
    assert modes.method == "general"
    kinds = [modes.kind(i) for i in modes.modes()]
    assert modes.is_stable in (True, False) and kinds
    assert "condition" not in modes.__dict__


@pytest.mark.parametrize("w", [1.0, 10.0])
def test_a_critically_damped_mode_is_not_called_at_risk(w):
    """A = [[0, 1], [-w^2, -2 w]] has the double eigenvalue -w (a Jordan block): its computed
    condition number is ~1/eps, and first order said rounding could move it by ~1 (2.8 of
    itself at w = 1). The pair moves by ~sqrt(eps): measured here by perturbing A's corner by
    eps max|A| (numpy's eigvals, the reference), 1e-8 of |lam|, under the 1e-6 that warns.
    (At w = 1e3 A's entries span 1 to 1e6 and a perturbation of norm eps 1e6 in the worst
    direction moves the pair by sqrt(|A|_F eps 1e6) = 1.5e-5 of itself: said, as any
    norm-wise risk is.)"""
    A = np.array([[0.0, 1.0], [-w * w, -2.0 * w]])
    model = pinlin.LinearModel(A=A, B=[[0.0], [1.0]], C=np.eye(2), D=np.zeros((2, 1)),
                               state_names=("q:a", "v:a"), input_names=("u:a",),
                               output_names=("q:a", "v:a"), name="critical")
    E = np.zeros((2, 2))
    E[1, 0] = np.finfo(float).eps * np.abs(A).max()
    # (each moves by sqrt(eps max|A|) / w exactly: 2.1e-8 at w = 1, 1.5e-8 at w = 10,
    # measured 2.1e-8 at both; the eigensolver's own backward error is of that order, so
    # only the bound is asserted)
    moved = np.abs(np.linalg.eigvals(A + E) + w).max() / w
    assert moved < 1e-7
    with warnings.catch_warnings():
        warnings.simplefilter("error", pinlin.AccuracyWarning)
        modes = pinlin.modal(model)
    assert np.allclose(modes.eigenvalues, -w, rtol=1e-6)
    # A defective pair beside a fast mode (max|A| = 1600) can move by sqrt(|A| eps |A|_F)
    # ~ 2e-5 of itself: still said.
    with pytest.warns(pinlin.AccuracyWarning, match="may move it by 2.*e-05"):
        pinlin.modal(_near_defective(0.0))
