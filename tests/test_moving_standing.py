"""Floating bases on contacts, weld loops and welded contacts at a moving state
(:mod:`pinlin.formulations.moving_manifold`).

References from outside the code under test:

- Pinocchio's constrained forward dynamics (``constraintDynamics``, its own contact and loop
  Jacobians, RigidConstraintModels to the universe for contacts) differenced on the
  constraint manifold in the model's chart x = [difference(q0, q)[z]; v[z]]: q re-assembled
  with z held, v the velocity with v[z] = z' that keeps the constraints (Pinocchio's
  Jacobian), d/dt difference(q0, q) = dDifference(q0, q) v (Pinocchio);
- the fixed-base four-bar (itself checked against the same differences in
  tests/test_moving_loops.py) equals the four-bar on a floating base welded to the world;
- on revolute mechanisms, the stacked analytic kernels of the fixed-base path.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR
from test_closed_loops import _two_branch_urdf
from test_contacts import _box

import pinlin
from pinlin.assembly import assemble
from pinlin.formulations import moving_manifold

G = 9.81


class ChartDynamics:
    """Pinocchio's constrained dynamics of a scene's contacts and loops, on the manifold, in
    the chart x = [difference(q0, q)[z]; v[z]]."""

    def __init__(self, system, z: np.ndarray) -> None:
        self.system, self.z = system, z
        pm = self.model = system.model
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        kinds = {"point": pin.ContactType.CONTACT_3D, "weld": pin.ContactType.CONTACT_6D}
        self.cm = pin.StdVec_RigidConstraintModel()
        for c in system.constraints.contacts:
            f = pm.frames[c.frame_id]
            self.cm.append(pin.RigidConstraintModel(kinds[c.type], pm, f.parentJoint,
                                                    f.placement, 0, c.placement, lwa))
        for loop in system.scene.loops:
            f1, f2 = pm.frames[pm.getFrameId(loop.frame1)], pm.frames[pm.getFrameId(loop.frame2)]
            self.cm.append(pin.RigidConstraintModel(kinds[loop.type], pm, f1.parentJoint,
                                                    f1.placement, f2.parentJoint, f2.placement,
                                                    lwa))
        self.cd = pin.StdVec_RigidConstraintData()
        for c in self.cm:
            self.cd.append(c.createData())
        self.data = pm.createData()
        pin.initConstraintDynamics(pm, self.data, self.cm, self.cd)
        self.prox = pin.ProximalSettings(1e-14, 1e-8, 400)

    def velocity(self, q: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The v with v[z] = w that keeps the constraints (Pinocchio's Jacobian)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        for c, cd in zip(self.cm, self.cd, strict=True):
            c.calc(self.model, self.data, cd)  # else the Jacobian is silently stale
        J = pin.getConstraintsJacobian(self.model, self.data, self.cm, self.cd)
        dep = np.setdiff1d(np.arange(self.model.nv), self.z)
        v = np.zeros(self.model.nv)
        v[self.z] = w
        v[dep] = -np.linalg.lstsq(J[:, dep], J[:, self.z] @ w, rcond=None)[0]
        return v

    def f(self, q0: np.ndarray, dz: np.ndarray, w: np.ndarray, u: np.ndarray) -> np.ndarray:
        """d/dt [difference(q0, q)[z]; v[z]] at the state (dz, w) with inputs u."""
        system, z = self.system, self.z
        step = np.zeros(system.nv)
        step[z] = dz
        q = assemble(system, pin.integrate(self.model, q0, step), z) if dz.any() else q0
        v = self.velocity(q, w)
        tau = system.input_matrix @ u + system.spring_torque(q) - system.damping * v
        a = pin.constraintDynamics(self.model, self.data, q, v, tau, self.cm, self.cd,
                                   self.prox)
        dq_dt = pin.dDifference(self.model, q0, q, pin.ArgumentPosition.ARG1) @ v
        return np.concatenate([dq_dt[z], a[z]])

    def jacobians(self, q0: np.ndarray, w: np.ndarray, u: np.ndarray, h: float,
                  points: int = 3) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) by central differences of :meth:`f` (three- or five-point), step h in dz and
        w, 1 in u (linear)."""
        nz = len(self.z)
        zero = np.zeros(nz)
        weights = {1: 0.5, -1: -0.5} if points == 3 else \
            {2: -1 / 12, 1: 8 / 12, -1: -8 / 12, -2: 1 / 12}

        def column(fun) -> np.ndarray:
            return sum(c * fun(k * h) for k, c in weights.items()) / h

        cols = [column(lambda s, e=e: self.f(q0, s * e, w, u)) for e in np.eye(nz)]
        cols += [column(lambda s, e=e: self.f(q0, zero, w + s * e, u)) for e in np.eye(nz)]
        B = [(self.f(q0, zero, w, u + e) - self.f(q0, zero, w, u - e)) / 2.0
             for e in np.eye(len(u))]
        return np.array(cols).T, np.array(B).T.reshape(2 * nz, len(u))


