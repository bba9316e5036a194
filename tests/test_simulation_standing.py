"""pinlin.simulate of standing robots (a floating base held by point or weld contacts) against
references from outside the code under test: the closed-form motion of the box balanced on a
point, conservation of energy (the contacts do no work) and the constraint staying
satisfied; the linear models (checked against MuJoCo and closed forms in test_contacts.py) as
the first-order limit of the nonlinear motion are checked with the fixed-base systems in
test_simulation.py::test_small_perturbations_follow_the_linear_model."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pinlin

G = 9.81
#: urdf/standing_box.urdf: 2 kg, 0.3 x 0.2 x 1.0 m, held at the centre of its bottom face,
#: its centre of mass l = 0.5 m above: a tilt about x is an inverted pendulum with
#: theta'' = m g l sin(theta) / (I_xx + m l^2), I_xx = m (0.2^2 + 1.0^2) / 12.
MASS, LENGTH = 2.0, 0.5
I_XX = MASS * (0.2**2 + 1.0**2) / 12.0
LAMBDA_X = np.sqrt(MASS * G * LENGTH / (I_XX + MASS * LENGTH**2))   # 3.8170 1/s


def test_box_on_a_point_falls_as_the_closed_form_inverted_pendulum():
    """A small tilt eps about x grows as eps cosh(lambda t) (the linearized closed form); the
    remainder of the odd sin nonlinearity is cubic: below eps^3 cosh(lambda T)^3 lambda^2 T^2
    relative, ~1e-7 here, and the tilt stays about x (the other coordinates at rounding)."""
    eps, T = 1e-4, 1.0
    t = np.linspace(0.0, T, 21)
    sim = pinlin.simulate("standing_box", t, dx0=[eps, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert sim.independent_names[:3] == ("q:root_joint[3]", "q:root_joint[4]",
                                         "q:root_joint[5]")
    closed = eps * np.cosh(LAMBDA_X * t)
    np.testing.assert_allclose(sim.z[:, 0], closed, rtol=1e-6, atol=0.0)
    assert np.abs(sim.z[:, [1, 2, 4, 5]]).max() < 1e-13
    assert sim.drift.max() < 1e-14                        # |Phi| [m], |Phi_q v| [m/s]


@pytest.mark.parametrize("name, tilt, spin, horizon", [("standing_box", 0.3, 2.0, 1.5),
                                                       ("g1_standing", 0.05, 0.0, 0.3)])
def test_standing_robot_stays_on_its_contacts_and_conserves_energy(name, tilt, spin, horizon):
    """Large motions: the box, tilted and spun about its long axis, falls around its held
    point in three dimensions (a heavy top upside down), far past the chart's 1 rad (the chart
    is re-centred on the way); the welded G1 collapses from its unstable posture. The contacts
    stay at their anchors to rounding and do no work: kinetic + gravity - u0 . (q - q0) is
    constant to 1e3 rtol of the peak kinetic energy (DOP853's global error over its steps,
    as for the fixed-base mechanisms in test_simulation.py)."""
    model = pinlin.linearize(name)
    dx0 = np.zeros(model.n_states)
    dx0[0] = tilt
    dx0[-1] = spin          # the box: about its long axis (root_joint[5], base frame)
    sim = pinlin.simulate(name, np.linspace(0.0, horizon, 61), dx0=dx0)
    system = pinlin.Scene.resolve(name).system
    kinetic = max(0.5 * v @ system.mass_matrix(q) @ v for q, v in zip(sim.q, sim.v, strict=True))
    assert kinetic > 0.1                                                     # [J]: it moved
    assert sim.drift[:, 0].max() < 1e-12                                     # [m or rad]
    assert sim.drift[:, 1].max() < 1e-13 * max(1.0, np.abs(sim.v).max())     # [m/s or rad/s]
    assert np.abs(sim.energy - sim.energy[0]).max() < 1e3 * sim.info["rtol"] * kinetic
    assert sim.info["effects"][-1] == "contacts"
    if name == "standing_box":
        assert sim.info["restarts"]["chart"] >= 1
        np.testing.assert_allclose(np.linalg.norm(sim.q[:, 3:7], axis=1), 1.0, atol=1e-15)


def test_cli_simulates_a_standing_robot(capsys):
    from pinlin.cli import main

    assert main(["simulate", "solo12_standing", "--t-end", "0.1", "--x0", "q:FL_KFE=0.01"]) == 0
    out = capsys.readouterr().out
    assert "gravity, contacts" in out and "constraint drift" in out


def test_initial_rotation_beyond_pi_is_the_same_motion():
    """A tilt of 3.2 rad and of 3.2 - 2 pi rad are one orientation: the motions agree (the chart
    starts at the initial configuration, so the log map's wrap at pi cannot mislead the first
    step; before, they parted by 1.6e-2 rad and the energy drifted 5e-7 J)."""
    t = np.linspace(0.0, 1.0, 11)
    a = pinlin.simulate("standing_box", t, dx0=[3.2, 0, 0, 0, 0, 1.0])
    b = pinlin.simulate("standing_box", t, dx0=[3.2 - 2 * np.pi, 0, 0, 0, 0, 1.0])
    model = pinlin.Scene.resolve("standing_box").system.model
    gap = max(np.abs(pin.difference(model, x, y)).max() for x, y in zip(a.q, b.q, strict=True))
    assert gap < 1e-9                                          # [rad]; 1e3 rtol
    assert np.ptp(a.energy) < 1e3 * a.info["rtol"] * MASS * G * 2 * LENGTH   # [J]


def test_unreachable_initial_deviation_is_a_clear_error():
    """Bending one knee of a robot standing on four points by 1 rad leaves no configuration
    for the other joints (Newton diverges): a ModelError that blames dx0, not numpy's
    LinAlgError."""
    with pytest.raises(pinlin.ModelError, match="at the initial state .* dx0 moves"):
        pinlin.simulate("solo12_standing", [0.0, 0.01], dx0=[0, 0, 1.0] + [0] * 9)  # HL_KFE


def test_independent_deviation_is_bounded_like_the_full_one():
    with pytest.raises(pinlin.ArgumentError, match="positions .* limited"):
        pinlin.simulate("solo12_standing", [0.0, 0.01], dx0=[1e7] + [0] * 11)


def test_no_note_without_a_deviation():
    assert pinlin.simulate("four_bar", [0.0, 0.1]).info["notes"] == []
