"""A catalogue of bad input: URDF, scene TOML, CLI arguments, operating point and loops.

Each case names the exception class pinlin raises from Python and a fragment of its message;
from the CLI the same input gives one line on stderr, exit status 2, no traceback and nothing
written to --out.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.cli import main

PENDULUM = (URDF_DIR / "pendulum.urdf").read_text()

EXCEPTION = {
    "armature_true_on_urdf": pinlin.SceneError,
    "bad_base": pinlin.SceneError,
    "bad_inertia": pinlin.UrdfError,
    "both_sources": pinlin.SceneError,
    "independent_wrong_size": pinlin.SceneError,
    "loop_adds_nothing": pinlin.SceneError,
    "loop_bad_type": pinlin.SceneError,
    "loop_cannot_close": pinlin.AssemblyError,
    "loop_same_body": pinlin.SceneError,
    "loop_unknown_frame": pinlin.UnknownNameError,
    "loop_without_frames": pinlin.SceneError,
    "malformed_toml": pinlin.SceneError,
    "malformed_urdf": pinlin.UrdfError,
    "massless_joint": pinlin.ModelError,
    "mimic_without_tags": pinlin.SceneError,
    "missing_urdf": pinlin.UrdfError,
    "nan_gravity": pinlin.SceneError,
    "negative_damping": pinlin.SceneError,
    "negative_mass": pinlin.UrdfError,
    "non_unit_quaternion": pinlin.SceneError,
    "not_a_urdf": pinlin.UrdfError,
    "not_equilibrium": pinlin.EquilibriumError,
    "q_wrong_count": pinlin.SceneError,
    "q_wrong_type": pinlin.SceneError,
    "rotation_off_axis": pinlin.SceneError,
    "spring_without_stiffness": pinlin.SceneError,
    "u_with_solve_inputs": pinlin.SceneError,
    "unknown_effect": pinlin.SceneError,
    "unknown_frame": pinlin.UnknownNameError,
    "unknown_input": pinlin.UnknownNameError,
    "unknown_joint_in_q": pinlin.UnknownNameError,
    "unknown_top_key": pinlin.SceneError,
    "wrong_length": pinlin.SceneError,
}


def run(capfd, *argv):
    code = main(list(argv))
    out, err = capfd.readouterr()
    return code, out, err


GOOD_URDF = {"robot__urdf": PENDULUM}
FOUR_BAR = (URDF_DIR / "four_bar.toml").read_text().replace("four_bar.urdf", "robot.urdf")
FOUR_BAR_URDF = {"robot__urdf": (URDF_DIR / "four_bar.urdf").read_text()}
SECOND_LOOP = ('\n[[loops]]\nname = "again"\ntype = "point"\nframe1 = "rocker_tip"\n'
               'frame2 = "coupler_tip"\n')

BAD_SCENES = {
    "missing_urdf": ('urdf = "missing.urdf"\n', {}, "missing.urdf: file not found"),
    "malformed_toml": ('urdf = "robot.urdf"\n[effects\n', GOOD_URDF, "malformed TOML"),
    "unknown_joint_in_q": ('urdf = "robot.urdf"\n[operating_point]\nq = { elbow = 1.0 }\n',
                           GOOD_URDF, "'elbow' is not a joint"),
    "unknown_effect": ('urdf = "robot.urdf"\n[effects]\nfriction = 1.0\n', GOOD_URDF,
                       "field 'effects.friction': unknown key"),
    "nan_gravity": ('urdf = "robot.urdf"\n[effects]\ngravity = [nan, 0.0, -9.81]\n', GOOD_URDF,
                    "expected a finite number"),
    "wrong_length": ('urdf = "robot.urdf"\n[effects]\ngravity = [0.0, -9.81]\n', GOOD_URDF,
                     "expected 3 numbers"),
    "negative_damping": ('urdf = "robot.urdf"\n[effects]\ndamping = { hinge = -1.0 }\n',
                         GOOD_URDF, "expected a number >= 0"),
    "unknown_frame": ('urdf = "robot.urdf"\n[outputs]\nframes = ["hand"]\n', GOOD_URDF,
                      "'hand' is not a frame"),
    "unknown_input": ('urdf = "robot.urdf"\n[inputs]\nactuated = ["knee"]\n', GOOD_URDF,
                      "field 'inputs.actuated': 'knee' is not a joint"),
    "both_sources": ('urdf = "robot.urdf"\nrobot = "ur5"\n', GOOD_URDF, "exactly one of"),
    "bad_base": ('urdf = "robot.urdf"\nbase = "floating"\n', GOOD_URDF,
                 "expected one of 'fixed', 'free'"),
    "unknown_top_key": ('urdf = "robot.urdf"\ngravity = true\n', GOOD_URDF,
                        "field 'gravity': unknown key"),
    "malformed_urdf": ('urdf = "robot.urdf"\n', {"robot__urdf": "<robot><link></robot>"},
                       "malformed XML"),
    "not_a_urdf": ('urdf = "robot.urdf"\n', {"robot__urdf": "<sdf/>"}, "must be <robot>"),
    "negative_mass": ('urdf = "robot.urdf"\n',
                      {"robot__urdf": PENDULUM.replace('value="1.0"', 'value="-2.0"')},
                      "mass must be a finite number >= 0"),
    "bad_inertia": ('urdf = "robot.urdf"\n',
                    {"robot__urdf": PENDULUM.replace('ixx="0.001"', 'ixx="-1"')},
                    "not positive semi-definite"),
    "spring_without_stiffness": ('urdf = "robot.urdf"\n[effects]\nsprings = { hinge = '
                                 '{ rest = 0.1 } }\n', GOOD_URDF, "stiffness': missing"),
    "q_wrong_type": ('urdf = "robot.urdf"\n[operating_point]\nq = { hinge = "up" }\n', GOOD_URDF,
                     "expected a number, a list of numbers or a table"),
    "q_wrong_count": ('urdf = "robot.urdf"\n[operating_point]\nq = { hinge = [0.1, 0.2] }\n',
                      GOOD_URDF, "has 1 configuration values, got 2"),
    "armature_true_on_urdf": ('urdf = "robot.urdf"\n[effects]\narmature = true\n', GOOD_URDF,
                              "this robot has none"),
    "loop_without_frames": ('urdf = "robot.urdf"\n[[loops]]\nname = "x"\n', GOOD_URDF,
                            "field 'loops[0].frame1': missing"),
    "non_unit_quaternion": ('robot = "solo12"\n[operating_point]\nq = { root_joint = { '
                            'quaternion = [0.0, 0.0, 0.0, 2.0] } }\n', {}, "unit quaternion"),
    "not_equilibrium": ('robot = "solo12"\n[effects]\ngravity = true\n', {},
                        "is not an equilibrium"),
    "loop_unknown_frame": (FOUR_BAR.replace('frame2 = "rocker_tip"', 'frame2 = "rocker_tpi"'),
                           FOUR_BAR_URDF, "'rocker_tpi' is not a frame of the robot"),
    "loop_cannot_close": (FOUR_BAR.replace('independent = ["crank"]', 'independent = ["rocker"]')
                          .replace("rocker = 1.6 }", "rocker = 0.0 }"), FOUR_BAR_URDF,
                          "the loops do not close from the given q"),
    "loop_adds_nothing": (FOUR_BAR + SECOND_LOOP, FOUR_BAR_URDF,
                          "loop 'again' adds no independent constraint"),
    "loop_same_body": (FOUR_BAR.replace('frame2 = "rocker_tip"', 'frame2 = "coupler_link"'),
                       FOUR_BAR_URDF, "are on the same body"),
    "independent_wrong_size": (FOUR_BAR.replace('independent = ["crank"]',
                                                'independent = ["crank", "rocker"]'),
                               FOUR_BAR_URDF, "expected 1 coordinates"),
    "loop_bad_type": (FOUR_BAR.replace('type = "point"', 'type = "hinge"'), FOUR_BAR_URDF,
                      "field 'loops[0].type': expected one of 'point', 'weld'"),
    "rotation_off_axis": ('urdf = "robot.urdf"\n[effects]\ngravity = [0.0, 0.0, -9.81]\n'
                          'rotation = { axis = [1.0, 0.0, 0.0], rate = 2.0 }\n', GOOD_URDF,
                          "a steady rotation needs gravity along the rotation axis"),
    "mimic_without_tags": ('urdf = "robot.urdf"\n[effects]\nmimic = true\n', GOOD_URDF,
                           "has no <mimic> joints"),
    "u_with_solve_inputs": ('urdf = "robot.urdf"\n[operating_point]\nu = { hinge = 1.0 }\n',
                            GOOD_URDF, "inputs are given only with solve"),
    "massless_joint": ('urdf = "robot.urdf"\n',
                       {"robot__urdf": PENDULUM.replace('value="1.0"', 'value="0.0"')
                                       .replace('"0.001"', '"0"')},
                       "carries no inertia"),
}


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scene_gives_one_line_and_exit_2(case, write_scene, capfd, tmp_path):
    text, files, fragment = BAD_SCENES[case]
    path = write_scene(text, **files)
    out_file = tmp_path / "never.npz"
    code, out, err = run(capfd, "linearize", str(path), "--out", str(out_file))
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("pinlin: error: ")
    assert fragment in err, err
    assert "Traceback" not in err and not out_file.exists()


BAD_ARGS = {
    "unknown_robot": (["linearize", "robocop"], "'robocop' is not a scene file"),
    "missing_scene_file": (["linearize", "nowhere/scene.toml"], "scene file not found"),
    "bad_out_suffix": (["linearize", "pendulum", "--out", "m.txt"], "unknown model format"),
    "out_folder_missing": (["linearize", "pendulum", "--out", "/nonexistent/dir/m.npz"],
                           "does not exist"),
    "bad_derivatives": (["linearize", "pendulum", "--derivatives", "fd7"], "invalid choice"),
    "bad_step": (["linearize", "pendulum", "--derivatives", "fd3", "--step", "-1"],
                 "step must be a positive number"),
    "unknown_option": (["linearize", "pendulum", "--fast"], "unrecognized arguments"),
    "no_command": ([], "required"),
    "alpha_not_positive": (["linearize", "four_bar", "--formulation", "penalty", "--alpha", "0"],
                           "penalty alpha must be a finite number > 0"),
    "alpha_for_independent": (["linearize", "four_bar", "--alpha", "1e5"],
                              "the independent formulation has no penalty"),
    "bad_formulation": (["linearize", "four_bar", "--formulation", "lagrange"],
                        "invalid choice"),
    "validate_nothing": (["validate"], "name scenes or robots, or give --all"),
    "export_mjcf_suffix": (["export-mjcf", "four_bar", "-o", "model.txt"],
                           "expected an .xml file"),
    "export_mjcf_rotation": (["export-mjcf", "rotating_double_pendulum", "-o", "/tmp/x.xml"],
                             "steady rotation has no MuJoCo counterpart"),
    "bench_unknown_system": (["bench", "robocop", "--no-progress"], "'robocop' is not"),
    "bench_bad_repeats": (["bench", "ur5", "--repeats", "0", "--no-progress"],
                          "--repeats must be >= 1"),
    "bench_repeats_not_a_number": (["bench", "ur5", "--repeats", "abc"], "invalid int value"),
    "memory_limit_malformed": (["linearize", "pendulum", "--memory-limit", "8Q"],
                               "'8Q' is not a size"),
    "memory_limit_too_small": (["linearize", "pendulum", "--memory-limit", "1K"],
                               "raise it with --memory-limit"),
}


@pytest.mark.parametrize("case", sorted(BAD_ARGS))
def test_bad_arguments_give_one_line_and_exit_2(case, capfd):
    argv, fragment = BAD_ARGS[case]
    code, _, err = run(capfd, *argv)
    assert code == 2 and err.count("\n") == 1 and fragment in err, err
    assert err.startswith("pinlin: error: "), err
    assert "Traceback" not in err


def test_console_script_bad_input_has_no_traceback(tmp_path):
    res = subprocess.run([sys.executable, "-m", "pinlin.cli", "linearize", "robocop"],
                         capture_output=True, text=True, check=False)
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "Traceback" not in res.stderr


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scene_raises_the_named_error_from_python(case, write_scene):
    text, files, fragment = BAD_SCENES[case]
    path = write_scene(text, **files)
    with pytest.raises(EXCEPTION[case]) as info:
        pinlin.linearize(pinlin.Scene.load(path))
    assert fragment in " ".join(str(info.value).split())


def test_catalogue_size():
    assert len(BAD_SCENES) + len(BAD_ARGS) >= 25


def test_nan_configuration_from_python_is_refused():
    scene = pinlin.Scene.load(URDF_DIR / "pendulum.toml")
    with pytest.raises(pinlin.ShapeError, match="NaN"):
        pinlin.linearize(scene, q=np.array([np.nan]))
    with pytest.raises(pinlin.ShapeError, match="nq = 1"):
        pinlin.linearize(scene, q=np.zeros(3))
