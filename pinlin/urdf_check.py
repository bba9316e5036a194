"""URDF files checked before Pinocchio parses them, with errors naming the element and the fault.

urdfdom (the URDF reader inside Pinocchio) is lenient in ways that change the robot without
failing: a malformed number in an ``<inertial>`` (``xyz="0 0 -0.5x"``, ``rpy="0 0 zero"``,
``"1e400"``, ``"nan"``, a missing ``izz``, ``value=" 1.0 "``) makes it print a complaint on the
C-level stderr and go on with that link's inertia zeroed; a broken ``<visual>`` or
``<collision>`` is complained about and dropped. It also accepts, without a word, things that no
robot can mean: a zero joint axis (Pinocchio then builds a joint that moves nothing), an
``<axis>`` without ``xyz`` (the same), a second ``<origin>``/``<axis>``/``<mass>`` where the
first silently wins, a misspelt attribute (``xzy=``) silently read as the default, an empty name,
a negative effort or damping, lower > upper limits, a ``<mimic>`` of a joint that does not exist
or of itself, and a ``planar`` joint whose axis Pinocchio ignores (its plane is always the x-y
plane of the joint frame).

:func:`check_urdf` therefore checks the XML itself with the standard library before Pinocchio
sees it, so that the message names the link or joint, the element, the attribute and what was
expected. (What it does not anticipate, :mod:`pinlin.urdf_io` catches as urdfdom's complaints.)

Numbers follow urdfdom's grammar (``std::istringstream`` in the classic locale): decimal, with
optional sign, fraction and exponent; leading blanks are skipped, trailing characters are an
error, and values outside the double range (``1e400``) as well as ``nan``/``inf`` are refused.
Vectors are numbers separated by spaces (urdfdom splits on spaces only: a tab or line break
inside ``xyz``/``rpy`` is refused with its line number), exactly three of them.

Checked besides: masses >= 0 and physical inertia tensors; names present, non-empty and unique;
known joint types; exactly one ``<parent>``/``<child>`` naming defined links; one root, no link
with two parents, no cycles; at most one of each ``<origin>``, ``<axis>``, ``<limit>``,
``<dynamics>``, ``<mimic>``, ``<inertial>``, ``<mass>``, ``<inertia>``; a ``<limit>`` (with
``effort`` and ``velocity`` >= 0) on revolute and prismatic joints, lower <= upper there;
``<dynamics>`` with damping or friction >= 0; a ``<mimic>`` names another existing joint and
chains of them do not loop. Unknown attributes are errors on ``<origin>``, ``<axis>``,
``<mass>``, ``<inertia>``, ``<parent>``, ``<child>``; on ``<limit>``, ``<dynamics>`` and
``<mimic>``, which carry vendor extensions (Panda: ``<dynamics D K mu_coulomb>``), only a
near-miss of a known name (``multipler``) is.

Accepted as they are (each gives the model the URDF specification describes):

- a non-unit joint axis: urdfdom passes it on and Pinocchio normalizes it (checked: ``0 2 0``
  gives the same mass matrix and gravity torque as ``0 1 0``; MuJoCo normalizes too). Axes
  shorter than :data:`MIN_AXIS_NORM` are refused as zero: Pinocchio cannot normalize a vector
  whose squared length underflows (``1e-300`` stays unnormalized);
- an absent ``<axis>`` on a revolute, continuous or prismatic joint: the URDF default (1, 0, 0);
- an absent ``lower``/``upper`` in ``<limit>``: the URDF default 0;
- a fixed or floating joint's ``<axis>`` (unused), even ``0 0 0`` as CAD exporters write it;
- a ``<mimic>`` on a fixed joint (Talos has them; Pinocchio ignores them);
- extra top-level elements (``<gazebo>``, ``<transmission>``, ...), which urdfdom ignores.

Refused although urdfdom accepts them: a planar joint whose axis is not ``0 0 1`` (Pinocchio's
planar joint always moves in the x-y plane of the joint frame; the URDF default axis is
(1, 0, 0)).
"""

from __future__ import annotations

import difflib
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import numpy as np

from .exceptions import UrdfError
from .fields import POSITION_LIMIT

#: Shortest joint axis accepted [-]: anything shorter is reported as a zero axis.
MIN_AXIS_NORM = 1e-6

