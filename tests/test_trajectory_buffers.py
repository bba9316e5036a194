"""``linearize_trajectory(..., out=previous)``: the new models written into the arrays of a
model an earlier call returned (pinlin.trajectory_buffers). Every array must equal a fresh
call's bit for bit, whatever the previous call held there (moving states before states at
rest, so that a stale Lie-group block or drift would show), and what cannot be reused safely
is refused."""

from __future__ import annotations

import pickle

import numpy as np
import pinocchio as pin
import pytest

import pinlin

FIELDS = ("A", "B", "C", "D", "f0", "q", "v", "u", "a", "y", "M", "C_damp", "K", "Bu")


def _states(scene, N, seed, moving=True):
    system = scene.system
    rng = np.random.default_rng(seed)
    neutral = pin.neutral(system.model)
    q = np.array([pin.integrate(system.model, neutral, rng.uniform(-1, 1, system.nv))
                  for _ in range(N)])
    v = rng.uniform(-2, 2, (N, system.nv)) if moving else np.zeros((N, system.nv))
    return q, v, rng.uniform(-3, 3, (N, len(system.actuated)))


def _equal(a, b):
    for key in FIELDS:
        x, y = getattr(a, key), getattr(b, key)
        assert (x is None) == (y is None), key
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=key)
    assert a.info == b.info and a.state_names == b.state_names


@pytest.mark.parametrize("name, kwargs", [
    ("ur5", {}),
    ("solo12", {}),                               # free flyer: -1/2 ad(v) blocks, then v = 0
    ("ur5", {"derivatives": "fd3"}),              # per-point path: f0 None at rest
    ("ur5", {"second_order": True}),
    ("double_pendulum", {}),                      # a frame output: C and y per point
])
def test_reused_arrays_equal_a_fresh_call(name, kwargs):
    scene = (pinlin.Scene.resolve(name) if name == "double_pendulum"
             else pinlin.Scene.from_robot(name))
    first = pinlin.linearize_trajectory(scene, *_states(scene, 6, 1), **kwargs)
    A_memory = first.A
    states = _states(scene, 6, 2, moving=False)
    again = pinlin.linearize_trajectory(scene, *states, out=first, **kwargs)
    assert again is first and again.A is A_memory and not again.A.flags.writeable
    _equal(again, pinlin.linearize_trajectory(scene, *states, **kwargs))
    # and back to moving states, into the same memory once more
    states = _states(scene, 6, 3)
    pinlin.linearize_trajectory(scene, *states, out=first, **kwargs)
    _equal(first, pinlin.linearize_trajectory(scene, *states, **kwargs))


def test_a_schedule_of_rest_points_reuses_its_arrays():
    scene = pinlin.Scene.from_robot("ur5")
    q1, q2 = _states(scene, 5, 4)[0], _states(scene, 5, 5)[0]
    first = pinlin.linearize_trajectory(scene, q1)
    pinlin.linearize_trajectory(scene, q2, out=first)
    _equal(first, pinlin.linearize_trajectory(scene, q2))


