"""A and B against central finite differences of pin.aba on the manifold (pin.integrate).

pinlin builds A from RNEA derivatives and M^-1; the reference here differentiates the forward
dynamics pin.aba numerically, a different algorithm, with the state perturbed on the manifold.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import aba_jacobians, rel_err

import pinlin

#: A against central differences of aba with h = 1e-6: rounding, ~eps |a| / h = 2e-10 |a|,
#: dominates (truncation: h^2 / 6 times a third derivative, ~1e-13); measured 2-3.5e-10 on
#: ur5, panda, talos_arm; 1e-8 leaves ~30x.
TOL = 1e-8
#: B against differences in u with a 1 N*m step (aba is linear in u: no truncation; rounding
#: ~eps |M^-1| |tau0| per evaluation, measured <= 1e-14 of max |B|): entrywise, small entries
#: included, to 1e-10 of max |B| (100x the worst measured) and 1e-9 relative.
B_ATOL, B_RTOL = 1e-10, 1e-9


def _check_b(model: pinlin.LinearModel, B_ref: np.ndarray) -> None:
    np.testing.assert_allclose(model.B, B_ref, rtol=B_RTOL,
                               atol=B_ATOL * np.abs(B_ref).max())


def _selection(system) -> np.ndarray:
    S = np.zeros((system.nv, len(system.actuated)))
    S[system.actuated, np.arange(len(system.actuated))] = 1.0
    return S


@pytest.mark.parametrize("robot", ["ur5", "panda", "talos_arm"])
def test_fixed_base_arms_match_aba_fd(robot):
    scene = pinlin.Scene.from_robot(robot)
    model = pinlin.linearize(scene)
    system = scene.system
    op = model.operating_point
    assert op.equilibrium
    A_ref, B_ref = aba_jacobians(system.model, op.q, _selection(system) @ op.u, _selection(system),
                                 h_u=1.0)
    assert rel_err(model.A, A_ref) < TOL
    _check_b(model, B_ref)
    assert np.array_equal(model.A[: system.nv, system.nv:], np.eye(system.nv))
    # u0 is the generalized gravity at q0 (every joint actuated), from Pinocchio directly.
    g = pin.computeGeneralizedGravity(system.model, system.model.createData(), op.q)
    np.testing.assert_allclose(op.u, g, rtol=1e-12, atol=1e-12 * np.abs(g).max())


def test_floating_talos_with_rotated_base_matches_aba_fd():
    scene = pinlin.Scene.from_robot("talos")
    system = scene.system
    q0 = system.q_ref.copy()
    rot = pin.rpy.rpyToMatrix(0.3, -0.2, 0.7)   # not the identity: exposes frame mix-ups
    q0[:3] = [0.1, -0.2, 1.0]
    q0[3:7] = pin.Quaternion(rot).coeffs()
    # A floating base under gravity cannot be held: opt in and linearize the falling robot.
    with pytest.raises(pinlin.EquilibriumError, match="root_joint"):
        pinlin.linearize(scene, q=q0)
    model = pinlin.linearize(scene, q=q0, allow_non_equilibrium=True)
    op = model.operating_point
    assert not op.equilibrium and np.linalg.norm(op.a) > 1.0
    S = _selection(system)
    A_ref, B_ref = aba_jacobians(system.model, q0, S @ op.u, S, h_u=1.0)
    assert rel_err(model.A, A_ref) < TOL
    _check_b(model, B_ref)
    assert model.state_names[0] == "q:root_joint[0]" and model.input_names[0].startswith("u:leg")
    # u0: the joints' share of gravity; the base's share (6 rows) is the residual.
    g = pin.computeGeneralizedGravity(system.model, system.model.createData(), q0)
    np.testing.assert_allclose(op.u, g[6:], rtol=1e-12, atol=1e-12 * np.abs(g).max())
    np.testing.assert_allclose(op.residual[:6], g[:6], rtol=1e-12, atol=1e-12)


def test_springs_damping_and_continuous_joints_match_aba_fd():
    stiff = {"joint1": 30.0, "joint2": 12.0}
    damp = {"joint1": 0.7, "joint2": 0.2}
    rest = {"joint1": 0.4, "joint2": -0.3}
    scene = pinlin.Scene.from_robot(
        "double_pendulum_continuous",
        effects={"gravity": [0.0, 0.0, -9.81],
                 "springs": {j: {"stiffness": k, "rest": rest[j]} for j, k in stiff.items()},
                 "damping": damp},
        operating_point={"q": {"joint1": 0.9, "joint2": 2.5}},
    )
    model = pinlin.linearize(scene)
    system = scene.system
    assert system.nq == 4 and system.nv == 2   # continuous joints: (cos, sin)
    op = model.operating_point
    k = np.array([stiff["joint1"], stiff["joint2"]])
    d = np.array([damp["joint1"], damp["joint2"]])
    r = np.array([rest["joint1"], rest["joint2"]])

    def spring_and_damper(q, v):
        angles = np.arctan2(q[1::2], q[0::2])
        return -k * (angles - r) - d * v

    S = _selection(system)
    A_ref, B_ref = aba_jacobians(system.model, op.q, S @ op.u, S, spring_and_damper, h_u=1.0)
    assert rel_err(model.A, A_ref) < TOL
    _check_b(model, B_ref)
    assert model.info["velocity_terms"] and np.allclose(np.diag(model.C_damp), d)


@pytest.mark.parametrize("backend", ["fd3", "fd5"])
def test_numerical_backends_agree_with_analytic(backend):
    scene = pinlin.Scene.load(pinlin.scene.bundled_scenes()["ur5_arm"])
    analytic = pinlin.linearize(scene)
    numeric = pinlin.linearize(scene, derivatives=backend)
    assert numeric.info["derivatives"] == backend
    # Within the error bound reported with the model (validation/reports/error_estimate.md).
    true = np.abs(numeric.A - analytic.A).max() / np.abs(analytic.A).max()
    assert true <= numeric.info["error_estimate"] < 1e-8


@pytest.mark.parametrize("formulation", ["independent", "penalty", "canonical"])
def test_error_estimate_of_dependent_models_is_not_diluted_by_the_penalty(formulation):
    """fd3 with a coarse step (0.1) moves the four-bar's physical pair by ~1e-3 (relative,
    against the analytic model of the same formulation). The estimate must say so in every
    formulation: before, the penalty and canonical ones divided by max |A| ~ Omega^2 or
    alpha Omega^2 (exact penalty terms) and reported 2e-11 without a warning."""
    with pytest.warns(pinlin.AccuracyWarning, match="estimated relative error"):
        coarse = pinlin.linearize("four_bar", formulation=formulation, derivatives="fd3",
                                  step=0.1)
    exact = pinlin.linearize("four_bar", formulation=formulation)

    def physical(model):
        lam = np.linalg.eigvals(model.A)
        return lam[np.argmin(np.abs(np.abs(lam) - 4.8066))]   # the independent model's pair

    error = abs(physical(coarse) - physical(exact)) / abs(physical(exact))
    assert 1e-4 < error <= coarse.info["error_estimate"]
