"""Values that numpy would turn into numbers without a word are refused, naming the argument.

``np.array(x, dtype=float)`` reads the text "1e3" as 1000, True as 1, a masked entry as the
value under its mask, and drops imaginary parts. The CLI's states files already refuse
booleans and text; the Python API must too, for a single state and for trajectories.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import pinlin
from pinlin.frequency import frequency_response


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


# Time responses and simulations: numpy's float conversion dropped imaginary parts with a
# ComplexWarning (the input then acted as zero), read text and booleans as numbers, and raised
# its own TypeError or ValueError for what a callable u(t) returned.
_T = np.linspace(0.0, 1.0, 11)


@pytest.mark.parametrize("argument, call, words", [
    ("step amplitude", lambda m: pinlin.response(m, _T, None, pinlin.step(np.array([1j]))),
     "complex"),
    ("step amplitude", lambda m: pinlin.response(m, _T, None, pinlin.step([True])),
     "booleans"),
    ("x0", lambda m: pinlin.response(m, _T, np.array([1 + 5j, 0])), "complex"),
    ("x0", lambda m: pinlin.response(m, _T, ["1", "0"]), "text"),
    ("x0", lambda m: pinlin.response(m, _T, [True, False]), "booleans"),
    ("u", lambda m: pinlin.response(m, _T, None, np.ones(11) * (1 + 1j)), "complex"),
    ("u", lambda m: pinlin.response(m, _T, None, np.ones(11, dtype=bool)), "booleans"),
    ("t", lambda m: pinlin.response(m, np.array([0, 1 + 1j]), [1, 0]), "complex"),
    ("t", lambda m: pinlin.response(m, ["0", "1"], [1, 0]), "text"),
    ("u", lambda m: pinlin.response(m, _T, None, lambda s: "abc"), "text"),
    ("u", lambda m: pinlin.response(m, _T, None, lambda s: {"a": 1}), "dict"),
    ("u", lambda m: pinlin.response(m, _T, None, lambda s: 1j), "complex"),
    ("f0", lambda m: _model(f0=[1, 1j]), "complex"),
    ("f0", lambda m: _model(f0=["1", "2"]), "text"),
    ("G", lambda m: _model(G=[["1"]]), "text"),
    ("G", lambda m: _model(G=[[True]]), "booleans"),
])
def test_responses_and_model_vectors(argument, call, words):
    with pytest.raises(pinlin.ArgumentError, match=f"argument '{argument}': expected .*got "
                                                   f"{words}"):
        call(_model())


@pytest.mark.parametrize("argument, kwargs, words", [
    ("u", {"u": np.ones(11) * 1j}, "complex"),
    ("u", {"u": np.ones(11, dtype=bool)}, "booleans"),
    ("u", {"u": lambda s: "a"}, "text"),
    ("dx0", {"dx0": [[0.1, 0.0]]}, r"a vector of 2 numbers, got shape \(1, 2\)"),
    ("t", {"t": np.array([0.0, 1j])}, "complex"),
])
def test_simulation_inputs(argument, kwargs, words):
    args = {"t": _T, **kwargs}
    t = args.pop("t")
    with pytest.raises(pinlin.ArgumentError, match=f"argument '{argument}': expected .*"
                                                   f"{words}"):
        pinlin.simulate("pendulum", t, **args)


def test_one_input_named_twice_is_refused():
    """``step({"a": 1, "u:a": 2})`` applied 2 and dropped 1 without a word."""
    with pytest.raises(pinlin.ArgumentError, match="input 'u:a' given twice, as 'a' and 'u:a'"):
        pinlin.response(_model(), _T, None, pinlin.step({"a": 1, "u:a": 2}))


def test_tolerances_and_sample_times_at_the_edges():
    # An absolute tolerance of 1e300 let the integrator take any step (0.145 J energy drift).
    with pytest.raises(pinlin.ArgumentError, match="argument 'atol': 1e\\+300 allows"):
        pinlin.simulate("pendulum", _T, atol=1e300)
    run = pinlin.simulate("pendulum", _T, atol=np.int64(1) * 1e-9, rtol=np.float32(1e-6))
    assert run.z.shape == (11, 2)
    with pytest.raises(pinlin.ArgumentError, match="argument 'atol': expected a finite number"):
        pinlin.simulate("pendulum", _T, atol=10 ** 400)
    # dt beyond float64 raised OverflowError from math.isfinite.
    with pytest.raises(pinlin.ArgumentError, match="argument 'dt': expected a sample time"):
        _model().discretize(10 ** 400)
    # Two samples 2e308 s apart: their step overflows, which is said as such.
    with pytest.raises(pinlin.ArgumentError, match="argument 't': the span .* exceeds "
                                                   "float64's range"):
        pinlin.response(_model(), [-1e308, 1e308], [1, 0])


def test_model_names_without_control_characters_and_no_discrete_input_derivative():
    with pytest.raises(pinlin.ArgumentError, match="argument 'name': expected a name without "
                                                   "control characters"):
        _model(name="two\tlines\n")
    with pytest.raises(pinlin.ModelError, match="output term F u'"):
        _model(F=np.ones((2, 1))).discretize(0.01)


def test_more_values_numpy_would_read_as_numbers():
    model = _model()
    with pytest.raises(pinlin.ArgumentError, match="argument 'w': .*got booleans"):
        frequency_response(model, [True, 2.0])
    dec = pinlin.modal(model).decoupling
    with pytest.raises(pinlin.ArgumentError, match="argument 'u': .*got complex"):
        dec.derivative(np.zeros(2), [1 + 5j])
    with pytest.raises(pinlin.ArgumentError, match="argument 'direction': .*got booleans"):
        pinlin.validity("pendulum", [0.01], direction=[True, False])
    traj = pinlin.linearize_trajectory("pendulum", np.zeros((2, 1)))
    with pytest.raises(pinlin.ArgumentError, match="argument 'A': .*got booleans"):
        dataclasses.replace(traj, A=traj.A != 0)


def test_one_sample_time_as_a_number_and_names_with_line_separators():
    assert pinlin.response(_model(), 0.5).t.tolist() == [0.5]
    for name in ("a\u2028b", "a\x85b"):
        with pytest.raises(pinlin.ArgumentError, match="control characters"):
            _model(name=name)
        with pytest.raises(pinlin.ArgumentError, match="control characters"):
            _model(output_names=(name, "y2"))


def test_discretize_says_f_first_and_products_that_overflow_are_refused():
    with pytest.raises(pinlin.ModelError, match="output term F u'"):
        _model(E=np.ones((2, 1)), F=np.ones((2, 1))).discretize(0.01)
    with pytest.raises(pinlin.ModelError, match="second-order matrices describe other"):
        pinlin.LinearModel([[0, 1], [1e200, 0]], np.zeros((2, 1)), np.eye(2),
                           np.zeros((2, 1)), ("q:a", "v:a"), ("u",), ("y1", "y2"),
                           M=[[1e200]], K=[[5.0]], C_damp=[[0.0]], Bu=[[0.0]])


def test_pickled_models_stay_read_only():
    import pickle

    for obj in (pinlin.linearize("pendulum"),
                pinlin.linearize_trajectory("pendulum", np.zeros((2, 1)))):
        again = pickle.loads(pickle.dumps(obj))
        assert np.array_equal(again.A, obj.A) and not again.A.flags.writeable