#: Smallest positive link mass [kg]: Pinocchio adds each link's inertia to its body's with
#: the centre of mass divided by max(m, eps), so below eps the lever arm shrinks by m / eps
#: (a 1e-18 kg link 0.15 m out got 3e-6 m; a 1e-16 kg pendulum bob gave A[1, 0] = -0.403
#: instead of -4.905); from eps on the division is exact.
MASS_FLOOR = 2.220446049250313e-16

#: Largest magnitudes accepted in ``<origin>`` [m, rad]: the scene files' position range.
#: (An offset of 1e200 m overflows m d^2 and made M NaN, reported as a body without mass.
#: Huge masses and inertias are left to the model's own check, which names matrix M.)
MAGNITUDE_LIMITS = {"xyz": POSITION_LIMIT, "rpy": POSITION_LIMIT}

#: Velocity dimension of each URDF joint type as Pinocchio builds it.
JOINT_NV = {"revolute": 1, "continuous": 1, "prismatic": 1, "fixed": 0, "floating": 6,
            "planar": 3}
_AXIS_TYPES = ("revolute", "continuous", "prismatic")

# urdfdom's strToDouble: istringstream >> double, then nothing may follow. Leading blanks are
# skipped by the stream; no hexadecimal, no 'nan'/'inf', no digit separators.
_NUMBER = re.compile(r"\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")

# Attributes each element may carry: anything else is a typo that urdfdom silently ignores.
_ATTRIBUTES = {
    "origin": ("xyz", "rpy"),
    "axis": ("xyz",),
    "mass": ("value",),
    "inertia": ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"),
    "limit": ("lower", "upper", "effort", "velocity"),
    "dynamics": ("damping", "friction"),
    "mimic": ("joint", "multiplier", "offset"),
    "parent": ("link",),
    "child": ("link",),
}
_EXTENSIBLE = ("limit", "dynamics", "mimic")
_UNITS = {
    "xyz": "m", "rpy": "rad", "value": "kg", "ixx": "kg*m^2", "ixy": "kg*m^2", "ixz": "kg*m^2",
    "iyy": "kg*m^2", "iyz": "kg*m^2", "izz": "kg*m^2", "lower": "rad or m", "upper": "rad or m",
    "effort": "N*m or N", "velocity": "rad/s or m/s", "damping": "N*m*s/rad or N*s/m",
    "friction": "N*m or N", "multiplier": "-", "offset": "rad or m",
}


@dataclass(frozen=True)
class UrdfSummary:
    """What :func:`check_urdf` learned about a valid URDF.

    Attributes:
        name: The robot's name.
        links: Number of links.
        joint_types: Joint name -> URDF type, in file order.
        nv: Velocity dimension of the Pinocchio model built from it (no free flyer).
        njoints: Pinocchio joints of that model, the universe included (fixed joints become
            frames, so this is 1 + the number of moving joints).
    """

    name: str
    links: int
    joint_types: dict[str, str]
    nv: int
    njoints: int


