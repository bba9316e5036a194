"""Gain files (``pinlin.read_gain``, ``pinlin.write_gain``) and the command line's
``--feedback``. References from outside the code under test: a hand-written ODE of the
inverted pendulum under u = -K x (solve_ivp), the closed loop's exponential
expm((A - B K) t) x0 (scipy), and gains permuted by hand."""

from __future__ import annotations

import pickle
import warnings

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg as sla
from conftest import URDF_DIR, deadline
from scipy.signal import place_poles

import pinlin
from pinlin.cli import main

G = 9.81
#: urdf/pendulum.urdf: 1 kg sphere (r = 0.05 m) 1 m below the hinge: J = 1 + 2/5 * 0.05^2.
J_PENDULUM = 1.001
MGL = 1.0 * G * 1.0   # [N*m]


def _upright(tmp_path):
    """The bundled pendulum's scene held upright (q0 = pi), as a scene file."""
    path = tmp_path / "upright.toml"
    path.write_text(f'name = "upright"\nurdf = "{URDF_DIR / "pendulum.urdf"}"\n'
                    'base = "fixed"\n[effects]\ngravity = [0.0, 0.0, -9.81]\n'
                    '[operating_point]\nq = { hinge = 3.141592653589793 }\nsolve = "inputs"\n'
                    '[inputs]\nactuated = ["hinge"]\n')
    return path


def _run(capfd, *argv):
    code = main([str(a) for a in argv])
    out, err = capfd.readouterr()
    return code, out, err


def test_a_written_gain_reads_back_bit_for_bit_and_names_its_point(tmp_path):
    model = pinlin.linearize("double_pendulum")
    K = np.random.default_rng(1).standard_normal((model.n_inputs, model.n_states)) * 1e3
    path = pinlin.write_gain(tmp_path / "K.csv", K, model)
    np.testing.assert_array_equal(pinlin.read_gain(path, model), K)
    text = path.read_text()
    assert "# q0 = " in text and "input," + ",".join(model.state_names) in text
    pinlin.write_gain(path, 2 * K, model)          # pinlin replaces its own file
    np.testing.assert_array_equal(pinlin.read_gain(path, model), 2 * K)
    np.save(tmp_path / "K.npy", K)
    np.testing.assert_array_equal(pinlin.read_gain(tmp_path / "K.npy", model), K)


def test_rows_and_columns_in_any_order_are_put_in_the_models(tmp_path):
    """A hand-written file with the states and inputs shuffled: K put back in the model's
    orders (the permutation applied by hand)."""
    model = pinlin.linearize("double_pendulum")
    K = np.arange(1.0, 1.0 + model.n_inputs * model.n_states).reshape(model.n_inputs, -1)
    cols = [3, 0, 2, 1][:model.n_states]
    rows = list(range(model.n_inputs))[::-1]
    lines = ["# written by hand", "input," + ",".join(model.state_names[c] for c in cols)]
    lines += [model.input_names[r] + "," + ",".join(repr(float(K[r, c])) for c in cols)
              for r in rows]
    path = tmp_path / "K.csv"
    path.write_text("\n".join(lines) + "\n")
    np.testing.assert_array_equal(pinlin.read_gain(path, model), K)


