"""Where each mode keeps its energy: kinetic and potential shares per joint and per body.

For a mode with position shape phi (complex for a damped mode) the motion is
q(t) = Re(phi e^{lam t}); over one cycle the average of q_i'(M q')_i is
|lam|^2 Re(conj(phi_i) (M phi)_i) / 2 (for an undamped mode exactly; a damped one decays
meanwhile, and the same split is used). So the kinetic share of coordinate i is::

    kinetic_i   = Re(conj(phi_i) (M phi)_i) / (phi^H M phi)
    potential_i = Re(conj(phi_i) (Ks phi)_i) / (phi^H Ks phi),     Ks = (K + K^T) / 2

Each row sums to 1. With a coupled (non-diagonal) M or K this is the symmetric split: the
cross term phi_i M_ij phi_j is shared half and half between coordinates i and j, so one share
may be negative or exceed 1 (coordinates that move against each other through the coupling).
The potential uses the symmetric part of K (a circulatory, non-symmetric part stores no
energy). A share per joint adds the shares of its coordinates (a free flyer's six).

Rigid-body modes, and any mode whose stiffness quotient |phi^H Ks phi| / phi^H M phi is at most
rigid_tol^2 (the threshold :func:`pinlin.modal` uses for rigid eigenvalues, squared), store no
potential energy: their potential row is NaN (never 0/0). Their kinetic row is defined.

Per body (given the model's :class:`~pinlin.Scene`): the body's spatial velocity in the mode
is V_b = J_b v with J_b Pinocchio's joint Jacobian in the joint frame
(``pin.computeJointJacobians`` then ``pin.getJointJacobian(..., pin.LOCAL)``) and v the
velocity shape in all of the robot's coordinates (v = R phi for a model in independent
coordinates, R from ``model.info["R"]``); its kinetic energy is Re(V_b^H I_b V_b) / 2 with
I_b the spatial inertia of the body (``model.inertias``: all links rigidly attached to the
joint). Rotor inertia (armature) is not in a body: it gets its own column, ``armature``. The
shares are over the sum of these, which equals phi^H M phi of the robot's mass matrix (the
penalty formulation's M also holds its penalty term, which no body owns).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .exceptions import ArgumentError, ModelError

if TYPE_CHECKING:
    from .linear_model import LinearModel
    from .modal import ModalAnalysis
    from .scene import Scene


@dataclass(frozen=True, eq=False)
class ModalEnergy:
    """Energy shares, one row per mode (conjugate and rigid pairs once); arrays read-only.

    Attributes:
        kinetic: Kinetic energy share per joint (modes x joints); rows sum to 1.
        potential: Potential energy share per joint (modes x joints); rows sum to 1, NaN rows
            for modes without potential energy (rigid-body modes).
        joint_names: Column names of ``kinetic`` and ``potential``.
        coordinate_kinetic, coordinate_potential: The same per coordinate (modes x nv).
        coordinate_names: Their column names.
        index: Row k describes eigenvalue ``index[k]`` of the modal analysis.
        eigenvalues: Those eigenvalues [1/s].
        rigid: Rigid-body rows.
        body_kinetic: Kinetic share per body (modes x bodies), rows sum to 1; None unless a
            scene was given.
        body_names: Its column names (link names, then ``armature`` when rotors have inertia).
        body_potential: Potential share per body (modes x len(body_potential_names)), rows
            sum to 1 (NaN rows for rigid modes): each body's gravity potential and the
            springs of the joint that carries it, plus a ``constraints`` column for the
            geometric stiffness of loop forces, which no body owns; None unless a scene was
            given, and for a rotating scene (its centrifugal potential is not split).
        body_potential_names: Its column names.
    """

    kinetic: np.ndarray
    potential: np.ndarray
    joint_names: tuple[str, ...]
    coordinate_kinetic: np.ndarray
    coordinate_potential: np.ndarray
    coordinate_names: tuple[str, ...]
    index: np.ndarray
    eigenvalues: np.ndarray
    rigid: np.ndarray
    body_kinetic: np.ndarray | None = None
    body_names: tuple[str, ...] = ()
    body_potential: np.ndarray | None = None
    body_potential_names: tuple[str, ...] = ()

    def table(self) -> str:
        """One line per mode: frequency and the largest kinetic and potential shares."""
        lines = [f"{'#':>3}  {'wn [rad/s]':>11}  {'kinetic (largest shares)':<40}  potential"]
        for k, lam in enumerate(self.eigenvalues):
            wn = "rigid" if self.rigid[k] else f"{abs(lam):.6g}"
            lines.append(f"{k + 1:>3}  {wn:>11}  {_top(self.kinetic[k], self.joint_names):<40}"
                         f"  {_top(self.potential[k], self.joint_names)}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()


def _top(row: np.ndarray, names: tuple[str, ...], limit: int = 3) -> str:
    if np.all(np.isnan(row)):
        return "-"
    order = np.argsort(-np.abs(row), kind="stable")[:limit]
    return ", ".join(f"{names[i]} {row[i]:.2f}" for i in order)


def _shares(phi: np.ndarray, mat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-coordinate parts Re(conj(phi_i) (mat phi)_i) (columns of phi are modes) and their
    sums."""
    parts = (phi.conj() * (mat @ phi)).real
    return parts, parts.sum(axis=0)


