"""The same system at another physical scale gives the same answer, scaled.

Reference (independent of the code): dynamic similarity. Lengths multiplied by s, masses by
k (inertias by k s^2), gravity unchanged, springs by k s (torque per radian) and a steady
rotation's rate by 1/sqrt(s): the equations of motion in joint angles are those of the
original with time stretched by sqrt(s), so every eigenvalue is the original's / sqrt(s),
and every verdict (an equilibrium or not, assembled or not) is the same. With s and k powers
of 2 (s an even power, so that sqrt(s) is one too) every number in the scaled problem is the
original's times a power of 2, exactly: floating-point arithmetic then scales exactly too,
and only a threshold that does not scale (an absolute tolerance, in metres or N*m) can tell
the two apart. The tolerances below are therefore not rounding bounds but the margin that a
threshold placed relative to the problem's own size leaves: 1e-11 relative, against the
1e-9 .. 1e-2 that absolute thresholds produced (a 4 mm pendulum accelerating at 1700 rad/s^2
was called an equilibrium; a 0.1 mm five-bar closed to 4e-9 of its size).
"""

from __future__ import annotations

import dataclasses
import tomllib
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import pinlin
from pinlin.robots import load_robot
from pinlin.scene import bundled_scenes


def scaled_scene(name: str, s: float, k: float, tmp: Path, **overrides) -> pinlin.Scene:
    """Bundled scene ``name`` with lengths x s and masses x k (see the module docstring);
    ``overrides``: scene fields replaced (after scaling)."""
    path = bundled_scenes()[name]
    data = tomllib.loads(path.read_text())
    tree = ET.parse(load_robot(data.pop("robot")).urdf_path if "robot" in data
                    else path.parent / data.pop("urdf"))
    for link in tree.getroot().iter("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
        for inertial in link.findall("inertial"):
            mass = inertial.find("mass")
            mass.set("value", repr(float(mass.get("value")) * k))
            inertia = inertial.find("inertia")
            for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                inertia.set(key, repr(float(inertia.get(key, "0")) * k * s * s))
    for origin in tree.getroot().iter("origin"):
        if origin.get("xyz"):
            origin.set("xyz", " ".join(repr(float(x) * s) for x in origin.get("xyz").split()))
    prismatic = {j.get("name") for j in tree.getroot().iter("joint")
                 if j.get("type") == "prismatic"}
    effects = data.get("effects", {})
    for joint, spring in effects.get("springs", {}).items():
        spring["stiffness"] *= k / s if joint in prismatic else k * s
        if joint in prismatic:
            spring["rest"] *= s
    if "rotation" in effects:
        effects["rotation"]["rate"] /= np.sqrt(s)
    for joint, value in data.get("operating_point", {}).get("q", {}).items():
        if joint in prismatic:
            data["operating_point"]["q"][joint] = value * s
    data.update(overrides)
    urdf = tmp / f"{name}_{s:g}_{k:g}.urdf"
    tree.write(urdf)
    return pinlin.Scene.from_urdf(urdf, **data)


def eigenvalues(model: pinlin.LinearModel) -> np.ndarray:
    """Sorted by imaginary part (exact zeros for real ones), then real part (of undamped
    modes: rounding, which must not decide the order)."""
    lam = np.linalg.eigvals(model.A)
    return lam[np.lexsort((lam.real, lam.imag))]


#: (s, k): a 4 mm robot of the same density, 61 um and 1/256 of the mass, 256 m and 2^20
#: times the mass; powers of 2 (module docstring).
SCALES = [(2.0 ** -8, 2.0 ** -24), (2.0 ** -14, 2.0 ** -8), (2.0 ** 8, 2.0 ** 20)]


@pytest.mark.parametrize("s, k", SCALES)
def test_a_joint_its_inputs_cannot_hold_is_refused_at_any_size(tmp_path, s, k):
    """The double pendulum with its elbow bent and only the shoulder actuated: gravity pulls
    the elbow (1.1 N*m at 1 m and 1 kg), at any size."""
    fields = {"operating_point": {"q": {"shoulder": 0.0, "elbow": 0.5}},
              "inputs": {"actuated": ["shoulder"]}}
    for scale, mass in ((1.0, 1.0), (s, k)):
        scene = scaled_scene("double_pendulum", scale, mass, tmp_path, **fields)
        with pytest.raises(pinlin.EquilibriumError, match="not an equilibrium"):
            pinlin.linearize(scene)
        # Asked for (allowed), the acceleration is the original's / s.
        op = pinlin.operating_point(scene, allow_non_equilibrium=True)
        if scale == 1.0:
            a_ref = op.a
        else:
            np.testing.assert_allclose(op.a * s, a_ref, rtol=1e-11)
            assert not op.equilibrium


@pytest.mark.parametrize("s, k", SCALES)
@pytest.mark.parametrize("name", ["double_pendulum", "rotating_double_pendulum", "four_bar",
                                  "five_bar", "slider_crank", "delta"])
def test_eigenvalues_scale_as_one_over_root_s(tmp_path, name, s, k):
    """Open chains held by their inputs, the rotating pendulum's passive equilibrium (whose
    gravity and centrifugal forces cancel: a large one was refused against an absolute
    tolerance), and the mechanisms' assemblies (closed to an absolute 1e-12 m before)."""
    reference = pinlin.linearize(scaled_scene(name, 1.0, 1.0, tmp_path))
    model = pinlin.linearize(scaled_scene(name, s, k, tmp_path))
    lam_ref, lam = eigenvalues(reference), eigenvalues(model) * np.sqrt(s)
    size = np.abs(lam_ref).max()
    assert np.abs(lam - lam_ref).max() <= 1e-11 * size, (lam, lam_ref)
    assert model.operating_point.equilibrium == reference.operating_point.equilibrium


@pytest.mark.parametrize("s, k", SCALES)
def test_a_standing_robot_splits_its_weight_alike_at_any_size_and_place(tmp_path, s, k):
    """solo12 on its four feet (point contacts) in its SRDF posture: the inputs and contact
    forces that hold it form a family of 6 dimensions, and the member pinlin reports must be
    the same physical split at any size (u0 times k s, the forces times k, the eigenvalues
    / sqrt(s)) and wherever the robot stands (moved 64 m along x). The plain least-norm
    [u0; lam], which adds N*m to N, picked another split at each size: u0 off by 10 % to 100 %
    and the eigenvalues by 4e-4 to 2e-3. Scaled, every number is the original's times a
    power of 2 (module docstring: measured equal bit for bit); moved, the feet's positions
    round to eps 64 m against their 0.2 m spread (measured 1e-13 relative): 1e-11."""
    q = load_robot("solo12").q_ref.copy()
    reference = pinlin.linearize(scaled_scene("solo12_standing", 1.0, 1.0, tmp_path), q=q)
    op_ref = reference.operating_point
    assert any("a family of 6 dimensions" in n for n in op_ref.notes)
    lam_ref = eigenvalues(reference)
    size = np.abs(lam_ref).max()
    q_scaled = q.copy()
    q_scaled[:3] *= s
    q_moved = q.copy()
    q_moved[0] += 64.0
    for scene, q_k, length, mass in (
            (scaled_scene("solo12_standing", s, k, tmp_path), q_scaled, s, k),
            (scaled_scene("solo12_standing", 1.0, 1.0, tmp_path), q_moved, 1.0, 1.0)):
        model = pinlin.linearize(scene, q=q_k)
        op = model.operating_point
        np.testing.assert_allclose(op.u / (mass * length), op_ref.u, rtol=0,
                                   atol=1e-11 * np.abs(op_ref.u).max())
        np.testing.assert_allclose(op.lam / mass, op_ref.lam, rtol=0,
                                   atol=1e-11 * np.abs(op_ref.lam).max())
        lam = eigenvalues(model) * np.sqrt(length)
        assert np.abs(lam - lam_ref).max() <= 1e-11 * size, (lam, lam_ref)


def test_the_penalty_warns_where_its_alpha_is_small_for_the_masses(tmp_path):
    """The penalty formulation's alpha is in kg per constraint unit^2: the default 1e7 leaves
    the four-bar of kilograms its physical eigenvalues to 3e-8 of the independent model's,
    but the same four-bar of 1e6 kg at 1/128 of the size lost them (0.1) and gained an
    unstable eigenvalue, silently. The estimate in ``info`` gives the error measured against
    the independent model (the reference) within a factor 2, and the warning comes where it
    is large (``test_penalty_error.py`` holds the estimate to a few per cent)."""
    for s, k, due in ((1.0, 1.0, False), (2.0 ** -7, 2.0 ** 20, True)):
        scene = scaled_scene("four_bar", s, k, tmp_path)
        exact = np.linalg.eigvals(pinlin.linearize(scene).A)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model = pinlin.linearize(scene, formulation="penalty")
        lam = np.linalg.eigvals(model.A)
        error = max(np.abs(lam - x).min() / abs(x) for x in exact)
        warned = [w for w in caught if issubclass(w.category, pinlin.AccuracyWarning)
                  and "penalty alpha" in str(w.message)]
        assert 0.5 * error <= model.info["penalty_error"] <= 2.0 * error
        assert bool(warned) == due
        assert (error > 1e-2) == due and (error < 1e-6) != due


@pytest.mark.parametrize("s, k", [(1.0, 1.0), (2.0 ** 8, 2.0 ** 20)])
def test_numerical_input_derivatives_keep_their_digits_on_heavy_robots(tmp_path, s, k):
    """The inputs enter the dynamics linearly, so fd5's B is exact but for the rounding of
    u0 +- h, eps |u0| / h relative: a fixed step of 1e-3 N*m beside the 1.8e9 N*m that hold a
    256 m, million-fold heavy double pendulum bent at the elbow left B 2.6e-5 off. The step
    now scales with max(1, |u0|): B agrees with the analytic one to rounding at any size."""
    scene = scaled_scene("double_pendulum", s, k, tmp_path,
                         operating_point={"q": {"shoulder": 0.5, "elbow": 0.3}})
    exact = pinlin.linearize(scene).B
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        numeric = pinlin.linearize(scene, derivatives="fd5").B
    # eps / h = 2.2e-13 per column, summed over fd5's four evaluations: 1e-12 with margin 5
    assert np.abs(numeric - exact).max() <= 1e-12 * np.abs(exact).max()


@pytest.mark.parametrize("name", ["four_bar", "slider_crank"])
def test_a_mechanism_moves_alike_at_any_size(tmp_path, name):
    """The mechanism released from q0 moved along its independent coordinate, simulated
    (nonlinear, loops closed by Newton at every state) 15 um large (s = 2^-16) and as it
    is, time stretched by sqrt(s): the same motion and about the same number of steps. The
    loops' Newton stopped at an absolute 1e-14 m: 1e-9 of the small one's size, reached only
    by its stall test, 50x the steps and the motion off by 1e-7. With a tolerance relative
    to the size the two runs still take different steps (Newton's last digits differ),
    each within the solver's own error (rtol = 1e-10 per step, ~40 to 160 steps): measured
    3.6e-9 of the amplitude (four-bar) and 2.6e-10 (slider-crank); 1e-8."""
    s = 2.0 ** -16
    runs = []
    for scale in (1.0, s):
        scene = scaled_scene(name, scale, 1.0, tmp_path)
        t = np.linspace(0.0, 2.0, 41) * np.sqrt(scale)
        runs.append(pinlin.simulate(scene, t, dx0=[0.3, 0.0]))
    reference, small = runs
    assert small.info["steps"] <= 2 * reference.info["steps"]
    assert np.abs(small.z[:, 0] - reference.z[:, 0]).max() <= 1e-8 * 0.3


@pytest.mark.parametrize("s, k", SCALES)
def test_a_floating_robot_reports_one_mass_condition_at_any_size(tmp_path, s, k):
    """solo12 floating (its contacts removed, falling: allowed), in its SRDF posture. Its
    mass matrix mixes kg (the base's translation) and kg*m^2 (every rotation), so tr(M)
    tr(M^-1) / n grew like 1/s^2: 1e4 at 1 m, 4e13 at 15 um with a warning that about 3
    digits were left, though the model is the same. The estimate of M scaled to unit
    diagonal, sum_i M_ii (M^-1)_ii, is a product of scaled pairs: equal at any size, bit for
    bit with powers of 2, and no warning."""
    q = load_robot("solo12").q_ref.copy()
    conditions = []
    for scale, mass in ((1.0, 1.0), (s, k)):
        scene = scaled_scene("solo12_standing", scale, mass, tmp_path, contacts=[],
                             operating_point={"allow_non_equilibrium": True})
        q_k = q.copy()
        q_k[:3] *= scale
        with warnings.catch_warnings():
            warnings.simplefilter("error", pinlin.AccuracyWarning)
            conditions.append(pinlin.linearize(scene, q=q_k).info["condition"]["mass_matrix"])
    assert conditions[1] == conditions[0] < 1e3


@pytest.mark.parametrize("name, s, k", [
    ("solo12_standing", 2.0 ** -8, 2.0 ** -24), ("solo12_standing", 2.0 ** 8, 2.0 ** 20),
    ("standing_box", 2.0 ** -16, 2.0 ** -8), ("standing_box", 2.0 ** 16, 2.0 ** 20),
    ("slider_crank", 2.0 ** -14, 2.0 ** -8), ("delta", 2.0 ** -8, 2.0 ** -24)])
def test_a_mechanism_keeps_its_coordinates_and_condition_at_any_size(tmp_path, name, s, k):
    """A floating base standing on its feet, a slider-crank and a delta (with linear
    coordinates beside angular ones) choose their independent coordinates (the standing
    robots; the mechanisms name theirs) and measure the condition of Phi_d in one unit, so
    both are the same at any size. In m/m beside m/rad
    they were not: solo12 at 256 m chose other joints, the box on its tip chose its own
    translations at 256 m with Phi_d's condition 128 (1.6 at 1 m) and 32768 at 65 km, and the
    condition of a 61 um slider-crank read 6e4 times its value at 1 m, past the "near a
    singular position" note. Scaled by powers of 2 the Jacobians scale exactly (module
    docstring): the same pivots, the condition equal to rounding (1e-11). A trajectory
    through one state measures every point as its first (stacked for the slider-crank,
    point by point for solo12), alike at any size."""
    models, conditions = [], []
    for scale, mass in ((1.0, 1.0), (s, k)):
        scene = scaled_scene(name, scale, mass, tmp_path)
        q = None
        if scene.system.base_joint:   # its position scaled with the robot; solo12 in its
            q = (load_robot("solo12").q_ref.copy() if name == "solo12_standing"  # SRDF
                 else pinlin.operating_point(scaled_scene(name, 1.0, 1.0, tmp_path)).q)
            q[:3] *= scale                                                      # posture
        with warnings.catch_warnings():
            warnings.simplefilter("error", pinlin.AccuracyWarning)
            models.append(pinlin.linearize(scene, q=q))
        if name in ("slider_crank", "solo12_standing"):
            op = models[-1].operating_point
            trajectory = pinlin.linearize_trajectory(
                scene, np.array([op.q] * 3), np.zeros((3, op.v.size)), np.array([op.u] * 3))
            conditions.append(trajectory.info["loops"]["condition"])
    reference, model = models
    assert model.info["independent"] == reference.info["independent"]
    assert model.info["dropped_rows"] == reference.info["dropped_rows"]
    c_ref = reference.info["condition"]["constraint_jacobian"]
    assert abs(model.info["condition"]["constraint_jacobian"] - c_ref) <= 1e-11 * c_ref
    assert c_ref < 1e3
    if conditions:
        np.testing.assert_allclose(conditions, conditions[0][0], rtol=1e-11)


@pytest.mark.parametrize("name, s, k", [("slider_crank", 2.0 ** -8, 2.0 ** -24),
                                        ("slider_crank", 2.0 ** 8, 2.0 ** 20),
                                        ("delta", 2.0 ** -8, 2.0 ** -24),
                                        ("standing_box", 2.0 ** 8, 2.0 ** 20)])
def test_a_given_velocity_is_projected_alike_at_any_size(tmp_path, name, s, k):
    """A velocity that does not satisfy the loops is projected onto those that do, to the
    closest one. Closest in m/s beside rad/s, the choice depended on the size: the slider's
    velocity (m/s) counted for nothing beside the crank's (rad/s) at 4 mm and for everything
    at 256 m. In one unit (a linear coordinate's velocity over the robot's length) the
    projected velocity of the scaled mechanism is the original's, scaled (linear ones by
    sqrt(s), angular ones by 1/sqrt(s)), in the single call and in a trajectory (stacked for
    the mechanisms, point by point for the box on its tip)."""
    from pinlin.coordinates import linear_coordinates

    v0 = np.random.default_rng(3).uniform(-1.0, 1.0, scaled_scene(name, 1.0, 1.0, tmp_path)
                                          .system.nv)
    projected = []
    for scale, mass in ((1.0, 1.0), (s, k)):
        scene = scaled_scene(name, scale, mass, tmp_path)
        factor = np.where(linear_coordinates(scene.system), np.sqrt(scale), 1 / np.sqrt(scale))
        op = pinlin.operating_point(scene)
        v = v0 * factor
        single = pinlin.linearize(scene, q=op.q, v=v, u=op.u).operating_point.v
        trajectory = pinlin.linearize_trajectory(scene, op.q[None], v[None], op.u[None]).v[0]
        np.testing.assert_allclose(trajectory, single, rtol=0, atol=1e-13 * np.abs(v).max())
        assert np.abs(single - v).max() > 0.01 * np.abs(v).max()   # it was projected
        projected.append(single / factor)
    np.testing.assert_allclose(projected[1], projected[0], rtol=0,
                               atol=1e-11 * np.abs(projected[0]).max())


@pytest.mark.parametrize("s, k", [(1.0, 1.0), (2.0 ** -14, 2.0 ** -8)])
def test_a_slider_parametrized_slider_crank_rechooses_its_coordinate_at_any_size(tmp_path,
                                                                               s, k):
    """The slider-crank parametrized by its slider, released with the crank turning: near the
    crank and rod in line the slider is a poor coordinate (Phi_d of crank and rod nearly
    singular) and the simulation re-chooses, comparing Phi_d's condition with a fresh
    choice's in one unit. In m/m beside m/rad the fresh choice (slider and rod dependent)
    looked no better and the simulation kept the slider, at 1 m as at 61 um. At both sizes
    it now re-chooses once and follows the crank-parametrized motion (time stretched by
    sqrt(s)) to 1e-7 rad, with simulate's default tolerances (an absolute 1e-12 m on the
    slider, 1.6e-8 of the 61 um mechanism, lost the loops at the dead centre: the default is
    now 1e-12 per radian, 1e-12 L per metre)."""
    scene = scaled_scene("slider_crank", s, k, tmp_path)
    spec = dataclasses.replace(scene.operating_point, independent=("slider",))
    by_slider = dataclasses.replace(scene, operating_point=spec)
    t = np.linspace(0.0, 3.0, 31) * np.sqrt(s)
    ref = pinlin.simulate(scene, t, dx0=[0.0, 8.0 / np.sqrt(s)], rtol=1e-12, atol=1e-14 * s)
    sim = pinlin.simulate(by_slider, t, q0=ref.q[0], v0=ref.v[0], u=lambda _: ref.u[0])
    assert sim.independent_names == ("q:slider", "v:slider")
    assert sim.info["restarts"]["partition"] == 1
    crank = scene.system.joint("crank").idx_q
    assert np.abs(sim.q[:, crank] - ref.q[:, crank]).max() < 1e-7


@pytest.mark.parametrize("s, k", [(2.0 ** -8, 2.0 ** -24), (2.0 ** 8, 2.0 ** 20)])
def test_the_sensitivity_check_moves_alike_at_any_size(tmp_path, s, k):
    """Near a singular position a mechanism's model is rebuilt at the configurations the
    assembly cannot tell apart, q0 -/+ d w with w the weakest direction of Phi_d. The
    slider-crank's dependent coordinates are the rod [rad] and the slider [m]: in mixed units
    that direction leaned to the slider at 4 mm and to the rod at 256 m. In one unit the move
    is the same, its length scaled by s (the reference: dynamic similarity)."""
    from pinlin.equilibrium import solve_constrained
    from pinlin.formulations.constrained import indistinguishable_move

    moves = []
    for scale, mass in ((1.0, 1.0), (s, k)):
        system = scaled_scene("slider_crank", scale, mass, tmp_path).system
        q = system.scene_configuration.copy()
        op, cp = solve_constrained(system, q)
        move = indistinguishable_move(system, op, cp)
        slider = system.joint("slider").idx_v
        move[slider] /= scale
        moves.append(move)
    np.testing.assert_allclose(moves[1], moves[0], rtol=1e-9, atol=0)


def cart_pole(s: float, k: float, tmp: Path) -> pinlin.Scene:
    """A cart on a spring (prismatic x) carrying a hanging pendulum (revolute y): 2 kg cart,
    1 kg bob 1 m below the hinge, spring 50 N/m, all scaled by lengths s and masses k (module
    docstring: the spring by k / s). Its two modes mix metres and radians."""
    urdf = tmp / f"cart_pole_{s:g}_{k:g}.urdf"
    inertia = repr(1e-3 * k * s * s)
    urdf.write_text(f"""<?xml version="1.0"?>
<robot name="cart_pole">
  <link name="base"/>
  <link name="cart"><inertial><mass value="{2.0 * k!r}"/>
    <inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" iyz="0" izz="{inertia}"/>
  </inertial></link>
  <link name="bob"><inertial><origin xyz="0 0 {-s!r}"/><mass value="{k!r}"/>
    <inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" iyz="0" izz="{inertia}"/>
  </inertial></link>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="cart"/>
    <axis xyz="1 0 0"/><limit lower="-1e3" upper="1e3" effort="1" velocity="1"/></joint>
  <joint name="hinge" type="revolute"><parent link="cart"/><child link="bob"/>
    <axis xyz="0 1 0"/><limit lower="-3.14" upper="3.14" effort="1" velocity="1"/></joint>
</robot>""")
    return pinlin.Scene.from_urdf(
        urdf, name="cart_pole", base="fixed",
        effects={"gravity": [0.0, 0.0, -9.81],
                 "springs": {"slide": {"stiffness": 50.0 * k / s, "rest": 0.0}}},
        operating_point={"q": {"slide": 0.0, "hinge": 0.0}, "solve": "positions"})


@pytest.mark.parametrize("s, k", [(2.0 ** -14, 2.0 ** -8), (2.0 ** 8, 2.0 ** 20)])
def test_validity_finds_the_same_radius_at_any_size(tmp_path, s, k):
    """pinlin.validity's amplitudes count lengths in units of L, the robot's characteristic
    length: a cart-pole (modes mixing m and rad) and the slider-crank parametrized by its
    slider (a length its only coordinate) have the same radii, initial states and orders at
    any size. In metres beside radians the cart-pole's modes were normalized by their radian
    entry at 61 um and by their metre entry at 256 m, and the slider-crank's sweep began at
    1 mm, 16 times the size of the 61 um mechanism (radius 0.001, "below range", against
    0.0022 m at 1 m). Scaled, the problem is the original's times powers of 2 (module
    docstring) and the simulations run alike; the integration noise the tolerance leaves,
    NOISE_RTOL rtol = 1e-7 of the error e ~ 1e-2, moves the radius by ~1e-5 relative at
    order p ~ 2 (measured 2e-9 on the slider-crank, 2.5e-8 on the cart-pole): 1e-5. The
    order is fitted where e is smallest, ~1e-6 for the cart-pole's p = 3, so the same noise
    moves it by ~1e-4 (measured 9e-5): 1e-3. The initial states are eigenvectors of A scaled
    exactly by powers of 2: equal to rounding (measured: bit for bit), 1e-12."""
    spec = dataclasses.replace(
        scaled_scene("slider_crank", 1.0, 1.0, tmp_path).operating_point,
        independent=("slider",))
    results = []
    for scale, mass in ((1.0, 1.0), (s, k)):
        crank = scaled_scene("slider_crank", scale, mass, tmp_path)
        by_slider = dataclasses.replace(crank, operating_point=dataclasses.replace(
            crank.operating_point, independent=spec.independent))
        results.append([pinlin.validity(by_slider, periods=2),
                        pinlin.validity(cart_pole(scale, mass, tmp_path), periods=2)])
    for ref, res in zip(*results, strict=True):
        assert ref.length is not None and res.length == pytest.approx(ref.length * s, rel=1e-12)
        assert [c.unit for c in res.cases] == ["rad or L"] * len(ref.cases)
        for c_ref, c in zip(ref.cases, res.cases, strict=True):
            assert c.bound is c_ref.bound is pinlin.validity_report.Bound.FOUND
            assert c.radius == pytest.approx(c_ref.radius, rel=1e-5)
            assert c.slope == pytest.approx(c_ref.slope, abs=1e-3)   # reported to 0.01
            # The initial state in rad and L (its metres scale by s), velocities per second
            # of the scaled time.
            n = len(res.weights)
            time = np.repeat([1.0, s ** 0.5], n)
            np.testing.assert_allclose(c.direction * np.tile(res.weights, 2) * time,
                                       c_ref.direction * np.tile(ref.weights, 2), rtol=0,
                                       atol=1e-12)


def test_validity_takes_a_given_atol_in_metres_and_advises_in_metres(tmp_path):
    """A given atol is absolute in rad and m; on the 61 um slider-crank parametrized by its
    slider (L = 9.4e-6 m) 1e-9 m is 1.1e-4 per L, whose noise (1e3 atol / a) reaches the 1 %
    tolerance at a = 1e-3: refused, with advice in metres that is then accepted (the advice
    had been given per L: 1e-9, the value just refused)."""
    crank = scaled_scene("slider_crank", 2.0 ** -14, 2.0 ** -8, tmp_path)
    scene = dataclasses.replace(crank, operating_point=dataclasses.replace(
        crank.operating_point, independent=("slider",)))
    with pytest.raises(pinlin.ArgumentError, match=r"atol = 1e-09 \(0.000107 per L, L = "
                                                   r"9.39e-06 m\).*or atol <= (\S+)") as exc:
        pinlin.validity(scene, [1e-3, 2e-3], periods=1, atol=1e-9)
    advised = float(exc.value.args[0].rsplit("atol <= ", 1)[1])
    assert advised == pytest.approx(1e-3 * 0.01 / 1e3 / 10 * 9.39e-6, rel=0.1)
    result = pinlin.validity(scene, [1e-3, 2e-3], periods=1, atol=advised)
    assert result.length == pytest.approx(9.39e-6, rel=1e-3)
