"""Saving, loading and python-control interop of LinearModel."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import URDF_DIR

import pinlin


@pytest.fixture(scope="module")
def model():
    return pinlin.linearize(URDF_DIR / "ur5_arm.toml")


@pytest.mark.parametrize("suffix", [".npz", ".mat", ".json"])
def test_round_trip(model, tmp_path, suffix):
    back = pinlin.LinearModel.load(model.save(tmp_path / f"m{suffix}"))
    for key in ("A", "B", "C", "D", "M", "C_damp", "K", "Bu"):
        np.testing.assert_array_equal(getattr(back, key), getattr(model, key))
    assert back.state_names == model.state_names and back.output_names == model.output_names
    np.testing.assert_array_equal(back.operating_point.q, model.operating_point.q)
    assert back.info["formulation"] == "independent"


def test_to_control_keeps_names_and_poles(model):
    sys = model.to_control()
    assert list(sys.input_labels) == list(model.input_names)
    assert list(sys.state_labels) == list(model.state_names)
    poles = np.sort_complex(sys.poles())
    np.testing.assert_allclose(poles, np.sort_complex(np.linalg.eigvals(model.A)), rtol=1e-10)


def test_shapes_are_validated():
    with pytest.raises(pinlin.ShapeError, match="B must be 2x1"):
        pinlin.LinearModel(A=np.zeros((2, 2)), B=np.zeros((3, 1)), C=np.eye(2),
                           D=np.zeros((2, 1)), state_names=["a", "b"], input_names=["u"],
                           output_names=["a", "b"])


def test_standard_form_removes_input_derivative():
    # x' = -x + u + 2 u': with x~ = x - 2u, x~' = -x~ + (1 - 2) u, y = x~ + 2u.
    m = pinlin.LinearModel(A=[[-1.0]], B=[[1.0]], C=[[1.0]], D=[[0.0]], E=[[2.0]],
                           state_names=["x"], input_names=["u"], output_names=["y"])
    s = m.standard_form()
    assert s.B[0, 0] == -1.0 and s.D[0, 0] == 2.0 and s.E is None


def test_arrays_are_read_only(model):
    with pytest.raises(ValueError):
        model.A[0, 0] = 1.0


@pytest.mark.parametrize("target", ["ur5_arm", "double_pendulum"])
def test_assembled_models_pass_the_public_checks(target):
    """Formulations build models without re-validation; the public constructor must accept
    every field they produce unchanged (shapes, dtypes, read-only arrays, distinct names)."""
    import dataclasses

    model = pinlin.linearize(target)
    fields = {f.name: getattr(model, f.name) for f in dataclasses.fields(model)}
    checked = pinlin.LinearModel(**fields)
    for key in ("A", "B", "C", "D", "M", "C_damp", "K", "Bu"):
        arr = getattr(model, key)
        assert arr.dtype == np.float64 and not arr.flags.writeable
        assert getattr(checked, key) is arr  # accepted as is: already consistent
    assert checked.info == model.info
    op = model.operating_point  # built by OperatingPoint.trusted: every field present
    point = {f.name: getattr(op, f.name) for f in dataclasses.fields(op)}
    assert op.__dict__.keys() == point.keys()
    assert pinlin.OperatingPoint(**point).__dict__ == op.__dict__


@pytest.mark.parametrize(("info", "words"), [
    ({"big": 10**400}, "more than 300 digits"),      # loaded back it would be inf
    ({3: "three"}, "key 3 is not a string"),          # loaded back it would be "3"
    ({"nested": {"ok": 1, (1, 2): 0}}, "is not a string"),
])
@pytest.mark.parametrize("suffix", [".npz", ".mat", ".json"])
def test_info_that_would_not_load_back_the_same_is_refused(info, words, suffix, tmp_path):
    import dataclasses

    model = pinlin.linearize("pendulum")
    path = tmp_path / f"m{suffix}"
    with pytest.raises(pinlin.ModelFileError, match=words):
        dataclasses.replace(model, info={**model.info, **info}).save(path)
    assert not path.exists()
