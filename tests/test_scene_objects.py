"""Scenes, specs, effects, loops and contacts built in Python (or changed with
``dataclasses.replace``) are checked and stored as the scene file's parser checks and stores
them; linearize's option objects and arguments refuse what has nothing to act on.

Found by a hostile-input hunt: a free flyer's q given as a list was ignored, u and v beside a
solve mode that finds them were dropped, numpy values reached numpy's own errors, and a
robot override built another robot under the first one's name.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.scene import Contact, Loop, OperatingPointSpec, Outputs


@pytest.fixture(scope="module")
def ur5():
    return pinlin.Scene.from_robot("ur5")


@pytest.mark.parametrize("q", [[0.1, 0.2, 0.9, 0, 0, 0, 1], np.array([0.1, 0.2, 0.9, 0, 0, 0, 1]),
                               (0.1, 0.2, 0.9, 0.0, 0.0, 0.0, 1.0)])
def test_free_flyer_configuration_given_in_python(q):
    """The same values through the dict form (the parser) are the reference."""
    spec = OperatingPointSpec(q={"root_joint": q}, allow_non_equilibrium=True)
    scene = dataclasses.replace(pinlin.Scene.from_robot("solo12"), operating_point=spec)
    reference = pinlin.Scene.from_robot("solo12", operating_point={
        "q": {"root_joint": [0.1, 0.2, 0.9, 0, 0, 0, 1]}, "allow_non_equilibrium": True})
    got = pinlin.operating_point(scene).q
    assert np.array_equal(got, pinlin.operating_point(reference).q)
    assert np.array_equal(got[:3], [0.1, 0.2, 0.9])


def test_numpy_numbers_in_a_spec_read_as_numbers(ur5):
    spec = OperatingPointSpec(q={"elbow_joint": np.float32(0.5)})
    scene = dataclasses.replace(ur5, operating_point=spec)
    assert spec.q == {"elbow_joint": 0.5}
    q = pinlin.operating_point(scene).q
    assert q[ur5.system.joint("elbow_joint").idx_q] == 0.5


@pytest.mark.parametrize("kwargs, fld, words", [
    ({"u": {"elbow_joint": 5.0}}, "operating_point.u", "inputs are given only with"),
    ({"v": {"elbow_joint": 5.0}}, "operating_point.v", "velocities are given only with"),
    ({"independent": "crank"}, "operating_point.independent", "expected a list of joint names"),
    ({"solve": 3}, "operating_point.solve", "expected one of"),
])
def test_spec_fields_refused_as_in_a_file(kwargs, fld, words):
    with pytest.raises(pinlin.SceneError, match=f"field '{fld}': {words}"):
        OperatingPointSpec(**kwargs)


@pytest.mark.parametrize("make, fld", [
    (lambda s: dataclasses.replace(s, inputs=None), "inputs.actuated"),
    (lambda s: dataclasses.replace(s, inputs="elbow_joint"), "inputs.actuated"),
    (lambda s: dataclasses.replace(s, outputs={"frames": ["tool0"]}), "outputs"),
    (lambda s: dataclasses.replace(s, robot=None), "urdf"),
    (lambda s: dataclasses.replace(s, name=None), "name"),
    (lambda s: dataclasses.replace(s, loops=({"frame1": "a", "frame2": "b"},)), "loops"),
    (lambda s: Outputs(frames="tool0"), "outputs.frames"),
    (lambda s: Outputs(), "outputs"),
    (lambda s: Loop("c", "hinge", "a", "b"), "loops.c.type"),
    (lambda s: Loop("c", "point", "a", "a"), "loops.c.frame2"),
    (lambda s: Contact("foot", "glue", "FL_FOOT"), "contacts.foot.type"),
    (lambda s: dataclasses.replace(s, effects=pinlin.Effects(damping={"elbow_joint": [1, 2]})),
     "effects.damping.elbow_joint"),
])
def test_scene_objects_refuse_what_the_file_refuses(ur5, make, fld):
    with pytest.raises(pinlin.SceneError) as info:
        scene = make(ur5)
        pinlin.linearize(scene)   # the damping list's length is checked against the joint
    if fld is not None:
        assert f"field '{fld}'" in str(info.value), str(info.value)


def test_inputs_and_gravity_as_numpy_arrays(ur5):
    names = np.array(["elbow_joint", "wrist_1_joint"])
    scene = dataclasses.replace(ur5, inputs=names)
    assert scene.inputs == ("elbow_joint", "wrist_1_joint")
    effects = pinlin.Effects(gravity=np.array([0.0, 0.0, -9.81]))
    assert effects.gravity == (0.0, 0.0, -9.81)
    model = pinlin.linearize(dataclasses.replace(ur5, effects=effects))
    assert np.array_equal(model.A, pinlin.linearize(ur5).A)


def test_constructor_overrides(ur5):
    assert pinlin.Scene.from_robot("ur5", name="my_arm").name == "my_arm"
    with pytest.raises(pinlin.ArgumentError, match="argument 'robot': not a scene field"):
        pinlin.Scene.from_robot("ur5", robot="panda")
    with pytest.raises(pinlin.ArgumentError, match="argument 'urdf': not a scene field"):
        pinlin.Scene.from_urdf(URDF_DIR / "pendulum.urdf", urdf="y.urdf")


def test_option_objects_do_not_drop_settings(ur5):
    """On an open chain the penalty's settings have nothing to act on (refused, as the string
    form's); estimate_error beside a FiniteDifferences object was ignored; numpy's True was
    read as 1.0."""
    with pytest.raises(pinlin.ArgumentError, match=r"Penalty\.alpha.*no constraint to act on"):
        pinlin.linearize(ur5, formulation=pinlin.Penalty(alpha=1.0))
    with pytest.raises(pinlin.ArgumentError, match="argument 'estimate_error': set it on"):
        pinlin.linearize(ur5, derivatives=pinlin.FiniteDifferences(order=3),
                         estimate_error=False)
    with pytest.raises(pinlin.ArgumentError, match="argument 'alpha': penalty alpha must be a "
                                                   "number"):
        pinlin.Penalty(alpha=np.True_)


@pytest.mark.parametrize("call", [
    lambda s: pinlin.linearize(s, formulation=10 ** 5000),
    lambda s: pinlin.linearize(s, derivatives=10 ** 5000),
    lambda s: pinlin.linearize(s, derivatives="fd3", step={"q": 10 ** 5000}),
    lambda s: pinlin.Penalty(alpha=10 ** 5000),
    lambda s: pinlin.FiniteDifferences(order=10 ** 5000),
])
def test_huge_integers_in_messages(ur5, call):
    """Messages written with repr() raised Python's own 'Exceeds the limit (4300 digits)'."""
    with pytest.raises(pinlin.ArgumentError, match="an integer of about 5001 digits"):
        call(ur5)