class _Checker:
    """Checks one parsed URDF document; every method raises :class:`UrdfError` on a fault."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, reason: str) -> NoReturn:
        raise UrdfError(self.path, reason)

    # -- numbers ---------------------------------------------------------------------------------
    def number(self, where: str, attr: str, text: str) -> float:
        unit = _UNITS.get(attr, "-")
        if not _NUMBER.fullmatch(text):
            self.fail(f"{where} {attr}={text!r}: expected a finite number [{unit}] (decimal, "
                      "no trailing characters)")
        value = float(text)
        if not math.isfinite(value):
            self.fail(f"{where} {attr}={text!r}: out of the range of a double; expected a finite "
                      f"number [{unit}]")
        return value

    def vector(self, where: str, attr: str, text: str, unit: str | None = None) -> np.ndarray:
        unit = unit or _UNITS.get(attr, "-")
        parts = [p for p in text.split(" ") if p != ""]   # urdfdom splits on spaces only
        expected = f"expected 3 finite numbers separated by spaces [{unit}]"
        if len(parts) != 3:
            self.fail(f"{where} {attr}={text!r}: {expected}, found {len(parts)}")
        values = []
        for p in parts:
            if not _NUMBER.fullmatch(p):
                self.fail(f"{where} {attr}={text!r}: {expected}; {p!r} is not a number")
            v = float(p)
            if not math.isfinite(v):
                self.fail(f"{where} {attr}={text!r}: {expected}; {p!r} is out of the range of "
                          "a double")
            values.append(v)
        return np.array(values)

    def bounded(self, where: str, attr: str, text: str, magnitude: float, limit: float) -> None:
        if magnitude > limit:
            self.fail(f"{where} {attr}={text!r}: magnitude {magnitude:.3g} above {limit:g} "
                      f"[{_UNITS.get(attr, '-')}]; expected a physical size (pinlin's range)")

    def optional(self, el: ET.Element, where: str, attr: str) -> float | None:
        text = el.get(attr)
        return None if text is None else self.number(where, attr, text)

    def required(self, el: ET.Element, where: str, attr: str) -> float:
        text = el.get(attr)
        if text is None:
            self.fail(f"{where}: attribute '{attr}' is missing; expected a finite number "
                      f"[{_UNITS.get(attr, '-')}]")
        return self.number(where, attr, text)

    # -- structure -------------------------------------------------------------------------------
    def attributes(self, el: ET.Element, where: str) -> None:
        allowed = _ATTRIBUTES.get(el.tag)
        if allowed is None:
            return
        for attr in el.attrib:
            if attr in allowed:
                continue
            # <limit>, <dynamics> and <mimic> carry vendor extensions (Panda's <dynamics D K
            # mu_coulomb>): there only a near-miss of a known name is an error.
            close = difflib.get_close_matches(attr, allowed, n=1)
            if el.tag in _EXTENSIBLE and not close:
                continue
            hint = f"did you mean '{close[0]}'?" if close else f"expected {', '.join(allowed)}"
            self.fail(f"{where}: unknown attribute '{attr}' (urdfdom would ignore it); {hint}")

    def children(self, el: ET.Element, tag: str, where: str, *, required: bool = False
                 ) -> ET.Element | None:
        found = el.findall(tag)
        if len(found) > 1:
            self.fail(f"{where} has {len(found)} <{tag}> elements; expected one (urdfdom would "
                      "silently use the first)")
        if required and not found:
            self.fail(f"{where} has no <{tag}> element")
        if found:
            self.attributes(found[0], f"{where} <{tag}>")
            return found[0]
        return None

    def origin(self, parent: ET.Element, where: str) -> None:
        el = self.children(parent, "origin", where)
        if el is not None:
            for attr in ("xyz", "rpy"):
                if attr in el.attrib:
                    values = self.vector(f"{where} <origin>", attr, el.attrib[attr])
                    self.bounded(f"{where} <origin>", attr, el.attrib[attr],
                                 float(np.abs(values).max()), MAGNITUDE_LIMITS[attr])

    def name(self, el: ET.Element, kind: str, index: int) -> str:
        name = el.get("name")
        if name is None:
            self.fail(f"{kind} #{index + 1} (in file order) has no name attribute")
        if not name.strip():
            self.fail(f"{kind} #{index + 1} (in file order) has an empty name {name!r}")
        return name

    # -- links -----------------------------------------------------------------------------------
    def link(self, link: ET.Element, name: str) -> None:
        where = f"link '{name}'"
        inertial = self.children(link, "inertial", where)
        if inertial is not None:
            self.inertial(inertial, f"{where} <inertial>", name)
        for tag in ("visual", "collision"):
            for k, el in enumerate(link.findall(tag)):
                self.origin(el, f"{where} <{tag}> #{k + 1}")

    def inertial(self, el: ET.Element, where: str, name: str) -> None:
        self.origin(el, where)
        mass_el = self.children(el, "mass", where, required=True)
        mass = self.required(mass_el, f"{where} <mass>", "value")
        if mass < 0.0:
            self.fail(f"link '{name}': mass must be a finite number >= 0 [kg], got "
                      f"{mass_el.get('value')}")
        if 0.0 < mass < MASS_FLOOR:
            self.fail(f"link '{name}': mass {mass_el.get('value')} kg is below "
                      f"{MASS_FLOOR:.3g} kg (eps), where Pinocchio's inertia arithmetic "
                      "shrinks the link's centre-of-mass offset by m / eps; give 0 for a "
                      "massless link or a mass of at least eps")
        inertia_el = self.children(el, "inertia", where, required=True)
        keys = _ATTRIBUTES["inertia"]
        missing = [k for k in keys if k not in inertia_el.attrib]
        if missing:
            self.fail(f"{where} <inertia>: attribute '{missing[0]}' is missing; expected all of "
                      f"{', '.join(keys)} [kg*m^2] (urdfdom would zero the link's inertia)")
        v = {k: self.number(f"{where} <inertia>", k, inertia_el.attrib[k]) for k in keys}
        inertia = np.array([[v["ixx"], v["ixy"], v["ixz"]],
                            [v["ixy"], v["iyy"], v["iyz"]],
                            [v["ixz"], v["iyz"], v["izz"]]])
        if v["ixy"] == v["ixz"] == v["iyz"] == 0.0:   # principal axes (most files): no solver
            eig = np.sort(np.diag(inertia))
        else:
            eig = np.linalg.eigvalsh(inertia)
        # Relative to the link's own inertia (no floor: a millimetre link's moments are
        # ~1e-12 kg*m^2, and an absolute 1e-12 let a negative one through).
        scale = float(np.abs(eig).max())
        if eig[0] < -1e-12 * scale:   # eigvalsh's rounding: ~eps * scale
            self.fail(f"link '{name}': inertia tensor is not positive semi-definite "
                      f"(principal moments {np.array2string(eig, precision=3)} kg*m^2)")
        # Principal moments of a real body satisfy the triangle inequality; 1e-6 of the
        # largest admits moments printed to 7 significant digits (a float32's), a flat body's
        # I3 = I1 + I2 among them.
        if eig[2] > eig[0] + eig[1] + 1e-6 * scale:
            self.fail(f"link '{name}': principal moments {np.array2string(eig, precision=3)} "
                      "kg*m^2 violate the triangle inequality I3 <= I1 + I2 (no physical body "
                      "has them)")

    # -- joints ----------------------------------------------------------------------------------
    def joint(self, joint: ET.Element, name: str, links: set[str]) -> tuple[str, str, str]:
        """Check a joint; returns (type, parent link, child link)."""
        where = f"joint '{name}'"
        jtype = joint.get("type")
        if jtype is None:
            self.fail(f"{where} has no type attribute; expected one of {', '.join(JOINT_NV)}")
        if jtype not in JOINT_NV:
            self.fail(f"{where}: unknown type {jtype!r}; expected one of {', '.join(JOINT_NV)}")
        ends = []
        for tag in ("parent", "child"):
            el = self.children(joint, tag, where, required=True)
            link = el.get("link")
            if link is None or not link.strip():
                self.fail(f"{where} <{tag}> has no link attribute")
            if link not in links:
                self.fail(f"{where}: {tag} link '{link}' is not defined (no <link name="
                          f"\"{link}\">)")
            ends.append(link)
        if ends[0] == ends[1]:
            self.fail(f"{where}: parent and child are the same link '{ends[0]}'")
        self.origin(joint, where)
        self.axis(joint, where, jtype)
        limit = self.children(joint, "limit", where, required=jtype in ("revolute", "prismatic"))
        if limit is not None:
            self.limit(limit, f"{where} <limit>", jtype)
        dynamics = self.children(joint, "dynamics", where)
        if dynamics is not None:
            dwhere = f"{where} <dynamics>"
            if not dynamics.attrib:
                self.fail(f"{dwhere} has neither damping nor friction")
            for attr in ("damping", "friction"):
                value = self.optional(dynamics, dwhere, attr)
                if value is not None and value < 0.0:
                    self.fail(f"{dwhere} {attr}={dynamics.get(attr)!r}: expected a number >= 0 "
                              f"[{_UNITS[attr]}]")
        mimic = self.children(joint, "mimic", where)
        if mimic is not None:
            mwhere = f"{where} <mimic>"
            if not mimic.get("joint", "").strip():
                self.fail(f"{mwhere} has no joint attribute (the joint it follows)")
            for attr in ("multiplier", "offset"):
                self.optional(mimic, mwhere, attr)
        for tag in ("calibration", "safety_controller"):
            self.children(joint, tag, where)
        return jtype, ends[0], ends[1]

    def axis(self, joint: ET.Element, where: str, jtype: str) -> None:
        el = self.children(joint, "axis", where)
        if el is None:
            if jtype == "planar":
                self.fail(f"{where}: a planar joint needs <axis xyz=\"0 0 1\"/>: Pinocchio's "
                          "planar joint moves in the x-y plane of the joint frame, and the URDF "
                          "default axis is (1, 0, 0); orient the plane with the joint's "
                          "<origin rpy>")
            return  # revolute, continuous, prismatic: the URDF default (1, 0, 0)
        text = el.get("xyz")
        if text is None:
            if jtype in ("fixed", "floating"):
                return
            self.fail(f"{where} <axis> has no xyz attribute; expected a direction: 3 numbers, "
                      "e.g. xyz=\"0 0 1\" (urdfdom would give the joint a zero axis)")
        axis = self.vector(f"{where} <axis>", "xyz", text, unit="-, a direction")
        if jtype not in _AXIS_TYPES and jtype != "planar":
            return  # fixed and floating joints have no axis: CAD exporters write 0 0 0 there
        norm = math.hypot(*axis)   # no underflow: 1e-300 has length 1e-300, not 0
        if norm < MIN_AXIS_NORM:
            self.fail(f"{where} <axis> xyz={text!r}: zero axis (length {norm:.3g} < "
                      f"{MIN_AXIS_NORM:g}); a {jtype} joint needs a direction, e.g. "
                      "xyz=\"0 0 1\" (the joint would move nothing)")
        if jtype == "planar" and not np.allclose(axis / norm, (0.0, 0.0, 1.0), rtol=0.0,
                                                 atol=1e-9):
            self.fail(f"{where} <axis> xyz={text!r}: Pinocchio's planar joint moves in the x-y "
                      "plane of the joint frame and ignores the axis; write xyz=\"0 0 1\" and "
                      "orient the plane with the joint's <origin rpy>")

    def limit(self, el: ET.Element, where: str, jtype: str) -> None:
        for attr in ("effort", "velocity"):
            value = self.required(el, where, attr)
            if value < 0.0:
                self.fail(f"{where} {attr}={el.get(attr)!r}: expected a number >= 0 "
                          f"[{_UNITS[attr]}] (a magnitude)")
        lower = self.optional(el, where, "lower")
        upper = self.optional(el, where, "upper")
        if jtype in ("revolute", "prismatic"):
            lo = 0.0 if lower is None else lower
            hi = 0.0 if upper is None else upper
            if lo > hi:
                self.fail(f"{where}: lower={lo:g} > upper={hi:g} [{_UNITS['lower']}]; expected "
                          "lower <= upper")

    # -- the tree --------------------------------------------------------------------------------
    def tree(self, link_names: list[str], edges: dict[str, tuple[str, str]]) -> None:
        """One root, every link reachable from it, no link with two parents."""
        parent_of: dict[str, str] = {}
        for jname, (_, child) in edges.items():
            if child in parent_of:
                self.fail(f"link '{child}' is the child of two joints, '{parent_of[child]}' and "
                          f"'{jname}'; a URDF is a tree (close loops in the scene's [[loops]])")
            parent_of[child] = jname
        roots = [n for n in link_names if n not in parent_of]
        if len(roots) > 1:
            shown = ", ".join(f"'{r}'" for r in roots[:5])
            more = f" ({len(roots)} in all)" if len(roots) > 5 else ""
            self.fail(f"links {shown}{more} are all roots (no joint has them as child); a URDF "
                      "is one tree with a single root link")
        children: dict[str, list[str]] = {}
        for parent, child in edges.values():
            children.setdefault(parent, []).append(child)
        reached: set[str] = set()
        stack = list(roots)
        while stack:
            link = stack.pop()
            reached.add(link)
            stack.extend(children.get(link, ()))
        unreached = [n for n in link_names if n not in reached]
        if unreached:
            # Every unreached link has a parent: following parents from one must come back.
            link, seen = unreached[0], []
            while link not in seen:
                seen.append(link)
                link = edges[parent_of[link]][0]
            cycle = seen[seen.index(link):]
            loop = " -> ".join(f"'{n}'" for n in [*cycle, link])
            head = "no root link (every link is some joint's child)" if not roots else \
                f"links not connected to the root '{roots[0]}'"
            self.fail(f"{head}: the joints form a cycle, each link's parent being the next: "
                      f"{loop}; a URDF is a tree (close loops in the scene's [[loops]])")

    def mimics(self, joints: list[ET.Element], types: dict[str, str]) -> None:
        """Each <mimic> follows another existing joint, and no chain of them loops. (A mimic
        on a fixed joint is allowed: Talos has them; Pinocchio ignores them.)"""
        targets: dict[str, str] = {}
        for joint in joints:
            mimic = joint.find("mimic")
            if mimic is None:
                continue
            name = joint.get("name", "")
            where = f"joint '{name}' <mimic>"
            target = mimic.get("joint", "")
            if target == name:
                self.fail(f"{where} joint='{target}': a joint cannot mimic itself")
            if target not in types:
                self.fail(f"{where} joint='{target}': no joint of that name")
            targets[name] = target
        for start in targets:
            chain, joint = [start], targets[start]
            while joint in targets:
                if joint in chain:
                    loop = " -> ".join(f"'{n}'" for n in [*chain[chain.index(joint):], joint])
                    self.fail(f"the <mimic> tags form a cycle {loop}; each chain of mimic joints "
                              "must end at a joint that mimics nothing")
                chain.append(joint)
                joint = targets[joint]


# Vector attributes urdfdom splits on spaces only. An XML parser turns a literal tab or line
# break inside an attribute value into a space (expat does, so ElementTree never sees them),
# tinyxml2 does not: urdfdom then fails on that vector. Found in the raw text.
_VECTOR_ATTRIBUTE_WITH_BREAK = re.compile(
    rb"\b(?:xyz|rpy|size|scale|rgba)\s*=\s*"
    rb"""(?:"[^"\t\r\n]*[\t\r\n][^"]*"|'[^'\t\r\n]*[\t\r\n][^']*')""")


def _parse_xml(path: Path) -> ET.Element:
    if not path.is_file():
        raise UrdfError(path, "file not found")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise UrdfError(path, f"cannot read: {exc.strerror or exc}") from None
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise UrdfError(path, f"malformed XML: {exc}") from None
    if root.tag != "robot":
        raise UrdfError(path, f"root element must be <robot>, got <{root.tag}>")
    match = _VECTOR_ATTRIBUTE_WITH_BREAK.search(data)
    if match is not None:
        line = data.count(b"\n", 0, match.start()) + 1
        text = match.group(0).decode(errors="replace")
        raise UrdfError(path, f"line {line}: {text!r}: a tab or line break separates the "
                              "numbers; urdfdom accepts only spaces between them")
    return root


def _check_root(path: Path, root: ET.Element) -> UrdfSummary:
    c = _Checker(path)
    robot_name = root.get("name")
    if robot_name is None or not robot_name.strip():
        c.fail("<robot> has no name attribute")
    links = root.findall("link")       # urdfdom reads only the direct children of <robot>
    if not links:
        c.fail("no <link> elements; a URDF needs at least one link")
    link_names: list[str] = []
    for k, link in enumerate(links):
        name = c.name(link, "link", k)
        if name in link_names:
            c.fail(f"link '{name}' is defined twice; link names must be unique")
        link_names.append(name)
        c.link(link, name)
    link_set = set(link_names)
    joints = root.findall("joint")
    joint_types: dict[str, str] = {}
    edges: dict[str, tuple[str, str]] = {}
    for k, joint in enumerate(joints):
        name = c.name(joint, "joint", k)
        if name in joint_types:
            c.fail(f"joint '{name}' is defined twice; joint names must be unique")
        jtype, parent, child = c.joint(joint, name, link_set)
        joint_types[name] = jtype
        edges[name] = (parent, child)
    c.tree(link_names, edges)
    c.mimics(joints, joint_types)
    nv = sum(JOINT_NV[t] for t in joint_types.values())
    njoints = 1 + sum(1 for t in joint_types.values() if t != "fixed")
    return UrdfSummary(robot_name, len(links), joint_types, nv, njoints)


def check_urdf(path: str | Path) -> UrdfSummary:
    """Check a URDF file with the standard library, without building a model.

    Returns:
        What a valid file describes (sizes used for the memory estimate).

    Raises:
        UrdfError: the file is missing, is not well-formed XML, is not a URDF, or has a fault
            that urdfdom would pass over silently or with a complaint on stderr (see the module
            docstring); the message names the link or joint, the element and what was expected.
    """
    path = Path(path)
    return _check_root(path, _parse_xml(path))
