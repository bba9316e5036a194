"""Frequency responses exactly at a pole: infinite where the entry sees the pole, finite (and
never NaN) where the mode is uncontrollable or unobservable. Expected values are the closed-form
transfer functions of the small models written out in each test."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import pinlin


def _model(A, B, C) -> pinlin.LinearModel:
    A, B, C = (np.array(a, dtype=float) for a in (A, B, C))
    return pinlin.LinearModel(A, B, C, np.zeros((C.shape[0], B.shape[1])),
                              tuple(f"x{i}" for i in range(len(A))),
                              tuple(f"u{i}" for i in range(B.shape[1])),
                              tuple(f"y{i}" for i in range(C.shape[0])))


def test_double_integrator_is_infinite_at_zero_and_closed_form_elsewhere():
    """x1' = x2, x2' = u (a rigid Jordan pair): y = x gives [1/s^2, 1/s], infinite at w = 0
    (before, a raw LinAlgError) and [-1/w^2, 1/(jw)] elsewhere."""
    fr = pinlin.frequency_response(_model([[0, 1], [0, 0]], [[0], [1]], np.eye(2)),
                                   [0.0, 2.0])
    assert np.isinf(fr.H[0]).all()
    np.testing.assert_allclose(fr.H[1, :, 0], [-0.25, 1 / 2j], rtol=1e-15)


def test_unseen_rigid_pair_adds_nothing_at_zero():
    """The same pair with C = 0 has H = 0 at w = 0, not NaN."""
    fr = pinlin.frequency_response(_model([[0, 1], [0, 0]], [[0], [1]], [[0, 0]]), [0.0])
    assert fr.H[0, 0, 0] == 0


def test_uncontrollable_integrator_leaves_the_other_mode_finite():
    """A = diag(0, -1), B = [0; 1], C = [1 1]: the integrator is not driven, so
    H = 1/(s + 1): 1 at w = 0 (before, 0 * inf = NaN)."""
    fr = pinlin.frequency_response(_model([[0, 0], [0, -1]], [[0], [1]], [[1, 1]]), [0.0, 1.0])
    np.testing.assert_allclose(fr.H[:, 0, 0], [1.0, 1 / (1j + 1)], rtol=1e-15)


def test_undamped_mode_at_its_own_frequency_is_infinite():
    """The pendulum's hinge torque to hinge angle is 1 / (J s^2 + m g L), infinite at
    w = sqrt(m g L / J) (the eigenvalue as modal computes it, hit exactly); outputs that do
    not see the mode (tip height to first order) stay finite."""
    model = pinlin.linearize("pendulum")
    w0 = float(np.abs(pinlin.modal(model).eigenvalues).max())
    fr = pinlin.frequency_response(model, [w0], inputs="hinge")
    H = fr.H[0, :, 0]
    assert not np.isnan(H).any()
    angle = fr.output_names.index(next(n for n in fr.output_names if "hinge" in n))
    assert np.isinf(H[angle])
    assert np.isfinite(H).sum() >= 1


def test_floating_robot_at_zero_frequency_has_no_nan():
    """solo12 away from equilibrium has rigid modes (its base, a defective Schur block): at
    w = 0 every entry is infinite or finite, never NaN (before, a raw LinAlgError; then
    entries came out ~1e15 but finite), and every entry that grows like 1/w^2 toward w = 0
    (50x from w = 1e-5 to 1e-6; 1/w^2 gives 100x) is infinite there."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = pinlin.linearize("solo12", allow_non_equilibrium=True)
    fr = pinlin.frequency_response(model, [0.0, 1e-5, 1e-6, 1.0])
    H0, H5, H6 = fr.H[0], fr.H[1], fr.H[2]
    assert not np.isnan(fr.H).any() and np.isfinite(fr.H[1:]).all()
    growing = np.abs(H6) >= 50 * np.abs(H5)
    assert growing.any() and np.isinf(H0[growing]).all()


def test_high_frequencies_keep_their_digits():
    """ur5_arm (servo springs and dampers): the modal sum cancels terms of size 1/w into an H
    of size 1/w^2, and lost all digits by 1e15 rad/s. Reference: (jwI - A) X = B solved
    directly, well conditioned there (|A|_F << w)."""
    from pinlin.frequency import frequency_response

    model = pinlin.linearize("ur5_arm")
    w = np.array([1e4, 1e8, 1e12, 1e15])
    H = frequency_response(model, w).H
    n = model.A.shape[0]
    for k, wk in enumerate(w):
        ref = model.C @ np.linalg.solve(1j * wk * np.eye(n) - model.A, model.B) + model.D
        assert np.abs(H[k] - ref).max() <= 1e-12 * np.abs(ref).max(), wk


def test_bad_selections_and_overflow_near_the_origin():
    from pinlin.frequency import frequency_response

    dint = _model([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], np.eye(2))
    with pytest.raises(pinlin.ModelError, match="leaves float64's range"):
        frequency_response(dint, [1e-160])     # inf - inf in the Jordan pair: NaN before
    for bad in (0, b"u0", [], ["u0", "u0"]):
        with pytest.raises(pinlin.ArgumentError, match="argument 'inputs'"):
            frequency_response(dint, [1.0], inputs=bad)


def test_gain_takes_an_input_without_its_prefix():
    from pinlin.frequency import frequency_response

    model = pinlin.linearize("double_pendulum")
    fr = frequency_response(model, [1.0, 2.0])
    name = model.input_names[0]
    assert np.array_equal(fr.gain(model.output_names[0], name.removeprefix("u:")),
                          fr.gain(model.output_names[0], name))
    with pytest.raises(pinlin.ArgumentError, match="argument 'input': expected one input"):
        fr.gain(model.output_names[0], [name])
