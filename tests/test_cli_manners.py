"""The CLI's manners (one-line warnings, flags named in refusals, --version, labelled matrices,
readable poses, zeta 0, plurals, graph poles) and one verdict on icub's singular mass matrix."""

from __future__ import annotations

import re
import warnings

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import REPO

import pinlin
from pinlin.cli import format_matrix, format_poles, main
from pinlin.conditioning import refuse_condition, scaled_condition

GRAPHS = REPO / "validation" / "graphs"


def run(capfd, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capfd.readouterr()
    return code, out, err


def one_error_line(err: str) -> str:
    assert err.count("\n") == 1 and err.startswith("pinlin: error: "), err
    return err


# ------------------------------------------------------------------------------------------
# Warnings

def test_accuracy_warning_is_one_line_without_source(capfd):
    code, _, err = run(capfd, "linearize", "ur5", "--derivatives", "fd3", "--step", "1e-9")
    assert code == 0
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("warning: model 'ur5': fd3 derivatives")
    assert ".py" not in err and "site-packages" not in err and "AccuracyWarning" not in err
    assert "--derivatives analytic" in err   # the way out, named as a flag


def test_library_users_keep_python_warnings(capfd):
    before = warnings.showwarning
    run(capfd, "linearize", "ur5", "--derivatives", "fd3", "--step", "1e-9")
    assert warnings.showwarning is before     # main() restores the hook
    with pytest.warns(pinlin.AccuracyWarning, match="estimated relative error"):
        pinlin.linearize("ur5", derivatives="fd3", step=1e-9)


# ------------------------------------------------------------------------------------------
# Refusals name the flag that lifts them

@pytest.mark.parametrize("formulation", ["independent", "penalty"])
def test_non_equilibrium_refusal_names_the_flag(capfd, formulation):
    code, _, err = run(capfd, "linearize", "solo12", "--formulation", formulation)
    assert code == 2
    one_error_line(err)
    assert "operating_point.allow_non_equilibrium = true" in err
    assert "(--allow-non-equilibrium on the command line)" in err


@pytest.mark.parametrize("command", [["simulate", "--t-end", "0.01"],
                                     ["response", "--t-end", "0.01"],
                                     ["validity", "--amplitudes", "0.01", "--modes", "7",
                                      "--periods", "0.1"]])
def test_every_command_that_names_the_flag_takes_it(capfd, command):
    """simulate, response and validity refused a non-equilibrium naming
    --allow-non-equilibrium, which they did not take (argparse: unrecognized arguments)."""
    name, *rest = command
    code, _, err = run(capfd, name, "solo12", *rest)
    assert code == 2 and "(--allow-non-equilibrium on the command line)" in err
    code, out, err = run(capfd, name, "solo12", *rest, "--allow-non-equilibrium")
    assert code == 0 and out, err


# ------------------------------------------------------------------------------------------
# Numbers on the command line

@pytest.mark.parametrize("argv, option", [
    (["response", "pendulum", "--t-end", "0.02", "--x0", "q:hinge=1_0"], "'--x0'"),
    (["response", "pendulum", "--t-end", "1_0"], "--t-end"),
    (["response", "pendulum", "--t-end", "0.02", "--step", "u:hinge=\u0663"], "'--step'"),
    (["validity", "pendulum", "--amplitudes", "0.0_1"], "--amplitudes"),
    (["linearize", "ur5", "--derivatives", "fd3", "--step", "1_0e-6"], "--step"),
])
def test_numbers_python_reads_but_no_one_writes_are_refused(capfd, argv, option):
    """float() reads "1_0" as 10 and "\u0663" (Arabic-Indic three) as 3: --x0 q:hinge=1_0
    started the pendulum 10 rad away. Refused, as in the CSV files."""
    code, out, err = run(capfd, *argv)
    assert code == 2 and not out
    one_error_line(err)
    assert option in err


# ------------------------------------------------------------------------------------------
# --version

def test_version_names_pinlin_and_its_libraries(capfd):
    code, out, err = run(capfd, "--version")
    assert code == 0 and err == "" and out.count("\n") == 1
    assert out.startswith(f"pinlin {pinlin.__version__} (")
    for label, version in (("pin", pin.__version__), ("mujoco", mujoco.__version__),
                           ("numpy", np.__version__)):
        assert f"{label} {version}" in out


def test_version_is_listed_in_help(capfd):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "--version" in capfd.readouterr().out


# ------------------------------------------------------------------------------------------
# Labelled matrices

def parse_matrix(text: str, key: str) -> tuple[list[str], list[str], np.ndarray]:
    """Rows, columns and values of matrix ``key`` as printed (all column blocks joined)."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(f"{key} = ("))
    n_rows, n_cols = (int(k) for k in re.findall(r"\d+", lines[start])[:2])
    columns: list[str] = []
    rows: list[str] = []
    blocks: list[np.ndarray] = []
    i = start + 1
    while len(columns) < n_cols:
        if lines[i].startswith(f"{key}, columns "):
            i += 1
        header = lines[i].split()
        columns += header
        body = [lines[i + 1 + k].split() for k in range(n_rows)]
        rows = [b[0] for b in body]
        blocks.append(np.array([[0.0 if c == "~0" else float(c) for c in b[1:]]
                                for b in body]))
        i += 1 + n_rows
    return rows, columns, np.hstack(blocks)


def test_matrices_have_row_and_column_names(capfd):
    code, out, _ = run(capfd, "linearize", "double_pendulum", "--matrices")
    assert code == 0
    model = pinlin.linearize("double_pendulum")
    for key, rows_expected, cols_expected in (
            ("A", model.state_names, model.state_names),
            ("B", model.state_names, model.input_names),
            ("C", model.output_names, model.state_names),
            ("D", model.output_names, model.input_names)):
        rows, cols, values = parse_matrix(out, key)
        assert tuple(rows) == rows_expected and tuple(cols) == cols_expected
        np.testing.assert_allclose(values, getattr(model, key), rtol=1e-5, atol=1e-12)


def test_wide_matrices_print_in_labelled_column_blocks(capfd):
    code, out, _ = run(capfd, "linearize", "ur5", "--matrices")
    assert code == 0
    matrices = out[out.index("A = ("):]
    assert max(len(line) for line in matrices.splitlines()) <= 100
    model = pinlin.linearize("ur5")
    assert "A, columns 1-" in out and f"of {model.n_states} (" in out
    rows, cols, values = parse_matrix(out, "A")
    assert tuple(cols) == model.state_names and tuple(rows) == model.state_names
    np.testing.assert_allclose(values, model.A, rtol=1e-5, atol=1e-12 * np.abs(model.A).max())


def test_format_matrix_marks_noise_and_empty():
    text = format_matrix("X", np.array([[1.0, 1e-17], [0.0, -0.0]]), ["r1", "r2"], ["a", "b"])
    assert text.splitlines() == ["X = (2 x 2)", "    a   b", "r1  1  ~0", "r2  0   0"]
    assert format_matrix("B", np.zeros((2, 0)), ["r1", "r2"], []) == "B = (2 x 0) empty"


# ------------------------------------------------------------------------------------------
# Floating-base pose

def test_floating_base_pose_prints_position_and_rpy(capfd, write_scene):
    path = write_scene("""
robot = "solo12"
[effects]
[operating_point]
q = { root_joint = { position = [0.1, -0.2, 0.4], rpy = [0.1, 0.2, 0.3] } }
""")
    code, out, _ = run(capfd, "linearize", str(path))
    assert code == 0
    assert "  q[root_joint] = position [0.1 -0.2 0.4] m, rpy [0.1 0.2 0.3] rad\n" in out


# ------------------------------------------------------------------------------------------
# zeta of undamped modes

def test_undamped_modes_print_zeta_zero(capfd):
    code, out, _ = run(capfd, "linearize", "double_pendulum", "--method", "general")
    assert code == 0
    modes = pinlin.modal(pinlin.linearize("double_pendulum"), method="general")
    assert np.any(modes.eigenvalues.real != 0.0)       # rounding leaves tiny real parts ...
    rows = [line for line in out.splitlines() if "undamped" in line]
    assert len(rows) == 2
    for row in rows:                                    # ... printed as 0, zeta too
        cells = row.split()
        assert cells[1] == "0" and cells[6] == "0" and "e-" not in row, row
    assert modes.is_stable and not modes.unstable.any()
    assert np.all(np.abs(modes.eigenvalues.real) <= modes.rounding)


def test_damped_modes_keep_their_zeta(capfd):
    code, out, _ = run(capfd, "linearize", "ur5_arm")
    assert code == 0
    modes = pinlin.modal(pinlin.linearize("ur5_arm"))
    assert f"{modes.zeta[0]:.4g}" in out and "oscillatory" in out
    assert np.all(np.abs(modes.eigenvalues.real) > 1e3 * modes.rounding)


# ------------------------------------------------------------------------------------------
# Plurals

def test_one_input_is_singular(capfd):
    code, out, _ = run(capfd, "linearize", "pendulum")
    assert code == 0
    assert "1 input, 5 outputs" in out and "1 inputs" not in out


def test_plural_helper():
    from pinlin.cli_format import plural as _plural

    assert _plural(1, "branch", "branches") == "1 branch"
    assert _plural(0, "branch", "branches") == "0 branches"
    assert _plural(2, "output") == "2 outputs"


# ------------------------------------------------------------------------------------------
# pinlin graph

def test_graph_prints_poles_after_the_matrices(capfd):
    code, out, _ = run(capfd, "graph", str(GRAPHS / "series_rlc.toml"))
    assert code == 0
    model = pinlin.graph.Graph.load(GRAPHS / "series_rlc.toml").linearize()
    last = out.splitlines()[-1]
    assert last.startswith("poles (eigenvalues of A) [1/s]: ")
    assert out.index("A = (") < out.index("poles")
    lam = np.linalg.eigvals(model.A)
    pair = lam[lam.imag > 0][0]
    assert last.endswith(f"{pair.real:.6g} +- {pair.imag:.6g}j")


def test_format_poles():
    assert format_poles(np.zeros((0, 0))) == "none"
    assert format_poles(np.diag([-3.0, -1.0])) == "-1, -3"
    assert format_poles(np.array([[0.0, 1.0], [-4.0, 0.0]])) == "0 +- 2j"


def test_standard_form_names_its_new_state(capfd):
    with pytest.raises(SystemExit):
        main(["graph", "--help"])
    help_text = " ".join(capfd.readouterr().out.split())
    assert "new state x' = x - E u" in help_text
    code, out, _ = run(capfd, "graph", str(GRAPHS / "lead_lag.toml"), "--standard-form")
    assert code == 0 and "new state x' = x - E u" in out and "states: v:C2'" in out
    assert "poles (eigenvalues of A) [1/s]: -20" in out


# ------------------------------------------------------------------------------------------
# icub: one verdict on a mass matrix singular to working precision

ICUB_ROTATED = {"allow_non_equilibrium": True,
                "q": {"root_joint": {"position": [0.1, -0.2, 1.0], "rpy": [0.2, -0.1, 0.5]}}}


def check_icub_message(message: str) -> None:
    assert "singular to working precision" in message
    assert "neck_yaw" in message and "neck_roll" in message
    assert "'head' (1.34 kg)" in message and "no rotational inertia" in message
    assert "allow_ill_conditioned=True (--allow-ill-conditioned on the command line)" in message
    assert "r_wrist_prosup" not in message


def test_icub_mass_matrix_is_singular_at_its_reference_posture():
    """Independent of pinlin's message: the head (1.34 kg) is a point mass, neck_2 a point
    mass on the neck_roll and neck_yaw axes, and at neck_yaw = 0 the head's centre of mass
    lies in the plane of those axes: one combination of them moves no mass at all."""
    system = pinlin.Scene.from_robot("icub").system
    model, q = system.model, system.q_ref
    head = model.getJointId("neck_yaw")
    assert np.abs(model.inertias[head].inertia).max() < 1e-30   # the URDF's ixz = 2.4e-35
    assert model.inertias[head].mass > 1.0
    M = pin.crba(model, model.createData(), q)
    w = np.linalg.eigvalsh(M)
    assert w[0] <= 1e3 * np.finfo(float).eps * w[-1]          # zero up to rounding
    # Also scaled to unit diagonal (units do not matter): rank-deficient by matrix_rank's rule.
    d = np.sqrt(np.diag(M))
    assert np.linalg.matrix_rank(M / np.outer(d, d), hermitian=True) == model.nv - 1
    assert scaled_condition(M) >= refuse_condition(model.nv)
    v = np.zeros(model.nv)
    v[model.joints[head].idx_v] = 1.0
    v[model.joints[model.getJointId("neck_roll")].idx_v] = -0.0185 / 0.1108  # lever x / y
    assert v @ M @ v <= 1e-12 * (v @ v) * w[-1]
    q_turned = q.copy()
    q_turned[model.joints[head].idx_q] = 0.3                  # away from neck_yaw = 0
    assert scaled_condition(pin.crba(model, model.createData(), q_turned)) < 1e-6 * \
        refuse_condition(model.nv)


def test_icub_is_refused_with_the_reason_in_library_and_cli(capfd):
    with pytest.raises(pinlin.ModelError) as info:
        pinlin.linearize(pinlin.Scene.from_robot("icub"), allow_non_equilibrium=True)
    check_icub_message(str(info.value))
    # The base pose validate uses (M^-1 comes out with a negative diagonal there): same verdict.
    with pytest.raises(pinlin.ModelError) as rotated:
        pinlin.linearize(pinlin.Scene.from_robot("icub", operating_point=ICUB_ROTATED))
    check_icub_message(str(rotated.value))
    code, out, err = run(capfd, "linearize", "icub", "--allow-non-equilibrium")
    assert code == 2 and out == ""
    check_icub_message(one_error_line(err))


def test_icub_opt_in_gives_a_model_and_one_line_warnings(capfd):
    code, out, err = run(capfd, "linearize", "icub", "--allow-non-equilibrium",
                         "--allow-ill-conditioned")
    assert code == 0 and "Modes of 'icub'" in out
    assert err and all(line.startswith("warning: ") for line in err.splitlines())
    assert "about 0 significant digits" in err
    with pytest.warns(pinlin.AccuracyWarning, match="about 0 significant digits"):
        model = pinlin.linearize("icub", allow_non_equilibrium=True, allow_ill_conditioned=True)
    assert np.all(np.isfinite(model.A))
    with pytest.raises(pinlin.ArgumentError, match="allow_ill_conditioned"):
        pinlin.linearize("icub", allow_ill_conditioned="yes")


def test_icub_turned_head_linearizes():
    """With the neck turned the head's point mass no longer sits on both neck axes: M is
    regular, its condition scaled to unit diagonal 4e4 (unscaled 1e8), far from the
    refusal limit and below the warning."""
    q = pinlin.Scene.from_robot("icub").system.q_ref.copy()
    system = pinlin.Scene.from_robot("icub").system
    q[system.joints["neck_yaw"].idx_q] = 0.3
    with warnings.catch_warnings():
        warnings.simplefilter("error", pinlin.AccuracyWarning)
        model = pinlin.linearize(system, q=q, allow_non_equilibrium=True)
    assert 1e3 < model.info["condition"]["mass_matrix"] < 1e10


# A point mass turned about an axis through it by a combination of two joints: M has no zero
# row, yet is exactly singular (the icub case in a few lines of URDF); M^-1 is not finite, so
# no opt-in can give a model.
TWO_AXES_URDF = """<?xml version="1.0"?>
<robot name="two_axes">
  <link name="base"/>
  <link name="gimbal"><inertial><mass value="0.1"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="bob"><inertial><origin xyz="0.5 0 -0.5"/><mass value="1.0"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="roll" type="revolute"><parent link="base"/><child link="gimbal"/>
    <axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="yaw" type="revolute"><parent link="gimbal"/><child link="bob"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


def test_point_mass_on_the_axis_of_two_joints_is_named(capfd, write_scene):
    path = write_scene('urdf = "two_axes.urdf"\n', two_axes__urdf=TWO_AXES_URDF)
    for extra in ((), ("--allow-ill-conditioned",)):
        code, _, err = run(capfd, "linearize", str(path), *extra)
        assert code == 2
        one_error_line(err)
        assert "the mass matrix is singular at q0" in err
        assert "the motion [roll +1, yaw -1]" in err
        assert "it turns 'bob' (1 kg) and 'gimbal' (0.1 kg) about axes through their centres " \
               "of mass, and they have no rotational inertia about them" in err
        assert "--allow-ill-conditioned" not in err      # it would not help


def test_coordinate_without_inertia_is_refused_even_with_the_opt_in(capfd):
    code, _, err = run(capfd, "linearize", "bravo7_gripper", "--allow-ill-conditioned")
    assert code == 2
    one_error_line(err)
    assert "coordinate 'bravo_finger1_joint' carries no inertia (row 6 of M is zero)" in err
    assert "nor does 1 other coordinate (bravo_finger2_joint)" in err


@pytest.mark.parametrize("argv", [["ur5_arm", "--method", "symmetric"],
                                  ["four_bar", "--formulation", "penalty", "--method",
                                   "symmetric"]])
def test_symmetric_solver_refused_before_anything_is_printed(argv, capfd):
    """The damped ur5 and the penalty four-bar have velocity terms: the symmetric solver does
    not apply, and the refusal comes alone (before, after 13-16 lines of results)."""
    code, out, err = run(capfd, "linearize", *argv)
    assert code == 2 and out == ""
    assert "symmetric (K, M) eigensolver does not apply" in one_error_line(err)


# ------------------------------------------------------------------------------------------
# Start-up

def test_importing_pinlin_leaves_the_heavy_optional_modules_unloaded():
    """Every command imports pinlin; what only some commands use is imported where it is used
    (MuJoCo by validate and export, matplotlib by pictures, scipy.integrate by simulate,
    scipy.optimize by nonlinear graphs, Dask by --dask): a few tenths of a second each."""
    import subprocess
    import sys

    heavy = ("mujoco", "matplotlib", "scipy.integrate", "scipy.optimize", "dask")
    code = ("import sys, pinlin, pinlin.cli; "
            f"print(' '.join(m for m in {heavy!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=REPO).stdout
    assert out.split() == []
