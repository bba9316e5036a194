"""A scene as a MuJoCo model with only the effects the scene calls for, and MuJoCo's linearization
of it expressed in pinlin's coordinates.

The URDF is imported through ``MjSpec`` after its ``<visual>``, ``<collision>``, ``<mimic>``,
``<dynamics>``, ``<transmission>`` and ``<gazebo>`` elements are removed (mesh paths, contacts,
friction loss, URDF damping and mimic equalities are not part of a scene unless it says so).
Joint limits and actuator force clamps are switched off, contacts disabled; gravity, armature,
viscous damping and springs are set from the pinlin system; a floating base gets a free joint.
Where MuJoCo refuses a link's inertia on its own (placeholder links whose fixed children carry
the mass), that link is merged into the body Pinocchio simulates (:mod:`pinlin.mjcf_merge`);
MuJoCo's own import is kept wherever it compiles. Visual-only geoms without mass or contacts
(:mod:`pinlin.mjcf_visual`) make the exported MJCF visible in MuJoCo's viewer.

Coordinates. MuJoCo's free joint has qpos = [p_world, quat (w, x, y, z)] and
qvel = [v_world, w_body]; Pinocchio's free flyer has q = [p, quat (x, y, z, w)] and
v = [v_body, w_body] with the position tangent also in the body frame. At the operating point
both tangents are related by T = blockdiag(R0, I) on the free joint (joints map by name), and
a_mj = T(q) a_pin adds (dT/dq) a0 = -R0 [a0_lin]x on the rotation columns when a0 != 0.

MuJoCo's linearization of the exported model (its Euler step's Jacobians, the continuous A
recovered from them) is in :mod:`pinlin.mjcf_linearization`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .exceptions import ArgumentError, PinlinError
from .mjcf_merge import Merge, UnrepresentableBodyError, import_urdf
from .mjcf_visual import add_visual_geoms

_STRIP = ("visual", "collision", "mimic", "dynamics", "transmission", "gazebo")


class MujocoError(PinlinError):
    """MuJoCo cannot represent or compile the scene; the message gives MuJoCo's reason."""


