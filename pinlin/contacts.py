"""Contacts at the operating point: the force each one carries and what it says about the pose.

A contact's constraint rows (``contact:<name>.x`` ... ``.rz``, see :mod:`pinlin.constraints`)
carry lam: the force [N] the world applies to the robot at the contact frame's origin and, for
a weld, the torque [N*m] about that origin, both in the world frame. From them:

- :func:`contact_forces`: contact name -> (force, torque), from any lam and its row names
  (so a saved operating point gives them back too);
- :func:`statics_notes`: the total vertical contact force against the robot's weight m g (on a
  floating base they are equal at rest), each contact's force, and a :class:`ContactWarning`
  for a point contact that pulls the robot towards the ground (a foot can only push);
- :func:`limb_conditions`: for each contact, the condition number of its frame's Jacobian with
  respect to the joints between the base and the frame: large at a singular posture of the
  limb (a straight knee), where :func:`warn_singular_limbs` gives an AccuracyWarning.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from .conditioning import AccuracyWarning
from .constraints import CONTACT_PREFIX

#: A limb whose contact Jacobian has a condition number above this is at (or near) a singular
#: posture: the same level at which the loop Jacobian's condition is warned about.
LIMB_CONDITION_WARN = 1e6


class ContactWarning(UserWarning):
    """A point contact pulls the robot towards the ground at the operating point: the model
    holds that foot as if glued (a real one would lift off).

    Attributes:
        contact: The contact's name.
        normal_force: Its force along the upward vertical (against gravity) [N], negative.
    """

    def __init__(self, message: str, contact: str, normal_force: float) -> None:
        super().__init__(message)
        self.contact = contact
        self.normal_force = normal_force


def contact_forces(lam: np.ndarray | None, names: Sequence[str]
                   ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Contact name -> (force [N] (3,), torque [N*m] (3,)) in the world frame, applied by the
    world to the robot at the contact frame's origin; a point contact's torque is zero. Read
    from the constraint forces ``lam`` and their row ``names`` (rows ``contact:<name>.<axis>``);
    empty without contacts."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if lam is None:
        return out
    for value, row in zip(lam, names, strict=True):
        if not row.startswith(CONTACT_PREFIX):
            continue
        name, _, axis = row[len(CONTACT_PREFIX):].rpartition(".")
        force, torque = out.setdefault(name, (np.zeros(3), np.zeros(3)))
        target = torque if axis.startswith("r") else force
        target["xyz".index(axis[-1])] = value
    return out


def _up(system) -> np.ndarray:
    """The upward vertical: against gravity, +z without gravity."""
    g = np.asarray(system.model.gravity.linear, dtype=float)
    norm = float(np.linalg.norm(g))
    return -g / norm if norm > 0.0 else np.array([0.0, 0.0, 1.0])


def _vector(x: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in x) + "]"


def statics_notes(system, lam: np.ndarray, scale: float) -> list[str]:
    """Notes on the contact forces at rest, and a :class:`ContactWarning` for each point contact
    that pulls the robot towards the ground.

    Args:
        system: The system (its constraints name the contacts).
        lam: Constraint forces per row.
        scale: The largest generalized force of the statics [N*m or N]: normal forces above
            -1e-9 max(scale, |lam|) count as zero. The statics are solved to a residual of
            1e-9 of that scale (``residual_tolerance``) and lam by a least-squares solve whose
            rounding is far below it, so a smaller pull is no pull to the solve's accuracy.
    """
    cons = system.constraints
    if not cons.contacts:
        return []
    forces = contact_forces(lam, cons.row_names)
    up = _up(system)
    mass = float(pin.computeTotalMass(system.model))
    weight = mass * float(np.linalg.norm(system.model.gravity.linear))
    vertical = float(sum(f for f, _ in forces.values()) @ up)
    total = (f"the weight m g = {weight:.6g} N (m = {mass:.6g} kg)" if weight > 0.0 else
             "no weight (no gravity)")
    carrier = (f"against {total}" if system.base_joint is not None else
               f"of {total}; the fixed base carries the rest")
    notes = [f"contact forces (world frame, on the robot): total vertical {vertical:.6g} N "
             f"{carrier}"]
    tol = 1e-9 * max(scale, float(np.abs(lam).max(initial=0.0)))
    for contact in cons.contacts:
        force, torque = forces[contact.name]
        text = f"contact '{contact.name}': force {_vector(force)} N"
        if contact.type == "weld":
            text += f", torque {_vector(torque)} N*m about the frame's origin"
        normal = float(force @ up)
        if contact.type == "point" and normal < -tol:
            text += ": it PULLS the robot towards the ground"
            warnings.warn(ContactWarning(
                f"scene '{system.scene.name}': point contact '{contact.name}' pulls the robot "
                f"towards the ground at the operating point (vertical force {normal:.6g} N): "
                "the model holds that foot as if glued, a real one would lift off; choose "
                "another split of the forces (operating_point.solve = \"forces\" with the "
                "inputs u) or another posture", contact.name, normal), stacklevel=5)
        notes.append(text)
    return notes


def limb_conditions(system, q: np.ndarray) -> dict[str, float]:
    """Contact name -> condition number of the contact frame's Jacobian (its 3 or 6 rows) with
    respect to the coordinates of the joints that move it, a floating base's own excluded
    (the largest over the smallest of its min(rows, columns) singular values; inf when one is
    zero), rows the limb cannot move at a generic nearby posture either (structure, such as
    a planar chain's out-of-plane row) left out. Contacts on the base itself (no joint
    between) are left out."""
    cons = system.constraints
    if not cons.contacts:
        return {}
    kin = system.kin_model
    offset = kin.njoints - system.model.njoints  # a rotating scene's spin joint comes first
    base = system.joints[system.base_joint].id if system.base_joint is not None else None
    jac = cons.jacobian(q)
    # The Jacobian at a generic nearby posture too: a row no joint of a limb moves there either
    # is the limb's structure (a planar chain's out-of-plane row), not a singular posture.
    wiggle = 0.1 * np.sin(np.arange(1, system.nv + 1))
    jac_elsewhere = cons.jacobian(pin.integrate(system.model, q, wiggle))
    out: dict[str, float] = {}
    for contact in cons.contacts:
        cols: list[int] = []
        for jid in kin.supports[kin.frames[contact.frame_id].parentJoint]:
            sid = jid - offset  # the joint's index in system.model
            if sid <= 0 or sid == base:
                continue
            jm = system.model.joints[sid]
            cols.extend(range(jm.idx_v, jm.idx_v + jm.nv))
        if not cols:
            continue
        rows = np.array(contact.rows)
        block = jac[rows][:, cols]
        reach = np.abs(jac_elsewhere[rows][:, cols]).max(axis=1)
        block = block[reach > 1e-12 * reach.max(initial=0.0)]   # structural rows left out
        if not block.shape[0]:
            continue
        sv = np.linalg.svd(block, compute_uv=False)
        smallest = sv[min(block.shape[0], len(cols)) - 1]
        out[contact.name] = float(sv[0] / smallest) if smallest > 0.0 else float("inf")
    return out


def warn_singular_limbs(system, conditions: dict[str, float], stacklevel: int = 5) -> None:
    """An AccuracyWarning for each contact whose limb condition (:func:`limb_conditions`)
    exceeds :data:`LIMB_CONDITION_WARN`."""
    for contact in system.constraints.contacts:
        condition = conditions.get(contact.name)
        if condition is None or condition <= LIMB_CONDITION_WARN:
            continue
        shown = f"{condition:.1e}" if np.isfinite(condition) else "infinite"
        warnings.warn(AccuracyWarning(
            f"model '{system.scene.name}': contact '{contact.name}': the Jacobian of frame "
            f"'{contact.frame}' with respect to the joints that move it from the base has "
            f"condition number {shown} (warned above {LIMB_CONDITION_WARN:.0e}): the limb is "
            "at or near a singular posture (a straight knee or elbow); its joints cannot move "
            "the frame in every direction, the inputs lose authority there and the linear "
            "model holds only very near q0 (bend the limb)", condition), stacklevel=stacklevel)


__all__ = ["LIMB_CONDITION_WARN", "ContactWarning", "contact_forces", "limb_conditions",
           "statics_notes", "warn_singular_limbs"]
