"""Standing robots: floating bases held by contacts with the world (scene ``[[contacts]]``).

Expected values come from outside the code under test:

- closed forms for a rigid box on a floating base (urdf/standing_box.urdf, its numbers written
  here again): on a point contact a spherical inverted pendulum, on two points of a blade a
  hinged inverted pendulum, welded nothing at all;
- the fixed-base four-bar (itself checked against a single-coordinate model) equals the same
  four-bar on a floating base whose ground link is welded to the world;
- Pinocchio alone: the total mass (pin.computeTotalMass), the contact Jacobians
  (getFrameJacobian), the statics g(q0) = S u0 + J^T lam, and the constrained forward dynamics
  (pin.constraintDynamics with RigidConstraintModels to the universe) differenced on the
  mechanism with re-assembly;
- the penalty formulation's O(1/alpha) convergence to the independent one.
"""

from __future__ import annotations

import math
import tomllib
import warnings

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg as sla
from conftest import URDF_DIR
from statics_reference import radius_of_gyration, weighted_orthogonality

import pinlin
from pinlin.assembly import assemble
from pinlin.cli import main
from pinlin.contacts import ContactWarning

G = 9.81
# urdf/standing_box.urdf: mass [kg], sides along x, y, z [m]; the link frame at the centre.
MASS, SIDE_X, SIDE_Y, HEIGHT = 2.0, 0.3, 0.2, 1.0
ARM = HEIGHT / 2  # contact (bottom face) to centre of mass [m]
I_XX = MASS * (SIDE_Y**2 + HEIGHT**2) / 12  # central inertia of a solid box [kg*m^2]
I_YY = MASS * (SIDE_X**2 + HEIGHT**2) / 12


def _tilt_rate(inertia: float) -> float:
    """Inverted pendulum about a horizontal axis through the contact: (I_cm + m l^2) th'' =
    m g l th, so lam = +-sqrt(m g l / (I_cm + m l^2)) [1/s]."""
    return math.sqrt(MASS * G * ARM / (inertia + MASS * ARM**2))


def _box(contacts: list[dict], **q) -> pinlin.Scene:
    spec = {"root_joint": {"position": [0.0, 0.0, ARM], "rpy": [0.0, 0.0, 0.0]}}
    spec["root_joint"].update(q)
    return pinlin.Scene.from_dict({
        "name": "box", "urdf": str(URDF_DIR / "standing_box.urdf"), "base": "free",
        "effects": {"gravity": [0.0, 0.0, -G]}, "contacts": contacts,
        "operating_point": {"q": spec}})


def _scene(name: str) -> pinlin.Scene:
    return pinlin.Scene.load(URDF_DIR / f"{name}.toml")


# ---------------------------------------------------------------------------------------------
# The box: closed forms


@pytest.mark.parametrize("rpy", [(0.0, 0.0, 0.0), (0.0, 0.0, 0.7)])
def test_box_on_a_point_is_a_spherical_inverted_pendulum(rpy):
    """Tilts about x and y: +-sqrt(m g l / (I_cm + m l^2)) with each axis's own I_cm (the box
    is not square, so swapped axes would show); the spin about the vertical meets nothing: a
    rigid pair. A yawed base (an identity orientation hides frame mix-ups) changes nothing."""
    model = pinlin.linearize(_box([{"name": "tip", "frame": "bottom"}], rpy=list(rpy)))
    assert model.n_states == 2 * (6 - 3)
    modes = pinlin.modal(model)
    assert modes.rigid.sum() == 2
    spin = np.abs(modes.shapes[:, np.flatnonzero(modes.rigid)[0]])   # body z is vertical
    assert modes.coordinate_names[int(np.argmax(spin))] == "root_joint[5]"
    assert np.sort(spin)[-2] < 1e-12
    growing = np.sort(modes.eigenvalues[modes.eigenvalues.real > 0].real)
    expected = np.sort([_tilt_rate(I_XX), _tilt_rate(I_YY)])
    np.testing.assert_allclose(growing, expected, rtol=1e-10)   # measured: 3e-15
    assert np.abs(modes.eigenvalues.imag).max() == 0.0
    force, torque = model.operating_point.contact_forces["tip"]
    np.testing.assert_allclose(force, [0.0, 0.0, MASS * G], atol=1e-12)
    assert not np.any(torque)


def test_box_on_a_blade_is_a_hinged_inverted_pendulum():
    """Two point contacts at the ends of a blade along x under the centre: 6 rows, 5
    independent (their distance is rigid), one degree of freedom: the tilt about the blade,
    +-sqrt(m g l / (I_xx + m l^2)). By symmetry each point carries half the weight."""
    model = pinlin.linearize(_box([{"name": "front", "frame": "blade_front"},
                                   {"name": "back", "frame": "blade_back"}]))
    assert model.n_states == 2 and len(model.info["dropped_rows"]) == 1
    lam = np.sort(np.linalg.eigvals(model.A).real)
    np.testing.assert_allclose(lam, [-_tilt_rate(I_XX), _tilt_rate(I_XX)], rtol=1e-10)
    forces = model.operating_point.contact_forces
    for name in ("front", "back"):
        np.testing.assert_allclose(forces[name][0], [0.0, 0.0, MASS * G / 2], atol=1e-12)