@dataclass
class MujocoScene:
    """A compiled MuJoCo model of a pinlin system and the maps between their coordinates.

    Attributes:
        model, data: MuJoCo model and data.
        spec: The MjSpec it was compiled from (``spec.to_xml()`` writes MJCF).
        dof: MuJoCo dof index of each pinlin velocity coordinate.
        free: Whether the base is a free joint (pinlin coordinates 0-5).
        dt: Time step [s].
        warnings: What MuJoCo warned while importing and compiling (for example joint limits
            it ignores; limits are switched off anyway).
        merged: URDF links whose inertial MuJoCo refused on its own, merged into the body
            Pinocchio simulates (:mod:`pinlin.mjcf_merge`); empty when MuJoCo's import of the
            file compiles as it is.
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    spec: mujoco.MjSpec
    dof: np.ndarray
    free: bool
    dt: float
    warnings: tuple[str, ...] = field(default_factory=tuple)
    merged: tuple[Merge, ...] = field(default_factory=tuple)


@contextmanager
def _captured_warnings() -> Iterator[list[str]]:
    """Collect MuJoCo's warnings in a list instead of its default handler, which appends them
    to MUJOCO_LOG.TXT in the current directory; the previous handler is restored after."""
    previous = mujoco.get_mju_user_warning()
    caught: list[str] = []
    mujoco.set_mju_user_warning(caught.append)
    try:
        yield caught
    finally:
        mujoco.set_mju_user_warning(previous)


def strip_urdf(text: str) -> str:
    """URDF text without the elements a scene does not call for, with MuJoCo's import options
    (keep static bodies, no inertia from geometry, no balancing)."""
    for tag in _STRIP:
        text = re.sub(rf"<{tag}\b[^>]*/>", "", text, flags=re.S)
        text = re.sub(rf"<{tag}\b.*?</{tag}>", "", text, flags=re.S)
    options = ('<mujoco><compiler fusestatic="false" discardvisual="true" '
               'balanceinertia="false" inertiafromgeom="false" strippath="true"/></mujoco>')
    return re.sub(r"(<robot\b[^>]*>)", r"\1" + options, text, count=1)


#: Soft-constraint settings of loop and mimic equalities: impedance d as close to 1 as MuJoCo
#: allows (0.9999) and a time constant of LOOP_TIMECONST_STEPS time steps (refsafe off).
#: MuJoCo leaks a fraction 1 - d of the unconstrained acceleration through its constraints,
#: a relative model error of order 1e-4 that no time step removes; validation therefore also
#: builds the model at d = 0.999 and extrapolates the eigenvalues to d = 1 (linear in 1 - d).
LOOP_IMPEDANCE = 0.9999
LOOP_TIMECONST_STEPS = 2.0


def build(system, dt: float = 1e-3, impedance: float = LOOP_IMPEDANCE, *,
          visual: bool = True) -> MujocoScene:
    """The MuJoCo model of ``system`` with exactly the scene's effects.

    Loops become ``connect`` (point) or ``weld`` equalities between sites at the two frames,
    mimic couplings ``joint`` equalities (q_m = offset + multiplier q_j), both stiff
    (solref time constant 2 dt, solimp ``impedance``). Steady rotation cannot be expressed.
    MuJoCo's warnings while importing and compiling are kept in ``warnings``. Links whose
    inertia MuJoCo refuses on its own are merged as Pinocchio merges them (``merged``).

    Args:
        dt: Time step [s], finite and at least :data:`MIN_TIME_STEP`.
        impedance: Solver impedance of the equalities, strictly between 0 and 1.
        visual: Add visual-only geoms (:func:`pinlin.mjcf_visual.add_visual_geoms`: no mass,
            no contacts) so that MuJoCo's viewer shows the mechanism.

    Raises:
        ArgumentError: ``dt`` or ``impedance`` out of range.
        MujocoError: MuJoCo refuses the model (its reason is quoted), or the scene has effects
            this exporter cannot express.
    """
    dt = check_time_step(dt, "dt")
    impedance = _number(impedance, "impedance")
    if not 0.0 < impedance < 1.0:
        raise ArgumentError("impedance", f"must be strictly between 0 and 1, got {impedance!r}")
    with _captured_warnings() as caught:
        ms = _build(system, dt, impedance, bool(visual))
    ms.warnings = tuple(caught)
    return ms


def _number(value: object, argument: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ArgumentError(argument, f"expected a number, got {type(value).__name__}")
    try:
        return float(value)
    except OverflowError:
        return float("inf")  # refused by the range checks


#: The shortest time step [s] an exported scene may have: a nanosecond, 1e9 MuJoCo steps per
#: simulated second (pinlin's own validation steps 1e-4 s at the shortest).
MIN_TIME_STEP = 1e-9


def check_time_step(dt: object, argument: str = "dt") -> float:
    """``dt`` [s] as a float, refused unless finite and at least :data:`MIN_TIME_STEP`.

    Raises:
        ArgumentError: naming ``argument`` (``dt`` from Python, ``--dt`` from the CLI).
    """
    value = _number(dt, argument)
    if not (np.isfinite(value) and value >= MIN_TIME_STEP):
        raise ArgumentError(argument, f"expected a finite time step of at least "
                                      f"{MIN_TIME_STEP:g} s (1e9 MuJoCo steps per simulated "
                                      f"second), got {dt!r}")
    return value


def check_resolved(model, dt: float, argument: str = "dt") -> None:
    """Refuse a time step [s] that MuJoCo's semi-implicit Euler step cannot integrate stably
    for the scene's fastest mode: an undamped oscillation of frequency w needs dt w < 2 (the
    step's amplification matrix has |eigenvalues| = 1 only then), so dt |lambda| >= 2 for the
    largest non-rigid |lambda| of the linear ``model`` (a :class:`pinlin.LinearModel` of the
    scene) grows without bound.

    Raises:
        ArgumentError: naming ``argument``, the fastest |lambda| and the largest stable dt.
    """
    if model.n_states == 0:
        return
    fastest = float(np.abs(np.linalg.eigvals(model.A)).max())
    if dt * fastest >= 2.0:
        raise ArgumentError(argument, f"a time step of {dt:g} s cannot follow the fastest mode "
                                      f"of '{model.name}' (|lambda| = {fastest:.4g} 1/s): "
                                      f"MuJoCo's Euler step is unstable from dt |lambda| = 2; "
                                      f"use dt < {2.0 / fastest:.3g} s")


def _build(system, dt: float, impedance: float, visual: bool) -> MujocoScene:
    scene = system.scene
    if system.rotation is not None:
        raise MujocoError(f"scene '{scene.name}': steady rotation has no MuJoCo counterpart "
                          "(MuJoCo integrates in an inertial frame)")
    planar = [name for name, j in system.joints.items() if j.kind == "JointModelPlanar"]
    if planar:
        raise MujocoError(f"scene '{scene.name}': joint '{planar[0]}' is planar, which MuJoCo "
                          "imports as two slides and a hinge (coordinates other than "
                          "Pinocchio's SE(2) configuration): it has no MuJoCo counterpart here")
    text = strip_urdf(system.urdf_path.read_text(encoding="utf-8"))
    free = system.base_joint is not None
    try:
        mujoco.MjSpec.from_string(text)
    except Exception as exc:  # MuJoCo raises ValueError with its reason
        raise MujocoError(f"MuJoCo cannot import {system.urdf_path}: {exc}") from None
    try:
        spec, merged = import_urdf(text, system.base_joint if free else None)
    except UnrepresentableBodyError as exc:
        raise MujocoError(f"MuJoCo refuses '{scene.name}': {exc}") from None
    except Exception as exc:  # MuJoCo's reason for refusing anything else
        raise MujocoError(f"MuJoCo refuses '{scene.name}': {exc}") from None
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    spec.option.timestep = dt
    g = scene.effects.gravity
    spec.option.gravity = np.zeros(3) if g is None else np.asarray(g, float)
    flags = (mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_LIMIT
             | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)
    if system.constraints:
        flags |= mujoco.mjtDisableBit.mjDSBL_REFSAFE
        _add_equalities(spec, system, dt, impedance)
        # Solve the constraints to convergence: solver noise would swamp finite differences.
        spec.option.tolerance = 0.0
        spec.option.ls_tolerance = 0.0
        spec.option.iterations = 500
    else:
        flags |= mujoco.mjtDisableBit.mjDSBL_EQUALITY
    spec.option.disableflags |= flags
    known = set(system.joints)
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_FREE:
            continue
        if joint.name not in known:
            raise MujocoError(f"scene '{scene.name}': MuJoCo joint '{joint.name}' is locked in "
                              "the Pinocchio model (a reduced model); its lock values are not "
                              "known from the URDF, so the model has no MuJoCo counterpart")
        j = system.joints[joint.name]
        joint.limited = mujoco.mjtLimited.mjLIMITED_FALSE
        joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        joint.armature = float(system.model.armature[j.idx_v])
        # damping and stiffness are 3-vectors in MuJoCo 4 (linear term first).
        joint.damping = np.array([system.damping[j.idx_v], 0.0, 0.0])
        joint.frictionloss = 0.0
        joint.stiffness = np.array([system.stiffness[j.idx_v], 0.0, 0.0])
        if j.continuous:
            rest = np.arctan2(system.q_rest[j.idx_q + 1], system.q_rest[j.idx_q])
        else:
            rest = system.q_rest[j.idx_q]
        joint.springref = float(rest)
    if visual:
        add_visual_geoms(spec)
    try:
        model = spec.compile()
    except Exception as exc:
        raise MujocoError(f"MuJoCo refuses '{scene.name}': {exc}") from None
    dof = np.zeros(system.nv, dtype=int)
    for name, j in system.joints.items():
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise MujocoError(f"scene '{scene.name}': joint '{name}' is missing in MuJoCo")
        dof[j.idx_v:j.idx_v + j.nv] = model.jnt_dofadr[jid] + np.arange(j.nv)
    if model.nv != system.nv:
        raise MujocoError(f"scene '{scene.name}': MuJoCo has {model.nv} dofs, Pinocchio "
                          f"{system.nv}")
    return MujocoScene(model, mujoco.MjData(model), spec, dof, free, dt, merged=merged)


def _add_equalities(spec: mujoco.MjSpec, system, dt: float, impedance: float) -> None:
    solref = np.array([LOOP_TIMECONST_STEPS * dt, 1.0])
    solimp = np.array([impedance, impedance, 0.001, 0.5, 2.0])
    bodies = {b.name for b in spec.bodies}
    for i, loop in enumerate(system.scene.loops):
        sites = []
        for k, frame in enumerate((loop.frame1, loop.frame2)):
            name = f"{loop.name}_site{k + 1}"
            body, pos, quat = _frame_on_body(system, frame, bodies, f"loops[{i}].frame{k + 1}")
            spec.body(body).add_site(name=name, pos=pos, quat=quat)
            sites.append(name)
        eq = spec.add_equality()
        eq.type = (mujoco.mjtEq.mjEQ_CONNECT if loop.type == "point" else mujoco.mjtEq.mjEQ_WELD)
        eq.objtype = mujoco.mjtObj.mjOBJ_SITE
        eq.name, eq.name1, eq.name2 = loop.name, sites[0], sites[1]
        eq.solref, eq.solimp = solref, solimp
        if loop.type == "weld":
            eq.data[:] = 0.0
            eq.data[6] = 1.0     # relative orientation (w, x, y, z): identity
            eq.data[10] = 1.0    # torque scale
    _add_contacts(spec, system, bodies, solref, solimp)
    from .mimic import read_mimic_tags

    if system.scene.effects.mimic:
        for c in read_mimic_tags(system.urdf_path):
            eq = spec.add_equality()
            eq.type = mujoco.mjtEq.mjEQ_JOINT
            eq.name1, eq.name2 = c.mimic, c.joint
            eq.data[:5] = [c.offset, c.multiplier, 0.0, 0.0, 0.0]
            eq.solref, eq.solimp = solref, solimp


def _add_contacts(spec: mujoco.MjSpec, system, bodies: set[str], solref: np.ndarray,
                  solimp: np.ndarray) -> None:
    """Each scene contact as an equality with the world, not a MuJoCo contact: a site
    ``<name>_site1`` at the contact frame on its body (:func:`_frame_on_body`),
    a site ``<name>_site2`` on the worldbody at the anchor placement
    (:attr:`pinlin.constraints.AnchoredContact.placement`, quaternion in MuJoCo's (w, x, y, z)
    order), joined by ``connect`` (point: the two origins coincide) or ``weld`` (the two
    frames coincide), with the loops' stiff ``solref`` / ``solimp``."""
    for i, contact in enumerate(system.constraints.contacts):
        site1, site2 = f"{contact.name}_site1", f"{contact.name}_site2"
        body, pos, quat = _frame_on_body(system, contact.frame, bodies, f"contacts[{i}].frame")
        spec.body(body).add_site(name=site1, pos=pos, quat=quat)
        spec.worldbody.add_site(name=site2, pos=np.array(contact.position),
                                quat=_wxyz(contact.rotation))
        eq = spec.add_equality()
        eq.type = (mujoco.mjtEq.mjEQ_CONNECT if contact.type == "point"
                   else mujoco.mjtEq.mjEQ_WELD)
        eq.objtype = mujoco.mjtObj.mjOBJ_SITE
        eq.name, eq.name1, eq.name2 = contact.name, site1, site2
        eq.solref, eq.solimp = solref, solimp
        if contact.type == "weld":
            eq.data[:] = 0.0
            eq.data[6] = 1.0     # relative orientation (w, x, y, z): identity
            eq.data[10] = 1.0    # torque scale