def _two_branch_weld(tmp_path) -> pinlin.Scene:
    """Two spatial 4R branches welded tip to tip (tests/test_closed_loops.py's scene)."""
    q_star = np.array([0.3, -0.5, 0.4, 0.9, 2.6, 0.4, -0.3, -0.8])
    path = tmp_path / "two_branches.urdf"
    path.write_text(_two_branch_urdf(None))
    pm = pin.buildModelFromUrdf(str(path))
    pd = pm.createData()
    pin.framesForwardKinematics(pm, pd, q_star)
    on_b3 = pd.oMf[pm.getFrameId("tip_b")].inverse() * pd.oMf[pm.getFrameId("tip_a")]
    path.write_text(_two_branch_urdf(on_b3))
    names = [f"a{i}" for i in range(4)] + [f"b{i}" for i in range(4)]
    return pinlin.Scene.from_dict({
        "urdf": str(path),
        "effects": {"gravity": [0, 0, -G],
                    "springs": {n: {"stiffness": 3.0, "rest": float(q) + 0.1}
                                for n, q in zip(names, q_star, strict=True)}},
        "loops": [{"name": "weld", "type": "weld", "frame1": "tip_a", "frame2": "tip_b"}],
        "operating_point": {"q": {n: float(q) for n, q in zip(names, q_star, strict=True)},
                            "independent": ["a0", "b0"]},
        "inputs": {"actuated": "all"}})


def _base_independent(name: str, rpy: list[float] | None = None) -> pinlin.Scene:
    """A bundled standing robot with its base's six coordinates independent (and every joint
    but the legs'), the base turned and tilted by ``rpy``: the kinematic block acts on
    z, and the legs' joints, dependent, carry W."""
    data = tomllib.loads((URDF_DIR / f"{name}.toml").read_text())
    system = pinlin.Scene.from_dict(data).system
    legs = ("leg_", "FL_", "FR_", "HL_", "HR_")
    data["operating_point"] = dict(data.get("operating_point", {}))
    data["operating_point"]["independent"] = ["root_joint"] + [
        j for j in system.joints if j != "root_joint" and not j.startswith(legs)]
    if rpy is not None:
        q = dict(data["operating_point"].get("q", {}))
        base = dict(q.get("root_joint", {"position": [0.1, -0.2, 0.25]}))
        base["rpy"] = rpy
        q["root_joint"] = base
        data["operating_point"]["q"] = q
    return pinlin.Scene.from_dict(data)


