"""Bad values in scene fields: huge integers, deep nesting, values beyond pinlin's ranges, wrong
types, names that break one-line messages, non-normalized configurations, duplicate outputs,
joint names with ':'; and bad arguments to the Python entry points and to ``pinlin.modal``.

Each scene case is a real TOML file (and URDF) in a temporary folder. From Python it raises the
named PinlinError subclass whose message holds every listed fragment; from the CLI it gives
exit status 2 and exactly one stderr line starting "pinlin: error: ", with no traceback.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.cli import main
from pinlin.scene import COEFFICIENT_LIMIT, POSITION_LIMIT, Effects, OperatingPointSpec, Scene

PENDULUM = (URDF_DIR / "pendulum.urdf").read_text()
GOOD = {"robot__urdf": PENDULUM}
HEAD = 'urdf = "robot.urdf"\n'
FOUR_BAR = (URDF_DIR / "four_bar.toml").read_text().replace("four_bar.urdf", "robot.urdf")
FOUR_BAR_URDF = {"robot__urdf": (URDF_DIR / "four_bar.urdf").read_text()}
HUGE = "9" * 500            # converts to int, not to float
HUGER = "9" * 5000          # more digits than Python's int() accepts (4300)
DEEP = "[" * 5000 + "]" * 5000

_INERTIAL = ('<inertial><origin xyz="0 0 -0.5"/><mass value="1.0"/><inertia ixx="0.1" ixy="0" '
             'ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>')


def _urdf(*joints: tuple[str, str]) -> str:
    """A chain of links joined by (name, type) joints, each link with a physical inertia."""
    parts = ['<?xml version="1.0"?><robot name="chain"><link name="base"/>']
    parent = "base"
    for k, (name, kind) in enumerate(joints):
        limit = ('<limit lower="-3" upper="3" effort="10" velocity="10"/>'
                 if kind in ("revolute", "prismatic") else "")
        axis = "0 0 1" if kind == "planar" else "0 1 0"  # a planar joint moves in x-y
        parts.append(f'<link name="l{k}">{_INERTIAL}</link>'
                     f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
                     f'<child link="l{k}"/><axis xyz="{axis}"/>{limit}</joint>')
        parent = f"l{k}"
    parts.append("</robot>")
    return "".join(parts)


# A planar joint (x, y, cos, sin), a continuous joint named with ':' and a floating joint.
MIXED = {"robot__urdf": _urdf(("slide", "planar"), ("arm:elbow", "continuous"),
                              ("float", "floating"))}
SLIDER = {"robot__urdf": _urdf(("rail", "prismatic"))}

# case: (scene text, files, exception class, fragments of the message)
CASES = {
    # 1. integers too large for a float, in every kind of numeric field
    "huge_int_gravity": (HEAD + f"[effects]\ngravity = [0, 0, -{HUGE}]\n", GOOD,
                         pinlin.SceneError, ["effects.gravity[2]", "too large for a float"]),
    "huger_int_gravity": (HEAD + f"[effects]\ngravity = [0, 0, -{HUGER}]\n", GOOD,
                          pinlin.SceneError, ["effects.gravity[2]", "more than 4300 digits"]),
    "huge_int_with_underscores": (HEAD + "[effects]\ndamping = { hinge = "
                                  + "9_" * 4400 + "9 }\n", GOOD, pinlin.SceneError,
                                  ["effects.damping.hinge", "more than 4300 digits"]),
    "huge_int_damping": (HEAD + f"[effects]\ndamping = {{ hinge = {HUGE} }}\n", GOOD,
                         pinlin.SceneError, ["effects.damping.hinge", "too large for a float"]),
    "huge_int_armature": (HEAD + f"[effects]\narmature = {{ hinge = {HUGE} }}\n", GOOD,
                          pinlin.SceneError, ["effects.armature.hinge", "too large"]),
    "huge_int_stiffness": (HEAD + f"[effects]\nsprings = {{ hinge = {{ stiffness = {HUGE} }} }}"
                           "\n", GOOD, pinlin.SceneError,
                           ["effects.springs.hinge.stiffness", "too large for a float"]),
    "huge_int_rest": (HEAD + "[effects]\nsprings = { hinge = { stiffness = 1.0, rest = "
                      f"-{HUGER} }} }}\n", GOOD, pinlin.SceneError,
                      ["effects.springs.hinge.rest", "more than 4300 digits"]),
    "huge_int_rate": (HEAD + f"[effects]\nrotation = {{ axis = [0, 0, 1], rate = {HUGE} }}\n",
                      GOOD, pinlin.SceneError, ["effects.rotation.rate", "too large"]),
    "huge_int_axis": (HEAD + f"[effects]\nrotation = {{ axis = [0, 0, {HUGE}], rate = 1.0 }}\n",
                      GOOD, pinlin.SceneError, ["effects.rotation.axis[2]", "too large"]),
    "huge_int_q": (HEAD + f"[operating_point]\nq = {{ hinge = {HUGE} }}\n", GOOD,
                   pinlin.SceneError, ["operating_point.q.hinge", "too large for a float"]),
    "huge_int_q_list": (HEAD + f"[operating_point]\nq = {{ hinge = [{HUGER}] }}\n", GOOD,
                        pinlin.SceneError, ["operating_point.q.hinge[0]", "4300 digits"]),
    "huge_int_u": (HEAD + f'[operating_point]\nsolve = "positions"\nu = {{ hinge = {HUGE} }}\n',
                   GOOD, pinlin.SceneError, ["operating_point.u.hinge", "too large"]),
    "huge_int_quaternion": (HEAD + "[operating_point]\nq = { float = { quaternion = "
                            f"[0, 0, 0, {HUGE}] }} }}\n", MIXED, pinlin.SceneError,
                            ["operating_point.q.float.quaternion[3]", "too large"]),
    "huge_int_position": (HEAD + "[operating_point]\nq = { float = { position = "
                          f"[{HUGE}, 0, 0] }} }}\n", MIXED, pinlin.SceneError,
                          ["operating_point.q.float.position[0]", "too large"]),
    # 1b. nesting deeper than the TOML reader's recursion
    "deep_array": (HEAD + f"[effects]\ngravity = {DEEP}\n", GOOD, pinlin.SceneError,
                   ["scene.toml", "nested too deeply"]),
    "deep_inline_table": (HEAD + "[effects]\ndamping = " + "{ a = " * 3000 + "1" + " }" * 3000
                          + "\n", GOOD, pinlin.SceneError, ["scene.toml", "nested too deeply"]),
    "nested_list_for_number": (HEAD + "[effects]\ngravity = [0, 0, [[[-9.81]]]]\n", GOOD,
                               pinlin.SceneError, ["effects.gravity[2]", "expected a number"]),
    # 2. finite values beyond the physical ranges
    "gravity_1e308": (HEAD + "[effects]\ngravity = [0, 0, -1e308]\n", GOOD, pinlin.SceneError,
                      ["effects.gravity[2]", "|value| <= 1e+12"]),
    "gravity_inf": (HEAD + "[effects]\ngravity = [0, 0, -inf]\n", GOOD, pinlin.SceneError,
                    ["effects.gravity[2]", "expected a finite number"]),
    "rate_1e200": (HEAD + "[effects]\ngravity = [0, 0, -9.81]\n"
                   "rotation = { axis = [0, 0, 1], rate = 1e200 }\n", GOOD, pinlin.SceneError,
                   ["effects.rotation.rate", "|value| <= 1e+06"]),
    "damping_1e300": (HEAD + "[effects]\ndamping = { hinge = 1e300 }\n", GOOD,
                      pinlin.SceneError, ["effects.damping.hinge", "|value| <= 1e+12"]),
    "stiffness_1e300": (HEAD + "[effects]\nsprings = { hinge = { stiffness = 1e300 } }\n", GOOD,
                        pinlin.SceneError, ["effects.springs.hinge.stiffness", "<= 1e+12"]),
    "armature_1e300": (HEAD + "[effects]\narmature = { hinge = 1e300 }\n", GOOD,
                       pinlin.SceneError, ["effects.armature.hinge", "|value| <= 1e+12"]),
    "q_revolute_1e300": (HEAD + "[effects]\ngravity = true\n[operating_point]\n"
                         "q = { hinge = 1e300 }\n", GOOD, pinlin.SceneError,
                         ["operating_point.q.hinge", "|value| <= 1e+06"]),
    "q_prismatic_1e300": (HEAD + "[operating_point]\nq = { rail = -1e300 }\n", SLIDER,
                          pinlin.SceneError, ["operating_point.q.rail", "|value| <= 1e+06"]),
    "rest_1e7": (HEAD + "[effects]\nsprings = { hinge = { stiffness = 1.0, rest = 1e7 } }\n",
                 GOOD, pinlin.SceneError, ["effects.springs.hinge.rest", "<= 1e+06"]),
    "u_1e300": (HEAD + '[operating_point]\nsolve = "positions"\nu = { hinge = 1e300 }\n', GOOD,
                pinlin.SceneError, ["operating_point.u.hinge", "|value| <= 1e+12"]),
    "rpy_1e300": (HEAD + "[operating_point]\nq = { float = { rpy = [1e300, 0, 0] } }\n", MIXED,
                  pinlin.SceneError, ["operating_point.q.float.rpy[0]", "<= 1e+06"]),
    # 3. types: booleans are booleans, names are non-empty strings, lists have no duplicates
    "allow_string": (HEAD + '[operating_point]\nallow_non_equilibrium = "no"\n', GOOD,
                     pinlin.SceneError, ["operating_point.allow_non_equilibrium",
                                         "expected true or false", "'no'"]),
    "allow_integer": (HEAD + "[operating_point]\nallow_non_equilibrium = 0\n", GOOD,
                      pinlin.SceneError, ["operating_point.allow_non_equilibrium",
                                          "expected true or false"]),
    "mimic_integer": (HEAD + "[effects]\nmimic = 1\n", GOOD, pinlin.SceneError,
                      ["effects.mimic", "expected true or false"]),
    "actuated_integer": (HEAD + "[inputs]\nactuated = [1]\n", GOOD, pinlin.SceneError,
                         ["inputs.actuated[0]", "expected a non-empty string"]),
    "actuated_nested": (HEAD + '[inputs]\nactuated = [["hinge"]]\n', GOOD, pinlin.SceneError,
                        ["inputs.actuated[0]", "expected a non-empty string"]),
    "actuated_empty_name": (HEAD + '[inputs]\nactuated = [""]\n', GOOD, pinlin.SceneError,
                            ["inputs.actuated[0]", "non-empty string"]),
    "actuated_duplicate": (HEAD + '[inputs]\nactuated = ["hinge", "hinge"]\n', GOOD,
                           pinlin.SceneError, ["inputs.actuated", "'hinge' is listed twice"]),
    "actuated_word": (HEAD + '[inputs]\nactuated = "none"\n', GOOD, pinlin.SceneError,
                      ["inputs.actuated", "expected one of 'all'"]),
    "frames_integer": (HEAD + "[outputs]\nframes = [3]\n", GOOD, pinlin.SceneError,
                       ["outputs.frames[0]", "expected a non-empty string"]),
    "joints_nested": (HEAD + "[outputs]\njoints = [[]]\n", GOOD, pinlin.SceneError,
                      ["outputs.joints[0]", "expected a non-empty string"]),
    "independent_integer": (FOUR_BAR.replace('independent = ["crank"]', "independent = [1]"),
                            FOUR_BAR_URDF, pinlin.SceneError,
                            ["operating_point.independent[0]", "non-empty string"]),
    "independent_duplicate": (FOUR_BAR.replace('independent = ["crank"]',
                                               'independent = ["crank", "crank"]'),
                              FOUR_BAR_URDF, pinlin.SceneError,
                              ["operating_point.independent", "'crank' is listed twice"]),
    # an explicit empty list is not "let pinlin choose" (that is leaving the key out)
    "independent_empty": (FOUR_BAR.replace('independent = ["crank"]', "independent = []"),
                          FOUR_BAR_URDF, pinlin.SceneError,
                          ["operating_point.independent", "got an empty list"]),
    # names that would break a one-line message
    "key_with_line_break": (HEAD + '[operating_point]\nq = { "hin\\nge" = 0.0 }\n', GOOD,
                            pinlin.SceneError, ["operating_point.q", "control characters",
                                                "'hin\\nge'"]),
    "name_with_line_break": ('name = "a\\nb"\n' + HEAD, GOOD, pinlin.SceneError,
                             ["field 'name'", "control characters"]),
    "urdf_with_control_character": ('urdf = "robot\\u0007.urdf"\n', GOOD, pinlin.SceneError,
                                    ["field 'urdf'", "control characters"]),
    "unknown_key_with_line_break": (HEAD + '[effects]\n"grav\\nity" = true\n', GOOD,
                                    pinlin.SceneError, ["effects.'grav\\nity'", "unknown key"]),
    "urdf_name_too_long": ('urdf = "' + "a" * 5000 + '.urdf"\n', {}, pinlin.SceneError,
                           ["field 'urdf'", "cannot use the path", "too long"]),
    # 4. configurations are never normalized silently
    "planar_cos_sin_2_0": (HEAD + "[operating_point]\nq = { slide = [0.0, 0.0, 2.0, 0.0] }\n",
                           MIXED, pinlin.SceneError,
                           ["operating_point.q.slide", "joint 'slide'", "(cos, sin)",
                            "unit norm", "got norm 2"]),
    "continuous_cos_sin_2_0": (HEAD + '[operating_point]\nq = { "arm:elbow" = [2.0, 0.0] }\n',
                               MIXED, pinlin.SceneError,
                               ["operating_point.q.arm:elbow", "joint 'arm:elbow'",
                                "(cos, sin) pair must have unit norm"]),
    "free_flyer_raw_quaternion": (HEAD + "[operating_point]\nq = { float = [0, 0, 0, 0, 0, 0, "
                                  "2] }\n", MIXED, pinlin.SceneError,
                                  ["operating_point.q.float", "quaternion", "unit norm"]),
    "free_flyer_quaternion_table": (HEAD + "[operating_point]\nq = { float = { quaternion = "
                                    "[0, 0, 0, 0.5] } }\n", MIXED, pinlin.SceneError,
                                    ["operating_point.q.float.quaternion", "unit quaternion"]),
    "empty_configuration_table": (HEAD + "[operating_point]\nq = { float = {} }\n", MIXED,
                                  pinlin.SceneError, ["operating_point.q.float", "empty table"]),
    "planar_wrong_count": (HEAD + "[operating_point]\nq = { slide = [0.0, 1.0] }\n", MIXED,
                           pinlin.SceneError, ["operating_point.q.slide",
                                               "has 4 configuration values, got 2"]),
    # 5. outputs
    "duplicate_output": (HEAD + '[outputs]\njoints = ["hinge", "q:hinge"]\n', GOOD,
                         pinlin.SceneError, ["outputs.joints", "'q:hinge' is requested twice"]),
    "duplicate_velocity_output": (HEAD + '[outputs]\njoints = ["v:slide", "slide"]\n', MIXED,
                                  pinlin.SceneError, ["outputs.joints", "'v:slide[0]'",
                                                      "requested twice"]),
    "colon_bad_prefix": (HEAD + '[outputs]\njoints = ["x:arm:elbow"]\n', MIXED,
                         pinlin.SceneError, ["outputs.joints", "'q:name' or 'v:name'"]),
    "colon_unknown_joint": (HEAD + '[outputs]\njoints = ["q:arm:elbo"]\n', MIXED,
                            pinlin.UnknownNameError, ["outputs.joints", "did you mean",
                                                      "'arm:elbow'"]),
    "colon_ambiguous": (HEAD + '[outputs]\njoints = ["q:x"]\n',
                        {"robot__urdf": _urdf(("x", "revolute"), ("q:x", "revolute"))},
                        pinlin.SceneError, ["outputs.joints", "'q:x' is ambiguous"]),
    # names and coefficients the robot's own files give
    "urdf_huge_damping": (HEAD + "[effects]\ndamping = true\n",
                          {"robot__urdf": PENDULUM.replace(
                              '<axis xyz="0 1 0"/>',
                              '<axis xyz="0 1 0"/><dynamics damping="1e300"/>')},
                          pinlin.SceneError, ["effects.damping", "<dynamics damping>",
                                              "'hinge' 1e+300", "[0, 1e+12]"]),
    # (damping = true on a URDF without <dynamics damping> gave zero damping while the model
    # listed damping among the effects in play; armature = true was refused alike)
    # (Pinocchio divides by max(m, eps): a 1e-16 kg bob's lever arm shrank, A came out wrong)
    "urdf_tiny_mass": (HEAD, {"robot__urdf": PENDULUM.replace('<mass value="1.0"/>',
                                                              '<mass value="1e-16"/>')},
                       pinlin.PinlinError, ["link 'bob'", "below 2.22e-16 kg (eps)"]),
    "urdf_has_no_damping": (HEAD + "[effects]\ndamping = true\n", {"robot__urdf": PENDULUM},
                            pinlin.SceneError, ["effects.damping", "this robot has none"]),
    "urdf_joint_named_spin": (HEAD + "[effects]\nrotation = { axis = [0, 0, 1], rate = 1.0 }\n",
                              {"robot__urdf": PENDULUM.replace('name="hinge"',
                                                               'name="__spin__"')},
                              pinlin.SceneError, ["field 'urdf'", "'__spin__'", "reserved"]),
    "urdf_coordinate_names_collide": (HEAD, {"robot__urdf": _urdf(("p", "planar"),
                                                                  ("p[0]", "revolute"))},
                                      pinlin.SceneError, ["field 'urdf'", "'p[0]'"]),
    "urdf_joint_name_with_line_break": (HEAD, {"robot__urdf": PENDULUM.replace(
                                            'name="hinge"', 'name="hin&#10;ge"')},
                                        pinlin.SceneError, ["field 'urdf'", "'hin\\nge'",
                                                            "control characters"]),
    # a URDF far outside physics: modal refuses the matrices instead of crashing
    "urdf_mass_1e200": (HEAD + "[effects]\ngravity = true\n",
                        {"robot__urdf": PENDULUM.replace('value="1.0"', 'value="1e200"')},
                        pinlin.ModelError, ["matrix M", "modal analysis needs finite entries"]),
}


def _linearize_and_analyse(path) -> None:
    pinlin.modal(pinlin.linearize(Scene.load(path)))


def test_catalogue_size():
    assert len(CASES) >= 40


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_field_raises_the_named_error(case, write_scene):
    text, files, exc, fragments = CASES[case]
    path = write_scene(text, **files)
    with pytest.raises(exc) as info:
        _linearize_and_analyse(path)
    message = str(info.value)
    assert "\n" not in message and len(message) < 600, message
    for fragment in fragments:
        assert fragment in message, message
    if isinstance(info.value, pinlin.SceneError):
        assert info.value.source == path


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_field_gives_one_line_and_exit_2(case, write_scene, capfd):
    text, files, _exc, fragments = CASES[case]
    path = write_scene(text, **files)
    code = main(["linearize", str(path)])
    _out, err = capfd.readouterr()
    assert code == 2, err
    assert err.startswith("pinlin: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in err, err


# --------------------------------------------------------------------------------------------
# What is accepted: the same fields with good values, at the edges of the ranges.

def test_joint_names_with_colons_work_in_outputs_and_survive_a_file(write_scene, tmp_path):
    path = write_scene(HEAD + '[operating_point]\nq = { "arm:elbow" = 0.4, slide = '
                       "[0.1, 0.2, 0.6, 0.8] }\n[outputs]\n"
                       'joints = ["arm:elbow", "v:slide"]\n', **MIXED)
    model = pinlin.linearize(Scene.load(path), allow_non_equilibrium=True)
    assert model.output_names == ("q:arm:elbow", "v:arm:elbow", "v:slide[0]", "v:slide[1]",
                                  "v:slide[2]")
    assert "q:arm:elbow" in model.state_names and "u:arm:elbow" in model.input_names
    saved = model.save(tmp_path / "model.npz")
    assert pinlin.LinearModel.load(saved).output_names == model.output_names
    q_only = Scene.from_dict({"urdf": str(tmp_path / "robot.urdf"),
                              "outputs": {"joints": ["q:arm:elbow"]}})
    assert pinlin.linearize(q_only).output_names == ("q:arm:elbow",)


def test_values_at_the_range_limits_give_finite_models(write_scene):
    path = write_scene(HEAD + f"[effects]\ngravity = [0, 0, -{COEFFICIENT_LIMIT:g}]\n"
                       f"damping = {{ hinge = {COEFFICIENT_LIMIT:g} }}\n"
                       f"springs = {{ hinge = {{ stiffness = {COEFFICIENT_LIMIT:g}, "
                       f"rest = {POSITION_LIMIT:g} }} }}\n"
                       "[operating_point]\nallow_non_equilibrium = true\n"
                       f"q = {{ hinge = {POSITION_LIMIT:g} }}\n", **GOOD)
    model = pinlin.linearize(Scene.load(path))
    modes = pinlin.modal(model)
    assert np.all(np.isfinite(model.A)) and np.all(np.isfinite(modes.eigenvalues))


def test_rotation_axis_is_a_direction_of_any_finite_size(write_scene):
    for axis in ("[0, 0, 1e300]", "[0, 0, 1e-320]", f"[0, 0, {HUGE[:300]}]"):
        path = write_scene(HEAD + "[effects]\ngravity = [0, 0, -9.81]\n"
                           f"rotation = {{ axis = {axis}, rate = 2.0 }}\n", **GOOD)
        assert Scene.load(path).effects.rotation.axis == (0.0, 0.0, 1.0)


def test_python_sequences_and_numpy_numbers_are_numbers():
    scene = Scene.from_dict({"urdf": str(URDF_DIR / "pendulum.urdf"),
                             "effects": {"gravity": np.array([0.0, 0.0, -9.81]),
                                         "damping": {"hinge": np.float32(0.5)}},
                             "operating_point": {"q": {"hinge": (0.1,)}}})
    assert scene.effects.gravity == (0.0, 0.0, -9.81)
    assert np.all(np.isfinite(pinlin.linearize(scene, allow_non_equilibrium=True).A))


def test_configuration_given_as_an_angle_or_normalized_values(write_scene):
    path = write_scene(HEAD + '[operating_point]\nq = { "arm:elbow" = 7.0, slide = '
                       "[0.5, 0.0, 0.6, 0.8], float = { position = [1, 2, 3], "
                       "rpy = [0.1, 0.2, 0.3] } }\nallow_non_equilibrium = true\n", **MIXED)
    model = pinlin.linearize(Scene.load(path))
    q = model.operating_point.q
    assert np.allclose(q[4:6], [np.cos(7.0), np.sin(7.0)]) and np.allclose(q[2:4], [0.6, 0.8])


# --------------------------------------------------------------------------------------------
# Python entry points: wrong argument types and values.

BAD_CALLS = {
    "load_int": (lambda: Scene.load(123), pinlin.ArgumentError, ["'path'", "got 123"]),
    "load_none": (lambda: Scene.load(None), pinlin.ArgumentError, ["'path'", "got None"]),
    "load_bytes": (lambda: Scene.load(b"scene.toml"), pinlin.ArgumentError, ["'path'"]),
    "from_robot_int": (lambda: Scene.from_robot(42), pinlin.ArgumentError,
                       ["'name'", "robot name", "got 42"]),
    "from_dict_list": (lambda: Scene.from_dict([]), pinlin.ArgumentError,
                       ["'data'", "expected a table"]),
    "from_dict_source_int": (lambda: Scene.from_dict({"urdf": "x.urdf"}, source=3),
                             pinlin.ArgumentError, ["'source'"]),
    "resolve_none": (lambda: Scene.resolve(None), pinlin.ArgumentError, ["'target'"]),
    "from_urdf_int": (lambda: Scene.from_urdf(5), pinlin.ArgumentError, ["'path'"]),
    "from_dict_huge_int": (lambda: Scene.from_dict({"urdf": "x.urdf",
                                                    "effects": {"gravity": [0, 0, -10**5000]}}),
                           pinlin.SceneError, ["effects.gravity[2]", "about 5001 digits"]),
    "from_dict_deep_list": (lambda: Scene.from_dict({"urdf": "x.urdf",
                                                     "effects": {"gravity": [0, 0, _deep()]}}),
                            pinlin.SceneError, ["effects.gravity[2]", "[[[[...]]]]"]),
    "from_dict_allow_string": (lambda: Scene.from_dict({"urdf": "x.urdf", "operating_point":
                                                        {"allow_non_equilibrium": "no"}}),
                               pinlin.SceneError, ["allow_non_equilibrium", "true or false"]),
    "from_dict_allow_numpy_bool": (lambda: Scene.from_dict(
        {"urdf": "x.urdf", "operating_point": {"allow_non_equilibrium": np.True_}}),
        pinlin.SceneError, ["allow_non_equilibrium", "true or false"]),
    "from_dict_joint_key_int": (lambda: Scene.from_dict(
        {"urdf": "x.urdf", "effects": {"damping": {1: 0.5}}}),
        pinlin.SceneError, ["effects.damping", "joint names", "got 1"]),
    "from_dict_names_array": (lambda: Scene.from_dict(
        {"urdf": "x.urdf", "inputs": {"actuated": np.array(["hinge"])}}),
        pinlin.SceneError, ["inputs.actuated", "expected a list of names"]),
    "spec_allow_string": (lambda: OperatingPointSpec(allow_non_equilibrium="no"),
                          pinlin.SceneError, ["allow_non_equilibrium", "true or false"]),
    "spec_bad_solve": (lambda: OperatingPointSpec(solve="everything"), pinlin.SceneError,
                       ["operating_point.solve", "'inputs', 'positions'"]),
    "effects_mimic_int": (lambda: Effects(mimic=1), pinlin.SceneError,
                          ["effects.mimic", "true or false"]),
}


def _deep(levels: int = 100_000) -> list:
    top: list = []
    node = top
    for _ in range(levels):
        node.append([])
        node = node[0]
    return top


@pytest.mark.parametrize("case", sorted(BAD_CALLS))
def test_bad_python_call_raises_the_named_error(case):
    call, exc, fragments = BAD_CALLS[case]
    with pytest.raises(exc) as info:
        call()
    message = str(info.value)
    assert "\n" not in message and len(message) < 400, message
    for fragment in fragments:
        assert fragment in message, message


def test_scene_path_too_long_for_the_file_system(capfd, tmp_path):
    path = tmp_path / ("a" * 5000 + ".toml")
    with pytest.raises(pinlin.SceneError, match="cannot use the path: File name too long"):
        Scene.load(path)
    code = main(["linearize", str(path)])
    err = capfd.readouterr().err
    assert code == 2 and err.startswith("pinlin: error: ") and err.count("\n") == 1
    assert len(err) < 400 and "too long" in err


def test_from_robot_overrides_are_checked_like_a_file():
    with pytest.raises(pinlin.SceneError, match=r"effects\.gravity\[2\].*too large"):
        Scene.from_robot("ur5", effects={"gravity": [0, 0, 10**400]})
    with pytest.raises(pinlin.SceneError, match="allow_non_equilibrium"):
        Scene.from_robot("ur5", operating_point={"allow_non_equilibrium": "no"})


@pytest.fixture(scope="module")
def pendulum_model() -> pinlin.LinearModel:
    return pinlin.linearize(Scene.load(URDF_DIR / "pendulum.toml"))


MODAL_CALLS = {
    "model_none": ({"model": None}, ["'model'", "LinearModel", "NoneType"]),
    "model_int": ({"model": 42}, ["'model'", "got int"]),
    "rigid_tol_string": ({"rigid_tol": "x"}, ["'rigid_tol'", "finite number >= 0"]),
    "rigid_tol_negative": ({"rigid_tol": -1.0}, ["'rigid_tol'", "-1.0"]),
    "rigid_tol_nan": ({"rigid_tol": float("nan")}, ["'rigid_tol'", "nan"]),
    "rigid_tol_inf": ({"rigid_tol": float("inf")}, ["'rigid_tol'", "inf"]),
    "rigid_tol_bool": ({"rigid_tol": True}, ["'rigid_tol'", "bool"]),
    "rigid_tol_huge_int": ({"rigid_tol": 10**400}, ["'rigid_tol'"]),
    "method_bogus": ({"method": "bogus"}, ["'method'", "'bogus'", "auto, symmetric, general"]),
    "method_none": ({"method": None}, ["'method'", "None"]),
}


@pytest.mark.parametrize("case", sorted(MODAL_CALLS))
def test_modal_refuses_bad_arguments(case, pendulum_model):
    kwargs, fragments = MODAL_CALLS[case]
    kwargs = {"model": pendulum_model, **kwargs}
    model = kwargs.pop("model")
    with pytest.raises(pinlin.ArgumentError) as info:
        pinlin.modal(model, **kwargs)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)


@pytest.mark.parametrize("value", [np.nan, np.inf, 1e200])
def test_modal_refuses_non_finite_or_huge_matrices(value, pendulum_model):
    # A model that skipped the constructor's checks (as one built by older code might have):
    # every field copied, one entry of A replaced.
    bad = object.__new__(pinlin.LinearModel)
    bad.__dict__.update(pendulum_model.__dict__)
    A = np.array(pendulum_model.A)
    A[1, 0] = value
    bad.__dict__["A"] = A
    with pytest.raises(pinlin.ModelError, match=r"matrix A .*A\[1, 0\]"):
        pinlin.modal(bad, method="general")


@pytest.mark.parametrize("value", ["1.0", "[1.0, 0, 0, 0, 0, 0]", "[1.0, 2.0]"])
def test_inputs_on_a_joint_without_any_say_so_whatever_their_count(value, tmp_path):
    """standing_box has no inputs at all: u on its free base is 'not actuated', not a count of
    6 inputs the scene does not have."""
    text = (URDF_DIR / "standing_box.toml").read_text().replace(
        'urdf = "standing_box.urdf"', f'urdf = "{URDF_DIR / "standing_box.urdf"}"')
    text += f'solve = "none"\nu = {{ root_joint = {value} }}\n'
    path = tmp_path / "box.toml"
    path.write_text(text)
    with pytest.raises(pinlin.SceneError, match=r"operating_point.u.root_joint.*is not "
                                                 r"actuated"):
        pinlin.linearize(Scene.load(path))


def _replaced(**changes):
    import dataclasses

    from pinlin.scene_effects import Rotation, Spring

    scene = pinlin.Scene.resolve("pendulum")
    R = dataclasses.replace
    made = {
        "negative_damping": lambda: R(scene, effects=R(scene.effects, damping={"hinge": -5.0})),
        "infinite_rest": lambda: R(scene, effects=R(scene.effects, springs={
            "hinge": Spring(1.0, float("inf"))})),
        "axis_not_unit": lambda: R(scene, effects=R(scene.effects, rotation=Rotation(
            (0.0, 0.0, 5.0), 1.0))),
        "axis_zero": lambda: R(scene, effects=R(scene.effects, rotation=Rotation(
            (0.0, 0.0, 0.0), 1.0))),
        "base_floating": lambda: R(scene, base="floating"),
        "q_boolean": lambda: R(scene, operating_point=R(scene.operating_point,
                                                        q={"hinge": True})),
        "q_huge": lambda: R(scene, operating_point=R(scene.operating_point,
                                                     q={"hinge": 1e300})),
        "gravity_text": lambda: R(scene, effects=R(scene.effects, gravity="down")),
        "v_text": lambda: R(scene, operating_point=R(scene.operating_point, solve="none",
                                                     v={"hinge": "x"})),
    }
    return made[changes["case"]]


@pytest.mark.parametrize("case, field", [
    ("negative_damping", "effects.damping.hinge"), ("infinite_rest", "effects.springs.rest"),
    ("axis_not_unit", "effects.rotation.axis"), ("axis_zero", "effects.rotation.axis"),
    ("base_floating", "base"), ("q_boolean", "operating_point.q.hinge"),
    ("q_huge", "operating_point.q.hinge"), ("gravity_text", "effects.gravity"),
    ("v_text", "operating_point.v.hinge")])
def test_scenes_changed_in_python_are_checked_like_files(case, field):
    """dataclasses.replace (the README's way to vary a scene) bypassed every check of the file
    parser: negative damping gave A[1, 1] = +4.995 (an unstable pendulum), a 5-long rotation
    axis spun the scene at 5 rad/s, text gravity a Boost.Python error."""
    with pytest.raises(pinlin.SceneError, match=f"field '{field}'"):
        _replaced(case=case)()


@pytest.mark.parametrize("argv, words", [
    (["linearize", "pendulum", "--formulation", "penalty", "--alpha", "5"],
     "argument '--alpha': scene 'pendulum' has no loops, contacts or mimic couplings"),
    (["linearize", "four_bar", "--mu", "2"], "argument '--mu': alpha, mu and omega set"),
])
def test_settings_with_nothing_to_act_on_are_refused(argv, words, capfd):
    """--alpha on an open chain was accepted and printed in the header, acting on nothing;
    the library's argument names become the command's options."""
    from pinlin.cli import main

    assert main(argv) == 2
    captured = capfd.readouterr()
    assert words in captured.err and captured.out == ""


def test_independent_joints_on_a_scene_without_constraints_are_refused(tmp_path):
    """operating_point.independent on an open chain was never looked up: a misspelt joint
    ('hinje') passed silently."""
    path = tmp_path / "scene.toml"
    path.write_text(f'urdf = "{URDF_DIR / "pendulum.urdf"}"\n'
                    '[operating_point]\nindependent = ["hinje"]\n')
    with pytest.raises(pinlin.SceneError, match="operating_point.independent.*has none"):
        pinlin.linearize(str(path))


def test_a_wound_spring_on_a_continuous_joint_is_refused(tmp_path):
    """A continuous joint's angle has no winding count: its spring acts on q - rest wrapped to
    (-pi, pi]. rest = 10 rad at q0 = 0 gave u0 = 20 (10 - 4 pi) = 51.3 N*m where the stated
    law -k (q - rest) needs -200: refused, naming the spring. Within pi the law holds: rest
    0.5 rad, k = 20 N*m/rad, no gravity: the input holds k (q0 - rest) = -10 N*m."""
    urdf = tmp_path / "cpend.urdf"
    text = (URDF_DIR / "pendulum.urdf").read_text().replace('type="revolute"',
                                                           'type="continuous"')
    urdf.write_text("\n".join(line for line in text.splitlines() if "<limit" not in line))
    scene = tmp_path / "scene.toml"
    for rest, q0 in ((10.0, 0.0), (0.0, 3.5)):
        scene.write_text(f'urdf = "{urdf}"\n[effects]\nsprings = {{ hinge = {{ stiffness = 20.0, '
                         f'rest = {rest} }} }}\n[operating_point]\nq = {{ hinge = {q0} }}\n')
        with pytest.raises(pinlin.SceneError, match=r"effects.springs.hinge.rest.*continuous"):
            pinlin.linearize(str(scene))
    scene.write_text(f'urdf = "{urdf}"\n[effects]\nsprings = {{ hinge = {{ stiffness = 20.0, '
                     'rest = 0.5 } }\n[operating_point]\nq = { hinge = 0.0 }\n')
    model = pinlin.linearize(str(scene))
    assert model.operating_point.u == pytest.approx([-10.0], abs=1e-12)