BAD_CSV = {
    "not_a_state": ("input,q:shoulder,q:elbow,v:shoulder,v:knee\n",
                    "line 1: 'v:knee' is not a state of model 'double_pendulum'"),
    "state_twice": ("input,q:shoulder,q:elbow,v:shoulder,q:elbow\n", "'q:elbow' appears twice"),
    "state_missing": ("input,q:shoulder,q:elbow,v:shoulder\nu:shoulder,1,2,3\n",
                      "missing state v:elbow"),
    "no_row_label": ("q:shoulder,q:elbow,v:shoulder,v:elbow\n", "expected 'input'"),
    "input_missing": ("input,q:shoulder,q:elbow,v:shoulder,v:elbow\nu:shoulder,1,2,3,4\n",
                      "no line for input u:elbow"),
    "input_twice": ("input,q:shoulder,q:elbow,v:shoulder,v:elbow\nu:elbow,1,2,3,4\n"
                    "u:elbow,1,2,3,4\n", "line 3: input 'u:elbow' appears twice"),
    "not_an_input": ("input,q:shoulder,q:elbow,v:shoulder,v:elbow\nu:wrist,1,2,3,4\n",
                     "'u:wrist' is not an input"),
    "short_line": ("input,q:shoulder,q:elbow,v:shoulder,v:elbow\nu:elbow,1,2,3\n",
                   "line 2: 4 values, the header names 5"),
    "text": ("input,q:shoulder,q:elbow,v:shoulder,v:elbow\nu:elbow,1,x,3,4\n",
             "line 2, column 'q:elbow': 'x' is not a number"),
    "nan": ("input,q:shoulder,q:elbow,v:shoulder,v:elbow\nu:elbow,1,nan,3,4\n",
            "'nan' is not a finite number"),
    "empty": ("# nothing\n", "empty"),
    "other_point": ("# q0 = 0.5,0\ninput,q:shoulder,q:elbow,v:shoulder,v:elbow\n",
                    "line 1: the gain was designed about another point: q0\\[0\\] = 0.5 in "
                    "the file, 0.0 for model"),
    "point_near_pi": ("# q0 = 3.141592657589793,0\ninput,q:shoulder,q:elbow,v:shoulder,"
                      "v:elbow\n", "q0\\[0\\] = 3.141592657589793 in the file, 0.0"),
    "bad_point": ("# v0 = fast\ninput,q:shoulder,q:elbow,v:shoulder,v:elbow\n",
                  "line 1, design point v0: 'fast' is not a number"),
    "nan_point": ("# v0 = nan,0\ninput,q:shoulder,q:elbow,v:shoulder,v:elbow\n",
                  "line 1, design point v0: 'nan' is not a finite number"),
    "point_size": ("# q0 = 0,0,0\ninput,q:shoulder,q:elbow,v:shoulder,v:elbow\n",
                   "the design point q0 has 3 entries; model 'double_pendulum' has 2"),
    "point_spelled_otherwise": ("## Q0: 1,1\ninput,q:shoulder,q:elbow,v:shoulder,v:elbow\n",
                                "designed about another point"),
    "point_twice": ("# q0 = 0,0\n# q0 = 0,0\ninput,q:shoulder,q:elbow,v:shoulder,v:elbow\n",
                    "line 2: a second design point q0"),
    "form_feed_in_a_comment": ("# a\x0cq0 = 1,1\ninput,q:shoulder,q:elbow,v:shoulder,v:elbow"
                               "\nu:elbow,1,2,3,4\n", "no line for input u:shoulder"),
}


@pytest.mark.parametrize("case", sorted(BAD_CSV))
def test_bad_gain_files_name_the_line_and_what_is_wrong(case, tmp_path):
    text, match = BAD_CSV[case]
    model = pinlin.linearize("double_pendulum")
    path = tmp_path / "K.csv"
    path.write_text(text)
    with pytest.raises(pinlin.ModelFileError, match=match):
        pinlin.read_gain(path, model)


