"""pinlin simulate, response and validity from the command line: the same numbers as the
Python API, files written where asked, one-line errors for bad options."""

from __future__ import annotations

import numpy as np
import pytest

import pinlin
from pinlin.cli import main


def run(capfd, *argv):
    code = main(list(argv))
    out, err = capfd.readouterr()
    return code, out, err


def test_simulate_writes_what_the_api_computes(capfd, tmp_path):
    csv, png = tmp_path / "sim.csv", tmp_path / "sim.png"
    code, out, err = run(capfd, "simulate", "pendulum", "--t-end", "1", "--dt", "0.05",
                         "--x0", "q:hinge=0.1", "--out", str(csv), "--plot", str(png))
    assert code == 0, err
    assert "nonlinear" in out and "energy change" in out
    marker, header, *rows = csv.read_text().splitlines()
    assert marker.startswith("# pinlin history")
    assert header.split(",")[:3] == ["t", "q:hinge", "v:hinge"]
    table = np.array([[float(x) for x in r.split(",")] for r in rows])
    t = np.arange(21) * 0.05
    sim = pinlin.simulate("pendulum", t, dx0=np.array([0.1, 0.0]))
    np.testing.assert_array_equal(table[:, 0], sim.t)
    np.testing.assert_array_equal(table[:, 1:3], sim.z)
    assert png.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("scene", ["four_bar", "slider_crank"])
def test_simulate_of_a_mechanism_writes_its_independent_states(scene, capfd, tmp_path):
    """A mechanism's simulation has z (the linear model's 2 nz states) besides x (all 2 nv):
    the CLI labels and writes z by the model's state names (before, a zip/IndexError after
    printing half the result), and `response --nonlinear` compares the same columns."""
    csv = tmp_path / "sim.csv"
    model = pinlin.linearize(scene)
    first = model.state_names[0]
    code, out, err = run(capfd, "simulate", scene, "--t-end", "0.5", "--dt", "0.05",
                         "--x0", f"{first}=0.01", "--out", str(csv))
    assert code == 0, err
    assert "loops" in out.splitlines()[0]      # the effects named include the loops
    _, header, *rows = csv.read_text().splitlines()
    n = model.n_states
    assert header.split(",")[1:n + 1] == list(model.state_names)
    table = np.array([[float(x) for x in r.split(",")] for r in rows])
    x0 = np.zeros(n)
    x0[0] = 0.01
    sim = pinlin.simulate(scene, np.arange(11) * 0.05, dx0=x0)
    np.testing.assert_array_equal(table[:, 1:n + 1], sim.z)
    code, out, err = run(capfd, "response", scene, "--t-end", "0.5", "--x0", f"{first}=0.01",
                         "--nonlinear")
    assert code == 0 and "nonlinear simulation from the same state" in out, err


def test_response_writes_what_the_api_computes(capfd, tmp_path):
    npz = tmp_path / "r.npz"
    code, out, err = run(capfd, "response", "double_pendulum", "--t-end", "2", "--x0",
                         "shoulder=0.05", "--step", "u:elbow=0.1", "--harmonic",
                         "u:shoulder=0.2@3.0", "--out", str(npz))
    assert code == 0, err
    data = np.load(npz)
    model = pinlin.linearize("double_pendulum")
    u = pinlin.step({"u:elbow": 0.1}) + pinlin.harmonic({"u:shoulder": 0.2}, 3.0)
    x0 = np.zeros(4)
    x0[model.state_names.index("q:shoulder")] = 0.05
    res = pinlin.response(model, data["t"], x0=x0, u=u)
    assert list(data["names"][:4]) == list(model.state_names)
    np.testing.assert_array_equal(data["values"], res.x)


def test_response_against_the_nonlinear_simulation(capfd):
    code, out, err = run(capfd, "response", "pendulum", "--t-end", "2", "--x0", "q:hinge=0.01",
                         "--nonlinear")
    assert code == 0, err
    line = next(x for x in out.splitlines() if x.startswith("nonlinear simulation"))
    relative = float(line.split("(")[1].split()[0])
    assert relative < 1e-3   # a 0.01 rad swing: the error is O(amplitude^2)


def test_validity_prints_the_radius_and_writes_plots(capfd, tmp_path):
    code, out, err = run(capfd, "validity", "pendulum", "--periods", "2", "--out-dir",
                         str(tmp_path / "v"))
    assert code == 0, err
    assert "radius" in out.lower()
    assert sorted(p.suffix for p in (tmp_path / "v").iterdir()) == [".png", ".png"]


