"""Writes the closed-loop mechanism URDFs shipped with pinlin (run from anywhere; files land
beside this script). Each mechanism is a URDF tree whose loops are closed by the scene's
``[[loops]]``. Rods are solid cylinders of radius 0.01 m with their axis along the rod.

Usage: python urdf/make_mechanisms.py
"""

from __future__ import annotations

import math
from pathlib import Path

HERE = Path(__file__).resolve().parent
R_ROD = 0.01


def rod_inertia(mass: float, length: float, axis: str) -> str:
    """Inertia tag of a solid cylinder about its centre, its axis along ``axis``."""
    along = 0.5 * mass * R_ROD**2
    across = mass * (3 * R_ROD**2 + length**2) / 12
    i = {"x": across, "y": across, "z": across}
    i[axis] = along
    return (f'<inertia ixx="{i["x"]:.12g}" ixy="0" ixz="0" iyy="{i["y"]:.12g}" iyz="0" '
            f'izz="{i["z"]:.12g}"/>')


def link(name: str, mass: float = 0.0, com: str = "0 0 0", inertia: str = "") -> str:
    if mass == 0.0:
        return f'  <link name="{name}"/>'
    return (f'  <link name="{name}">\n    <inertial>\n      <origin xyz="{com}"/>\n'
            f'      <mass value="{mass:.12g}"/>\n      {inertia}\n    </inertial>\n  </link>')


def joint(name: str, kind: str, parent: str, child: str, xyz: str = "0 0 0",
          axis: str | None = None, rpy: str = "0 0 0") -> str:
    lines = [f'  <joint name="{name}" type="{kind}">', f'    <parent link="{parent}"/>',
             f'    <child link="{child}"/>', f'    <origin xyz="{xyz}" rpy="{rpy}"/>']
    if axis is not None:
        lines.append(f'    <axis xyz="{axis}"/>')
        if kind in ("revolute", "prismatic"):
            lines.append('    <limit lower="-10" upper="10" effort="100" velocity="10"/>')
    lines.append("  </joint>")
    return "\n".join(lines)


def write(name: str, comment: str, parts: list[str]) -> None:
    text = ('<?xml version="1.0"?>\n<!-- Written for pinlin by urdf/make_mechanisms.py.\n'
            f'{comment} -->\n<robot name="{name}">\n' + "\n".join(parts) + "\n</robot>\n")
    (HERE / f"{name}.urdf").write_text(text)


def planar_rod(name: str, mass: float, length: float) -> str:
    """A rod along its link's +x axis from the joint, in the x-z plane."""
    return link(name, mass, f"{length / 2:.12g} 0 0", rod_inertia(mass, length, "x"))


def four_bar_parts(a: float, b: float, c: float, d: float,
                   masses: dict[str, float]) -> list[str]:
    """Links and joints of a planar four-bar: crank a, coupler b, rocker c, ground d [m]."""
    return [
        link("ground"), planar_rod("crank_link", masses["crank"], a),
        planar_rod("coupler_link", masses["coupler"], b),
        planar_rod("rocker_link", masses["rocker"], c),
        link("coupler_tip"), link("rocker_tip"),
        joint("crank", "revolute", "ground", "crank_link", axis="0 -1 0"),
        joint("coupler", "revolute", "crank_link", "coupler_link", f"{a} 0 0", "0 -1 0"),
        joint("coupler_tip_fixed", "fixed", "coupler_link", "coupler_tip", f"{b} 0 0"),
        joint("rocker", "revolute", "ground", "rocker_link", f"{d} 0 0", "0 -1 0"),
        joint("rocker_tip_fixed", "fixed", "rocker_link", "rocker_tip", f"{c} 0 0"),
    ]


def four_bar() -> None:
    a, b, c, d = 0.2, 0.5, 0.4, 0.45
    m = {"crank": 0.4, "coupler": 1.0, "rocker": 0.8}
    comment = (f"     Planar four-bar in the x-z plane, hinges about -y (angles counter-clockwise "
               f"from +x).\n     Ground pivots O2 = (0, 0, 0) and O4 = ({d}, 0, 0); crank "
               f"a = {a} m ({m['crank']} kg),\n     coupler b = {b} m ({m['coupler']} kg), rocker "
               f"c = {c} m ({m['rocker']} kg): a crank-rocker (Grashof).\n     Loop: point "
               "coupler_tip = rocker_tip (the y row is redundant).")
    write("four_bar", comment, four_bar_parts(a, b, c, d, m))


def slider_crank() -> None:
    r, ell, ms = 0.1, 0.35, 0.5
    m = {"crank": 0.3, "rod": 0.6}
    comment = (f"     Slider-crank in the x-z plane: crank r = {r} m ({m['crank']} kg) about -y "
               f"at the origin,\n     connecting rod l = {ell} m ({m['rod']} kg), slider "
               f"{ms} kg on a prismatic joint along x through the origin.\n     Loop: point "
               "rod_tip = slider_pin, between two moving bodies (the y row is redundant).")
    write("slider_crank", comment, [
        link("ground"), planar_rod("crank_link", m["crank"], r),
        planar_rod("rod_link", m["rod"], ell),
        link("slider_link", ms, "0 0 0", rod_inertia(ms, 0.05, "x")),
        link("rod_tip"), link("slider_pin"),
        joint("crank", "revolute", "ground", "crank_link", axis="0 -1 0"),
        joint("rod", "revolute", "crank_link", "rod_link", f"{r} 0 0", "0 -1 0"),
        joint("rod_tip_fixed", "fixed", "rod_link", "rod_tip", f"{ell} 0 0"),
        joint("slider", "prismatic", "ground", "slider_link", axis="1 0 0"),
        joint("slider_pin_fixed", "fixed", "slider_link", "slider_pin"),
    ])