def _case(name: str, tmp_path) -> pinlin.Scene:
    if name == "tilted_box":   # the base in z, turned and tilted: the kinematic block acts
        return _box([{"name": "tip", "frame": "bottom"}], rpy=[0.2, -0.15, 0.7])
    if name == "solo12_base":   # point feet, the base independent, turned and tilted
        return _base_independent("solo12_standing", [0.3, -0.25, 1.1])
    if name == "talos_base":    # welded soles, the base independent
        return _base_independent("talos_standing")
    if name == "blade":        # a redundant contact row
        return _box([{"name": "front", "frame": "blade_front"},
                     {"name": "back", "frame": "blade_back"}])
    if name == "two_branch_weld":
        return _two_branch_weld(tmp_path)
    return pinlin.Scene.load(URDF_DIR / f"{name}.toml")


@pytest.mark.parametrize("name, seed, h", [
    ("tilted_box", 0, 1e-4), ("blade", 1, 1e-4), ("solo12_standing", 2, 1e-4),
    ("solo12_base", 7, 1e-4), ("talos_standing", 3, 1e-4), ("talos_base", 8, 1e-4),
    ("two_branch_weld", 4, 3e-5)])
def test_moving_model_matches_constraint_dynamics_in_its_chart(name, seed, h, tmp_path):
    """A, B and f0 at a moving state against five-point central differences (step h) of
    Pinocchio's constrained dynamics in the chart (module docstring). Measured distances to
    the model: 1e-15 (blade) to 4.1e-10 (Talos, base independent) of max |A|; three-point
    differences at h = 1e-5 stay at 1e-7 there (truncation: the legs move fast along the
    base's height). The two-branch weld (Phi_d's condition 293, a dependent joint 35x faster
    than z, entries of A up to 1e4 from terms of 8e4) curves much more: h = 3e-5, measured
    4.6e-10 (4.4e-8 at h = 1e-4). Tolerance 1e-8: >= 20x. The model at rest differs by O(1)
    (but on the blade, a hinged pendulum), so the velocity terms are checked."""
    scene = _case(name, tmp_path)
    system = scene.system
    rng = np.random.default_rng(seed)
    u0 = rng.uniform(-1.0, 1.0, len(system.actuated))
    still = pinlin.linearize(scene, v=np.zeros(system.nv), u=u0)  # assembled, not moving
    z = np.array([system.coordinate_names.index(c) for c in still.info["independent"]])
    nz = len(z)
    ref = ChartDynamics(system, z)
    w0 = rng.uniform(-1.0, 1.0, nz)
    q0 = still.operating_point.q
    v0 = ref.velocity(q0, w0)                 # consistent: nothing to project
    model = pinlin.linearize(scene, q=q0, v=v0, u=u0)
    assert model.state_names == still.state_names
    np.testing.assert_allclose(model.operating_point.v, v0, rtol=0, atol=1e-12)
    A, B = ref.jacobians(q0, w0, u0, h, points=5)
    scale = np.abs(A).max()
    np.testing.assert_allclose(model.A, A, rtol=0, atol=1e-8 * scale)
    if B.size:
        np.testing.assert_allclose(model.B, B, rtol=0, atol=1e-7 * np.abs(B).max())
    f0 = ref.f(q0, np.zeros(nz), w0, u0)
    np.testing.assert_allclose(model.f0, f0, rtol=0, atol=1e-9 * np.abs(f0).max())
    if name != "blade":   # a hinged pendulum: th'' = (m g l / I) sin th has no velocity terms
        assert np.abs(model.A - still.A).max() > 1e-3 * scale


def test_tilted_box_upper_rows_carry_the_kinematic_block(tmp_path):
    """With the base's coordinates independent and a turning base, d/dt difference(q0, q)
    depends on dq: the upper block row is not [0 I] (its first block is (-1/2 ad(v0) R)[z],
    checked against the differences above); at rest it is."""
    scene = _case("tilted_box", tmp_path)
    rest = pinlin.linearize(scene, v=np.zeros(6))
    nz = rest.A.shape[0] // 2
    v = np.zeros(6)
    v[3:] = [0.4, -0.3, 0.8]
    model = pinlin.linearize(scene, q=rest.operating_point.q, v=v)
    np.testing.assert_array_equal(rest.A[:nz, :nz], 0.0)
    assert np.abs(model.A[:nz, :nz]).max() > 0.1
    np.testing.assert_array_equal(model.A[:nz, nz:], np.eye(nz))


