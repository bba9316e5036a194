"""Holonomic constraints Phi(q) = 0: loop closures, contacts with the world and URDF mimic
couplings.

Rows, in the world frame (the rotating frame when the scene spins):

- ``point`` loop: Phi = p1 - p2, the frame origins [m] (3 rows);
- ``weld`` loop: Phi = [p1 - p2; log3(R1 R2^T)] [m, rad] (6 rows);
- ``point`` contact: Phi = p - p_a, the frame origin against its anchor [m] (3 rows);
- ``weld`` contact: Phi = [p - p_a; log3(R R_a^T)] [m, rad] (6 rows);
- mimic coupling: Phi = q_mimic - multiplier * q_joint - offset [rad or m] (1 row).

A contact is a loop whose second frame is the world at the anchor (p_a, R_a): the contact
frame's world placement at the anchoring configuration, by default the scene's posture
(``operating_point.q`` on the reference posture, before assembly; :meth:`System.anchored_at`
anchors elsewhere). Its rows are the loop rows with the second frame's velocity, Jacobian and
Jacobian variation zero. :attr:`ConstraintSet.contacts` lists each contact's frame, anchor and
rows (the hook an exporter needs to hold the same frames in another engine).

Everything is in the tangent space: ``jacobian(q)`` is dPhi(q (+) dq)/d(dq) (m x nv) and
``hessian(q, lam)`` is the derivative of the constraint force Phi_q(q (+) dq)^T lam at dq = 0,
exact (the geometric stiffness). Pinocchio's Jacobian time variation at v = e_j is
d(Phi_q)/d(dq_j) for the point rows; the weld rotation rows, Jlog3(E) E^T (J1 - E J2) with
E = R1 R2^T, add -1/2 d_j x d_k - d_j x w2_k at an assembled configuration (E = I), with w1, w2
the frames' world angular-velocity Jacobians and d = w1 - w2 (derivatives of Jlog3(E) E^T =
I - 1/2 [log E] and of E). For joints whose tangent coordinates commute (revolute, prismatic,
continuous) this derivative is symmetric: it is lam^T Phi_qq, and rounding is removed by taking
its symmetric part. On Lie-group joints (a free flyer, a spherical or planar joint) the
derivatives along two of the joint's own coordinates do not commute,
X_j X_k Phi - X_k X_j Phi = Phi_q [e_j, e_k], and the exact, non-symmetric block is kept: a
standing robot's base carries the contact forces' wrench, and Pinocchio's RNEA derivative of
gravity has the matching antisymmetric part (they cancel in the sum, as the base is not
actuated). The constraint force the closure applies is Phi_q^T lam, with lam the force [N] (and
torque [N*m], about the frame's origin) on frame1's body, expressed in the world frame; for a
contact the force the world applies to the robot.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from . import constraint_derivatives
from .coordinates import slides_only
from .exceptions import ModelError, SceneError
from .loop_kernels import frame_jacobian
from .mimic import MimicCoupling

#: Prefix of a contact's constraint rows: ``contact:<name>.x`` ... ``.rz``.
CONTACT_PREFIX = "contact:"
_AXES = {"point": ("x", "y", "z"), "weld": ("x", "y", "z", "rx", "ry", "rz")}


@dataclass(frozen=True, eq=False)
class AnchoredContact:
    """A scene contact as the constraint set holds it.

    Attributes:
        name: The contact's name.
        type: ``"point"`` (3 rows) or ``"weld"`` (6 rows).
        frame: Frame (link) name.
        frame_id: Its index in the system's kinematic model (``System.kin_model``).
        rows: Its constraint rows in :attr:`ConstraintSet.row_names`.
        position: Anchor position in the world [m] (read-only, 3).
        rotation: Anchor orientation in the world (read-only, 3 x 3): the frame's at the
            anchoring configuration.
    """

    name: str
    type: str
    frame: str
    frame_id: int
    rows: range
    position: np.ndarray
    rotation: np.ndarray

    @property
    def placement(self) -> pin.SE3:
        """The anchor as a fresh ``pin.SE3`` (world placement the frame is held at)."""
        return pin.SE3(self.rotation.copy(), self.position.copy())


class _Closure(NamedTuple):
    """One loop or contact: frame ids (f2 None: the world at ``anchor``) and first row."""

    kind: str
    f1: int
    f2: int | None
    row: int
    anchor: pin.SE3 | None


class ConstraintSet:
    """The scene's loops, contacts and mimic couplings, evaluated on the system's kinematic
    model.

    Args:
        system: The system being built.
        mimics: Its mimic couplings.
        anchor_q: Configuration (nq) whose contact-frame placements are the anchors; None: the
            scene's posture (``pinlin.operating_point.configuration``).

    Attributes:
        row_names: One name per row: ``<loop>.x`` ... (``.rx``... for weld rotations),
            ``contact:<contact>.x`` ..., ``mimic:<joint>``.
        size: Number of rows m.
        loop_rows: Constraint rows of each loop, in scene order.
        contacts: Each contact's frame, anchor and rows, in scene order.
        groups: (scene field, description, rows) of every loop and contact, for messages.
    """

    def __init__(self, system, mimics: tuple[MimicCoupling, ...] = (),
                 anchor_q: np.ndarray | None = None) -> None:
        self.system = system
        self._mimics = mimics
        scene = system.scene
        self._closures: list[_Closure] = []
        self.loop_rows: list[range] = []
        self.groups: list[tuple[str, str, range]] = []
        names: list[str] = []
        for i, loop in enumerate(scene.loops):
            fld = f"loops[{i}]"
            f1 = system.frame_id(loop.frame1, f"{fld}.frame1")
            f2 = system.frame_id(loop.frame2, f"{fld}.frame2")
            kin = system.kin_model
            if kin.frames[f1].parentJoint == kin.frames[f2].parentJoint:
                raise SceneError(scene.source, fld, f"frames '{loop.frame1}' and '{loop.frame2}' "
                                                    "are on the same body: the loop constrains "
                                                    "nothing")
            rows = self._add(names, loop.type, f1, f2, None, loop.name)
            self.loop_rows.append(rows)
            self.groups.append((fld, f"loop '{loop.name}'", rows))
        self.contacts = self._anchor_contacts(names, anchor_q)
        self._mimic_rows: list[tuple[int, int, float, float, bool, bool]] = []
        for c in mimics:
            jm = system.joint(c.mimic, "effects.mimic")
            jj = system.joint(c.joint, "effects.mimic")
            if jm.nv != 1 or jj.nv != 1:
                raise SceneError(scene.source, "effects.mimic", f"mimic joint '{c.mimic}' "
                                                                "couples joints that are not 1-DoF")
            self._mimic_rows.append((jm.idx_v, jj.idx_v, c.multiplier, c.offset,
                                     jm.continuous, jj.continuous))
            names.append(f"mimic:{c.mimic}")
        self._mimic_q = [(system.joint(c.mimic).idx_q, system.joint(c.joint).idx_q)
                         for c in mimics]
        self.row_names = tuple(names)
        self.size = len(names)
        self.linear_rows = self._linear_rows()
        self.length_scale, self.row_scale, self.uniform_scale = self._row_scales()
        self._support = self._support_columns()
        self._lie_blocks = [slice(j.idx_v, j.idx_v + j.nv) for j in system.joints.values()
                            if j.nv > 1 and j.nq != j.nv]
        # (frame id, sign, first row) of every moving closure frame, and whether the batched
        # Hessian applies: point closures only, every support joint 1-DoF.
        self._signed_frames = [(f, s, row) for kind, f1, f2, row, _ in self._closures
                               for f, s in ((f1, 1.0), (f2, -1.0)) if f is not None]
        self._batched_hessian = (not self.has_welds and
                                 all(kin_nv == 1 for kin_nv in self._support_joint_nv()))
        # Made on first use by pinlin.assembly: the scene's named independent coordinates, the
        # cache of solved assemblies (one per constraint set: per system and anchoring) and
        # the factors that put Phi_q in one unit (assembly.unit_factors).
        self._named_independent: tuple[np.ndarray, np.ndarray] | None = None
        self._assembly_cache = None
        self._unit_factors: list = []   # [rows, columns], or [None] where one unit already

    def _add(self, names: list[str], kind: str, f1: int, f2: int | None,
             anchor: pin.SE3 | None, label: str) -> range:
        rows = range(len(names), len(names) + len(_AXES[kind]))
        self._closures.append(_Closure(kind, f1, f2, len(names), anchor))
        names.extend(f"{label}.{a}" for a in _AXES[kind])
        return rows

    def _anchor_contacts(self, names: list[str], anchor_q: np.ndarray | None
                         ) -> tuple[AnchoredContact, ...]:
        """Check the scene's contacts against the robot and anchor them at ``anchor_q``."""
        system = self.system
        scene = system.scene
        if not scene.contacts:
            return ()
        if anchor_q is None:
            from .operating_point import configuration

            anchor_q = configuration(system)
        kin, kd = system.kin_model, pin.Data(system.kin_model)
        pin.framesForwardKinematics(kin, kd, system.kin_q(np.asarray(anchor_q, dtype=float)))
        world = 0 if system.rotation is None else 1  # the spin joint carries the scene's world
        out = []
        for i, contact in enumerate(scene.contacts):
            fld = f"contacts[{i}]"
            fid = system.frame_id(contact.frame, f"{fld}.frame")
            if kin.frames[fid].parentJoint == world:
                raise SceneError(scene.source, f"{fld}.frame",
                                 f"frame '{contact.frame}' is fixed to the world (no joint moves "
                                 "it): a contact there holds nothing; name a frame on a moving "
                                 "body (a foot)")
            placement = kd.oMf[fid].copy()
            rows = self._add(names, contact.type, fid, None, placement,
                             f"{CONTACT_PREFIX}{contact.name}")
            self.groups.append((fld, f"contact '{contact.name}'", rows))
            position, rotation = placement.translation.copy(), placement.rotation.copy()
            position.flags.writeable = rotation.flags.writeable = False
            out.append(AnchoredContact(contact.name, contact.type, contact.frame, fid, rows,
                                       position, rotation))
        return tuple(out)

    def _row_scales(self) -> tuple[float, np.ndarray, float | None]:
        """(L, the size each row's residual is measured against (m), that size when all rows
        share it, else None).

        L [m] bounds the closure frames' distance from the world origin in any configuration:
        the offsets of the joints that carry them (each counted once) and their own offsets
        on their bodies, summed, plus the largest contact anchor's distance. The rounding of
        Phi is then at most ~eps L, whatever the configuration, and L scales with the robot.
        Position rows are measured against L, rotation rows [rad] and mimic rows of revolute
        joints against 1, mimic rows of prismatic joints against L. A closure tolerance
        relative to L keeps a 0.1 mm mechanism's digits (closed to 1e-12 m it kept 4e-9 of
        its size)."""
        kin = self.system.kin_model
        carriers: set[int] = set()
        length, anchors = 0.0, 0.0
        for _, f1, f2, _, anchor in self._closures:
            for f in (f1, f2):
                if f is None:
                    continue
                length += float(np.linalg.norm(kin.frames[f].placement.translation))
                joint = kin.frames[f].parentJoint
                while joint > 0:
                    carriers.add(joint)
                    joint = kin.parents[joint]
            if anchor is not None:
                anchors = max(anchors, float(np.linalg.norm(anchor.translation)))
        length += sum(float(np.linalg.norm(kin.jointPlacements[j].translation))
                      for j in carriers) + anchors
        length = length or 1.0   # nothing has a size: Phi is 0 anyway
        scale = np.where(self.linear_rows, length, 1.0)
        scale.setflags(write=False)
        uniform = float(scale[0]) if scale.size and bool(np.all(scale == scale[0])) else None
        return length, scale, uniform

    def _linear_rows(self) -> np.ndarray:
        """Which rows (m,) are lengths [m], their multipliers forces [N]: position rows and
        the mimic rows of prismatic joints; the others (a weld's rotation rows, mimic rows of
        revolute joints) are angles [rad], their multipliers moments [N*m]. Read-only."""
        linear = np.ones(self.size, dtype=bool)
        for kind, _, _, row, _ in self._closures:
            if kind == "weld":
                linear[row + 3:row + 6] = False
        first = self.size - len(self._mimic_rows)
        joints = {j.idx_v: j for j in self.system.joints.values()}
        for k, (iv_m, *_rest) in enumerate(self._mimic_rows):
            linear[first + k] = slides_only(joints[iv_m].kind)
        linear.setflags(write=False)
        return linear

    def closure_frames(self) -> list[int]:
        """Frame ids of every loop's and contact's moving frames (a contact's world anchor is
        none), in row order."""
        return [f for _, f1, f2, _, _ in self._closures for f in (f1, f2) if f is not None]

    def closure_error(self, phi: np.ndarray) -> float:
        """max_i |Phi_i| / row_scale_i: the closure residual relative to the mechanism's
        size (:meth:`_row_scales`), what the assembly drives below ASSEMBLY_TOL."""
        if self.uniform_scale is not None:
            return float(np.abs(phi).max(initial=0.0)) / self.uniform_scale
        return float((np.abs(phi) / self.row_scale).max(initial=0.0))

    def anchored_at(self, system, q: np.ndarray) -> ConstraintSet:
        """The same constraints for ``system`` with the contacts anchored at configuration
        ``q`` (nq)."""
        other = ConstraintSet(system, self._mimics, anchor_q=q)
        other._unit_factors = self._unit_factors   # the robot's, shared: not where it stands
        return other

    def __bool__(self) -> bool:
        return self.size > 0

    # ----------------------------------------------------------------------------------------
    def residual(self, q: np.ndarray) -> np.ndarray:
        """Phi(q) [m, rad]."""
        if self._closures:
            kin, kd = self.system.kin_model, self.system.kin_data
            pin.framesForwardKinematics(kin, kd, self.system.kin_q(q))
            out = self._closure_residual(kd)
        else:
            out = np.zeros(self.size)
        self._mimic_residual(q, out)
        return out

    def _closure_residual(self, kd: pin.Data) -> np.ndarray:
        """Phi of the loop and contact rows from the frame placements in ``kd`` (mimic rows
        zero) [m, rad]."""
        out = np.zeros(self.size)
        for kind, f1, f2, row, anchor in self._closures:
            m1, m2 = kd.oMf[f1], (kd.oMf[f2] if f2 is not None else anchor)
            out[row:row + 3] = m1.translation - m2.translation
            if kind == "weld":
                out[row + 3:row + 6] = pin.log3(m1.rotation @ m2.rotation.T)
        return out

    def _mimic_residual(self, q: np.ndarray, out: np.ndarray) -> None:
        """Write the mimic rows of Phi(q) into ``out`` [rad or m]."""
        for k, ((iq_m, iq_j), (_, _, mult, off, cm, cj)) in enumerate(
                zip(self._mimic_q, self._mimic_rows, strict=True)):
            row = len(self.row_names) - len(self._mimic_rows) + k
            out[row] = _angle(q, iq_m, cm) - mult * _angle(q, iq_j, cj) - off

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Phi_q (m x nv), tangent space."""
        return self.residual_and_jacobian(q)[1]

    def residual_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Phi(q), Phi_q(q)) from one kinematics pass (``computeJointJacobians`` computes
        the placements :meth:`residual` reads) [m, rad; m/rad, -]."""
        sysm = self.system
        plan = self._point_plan
        if plan is not None:
            return self._point_residual_and_jacobian(q, plan)
        out = np.zeros((self.size, sysm.nv))
        if self._closures:
            kin, kd = sysm.kin_model, sysm.kin_data
            pin.computeJointJacobians(kin, kd, sysm.kin_q(q))
            pin.updateFramePlacements(kin, kd)
            phi = self._closure_residual(kd)
            cols = sysm.kin_columns
            for kind, f1, f2, row, anchor in self._closures:
                J1 = frame_jacobian(kin, kd, f1)[:, cols]
                if f2 is None:
                    out[row:row + 3] = J1[:3]
                    if kind == "weld":
                        E = kd.oMf[f1].rotation @ anchor.rotation.T
                        out[row + 3:row + 6] = pin.Jlog3(E) @ E.T @ J1[3:]
                    continue
                J2 = frame_jacobian(kin, kd, f2)[:, cols]
                out[row:row + 3] = J1[:3] - J2[:3]
                if kind == "weld":
                    E = kd.oMf[f1].rotation @ kd.oMf[f2].rotation.T
                    out[row + 3:row + 6] = pin.Jlog3(E) @ E.T @ (J1[3:] - E @ J2[3:])
        else:
            phi = np.zeros(self.size)
        self._mimic_residual(q, phi)
        self._mimic_jacobian(out)
        return phi, out

    def _mimic_jacobian(self, out: np.ndarray) -> None:
        """Add the mimic rows' constant Jacobian (q_m - multiplier q_j) into ``out``'s last
        rows."""
        first = self.size - len(self._mimic_rows)
        for k, (iv_m, iv_j, mult, _, _, _) in enumerate(self._mimic_rows):
            out[first + k, iv_m] += 1.0
            out[first + k, iv_j] -= mult

    def _point_residual_and_jacobian(self, q: np.ndarray, plan: tuple
                                     ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`residual_and_jacobian` of point loops and contacts (and mimic rows), every
        frame read once: Phi = P p - p_anchor and Phi_q = P Jp with P the fixed +-1 map from
        the stacked frame positions p (and their linear Jacobians Jp) to the rows, the same
        differences as row by row, exactly."""
        sysm = self.system
        kin, kd = sysm.kin_model, sysm.kin_data
        frames, P, anchor = plan
        pin.computeJointJacobians(kin, kd, sysm.kin_q(q))
        position = np.array([pin.updateFramePlacement(kin, kd, f).translation for f in frames])
        J = np.concatenate([frame_jacobian(kin, kd, f)[:3] for f in frames])
        if sysm.rotation is not None:
            J = J[:, sysm.kin_columns]
        phi = P @ position.reshape(-1)
        phi -= anchor
        jac = P @ J
        if self._mimic_rows:
            self._mimic_residual(q, phi)
            self._mimic_jacobian(jac)
        return phi, jac

    @functools.cached_property
    def _point_plan(self) -> tuple[list[int], np.ndarray, np.ndarray] | None:
        """(moving frames, P, anchor positions per row) for
        :meth:`_point_residual_and_jacobian`; None with a weld or without closures. P maps
        the 3F stacked frame coordinates to all m rows (mimic rows: zero, filled after)."""
        if not self._closures or self.has_welds:
            return None
        frames: list[int] = []
        P = np.zeros((self.size, 0))
        columns: list[np.ndarray] = []
        anchor = np.zeros(self.size)
        for _, f1, f2, row, fixed in self._closures:
            for f, sign in ((f1, 1.0), (f2, -1.0)):
                if f is None:
                    anchor[row:row + 3] = fixed.translation
                    continue
                block = np.zeros((self.size, 3))
                block[row:row + 3] = sign * np.eye(3)
                frames.append(f)
                columns.append(block)
        P = np.hstack(columns) if columns else P
        return frames, P, anchor

    @property
    def has_welds(self) -> bool:
        """Whether some loop or contact is a weld."""
        return any(c.kind == "weld" for c in self._closures)

    def bias_acceleration(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """gamma = Phi_qq[v, v] (m): the constraint acceleration at (q, v) with zero joint
        acceleration, so that the loops stay closed when Phi_q a = -gamma [m/s^2]. Point
        loops and contacts: the difference of the two frames' classical accelerations
        (LOCAL_WORLD_ALIGNED, from ``forwardKinematics(q, v, 0)``; the world's is zero); mimic
        rows are linear: 0. With welds, at an assembled q only
        (:func:`pinlin.constraint_derivatives.motion_rows`).
        """
        return constraint_derivatives.bias_acceleration(self, q, v)

    def jacobian_variation(self, q: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Phi_qq[w, .] (m x nv): the time variation of Phi_q along a velocity w [1/s], from
        ``computeJointJacobiansTimeVariation(q, w)`` (point loops and contacts; mimic rows: 0).

        Raises:
            ModelError: a weld loop or contact (not supported at a moving state yet).
        """
        return constraint_derivatives.jacobian_variation(self, q, w)

    def _refuse_welds(self) -> None:
        if self.has_welds:
            raise ModelError(f"scene '{self.system.scene.name}': weld loops and contacts at a "
                             "moving state are not supported yet (point loops and contacts and "
                             "mimic couplings are)")

    def hessian(self, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """d(Phi_q^T lam)/d(dq) at dq = 0 (nv x nv) at an assembled configuration q, lam held:
        the geometric stiffness of the constraint forces (module docstring). Symmetric (it is
        sum_i lam_i Phi_i,qq) but for the blocks of Lie-group joints (a free flyer's), which
        keep their exact antisymmetric part.

        Mimic rows are linear in the joint coordinates and contribute nothing. For a loop or
        contact row, one ``computeJointJacobiansTimeVariation`` per coordinate j of the
        closures' support gives d(Phi_q)/d(dq_j) (at v = e_j, d/dt(J) is dJ/dq_j), the weld
        rotation rows adding -1/2 d_j x d_k - d_j x w2_k.
        """
        return constraint_derivatives.hessian(self, q, lam)

    def _point_hessian(self, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """:func:`pinlin.constraint_derivatives._point_hessian` (batched :meth:`hessian` of point
        loops and contacts on 1-DoF joints)."""
        return constraint_derivatives._point_hessian(self, q, lam)

    @functools.cached_property
    def _hessian_plan(self) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray]:
        """For :meth:`_point_hessian`, built once: see
        :func:`pinlin.constraint_derivatives._hessian_plan`."""
        return constraint_derivatives._hessian_plan(self)

    @functools.cached_property
    def _triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Masks of the upper triangle of an nv x nv matrix, with and without the diagonal
        (np.triu builds its mask on every call)."""
        return constraint_derivatives._triangles(self)

    def hessian_by_time_variation(self, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """:meth:`hessian` by one ``computeJointJacobiansTimeVariation`` per support coordinate
        (any joint and closure type; the reference the batched path is tested against)."""
        return constraint_derivatives.hessian_by_time_variation(self, q, lam)

    # ----------------------------------------------------------------------------------------
    def _loop_rows(self) -> int:
        return self.size - len(self._mimic_rows)

    def _support_joint_nv(self) -> list[int]:
        """nv of every kinematic-model joint that moves some loop or contact frame (0 for a
        joint that is not revolute, prismatic or helical: its axis is not constant)."""
        kin = self.system.kin_model
        out = []
        for _, f1, f2, _, _ in self._closures:
            for fid in (f1, f2):
                if fid is not None:
                    out.extend(kin.joints[sj].nv if kin.joints[sj].shortname().startswith(
                        ("JointModelR", "JointModelP", "JointModelH")) else 0
                        for sj in kin.supports[kin.frames[fid].parentJoint] if sj != 0)
        return out

    def _support_columns(self) -> list[int]:
        """Velocity indices of the joints that move some loop or contact frame (system
        coordinates)."""
        sysm = self.system
        kin = sysm.kin_model
        offset = kin.nv - sysm.nv  # the spin coordinate of a rotating scene comes first
        cols: set[int] = set()
        for _, f1, f2, _, _ in self._closures:
            for fid in (f1, f2):
                if fid is None:
                    continue
                jid = kin.frames[fid].parentJoint
                for sj in kin.supports[jid]:
                    if sj == 0:
                        continue
                    jm = kin.joints[sj]
                    cols.update(i - offset for i in range(jm.idx_v, jm.idx_v + jm.nv)
                                if i - offset >= 0)
        return sorted(cols)


def _angle(q: np.ndarray, idx_q: int, continuous: bool) -> float:
    if continuous:
        return float(np.arctan2(q[idx_q + 1], q[idx_q]))
    return float(q[idx_q])
