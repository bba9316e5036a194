"""The MJCF text of a scene's MuJoCo model (``pinlin export-mjcf``): MuJoCo's own writer, with
the numbers it rounds to 6 digits written again at full precision, and optionally a keyframe
at pinlin's operating point with the inputs that hold it as motors."""

from __future__ import annotations

import re
from xml.sax.saxutils import escape as xml_escape

import mujoco
import numpy as np

from .mjcf import MJCF_MARKER, MujocoError, MujocoScene, set_state


def to_xml(ms: MujocoScene, system, q: np.ndarray | None = None, v: np.ndarray | None = None,
           key: str = "operating_point", u: np.ndarray | None = None) -> str:
    """The MJCF text of ``ms``; with ``q`` (and ``v``), a keyframe ``key`` holding pinlin's
    (q, v) in MuJoCo's coordinates: ``mj_resetDataKeyframe`` starts MuJoCo there (``ms``'s
    own spec is left as it was). With ``u`` too (the scene's inputs at that point), each input
    on a 1-DoF joint becomes a motor actuator named as the input (``u:<joint>``, gear 1, no
    control limit) and the keyframe's ``ctrl`` holds u: reset to the key, MuJoCo applies the
    inputs that hold the posture. MuJoCo's writer keeps 6 digits, which opens a held foot by
    ~1e-6 m: the bodies' placements and inertias, pinlin's sites, the time step and gravity,
    the joints' stiffness, spring reference, damping and armature, and the key are rewritten
    at full precision. The text begins with :data:`MJCF_MARKER`.

    Raises:
        MujocoError: MuJoCo cannot write the model.
    """
    spec = ms.spec
    if q is not None:
        v = np.zeros(system.nv) if v is None else v
        set_state(ms, system, q, v, np.zeros(system.nv))
        qpos, qvel = ms.data.qpos.copy(), ms.data.qvel.copy()
        spec = ms.spec.copy()    # the key goes into the file, not into ms's own spec
        ctrl = _motors(spec, system, u) if u is not None and u.size else None
        spec.add_key(name=key, qpos=qpos, qvel=qvel, **({} if ctrl is None else {"ctrl": ctrl}))
    try:
        xml = spec.to_xml()
    except Exception as exc:  # noqa: BLE001  MuJoCo raises ValueError or RuntimeError
        raise MujocoError(f"MuJoCo cannot write MJCF for '{system.scene.name}': {exc}") from None
    m = ms.model
    for i in range(1, m.nbody):  # placements and inertias as compiled, at full precision
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i)
        head = f'<body name="{_xml_attribute(name)}"'
        xml = _exact_attributes(xml, head, {"pos": m.body_pos[i], "quat": m.body_quat[i]})
        start = xml.find(head)
        inertial = xml.find("<inertial", start)
        if start >= 0 and 0 <= inertial < min(_next(xml, "<body", start + 1),
                                              _next(xml, "</body>", start)):
            xml = _exact_attributes(xml, "<inertial", {
                "pos": m.body_ipos[i], "quat": m.body_iquat[i], "mass": m.body_mass[i:i + 1],
                "diaginertia": m.body_inertia[i]}, inertial)
    xml = _exact_attributes(xml, "<option", {"timestep": np.array([m.opt.timestep]),
                                             "gravity": m.opt.gravity})
    for i in range(m.njnt):      # the scene's effects: springs, damping, armature
        if int(m.jnt_type[i]) not in (int(mujoco.mjtJoint.mjJNT_HINGE),
                                      int(mujoco.mjtJoint.mjJNT_SLIDE)):
            continue
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, i)
        dof, adr = m.jnt_dofadr[i], m.jnt_qposadr[i]
        xml = _exact_attributes(xml, f'<joint name="{_xml_attribute(name)}"', {
            "stiffness": m.jnt_stiffness[i:i + 1], "springref": m.qpos_spring[adr:adr + 1],
            "damping": m.dof_damping[dof:dof + 1], "armature": m.dof_armature[dof:dof + 1]})
    for i in range(m.nsite):     # the sites pinlin placed: loop and contact anchors
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, i)
        xml = _exact_attributes(xml, f'<site name="{_xml_attribute(name)}"',
                                {"pos": m.site_pos[i], "quat": m.site_quat[i]})
    if q is not None:
        xml = _exact_attributes(xml, f'<key name="{_xml_attribute(key)}"', {
            "qpos": qpos, "qvel": qvel, **({} if ctrl is None else {"ctrl": ctrl})})
    name = system.scene.name.replace("--", "- -")    # "--" may not appear in a comment
    return f"{MJCF_MARKER} from scene '{name}' -->\n" + xml


def _motors(spec, system, u: np.ndarray) -> np.ndarray | None:
    """Add a motor actuator (gear 1, no limits) per input of ``system`` on ``spec`` and return
    the controls u in their order; None (nothing added) when an input drives a coordinate of
    a multi-DoF joint, which a joint motor cannot."""
    joint_of = {}
    for name, j in system.joints.items():
        if j.nv == 1:
            joint_of[j.idx_v] = name
    columns = [int(c) for c in system.actuated]
    if any(c not in joint_of for c in columns):
        return None
    for c, input_name in zip(columns, system.input_names, strict=True):
        act = spec.add_actuator()
        act.name = input_name
        act.target = joint_of[c]
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_motor()
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
    return np.asarray(u, dtype=float)


def _next(xml: str, text: str, start: int) -> int:
    """Index of ``text`` in ``xml`` from ``start``, or len(xml)."""
    found = xml.find(text, start)
    return len(xml) if found < 0 else found


def _xml_attribute(name: str) -> str:
    """``name`` as MuJoCo's writer (tinyxml2) escapes it in an attribute value, so that the
    element it names is found in the written file (a joint 'j&1' is written 'j&amp;1')."""
    return xml_escape(name, {'"': "&quot;", "'": "&apos;"})


def _exact_attributes(xml: str, head: str, values: dict[str, np.ndarray], at: int = 0) -> str:
    """``xml`` with the listed attributes of the first element starting with ``head`` (from
    index ``at``) written at full precision (repr of each float64); attributes the element
    does not carry stay absent (MuJoCo left them at their defaults)."""
    start = xml.find(head, at)
    if start < 0:
        return xml
    end = xml.index(">", start)

    def full(match: re.Match) -> str:
        written = match.group(2).split()     # as many numbers as MuJoCo wrote (a 3-vector
        exact = values[match.group(1)]       # whose trailing zeros it left out: the first)
        numbers = " ".join(repr(float(x)) for x in exact[:max(len(written), 1)])
        return f'{match.group(1)}="{numbers}"'

    keys = "|".join(values)
    element = re.sub(rf'\b({keys})="([^"]*)"', full, xml[start:end])
    return xml[:start] + element + xml[end:]