#: How the MJCF pinlin writes begins (an XML comment before <mujoco>): an existing .xml
#: is replaced only when it begins so (:data:`pinlin.files.SIGNATURES`).
MJCF_MARKER = "<!-- Written by pinlin export-mjcf"


def _wxyz(rotation: np.ndarray) -> np.ndarray:
    """A rotation matrix as MuJoCo's quaternion (w, x, y, z)."""
    import pinocchio as pin

    x, y, z, w = pin.Quaternion(np.array(rotation)).coeffs()
    return np.array([w, x, y, z])


def _frame_on_body(system, frame: str, bodies: set[str], fld: str
                   ) -> tuple[str, np.ndarray, np.ndarray]:
    """(MuJoCo body, site position, site quaternion (w, x, y, z)) of a Pinocchio frame: a URDF
    link is a MuJoCo body of its own name (fusestatic off; its frame is the link frame); any
    other frame (a joint's, a fixed joint's) sits on a link moved by the same joint, at
    their relative placement.

    Raises:
        MujocoError: no MuJoCo body moves with the frame (naming ``fld``).
    """
    import pinocchio as pin

    kin = system.kin_model
    if frame in bodies:
        fid = kin.getFrameId(frame, pin.FrameType.BODY)
        if fid < len(kin.frames):
            return frame, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
    try:
        fid = system.frame_id(frame, fld)   # a link and a joint may share a name
    except PinlinError:
        raise MujocoError(f"{fld}: '{frame}' is not a frame of the model") from None
    target = kin.frames[fid]
    for f in kin.frames:
        if (f.type == pin.FrameType.BODY and f.parentJoint == target.parentJoint
                and f.name in bodies):
            rel = f.placement.inverse() * target.placement
            return f.name, rel.translation.copy(), _wxyz(rel.rotation)
    raise MujocoError(f"{fld}: no MuJoCo body moves with frame '{frame}' (no URDF link on its "
                      "joint survived MuJoCo's import)")


