"""Mechanisms at a moving state (eqs. 9.8-9.11 with every velocity term) against central
differences of Pinocchio's own constrained forward dynamics on the mechanism: the reduced
dynamics z'' = f(z, z', u), with q(z) re-assembled and v = the velocity with those
independent speeds that keeps the loops closed (from Pinocchio's constraint Jacobian),
a = pin.constraintDynamics(q, v, tau) (its proximal KKT solver, its own loop Jacobians)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.assembly import assemble


class ConstrainedDynamics:
    """Pinocchio's constrained forward dynamics of a scene's point loops, on the manifold."""

    def __init__(self, scene: pinlin.Scene) -> None:
        self.system = system = scene.system
        pm = self.model = system.model
        self.contacts = pin.StdVec_RigidConstraintModel()
        for loop in scene.loops:
            f1, f2 = pm.frames[pm.getFrameId(loop.frame1)], pm.frames[pm.getFrameId(loop.frame2)]
            self.contacts.append(pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D, pm, f1.parentJoint, f1.placement, f2.parentJoint,
                f2.placement, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
        self.datas = pin.StdVec_RigidConstraintData()
        for c in self.contacts:
            self.datas.append(c.createData())
        self.data = pm.createData()
        pin.initConstraintDynamics(pm, self.data, self.contacts, self.datas)
        self.prox = pin.ProximalSettings(1e-14, 1e-10, 400)

    def velocity(self, q: np.ndarray, z: np.ndarray, zdot: np.ndarray) -> np.ndarray:
        """The v with v[z] = zdot and J v = 0 (J from Pinocchio's constraint models)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        for c, cd in zip(self.contacts, self.datas, strict=True):
            c.calc(self.model, self.data, cd)  # else the Jacobian is silently stale
        J = pin.getConstraintsJacobian(self.model, self.data, self.contacts, self.datas)
        dep = np.setdiff1d(np.arange(self.model.nv), z)
        v = np.zeros(self.model.nv)
        v[z] = zdot
        v[dep] = -np.linalg.lstsq(J[:, dep], J[:, z] @ zdot, rcond=None)[0]
        return v

    def zdd(self, q0, z, dz, zdot, u) -> np.ndarray:
        system = self.system
        step = np.zeros(system.nv)
        step[z] = dz
        q = assemble(system, pin.integrate(self.model, q0, step), z)
        v = self.velocity(q, z, zdot)
        tau = system.input_matrix @ u + system.spring_torque(q) - system.damping * v
        a = pin.constraintDynamics(self.model, self.data, q, v, tau, self.contacts, self.datas,
                                   self.prox)
        return a[z].copy()

    def lower_rows(self, q0, z, zdot, u, h: float = 1e-5) -> np.ndarray:
        """d z''/d[z, z'] (nz x 2nz) by central differences of :meth:`zdd` with step h."""
        nz = len(z)
        zero = np.zeros(nz)
        cols = []
        for k in range(nz):
            e = np.zeros(nz)
            e[k] = h
            cols.append((self.zdd(q0, z, e, zdot, u) - self.zdd(q0, z, -e, zdot, u)) / (2 * h))
        for k in range(nz):
            e = np.zeros(nz)
            e[k] = h
            cols.append((self.zdd(q0, z, zero, zdot + e, u) - self.zdd(q0, z, zero, zdot - e, u))
                        / (2 * h))
        return np.array(cols).T


@pytest.mark.parametrize("name, seed", [("four_bar", 0), ("slider_crank", 1), ("delta", 2),
                                        ("five_bar", 3)])
def test_moving_mechanism_matches_constrained_dynamics(name, seed):
    """A, B and f0 of the independent model at a moving state against central differences
    of Pinocchio's constrained dynamics (h = 1e-5 in z and z', 1 N*m in u). Measured: the
    difference falls as h^2 (8e-9 to 1.4e-8 of max |A| at h = 1e-4, 6e-11 to 1.3e-10 at
    1e-5) until rounding; the tolerance 1e-8 leaves ~75x."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    system = scene.system
    rng = np.random.default_rng(seed)
    rest = pinlin.linearize(scene)
    z = np.array([system.coordinate_names.index(c) for c in rest.info["independent"]])
    ref = ConstrainedDynamics(scene)
    zdot0 = rng.uniform(-2.0, 2.0, len(z))
    u0 = rng.uniform(-1.0, 1.0, len(system.actuated))
    v0 = ref.velocity(rest.operating_point.q, z, zdot0)   # consistent: no projection
    model = pinlin.linearize(scene, q=rest.operating_point.q, v=v0, u=u0)
    q0 = model.operating_point.q
    assert model.state_names == rest.state_names
    np.testing.assert_allclose(model.operating_point.v, v0, rtol=0, atol=1e-12)
    nz = len(z)
    zero = np.zeros(nz)
    lower = ref.lower_rows(q0, z, zdot0, u0, 1e-5)
    scale = np.abs(lower).max()
    np.testing.assert_allclose(model.A[nz:], lower, rtol=0, atol=1e-8 * scale)
    np.testing.assert_array_equal(model.A[:nz], np.hstack([np.zeros((nz, nz)), np.eye(nz)]))
    B = np.array([(ref.zdd(q0, z, zero, zdot0, u0 + e) - ref.zdd(q0, z, zero, zdot0, u0 - e))
                  / 2.0 for e in np.eye(len(u0))]).T
    np.testing.assert_allclose(model.B[nz:], B, rtol=0, atol=1e-8 * np.abs(B).max())
    a0 = ref.zdd(q0, z, zero, zdot0, u0)
    np.testing.assert_allclose(model.f0, np.concatenate([zdot0, a0]), rtol=0,
                               atol=1e-9 * np.abs(a0).max())
    # The velocity terms matter: the model at rest differs.
    assert np.abs(model.A[nz:] - rest.A[nz:]).max() > 1e-3 * scale


def test_inconsistent_velocity_is_projected_and_reported():
    model = pinlin.linearize("four_bar", v=np.array([1.0, 0.0, 0.0]))
    op = model.operating_point
    G = model.info["constraint_rows"]
    assert G and any("projected onto the constraint nullspace" in n for n in op.notes)
    system = pinlin.Scene.resolve("four_bar").system
    J = system.constraints.jacobian(op.q)
    assert np.abs(J @ op.v).max() <= 1e-12
    # Orthogonal projection: the correction is along the constraint normals.
    d = np.array([1.0, 0.0, 0.0]) - op.v
    N = np.linalg.svd(J)[2][np.linalg.matrix_rank(J):]
    assert np.abs(N @ d).max() <= 1e-12


@pytest.mark.parametrize("kwargs, words", [
    ({"formulation": "canonical"}, "not supported there yet"),
    ({"basis": "orthonormal"}, "not supported there yet"),
    ({"derivatives": "fd5", "formulation": "penalty"}, "independent formulation only"),
])
def test_what_moving_mechanisms_do_not_support_yet(kwargs, words):
    with pytest.raises(pinlin.ModelError, match=words):
        pinlin.linearize("four_bar", v=np.array([1.0, 0.0, 0.0]), **kwargs)


def _penalty_ode(scene: pinlin.Scene, alpha: float, mu: float, omega: float):
    """q'' of the penalty model (eq. 9.35) at any (q, q', u), from Pinocchio alone: crba, rnea,
    frame Jacobians and classical accelerations of the loop frames (all three rows of each
    point loop; the planar loops' out-of-plane rows are identically zero)."""
    system = scene.system
    pm, pd = system.model, system.model.createData()
    LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    frames = [(pm.getFrameId(lp.frame1), pm.getFrameId(lp.frame2)) for lp in scene.loops]

    def qdd(q: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        pin.forwardKinematics(pm, pd, q, v, np.zeros(pm.nv))
        pin.computeJointJacobians(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        phi, G, gamma = [], [], []
        for f1, f2 in frames:
            phi.append(pd.oMf[f1].translation - pd.oMf[f2].translation)
            G.append(pin.getFrameJacobian(pm, pd, f1, LWA)[:3]
                     - pin.getFrameJacobian(pm, pd, f2, LWA)[:3])
            gamma.append(pin.getFrameClassicalAcceleration(pm, pd, f1, LWA).linear
                         - pin.getFrameClassicalAcceleration(pm, pd, f2, LWA).linear)
        phi, G, gamma = np.concatenate(phi), np.vstack(G), np.concatenate(gamma)
        M = pin.crba(pm, pd, q)
        M = np.triu(M) + np.triu(M, 1).T
        tau = (system.input_matrix @ u + system.spring_torque(q) - system.damping * v
               - pin.rnea(pm, pd, q, v, np.zeros(pm.nv)))
        force = alpha * G.T @ (gamma + 2 * mu * omega * (G @ v) + omega**2 * phi)
        return np.linalg.solve(M + alpha * G.T @ G, tau - force)

    return qdd


@pytest.mark.parametrize("name, seed", [("four_bar", 4), ("slider_crank", 5), ("five_bar", 6)])
def test_moving_penalty_model_matches_its_equation(name, seed):
    """The penalty model at a moving state against five-point differences of eq. 9.35
    written out with Pinocchio (alpha = 1e4, mu = 0.4, Omega = 8). The reference solves with
    M + alpha G^T G (condition ~alpha), so its rounding, ~eps alpha |q''| / h, grows as h falls
    (measured 3e-6 at h = 1e-6 with central differences); five-point differences at h = 3e-3
    (truncation ~h^4) agree to ~1e-9; tolerance 1e-7."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    system = scene.system
    rng = np.random.default_rng(seed)
    rest = pinlin.linearize(scene)
    z = np.array([system.coordinate_names.index(c) for c in rest.info["independent"]])
    v0 = ConstrainedDynamics(scene).velocity(rest.operating_point.q, z,
                                             rng.uniform(-2.0, 2.0, len(z)))
    u0 = rng.uniform(-1.0, 1.0, len(system.actuated))
    kw = {"alpha": 1e4, "mu": 0.4, "omega": 8.0}
    model = pinlin.linearize(scene, q=rest.operating_point.q, v=v0, u=u0,
                             formulation="penalty", **kw)
    q0 = model.operating_point.q
    f = _penalty_ode(scene, kw["alpha"], kw["mu"], kw["omega"])
    n, h = system.nv, 3e-3

    def five_point(g) -> np.ndarray:
        return (-g(2 * h) + 8 * g(h) - 8 * g(-h) + g(-2 * h)) / (12 * h)

    cols = [five_point(lambda s, e=e: f(pin.integrate(system.model, q0, s * e), v0, u0))
            for e in np.eye(n)]
    cols += [five_point(lambda s, e=e: f(q0, v0 + s * e, u0)) for e in np.eye(n)]
    lower = np.array(cols).T
    np.testing.assert_allclose(model.A[n:], lower, rtol=0, atol=1e-7 * np.abs(lower).max())
    B = np.array([(f(q0, v0, u0 + e) - f(q0, v0, u0 - e)) / 2.0 for e in np.eye(len(u0))]).T
    np.testing.assert_allclose(model.B[n:], B, rtol=0, atol=1e-9 * np.abs(B).max())
    np.testing.assert_allclose(model.f0[n:], f(q0, v0, u0), rtol=0, atol=1e-9 * 1e2)


def _four_bar_near_fold(offset: float) -> pinlin.Scene:
    """The bundled four-bar with the rocker independent, ``offset`` [rad] from the rocker's
    extreme (crank and coupler in line; link lengths of four_bar.urdf: crank 0.2, coupler
    0.5, rocker 0.4, ground 0.45)."""
    a, b, c, d = 0.2, 0.5, 0.4, 0.45
    psi0 = math.pi - math.acos((c * c + d * d - (a + b) ** 2) / (2 * c * d))
    return pinlin.Scene.from_dict({
        "urdf": str(URDF_DIR / "four_bar.urdf"), "effects": {"gravity": [0, 0, -9.81]},
        "loops": [{"name": "closure", "frame1": "coupler_tip", "frame2": "rocker_tip"}],
        "inputs": {"actuated": ["crank"]},
        "operating_point": {"q": {"crank": 0.5, "coupler": -0.1, "rocker": psi0 + offset},
                            "independent": ["rocker"]}})


def test_moving_near_a_fold_is_warned():
    """Four-bar with the rocker independent, 1e-9 rad from its extreme, moving at 0.1 rad/s:
    configurations that close the loop equally well (to the assembly's tolerance) give state
    matrices 1.8e-3 apart (velocity terms grow like v^2 over the distance to the fold
    squared), and the moving model said nothing; at rest the same point is quiet (4e-7).
    Reference: the loop closed to rounding by a Newton written here (crank and coupler,
    rocker held), linearized at the same state."""
    scene = _four_bar_near_fold(1e-9)
    rest = pinlin.linearize(scene)
    q0, u0 = rest.operating_point.q, rest.operating_point.u
    v = np.array(rest.info["R"])[:, 0] * 0.1
    with pytest.warns(pinlin.AccuracyWarning, match="singular position"):
        moving = pinlin.linearize(scene, q=q0, v=v, u=u0)
    change = moving.info["condition"]["operating_point_sensitivity"]
    model, data = scene.system.model, scene.system.model.createData()
    f1, f2 = model.getFrameId("coupler_tip"), model.getFrameId("rocker_tip")
    q = q0.copy()
    for _ in range(20):   # Newton on crank and coupler, rocker held, rows x and z
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        r = (data.oMf[f1].translation - data.oMf[f2].translation)[[0, 2]]
        J = (pin.getFrameJacobian(model, data, f1, pin.LOCAL_WORLD_ALIGNED)
             - pin.getFrameJacobian(model, data, f2, pin.LOCAL_WORLD_ALIGNED))[[0, 2]][:, :2]
        q[:2] -= np.linalg.lstsq(J, r, rcond=None)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        closed = pinlin.linearize(scene, q=q, v=v, u=u0)
    actual = np.abs(closed.A - moving.A).max() / np.abs(moving.A).max()
    assert actual > 1e-4                 # the point is sensitive: what the warning is about
    assert change >= 0.5 * actual        # and the estimate says so (4.2e-3 against 1.8e-3)


def test_a_moving_trajectory_near_a_fold_is_warned():
    """The same point as above as one point of a trajectory: the stack is warned about at its
    point nearest the fold, as the single call is."""
    scene = _four_bar_near_fold(1e-9)
    rest = pinlin.linearize(scene)
    q0, u0 = rest.operating_point.q, rest.operating_point.u
    v = np.array(rest.info["R"])[:, 0] * 0.1
    with pytest.warns(pinlin.AccuracyWarning, match="trajectory point 0, the trajectory's point "
                                                    "nearest a singular position"):
        traj = pinlin.linearize_trajectory(scene, np.array([q0, q0]), np.array([0.5 * v, v]),
                                           np.array([u0, u0]))
    assert traj.info["operating_point_sensitivity"]["point"] == 0   # the first of equals


def test_a_trajectory_from_rest_near_a_fold_checks_its_moving_point():
    """At rest 1e-9 rad from the fold (condition 1.3e5, quiet: 4e-7), then moving 2e-9 rad
    from it (condition 9e4, 2e-3 as a single call says): the point of largest condition alone
    missed the moving one."""
    scene_at = _four_bar_near_fold
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        p0, p1 = pinlin.linearize(scene_at(1e-9)), pinlin.linearize(scene_at(2e-9))
    v1 = np.array(p1.info["R"])[:, 0] * 0.1
    Q = np.array([p0.operating_point.q, p1.operating_point.q])
    V = np.array([np.zeros_like(v1), v1])
    U = np.array([p0.operating_point.u, p1.operating_point.u])
    with pytest.warns(pinlin.AccuracyWarning, match="trajectory point 1"):
        traj = pinlin.linearize_trajectory(scene_at(1e-9), Q, V, U)
    assert traj.info["operating_point_sensitivity"]["point"] == 1
