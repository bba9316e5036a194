"""A state given at rest with the inputs that hold it is diagnosed an equilibrium.

The reference is the scene's own operating point (``solve = "inputs"``: the inputs solved
by the statics, whose residual the at-rest path checks): linearizing at that very state as a
given one (``q=, v=0, u=``) must say equilibrium and describe the same model. With an input
changed by far more than the tolerance, or with a velocity, it must not.
"""

from __future__ import annotations

import numpy as np
import pytest

import pinlin
from pinlin.scene import Scene, bundled_scenes

CASES = ["four_bar", "slider_crank", "delta", "standing_box", "solo12_standing", "pendulum"]


@pytest.mark.parametrize("name", CASES)
def test_rest_state_given_is_an_equilibrium(name: str) -> None:
    scene = Scene.load(bundled_scenes()[name])
    rest = pinlin.linearize(scene)
    op = rest.operating_point
    assert op.equilibrium
    nv = scene.system.nv
    given = pinlin.linearize(scene, q=op.q, v=np.zeros(nv), u=op.u)
    gop = given.operating_point
    assert gop.equilibrium, gop.notes
    assert "an equilibrium" in gop.notes[0]
    # The same model, to the rounding of two routes through the dynamics.
    assert given.A.shape == rest.A.shape
    assert np.abs(given.A - rest.A).max() <= 1e-9 * max(1.0, np.abs(rest.A).max())


@pytest.mark.parametrize("name", ["four_bar", "delta", "solo12_standing", "pendulum"])
def test_pushed_or_moving_state_is_not(name: str) -> None:
    scene = Scene.load(bundled_scenes()[name])
    op = pinlin.linearize(scene).operating_point
    system = scene.system
    pushed = op.u.copy()
    pushed[0] += 1e-3 * max(1.0, np.abs(op.u).max())  # 1e6 x the tolerance
    gop = pinlin.linearize(scene, q=op.q, v=np.zeros(system.nv), u=pushed).operating_point
    assert not gop.equilibrium
    model = pinlin.linearize(scene, q=op.q, v=np.zeros(system.nv), u=pushed)
    assert model.f0 is not None and np.abs(model.f0).max() > 0.0
    # A velocity the constraints allow (the first column of the model's own R, or a joint
    # of an open chain): never an equilibrium.
    R = np.asarray(pinlin.linearize(scene).info.get("R", np.eye(system.nv)))
    v = 0.1 * R[:, 0]
    gop = pinlin.linearize(scene, q=op.q, v=v, u=op.u).operating_point
    assert not gop.equilibrium


def test_positions_solve_says_q_was_a_starting_guess():
    """With solve = "positions" a given q is where Newton starts; the equilibrium it finds can
    be another one (here 5.7 rad away): the operating point says so instead of nothing."""
    scene = pinlin.Scene.resolve("rotating_double_pendulum")
    q = np.array([2.5, 0.1])
    op = pinlin.linearize(scene, q=q).operating_point
    note = next(n for n in op.notes if n.startswith('solve = "positions"'))
    moved = float(np.abs(op.q - q).max())
    assert moved > 1.0 and f"{moved:.3g} rad or m away" in note