@pytest.mark.parametrize("frames", [("blade_front", "blade_back"),
                                    ("box", "blade_front", "blade_back")])
def test_redundant_point_contacts_share_the_weight_least_norm(frames):
    """Points in one vertical plane through the centre of mass hold the box redundantly: the
    least-norm forces minimize sum |f_i|^2 under the balance A f = (0, 0, m g, 0, 0, 0); the
    equal split f_i = (0, 0, m g / n) balances (the points' x are symmetric about the centre
    of mass) and is m g / n times the force row of A, so lies in A's row space: it is the
    least-norm one. pinlin splits over every row, the redundant ones included."""
    model = pinlin.linearize(_box([{"name": f, "frame": f} for f in frames]))
    forces = model.operating_point.contact_forces
    for f in frames:
        np.testing.assert_allclose(forces[f][0], [0.0, 0.0, MASS * G / len(frames)], rtol=0,
                                   atol=1e-12)
    assert any("not unique" in n and "least-norm" in n for n in model.operating_point.notes)


def test_welded_box_has_no_state_and_nothing_breaks(capfd, tmp_path):
    """A weld holds all six base coordinates: a model with zero states, in every formulation
    (penalty and canonical keep the 12 states of the dependent coordinates, all constraint
    modes), modal analysis and printing included; the weld carries the weight, no torque."""
    scene = _box([{"name": "foot", "frame": "bottom", "type": "weld"}])
    model = pinlin.linearize(scene)
    assert model.A.shape == (0, 0) and model.B.shape == (0, 0) and model.n_states == 0
    modes = pinlin.modal(model)
    assert modes.eigenvalues.size == 0 and "0 eigenvalues" in str(modes)
    force, torque = model.operating_point.contact_forces["foot"]
    np.testing.assert_allclose(force, [0.0, 0.0, MASS * G], atol=1e-12)
    np.testing.assert_allclose(torque, 0.0, atol=1e-12)
    for formulation in ("penalty", "canonical"):
        other = pinlin.linearize(scene, formulation=formulation)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", pinlin.AccuracyWarning)  # defective mu = 1 roots
            assert pinlin.modal(other).constraint.all()
    path = tmp_path / "welded.toml"
    path.write_text(f'urdf = "{URDF_DIR / "standing_box.urdf"}"\nbase = "free"\n'
                    '[effects]\ngravity = true\n'
                    '[[contacts]]\nname = "foot"\nframe = "bottom"\ntype = "weld"\n'
                    '[operating_point]\nq = { root_joint = { position = [0.0, 0.0, 0.5] } }\n')
    assert main(["linearize", str(path), "--out", str(tmp_path / "welded.npz")]) == 0
    out = capfd.readouterr().out
    assert "contact 'foot': force [0, 0, 19.62] N" in out
    assert pinlin.LinearModel.load(tmp_path / "welded.npz").n_states == 0
    # MuJoCo with the weld as a stiff equality: its 12 eigenvalues are all soft modes.
    assert main(["validate", str(path), "--out-dir", str(tmp_path / "v")]) == 0
    report = (tmp_path / "v" / "welded.md").read_text()
    assert "**pass**" in report and "no states" in report and "12 eigenvalues" in report


def test_contacts_anchor_where_the_configuration_puts_the_frame():
    """``linearize(q=...)`` anchors the contacts where that configuration puts their frames
    (here the box moved and yawed): the same pendulum, the anchor at the moved bottom centre
    (the hook an exporter reads), the scene's own anchor untouched."""
    scene = _box([{"name": "tip", "frame": "bottom"}])
    q = np.concatenate([[1.0, -2.0, ARM], pin.Quaternion(pin.rpy.rpyToMatrix(0, 0, 1.2))
                        .coeffs()])
    model = pinlin.linearize(scene, q=q)
    np.testing.assert_allclose(model.operating_point.q, q, atol=1e-15)
    growing = np.sort(np.linalg.eigvals(model.A).real)[-2:]
    np.testing.assert_allclose(growing, np.sort([_tilt_rate(I_XX), _tilt_rate(I_YY)]),
                               rtol=1e-10)
    contact = scene.system.anchored_at(q).constraints.contacts[0]
    np.testing.assert_allclose(contact.position, [1.0, -2.0, 0.0], atol=1e-15)
    assert contact.frame == "bottom" and contact.type == "point" and list(contact.rows) == [0, 1, 2]
    np.testing.assert_allclose(scene.system.constraints.contacts[0].position, [0, 0, 0],
                               atol=1e-15)


