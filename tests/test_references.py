"""Constrained models against references built here from Pinocchio alone.

pinlin's penalty and canonical tests used to compare pinlin with itself (slope in alpha,
penalty = canonical through shared helpers). Here every expected value is computed from the
definitions with Pinocchio's crba/rnea/frame placements and finite differences, never from
pinlin's own matrices:

- eqs. 9.35-9.37: M_p = M + alpha G^T G, C_p = 2 mu Omega alpha G^T G (+ C), K_p = K + alpha
  Omega^2 G^T G, with G from central differences of the loop's frame positions and K from
  central differences of gravity minus the constraint forces;
- the 2m constraint eigenvalues tend to the roots of s^2 + 2 mu Omega s + Omega^2;
- B of each formulation against a plain solve (penalty) and against Pinocchio's constrained
  forward dynamics differenced in u (independent coordinates);
- frame and joint outputs against the frame positions along the mechanism's own motion
  (independent coordinates: re-assembled; penalty: each coordinate moved alone).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.assembly import assemble

POINT_LOOPS = ["four_bar", "slider_crank", "delta"]
#: Penalty parameters away from the defaults, so that a swapped or rescaled one shows.
ALPHA, MU, OMEGA = 1e5, 0.3, 7.0
#: Central-difference step [rad or m]: truncation ~h^2 |Phi'''| ~ 1e-10, rounding
#: eps |Phi| / h ~ 2e-11; both far below the 1e-7 relative tolerances used.
H = 1e-5


def _frame_position(model: pin.Model, data: pin.Data, q: np.ndarray, frame: str) -> np.ndarray:
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId(frame)].translation.copy()


def _loop_residual(scene: pinlin.Scene, q: np.ndarray) -> np.ndarray:
    """Phi(q): frame1 - frame2 positions of every (point) loop, stacked [m]."""
    model = scene.system.model
    data = model.createData()
    return np.concatenate([_frame_position(model, data, q, lp.frame1)
                           - _frame_position(model, data, q, lp.frame2) for lp in scene.loops])


def _central(fun, q0: np.ndarray, model: pin.Model, h: float = H) -> np.ndarray:
    """d fun / d(dq) at q0 on the manifold, central differences."""
    cols = []
    for j in range(model.nv):
        e = np.zeros(model.nv)
        e[j] = h
        cols.append((fun(pin.integrate(model, q0, e)) - fun(pin.integrate(model, q0, -e)))
                    / (2 * h))
    return np.array(cols).T


def _definition(scene: pinlin.Scene, op) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, K, G^T G) at the operating point, from Pinocchio and finite differences only."""
    system = scene.system
    model = system.model
    data = model.createData()
    M = pin.crba(model, data, op.q)
    M = np.triu(M) + np.triu(M, 1).T
    G = _central(lambda q: _loop_residual(scene, q), op.q, model)

    def frame_jacobian(q: np.ndarray, frame: str) -> np.ndarray:
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        return pin.getFrameJacobian(model, data, model.getFrameId(frame),
                                    pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]

    def held_force(q: np.ndarray) -> np.ndarray:
        """gravity - springs - Phi_q^T lam at fixed lam (the residual of the statics)."""
        tau = pin.computeGeneralizedGravity(model, data, q).copy()
        tau -= system.spring_torque(q)
        for k, lp in enumerate(scene.loops):
            J = frame_jacobian(q, lp.frame1) - frame_jacobian(q, lp.frame2)
            tau -= J.T @ op.lam[3 * k:3 * k + 3]
        return tau

    K = _central(held_force, op.q, model)
    return M, K, G.T @ G


@pytest.mark.parametrize("name", POINT_LOOPS)
def test_penalty_matrices_follow_their_definition(name):
    """M_p, C_p, K_p of eqs. 9.35-9.37 with the alpha, mu and Omega given (a consistently
    rescaled alpha or mu, model and info alike, fails here)."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    pen = pinlin.linearize(scene, formulation="penalty", alpha=ALPHA, mu=MU, omega=OMEGA)
    M, K, GtG = _definition(scene, pen.operating_point)
    scale = ALPHA * np.abs(GtG).max()
    np.testing.assert_allclose(pen.M, M + ALPHA * GtG, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(pen.C_damp, 2 * MU * OMEGA * ALPHA * GtG, rtol=0,
                               atol=1e-8 * scale)
    np.testing.assert_allclose(pen.K, K + ALPHA * OMEGA**2 * GtG, rtol=0,
                               atol=1e-7 * OMEGA**2 * scale)


@pytest.mark.parametrize("name", POINT_LOOPS)
def test_penalty_input_matrix_against_a_plain_solve(name):
    """B = [0; M_p^-1 S] with M_p from the definition, solved plainly at an alpha where that is
    accurate (cond(M_p) ~ 1e3)."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    pen = pinlin.linearize(scene, formulation="penalty", alpha=1e3, mu=MU, omega=OMEGA)
    M, _, GtG = _definition(scene, pen.operating_point)
    n = M.shape[0]
    S = scene.system.input_matrix
    np.testing.assert_allclose(pen.B[:n], 0.0, atol=0)
    expected = np.linalg.solve(M + 1e3 * GtG, S)
    np.testing.assert_allclose(pen.B[n:], expected, rtol=0, atol=1e-8 * np.abs(expected).max())


