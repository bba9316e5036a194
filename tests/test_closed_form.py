"""Linear models against closed-form mechanics derived by hand (no Pinocchio in the reference)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import URDF_DIR

import pinlin

G = 9.81
# urdf/double_pendulum.urdf: uniform rods about y, centres of mass at mid-length.
L1, M1, L2, M2 = 1.0, 1.0, 0.8, 0.6
C1, C2 = L1 / 2, L2 / 2
I1, I2 = M1 * L1**2 / 12, M2 * L2**2 / 12


def test_pendulum_is_textbook():
    """urdf/pendulum.urdf: a solid sphere of mass m = 1 kg and radius r = 0.05 m, its centre
    L = 1 m below a hinge (a point mass has no MuJoCo counterpart). About the hinge its inertia
    is J = m L^2 + 2/5 m r^2 = 1 + 0.001 = 1.001 kg*m^2 (parallel-axis theorem on the sphere's
    2/5 m r^2); gravity's torque is -m g L sin(q). Linearized at q = 0, J q'' = -m g L q + u:
    A = [[0, 1], [-m g L / J, 0]], B = [[0], [1 / J]], omega_n = sqrt(m g L / J), which is the
    textbook point mass -g/L for r -> 0."""
    m, L, r = 1.0, 1.0, 0.05
    J = m * L**2 + 0.4 * m * r**2
    model = pinlin.linearize(URDF_DIR / "pendulum.toml")
    np.testing.assert_allclose(model.A, [[0.0, 1.0], [-m * G * L / J, 0.0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(model.B, [[0.0], [1.0 / J]], rtol=0, atol=1e-12)
    modes = pinlin.modal(model)
    np.testing.assert_allclose(modes.wn, [np.sqrt(m * G * L / J)] * 2, rtol=1e-12)
    assert model.output_names == ("q:hinge", "v:hinge", "p:tip[x]", "p:tip[y]", "p:tip[z]")
    np.testing.assert_allclose(model.operating_point.y[2:], [0.0, 0.0, -1.0], rtol=0, atol=1e-15)


def _hand_mass(t2):
    m11 = I1 + M1 * C1**2 + I2 + M2 * (L1**2 + C2**2 + 2 * L1 * C2 * np.cos(t2))
    m12 = I2 + M2 * (C2**2 + L1 * C2 * np.cos(t2))
    m22 = I2 + M2 * C2**2
    return np.array([[m11, m12], [m12, m22]])


def _hand_stiffness(t1, t2):
    # Hessian of V = -g [(m1 c1 + m2 L1) cos t1 + m2 c2 cos(t1 + t2)]; the holding torques u0 are
    # constant, so they add no stiffness.
    k12 = G * M2 * C2 * np.cos(t1 + t2)
    k11 = G * (M1 * C1 + M2 * L1) * np.cos(t1) + k12
    return np.array([[k11, k12], [k12, k12]])


@pytest.mark.parametrize("t1, t2", [(0.0, 0.0), (0.3, 0.5), (-1.1, 2.0)])
def test_double_pendulum_matches_hand_derivation(t1, t2):
    scene = pinlin.Scene.load(URDF_DIR / "double_pendulum.toml")
    q = np.array([t1, t2])
    model = pinlin.linearize(scene, q=q)
    np.testing.assert_allclose(model.M, _hand_mass(t2), rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(model.K, _hand_stiffness(t1, t2), rtol=1e-12, atol=1e-12)
    Minv = np.linalg.inv(_hand_mass(t2))
    np.testing.assert_allclose(model.A[2:, :2], -Minv @ _hand_stiffness(t1, t2),
                               rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(model.B[2:], Minv, rtol=1e-12)
    # Holding torques: u0 = dV/dq.
    dv1 = G * ((M1 * C1 + M2 * L1) * np.sin(t1) + M2 * C2 * np.sin(t1 + t2))
    dv2 = G * M2 * C2 * np.sin(t1 + t2)
    np.testing.assert_allclose(model.operating_point.u, [dv1, dv2], rtol=0, atol=1e-12)
    # Tip position output: p = (-(L1 s1 + L2 s12), 0, -(L1 c1 + L2 c12)) and its Jacobian.
    s1, c1, s12, c12 = np.sin(t1), np.cos(t1), np.sin(t1 + t2), np.cos(t1 + t2)
    p = [-(L1 * s1 + L2 * s12), 0.0, -(L1 * c1 + L2 * c12)]
    J = np.array([[-(L1 * c1 + L2 * c12), -L2 * c12], [0.0, 0.0], [L1 * s1 + L2 * s12, L2 * s12]])
    np.testing.assert_allclose(model.operating_point.y, p, rtol=0, atol=1e-14)
    np.testing.assert_allclose(model.C[:, :2], J, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(model.C[:, 2:], 0.0)


def test_double_pendulum_frequencies_are_the_roots_of_the_characteristic_equation():
    model = pinlin.linearize(URDF_DIR / "double_pendulum.toml")
    M, K = _hand_mass(0.0), _hand_stiffness(0.0, 0.0)
    # det(K - w^2 M) = 0 is a quadratic in w^2.
    a = np.linalg.det(M)
    b = -(K[0, 0] * M[1, 1] + K[1, 1] * M[0, 0] - 2 * K[0, 1] * M[0, 1])
    c = np.linalg.det(K)
    w2 = np.sort(np.roots([a, b, c]).real)
    modes = pinlin.modal(model)
    assert modes.method == "symmetric"
    np.testing.assert_allclose(np.unique(np.round(modes.wn, 10)), np.sqrt(w2), rtol=1e-10)


def test_armature_adds_to_the_mass_diagonal_only_when_called_for():
    base = {"gravity": [0.0, 0.0, -9.81]}
    plain = pinlin.linearize(pinlin.Scene.from_urdf(URDF_DIR / "pendulum.urdf", effects=base))
    geared = pinlin.linearize(pinlin.Scene.from_urdf(
        URDF_DIR / "pendulum.urdf", effects={**base, "armature": {"hinge": 0.25}}))
    # The bob's J = m L^2 + 2/5 m r^2 = 1.001 kg*m^2 (see test_pendulum_is_textbook).
    assert plain.M[0, 0] == pytest.approx(1.001, abs=1e-15)
    assert geared.M[0, 0] == pytest.approx(1.251, abs=1e-15)
    assert geared.A[1, 0] == pytest.approx(-G / 1.251, rel=1e-13)


def test_no_gravity_unless_listed():
    model = pinlin.linearize(pinlin.Scene.from_urdf(URDF_DIR / "pendulum.urdf", effects={}))
    assert np.all(model.K == 0.0) and model.info["effects"] == []
    modes = pinlin.modal(model)
    assert modes.rigid.all()