def test_point_contact_that_pulls_warns(tmp_path):
    """Blade points at x = 0.15 m and 0.45 m (a toe added ahead of the box), the centre of mass
    at x = 0 behind both: moments about the centre give F_toe = -m g 0.15 / 0.30 = -9.81 N (a
    pull) and F_front = 29.43 N. Both at the same height, so no internal force along the line
    between them can change that split."""
    urdf = tmp_path / "box_toe.urdf"
    urdf.write_text((URDF_DIR / "standing_box.urdf").read_text().replace(
        "</robot>", '<link name="toe"/><joint name="toe_fixed" type="fixed"><parent link="box"/>'
                    '<child link="toe"/><origin xyz="0.45 0 -0.5"/></joint></robot>'))
    scene = pinlin.Scene.from_dict({
        "urdf": str(urdf), "base": "free", "effects": {"gravity": [0.0, 0.0, -G]},
        "contacts": [{"name": "front", "frame": "blade_front"}, {"name": "toe", "frame": "toe"}],
        "operating_point": {"q": {"root_joint": {"position": [0.0, 0.0, ARM]}}}})
    with pytest.warns(ContactWarning, match="'toe' pulls the robot") as caught:
        model = pinlin.linearize(scene)
    pulls = [w.message for w in caught if isinstance(w.message, ContactWarning)]
    assert [w.contact for w in pulls] == ["toe"]
    assert pulls[0].normal_force == pytest.approx(-MASS * G * 0.15 / 0.30, rel=1e-12)
    forces = model.operating_point.contact_forces
    assert forces["front"][0][2] == pytest.approx(MASS * G * 0.45 / 0.30, rel=1e-12)
    assert any("PULLS" in n for n in model.operating_point.notes)


# ---------------------------------------------------------------------------------------------
# A floating base welded to the world is a fixed base


