"""Closed loops at many operating points (a gain schedule's sweep): the assembly cache and the
fast kernels change no result.

References: a cold solve on a freshly built scene (its own, empty cache); Pinocchio's Jacobian
time variation for the geometric stiffness (the general path, one
``computeJointJacobiansTimeVariation`` per coordinate); the row-by-row constraint Jacobian;
numpy's and scipy's checked wrappers for the LAPACK calls.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg as sla

import pinlin
from pinlin.assembly import ASSEMBLY_TOL, AssemblyCache, assembly_cache
from pinlin.lapack_direct import condition_2, lstsq, lstsq_rank, pivoted_qr
from pinlin.operating_point import configuration
from pinlin.scene import Scene, bundled_scenes

LOOP_SCENES = ["four_bar", "delta", "five_bar", "slider_crank"]


def _scene(name: str) -> Scene:
    return Scene.load(bundled_scenes()[name])


def _sweep(scene: Scene, points: int = 12, span: float = 0.6) -> list[np.ndarray]:
    """Distinct guesses: the scene's configuration with its independent coordinates swept
    over +-span [rad], and in the middle one point far from its neighbours."""
    system = scene.system
    q_op = pinlin.operating_point(scene).q
    guess = configuration(system)
    zq = [system.joint(n).idx_q for n in scene.operating_point.independent]
    out = []
    for k in range(points):
        q = guess.copy()
        for i, iq in enumerate(zq):
            q[iq] = q_op[iq] + span * (2.0 * k / (points - 1) - 1.0) * (1.0 - 0.3 * i)
        out.append(q)
    far = guess.copy()
    for iq in zq:
        far[iq] = q_op[iq] - 0.5
    out.insert(points // 2, far)
    return out


def _same_model(a: pinlin.LinearModel, b: pinlin.LinearModel) -> None:
    for key in ("A", "B", "C", "D", "M", "K"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    np.testing.assert_array_equal(a.operating_point.q, b.operating_point.q)
    np.testing.assert_array_equal(a.operating_point.lam, b.operating_point.lam)


@pytest.mark.parametrize("name", ["four_bar", "delta"])
def test_sweep_gives_the_cold_solve_at_every_point(name):
    """A sweep on one scene (its cache filling as it goes, a far jump in the middle) gives at
    every point the model a fresh scene gives cold; then the same sweep again, now from the
    cache, gives the same models bit for bit (Newton from one guess is deterministic)."""
    scene = _scene(name)
    guesses = _sweep(scene)
    swept = [pinlin.linearize(scene, q=q) for q in guesses]
    cache = assembly_cache(scene.system)
    assert cache.hits == 0 and cache.misses >= len(guesses)
    for q, model in zip(guesses, swept, strict=True):
        cold = pinlin.linearize(_scene(name), q=q)
        _same_model(model, cold)
        residual = scene.system.constraints.residual(model.operating_point.q)
        assert np.abs(residual).max() <= ASSEMBLY_TOL
    again = [pinlin.linearize(scene, q=q) for q in guesses]
    assert cache.hits >= len(guesses)
    for a, b in zip(swept, again, strict=True):
        _same_model(a, b)


def test_a_guess_on_the_other_branch_is_not_pulled_to_the_cached_one():
    """Four-bar with the crank at 1 rad closes on two branches (coupler, rocker) = (-0.55,
    1.30) (open) and (-2.36, -2.21) (crossed). With the open branch solved at crank 1.00, a
    guess near the crossed branch at crank 1.05 must assemble crossed, as it does cold:
    starting Newton from the nearest solved point would have returned the open branch."""
    scene = _scene("four_bar")
    system = scene.system
    open_guess = np.array([1.0, -0.6, 1.6])
    crossed_guess = np.array([1.05, -2.3, -2.2])
    open_model = pinlin.linearize(scene, q=open_guess)
    crossed = pinlin.linearize(scene, q=crossed_guess)
    q_open, q_crossed = open_model.operating_point.q, crossed.operating_point.q
    assert abs(q_open[2] - 1.30) < 0.05
    assert abs(q_crossed[2] - (-2.21)) < 0.1  # the crossed branch
    _same_model(crossed, pinlin.linearize(_scene("four_bar"), q=crossed_guess))
    # Starting from the solved open point, Newton stays on the open branch: the case the
    # cache must not create.
    from pinlin.assembly import assemble

    start = q_open.copy()
    start[0] = 1.05
    warm = assemble(system, start, np.array([0]))
    assert abs(warm[2] - q_crossed[2]) > 1.0


def test_caches_do_not_cross_scenes_or_anchors():
    a, b = _scene("four_bar"), _scene("four_bar")
    pinlin.linearize(a, q=np.array([1.1, -0.6, 1.6]))
    assert len(assembly_cache(a.system)._table) == 1
    assert len(assembly_cache(b.system)._table) == 0
    assert assembly_cache(a.system) is not assembly_cache(b.system)
    # A scene with contacts anchors them where q puts its frames: each anchoring is a new
    # constraint set with its own cache.
    standing = _scene("standing_box")
    q = pinlin.operating_point(standing).q
    anchored = standing.system.anchored_at(q)
    if standing.system.constraints.contacts:
        assert anchored.constraints is not standing.system.constraints
        assert assembly_cache(anchored) is not assembly_cache(standing.system)


def test_cache_keeps_the_most_recent_entries():
    cache = AssemblyCache(size=3)
    q, jac = np.zeros(2), np.zeros((1, 2))
    keys = [cache.key(np.array([float(k), 0.0]), np.array([0])) for k in range(5)]
    for key in keys:
        cache.put(key, q, jac)
    assert cache.get(keys[0]) is None and cache.get(keys[1]) is None
    found = cache.get(keys[4])
    assert found is not None and not found[0].flags.writeable


def test_threads_sweeping_one_scene_get_the_serial_models():
    scene = _scene("delta")
    guesses = _sweep(scene, points=16) * 2  # the second half hits the cache
    serial = [pinlin.linearize(_scene("delta"), q=q).A for q in guesses[:17]]
    with ThreadPoolExecutor(max_workers=4) as pool:
        threaded = list(pool.map(lambda q: pinlin.linearize(scene, q=q).A, guesses))
    for k, A in enumerate(threaded):
        np.testing.assert_array_equal(A, serial[k % 17])


# ---------------------------------------------------------------------------------------------
# Kernels against their references


def _random_points(system, count: int, seed: int):
    rng = np.random.default_rng(seed)
    lower, upper = -np.ones(system.nq), np.ones(system.nq)
    for _ in range(count):
        yield pin.randomConfiguration(system.model, lower, upper), rng


@pytest.mark.parametrize("name", LOOP_SCENES + ["standing_box", "solo12_standing"])
def test_batched_geometric_stiffness_matches_the_time_variation(name):
    """lam^T Phi_qq by the batched closed form against one Pinocchio time variation per
    coordinate, at the operating point and random configurations, random lam: the two agree
    to rounding (a few eps of the largest entry)."""
    scene = _scene(name)
    cons = scene.system.constraints
    op = pinlin.operating_point(scene)
    points = [(op.q, np.random.default_rng(3))] + list(_random_points(scene.system, 3, 5))
    for q, rng in points:
        lam = rng.standard_normal(cons.size)
        fast = cons.hessian(q, lam)
        ref = cons.hessian_by_time_variation(q, lam)
        scale = max(float(np.abs(ref).max()), 1.0)
        assert np.abs(fast - ref).max() <= 64 * np.finfo(float).eps * scale


def test_batched_geometric_stiffness_in_a_rotating_scene():
    """The four-bar spinning about the vertical: the spin joint heads the kinematic model, its
    column is dropped, and the batched path agrees with the reference."""
    base = _scene("four_bar")
    data = {"name": "spinning_four_bar", "urdf": str(base.urdf),
            "effects": {"gravity": [0.0, 0.0, -9.81],
                        "rotation": {"axis": [0.0, 0.0, 1.0], "rate": 2.0}},
            "loops": [{"name": "closure", "type": "point", "frame1": "coupler_tip",
                       "frame2": "rocker_tip"}],
            "operating_point": {"q": {"crank": 1.0, "coupler": -0.6, "rocker": 1.6},
                                "independent": ["crank"]},
            "inputs": {"actuated": ["crank"]}}
    scene = Scene.from_dict(data)
    cons = scene.system.constraints
    assert cons._batched_hessian
    for q, rng in _random_points(scene.system, 3, 9):
        lam = rng.standard_normal(cons.size)
        ref = cons.hessian_by_time_variation(q, lam)
        np.testing.assert_allclose(cons.hessian(q, lam), ref, rtol=0,
                                   atol=64 * np.finfo(float).eps * max(np.abs(ref).max(), 1))


@pytest.mark.parametrize("name", LOOP_SCENES + ["standing_box", "solo12_standing"])
def test_stacked_constraint_rows_equal_the_row_by_row_ones(name):
    """Phi and Phi_q from the stacked frames equal, bit for bit, the loop over closures."""
    scene = _scene(name)
    cons = scene.system.constraints
    plan = cons._point_plan
    assert plan is not None
    for q, _ in _random_points(scene.system, 3, 2):
        phi, jac = cons.residual_and_jacobian(q)
        cons.__dict__["_point_plan"] = None
        try:
            phi_ref, jac_ref = cons.residual_and_jacobian(q)
            residual = cons.residual(q)
        finally:
            cons.__dict__["_point_plan"] = plan
        np.testing.assert_array_equal(phi, phi_ref)
        np.testing.assert_array_equal(jac, jac_ref)
        np.testing.assert_array_equal(residual, phi_ref)


def _matrices():
    rng = np.random.default_rng(17)
    square = rng.standard_normal((6, 6))
    tall = rng.standard_normal((7, 4))
    with_zero_row = np.vstack([rng.standard_normal((2, 3))[:, :2], np.zeros((1, 2))])
    deficient = np.outer(rng.standard_normal(5), rng.standard_normal(5))
    near = square.copy()
    near[:, -1] = near[:, 0] * (1 + 1e-13)
    return [square, tall, with_zero_row, deficient, near, rng.standard_normal((3, 5))]


@pytest.mark.parametrize("a", _matrices())
def test_lapack_helpers_match_the_checked_wrappers(a):
    b = np.random.default_rng(1).standard_normal(a.shape[0])
    ref, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
    x, r = lstsq_rank(a, b)
    scale = max(1.0, float(np.abs(ref).max()))
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10 * scale)
    assert r == rank
    well_posed = np.linalg.cond(a) < 1e8
    if well_posed:
        np.testing.assert_allclose(lstsq(a, b), ref, rtol=0, atol=1e-10 * scale)
    diag, piv = pivoted_qr(a.T)
    _, R, piv_ref = sla.qr(a.T, mode="economic", pivoting=True)
    np.testing.assert_array_equal(piv, piv_ref)
    np.testing.assert_allclose(diag, np.abs(np.diag(R)), rtol=1e-12, atol=0)
    if a.shape[0] == a.shape[1]:
        ref_cond = np.linalg.cond(a)
        assert condition_2(a) == pytest.approx(ref_cond, rel=1e-8) or ref_cond > 1e15


def test_non_finite_jacobian_block_has_nan_condition():
    assert np.isnan(condition_2(np.array([[np.nan, 1.0], [0.0, 1.0]])))
