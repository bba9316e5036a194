"""Values that numpy would turn into numbers without a word are refused, naming the argument.

``np.array(x, dtype=float)`` reads the text "1e3" as 1000, True as 1, a masked entry as the
value under its mask, and drops imaginary parts. The CLI's states files already refuse
booleans and text; the Python API must too, for a single state and for trajectories.
"""

from __future__ import annotations

import numpy as np
import pytest

import pinlin


@pytest.fixture(scope="module")
def ur5():
    scene = pinlin.Scene.from_robot("ur5")
    return scene, pinlin.linearize(scene).operating_point


BAD = {
    "text": (["1e3"] * 6, "text"),
    "bools": ([True] * 6, "booleans"),
    "bool_among_numbers": ([True, 0, 0, 0, 0, 0], "booleans"),   # numpy reads it as int
    "text_among_numbers": ([0.0, 0.0, "1", 0.0, 0.0, 0.0], "text"),
    "complex": ([1j] * 6, "complex entries"),
    "object_text": (np.array([1, 2, 3, 4, 5, "x"], dtype=object), "text"),
}


@pytest.mark.parametrize("argument", ["v", "u"])
@pytest.mark.parametrize("case", sorted(BAD))
def test_single_state(ur5, argument, case):
    scene, op = ur5
    value, words = BAD[case]
    args = {"q": op.q, "v": np.zeros(6), "u": op.u, argument: value}
    with pytest.raises(pinlin.ArgumentError, match=f"argument '{argument}': expected real "
                                                   f"numbers .* got {words}"):
        pinlin.linearize(scene, **args)


def test_masked_configuration(ur5):
    scene, op = ur5
    q = np.ma.masked_array(op.q, mask=[True] + [False] * 5)
    with pytest.raises(pinlin.ArgumentError, match="argument 'q': .* got masked entries"):
        pinlin.linearize(scene, q=q)
    # Nothing masked: the numbers themselves.
    unmasked = pinlin.linearize(scene, q=np.ma.masked_array(op.q, mask=False))
    assert np.array_equal(unmasked.A, pinlin.linearize(scene, q=op.q).A)


def test_integers_are_numbers(ur5):
    scene, op = ur5
    model = pinlin.linearize(scene, q=op.q, v=np.arange(6), u=np.zeros(6, dtype=int))
    reference = pinlin.linearize(scene, q=op.q, v=np.arange(6.0), u=np.zeros(6))
    assert np.array_equal(model.A, reference.A)


@pytest.mark.parametrize("argument, value, words", [
    ("q", "text", "text"),
    ("v", "bools", "booleans"),
    ("u", "text", "text"),
    ("t", "text", "text"),
])
def test_trajectory(ur5, argument, value, words):
    scene, op = ur5
    arrays = {"q": np.tile(op.q, (3, 1)), "v": np.zeros((3, 6)), "u": np.zeros((3, 6)),
              "t": np.arange(3.0)}
    arrays[argument] = (arrays[argument].astype(str) if value == "text"
                        else arrays[argument] != 0)
    with pytest.raises(pinlin.ArgumentError, match=f"argument '{argument}': expected real "
                                                   f".* got {words}"):
        pinlin.linearize_trajectory(scene, arrays["q"], arrays["v"], arrays["u"], arrays["t"])


def _model(**changes):
    fields = dict(A=np.array([[0.0, 1.0], [-1.0, -0.1]]), B=np.array([[0.0], [1.0]]),
                  C=np.eye(2), D=np.zeros((2, 1)), state_names=("q:a", "v:a"),
                  input_names=("u:a",), output_names=("y1", "y2"))
    fields.update(changes)
    return pinlin.LinearModel(**fields)


def test_linear_model_matrices_and_names():
    with pytest.raises(pinlin.ArgumentError, match="argument 'A': .* got booleans"):
        _model(A=np.eye(2, dtype=bool))
    with pytest.raises(pinlin.ArgumentError, match="argument 'state_names': name 'q:\\\\n' has "
                                                   "control characters"):
        _model(state_names=("q:\n", "v:a"))


def test_modal_indices_and_coordinates():
    modes = pinlin.modal(_model())
    assert modes.kind(1) == modes.kind(np.int64(1))
    for bad in (2, -1, 1.0, True):
        for method in (modes.kind, modes.dominant):
            with pytest.raises(pinlin.ArgumentError, match="argument 'index': expected an "
                                                           "eigenvalue index from 0 to 1"):
                method(bad)
    for kwargs, argument in (({"limit": -1}, "limit"), ({"limit": 1.5}, "limit"),
                             ({"threshold": 2.0}, "threshold"), ({"threshold": 0}, "threshold")):
        with pytest.raises(pinlin.ArgumentError, match=f"argument '{argument}'"):
            modes.dominant(0, **kwargs)      # before: [] without a word
    for method in (modes.to_modal, modes.from_modal):
        with pytest.raises(pinlin.ArgumentError, match="has NaN or inf"):
            method(np.array([np.nan, 0.0]))
        with pytest.raises(pinlin.ArgumentError, match="expected numbers"):
            method(np.array(["1", "0"]))
    r = modes.to_modal(np.array([1.0, 0.0]))
    assert np.allclose(modes.from_modal(r), [1.0, 0.0], atol=1e-14)