def five_bar() -> None:
    a, b, d = 0.2, 0.3, 0.15
    m = {"crank": 0.4, "distal": 0.6}
    comment = (f"     Planar five-bar in the x-z plane, hinges about -y: cranks a = {a} m "
               f"({m['crank']} kg) at (0, 0, 0) and ({d}, 0, 0),\n     distal links b = {b} m "
               f"({m['distal']} kg); loop: point left_tip = right_tip. Two degrees of freedom.")
    parts = [link("ground")]
    for side, x0 in (("left", 0.0), ("right", d)):
        parts += [planar_rod(f"{side}_crank_link", m["crank"], a),
                  planar_rod(f"{side}_distal_link", m["distal"], b), link(f"{side}_tip"),
                  joint(f"{side}_crank", "revolute", "ground", f"{side}_crank_link", f"{x0} 0 0",
                        "0 -1 0"),
                  joint(f"{side}_distal", "revolute", f"{side}_crank_link", f"{side}_distal_link",
                        f"{a} 0 0", "0 -1 0"),
                  joint(f"{side}_tip_fixed", "fixed", f"{side}_distal_link", f"{side}_tip",
                        f"{b} 0 0")]
    write("five_bar", comment, parts)


def delta() -> None:
    R, r, L1, L2 = 0.2, 0.05, 0.2, 0.45
    m_arm, m_rod, m_plat = 0.3, 0.2, 0.5
    comment = (f"     Delta-type translational parallel robot (3-RUS): three legs at 0, 120 and "
               f"240 degrees,\n     base radius {R} m, platform radius {r} m, arms {L1} m "
               f"({m_arm} kg), rods {L2} m ({m_rod} kg),\n     platform {m_plat} kg. Each arm "
               "turns about the tangent of the base circle (actuated), its rod hangs from a\n"
               "     universal joint (cross 0.01 kg); the platform is guided in translation by "
               "an x-y-z slider chain\n     (carriages 0.05 kg; the role of a real delta's "
               "parallelograms). Loops: "
               "rod<i>_tip = anchor<i>, three point loops.")
    small = '<inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/>'
    parts = [link("ground"), link("carriage_x", 0.05, "0 0 0", small),
             link("carriage_y", 0.05, "0 0 0", small),
             link("platform", m_plat, "0 0 0",
                  '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.002"/>'),
             joint("platform_x", "prismatic", "ground", "carriage_x", axis="1 0 0"),
             joint("platform_y", "prismatic", "carriage_x", "carriage_y", axis="0 1 0"),
             joint("platform_z", "prismatic", "carriage_y", "platform", axis="0 0 1")]
    for i in range(3):
        g = 2 * math.pi * i / 3
        c, s = math.cos(g), math.sin(g)
        leg = f"leg{i + 1}"
        parts += [
            # arm frame: x radial outward, y tangent (hinge axis), z up
            link(f"{leg}_arm", m_arm, f"{L1 / 2:.12g} 0 0", rod_inertia(m_arm, L1, "x")),
            link(f"{leg}_cross", 0.01, "0 0 0",
                 '<inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/>'),
            link(f"{leg}_rod", m_rod, f"0 0 {-L2 / 2:.12g}", rod_inertia(m_rod, L2, "z")),
            link(f"rod{i + 1}_tip"), link(f"anchor{i + 1}"),
            joint(f"{leg}_hip", "revolute", "ground", f"{leg}_arm",
                  f"{R * c:.12g} {R * s:.12g} 0", "0 -1 0", rpy=f"0 0 {g:.12g}"),
            joint(f"{leg}_knee_a", "revolute", f"{leg}_arm", f"{leg}_cross", f"{L1} 0 0",
                  "0 1 0"),
            joint(f"{leg}_knee_b", "revolute", f"{leg}_cross", f"{leg}_rod", axis="1 0 0"),
            joint(f"rod{i + 1}_tip_fixed", "fixed", f"{leg}_rod", f"rod{i + 1}_tip",
                  f"0 0 {-L2}"),
            joint(f"anchor{i + 1}_fixed", "fixed", "platform", f"anchor{i + 1}",
                  f"{r * c:.12g} {r * s:.12g} 0"),
        ]
    write("delta", comment, parts)


def rotating_double_pendulum() -> None:
    ell = 0.5
    comment = ("     Examples 9.1 and 9.2 of Garcia de Jalon & Bayo: a planar double pendulum "
               "spinning about\n     the vertical axis. Each link has length 2l = "
               f"{2 * ell} m and a lumped unit mass at both ends,\n     written as a 2 kg body "
               f"with its centre of mass at mid-link and inertia 2 l^2 = {2 * ell**2} kg m^2\n"
               "     about the axes normal to the link (two unit point masses l from the centre)."
               "\n     Hinges about -y at the pivot and between the links; q = 0 hangs straight "
               "down,\n     positive angles swing toward +x.")
    inertia = (f'<inertia ixx="{2 * ell**2:.12g}" ixy="0" ixz="0" iyy="{2 * ell**2:.12g}" '
               'iyz="0" izz="0"/>')
    write("rotating_double_pendulum", comment, [
        link("pivot"), link("link1", 2.0, f"0 0 {-ell}", inertia),
        link("link2", 2.0, f"0 0 {-ell}", inertia), link("tip"),
        joint("phi1", "revolute", "pivot", "link1", axis="0 -1 0"),
        joint("phi2", "revolute", "link1", "link2", f"0 0 {-2 * ell}", "0 -1 0"),
        joint("tip_fixed", "fixed", "link2", "tip", f"0 0 {-2 * ell}"),
    ])


if __name__ == "__main__":
    four_bar()
    slider_crank()
    five_bar()
    delta()
    rotating_double_pendulum()
