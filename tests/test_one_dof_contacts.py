"""A one-joint robot held by a contact: Pinocchio hands a 6 x 1 Jacobian back as a vector, which
crashed assembly (weld: IndexError; point: ValueError in the pivoted QR). The pendulum with its
tip held has no motion left; the holding forces are checked against Pinocchio's own gravity
torque and frame Jacobian, and MuJoCo's model (validate) has only soft modes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import pinlin
from pinlin.cli import main

URDF = Path(pinlin.__file__).resolve().parent.parent / "urdf" / "pendulum.urdf"
HINGE = 0.3


def _scene(tmp_path: Path, kind: str) -> Path:
    path = tmp_path / f"held_{kind}.toml"
    path.write_text(f'urdf = "{URDF}"\n[effects]\ngravity = [0.0, 0.0, -9.81]\n'
                    '[inputs]\nactuated = ["hinge"]\n'
                    f'[[contacts]]\nname = "grip"\nframe = "tip"\ntype = "{kind}"\n'
                    f'[operating_point]\nq = {{ hinge = {HINGE} }}\n')
    return path


@pytest.mark.parametrize("kind", ["weld", "point"])
def test_held_pendulum_has_no_states_and_its_forces_balance_gravity(tmp_path, kind, capfd):
    path = _scene(tmp_path, kind)
    model = pinlin.linearize(str(path))
    assert model.n_states == 0 and model.A.shape == (0, 0)
    op = model.operating_point
    # Statics: g(q) = u + J^T [f; tau] with Pinocchio's gravity torque and the tip's
    # world-aligned Jacobian (6 x 1; a point contact carries the force rows only).
    pm = pin.buildModelFromUrdf(str(URDF))
    data = pm.createData()
    q = np.array([HINGE])
    gravity = pin.computeGeneralizedGravity(pm, data, q)
    pin.computeJointJacobians(pm, data, q)
    pin.updateFramePlacements(pm, data)
    J = pin.getFrameJacobian(pm, data, pm.getFrameId("tip"),
                             pin.LOCAL_WORLD_ALIGNED).reshape(6, 1)
    force, torque = op.contact_forces["grip"]
    wrench = np.concatenate([force, torque if torque is not None else np.zeros(3)])
    np.testing.assert_allclose(op.u + J.T @ wrench, gravity, rtol=0, atol=1e-12)
    assert any("not unique" in note for note in op.notes)   # hinge and contact share it
    assert pinlin.modal(model).eigenvalues.size == 0
    assert main(["response", str(path), "--t-end", "1"]) == 0
    assert "no states" in capfd.readouterr().out
    assert main(["response", str(path), "--t-end", "0.1", "--nonlinear"]) == 0
    assert main(["simulate", str(path), "--t-end", "0.1"]) == 0
    assert "final deviation: none (no states" in capfd.readouterr().out
    sim = pinlin.simulate(str(path), t=[0.0, 0.1])
    assert sim.info["effects"] == ["gravity", "contacts"]   # as the CLI's banner says
    assert main(["validate", str(path), "--out-dir", str(tmp_path / "v")]) == 0
    report = (tmp_path / "v" / f"held_{kind}.md").read_text()
    assert "**pass**" in report and "2 eigenvalues" in report


def test_held_pendulum_at_a_given_state_has_no_states(tmp_path):
    """At a given state the contact holds the tip: the model still has no states."""
    model = pinlin.linearize(str(_scene(tmp_path, "weld")), q=np.array([HINGE]),
                             v=np.array([0.0]))
    assert model.n_states == 0


def test_report_asked_for_validity_says_why_there_is_none(tmp_path):
    """Nothing moves, so there is no mode to simulate: the report says so where the validity
    plots would be (before, the request was dropped without a word)."""
    out = pinlin.write_html_report(str(_scene(tmp_path, "weld")), tmp_path / "held.html",
                                   include_validity=True)
    assert "Validity of the linear model</h2><p class='note'>Not computed" in out.read_text()


def test_contact_on_the_joint_axis_says_its_frame_cannot_move(tmp_path):
    """The bob's own frame sits on the hinge axis: a point contact there holds nothing, and
    the error says why (before: "every row repeats others", which suggests another contact)."""
    path = _scene(tmp_path, "point")
    path.write_text(path.read_text().replace('frame = "tip"', 'frame = "bob"'))
    with pytest.raises(pinlin.SceneError, match="its frames cannot move"):
        pinlin.linearize(str(path))
