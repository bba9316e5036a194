"""The stacked kernels behind trajectories: the loop closures' second and third derivatives
from frame Jacobians (pinlin.loop_kernels) against Pinocchio and central differences, and the
screening by which a batch finds the points where M is singular to working precision."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest

import pinlin
from pinlin import loop_kernels as lk
from pinlin.conditioning import scaled_condition

EPS = np.finfo(float).eps
MECHANISMS = ("four_bar", "slider_crank", "delta", "five_bar")


def _state(name: str, seed: int):
    system = pinlin.Scene.resolve(name).system
    rng = np.random.default_rng(seed)
    q = pin.randomConfiguration(system.model, -np.ones(system.nq), np.ones(system.nq))
    plan = lk.plan(system)
    assert plan is not None
    J = np.zeros((1, len(plan.frames), 6, system.nv))
    lk.frame_jacobians(system.model, system.data, q, plan.frames, J[0])
    return system, plan, q, J, rng


@pytest.mark.parametrize("name", MECHANISMS)
def test_kernels_match_pinocchio(name):
    """Phi_q, Phi_qq[w, .] (Pinocchio's Jacobian time variation), gamma (its classical frame
    accelerations) and lam^T Phi_qq (one time variation per coordinate) at a random q. Both
    sides sum the same few products in another order: rounding, a few eps of the largest
    term (tolerance 64 eps times the magnitude)."""
    system, plan, q, J, rng = _state(name, 0)
    cons = system.constraints
    v, a = rng.uniform(-2, 2, (2, system.nv))
    lam = rng.uniform(-5, 5, cons.size)
    np.testing.assert_array_equal(lk.jacobian(plan, J)[0], cons.jacobian(q))
    ref = cons.jacobian_variation(q, a)
    ours = lk.variation(plan, J, a[None])[0]
    np.testing.assert_allclose(ours, ref, rtol=0, atol=64 * EPS * max(np.abs(ref).max(), 1))
    Jv, gamma, _ = lk.bias_terms(plan, J, v[None])
    ref = cons.bias_acceleration(q, v)
    np.testing.assert_allclose(gamma[0], ref, rtol=0, atol=64 * EPS * np.abs(ref).max())
    np.testing.assert_allclose(Jv[0], cons.jacobian_variation(q, v), rtol=0,
                               atol=64 * EPS * np.abs(Jv).max())
    ref = cons.hessian_by_time_variation(q, lam)
    np.testing.assert_allclose(lk.hessian(plan, J, lam[None])[0], ref, rtol=0,
                               atol=64 * EPS * np.abs(ref).max())


@pytest.mark.parametrize("name", MECHANISMS)
def test_bias_derivative_against_central_differences(name):
    """d gamma / dq (analytic, a third derivative of Phi) against five-point central
    differences of Pinocchio's gamma on the manifold, v held. Error budget of the difference
    D(h): truncation c h^4, estimated from two steps as |D(h) - D(2h)| (= 15 c h^4, so it
    bounds the truncation of D(h) 15 times over), plus rounding 3 eps max|gamma| / h (the
    weights' sum 18/12 times the rounding of each gamma value, with margin 2)."""
    system, plan, q, J, rng = _state(name, 1)
    cons = system.constraints
    v = rng.uniform(-2, 2, system.nv)
    _, _, dgamma = lk.bias_terms(plan, J, v[None])

    def five_point(h: float) -> tuple[np.ndarray, float]:
        out, e, scale = np.zeros((cons.size, system.nv)), np.zeros(system.nv), 0.0
        for j in range(system.nv):
            e[j] = h
            g = {k: cons.bias_acceleration(pin.integrate(system.model, q, k * e), v)
                 for k in (-2, -1, 1, 2)}
            e[j] = 0.0
            out[:, j] = (g[-2] - 8 * g[-1] + 8 * g[1] - g[2]) / (12 * h)
            scale = max(scale, *(np.abs(x).max() for x in g.values()))
        return out, scale

    h = 1e-3
    D1, scale = five_point(h)
    D2, _ = five_point(2 * h)
    tol = np.abs(D1 - D2).max() + 3 * EPS * scale / h
    assert np.abs(dgamma[0] - D1).max() <= tol
    assert tol < 1e-9 * max(np.abs(dgamma).max(), 1)  # the check has teeth


# ---------------------------------------------------------------------------------------------
# The singular-mass screening of open-chain batches

GIMBAL = """<?xml version="1.0"?>
<robot name="gimbal">
  <link name="base"/>
  <link name="ring1"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0"
    iyz="0" izz="0"/></inertial></link>
  <link name="ring2"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0"
    iyz="0" izz="0"/></inertial></link>
  <link name="body"><inertial><origin xyz="0 0 0"/><mass value="1.0"/><inertia ixx="0.1"
    ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link>
  <joint name="yaw" type="revolute"><parent link="base"/><child link="ring1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
  <joint name="pitch" type="revolute"><parent link="ring1"/><child link="ring2"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
  <joint name="roll" type="revolute"><parent link="ring2"/><child link="body"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
</robot>
"""


def test_trajectory_through_a_singular_mass_matrix_is_refused(write_scene):
    """A gimbal (yaw, pitch, roll, massless rings): at pitch = 0 the yaw and roll axes
    coincide and M is singular. At pitch = 3e-8 M^-1 is finite with a positive diagonal (the
    old screening passed it) while its scaled condition (~1e16) is 60x 0.1 / (n eps):
    single linearize refuses that state, so the trajectory must, naming the point."""
    path = write_scene('name = "gimbal"\nurdf = "gimbal.urdf"\nbase = "fixed"\n'
                       '[inputs]\nactuated = "all"\n', gimbal__urdf=GIMBAL)
    scene = pinlin.Scene.load(path)
    system = scene.system
    N, bad = 9, 5
    Q = np.zeros((N, 3))
    Q[:, 1] = np.linspace(0.8, 0.2, N)
    Q[bad, 1] = 3e-8
    V = np.full((N, 3), 0.3)
    U = np.zeros((N, 3))
    Minv = pin.computeMinverse(system.model, system.data, Q[bad])
    assert np.all(np.isfinite(Minv)) and Minv.diagonal().min() > 0
    assert scaled_condition(system.mass_matrix(Q[bad])) > 10 * system._refuse_limit
    with pytest.raises(pinlin.ModelError):
        pinlin.linearize(scene, q=Q[bad], v=V[bad], u=U[bad])
    with pytest.raises(pinlin.ModelError, match=f"^trajectory point {bad}: "):
        pinlin.linearize_trajectory(scene, Q, V, U)
    keep = np.arange(N) != bad  # the others pass, and equal single models
    traj = pinlin.linearize_trajectory(scene, Q[keep], V[keep], U[keep])
    single = pinlin.linearize(scene, q=Q[0], v=V[0], u=U[0])
    np.testing.assert_allclose(traj.A[0], single.A, rtol=0, atol=1e-12 * np.abs(single.A).max())


@pytest.mark.parametrize("workers", [1, 2])
def test_an_exactly_singular_point_is_refused_without_a_numpy_warning(tmp_path, workers):
    """A point mass on two joints at q2 = 0: M is singular and M^-1 holds inf and NaN. The
    batch's product M^-1 [K, C] warned 'invalid value encountered in matmul' before the
    refusal (an error where warnings are errors, and not a PinlinError)."""
    from test_trajectory import _SINGULAR

    (tmp_path / "sing.urdf").write_text(_SINGULAR)
    scene = pinlin.Scene.from_urdf(tmp_path / "sing.urdf")
    q = np.array([[0.3, 0.5], [0.1, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(pinlin.ModelError, match="^trajectory point 1: .*singular"):
            pinlin.linearize_trajectory(scene, q, np.full((2, 2), 0.2), np.zeros((2, 2)),
                                        workers=workers)
