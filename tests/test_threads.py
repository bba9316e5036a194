"""Concurrency: threads share a System but not its Pinocchio workspaces, and scenes travel to
other processes without their built System."""

from __future__ import annotations

import pickle
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pinocchio as pin

import pinlin


def test_threads_get_the_serial_results():
    """8 threads linearize 300 states of a floating Talos (moving, so that every kernel runs;
    nv = 38) of one shared scene; every A and B equals the serial one bit for bit. The
    threads interleave between the Pinocchio calls of one linearization, each of which reads
    what the previous one left in the Data (computeABADerivatives itself keeps the GIL). With
    one shared pin.Data this went silently wrong (7 of 1000
    ur5 matrices with 8 threads; planted back, this test failed in 10 of 10 runs)."""
    scene = pinlin.Scene.from_robot("talos")
    system = scene.system
    rng = np.random.default_rng(11)
    nv, nu = system.nv, len(system.actuated)
    lower, upper = -np.ones(system.nq), np.ones(system.nq)
    states = [(pin.randomConfiguration(system.model, lower, upper), rng.uniform(-1, 1, nv),
               rng.uniform(-5, 5, nu)) for _ in range(300)]

    def one(state):
        q, v, u = state
        model = pinlin.linearize(scene, q=q, v=v, u=u, estimate_error=False)
        return model.A, model.B

    serial = [one(s) for s in states]
    with ThreadPoolExecutor(max_workers=8) as pool:
        threaded = list(pool.map(one, states))
    wrong = sum(not (np.array_equal(a, c) and np.array_equal(b, d))
                for (a, b), (c, d) in zip(serial, threaded, strict=True))
    assert wrong == 0


def test_a_pickled_scene_leaves_its_system_behind():
    scene = pinlin.Scene.from_robot("talos_arm")
    small = len(pickle.dumps(scene))
    model = pinlin.linearize(scene)          # builds and caches the System
    assert len(pickle.dumps(scene)) == small < 2000
    back = pickle.loads(pickle.dumps(scene))
    assert "system" not in back.__dict__
    np.testing.assert_array_equal(pinlin.linearize(back).A, model.A)
