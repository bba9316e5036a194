"""MuJoCo validation: the exported scene holds exactly the scene's effects, and pinlin's models
agree with MuJoCo's transition derivatives (an engine that shares none of pinlin's code)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin import mjcf
from pinlin.bench import check_scene
from pinlin.cli import main
from pinlin.validate import MATRIX_TOL, run, sanity, validate


@pytest.mark.parametrize("target", ["ur5", "solo12", "four_bar", "delta", "ur5_arm"])
def test_systems_pass(target):
    """Open chains (a floating base with a rotated base, a servoed arm with damping) and
    closed loops (set-aside soft-constraint modes) pass at the stated tolerances."""
    scene, _ = check_scene(target)
    res = validate(scene, name=target)
    assert res.passed, res.reason
    if scene.loops:
        assert res.matrix_error is None
        assert len(res.set_aside) == len(res.mujoco_eigs) - len(res.pinlin_eigs) > 0
        assert res.eig_error_raw > 10 * res.eig_error  # MuJoCo's constraint leak, removed
    else:
        assert res.matrix_error <= MATRIX_TOL
    assert res.eig_error <= 1e-6


def test_floating_base_rotation_is_not_the_identity():
    scene, _ = check_scene("solo12")
    q = scene.system.joints["root_joint"]
    quat = pinlin.linearize(scene).operating_point.q[q.idx_q + 3:q.idx_q + 7]
    assert abs(abs(quat[3]) - 1.0) > 1e-2


def _export(scene, tmp_path, name):
    out = tmp_path / f"{name}.xml"
    ms = mjcf.build(scene.system)
    out.write_text(ms.spec.to_xml())
    return out.read_text(), ms


def test_damping_changes_both_models_and_absent_effects_are_absent(tmp_path):
    base = {"effects": {"gravity": True}}
    plain = pinlin.Scene.from_robot("ur5", **base)
    damped = pinlin.Scene.from_robot("ur5", effects={"gravity": True,
                                                     "damping": {"elbow_joint": 3.0}})
    xml_plain, ms_plain = _export(plain, tmp_path, "plain")
    xml_damped, ms_damped = _export(damped, tmp_path, "damped")
    # Only what the scene names: no damping, friction loss, limits, contacts or equalities.
    joints = ET.fromstring(xml_plain).iter("joint")
    for joint in joints:
        assert "damping" not in joint.attrib and "frictionloss" not in joint.attrib
        assert joint.get("limited", "false") == "false"
    assert "<equality" not in xml_plain
    for geom in ET.fromstring(xml_plain).iter("geom"):  # visual only: no contacts, no mass
        assert (geom.get("contype"), geom.get("conaffinity"), geom.get("mass")) == ("0", "0", "0")
    flags = ET.fromstring(xml_plain).find("option/flag").attrib
    for flag in ("contact", "limit", "frictionloss", "equality"):
        assert flags[flag] == "disable"
    elbow_xml = next(j for j in ET.fromstring(xml_damped).iter("joint")
                     if j.get("name") == "elbow_joint")
    assert float(elbow_xml.get("damping").split()[0]) == 3.0
    m_plain, m_damped = pinlin.linearize(plain), pinlin.linearize(damped)
    A_plain = mjcf.continuous_state_matrix(ms_plain, plain.system, m_plain.operating_point)
    A_damped = mjcf.continuous_state_matrix(ms_damped, damped.system, m_damped.operating_point)
    nv = plain.system.nv
    elbow = plain.system.joints["elbow_joint"].idx_v
    assert m_plain.A[nv + elbow, nv + elbow] == 0.0
    assert m_damped.A[nv + elbow, nv + elbow] < -1.0          # pinlin's model changed
    assert abs(A_plain[nv + elbow, nv + elbow]) < 1e-8        # MuJoCo's did too
    assert A_damped[nv + elbow, nv + elbow] < -1.0
    np.testing.assert_allclose(A_damped, m_damped.A, atol=1e-7 * abs(m_damped.A).max())


def test_export_mjcf_command(tmp_path, capfd):
    out = tmp_path / "four_bar.xml"
    assert main(["export-mjcf", str(URDF_DIR / "four_bar.toml"), "-o", str(out)]) == 0
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.nv == 3 and model.neq == 1 and model.eq_type[0] == mujoco.mjtEq.mjEQ_CONNECT
    assert main(["export-mjcf", "four_bar", "-o", str(tmp_path / "x.txt")]) == 2
    assert "expected an .xml file" in capfd.readouterr().err


def test_sanity_mismatch_names_the_joint():
    scene = pinlin.Scene.from_robot("ur5")
    ms = mjcf.build(scene.system)
    jid = mujoco.mj_name2id(ms.model, mujoco.mjtObj.mjOBJ_JOINT, "wrist_2_joint")
    ms.model.dof_armature[ms.model.jnt_dofadr[jid]] = 0.5
    with pytest.raises(mjcf.MujocoError, match="mass matrix.*'wrist_2_joint'"):
        sanity(ms, scene.system, pinlin.linearize(scene).operating_point.q)


def test_validate_command_writes_reports_and_fails_on_mismatch(tmp_path, monkeypatch, capfd):
    assert main(["validate", "double_pendulum", "rotating_double_pendulum", "--out-dir",
                 str(tmp_path), "--no-progress"]) == 0
    summary = (tmp_path / "README.md").read_text()
    assert "| [double_pendulum](double_pendulum.md) | pass |" in summary
    assert "not expressible" in summary
    assert (tmp_path / "double_pendulum.png").exists()
    build = mjcf.build

    def heavier(system, **kw):  # a MuJoCo scene that is not the scene: must be caught
        ms = build(system, **kw)
        ms.model.body_mass[int(np.argmax(ms.model.body_mass))] *= 1.01
        return ms

    monkeypatch.setattr(mjcf, "build", heavier)
    results = run(["double_pendulum"], tmp_path, progress=False, summary=False)
    assert results[0].failed and "differs from Pinocchio's" in results[0].reason
    capfd.readouterr()
    assert main(["validate", "double_pendulum", "--out-dir", str(tmp_path),
                 "--no-progress"]) == 1


def test_mujoco_import_warnings_are_kept_not_written_to_the_working_folder(tmp_path, monkeypatch):
    """A URDF with equal joint limits makes MuJoCo warn; the warnings land on the MujocoScene,
    no MUJOCO_LOG.TXT appears in the working folder, and the previous handler is restored."""
    monkeypatch.chdir(tmp_path)
    before = mujoco.get_mju_user_warning()
    ms = mjcf.build(pinlin.Scene.from_robot("double_pendulum_simple").system)
    assert any("equal lower and upper limits" in w for w in ms.warnings)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert mujoco.get_mju_user_warning() is before


def test_scene_with_armature_passes():
    """SRDF armature (0.1 kg m^2 on every Talos arm joint) is exported to MuJoCo; without it
    MuJoCo's mass matrix and eigenvalues would differ by the armature."""
    scene, _ = check_scene("talos_arm")
    assert scene.effects.armature and scene.system.model.armature.max() > 0
    res = validate(scene, name="talos_arm")
    assert res.passed, res.reason
    assert res.matrix_error <= MATRIX_TOL and res.eig_error <= 1e-6