def set_state(ms: MujocoScene, system, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> None:
    """Write pinlin's (q, v) and generalized force tau into MuJoCo's data."""
    m, d = ms.model, ms.data
    for name, j in system.joints.items():
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        adr = m.jnt_qposadr[jid]
        qj = q[j.idx_q:j.idx_q + j.nq]
        if m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_FREE:
            d.qpos[adr:adr + 3] = qj[:3]
            d.qpos[adr + 3:adr + 7] = [qj[6], qj[3], qj[4], qj[5]]
        elif j.continuous:
            d.qpos[adr] = np.arctan2(qj[1], qj[0])
            if m.jnt_stiffness[jid]:   # on the branch of the spring's reference (MuJoCo's hinge
                # spring -k (qpos - springref) does not wrap; pinlin's acts on the wrapped
                # difference)
                ref = float(m.qpos_spring[adr])
                gap = d.qpos[adr] - ref
                d.qpos[adr] = ref + np.arctan2(np.sin(gap), np.cos(gap))
        else:
            d.qpos[adr] = qj[0]
    rot = _base_rotation(system, q) if ms.free else None
    vm = v.copy()
    if rot is not None:
        vm[:3] = rot @ v[:3]
    d.qvel[ms.dof] = vm
    d.qfrc_applied[:] = 0.0
    d.qfrc_applied[ms.dof] = tau if rot is None else np.concatenate([rot @ tau[:3], tau[3:]])
    d.ctrl[:] = 0.0
    mujoco.mj_forward(m, d)


def _base_rotation(system, q: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    j = system.joints[system.base_joint]
    quat = q[j.idx_q + 3:j.idx_q + 7]
    return pin.Quaternion(quat[3], quat[0], quat[1], quat[2]).matrix()


# MuJoCo's linearization lives in pinlin.mjcf_linearization and the MJCF text in
# pinlin.mjcf_xml, which build on set_state above.
# Its names stay importable from here, loaded on first access (PEP 562): a plain import at the
# top would be circular.
_LINEARIZATION = frozenset({"_skew", "continuous_state_matrix", "euler_step_jacobians",
                            "recover_continuous", "to_pinlin_coordinates", "transition_matrix"})
#: The MJCF text (:mod:`pinlin.mjcf_xml`), likewise.
_XML = frozenset({"to_xml"})


def __getattr__(name: str) -> object:
    if name in _LINEARIZATION:
        from . import mjcf_linearization

        return getattr(mjcf_linearization, name)
    if name in _XML:
        from . import mjcf_xml

        return getattr(mjcf_xml, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