def modal_energy(modes: ModalAnalysis, scene: Scene | None = None) -> ModalEnergy:
    """The energy shares of the modes of ``modes`` (a :class:`~pinlin.modal.ModalAnalysis` of
    a mechanical model); per body too when ``scene`` (the model's scene) is given.

    Raises:
        ModelError: the model has no M and K (a linear-graph or first-order model), or the
            scene does not match the model.
        ArgumentError: ``scene`` is not a Scene.
    """
    model = modes.model
    if not model.has_second_order:
        raise ModelError(f"model '{model.name}' has no mass and stiffness matrices (M, K): "
                         "modal energies need a mechanical model from pinlin.linearize, not a "
                         "linear graph or a first-order model")
    nv = model.M.shape[0]
    index = np.array(modes.modes(), dtype=int)
    phi = modes.right_vectors[:nv, index]
    M, Ks = model.M, 0.5 * (model.K + model.K.T)
    kin_parts, kin_total = _shares(phi, M)
    pot_parts, pot_total = _shares(phi, Ks)
    with np.errstate(divide="ignore", invalid="ignore"):
        kinetic = (kin_parts / kin_total).T
        potential = (pot_parts / pot_total).T
    no_potential = np.abs(pot_total) <= modes.rigid_tol ** 2 * kin_total
    potential[no_potential | modes.rigid[index]] = np.nan
    names = tuple(s.removeprefix("q:") for s in model.state_names[:nv])
    joints = tuple(dict.fromkeys(s.split("[")[0] for s in names))
    groups = np.array([[s.split("[")[0] == j for s in names] for j in joints], dtype=float)
    body, body_names = (None, ()) if scene is None else _bodies(model, scene, phi)
    pot_body, pot_names = (None, ()) if scene is None else _body_potential(model, scene, phi,
                                                                           pot_total)
    if pot_body is not None:
        pot_body[no_potential | modes.rigid[index]] = np.nan
    arrays = [kinetic @ groups.T, potential @ groups.T, kinetic, potential,
              index, modes.eigenvalues[index], modes.rigid[index].copy()]
    for arr in [*arrays, body, pot_body]:
        if arr is not None:
            arr.flags.writeable = False
    return ModalEnergy(arrays[0], arrays[1], joints, arrays[2], arrays[3], names, arrays[4],
                       arrays[5], arrays[6], body, body_names, pot_body, pot_names)


def _bodies(model: LinearModel, scene: Scene, phi: np.ndarray
            ) -> tuple[np.ndarray, tuple[str, ...]]:
    """Kinetic shares per body (modes x bodies) and the body names."""
    import pinocchio as pin

    from .scene import Scene

    if not isinstance(scene, Scene):
        raise ArgumentError("scene", f"expected a pinlin Scene, got {type(scene).__name__}")
    system = scene.system
    pm = system.model
    op = model.operating_point
    if op is None or np.shape(op.q) != (pm.nq,):
        raise ModelError(f"scene '{scene.name}' does not match model '{model.name}': the model "
                         f"has no operating point with {pm.nq} configuration values")
    v = _shape_matrix(model, scene, phi.shape[0]) @ phi   # velocity shapes, all coordinates
    data = pm.createData()                          # a workspace of our own (thread safety)
    pin.computeJointJacobians(pm, data, np.asarray(op.q, dtype=float))
    energies, names = [], []
    for jid in range(1, pm.njoints):
        J = pin.getJointJacobian(pm, data, jid, pin.ReferenceFrame.LOCAL).reshape(6, -1)
        V = J @ v
        energies.append((V.conj() * (pm.inertias[jid].matrix() @ V)).real.sum(axis=0))
        names.append(_link_name(pm, jid))
    arm = np.asarray(pm.armature, dtype=float)
    if np.any(arm):
        energies.append((arm[:, None] * np.abs(v) ** 2).sum(axis=0))
        names.append("armature")
    E = np.array(energies).T                        # modes x bodies
    total = E.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return E / total, tuple(names)