def test_scene_with_mimic_coupling_passes():
    """Panda's finger mimic becomes a MuJoCo joint equality (soft: its modes set aside)."""
    scene = pinlin.Scene.from_robot("panda", effects={"gravity": True, "mimic": True})
    res = validate(scene, name="panda_mimic")
    assert res.passed, res.reason
    assert res.eig_error <= 1e-6 and res.set_aside


def test_scene_with_a_weld_passes(tmp_path):
    """A 4R planar arm welded to the base (three weld rows redundant) against MuJoCo's weld
    equality between sites."""
    import numpy as np
    from test_closed_loops import _planar_arm_urdf

    q_star = np.array([0.3, 0.4, -0.5, 0.2])
    (tmp_path / "arm4.urdf").write_text(_planar_arm_urdf(q_star))
    scene = pinlin.Scene.from_dict({
        "urdf": str(tmp_path / "arm4.urdf"),
        "effects": {"gravity": [0, 0, -9.81],
                    "springs": {f"j{i}": {"stiffness": 5.0, "rest": float(q_star[i])}
                                for i in range(4)}},
        "loops": [{"name": "grip", "type": "weld", "frame1": "tip", "frame2": "anchor"}],
        "operating_point": {"q": {f"j{i}": float(q_star[i]) for i in range(4)},
                            "independent": ["j0"]},
        "inputs": {"actuated": ["j0"]}})
    res = validate(scene, name="arm4_weld")
    # Each eigenvalue within its own tolerance: 1e-6, or the first-order bound where MuJoCo's
    # stiff soft weld leaves its matrix less accurate (kappa |dA| / |lam|).
    assert res.passed, res.reason
    assert res.set_aside


@pytest.mark.parametrize("s, k", [(4.0, 2.0 ** 6), (256.0, 1.0)])
def test_a_mechanism_validates_alike_at_any_size(tmp_path, s, k):
    """The four-bar 4x and 256x larger (dynamic similarity, tests/test_scale_invariance.py:
    eigenvalues / sqrt(s)). MuJoCo's step follows the system's time scale (LOOP_PHASE /
    max |lam|), so MuJoCo solves the same problem with time stretched and the extrapolated
    eigenvalue error is the original's to rounding (measured 4.09e-8 against 4.16e-8 and
    4.20e-8). With a fixed dt = 1e-4 s the constraint springs amplified the rounding of
    positions against the slower modes: 1.2e-6 and 1.2e-4, both reported as failures."""
    from test_scale_invariance import scaled_scene

    original = validate(pinlin.Scene.resolve("four_bar"), name="four_bar")
    res = validate(scaled_scene("four_bar", s, k, tmp_path), name="four_bar_scaled")
    assert res.passed, res.reason
    assert res.dt == pytest.approx(original.dt * np.sqrt(s), rel=1e-12)
    assert res.eig_error <= 2 * original.eig_error + 1e-9