def test_welded_floating_four_bar_equals_the_fixed_four_bar():
    """The bundled four-bar on a floating base, its ground link welded where it is, plus its
    loop (assembled with the weld held): the same u0, loop forces, eigenvalues, B and C as the
    fixed-base four-bar; the weld carries the weight m g."""
    data = tomllib.loads((URDF_DIR / "four_bar.toml").read_text())
    data["urdf"] = str(URDF_DIR / data["urdf"])
    fixed = pinlin.linearize(pinlin.Scene.from_dict(data))
    data.update(base="free", contacts=[{"name": "ground", "frame": "ground", "type": "weld"}])
    scene = pinlin.Scene.from_dict(data)
    free = pinlin.linearize(scene)
    assert free.state_names == fixed.state_names == ("q:crank", "v:crank")
    for a, b in ((free.A, fixed.A), (free.B, fixed.B), (free.C, fixed.C)):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
    op, ref = free.operating_point, fixed.operating_point
    np.testing.assert_allclose(op.u, ref.u, rtol=1e-12)
    np.testing.assert_allclose(op.lam[:3], ref.lam, rtol=1e-10, atol=1e-12)
    mass = pin.computeTotalMass(scene.system.model)
    assert op.contact_forces["ground"][0][2] == pytest.approx(mass * G, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# Standing robots against Pinocchio


def _contact_jacobian(system, q: np.ndarray) -> np.ndarray:
    """The contacts' rows from Pinocchio's LOCAL_WORLD_ALIGNED frame Jacobians (3 rows for a
    point, 6 for a weld), in scene order."""
    model = system.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    rows = []
    for c in system.scene.contacts:
        J = pin.getFrameJacobian(model, data, model.getFrameId(c.frame),
                                 pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        rows.append(J[:3] if c.type == "point" else J)
    return np.vstack(rows)


def _contact_lam(system, op) -> np.ndarray:
    """lam of the contacts stacked as the rows of :func:`_contact_jacobian`."""
    out = []
    for c in system.scene.contacts:
        force, torque = op.contact_forces[c.name]
        out.append(force if c.type == "point" else np.concatenate([force, torque]))
    return np.concatenate(out)


STANDING = ["talos_standing", "solo12_standing", "g1_standing"]


@pytest.mark.parametrize("name", STANDING)
def test_standing_robot_statics(name):
    """The contacts carry the weight (vertical forces sum to m g, m from Pinocchio, to 1e-9;
    measured 2e-15); gravity is balanced, g(q0) = S u0 + J^T lam with Pinocchio's Jacobians;
    the split is one of a family whose dimension the note states, and pinlin's is its
    least-norm member with the norm in N*m (forces times the robot's radius of gyration L,
    from the bodies' inertias here; torques as they are): W x orthogonal to W times the
    family's directions (an SVD here); the independent model has 2 (nv - rank J) states."""
    scene = _scene(name)
    system = scene.system
    model = pinlin.linearize(scene)
    op = model.operating_point
    pm = system.model
    weight = pin.computeTotalMass(pm) * G
    vertical = sum(force[2] for force, _ in op.contact_forces.values())
    assert abs(vertical - weight) <= 1e-9 * weight
    J = _contact_jacobian(system, op.q)
    lam = _contact_lam(system, op)
    gravity = pin.computeGeneralizedGravity(pm, pm.createData(), op.q)
    SJ = np.hstack([system.input_matrix, J.T])
    x = np.concatenate([op.u, lam])
    np.testing.assert_allclose(SJ @ x, gravity, rtol=0, atol=1e-9 * np.abs(gravity).max())
    rank = np.linalg.matrix_rank(J)
    assert model.n_states == 2 * (system.nv - rank)
    family = sla.null_space(SJ)
    assert any(f"a family of {family.shape[1]} dimensions" in n for n in op.notes)
    assert not any(j.kind.startswith("JointModelP") for j in system.joints.values())
    forces = np.concatenate([[True, True, True] if c.type == "point" else [True] * 3 + [False] * 3
                             for c in system.scene.contacts])
    L = radius_of_gyration(pm, op.q)
    weights = np.concatenate([np.ones(len(op.u)), np.where(forces, L, 1.0)])
    # rounding: |W x| eps per entry of SJ's SVD, conditioning of the family aside: 1e-9
    assert weighted_orthogonality(family, x, weights) <= 1e-9
    assert any(f"the radius of gyration, {L:.4g} m" in n for n in op.notes)
    assert all(f[2] > 0 for f, _ in op.contact_forces.values())   # every foot pushes


@pytest.mark.parametrize("name", ["talos_standing", "solo12_standing"])
def test_penalty_converges_to_independent_on_standing_robots(name):
    """Physical eigenvalues of the penalty model approach the independent model's like 1/alpha
    over alpha = 1e3..1e7 (fitted slope measured: -1.045 Talos, -0.985 solo12)."""
    scene = _scene(name)
    ref = np.linalg.eigvals(pinlin.linearize(scene).A)
    alphas = np.array([1e3, 1e4, 1e5, 1e6, 1e7])
    errors = []
    from scipy.optimize import linear_sum_assignment

    for alpha in alphas:
        modes = pinlin.modal(pinlin.linearize(scene, formulation="penalty", alpha=alpha))
        lam = modes.eigenvalues[~modes.constraint]
        assert lam.size == ref.size
        cost = np.abs(lam[:, None] - ref[None, :])
        rows, cols = linear_sum_assignment(cost)
        errors.append(cost[rows, cols].max() / np.abs(ref).max())
    slope = np.polyfit(np.log10(alphas), np.log10(errors), 1)[0]
    assert -1.1 < slope < -0.9, (slope, errors)


@pytest.mark.parametrize("alpha", [1e5, None])
@pytest.mark.parametrize("name", STANDING)
def test_canonical_model_of_standing_robots(name, alpha):
    """The canonical model keeps the penalty model's spectrum (its own check: gap <= 1e-6, no
    growth invented beyond rounding). A standing robot's undamped modes get only the
    penalty's O(1/alpha) damping, while rounding in K_p moves their real parts by
    O(eps alpha): at the default alpha = 1e7 G1's canonical model shows a growth of ~1e-12
    1/s, far below eps |A|_F (the backward error of its eigenvalues, 2.4e-6 1/s), so it is
    rounding and the model is returned. (At alpha = 1e5 the penalty itself is soft for a
    humanoid's mass: its own error bound warns, which is not what this test is about.)"""
    with warnings.catch_warnings():
        warnings.simplefilter("error", pinlin.AccuracyWarning)
        warnings.filterwarnings("ignore", "model '.*': the penalty alpha",
                                pinlin.AccuracyWarning)
        model = pinlin.linearize(_scene(name), formulation="canonical", alpha=alpha)
    assert model.n_states == 2 * _scene(name).system.nv
    assert model.info["condition"]["canonical_vs_penalty_spectrum"] < 1e-6


def _pinocchio_contacts(system, q: np.ndarray):
    """RigidConstraintModels of the scene's contacts to the universe, anchored at the contact
    frames' placements at q (Pinocchio's forward kinematics), and their datas."""
    pm = system.model
    pd = pm.createData()
    pin.framesForwardKinematics(pm, pd, q)
    models = pin.StdVec_RigidConstraintModel()
    for c in system.scene.contacts:
        fid = pm.getFrameId(c.frame)
        frame = pm.frames[fid]
        kind = pin.ContactType.CONTACT_3D if c.type == "point" else pin.ContactType.CONTACT_6D
        models.append(pin.RigidConstraintModel(kind, pm, frame.parentJoint, frame.placement, 0,
                                               pd.oMf[fid].copy(),
                                               pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
    datas = pin.StdVec_RigidConstraintData()
    for m in models:
        datas.append(m.createData())
    pin.initConstraintDynamics(pm, pd, models, datas)
    return models, datas, pd


@pytest.mark.parametrize("case", ["talos_standing", "solo12_standing", "g1_standing",
                                  "standing_box", "blade"])
def test_independent_model_matches_constraint_dynamics(case):
    """A of the independent model against central differences (h = 1e-5) of Pinocchio's
    constraintDynamics with the contacts to the universe, at configurations re-assembled
    around q0 with z held, inputs at u0; B against differences in u (linear: exact to
    rounding). Tolerance 1e-7 of the largest entry: the differences' truncation (h^2 times the
    third derivative) and rounding (eps |a| / h) are below 1e-9 here (measured 1.7e-11 box,
    1.2e-10 Talos, 5e-10 solo12, 2e-10 g1). The box on its blade has a redundant row, where
    the proximal solver's mu = 1e-8 keeps Pinocchio's solve finite (PITFALLS)."""
    scene = (_box([{"name": "front", "frame": "blade_front"},
                   {"name": "back", "frame": "blade_back"}]) if case == "blade"
             else _scene(case))
    system = scene.system
    model = pinlin.linearize(scene)
    op = model.operating_point
    z = np.array([system.coordinate_names.index(n) for n in model.info["independent"]])
    pm = system.model
    contacts, datas, pd = _pinocchio_contacts(system, op.q)
    for c, anchored in zip(contacts, system.constraints.contacts, strict=True):
        assert anchored.placement.isApprox(c.joint2_placement, 1e-12)   # the exporter's hook
    prox = pin.ProximalSettings(1e-14, 1e-8, 200)
    S = system.input_matrix

    def zdd(dz: np.ndarray, du: np.ndarray | None = None) -> np.ndarray:
        step = np.zeros(system.nv)
        step[z] = dz
        q = assemble(system, pin.integrate(pm, op.q, step), z) if dz.any() else op.q
        tau = S @ (op.u if du is None else op.u + du)
        return pin.constraintDynamics(pm, pd, q, np.zeros(system.nv), tau, contacts, datas,
                                      prox)[z].copy()

    nz, h = len(z), 1e-5
    assert np.abs(zdd(np.zeros(nz))).max() < 1e-9   # u0 and the contacts hold q0
    fd = np.array([(zdd(h * e) - zdd(-h * e)) / (2 * h) for e in np.eye(nz)]).T
    np.testing.assert_allclose(model.A[nz:, :nz], fd, rtol=0, atol=1e-7 * np.abs(fd).max())
    if S.shape[1]:
        zero = np.zeros(nz)
        fd_u = np.array([(zdd(zero, e) - zdd(zero, -e)) / 2.0 for e in np.eye(S.shape[1])]).T
        np.testing.assert_allclose(model.B[nz:], fd_u, rtol=0,
                                   atol=1e-8 * np.abs(fd_u).max())


def test_user_split_with_solve_forces():
    """solve = "forces": the inputs are the user's (here another member of solo12's family of
    balancing [u; lam], built from Pinocchio's Jacobians and an SVD) and the contact forces
    follow, uniquely: those of that member. Inputs that cannot balance (all zero) are refused
    with the force left over."""
    scene = _scene("solo12_standing")
    system = scene.system
    op = pinlin.linearize(scene).operating_point
    J = _contact_jacobian(system, op.q)
    SJ = np.hstack([system.input_matrix, J.T])
    family = sla.null_space(SJ)
    x = np.concatenate([op.u, _contact_lam(system, op)]) + 2.0 * family[:, 0] - family[:, 1]
    nu = len(op.u)
    names = [n[2:] for n in system.input_names]
    data = tomllib.loads((URDF_DIR / "solo12_standing.toml").read_text())
    data["operating_point"] = {"solve": "forces",
                               "u": {n: float(v) for n, v in zip(names, x[:nu], strict=True)}}
    split = pinlin.linearize(pinlin.Scene.from_dict(data))
    np.testing.assert_allclose(split.operating_point.u, x[:nu], rtol=0, atol=0)
    np.testing.assert_allclose(_contact_lam(system, split.operating_point), x[nu:], rtol=0,
                               atol=1e-9 * np.abs(x).max())
    assert not any("not unique" in n for n in split.operating_point.notes)
    data["operating_point"] = {"solve": "forces"}
    with pytest.raises(pinlin.EquilibriumError, match="is left over.*cannot balance"):
        pinlin.linearize(pinlin.Scene.from_dict(data))


def test_straight_knees_warn_with_a_condition_estimate():
    """Talos with every leg joint at zero (knees straight), the base lowered so the feet are
    where that posture puts them: each foot's Jacobian with respect to its leg's joints is
    singular. pinlin warns for both feet, with the condition number, and returns a finite
    model in every formulation (the constraint Jacobian with the base is still full rank)."""
    data = tomllib.loads((URDF_DIR / "talos_standing.toml").read_text())
    legs = {f"leg_{side}_{i}_joint": 0.0 for side in ("left", "right") for i in range(1, 7)}
    data["operating_point"] = {"q": {"root_joint": {"position": [0.0, 0.0, 1.08]}, **legs}}
    scene = pinlin.Scene.from_dict(data)
    for formulation in ("independent", "penalty", "canonical"):
        with pytest.warns(pinlin.AccuracyWarning, match="straight knee") as caught:
            model = pinlin.linearize(scene, formulation=formulation)
        limbs = [w.message for w in caught if "straight knee" in str(w.message)]
        assert {str(w).split("'")[3] for w in limbs} == {"left_foot", "right_foot"}
        assert all(w.condition > 1e12 for w in limbs)
        assert np.all(np.isfinite(model.A)) and np.all(np.isfinite(model.B))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", pinlin.AccuracyWarning)
            assert np.all(np.isfinite(pinlin.modal(model).eigenvalues))
    assert model.info["condition"]["contact_limbs"]["left_foot"] > 1e12


def test_bundled_standing_scenes_name_their_contacts(capfd):
    """The command line prints each contact's force and the weight balance."""
    assert main(["linearize", "solo12_standing"]) == 0
    out = capfd.readouterr().out
    assert "total vertical 24.525 N against the weight m g = 24.525 N" in out
    for foot in ("FL", "FR", "HL", "HR"):
        assert f"contact '{foot}': force" in out and f"lam[contact:{foot}.z]" in out


def test_contact_forces_survive_saving(tmp_path):
    model = pinlin.linearize(_box([{"name": "tip", "frame": "bottom"}]))
    path = model.save(tmp_path / "box.npz")
    back = pinlin.LinearModel.load(path).operating_point.contact_forces
    np.testing.assert_array_equal(back["tip"][0], model.operating_point.contact_forces["tip"][0])


# ---------------------------------------------------------------------------------------------
# MuJoCo: contacts exported as equalities to the world


def _mujoco_rows(ms, system, q, tau):
    """MuJoCo's equality residual, dense constraint Jacobian and bias - applied force at q."""
    import mujoco

    from pinlin import mjcf

    mjcf.set_state(ms, system, q, np.zeros(system.nv), tau)
    m, d = ms.model, ms.data
    mujoco.mj_forward(m, d)
    jac = np.zeros((d.nefc, m.nv))
    if mujoco.mj_isSparse(m):
        mujoco.mju_sparse2dense(jac, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
    else:
        jac[:] = d.efc_J[:d.nefc * m.nv].reshape(d.nefc, m.nv)
    return d.efc_pos[:d.nefc].copy(), jac, d.qfrc_bias - d.qfrc_applied


def _frames_scene(name: str) -> pinlin.Scene:
    """A bundled standing scene, or the box held at frames that are no URDF link: a fixed
    joint's frame (at the bottom face) and a joint's frame (the free flyer's, at the centre)."""
    if name == "box_joint_frames":
        return _box([{"name": "tip", "frame": "bottom_fixed"},
                     {"name": "centre", "frame": "root_joint"}])
    return _scene(name)


@pytest.mark.parametrize("name", ["standing_box", "solo12_standing", "talos_standing",
                                  "box_joint_frames"])
def test_exported_contacts_hold_the_frames_where_pinlin_anchors_them(name):
    """One connect (point) or weld equality per contact, from a site on the frame's body to a
    world site at the anchor: at a configuration away from q0 MuJoCo's residual equals
    pinlin's Phi(q) row by row: the world position difference exactly, a weld's rotation as
    MuJoCo writes it, the vector part of the error quaternion in the frame's own axes,
    sin(|r| / 2) R^T r / |r| for pinlin's world r = log3(R1 R2^T) and the anchor's R (both to
    rounding of O(1) numbers: 1e-12)."""
    from pinlin import mjcf

    scene = _frames_scene(name)
    system = scene.system
    q0 = pinlin.operating_point(scene).q
    ms = mjcf.build(system, dt=1e-4)
    contacts = system.constraints.contacts
    assert ms.model.neq == len(contacts)
    q = pin.integrate(system.model, q0, 0.1 * np.random.default_rng(7).standard_normal(system.nv))
    mj, _, _ = _mujoco_rows(ms, system, q, np.zeros(system.nv))
    phi = system.constraints.residual(q)
    assert mj.shape == phi.shape and np.abs(phi).max() > 1e-2   # really moved away
    for contact in contacts:
        rows = np.array(contact.rows)
        np.testing.assert_allclose(mj[rows[:3]], phi[rows[:3]], rtol=0, atol=1e-12)
        if contact.type == "weld":
            r = phi[rows[3:]]
            angle = np.linalg.norm(r)
            local = contact.rotation.T @ r  # = R1^T r: the axis of R1 R2^T is its own image
            np.testing.assert_allclose(mj[rows[3:]], math.sin(angle / 2) * local / angle,
                                       rtol=0, atol=1e-12)
    at_q0, _, _ = _mujoco_rows(ms, system, q0, np.zeros(system.nv))
    assert np.abs(at_q0).max() <= 1e-12


@pytest.mark.parametrize("name", ["standing_box", "solo12_standing", "talos_standing",
                                  "g1_standing"])
def test_mujoco_confirms_the_standing_statics(name):
    """pinlin's u0 holds the robot in MuJoCo's model: some contact forces f balance MuJoCo's
    own bias force against the applied S u0 through MuJoCo's own constraint Jacobian,
    J^T f = c(q0) - S u0. The least-squares residual is rounding, bounded by
    10 m cond(J) eps relative (m rows); the box's single contact carries m g upwards."""
    from pinlin import mjcf

    scene = _scene(name)
    system = scene.system
    op = pinlin.operating_point(scene)
    ms = mjcf.build(system, dt=1e-4)
    _, jac, rhs = _mujoco_rows(ms, system, op.q, system.input_matrix @ op.u)
    f, *_ = np.linalg.lstsq(jac.T, rhs, rcond=None)
    bound = 10 * jac.shape[0] * np.linalg.cond(jac) * np.finfo(float).eps
    assert np.abs(jac.T @ f - rhs).max() <= bound * np.abs(rhs).max()
    if name == "standing_box":
        np.testing.assert_allclose(f, [0.0, 0.0, MASS * G], rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["standing_box", "solo12_standing"])
def test_standing_scenes_validate_against_mujoco(name):
    """Eigenvalues against MuJoCo's model with the contacts as stiff equalities to the world
    (the soft-constraint modes set aside, 2 per contact row)."""
    from pinlin.validate import validate

    res = validate(_scene(name), name=name)
    assert res.passed, res.reason
    rows = _scene(name).system.constraints.size
    assert len(res.set_aside) == 2 * rows


# ---------------------------------------------------------------------------------------------
# Bad input

BOX_URDF = {"robot__urdf": (URDF_DIR / "standing_box.urdf").read_text()}
BOX = ('urdf = "robot.urdf"\nbase = "free"\n[effects]\ngravity = true\n'
       '[operating_point]\nq = { root_joint = { position = [0.0, 0.0, 0.5] } }\n')
PENDULUM_URDF = {"robot__urdf": (URDF_DIR / "pendulum.urdf").read_text()}

BAD_CONTACTS = {
    "unknown_frame": (BOX + '[[contacts]]\nname = "tip"\nframe = "botom"\n', BOX_URDF,
                      pinlin.UnknownNameError, "'botom' is not a frame of the robot"),
    "bad_type": (BOX + '[[contacts]]\nname = "tip"\nframe = "bottom"\ntype = "hinge"\n',
                 BOX_URDF, pinlin.SceneError,
                 "field 'contacts[0].type': expected one of 'point', 'weld'"),
    "duplicate_name": (BOX + '[[contacts]]\nname = "tip"\nframe = "bottom"\n'
                       '[[contacts]]\nname = "tip"\nframe = "blade_front"\n', BOX_URDF,
                       pinlin.SceneError, "field 'contacts[1].name': name 'tip' is already"),
    "name_of_a_loop": ('urdf = "robot.urdf"\n[[loops]]\nname = "tip"\nframe1 = "bob"\n'
                       'frame2 = "base"\n[[contacts]]\nname = "tip"\nframe = "tip"\n',
                       PENDULUM_URDF, pinlin.SceneError,
                       "name 'tip' is already a loop's (loops[0]) name"),
    "on_the_universe": ('urdf = "robot.urdf"\n[[contacts]]\nname = "floor"\nframe = "base"\n',
                        PENDULUM_URDF, pinlin.SceneError,
                        "field 'contacts[0].frame': frame 'base' is fixed to the world"),
    "without_frame": (BOX + '[[contacts]]\nname = "tip"\n', BOX_URDF, pinlin.SceneError,
                      "field 'contacts[0].frame': missing"),
    "unknown_key": (BOX + '[[contacts]]\nframe = "bottom"\nframe2 = "x"\n', BOX_URDF,
                    pinlin.SceneError, "field 'contacts[0].frame2': unknown key"),
    "not_an_array": (BOX.replace("[effects]", 'contacts = "bottom"\n[effects]'), BOX_URDF,
                     pinlin.SceneError, "expected an array of tables ([[contacts]])"),
    "adds_nothing": (BOX + '[[contacts]]\nname = "a"\nframe = "bottom"\n'
                     '[[contacts]]\nname = "b"\nframe = "bottom"\n', BOX_URDF,
                     pinlin.SceneError, "contact 'b' adds no independent constraint"),
}


@pytest.mark.parametrize("case", sorted(BAD_CONTACTS))
def test_bad_contacts_give_one_line_and_exit_2(case, write_scene, capfd, tmp_path):
    text, files, exception, fragment = BAD_CONTACTS[case]
    path = write_scene(text, **files)
    with pytest.raises(exception) as info:
        pinlin.linearize(pinlin.Scene.load(path))
    assert fragment in str(info.value)
    out_file = tmp_path / "never.npz"
    code = main(["linearize", str(path), "--out", str(out_file)])
    out, err = capfd.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("pinlin: error: ")
    assert fragment in err, err
    assert "Traceback" not in err and not out_file.exists()


TRI_URDF = """<?xml version="1.0"?><robot name="tri"><link name="base"/>{links}{joints}
<link name="tip"/><joint name="tipj" type="fixed"><parent link="l3"/><child link="tip"/>
<origin xyz="0.5 0 0"/></joint></robot>"""


@pytest.mark.parametrize("posture, warns", [((-0.5, 1.2, 0.9), False), ((-0.5, 0.0, 0.0), True)])
def test_planar_limb_warns_only_when_straight(tmp_path, posture, warns):
    """A planar 3R chain (axes along y) with its tip held: the contact's y row is zero at every
    posture (the limb cannot move the tip out of its plane), which made the limb condition
    infinite and warned "straight knee" at any posture. That row is structure, left out: bent,
    the in-plane 2 x 3 Jacobian has full rank (no warning); stretched straight, its rank
    drops (the warning stays)."""
    inertial = ('<inertial><origin xyz="0.25 0 0"/><mass value="1"/><inertia ixx="0.01" '
                'ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>')
    links = "".join(f'<link name="l{i}">{inertial}</link>' for i in (1, 2, 3))
    joints = "".join(
        f'<joint name="j{i}" type="revolute"><parent link="{"base" if i == 1 else f"l{i - 1}"}"/>'
        f'<child link="l{i}"/><origin xyz="{0 if i == 1 else 0.5} 0 0"/><axis xyz="0 1 0"/>'
        '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>' for i in (1, 2, 3))
    (tmp_path / "tri.urdf").write_text(TRI_URDF.format(links=links, joints=joints))
    q = ", ".join(f"j{i} = {a}" for i, a in zip((1, 2, 3), posture, strict=True))
    (tmp_path / "tri.toml").write_text(
        'urdf = "tri.urdf"\n[effects]\ngravity = [0.0, 0.0, -9.81]\n[[contacts]]\n'
        'name = "foot"\nframe = "tip"\ntype = "point"\n'
        f'[operating_point]\nq = {{ {q} }}\n[inputs]\nactuated = ["j1", "j2", "j3"]\n')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pinlin.linearize(str(tmp_path / "tri.toml"))
    limb = [w for w in caught if "singular posture" in str(w.message)]
    assert bool(limb) == warns


def _point_mass_arm(x0: float) -> str:
    """A 3R arm in the x-z plane, its base joint at (x0, 0, 0), links 0.4 m; its only mass a
    1 kg point on the second link (no radius of gyration)."""
    joint = ('<joint name="{0}" type="revolute"><parent link="{1}"/><child link="{2}"/>'
             '<origin xyz="{3} 0 0"/><axis xyz="0 -1 0"/>'
             '<limit lower="-9" upper="9" effort="100" velocity="10"/></joint>')
    return ('<robot name="arm3"><link name="world_link"/><link name="l1"/>'
            '<link name="l2"><inertial><origin xyz="0.2 0 0"/><mass value="1.0"/>'
            '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>'
            '<link name="l3"/><link name="tip"/>'
            + joint.format("j1", "world_link", "l1", x0) + joint.format("j2", "l1", "l2", 0.4)
            + joint.format("j3", "l2", "l3", 0.4)
            + '<joint name="tipj" type="fixed"><parent link="l3"/><child link="tip"/>'
              '<origin xyz="0.4 0 0"/></joint></robot>')


def test_a_point_mass_arm_splits_alike_wherever_it_stands(tmp_path):
    """The 3R arm, every joint driven, its tip held by a point contact: inputs and tip force
    are a family of 2 dimensions. Its mass is one point, so it has no radius of gyration:
    the length of the split's norm is then the spread of its joints and closure frames, which
    moves with the arm. Moved 10 m along x it must report the same split (the anchors' and
    the base's distance from the world origin had stood in: 2.1 m here, 22.1 m there, and
    the split changed by 20 %); positions at 10 m round to eps 10 m against the 0.4 m links:
    1e-12 relative."""
    ops = []
    for x0 in (0.0, 10.0):
        path = tmp_path / f"arm_{x0:g}.urdf"
        path.write_text(_point_mass_arm(x0))
        scene = pinlin.Scene.from_dict({
            "name": "arm3", "urdf": str(path), "effects": {"gravity": [0.0, 0.0, -G]},
            "contacts": [{"name": "tip", "frame": "tip", "type": "point"}],
            "operating_point": {"q": {"j1": 0.6, "j2": -0.9, "j3": -0.8},
                                "independent": ["j1"]},
            "inputs": {"actuated": "all"}})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", pinlin.AccuracyWarning)
            ops.append(pinlin.linearize(scene).operating_point)
    assert any("a family of 2 dimensions" in n and "spread of its joints" in n
               for n in ops[0].notes)
    np.testing.assert_allclose(ops[1].u, ops[0].u, rtol=0, atol=1e-12 * np.abs(ops[0].u).max())
    np.testing.assert_allclose(ops[1].lam, ops[0].lam, rtol=0,
                               atol=1e-12 * np.abs(ops[0].lam).max())


@pytest.mark.parametrize("name", ["solo12_standing", "g1_standing", "talos_standing", "blade"])
def test_a_standing_robot_keeps_its_states_under_another_machines_rounding(name):
    """A symmetric robot's legs give the partition's pivoted QR columns of equal norm, and
    rounding alone chose among them: Phi_q perturbed by 1e-14 relative (what another CPU or
    BLAS may round differently) gave 8 to 14 different sets of independent coordinates, so
    the states of a saved model or gain could change from machine to machine; the box on a
    blade dropped the x row of either end. Ties now go to the earlier coordinate or row: one
    partition under every perturbation, the model's own, with a well-conditioned Phi_d."""
    from pinlin.assembly import partition

    scene = (_box([{"name": "front", "frame": "blade_front"},
                   {"name": "back", "frame": "blade_back"}]) if name == "blade"
             else pinlin.Scene.resolve(name))
    model = pinlin.linearize(scene)
    q = model.operating_point.q
    system = scene.system.anchored_at(q)
    jac = system.constraints.jacobian(q)
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(20):
        part = partition(system, q, jac * (1.0 + 1e-14 * rng.standard_normal(jac.shape)))
        seen.add((tuple(system.coordinate_names[i] for i in part.independent), part.dropped))
        assert part.condition < 1e3
    assert seen == {(tuple(model.info["independent"]), tuple(model.info["dropped_rows"]))}
