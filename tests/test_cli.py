"""The command line: the main job works, and bad input gives one line on stderr and exit 2."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
from conftest import URDF_DIR

import pinlin
from pinlin.cli import main

PENDULUM = (URDF_DIR / "pendulum.urdf").read_text()


def run(capfd, *argv):
    code = main(list(argv))
    out, err = capfd.readouterr()
    return code, out, err


def test_linearize_bundled_scene_prints_operating_point_and_modes(capfd, tmp_path):
    out_file = tmp_path / "dp.npz"
    code, out, err = run(capfd, "linearize", "double_pendulum", "--out", str(out_file))
    assert code == 0 and err == ""
    assert "residual max |r|" in out and "equilibrium" in out
    assert "symmetric eigensolver" in out and "undamped" in out
    model = pinlin.LinearModel.load(out_file)
    assert model.state_names == ("q:shoulder", "q:elbow", "v:shoulder", "v:elbow")


def test_linearize_robot_name_with_matrices(capfd):
    code, out, _ = run(capfd, "linearize", "ur5", "--matrices", "--derivatives", "fd5")
    assert code == 0 and "A =" in out and "fd5 derivatives (steps q 0.001, v 0.001, u 0.001)" in out
    assert "error estimate of A" in out


def test_robots_lists_the_loadable_ones(capfd):
    from pinlin.robots import loadable_robots

    code, out, _ = run(capfd, "robots")
    assert code == 0
    status = loadable_robots()   # whatever this installation's data loads
    loaded, _, failed = out.partition("do not load here:")
    for name, reason in status.items():
        section = loaded if reason is None else failed
        assert f"  {name} " in section, name
    assert "talos" in loaded


def test_console_script_runs():
    res = subprocess.run([sys.executable, "-m", "pinlin.cli", "linearize", "pendulum"],
                         capture_output=True, text=True, check=False)
    # wn = sqrt(m g L / J), J = m L^2 + 2/5 m r^2 = 1.001 kg*m^2 (a 1 kg sphere, r = 0.05 m)
    assert res.returncode == 0 and f"{np.sqrt(9.81 / 1.001):.6g}j" in res.stdout
