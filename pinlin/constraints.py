"""Holonomic constraints Phi(q) = 0: loop closures between frames and URDF mimic couplings.

Rows, in the world frame (the rotating frame when the scene spins):

- ``point`` loop: Phi = p1 - p2, the frame origins [m] (3 rows);
- ``weld`` loop: Phi = [p1 - p2; log3(R1 R2^T)] [m, rad] (6 rows);
- mimic coupling: Phi = q_mimic - multiplier * q_joint - offset [rad or m] (1 row).

Everything is in the tangent space: ``jacobian(q)`` is dPhi(q (+) dq)/d(dq) (m x nv) and
``hessian(q, lam)`` is the symmetric Hessian of lam^T Phi(q (+) dq) at dq = 0, exact: along
geodesics (v' = 0) d^2/dt^2 Phi(q (+) t v) = d/dt(Phi_q) v = v^T (Phi_qq) v, and Pinocchio's
Jacobian time variation at v = e_j is dJ/dq_j (for a weld at an assembled configuration the
rotation rows add -omega1 x omega2, the second-order term of log(exp(a) exp(-b))). The constraint
force the closure applies is Phi_q^T lam, with lam the
force [N] (and torque [N*m]) on frame1's body, expressed in the world frame.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from .exceptions import ModelError, SceneError, UrdfError

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass(frozen=True)
class MimicCoupling:
    """q_mimic = multiplier * q_joint + offset, from a URDF ``<mimic>`` tag."""

    mimic: str
    joint: str
    multiplier: float
    offset: float


def read_mimic_tags(urdf: Path) -> tuple[MimicCoupling, ...]:
    """The ``<mimic>`` couplings of a URDF file, in file order."""
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as exc:
        raise UrdfError(urdf, f"malformed XML: {exc}") from None
    out = []
    for joint in root.findall("joint"):  # not <transmission><joint>
        tag = joint.find("mimic")
        if tag is None:
            continue
        try:
            out.append(MimicCoupling(joint.get("name", ""), tag.get("joint", ""),
                                     float(tag.get("multiplier", 1.0)),
                                     float(tag.get("offset", 0.0))))
        except ValueError:
            raise UrdfError(urdf, f"joint '{joint.get('name')}': <mimic> multiplier and offset "
                                  "must be numbers") from None
    return tuple(out)


class ConstraintSet:
    """The scene's loops and mimic couplings, evaluated on the system's kinematic model.

    Attributes:
        row_names: One name per row: ``<loop>.x`` ... (``.rx``... for weld rotations),
            ``mimic:<joint>``.
        size: Number of rows m.
    """

    def __init__(self, system, mimics: tuple[MimicCoupling, ...] = ()) -> None:
        self.system = system
        src = system.scene.source
        self._loops: list[tuple[str, int, int, int]] = []  # (type, fid1, fid2, first row)
        #: Constraint rows of each loop, in scene order.
        self.loop_rows: list[range] = []
        names: list[str] = []
        for i, loop in enumerate(system.scene.loops):
            fld = f"loops[{i}]"
            f1 = system.frame_id(loop.frame1, f"{fld}.frame1")
            f2 = system.frame_id(loop.frame2, f"{fld}.frame2")
            kin = system.kin_model
            if kin.frames[f1].parentJoint == kin.frames[f2].parentJoint:
                raise SceneError(src, fld, f"frames '{loop.frame1}' and '{loop.frame2}' are on "
                                           "the same body: the loop constrains nothing")
            self._loops.append((loop.type, f1, f2, len(names)))
            self.loop_rows.append(range(len(names), len(names) + (3 if loop.type == "point"
                                                                  else 6)))
            axes = ("x", "y", "z") if loop.type == "point" else ("x", "y", "z", "rx", "ry", "rz")
            names.extend(f"{loop.name}.{a}" for a in axes)
        self._mimic_rows: list[tuple[int, int, float, float, bool, bool]] = []
        for c in mimics:
            jm = system.joint(c.mimic, "effects.mimic")
            jj = system.joint(c.joint, "effects.mimic")
            if jm.nv != 1 or jj.nv != 1:
                raise SceneError(src, "effects.mimic", f"mimic joint '{c.mimic}' couples "
                                                       "joints that are not 1-DoF")
            self._mimic_rows.append((jm.idx_v, jj.idx_v, c.multiplier, c.offset,
                                     jm.continuous, jj.continuous))
            names.append(f"mimic:{c.mimic}")
        self._mimic_q = [(system.joint(c.mimic).idx_q, system.joint(c.joint).idx_q)
                         for c in mimics]
        self.row_names = tuple(names)
        self.size = len(names)
        self._support = self._support_columns()

    def __bool__(self) -> bool:
        return self.size > 0

    # ----------------------------------------------------------------------------------------
    def residual(self, q: np.ndarray) -> np.ndarray:
        """Phi(q) [m, rad]."""
        out = np.zeros(self.size)
        if self._loops:
            kin, kd = self.system.kin_model, self.system.kin_data
            pin.framesForwardKinematics(kin, kd, self.system.kin_q(q))
            for kind, f1, f2, row in self._loops:
                m1, m2 = kd.oMf[f1], kd.oMf[f2]
                out[row:row + 3] = m1.translation - m2.translation
                if kind == "weld":
                    out[row + 3:row + 6] = pin.log3(m1.rotation @ m2.rotation.T)
        for k, ((iq_m, iq_j), (_, _, mult, off, cm, cj)) in enumerate(
                zip(self._mimic_q, self._mimic_rows, strict=True)):
            row = len(self.row_names) - len(self._mimic_rows) + k
            out[row] = _angle(q, iq_m, cm) - mult * _angle(q, iq_j, cj) - off
        return out

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Phi_q (m x nv), tangent space."""
        sysm = self.system
        out = np.zeros((self.size, sysm.nv))
        if self._loops:
            kin, kd = sysm.kin_model, sysm.kin_data
            pin.computeJointJacobians(kin, kd, sysm.kin_q(q))
            pin.updateFramePlacements(kin, kd)
            cols = sysm.kin_columns
            for kind, f1, f2, row in self._loops:
                J1 = pin.getFrameJacobian(kin, kd, f1, LWA)[:, cols]
                J2 = pin.getFrameJacobian(kin, kd, f2, LWA)[:, cols]
                out[row:row + 3] = J1[:3] - J2[:3]
                if kind == "weld":
                    E = kd.oMf[f1].rotation @ kd.oMf[f2].rotation.T
                    out[row + 3:row + 6] = pin.Jlog3(E) @ E.T @ (J1[3:] - E @ J2[3:])
        first = self.size - len(self._mimic_rows)
        for k, (iv_m, iv_j, mult, _, _, _) in enumerate(self._mimic_rows):
            out[first + k, iv_m] += 1.0
            out[first + k, iv_j] -= mult
        return out

    @property
    def has_welds(self) -> bool:
        return any(kind == "weld" for kind, *_ in self._loops)

    def bias_acceleration(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """gamma = Phi_qq[v, v] (m): the constraint acceleration at (q, v) with zero joint
        acceleration, so that the loops stay closed when Phi_q a = -gamma [m/s^2]. Point
        loops: the difference of the two frames' classical accelerations (LOCAL_WORLD_ALIGNED,
        from ``forwardKinematics(q, v, 0)``); mimic rows are linear: 0.

        Raises:
            ModelError: a weld loop (not supported at a moving state yet).
        """
        out = np.zeros(self.size)
        if not self._loops:
            return out
        self._refuse_welds()
        sysm = self.system
        kin, kd = sysm.kin_model, sysm.kin_data
        pin.forwardKinematics(kin, kd, sysm.kin_q(q), sysm.kin_v(v, spin=False),
                              np.zeros(kin.nv))
        pin.updateFramePlacements(kin, kd)
        for _, f1, f2, row in self._loops:
            out[row:row + 3] = (pin.getFrameClassicalAcceleration(kin, kd, f1, LWA).linear
                                - pin.getFrameClassicalAcceleration(kin, kd, f2, LWA).linear)
        return out

    def jacobian_variation(self, q: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Phi_qq[w, .] (m x nv): the time variation of Phi_q along a velocity w [1/s], from
        ``computeJointJacobiansTimeVariation(q, w)`` (point loops; mimic rows: 0).

        Raises:
            ModelError: a weld loop (not supported at a moving state yet).
        """
        sysm = self.system
        out = np.zeros((self.size, sysm.nv))
        if not self._loops:
            return out
        self._refuse_welds()
        kin, kd = sysm.kin_model, sysm.kin_data
        pin.computeJointJacobiansTimeVariation(kin, kd, sysm.kin_q(q), sysm.kin_v(w, spin=False))
        cols = sysm.kin_columns
        for _, f1, f2, row in self._loops:
            out[row:row + 3] = (pin.getFrameJacobianTimeVariation(kin, kd, f1, LWA)[:3, cols]
                                - pin.getFrameJacobianTimeVariation(kin, kd, f2, LWA)[:3, cols])
        return out

    def _refuse_welds(self) -> None:
        if self.has_welds:
            raise ModelError(f"scene '{self.system.scene.name}': weld loops at a moving state "
                             "are not supported yet (point loops and mimic couplings are)")

    def hessian(self, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """sum_i lam_i Phi_i,qq (nv x nv, symmetric) at an assembled configuration q.

        Mimic rows are linear in the joint coordinates and contribute nothing. For a loop row
        the second time derivative along q (+) t v is d/dt(Phi_q) v, with d/dt(Phi_q) linear in
        v: one ``computeJointJacobiansTimeVariation`` per coordinate j of the loops' support
        gives the row j of the Hessian (d/dt(J) at v = e_j is dJ/dq_j), the weld rotation rows
        adding -w1 x w2; the symmetric part is the Hessian (polarization identity).
        """
        sysm = self.system
        nv = sysm.nv
        out = np.zeros((nv, nv))
        if not self._loops or not np.any(lam[:self._loop_rows()]):
            return out
        kin, kd = sysm.kin_model, sysm.kin_data
        qk = sysm.kin_q(q)
        cols = sysm.kin_columns
        pin.computeJointJacobians(kin, kd, qk)
        pin.updateFramePlacements(kin, kd)
        angular = {}  # world angular-velocity Jacobians of weld frames
        for kind, f1, f2, _ in self._loops:
            if kind == "weld":
                for f in (f1, f2):
                    angular[f] = pin.getFrameJacobian(kin, kd, f, LWA)[3:, cols]
        e = np.zeros(nv)
        for j in self._support:
            e[j] = 1.0
            pin.computeJointJacobiansTimeVariation(kin, kd, qk, sysm.kin_v(e, spin=False))
            for kind, f1, f2, row in self._loops:
                dJ1 = pin.getFrameJacobianTimeVariation(kin, kd, f1, LWA)[:, cols]
                dJ2 = pin.getFrameJacobianTimeVariation(kin, kd, f2, LWA)[:, cols]
                out[j] += lam[row:row + 3] @ (dJ1[:3] - dJ2[:3])
                if kind == "weld":
                    lr = lam[row + 3:row + 6]
                    out[j] += lr @ (dJ1[3:] - dJ2[3:])
                    # -w1 x w2 with w1 = J1 e_j, w2 = J2 e_k (and the swap, by symmetrization)
                    w1 = angular[f1][:, j]
                    out[j] -= lr @ np.cross(w1, angular[f2].T).T
            e[j] = 0.0
        return 0.5 * (out + out.T)

    # ----------------------------------------------------------------------------------------
    def _loop_rows(self) -> int:
        return self.size - len(self._mimic_rows)

    def _support_columns(self) -> list[int]:
        """Velocity indices of the joints that move some loop frame (system coordinates)."""
        sysm = self.system
        kin = sysm.kin_model
        offset = kin.nv - sysm.nv  # the spin coordinate of a rotating scene comes first
        cols: set[int] = set()
        for _, f1, f2, _ in self._loops:
            for fid in (f1, f2):
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
