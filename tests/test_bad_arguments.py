"""Bad arguments to pinlin.linearize and pinlin.operating_point, from Python and the CLI.

Every wrong type, out-of-range value or option that does not apply to the request is an
ArgumentError naming the argument; from the CLI it is one line on stderr and exit status 2.
Options are refused alike whatever the formulation (none is silently dropped)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import URDF_DIR

import pinlin
from pinlin.cli import main

PENDULUM = URDF_DIR / "pendulum.toml"
FOUR_BAR = URDF_DIR / "four_bar.toml"

BAD_CALLS = {  # name: (target, keyword arguments, argument named, words in the message)
    "scene_none": (None, {}, "scene", "got NoneType"),
    "scene_int": (42, {}, "scene", "got int"),
    "scene_list": ([PENDULUM], {}, "scene", "got list"),
    "q_strings": (PENDULUM, {"q": ["a"]}, "q", "got text"),
    "q_nested_junk": (PENDULUM, {"q": [[1.0], "x"]}, "q", "got text"),
    "q_object": (PENDULUM, {"q": object()}, "q", "expected 1 numbers"),
    "q_huge_int": (PENDULUM, {"q": [10**400]}, "q", "expected 1 numbers"),
    "allow_string": (PENDULUM, {"allow_non_equilibrium": "no"}, "allow_non_equilibrium",
                     "expected True or False"),
    "allow_int": (PENDULUM, {"allow_non_equilibrium": 0}, "allow_non_equilibrium",
                  "expected True or False"),
    "estimate_string": (PENDULUM, {"estimate_error": "yes"}, "estimate_error",
                        "expected True or False"),
    "formulation_int": (PENDULUM, {"formulation": 1}, "formulation", "expected one of"),
    "formulation_unknown": (PENDULUM, {"formulation": "lagrange"}, "formulation",
                            "'independent', 'penalty', 'canonical'"),
    "derivatives_unknown": (PENDULUM, {"derivatives": "fd7"}, "derivatives", "expected one of"),
    "step_with_analytic": (PENDULUM, {"step": 1e-3}, "step", "analytic derivatives take none"),
    "step_table_with_analytic": (PENDULUM, {"step": {"q": 1e-3}}, "step",
                                 "analytic derivatives take none"),
    "step_list": (PENDULUM, {"derivatives": "fd3", "step": [1e-3]}, "step",
                  "expected a number or a table"),
    "step_two_pi": (PENDULUM, {"derivatives": "fd5", "step": 6.283185307179586}, "step",
                    "outside [1e-10, 0.1]"),
    "basis_open_chain": (PENDULUM, {"basis": "orthonormal"}, "basis", "has no loops"),
    "basis_partitioned_open_chain": (PENDULUM, {"basis": "partitioned"}, "basis",
                                     "has no loops"),
    "basis_with_penalty": (FOUR_BAR, {"formulation": "penalty", "basis": "orthonormal"},
                           "basis", "the penalty formulation keeps the dependent"),
    "basis_with_canonical": (FOUR_BAR, {"formulation": "canonical", "basis": "partitioned"},
                             "basis", "the canonical formulation keeps the dependent"),
    "basis_unknown": (FOUR_BAR, {"basis": "qr"}, "basis", "expected one of"),
    "alpha_with_independent": (FOUR_BAR, {"alpha": 1e5}, "alpha",
                               "the independent formulation has no penalty"),
    "mu_with_independent": (FOUR_BAR, {"mu": 0.5}, "mu", "has no penalty"),
    "omega_with_independent": (FOUR_BAR, {"omega": 5.0}, "omega", "has no penalty"),
    "alpha_zero": (FOUR_BAR, {"formulation": "penalty", "alpha": 0.0}, "alpha", "> 0"),
    "alpha_string": (FOUR_BAR, {"formulation": "penalty", "alpha": "big"}, "alpha",
                     "must be a number"),
    "alpha_bool": (FOUR_BAR, {"formulation": "penalty", "alpha": True}, "alpha",
                   "must be a number"),
    "alpha_inf": (FOUR_BAR, {"formulation": "penalty", "alpha": float("inf")}, "alpha",
                  "finite number > 0"),
    "alpha_huge_int": (FOUR_BAR, {"formulation": "penalty", "alpha": 10**400}, "alpha",
                       "must be a number"),
    "mu_negative": (FOUR_BAR, {"formulation": "canonical", "mu": -1.0}, "mu", "> 0"),
    "omega_nan": (FOUR_BAR, {"formulation": "penalty", "omega": float("nan")}, "omega",
                  "finite number > 0"),
    "alpha_canonical_too_large": (FOUR_BAR, {"formulation": "canonical", "alpha": 1e14},
                                  "alpha", "canonical state matrix"),
    # Finite options whose products overflow (alpha Omega^2 = inf; 2 alpha mu Omega = inf).
    "omega_overflows": (FOUR_BAR, {"formulation": "penalty", "omega": 1e155}, "omega",
                        "alpha * omega^2 = inf"),
    "mu_overflows": (FOUR_BAR, {"formulation": "penalty", "mu": 1e300}, "mu",
                     "2 alpha mu omega = inf"),
    "alpha_beyond_limit": (FOUR_BAR, {"formulation": "canonical", "alpha": 1e300}, "alpha",
                           "must stay within 1e+100"),
}


@pytest.mark.parametrize("case", sorted(BAD_CALLS))
def test_bad_argument_names_the_argument(case):
    target, kwargs, argument, words = BAD_CALLS[case]
    with pytest.raises(pinlin.ArgumentError) as info:
        pinlin.linearize(target, **kwargs)
    assert info.value.argument == argument
    assert f"argument '{argument}'" in str(info.value) and words in str(info.value), info.value


BAD_CLI = {  # name: (argv, words on the one stderr line)
    "step_with_analytic": (["linearize", "pendulum", "--step", "1e-3"],
                           "analytic derivatives take none"),
    "step_two_pi": (["linearize", "pendulum", "--derivatives", "fd5", "--step",
                     "6.283185307179586"], "outside [1e-10, 0.1]"),
    "step_huge": (["linearize", "pendulum", "--derivatives", "fd5", "--step", "1e10"],
                  "outside [1e-10, 0.1]"),
    "step_tiny": (["linearize", "pendulum", "--derivatives", "fd3", "--step", "1e-300"],
                  "outside [1e-10, 0.1]"),
    "step_nan": (["linearize", "pendulum", "--derivatives", "fd3", "--step", "nan"],
                 "positive number"),
    "basis_open_chain": (["linearize", "pendulum", "--basis", "orthonormal"], "has no loops"),
    "basis_with_penalty": (["linearize", "four_bar", "--formulation", "penalty", "--basis",
                            "orthonormal"], "keeps the dependent coordinates"),
    "mu_with_independent": (["linearize", "four_bar", "--mu", "0.3"], "has no penalty"),
    "omega_inf": (["linearize", "four_bar", "--formulation", "penalty", "--omega", "inf"],
                  "finite number > 0"),
    "canonical_alpha_too_large": (["linearize", "four_bar", "--formulation", "canonical",
                                   "--alpha", "1e14"], "canonical state matrix"),
    "omega_overflows": (["linearize", "four_bar", "--formulation", "penalty", "--omega",
                         "1e300"], "penalty terms must stay within"),
}


@pytest.mark.parametrize("case", sorted(BAD_CLI))
def test_bad_option_gives_one_line_and_exit_2(case, capfd, tmp_path):
    argv, words = BAD_CLI[case]
    out_file = tmp_path / "m.npz"
    code = main([*argv, "--out", str(out_file)])
    _, err = capfd.readouterr()
    assert code == 2 and err.count("\n") == 1 and err.startswith("pinlin: error: "), err
    assert words in err and "Traceback" not in err
    assert not out_file.exists()


def test_operating_point_resolves_like_linearize():
    """One resolver for both entry points: on the four-bar, pinlin.operating_point assembles
    the loop and solves u0 and the constraint forces exactly as linearize does (it used to
    refuse the point, or with allow_non_equilibrium return the unassembled guess)."""
    model = pinlin.linearize(FOUR_BAR)
    scene = pinlin.Scene.load(FOUR_BAR)
    for allow in (None, True, False):
        op = pinlin.operating_point(scene, allow_non_equilibrium=allow)
        np.testing.assert_array_equal(op.q, model.operating_point.q)
        np.testing.assert_array_equal(op.u, model.operating_point.u)
        np.testing.assert_array_equal(op.lam, model.operating_point.lam)
        assert np.abs(scene.system.constraints.residual(op.q)).max() <= 1e-12
    # Statics by hand: S u0 + Phi_q^T lam = gravity - spring force at q0.
    s = scene.system
    lhs = s.input_matrix @ op.u + s.constraints.jacobian(op.q).T @ op.lam
    rhs = s.static_force(op.q) - s.spring_torque(op.q)
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)


def test_configuration_override_out_of_range_is_refused():
    with pytest.raises(pinlin.ShapeError, match="limited to"):
        pinlin.linearize(PENDULUM, q=np.array([1e300]))
    with pytest.raises(pinlin.ShapeError, match="NaN or inf"):
        pinlin.linearize(PENDULUM, q=np.array([np.inf]))


def test_operating_point_accepts_names_and_refuses_junk():
    op = pinlin.operating_point("pendulum")
    assert op.equilibrium and op.q.shape == (1,)
    with pytest.raises(pinlin.ArgumentError, match="argument 'scene'"):
        pinlin.operating_point(None)
    with pytest.raises(pinlin.ArgumentError, match="argument 'allow_non_equilibrium'"):
        pinlin.operating_point("pendulum", allow_non_equilibrium="yes")


def test_option_objects_equal_the_string_shortcuts():
    """pinlin.Penalty(...) / FiniteDifferences(...) carry exactly what the string shortcuts'
    keyword arguments carry: the same models."""
    a = pinlin.linearize(FOUR_BAR, formulation="penalty", alpha=1e5, mu=0.5, omega=7.0,
                         derivatives="fd5", step=1e-3)
    b = pinlin.linearize(FOUR_BAR, formulation=pinlin.Penalty(alpha=1e5, mu=0.5, omega=7.0),
                         derivatives=pinlin.FiniteDifferences(order=5, step=1e-3))
    np.testing.assert_array_equal(a.A, b.A)
    c = pinlin.linearize(FOUR_BAR, basis="orthonormal")
    d = pinlin.linearize(FOUR_BAR, formulation=pinlin.Independent(basis="orthonormal"))
    np.testing.assert_array_equal(c.A, d.A)
    e = pinlin.linearize(FOUR_BAR, formulation=pinlin.Canonical(alpha=1e5))
    assert e.info["formulation"] == "canonical" and e.info["alpha"] == 1e5


@pytest.mark.parametrize("make, argument", [
    (lambda: pinlin.Penalty(alpha=-1.0), "alpha"),
    (lambda: pinlin.Penalty(mu="x"), "mu"),
    (lambda: pinlin.Canonical(omega=float("inf")), "omega"),
    (lambda: pinlin.Independent(basis="qr"), "basis"),
    (lambda: pinlin.FiniteDifferences(order=4), "order"),
    (lambda: pinlin.FiniteDifferences(order=3.0), "order"),     # a KeyError 'fd3.0' before
    (lambda: pinlin.FiniteDifferences(order=True), "order"),
    (lambda: pinlin.FiniteDifferences(step=6.3), "step"),
    (lambda: pinlin.FiniteDifferences(estimate_error="no"), "estimate_error"),
    (lambda: pinlin.linearize(FOUR_BAR, formulation=pinlin.Penalty(), mu=0.3), "mu"),
    (lambda: pinlin.linearize(FOUR_BAR, formulation=pinlin.Independent(), basis="orthonormal"),
     "basis"),
    (lambda: pinlin.linearize(PENDULUM, derivatives=pinlin.FiniteDifferences(), step=1e-3),
     "step"),
    (lambda: pinlin.linearize(PENDULUM, formulation=pinlin.Independent(basis="orthonormal")),
     "basis"),
])
def test_bad_option_objects_name_their_field(make, argument):
    with pytest.raises(pinlin.ArgumentError) as info:
        make()
    assert info.value.argument == argument


@pytest.mark.parametrize("argv, argument", [
    (["linearize", ""], "SCENE_OR_ROBOT"),
    (["simulate", "", "--t-end", "1"], "SCENE_OR_ROBOT"),
    (["modes", ""], "SCENE_OR_ROBOT"),
    (["validate", "pendulum", ""], "SCENE_OR_ROBOT"),
    (["bench", ""], "SYSTEM"),
])
def test_an_empty_system_name_is_named_as_the_command_line_calls_it(argv, argument, capfd,
                                                                    tmp_path, monkeypatch):
    """The library's names for these arguments ('target', 'names', 'name') are not what the
    command line calls them."""
    monkeypatch.chdir(tmp_path)
    code = main(argv + (["--out-dir", str(tmp_path / "r")] if argv[0] in ("validate", "bench")
                        else []))
    _, err = capfd.readouterr()
    assert code == 2 and err.startswith(f"pinlin: error: argument '{argument}': ")
    assert err.count("\n") == 1 and not (tmp_path / "r").exists()


def _model(name: str = "double_pendulum") -> pinlin.LinearModel:
    return pinlin.linearize(pinlin.Scene.load(URDF_DIR / f"{name}.toml"))


@pytest.mark.parametrize("call, argument", [
    (lambda: pinlin.linearize_trajectory(pinlin.Scene.load(URDF_DIR / "double_pendulum.toml"),
                                         np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2)),
                                         t=np.zeros((3, 1))), "t"),
    (lambda: _model().discretize(np.full((2, 2), 0.01)), "dt"),
    (lambda: pinlin.modal(_model()).dominant(np.zeros((2, 2), dtype=int)), "index"),
])
def test_an_array_in_a_message_is_its_shape_on_one_line(call, argument):
    """A 2-D array where a number or a list was expected was shown by its repr, which numpy
    breaks over lines ("got array([[0.],\\n       [0.], ..."): now by its shape."""
    with pytest.raises(pinlin.ArgumentError) as exc:
        call()
    assert exc.value.argument == argument
    assert "\n" not in str(exc.value) and "an array of shape (" in str(exc.value)
