"""Property-based tests (hypothesis): random serial chains and random four-bar linkages.

- serial chains (revolute, continuous or prismatic joints about random axes, masses and
  inertias within physical bounds): the analytic model agrees with the fd5 one within fd5's own
  error estimate, and the symmetric and general eigensolvers agree where both apply;
- closed chains (random Grashof four-bars): penalty physical eigenvalues approach the
  independent-coordinate ones within the O(1/alpha) penalty error.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

import pinlin
from pinlin.modal import symmetric_applicable

SETTINGS = settings(max_examples=25, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


axes = st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(
    lambda v: np.linalg.norm(v) > 0.3)


@st.composite
def serial_chains(draw):
    n = draw(st.integers(2, 5))
    links = []
    for _ in range(n):
        kind = draw(st.sampled_from(["revolute", "revolute", "continuous", "prismatic"]))
        axis = _unit(draw(axes))
        mass = draw(st.floats(0.1, 5.0))
        # principal moments that satisfy the triangle inequality: sums of two positives
        a, b, c = (draw(st.floats(1e-3, 0.05)) for _ in range(3))
        inertia = (a + b, b + c, a + c)
        offset = [draw(st.floats(-0.3, 0.3)) for _ in range(3)]
        com = [draw(st.floats(-0.2, 0.2)) for _ in range(3)]
        links.append((kind, axis, mass, inertia, offset, com))
    return links


def _chain_urdf(links) -> str:
    parts = ['<?xml version="1.0"?><robot name="chain"><link name="base"/>']
    parent = "base"
    for i, (kind, axis, mass, inertia, offset, com) in enumerate(links):
        parts.append(f'<link name="l{i}"><inertial><origin xyz="{com[0]} {com[1]} {com[2]}"/>'
                     f'<mass value="{mass}"/><inertia ixx="{inertia[0]}" ixy="0" ixz="0" '
                     f'iyy="{inertia[1]}" iyz="0" izz="{inertia[2]}"/></inertial></link>')
        limit = ('' if kind == "continuous"
                 else '<limit lower="-3" upper="3" effort="100" velocity="10"/>')
        parts.append(f'<joint name="j{i}" type="{kind}"><parent link="{parent}"/>'
                     f'<child link="l{i}"/><origin xyz="{offset[0]} {offset[1]} {offset[2]}"/>'
                     f'<axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>{limit}</joint>')
        parent = f"l{i}"
    parts.append("</robot>")
    return "".join(parts)


def _chain_scene(tmp_path, links, data, stiffness=50.0):
    """The chain at a drawn configuration, servoed, under gravity."""
    q = data.draw(st.lists(st.floats(-1.0, 1.0), min_size=len(links), max_size=len(links)))
    urdf = tmp_path / "chain.urdf"
    urdf.write_text(_chain_urdf(links))
    return pinlin.Scene.from_urdf(urdf, effects={
        "gravity": [0.0, 0.0, -9.81],
        "springs": {f"j{i}": {"stiffness": stiffness} for i in range(len(links))}},
        operating_point={"q": {f"j{i}": q[i] for i in range(len(links))}})


@SETTINGS
@given(links=serial_chains(), data=st.data())
def test_random_chain_analytic_matches_fd5(tmp_path, links, data):
    scene = _chain_scene(tmp_path, links, data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        exact = pinlin.linearize(scene)
        approx = pinlin.linearize(scene, derivatives="fd5")
    scale = np.abs(exact.A).max()
    err = np.abs(approx.A - exact.A).max() / scale
    assert err <= 10 * approx.info["error_estimate"] + 1e-12, (err, approx.info)
    np.testing.assert_allclose(approx.B, exact.B, atol=1e-10 * np.abs(exact.B).max())


@SETTINGS
@given(links=serial_chains(), data=st.data())
def test_random_chain_symmetric_and_general_eigensolvers_agree(tmp_path, links, data):
    scene = _chain_scene(tmp_path, links, data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        model = pinlin.linearize(scene)
        if not symmetric_applicable(model):
            return  # K not symmetric (a spring-less gravity term can make it so): nothing to do
        sym = pinlin.modal(model, method="symmetric")
        gen = pinlin.modal(model, method="general")
    _, cols = linear_sum_assignment(np.abs(gen.eigenvalues[:, None]
                                           - sym.eigenvalues[None, :]))
    bound = 100 * gen.condition * np.finfo(float).eps * np.abs(model.A).max() + 1e-9
    assert np.all(np.abs(sym.eigenvalues[cols] - gen.eigenvalues) <= bound)


FOUR_BAR = """<?xml version="1.0"?><robot name="fb"><link name="ground"/>
<link name="crank_link"><inertial><origin xyz="{a2} 0 0"/><mass value="{ma}"/>
<inertia ixx="{ja}" ixy="0" ixz="0" iyy="{ia}" iyz="0" izz="{ia}"/></inertial></link>
<link name="coupler_link"><inertial><origin xyz="{b2} 0 0"/><mass value="{mb}"/>
<inertia ixx="{jb}" ixy="0" ixz="0" iyy="{ib}" iyz="0" izz="{ib}"/></inertial></link>
<link name="rocker_link"><inertial><origin xyz="{c2} 0 0"/><mass value="{mc}"/>
<inertia ixx="{jc}" ixy="0" ixz="0" iyy="{ic}" iyz="0" izz="{ic}"/></inertial></link>
<link name="coupler_tip"/><link name="rocker_tip"/>
<joint name="crank" type="revolute"><parent link="ground"/><child link="crank_link"/>
<axis xyz="0 -1 0"/><limit lower="-9" upper="9" effort="1" velocity="1"/></joint>
<joint name="coupler" type="revolute"><parent link="crank_link"/><child link="coupler_link"/>
<origin xyz="{a} 0 0"/><axis xyz="0 -1 0"/><limit lower="-9" upper="9" effort="1" velocity="1"/>
</joint>
<joint name="ct" type="fixed"><parent link="coupler_link"/><child link="coupler_tip"/>
<origin xyz="{b} 0 0"/></joint>
<joint name="rocker" type="revolute"><parent link="ground"/><child link="rocker_link"/>
<origin xyz="{d} 0 0"/><axis xyz="0 -1 0"/><limit lower="-9" upper="9" effort="1" velocity="1"/>
</joint>
<joint name="rt" type="fixed"><parent link="rocker_link"/><child link="rocker_tip"/>
<origin xyz="{c} 0 0"/></joint></robot>"""


@st.composite
def four_bars(draw):
    b, c, d = (draw(st.floats(0.3, 0.6)) for _ in range(3))
    # A Grashof crank-rocker with margin: the crank is the shortest link and
    # a + longest <= sum of the other two - 0.05 (never a change point or a fold).
    a_max = min(min(b, c, d), b + c + d - 2 * max(b, c, d)) - 0.05
    a = draw(st.floats(0.3, 1.0)) * max(a_max, 0.02) if a_max > 0.02 else None
    if a is None:
        b, c, d, a = 0.5, 0.4, 0.45, 0.2
    masses = [draw(st.floats(0.1, 2.0)) for _ in range(3)]
    theta = draw(st.floats(0.0, 2 * math.pi))
    return a, b, c, d, masses, theta


def _rocker_angle(a, b, c, d, theta):
    bx, bz = a * math.cos(theta), a * math.sin(theta)
    px, pz = bx - d, bz
    e = math.hypot(px, pz)
    cosang = (c * c + e * e - b * b) / (2 * c * e)
    return math.atan2(pz, px) - math.acos(max(-1.0, min(1.0, cosang))), bx, bz


@SETTINGS
@given(fb=four_bars())
def test_random_four_bar_penalty_converges_to_independent(tmp_path, fb):
    a, b, c, d, (ma, mb, mc), theta = fb
    psi, bx, bz = _rocker_angle(a, b, c, d, theta)
    cx, cz = d + c * math.cos(psi), c * math.sin(psi)
    coupler = math.atan2(cz - bz, cx - bx) - theta
    urdf = tmp_path / "fb.urdf"
    urdf.write_text(FOUR_BAR.format(a=a, b=b, c=c, d=d, a2=a / 2, b2=b / 2, c2=c / 2, ma=ma,
                                    mb=mb, mc=mc, ia=ma * a * a / 12, ib=mb * b * b / 12,
                                    ic=mc * c * c / 12, ja=ma * a * a / 12e3,
                                    jb=mb * b * b / 12e3, jc=mc * c * c / 12e3))
    # Rods: the moment about the rod's axis is 1e-3 of the others, so every drawn inertia
    # satisfies the triangle inequality (a fixed 1e-5 broke it for short light cranks).
    scene = pinlin.Scene.from_dict({
        "urdf": str(urdf), "effects": {"gravity": [0, 0, -9.81],
                                       "springs": {"crank": {"stiffness": 5.0,
                                                             "rest": theta}}},
        "loops": [{"name": "closure", "frame1": "coupler_tip", "frame2": "rocker_tip"}],
        "operating_point": {"q": {"crank": theta, "coupler": coupler, "rocker": psi},
                            "independent": ["crank"]},
        "inputs": {"actuated": ["crank"]}})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pinlin.AccuracyWarning)
        ref = np.linalg.eigvals(pinlin.linearize(scene).A)
        errors = []
        for alpha in (1e6, 1e8):
            modes = pinlin.modal(pinlin.linearize(scene, formulation="penalty", alpha=alpha))
            phys = modes.eigenvalues[~modes.constraint]
            errors.append(max(np.min(np.abs(phys - x)) / abs(x) for x in ref))
    assert errors[1] <= 1e-5
    assert errors[1] <= 0.05 * errors[0] + 1e-12  # shrinking like 1/alpha