def test_bad_npy_gains_are_refused(tmp_path):
    model = pinlin.linearize("double_pendulum")
    np.save(tmp_path / "wide.npy", np.zeros((2, 6)))
    with pytest.raises(pinlin.ModelFileError, match="2x6 array; model 'double_pendulum' "
                                                    "needs 2 x 4"):
        pinlin.read_gain(tmp_path / "wide.npy", model)
    np.save(tmp_path / "obj.npy", np.array([{"K": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(pinlin.ModelFileError, match="a pickle"):
        pinlin.read_gain(tmp_path / "obj.npy", model)
    raw = (tmp_path / "wide.npy").read_bytes()
    (tmp_path / "cut.npy").write_bytes(raw[:-40])
    with pytest.raises(pinlin.ModelFileError, match="header declares shape"):
        pinlin.read_gain(tmp_path / "cut.npy", model)
    (tmp_path / "long.npy").write_bytes(raw + bytes(64))     # more data than declared
    with pytest.raises(pinlin.ModelFileError, match="header declares shape"):
        pinlin.read_gain(tmp_path / "long.npy", model)
    (tmp_path / "K.pkl").write_bytes(pickle.dumps(np.zeros((2, 4))))
    with pytest.raises(pinlin.ModelFileError, match="unknown gain format"):
        pinlin.read_gain(tmp_path / "K.pkl", model)
    with pytest.raises(pinlin.ModelFileError, match="file not found"):
        pinlin.read_gain(tmp_path / "none.csv", model)


def test_write_gain_keeps_what_the_user_has(tmp_path):
    model = pinlin.linearize("double_pendulum")
    mine = tmp_path / "K.csv"
    mine.write_text("my notes\n")
    with pytest.raises(pinlin.ModelFileError, match="pinlin does not replace it"):
        pinlin.write_gain(mine, np.zeros((2, 4)), model)
    assert mine.read_text() == "my notes\n"
    with pytest.raises(pinlin.ArgumentError, match="argument 'K': expected a gain matrix of "
                                                  "shape \\(2, 4\\)"):
        pinlin.write_gain(tmp_path / "new.csv", np.zeros((2, 3)), model)
    assert not (tmp_path / "new.csv").exists()
    # A states file of the user's (t, q:..., u:...) and a time history are not gains.
    states = tmp_path / "states.csv"
    states.write_text("t,q:shoulder,q:elbow,v:shoulder,v:elbow,u:shoulder,u:elbow\n"
                      "0,0,0,0,0,0,0\n")
    with pytest.raises(pinlin.ModelFileError, match="pinlin does not replace"):
        pinlin.write_gain(states, np.zeros((2, 4)), model)
    assert states.read_text().startswith("t,q:shoulder")


@pytest.mark.parametrize("bad, match", [
    ("abc", "argument 'K'"), ([[1, 2, 3, 4], [1, 2]], "argument 'K'"), ({"a": 1}, "argument 'K'"),
    (np.ones((2, 4)) * (1 + 2j), "argument 'K'"), (np.full((2, 4), np.inf), "NaN or inf")])
def test_write_gain_refuses_what_is_not_a_real_gain(tmp_path, bad, match):
    model = pinlin.linearize("double_pendulum")
    with pytest.raises(pinlin.ArgumentError, match=match):
        pinlin.write_gain(tmp_path / "K.csv", bad, model)
    assert not (tmp_path / "K.csv").exists()


def test_gain_functions_want_a_model(tmp_path):
    for call in (lambda: pinlin.read_gain(tmp_path / "K.csv", "double_pendulum"),
                 lambda: pinlin.write_gain(tmp_path / "K.csv", np.zeros((2, 4)),
                                           "double_pendulum")):
        with pytest.raises(pinlin.ArgumentError, match="argument 'model'"):
            call()


@pytest.mark.parametrize("name, written", [("hin,ge", '"q:hin,ge"'), ("hinge ", "q:hinge ,")])
def test_names_with_commas_or_spaces_round_trip(tmp_path, name, written):
    """A joint named 'hin,ge' or 'hinge ' (URDF allows both): a comma is quoted, a trailing
    space kept, and the file reads back."""
    text = (URDF_DIR / "pendulum.urdf").read_text().replace('name="hinge"', f'name="{name}"')
    (tmp_path / "odd.urdf").write_text(text)
    model = pinlin.linearize(pinlin.Scene.from_urdf(
        tmp_path / "odd.urdf", effects={"gravity": [0, 0, -9.81]},
        operating_point={"solve": "inputs"}, inputs={"actuated": [name]}))
    K = np.array([[3.0, 0.5]])
    path = pinlin.write_gain(tmp_path / "K.csv", K, model)
    assert written in path.read_text()
    np.testing.assert_array_equal(pinlin.read_gain(path, model), K)


def test_a_design_point_needs_a_model_with_one(tmp_path):
    model = pinlin.linearize("double_pendulum")
    bare = pinlin.LinearModel(model.A, model.B, model.C, model.D,
                              state_names=model.state_names, input_names=model.input_names,
                              output_names=model.output_names, name="bare")
    path = pinlin.write_gain(tmp_path / "K.csv", np.ones((2, 4)), model)
    with pytest.raises(pinlin.ModelFileError, match="has no operating point to check it"):
        pinlin.read_gain(path, bare)
    pinlin.write_gain(tmp_path / "bare.csv", np.ones((2, 4)), bare)     # no point to record
    np.testing.assert_array_equal(pinlin.read_gain(tmp_path / "bare.csv", bare), np.ones((2, 4)))


def test_cli_simulate_closes_the_loop_as_by_hand(capfd, tmp_path):
    """``pinlin simulate upright.toml --feedback K.csv`` from 0.6 rad: the pendulum is held
    up as J x'' = m g l sin(x) - K [x, x'] integrates it (solve_ivp, 1e-12), to 1e-8 rad; the
    output file carries the inputs applied, u = -K x (u0 = 0 upright). Without the option
    it falls."""
    scene = _upright(tmp_path)
    model = pinlin.linearize(scene)
    K = place_poles(model.A, model.B, [-3.0, -4.0]).gain_matrix
    pinlin.write_gain(tmp_path / "K.csv", K, model)
    out_file = tmp_path / "loop.csv"
    code, out, err = _run(capfd, "simulate", scene, "--t-end", "4", "--dt", "0.05",
                          "--x0", "q:hinge=0.6", "--feedback", tmp_path / "K.csv",
                          "--out", out_file)
    assert code == 0, err
    assert "closed loop: u = u0 - K x, K (1 inputs x 2 states)" in out
    _, header, *rows = out_file.read_text().splitlines()
    table = np.array([[float(x) for x in r.split(",")] for r in rows])
    names = header.split(",")
    t, x, v = (table[:, names.index(k)] for k in ("t", "q:hinge", "v:hinge"))

    def rhs(_, s):
        return [s[1], (MGL * np.sin(s[0]) - (K @ s)[0]) / J_PENDULUM]

    ref = scipy.integrate.solve_ivp(rhs, (0.0, 4.0), [0.6, 0.0], t_eval=t, method="DOP853",
                                    rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(x, ref.y[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(v, ref.y[1], rtol=0, atol=1e-8)
    u = table[:, names.index("u:hinge")]
    np.testing.assert_allclose(u, -(K @ np.vstack([x, v]))[0], rtol=0, atol=1e-9)
    code, out, err = _run(capfd, "simulate", scene, "--t-end", "2", "--x0", "q:hinge=0.6")
    assert code == 0 and "final deviation: q:hinge" in out
    assert abs(float(out.split("q:hinge = ")[1].split()[0])) > 2.0      # fell over


def test_cli_response_and_validity_take_the_closed_loop(capfd, tmp_path):
    """``pinlin response --feedback``: the linear closed loop, expm((A - B K) t) x0; with
    --nonlinear, the closed loop's simulation beside it. ``pinlin validity --feedback``:
    the closed loop's modes, at the placed poles -3 and -4."""
    scene = _upright(tmp_path)
    model = pinlin.linearize(scene)
    K = place_poles(model.A, model.B, [-3.0, -4.0]).gain_matrix
    np.save(tmp_path / "K.npy", K)
    out_file = tmp_path / "lin.csv"
    code, out, err = _run(capfd, "response", scene, "--t-end", "2", "--dt", "0.1",
                          "--x0", "q:hinge=0.01", "--feedback", tmp_path / "K.npy",
                          "--nonlinear", "--out", out_file)
    assert code == 0, err
    _, header, *rows = out_file.read_text().splitlines()
    table = np.array([[float(x) for x in r.split(",")] for r in rows])
    names = header.split(",")
    x0 = np.array([0.01, 0.0])
    ref = np.array([sla.expm((model.A - model.B @ K) * tk) @ x0 for tk in table[:, 0]])
    lin = table[:, [names.index("q:hinge"), names.index("v:hinge")]]
    np.testing.assert_allclose(lin, ref, rtol=0, atol=1e-13)
    nl = table[:, names.index("nl:q:hinge")]
    assert np.abs(nl - lin[:, 0]).max() <= 1e-5 * 0.01     # quadratic remainder at 1 cm rad
    code, out, err = _run(capfd, "validity", scene, "--feedback", tmp_path / "K.npy",
                          "--periods", "2")
    assert code == 0, err
    assert "closed loop" in out.splitlines()[0]
    eigs = sorted(float(line.split()[3]) for line in out.splitlines()
                  if line.startswith("mode ") and ":" not in line.split()[1])
    np.testing.assert_allclose(eigs, [-4.0, -3.0], rtol=1e-9)


def test_cli_feedback_refusals_are_one_line(capfd, tmp_path):
    scene = _upright(tmp_path)
    model = pinlin.linearize(scene)
    pinlin.write_gain(tmp_path / "K.csv", np.array([[20.0, 7.0]]), model)
    (tmp_path / "huge.csv").write_text("input,q:hinge,v:hinge\nu:hinge,1e300,1e300\n")
    for argv, words in (
            (["simulate", "pendulum", "--t-end", "1", "--feedback", tmp_path / "K.csv"],
             "designed about another point"),
            (["simulate", "double_pendulum", "--t-end", "1", "--feedback",
              tmp_path / "K.csv"], "'q:hinge' is not a state of model 'double_pendulum'"),
            (["response", scene, "--t-end", "1", "--feedback", tmp_path / "none.npy"],
             "file not found"),
            (["validity", scene, "--feedback", tmp_path / "none.csv"], "file not found"),
            (["simulate", scene, "--t-end", "1", "--feedback", tmp_path / "K.csv", "--out",
              tmp_path / "K.csv"], "holds a saved gain, not a time history"),
            (["simulate", scene, "--t-end", "1", "--feedback", tmp_path / "huge.csv"],
             "entries beyond 1e+150")):
        code, out, err = _run(capfd, *argv)
        assert code == 2 and err.count("\n") == 1 and words in err, err
        assert out == ""
    assert (tmp_path / "K.csv").read_text().startswith("# pinlin gain:")   # not replaced


def test_a_gain_that_overflows_the_integration_is_refused_in_one_line(tmp_path):
    """1e149 on the velocity (below the 1e150 entry limit): the stiff solver's Jacobian
    overflowed and scipy's own check left a traceback; now a ModelError, and no numpy
    warning on the way. From 1e150 the gain itself is refused."""
    scene = pinlin.Scene.load(_upright(tmp_path))
    t = np.linspace(0.0, 1.0, 5)
    with warnings.catch_warnings(), deadline(120):   # a non-stiff solver would never end
        warnings.simplefilter("error")
        with pytest.raises(pinlin.ModelError, match="the dynamics overflowed"):
            pinlin.simulate(scene, t, dx0=[0.1, 0.0], feedback=np.array([[0.0, 1e149]]))
    with pytest.raises(pinlin.ArgumentError, match="entries beyond 1e\\+150"):
        pinlin.simulate(scene, t, dx0=[0.1, 0.0], feedback=np.array([[0.0, 1e151]]))


def test_a_non_finite_gain_names_its_entry(tmp_path):
    model = pinlin.linearize("double_pendulum")
    K = np.ones((2, 4))
    K[1, 2] = np.inf
    with pytest.raises(pinlin.ArgumentError, match=r"NaN or inf \(the first at \[1, 2\]: inf\)"):
        pinlin.write_gain(tmp_path / "K.csv", K, model)