#: Step of the second differences of each body's gravity potential along a mode shape
#: (scaled to a largest entry of 1) [rad or m]: truncation ~h^2, rounding ~eps |V| / h^2,
#: about 1e-8 of the potential energy.
POTENTIAL_STEP = 1e-3


def _shape_matrix(model: LinearModel, scene: Scene, n: int) -> np.ndarray:
    """R mapping the model's position shape to all of the robot's coordinates."""
    system = scene.system
    coords = [s.removeprefix("q:") for s in model.state_names[:n]]
    if "R" in model.info:
        R = np.asarray(model.info["R"], dtype=float)
    elif coords == list(system.coordinate_names):
        R = np.eye(system.nv)
    else:
        R = None
    if R is None or R.shape != (system.nv, n):
        raise ModelError(f"scene '{scene.name}' does not match model '{model.name}': its "
                         f"coordinates are not the model's ({', '.join(coords[:4])}...)")
    return R


def _body_potential(model: LinearModel, scene: Scene, phi: np.ndarray, total: np.ndarray
                    ) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """Potential shares per body (modes x bodies [+ constraints]) and the column names.

    Body b's share is the second derivative of its gravity potential -m_b g . c_b(q) along
    the shape (real and imaginary parts, central differences with :data:`POTENTIAL_STEP`)
    plus 1/2 k |dq_j|^2 of the springs on the joint that carries it; what the model's
    stiffness holds beyond these (the loop forces' geometric stiffness) is the
    ``constraints`` column."""
    import pinocchio as pin

    system = scene.system
    if system.rotation is not None:
        return None, ()
    pm = system.model
    q0 = np.asarray(model.operating_point.q, dtype=float)
    data = pin.Data(pm)
    R = _shape_matrix(model, scene, phi.shape[0])
    shapes = R @ phi
    g = np.asarray(pm.gravity.linear, dtype=float)

    def potentials(q: np.ndarray) -> np.ndarray:
        pin.forwardKinematics(pm, data, q)
        return np.array([-pm.inertias[j].mass * g @ (data.oMi[j] * pm.inertias[j].lever)
                         for j in range(1, pm.njoints)])

    h = POTENTIAL_STEP
    E = np.zeros((phi.shape[1], pm.njoints - 1))
    base = potentials(q0)
    for k in range(phi.shape[1]):
        scale = max(float(np.abs(shapes[:, k]).max()), np.finfo(float).tiny)
        for part in (shapes[:, k].real, shapes[:, k].imag):
            if not np.any(part):
                continue
            d = part / scale
            second = (potentials(pin.integrate(pm, q0, h * d)) - 2 * base
                      + potentials(pin.integrate(pm, q0, -h * d))) / h**2
            E[k] += second * scale**2
    stiffness = np.asarray(system.stiffness, dtype=float)
    for j in system.joints.values():
        sl = slice(j.idx_v, j.idx_v + j.nv)
        E[:, j.id - 1] += (stiffness[sl, None] * np.abs(shapes[sl]) ** 2).sum(axis=0)
    names = [_link_name(pm, jid) for jid in range(1, pm.njoints)]
    if system.constraints:
        E = np.hstack([E, (total - E.sum(axis=1))[:, None]])
        names.append("constraints")
    with np.errstate(divide="ignore", invalid="ignore"):
        return E / E.sum(axis=1, keepdims=True), tuple(names)


def _link_name(pm, jid: int) -> str:  # pm: pinocchio.Model
    """The first body frame a joint carries (its child link), else the joint's name."""
    import pinocchio as pin

    for frame in pm.frames:
        if frame.parentJoint == jid and frame.type == pin.FrameType.BODY:
            return frame.name
    return pm.names[jid]


__all__ = ["ModalEnergy", "modal_energy"]