def test_welded_floating_four_bar_moves_as_the_fixed_four_bar():
    """The four-bar on a floating base welded to the world where it stands, at the fixed
    four-bar's moving state (base at rest): the same A, B, f0 as the fixed-base model, which
    the stacked analytic kernels compute (the floating one takes the manifold path). Measured
    1.1e-12 of max |A| apart (the manifold differences' error); tolerance 1e-10."""
    data = tomllib.loads((URDF_DIR / "four_bar.toml").read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    fixed_scene = pinlin.Scene.from_dict(data)
    rest = pinlin.linearize(fixed_scene)
    q = rest.operating_point.q
    system = fixed_scene.system
    G = system.constraints.jacobian(q)
    v = np.linalg.svd(G)[2][-1] * 2.0        # a consistent velocity (nullspace of Phi_q)
    u = np.array([0.7])
    fixed = pinlin.linearize(fixed_scene, q=q, v=v, u=u)
    data.update(base="free", contacts=[{"name": "ground", "frame": "ground", "type": "weld"}])
    scene = pinlin.Scene.from_dict(data)
    base = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    free = pinlin.linearize(scene, q=np.concatenate([base, q]), v=np.concatenate([np.zeros(6), v]),
                            u=u)
    assert free.state_names == fixed.state_names
    scale = np.abs(fixed.A).max()
    np.testing.assert_allclose(free.A, fixed.A, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(free.B, fixed.B, rtol=0, atol=1e-9 * np.abs(fixed.B).max())
    np.testing.assert_allclose(free.f0, fixed.f0, rtol=0, atol=1e-9 * np.abs(fixed.f0).max())


@pytest.mark.parametrize("name", ["four_bar", "slider_crank", "delta", "five_bar"])
def test_manifold_path_equals_the_revolute_kernels(name):
    """On revolute mechanisms both halves of Phi_qq agree: the manifold path (differences
    along the mechanism, module docstring) gives the analytic kernels' model to the
    differences' error: measured 9e-15 (slider-crank) to 1.5e-12 (four-bar) of max |A|;
    tolerance 1e-10."""
    scene = pinlin.Scene.resolve(name)
    system = scene.system
    rng = np.random.default_rng(5)
    model = pinlin.linearize(scene, v=rng.uniform(-2.0, 2.0, system.nv),
                             u=rng.uniform(-1.0, 1.0, len(system.actuated)))
    op = model.operating_point
    from pinlin.assembly import partition

    part = partition(system, op.q, system.constraints.jacobian(op.q))
    G = system.constraints.jacobian(op.q)[part.rows]
    A, B, f0, *_ = moving_manifold.model(system, op, part, G)
    np.testing.assert_allclose(A, model.A, rtol=0, atol=1e-10 * np.abs(model.A).max())
    np.testing.assert_allclose(B, model.B, rtol=0, atol=1e-10 * np.abs(model.B).max())
    np.testing.assert_array_equal(f0, model.f0)


@pytest.mark.parametrize("name, kwargs", [
    ("standing_box", {"derivatives": "fd5"}), ("standing_box", {"formulation": "canonical"}),
    ("talos_standing", {"formulation": "penalty"})])
def test_what_standing_robots_in_motion_do_not_support_yet(name, kwargs):
    scene = pinlin.Scene.resolve(name)
    with pytest.raises(pinlin.ModelError, match="not supported"):
        pinlin.linearize(scene, v=np.zeros(scene.system.nv), **kwargs)


@pytest.mark.parametrize("workers", [1, 2])
def test_standing_trajectory_points_are_single_calls(workers):
    """solo12 standing, its joints swept and moving: each point of linearize_trajectory is the
    single linearize at its assembled configuration with the same independent coordinates
    (named in the scene: a trajectory freezes point 0's, a single call would choose its
    own), in one process and in two. Not bit for bit: the single call anchors the feet where
    traj.q[k] puts them, which the trajectory's assembly closed to 1e-12 m, so the manifold
    differences (step 1e-4, rounding ~eps |f| / h) run on a minutely different curve;
    measured 1.6e-12 of max |A| apart, tolerance 1e-10."""
    data = tomllib.loads((URDF_DIR / "solo12_standing.toml").read_text())
    scene = pinlin.Scene.from_dict(data)
    system = scene.system
    rest = pinlin.linearize(scene)
    data["operating_point"] = {"independent": list(rest.info["independent"])}
    scene = pinlin.Scene.from_dict(data)
    z = [system.coordinate_names.index(c) for c in rest.info["independent"]]
    rng = np.random.default_rng(6)
    N = 4
    Q = np.empty((N, system.nq))
    for k in range(N):
        dq = np.zeros(system.nv)
        dq[z] = 0.03 * k
        Q[k] = pin.integrate(system.model, rest.operating_point.q, dq)
    V = rng.uniform(-0.5, 0.5, (N, system.nv))
    U = rest.operating_point.u + rng.uniform(-0.2, 0.2, (N, len(system.actuated)))
    traj = pinlin.linearize_trajectory(scene, Q, V, U, workers=workers)
    for k in range(N):
        single = pinlin.linearize(scene, q=traj.q[k], v=V[k], u=U[k])
        assert single.state_names == traj.state_names
        np.testing.assert_allclose(traj.A[k], single.A, rtol=0,
                                   atol=1e-10 * np.abs(single.A).max())
        np.testing.assert_allclose(traj.B[k], single.B, rtol=0,
                                   atol=1e-10 * np.abs(single.B).max())
        np.testing.assert_allclose(traj.f0[k], single.f0, rtol=0,
                                   atol=1e-10 * np.abs(single.f0).max())


FLAGPOLE = """<?xml version="1.0"?>
<robot name="flagpole">
  <link name="body"><inertial><mass value="2.0"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="flag"/>
  <joint name="hinge" type="revolute"><parent link="body"/><child link="flag"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


def test_a_motion_that_moves_no_inertia_is_refused(tmp_path, capsys):
    """A floating body welded to the world with a massless flag on a hinge: the hinge, the one
    motion the weld allows, moves no inertia, so the constrained dynamics are singular. A
    ModelError saying so (the CLI: one line, exit 2), not numpy's LinAlgError."""
    from pinlin.cli import main

    (tmp_path / "flag.urdf").write_text(FLAGPOLE)
    text = ('urdf = "flag.urdf"\nbase = "free"\n[effects]\ngravity = [0.0, 0.0, -9.81]\n'
            '[[contacts]]\nname = "hold"\nframe = "body"\ntype = "weld"\n'
            '[operating_point]\nsolve = "none"\nv = { hinge = 1.0 }\n')
    (tmp_path / "flag.toml").write_text(text)
    with pytest.raises(pinlin.ModelError, match="moves no inertia"):
        pinlin.linearize(pinlin.Scene.load(tmp_path / "flag.toml"))
    assert main(["linearize", str(tmp_path / "flag.toml")]) == 2
    err = capsys.readouterr().err
    assert "moves no inertia" in err and "Traceback" not in err and len(err.splitlines()) == 1


def _penalty_ode(system, alpha: float, mu: float, omega: float):
    """d/dt [difference(q0, q); v] of eq. 9.35 for point contacts, from Pinocchio alone:
    crba, rnea, the contact frames' LOCAL_WORLD_ALIGNED Jacobians and classical
    accelerations, the anchors from the constraint set, dDifference for the chart."""
    pm, pd = system.model, system.model.createData()
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    contacts = [(c.frame_id, c.position) for c in system.constraints.contacts]

    def f(q0: np.ndarray, dq: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        q = pin.integrate(pm, q0, dq)
        pin.forwardKinematics(pm, pd, q, v, np.zeros(pm.nv))
        pin.computeJointJacobians(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        phi = np.concatenate([pd.oMf[fid].translation - anchor for fid, anchor in contacts])
        G = np.vstack([pin.getFrameJacobian(pm, pd, fid, lwa)[:3] for fid, _ in contacts])
        gamma = np.concatenate([pin.getFrameClassicalAcceleration(pm, pd, fid, lwa).linear
                                for fid, _ in contacts])
        M = pin.crba(pm, pd, q)
        M = np.triu(M) + np.triu(M, 1).T
        tau = (system.input_matrix @ u + system.spring_torque(q) - system.damping * v
               - pin.rnea(pm, pd, q, v, np.zeros(pm.nv)))
        force = alpha * G.T @ (gamma + 2 * mu * omega * (G @ v) + omega**2 * phi)
        a = np.linalg.solve(M + alpha * G.T @ G, tau - force)
        return np.concatenate([pin.dDifference(pm, q0, q, pin.ArgumentPosition.ARG1) @ v, a])

    return f


@pytest.mark.parametrize("name, seed", [("tilted_box", 9), ("solo12_standing", 10)])
def test_moving_penalty_model_of_point_contacts_matches_its_equation(name, seed, tmp_path):
    """The penalty model of a floating base on point contacts at a moving state (all 2 nv
    states, the base's kinematic block included) against five-point differences of eq. 9.35
    written out with Pinocchio in the chart (alpha = 1e4, mu = 0.4, Omega = 8; h = 3e-3, as
    for the mechanisms in tests/test_moving_loops.py: the reference's rounding grows like
    eps alpha / h). Measured 6e-12 (box) and 1.3e-9 (solo12) of max |A|; tolerance 1e-7.
    The turning box's upper block row carries the base's kinematic block."""
    scene = _case(name, tmp_path)
    system = scene.system
    rng = np.random.default_rng(seed)
    u0 = rng.uniform(-1.0, 1.0, len(system.actuated))
    still = pinlin.linearize(scene, v=np.zeros(system.nv), u=u0)
    R = np.array(still.info["R"])
    v0 = R @ rng.uniform(-1.0, 1.0, R.shape[1])       # consistent with the contacts
    kw = {"alpha": 1e4, "mu": 0.4, "omega": 8.0}
    model = pinlin.linearize(scene, q=still.operating_point.q, v=v0, u=u0,
                             formulation="penalty", **kw)
    q0, n, h = model.operating_point.q, system.nv, 3e-3
    f = _penalty_ode(system, kw["alpha"], kw["mu"], kw["omega"])

    def five_point(g) -> np.ndarray:
        return (-g(2 * h) + 8 * g(h) - 8 * g(-h) + g(-2 * h)) / (12 * h)

    zero = np.zeros(n)
    cols = [five_point(lambda s, e=e: f(q0, s * e, v0, u0)) for e in np.eye(n)]
    cols += [five_point(lambda s, e=e: f(q0, zero, v0 + s * e, u0)) for e in np.eye(n)]
    A = np.array(cols).T
    np.testing.assert_allclose(model.A, A, rtol=0, atol=1e-7 * np.abs(A).max())
    np.testing.assert_allclose(model.f0, f(q0, zero, v0, u0), rtol=0,
                               atol=1e-9 * np.abs(model.f0).max())
    if len(u0):
        B = np.array([(f(q0, zero, v0, u0 + e) - f(q0, zero, v0, u0 - e)) / 2.0
                      for e in np.eye(len(u0))]).T
        np.testing.assert_allclose(model.B, B, rtol=0, atol=1e-9 * np.abs(B).max())
    if name == "tilted_box":
        assert np.abs(model.A[:n, :n]).max() > 0.1
