"""Numerical derivatives (fd3, fd5) of mechanisms at a moving state
(pinlin.formulations.moving_fd): right against Pinocchio's own constrained dynamics
differenced on the constraint manifold, within the error they report against the analytic
model (a second formulation, itself checked in test_moving_loops), and the same along
trajectories."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import URDF_DIR
from test_moving_loops import ConstrainedDynamics

import pinlin

MECHANISMS = ["four_bar", "slider_crank", "delta", "five_bar"]


def moving_state(scene: pinlin.Scene, seed: int):
    """A consistent moving state: the scene's assembly, independent velocities and inputs
    drawn at random, the dependent velocities from Pinocchio's constraint Jacobian."""
    system = scene.system
    rest = pinlin.linearize(scene)
    z = np.array([system.coordinate_names.index(c) for c in rest.info["independent"]])
    rng = np.random.default_rng(seed)
    zdot = rng.uniform(-2.0, 2.0, len(z))
    u = rng.uniform(-1.0, 1.0, len(system.actuated))
    ref = ConstrainedDynamics(scene)
    q = rest.operating_point.q
    return ref, z, q, ref.velocity(q, z, zdot), zdot, u


@pytest.mark.parametrize("name", MECHANISMS)
def test_fd5_model_matches_pinocchios_constrained_dynamics(name):
    """The lower rows of A against central differences (h = 1e-5) of Pinocchio's
    ``constraintDynamics`` with re-assembly at each perturbed z, as the analytic model is
    checked in test_moving_loops: both sides carry O(h^2) ~ 1e-10 of max |A| (measured there)
    and fd5 at its default steps ~1e-11 (its own estimate); 1e-8 leaves ~50x."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    ref, z, q, v, zdot, u = moving_state(scene, 1)
    model = pinlin.linearize(scene, q=q, v=v, u=u, derivatives="fd5")
    assert model.info["derivatives"] == "fd5" and model.info["error_estimate"] < 1e-8
    nz = len(z)
    lower = ref.lower_rows(model.operating_point.q, z, zdot, u, 1e-5)
    np.testing.assert_allclose(model.A[nz:], lower, rtol=0, atol=1e-8 * np.abs(lower).max())


@pytest.mark.parametrize("name", MECHANISMS)
@pytest.mark.parametrize("backend", ["fd3", "fd5"])
@pytest.mark.parametrize("step, speed", [(2e-10, 15.0), (1e-6, 1.0), (1e-4, 1.0),
                                         (1e-2, 1.0)])
def test_reported_error_bounds_the_true_error(name, backend, step, speed):
    """The error estimate is a claim: |A_fd - A_analytic| / max |A| must stay below it, at
    steps where rounding rules (1e-6; 2e-10 with fast joints, where the noise of the
    constraint acceleration also reaches A through W), where truncation rules (1e-2) and
    between. Measured over steps 1e-10 .. 0.1 on these four mechanisms (validation/
    error_estimate.py): true / estimate <= 0.7 but for a slider-crank spinning at 20 rad/s at
    the largest step. B comes from inputs that enter linearly: exact to rounding."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    _, z, q, v, _, u = moving_state(scene, 2)
    v = speed * v
    exact = pinlin.linearize(scene, q=q, v=v, u=u)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)  # large steps warn, rightly
        model = pinlin.linearize(scene, q=q, v=v, u=u, derivatives=backend,
                                 step={"q": step, "v": step, "u": 1e-3})
    true = np.abs(model.A - exact.A).max() / np.abs(exact.A).max()
    assert true <= model.info["error_estimate"]
    assert 0.0 < model.info["error_estimate_rounding"] <= model.info["error_estimate"]
    np.testing.assert_allclose(model.B, exact.B, rtol=0, atol=1e-12 * np.abs(exact.B).max())
    assert model.state_names == exact.state_names
    np.testing.assert_array_equal(model.f0, exact.f0)


def test_a_rotating_mechanism_takes_numerical_derivatives_too():
    """The spinning four-bar (its analytic model from Pinocchio point by point, d gamma/dq by
    differences): fd5 agrees within its estimate."""
    import tomllib

    data = tomllib.loads((URDF_DIR / "four_bar.toml").read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    data["effects"]["rotation"] = {"axis": [0.0, 0.0, 1.0], "rate": 5.0}
    scene = pinlin.Scene.from_dict(data)
    q = pinlin.operating_point(scene).q
    v, u = np.array([0.3, -0.2, 0.1]), np.array([0.4])
    exact = pinlin.linearize(scene, q=q, v=v, u=u)
    model = pinlin.linearize(scene, q=q, v=v, u=u, derivatives="fd5")
    true = np.abs(model.A - exact.A).max() / np.abs(exact.A).max()
    assert true <= model.info["error_estimate"] < 1e-8


def test_penalty_at_a_moving_state_keeps_analytic_derivatives():
    with pytest.raises(pinlin.ModelError, match="independent formulation only"):
        pinlin.linearize("four_bar", v=np.array([1.0, 0.0, 0.0]), derivatives="fd3",
                         formulation="penalty")