BAD = {
    "t_end_negative": (["simulate", "pendulum", "--t-end", "-1"], "--t-end"),
    "dt_zero": (["response", "pendulum", "--t-end", "1", "--dt", "0"], "--dt"),
    "too_many_times": (["response", "pendulum", "--t-end", "1e300"],
                       "--t-end / --dt gives 1e+302 output times; at most 1000000"),
    "simulate_forever": (["simulate", "pendulum", "--t-end", "1e7", "--dt", "100", "--x0",
                          "q:hinge=0.1"], "periods of the fastest oscillation"),
    "x0_unknown": (["simulate", "pendulum", "--t-end", "1", "--x0", "q:nope=1"],
                   "'q:nope' is not one of"),
    "x0_not_assignment": (["simulate", "pendulum", "--t-end", "1", "--x0", "hinge"],
                          "expected NAME=VALUE"),
    "x0_not_number": (["response", "pendulum", "--t-end", "1", "--x0", "hinge=abc"],
                      "expected a number"),
    "step_unknown_input": (["response", "pendulum", "--t-end", "1", "--step", "u:knee=1"],
                           "'u:knee' is not one of"),
    "harmonic_without_w": (["response", "pendulum", "--t-end", "1", "--harmonic",
                            "u:hinge=1"], "AMPLITUDE@W"),
    "out_suffix": (["simulate", "pendulum", "--t-end", "1", "--out", "x.txt"],
                   "unknown format '.txt'"),
    "plot_suffix": (["response", "pendulum", "--t-end", "1", "--plot", "x.jpg"],
                    "expected a .png"),
    "nonlinear_with_inputs": (["response", "pendulum", "--t-end", "1", "--step", "u:hinge=1",
                               "--nonlinear"], "--nonlinear"),
    "impulse_nonlinear": (["response", "pendulum", "--t-end", "1", "--impulse", "hinge=1",
                           "--nonlinear"], "argument '--nonlinear'"),
    "x0_given_twice": (["simulate", "pendulum", "--t-end", "1", "--x0", "hinge=1", "--x0",
                        "hinge=2"], "'q:hinge' is given twice (1 and 2)"),
    "step_given_twice": (["response", "pendulum", "--t-end", "1", "--step", "hinge=1",
                          "u:hinge=2"], "'u:hinge' is given twice"),
    "x0_beyond_limit": (["simulate", "pendulum", "--t-end", "1", "--x0", "hinge=1e7"],
                        "argument '--x0'"),
    "rtol_below_eps": (["simulate", "pendulum", "--t-end", "1", "--rtol", "1e-30"],
                       "argument '--rtol': 1e-30 is below 2.22e-14"),
    "rtol_one": (["simulate", "pendulum", "--t-end", "1", "--rtol", "1"],
                 "argument '--rtol': 1 allows errors as large as the state itself"),
    "out_names_a_folder": (["simulate", "pendulum", "--t-end", "1", "--out", "h.csv/"],
                           "argument '--out': needs a file name, got 'h.csv/', which names a "
                           "folder"),
    "modes_amplitude_alone": (["modes", "pendulum", "--amplitude", "0.3"],
                              "argument '--amplitude': sets the drawn amplitude"),
    "validity_tolerance": (["validity", "pendulum", "--tolerance", "-1"], "tolerance"),
    "validity_out_dir_file": (["validity", "pendulum", "--out-dir", __file__],
                              "it is a file, not a folder"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_motion_options_give_one_line_and_exit_2(case, capfd):
    argv, words = BAD[case]
    code, out, err = run(capfd, *argv)
    assert code == 2 and err.count("\n") == 1 and err.startswith("pinlin: error: "), err
    assert words in err, err
    assert out == "", out    # refused before any result is printed


@pytest.mark.parametrize("case", ["scalar_q", "dt_overflows"])
def test_bad_trajectory_runs_print_nothing_but_the_error(case, capfd, tmp_path):
    """A 0-d q member (before, a TypeError in the progress bar) and a --dt the zero-order
    hold cannot take (its matrices overflowed; now refused before, as keeping no correct
    digit; before, refused after the summary line) give one error line only."""
    states = tmp_path / "s.npz"
    if case == "scalar_q":
        np.savez(states, q=np.float64(0.1))
        argv, words = [], "member 'q' is a single number"
    else:
        np.savez(states, q=np.zeros((3, 2)), v=np.zeros((3, 2)), u=np.zeros((3, 2)))
        argv, words = ["--dt", "1e300"], "no correct digit"
    code, out, err = run(capfd, "trajectory", "double_pendulum", str(states), "--out",
                         str(tmp_path / "o.npz"), "--no-progress", *argv)
    assert code == 2 and err.count("\n") == 1 and words in err, err
    assert out == "" and not (tmp_path / "o.npz").exists()


def test_time_grid_ends_at_t_end(capfd, tmp_path):
    """--t-end 1 --dt 0.3 samples 0, 0.3, 0.6, 0.9 and 1 (it stopped at 0.9 s)."""
    out = tmp_path / "h.csv"
    code, _, _ = run(capfd, "simulate", "pendulum", "--t-end", "1", "--dt", "0.3", "--out",
                     str(out))
    assert code == 0
    t = [float(line.split(",")[0]) for line in out.read_text().splitlines()[2:]]
    np.testing.assert_allclose(t, [0.0, 0.3, 0.6, 0.9, 1.0], rtol=0, atol=1e-15)


def test_ctrl_c_prints_one_line_and_exits_130(capfd, monkeypatch):
    from pinlin import cli_motion

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_motion, "_cmd_simulate", interrupted)
    code, out, err = run(capfd, "simulate", "pendulum", "--t-end", "1")
    assert code == 130 and err == "pinlin: interrupted\n" and out == ""


def test_validity_refuses_a_foreign_plot_before_the_run(capfd, tmp_path):
    """A picture of the user's own where validity would write its errors plot: refused before
    anything is simulated, printed or written (the table was printed and the histories plot
    written first)."""
    from PIL import Image

    Image.new("RGB", (4, 4)).save(tmp_path / "pendulum_errors.png")
    code, out, err = run(capfd, "validity", "pendulum", "--periods", "1", "--out-dir",
                         str(tmp_path))
    assert code == 2 and out == "" and "pendulum_errors.png" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pendulum_errors.png"]


@pytest.mark.parametrize("argv", [
    ["linearize", "pendulum", "--out", "OUT.npz"],
    ["simulate", "pendulum", "--t-end", "0.1", "--out", "OUT.csv"],
    ["response", "pendulum", "--t-end", "0.1", "--x0", "hinge=0.1", "--out", "OUT.csv"]])
def test_a_failed_write_prints_nothing_but_the_error(argv, capfd, tmp_path, monkeypatch):
    """A disk that is full (or a file size limit) fails the write: one line on stderr and
    nothing on stdout (the operating point and mode table, or the simulation's summary, were
    printed before the write)."""
    from pinlin import files
    from pinlin.exceptions import ModelFileError

    def full(path, data):
        raise ModelFileError(path, "cannot write: File too large")

    monkeypatch.setattr(files, "write_text_atomic", full)
    monkeypatch.setattr(files, "write_bytes_atomic", full)
    monkeypatch.setattr(pinlin.LinearModel, "save", lambda self, path: full(path, None))
    argv = [str(tmp_path / a) if a.startswith("OUT") else a for a in argv]
    code, out, err = run(capfd, *argv)
    assert code == 2 and out == "" and "File too large" in err and err.count("\n") == 1


def test_two_outputs_appear_together_or_not_at_all(capfd, tmp_path, monkeypatch):
    """--out and --plot: when the plot cannot be written, the history is not kept either
    (it was left behind, the command exiting 2), and no temporary file remains."""
    from pinlin import cli_histories
    from pinlin.exceptions import ModelFileError

    def full(path, title, t, curves):
        raise ModelFileError(path, "cannot write: No space left on device")

    monkeypatch.setattr(cli_histories, "plot_histories", full)
    code, out, err = run(capfd, "response", "pendulum", "--t-end", "0.1", "--x0", "hinge=0.1",
                         "--out", str(tmp_path / "r.csv"), "--plot", str(tmp_path / "r.png"))
    assert code == 2 and out == "" and "No space left" in err
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    code, out, _ = run(capfd, "response", "pendulum", "--t-end", "0.1", "--x0", "hinge=0.1",
                       "--out", str(tmp_path / "r.csv"), "--plot", str(tmp_path / "r.png"))
    assert code == 0 and sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.png"]


def test_trajectory_says_when_it_moved_the_given_states(capfd, tmp_path):
    """A four-bar state off its loop (q and v violate the closure) is closed and projected
    before it is linearized; the CLI said nothing about it (the correction sat in
    info['loops'] only). An open chain's states are taken as given: no such line."""
    states = tmp_path / "fb.npz"
    np.savez(states, q=np.array([[1.0, 3.0, -2.0]]), v=np.array([[1.0, 5.0, 5.0]]),
             u=np.zeros((1, 1)))
    code, out, _ = run(capfd, "trajectory", "four_bar", str(states), "--out",
                       str(tmp_path / "m.npz"), "--no-progress")
    assert code == 0 and "states moved onto the constraints" in out
    model = pinlin.TrajectoryModel.load(tmp_path / "m.npz")
    change = float(out.split("|dq| = ")[1].split(",")[0])     # a norm of the tangent change
    assert change >= float(np.abs(model.q[0] - [1.0, 3.0, -2.0]).max()) > 0.1
    pend = tmp_path / "p.npz"
    np.savez(pend, q=np.array([[0.3]]), v=np.array([[1.0]]), u=np.zeros((1, 1)))
    code, out, _ = run(capfd, "trajectory", "pendulum", str(pend), "--out",
                       str(tmp_path / "pm.npz"), "--no-progress")
    assert code == 0 and "states moved" not in out


def test_trajectory_says_when_dt_is_not_the_states_files_spacing(capfd, tmp_path):
    """Points sampled every 0.05 s discretized at --dt 0.01: each model steps 0.01 s, which a
    TV-LQR chaining the points would misuse; the summary says so (and not where they agree)."""
    states = tmp_path / "p.npz"
    t = np.arange(4) * 0.05
    np.savez(states, t=t, q=0.1 * np.sin(t)[:, None], v=0.1 * np.cos(t)[:, None],
             u=np.zeros((4, 1)))
    for dt, remark in (("0.01", True), ("0.05", False)):
        code, out, _ = run(capfd, "trajectory", "pendulum", str(states), "--dt", dt, "--out",
                           str(tmp_path / f"m{dt}.npz"), "--no-progress")
        assert code == 0 and f"dt = {dt} s" in out
        assert ("the states file's t is spaced 0.05 s" in out) == remark, out


def test_nonlinear_response_names_the_option_and_unknown_names_are_listed_once(capfd):
    """The nonlinear run's refusal of the initial state named the API's 'dx0'; a name that is
    both a bundled scene and a robot was suggested twice."""
    code, out, err = run(capfd, "response", "pendulum", "--t-end", "1", "--x0", "q:hinge=1e10",
                         "--nonlinear")
    assert code == 2 and "argument '--x0'" in err and "dx0" not in err
    code, out, err = run(capfd, "simulate", "nopendulum", "--t-end", "1")
    assert code == 2 and err.count("'double_pendulum'") == 1, err


def test_trajectory_out_over_a_time_history_is_refused_before_the_work(capfd, tmp_path,
                                                                        monkeypatch):
    """`pinlin trajectory ... --out h.npz` where h.npz is a time history pinlin wrote: refused
    (as the final save would refuse it) before any point is linearized."""
    history = tmp_path / "h.npz"
    code, _, err = run(capfd, "simulate", "pendulum", "--t-end", "0.1", "--out", str(history))
    assert code == 0, err
    states = tmp_path / "states.npz"
    np.savez(states, q=np.zeros((3, 1)), v=np.zeros((3, 1)), u=np.zeros((3, 1)))

    def never(*args, **kwargs):
        raise AssertionError("the trajectory was linearized before the refusal")

    from pinlin import trajectory
    monkeypatch.setattr(trajectory, "linearize_trajectory", never)
    before = history.read_bytes()
    code, out, err = run(capfd, "trajectory", "pendulum", str(states), "--out", str(history))
    assert code == 2 and "holds a saved time history, not a model" in err, err
    assert history.read_bytes() == before


def test_a_history_replaces_only_a_history(capfd, tmp_path):
    """`--out h.csv` replaces a time history pinlin wrote (its first line says so), never a
    user's states file, whose header (t, q:..., v:...) a history shares. A history is not
    read as a states file either, even cut down to its q: columns: those are deviations from
    the operating point (ur5_arm's history from rest at its q0 read as the configurations
    [0, ..., 0])."""
    mine = tmp_path / "plan.csv"
    plan = "t,q:hinge,v:hinge,u:hinge\n0,0.1,0,0\n1,0.2,0,0\n"
    mine.write_text(plan)
    code, out, err = run(capfd, "simulate", "pendulum", "--t-end", "0.1", "--out", str(mine))
    assert code == 2 and out == "" and "plan.csv" in err and "does not replace it" in err
    assert mine.read_text() == plan
    history = tmp_path / "h.csv"
    for t_end in ("0.1", "0.2"):   # the second run replaces the first run's history
        code, _, err = run(capfd, "simulate", "pendulum", "--t-end", t_end, "--dt", "0.05",
                           "--out", str(history))
        assert code == 0, err
    rows = history.read_text().splitlines()
    assert rows[0].startswith("# pinlin history: ") and len(rows) == 2 + 5
    states = tmp_path / "states.csv"
    states.write_text("\n".join(",".join(r.split(",")[:2]) for r in rows) + "\n")  # t, q
    code, _, err = run(capfd, "trajectory", "pendulum", str(states), "--out",
                       str(tmp_path / "m.npz"))
    assert code == 2 and "states.csv" in err and "is a time history" in err, err
    assert not (tmp_path / "m.npz").exists()
    code, _, err = run(capfd, "simulate", "pendulum", "--t-end", "0.1", "--out", str(states))
    assert code == 0, err      # a history (marker kept), edited: still pinlin's to replace