def test_what_cannot_be_reused_is_refused():
    scene = pinlin.Scene.from_robot("ur5")
    states = _states(scene, 4, 6)
    model = pinlin.linearize_trajectory(scene, *states)
    cases = [
        (lambda: pinlin.linearize_trajectory(scene, *states, out=pinlin.linearize(scene)),
         "expected a TrajectoryModel"),
        (lambda: pinlin.linearize_trajectory(scene, *_states(scene, 5, 6), out=model),
         "holds 4 points without second-order stacks; this call makes 5 points"),
        (lambda: pinlin.linearize_trajectory(scene, *states, second_order=True, out=model),
         "this call makes 4 points with second-order stacks"),
        (lambda: pinlin.linearize_trajectory(pinlin.Scene.from_robot("ur5"), *states,
                                             out=model), "another system"),
        (lambda: pinlin.linearize_trajectory(scene, *states, workers=2, out=model),
         "not with workers > 1"),
        (lambda: pinlin.linearize_trajectory(scene, *states, out=model.discretize(0.01)),
         "was not computed by linearize_trajectory"),
        (lambda: pinlin.linearize_trajectory(scene, *states,
                                             out=pickle.loads(pickle.dumps(model))),
         "was not computed by linearize_trajectory"),
    ]
    for call, words in cases:
        with pytest.raises(pinlin.ArgumentError, match=f"argument 'out': .*{words}"):
            call()
    mechanism = pinlin.Scene.resolve("four_bar")
    q = np.tile(pinlin.linearize(mechanism).operating_point.q, (3, 1))
    loops = pinlin.linearize_trajectory(mechanism, q)
    with pytest.raises(pinlin.ArgumentError, match="argument 'out': reuses an open chain's"):
        pinlin.linearize_trajectory(mechanism, q, out=loops)


def test_a_failed_call_leaves_nan_and_no_reuse():
    """The previous models are gone once writing began: NaN, not a mix of two calls."""
    scene = pinlin.Scene.from_robot("ur5")
    states = _states(scene, 300, 7)
    model = pinlin.linearize_trajectory(scene, *states)

    def stop(done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        pinlin.linearize_trajectory(scene, *states, out=model, progress=stop)
    assert np.isnan(model.A).all() and np.isnan(model.B).all()
    with pytest.raises(pinlin.ArgumentError, match="invalidated by a call that failed"):
        pinlin.linearize_trajectory(scene, *states, out=model)


def test_a_schedule_by_single_calls_refuses_out():
    """A standing robot's schedule is single static calls, one per point: nothing to reuse
    (out was ignored)."""
    scene = pinlin.Scene.resolve("solo12_standing")
    q = np.tile(pinlin.linearize(scene).operating_point.q, (2, 1))
    first = pinlin.linearize_trajectory(scene, q)
    with pytest.raises(pinlin.ArgumentError, match="argument 'out': .*scheduled by single"):
        pinlin.linearize_trajectory(scene, q, out=first)


def test_what_was_derived_before_does_not_change():
    """at(k), discretize() and dataclasses.replace() of a model later passed as out= shared
    its memory: they took the next call's matrices beside their own states. They copy now;
    out's own arrays (views included) change, as NumPy's out= does."""
    import dataclasses

    scene = pinlin.Scene.resolve("double_pendulum")      # frame outputs: C and y per point
    model = pinlin.linearize_trajectory(scene, *_states(scene, 4, 9))
    point, disc = model.at(1), model.discretize(0.01)
    copy = dataclasses.replace(model, name="kept")
    before = {"point": point.A.copy(), "C": disc.C.copy(), "y": disc.y.copy(),
              "a": disc.a.copy(), "copy": copy.A.copy(), "pC": point.C.copy()}
    pinlin.linearize_trajectory(scene, *_states(scene, 4, 10), out=model)
    np.testing.assert_array_equal(point.A, before["point"])
    np.testing.assert_array_equal(point.C, before["pC"])
    for key in ("C", "y", "a"):
        np.testing.assert_array_equal(getattr(disc, key), before[key], err_msg=key)
    np.testing.assert_array_equal(copy.A, before["copy"])
    assert not np.array_equal(model.A, before["copy"])     # out itself holds the new models


def test_arrays_made_writeable_are_not_reused():
    """Entries a call does not write (structural zeros) kept a user's edits."""
    scene = pinlin.Scene.from_robot("ur5")
    states = _states(scene, 3, 11)
    model = pinlin.linearize_trajectory(scene, *states)
    model.A.setflags(write=True)
    model.A[0, 0, 1] = 123.0
    with pytest.raises(pinlin.ArgumentError, match="arrays made writeable"):
        pinlin.linearize_trajectory(scene, *states, out=model)