@pytest.mark.parametrize("formulation", ["penalty", "canonical"])
def test_constraint_modes_tend_to_the_penalty_roots(formulation):
    """The 2m constraint eigenvalues approach the roots of s^2 + 2 mu Omega s + Omega^2 like
    1/alpha (the constraint violation obeys that equation as alpha grows)."""
    roots = np.roots([1.0, 2 * MU * OMEGA, OMEGA**2])
    distances = []
    for alpha in (1e4, 1e6):
        model = pinlin.linearize(URDF_DIR / "four_bar.toml", formulation=formulation,
                                 alpha=alpha, mu=MU, omega=OMEGA)
        lam = np.linalg.eigvals(model.A)
        m = model.G.shape[0]
        near = [np.sort(np.abs(lam - r))[:m] for r in roots]  # m modes at each root
        distances.append(max(float(d.max()) for d in near) / OMEGA)
    assert distances[1] < 1e-4
    assert distances[1] < 3e-2 * distances[0]  # 1/alpha: x 1e-2 for alpha x 1e2


def _reassembled(scene: pinlin.Scene, op, z: np.ndarray, dz: np.ndarray) -> np.ndarray:
    system = scene.system
    step = np.zeros(system.nv)
    step[z] = dz
    q = assemble(system, pin.integrate(system.model, op.q, step), z)
    assert np.abs(_loop_residual(scene, q)).max() < 1e-11
    return q


def _outputs(scene: pinlin.Scene, q: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """Position outputs ``names`` at q: 'p:<frame>[x|y|z]' [m] and 'q:<1-DoF joint>'."""
    system = scene.system
    model = system.model
    data = model.createData()
    out = []
    for name in names:
        kind, _, what = name.partition(":")
        if kind == "p":
            frame, axis = what[:-3], "xyz".index(what[-2])
            out.append(_frame_position(model, data, q, frame)[axis])
        else:
            assert kind == "q"
            out.append(q[system.joints[what].idx_q])
    return np.array(out)


@pytest.mark.parametrize("name", ["four_bar", "delta"])
def test_independent_outputs_follow_the_mechanism_motion(name):
    """C of the independent model: the derivative of the frame and joint outputs along the
    mechanism's own motion (z moved, the loops re-assembled), dependent joints included."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    model = pinlin.linearize(scene)
    op = model.operating_point
    system = scene.system
    z = np.array([system.coordinate_names.index(c) for c in model.info["independent"]])
    rows = [k for k, o in enumerate(model.output_names) if not o.startswith("v:")]
    names = tuple(model.output_names[k] for k in rows)
    expected = np.zeros((len(rows), len(z)))
    for k in range(len(z)):
        e = np.zeros(len(z))
        e[k] = H
        expected[:, k] = (_outputs(scene, _reassembled(scene, op, z, e), names)
                          - _outputs(scene, _reassembled(scene, op, z, -e), names)) / (2 * H)
    got = model.C[rows][:, :len(z)]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-7 * np.abs(expected).max())
    # Outputs on dependent joints move with z: a C that ignored them would be zero there.
    dependent = [k for k, n in enumerate(names) if n.startswith("q:")
                 and n[2:] not in model.info["independent"]]
    assert all(np.abs(expected[k]).max() > 1e-3 for k in dependent)
    frames = [k for k, n in enumerate(names) if n.startswith("p:")]
    np.testing.assert_allclose(op.y[rows][frames], _outputs(scene, op.q, names)[frames],
                               atol=1e-12)


def test_penalty_outputs_move_with_each_coordinate():
    """C of the penalty model maps every dependent coordinate alone (no re-assembly)."""
    scene = pinlin.Scene.load(URDF_DIR / "four_bar.toml")
    model = pinlin.linearize(scene, formulation="penalty")
    rows = [k for k, o in enumerate(model.output_names) if not o.startswith("v:")]
    names = tuple(model.output_names[k] for k in rows)
    expected = _central(lambda q: _outputs(scene, q, names), model.operating_point.q,
                        scene.system.model)
    nv = scene.system.nv
    np.testing.assert_allclose(model.C[rows][:, :nv], expected, rtol=0,
                               atol=1e-8 * np.abs(expected).max())


@pytest.mark.parametrize("name", ["four_bar", "five_bar"])
def test_reduced_input_matrix_matches_constrained_forward_dynamics(name):
    """B_z = d z''/d u from Pinocchio's own constrained forward dynamics (proximal solver, its
    own loop Jacobians) at q0: linear in u, so the difference is exact to rounding."""
    scene = pinlin.Scene.load(URDF_DIR / f"{name}.toml")
    system = scene.system
    model = pinlin.linearize(scene)
    op = model.operating_point
    z = np.array([system.coordinate_names.index(c) for c in model.info["independent"]])
    pm = system.model
    contacts = pin.StdVec_RigidConstraintModel()
    for loop in scene.loops:
        f1, f2 = pm.frames[pm.getFrameId(loop.frame1)], pm.frames[pm.getFrameId(loop.frame2)]
        contacts.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, pm, f1.parentJoint,
                                                 f1.placement, f2.parentJoint, f2.placement,
                                                 pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
    datas = pin.StdVec_RigidConstraintData()
    for c in contacts:
        datas.append(c.createData())
    pd = pm.createData()
    pin.initConstraintDynamics(pm, pd, contacts, datas)
    prox = pin.ProximalSettings(1e-14, 1e-8, 200)
    S = system.input_matrix

    def zdd(u: np.ndarray) -> np.ndarray:
        tau = S @ u + system.spring_torque(op.q)
        return pin.constraintDynamics(pm, pd, op.q, np.zeros(system.nv), tau, contacts, datas,
                                      prox)[z].copy()

    du = 1e-2
    expected = np.array([(zdd(op.u + du * e) - zdd(op.u - du * e)) / (2 * du)
                         for e in np.eye(len(op.u))]).T
    np.testing.assert_allclose(model.B[len(z):], expected, rtol=0,
                               atol=1e-6 * np.abs(expected).max())
    assert np.abs(model.B[:len(z)]).max() == 0.0
