"""Scenes and example-robot-data models: the fast loading route equals the real loaders."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pinocchio as pin
import pytest
from example_robot_data import load as erd_load

import pinlin
from pinlin.robots import load_robot


@pytest.mark.parametrize("name", ["ur5", "talos", "panda", "solo12", "talos_legs"])
def test_fast_loading_matches_example_robot_data(name):
    with contextlib.redirect_stdout(io.StringIO()):
        ref = erd_load(name)
    ours = load_robot(name)
    assert ours.model.nq == ref.model.nq and ours.model.nv == ref.model.nv
    assert list(ours.model.names) == list(ref.model.names)
    np.testing.assert_array_equal(ours.model.armature, ref.model.armature)
    np.testing.assert_allclose(ours.q_ref, ref.q0, rtol=0, atol=1e-15)
    q = pin.randomConfiguration(ref.model, -np.ones(ref.model.nq), np.ones(ref.model.nq))
    M_ours = pin.crba(ours.model, ours.model.createData(), q)
    M_ref = pin.crba(ref.model, ref.model.createData(), q)
    np.testing.assert_allclose(M_ours, M_ref, rtol=1e-14, atol=1e-14)


def test_from_robot_uses_reference_posture_and_loader_armature():
    scene = pinlin.Scene.from_robot("talos")
    system = scene.system
    assert scene.effects.armature is True and system.base_joint == "root_joint"
    with contextlib.redirect_stdout(io.StringIO()):
        ref = erd_load("talos")
    np.testing.assert_array_equal(system.model.armature, ref.model.armature)
    assert np.all(system.model.armature[:6] == 0.0) and system.model.armature.max() == 0.1
    np.testing.assert_allclose(pinlin.operating_point(system, allow_non_equilibrium=True).q,
                               ref.q0)


def test_armature_absent_unless_called_for():
    scene = pinlin.Scene.from_robot("talos_arm", effects={"gravity": True})
    assert not np.any(scene.system.model.armature)


def test_fixed_base_override_locks_the_free_flyer():
    scene = pinlin.Scene.from_robot("talos", base="fixed")
    assert scene.system.base_joint is None and scene.system.nv == 32
    model = pinlin.linearize(scene)           # now every DoF is actuated: an equilibrium
    assert model.operating_point.equilibrium and model.A.shape == (64, 64)


def test_scene_file_round_trip(write_scene):
    path = write_scene("""
name = "arm"
robot = "ur5"
[effects]
gravity = true
damping = { elbow_joint = 0.5 }
springs = { wrist_1_joint = { stiffness = 10.0, rest = 0.2 } }
[operating_point]
q = { elbow_joint = 1.0 }
[inputs]
actuated = ["shoulder_lift_joint", "elbow_joint"]
[outputs]
joints = ["elbow_joint", "v:wrist_1_joint"]
frames = ["tool0"]
""")
    scene = pinlin.Scene.load(path)
    assert scene.effects.in_play() == ["gravity", "damping", "springs"]
    system = scene.system
    assert system.input_names == ("u:shoulder_lift_joint", "u:elbow_joint")
    assert system.outputs.names[:3] == ("q:elbow_joint", "v:elbow_joint", "v:wrist_1_joint")
    # Four unactuated joints: the posture is held only if gravity leaves them unloaded.
    with pytest.raises(pinlin.EquilibriumError, match="cannot supply"):
        pinlin.linearize(scene)
    model = pinlin.linearize(scene, allow_non_equilibrium=True)
    assert model.B.shape == (12, 2) and model.C.shape == (6, 12)
    assert "not an equilibrium" in model.operating_point.notes[0]


def test_floating_base_pose_from_table(write_scene):
    path = write_scene("""
robot = "solo12"
[effects]
[operating_point]
q = { root_joint = { position = [0.0, 0.0, 0.4], rpy = [0.1, 0.2, 0.3] } }
""")
    system = pinlin.Scene.load(path).system
    q0 = pinlin.operating_point(system).q
    np.testing.assert_allclose(q0[:3], [0, 0, 0.4])
    np.testing.assert_allclose(pin.Quaternion(q0[3:7]).matrix(),
                               pin.rpy.rpyToMatrix(0.1, 0.2, 0.3), atol=1e-15)


def test_bundled_scenes_all_linearize():
    for name, path in pinlin.scene.bundled_scenes().items():
        model = pinlin.linearize(path)
        assert model.name == name and np.all(np.isfinite(model.A))


def test_every_loadable_robot_linearizes_or_names_its_massless_joint():
    from pinlin.robots import loadable_robots

    linearized = 0
    refused: list[str] = []
    for name, reason in loadable_robots().items():
        if reason is not None:
            continue
        scene = pinlin.Scene.from_robot(name)
        try:
            model = pinlin.linearize(scene, allow_non_equilibrium=True)
        except pinlin.ModelError as exc:
            system = scene.system
            M = pin.crba(system.model, system.model.createData(), system.q_ref)
            M = np.triu(M) + np.triu(M, 1).T
            if "carries no inertia" in str(exc):
                # Independent check: crba at q0 has a zero row for the named coordinate.
                coord = str(exc).split("coordinate '")[1].split("'")[0]
                assert M[system.coordinate_names.index(coord)].max() == 0.0, name
            else:
                # Singular to working precision (icub: its head is a point mass that two neck
                # joints turn about its centre): scaled to unit diagonal, M's smallest
                # eigenvalue is rounding noise (~1e-15), against >= 1e-3 for every robot kept.
                assert "singular to working precision" in str(exc), name
                d = np.sqrt(np.diag(M))
                assert np.linalg.eigvalsh(M / np.outer(d, d))[0] < 1e-12, name
            refused.append(name)
            continue
        modes = pinlin.modal(model)
        assert np.all(np.isfinite(model.A)) and np.all(np.isfinite(modes.eigenvalues)), name
        linearized += 1
    assert linearized >= 60
    assert "icub" in refused


def test_loading_a_bundled_name_as_a_file_says_how_to_load_it(tmp_path, monkeypatch):
    """``Scene.load`` reads files; given a bundled scene's name (no such file here) it says
    that ``Scene.resolve`` takes names, instead of only "not found"."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(pinlin.SceneError, match=r"bundled scene: pinlin.Scene.resolve"):
        pinlin.Scene.load("four_bar")
    with pytest.raises(pinlin.SceneError, match="scene file not found$"):
        pinlin.Scene.load("no_such_scene")