def test_mass_inverse_argument_is_checked(ur5):
    system = ur5.system
    for bad, words in ((np.full((6, 6), np.nan), "finite entries"),
                       (np.zeros((6, 6)), "positive diagonal"),
                       (np.eye(3), r"expected an 6 x 6 matrix")):
        with pytest.raises(pinlin.ArgumentError, match=f"argument 'mass_inverse': .*{words}"):
            pinlin.operating_point(ur5, mass_inverse=bad)
    Minv = system.mass_inverse(pinlin.operating_point(ur5).q)
    assert np.array_equal(pinlin.operating_point(ur5, mass_inverse=Minv).q,
                          pinlin.operating_point(ur5).q)


def test_missing_values_and_empty_paths(ur5):
    """numpy reads None as NaN (the message said 'contains NaN or inf'); an empty path was
    read as the current folder ('/tmp/x: file not found')."""
    with pytest.raises(pinlin.ArgumentError, match="argument 'q': .*got None \\(missing"):
        pinlin.linearize(ur5, q=np.array([None] * 6))
    with pytest.raises(pinlin.ArgumentError, match="argument 'v': .*got None \\(missing"):
        pinlin.linearize(ur5, v=[0.0, None, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(pinlin.ArgumentError, match="argument 'path': expected a file path, got "
                                                   "an empty one"):
        pinlin.Scene.from_urdf("")
