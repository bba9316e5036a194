"""Assembly of closed loops: independent constraint rows, the choice of independent
coordinates z, Newton on Phi(q) = 0 with z held, and the velocity projection R (chapter 9.1.1).

Coordinates are velocity (tangent-space) indices throughout; a configuration moves by
``pin.integrate``, so a floating base's six coordinates (body-frame twist, a Lie group) take
part like any joint's: Newton may move them and the partition may make them dependent or
independent (states then named ``q:root_joint[i]``). Redundant rows (a planar loop closed by a
3-D point constraint has one; two point contacts on one rigid body share their distance) are
found by a column-pivoted QR of Phi_q^T and dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import scipy.linalg as sla

from .arrays import complement
from .exceptions import AssemblyError, SceneError

#: Rank threshold relative to the largest pivot of the constraint Jacobian.
RANK_TOL = 1e-9
#: Assembly converges when max |Phi| is below this [m or rad].
ASSEMBLY_TOL = 1e-12


@dataclass(frozen=True)
class Partition:
    """Independent rows and coordinates at a configuration.

    Attributes:
        rows: Indices of the independent constraint rows (the others are dropped).
        dropped: Names of the dropped (redundant) rows.
        independent: Velocity indices of the independent coordinates z.
        dependent: Velocity indices of the dependent coordinates.
        chosen: Whether pinlin chose z (True) or the scene named it.
        condition: 2-norm condition number of Phi_d, the Jacobian block of the dependent
            coordinates (large near a singular, e.g. toggle, position); NaN when the
            partition was made unchecked (a starting guess).
    """

    rows: np.ndarray
    dropped: tuple[str, ...]
    independent: np.ndarray
    dependent: np.ndarray
    chosen: bool
    condition: float


def independent_rows(jac: np.ndarray, groups: list[tuple[str, str, range]], source
                     ) -> np.ndarray:
    """Rows of ``jac`` that are linearly independent (pivoted QR of jac^T), in order.

    Args:
        jac: The constraint Jacobian (m x nv).
        groups: (scene field, description, rows) of each loop and contact
            (:attr:`pinlin.constraints.ConstraintSet.groups`).
        source: The scene file, for messages.

    Raises:
        SceneError: a loop or contact contributes no independent row at all.
    """
    if jac.shape[0] == 0:
        return np.zeros(0, dtype=int)
    _, r, piv = sla.qr(jac.T, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    scale = diag[0] if diag.size else 0.0
    rank = int(np.sum(diag > RANK_TOL * max(scale, 1e-300)))
    keep = np.sort(piv[:rank])
    kept = set(keep.tolist())
    for fld, what, own in groups:
        if not kept.intersection(own):
            raise SceneError(source, fld, f"{what} adds no independent constraint: every row "
                                          "repeats others")
    return keep


def partition(system, q: np.ndarray, jac: np.ndarray | None = None, check: bool = True
              ) -> Partition:
    """Independent rows and coordinates at ``q`` (the scene's ``independent`` or a choice).

    pinlin's choice: dependent coordinates are the pivots of a column-pivoted QR of the
    independent rows of Phi_q, with unactuated coordinates preferred as dependent (columns of
    actuated ones scaled by 1e-3), so that actuated joints stay independent where the mechanism
    allows: a standing robot's floating base is dependent, its states are joints.

    Raises:
        SceneError: the scene's ``independent`` list has the wrong size, names an unknown joint,
            or its coordinates cannot parametrize the mechanism at ``q`` (Phi_d singular;
            checked when ``check``, i.e. at an assembled configuration).
    """
    cons = system.constraints
    src = system.scene.source
    jac = cons.jacobian(q) if jac is None else jac
    rows = independent_rows(jac, cons.groups, src)
    kept = set(rows.tolist())
    dropped = tuple(n for k, n in enumerate(cons.row_names) if k not in kept)
    G = jac[rows]
    nv, m = system.nv, len(rows)
    names = system.scene.operating_point.independent
    if names:
        z: list[int] = []
        for name in names:
            j = system.joint(name, "operating_point.independent")
            z.extend(range(j.idx_v, j.idx_v + j.nv))
        if len(z) != nv - m:
            raise SceneError(src, "operating_point.independent",
                             f"expected {nv - m} coordinates (the mechanism has {nv} "
                             f"coordinates and {m} independent constraints), got {len(z)}")
        independent = np.array(sorted(z), dtype=int)
        chosen = False
    elif m == 0:
        independent, chosen = np.arange(nv), False
    else:
        weight = np.ones(nv)
        weight[system.actuated] = 1e-3
        _, _, piv = sla.qr(G * weight, mode="economic", pivoting=True)
        independent = np.sort(piv[m:])
        chosen = True
    dependent = complement(nv, independent)
    if not check:
        return Partition(rows, dropped, independent, dependent, chosen, float("nan"))
    cond = float(np.linalg.cond(G[:, dependent])) if m else 1.0
    if not np.isfinite(cond) or cond > 1e12:
        names_z = ", ".join(system.coordinate_names[i] for i in independent)
        raise SceneError(src, "operating_point.independent",
                         f"coordinates [{names_z}] cannot parametrize the mechanism at this "
                         f"configuration (the Jacobian of the others is singular, condition "
                         f"{cond:.3g}); name other independent joints or move q")
    return Partition(rows, dropped, independent, dependent, chosen, cond)


def assemble(system, q_guess: np.ndarray, independent: np.ndarray, *, max_iter: int = 50
             ) -> np.ndarray:
    """Close the loops from ``q_guess`` by Newton on the dependent coordinates, z held.

    Raises:
        AssemblyError: no convergence; the message gives the residual and the worst row.
    """
    cons = system.constraints
    q = np.array(q_guess, dtype=float)
    dependent = complement(system.nv, independent)
    phi = cons.residual(q)
    best = np.abs(phi).max(initial=0.0)
    for _ in range(max_iter):
        if best <= ASSEMBLY_TOL:
            return q
        J = cons.jacobian(q)[:, dependent]
        step, *_ = np.linalg.lstsq(J, -phi, rcond=None)
        dq = np.zeros(system.nv)
        dq[dependent] = step
        # Backtracking keeps Newton from leaving the basin of the branch the guess picked.
        for scale in (1.0, 0.5, 0.25, 0.125, 0.0625):
            trial = pin.integrate(system.model, q, scale * dq)
            phi_t = cons.residual(trial)
            if np.abs(phi_t).max() < best:
                q, phi, best = trial, phi_t, np.abs(phi_t).max()
                break
        else:
            break
    if best <= 1e3 * ASSEMBLY_TOL:
        return q
    worst = int(np.argmax(np.abs(phi)))
    raise AssemblyError(f"scene '{system.scene.name}': the loops do not close from the given q: "
                        f"residual {phi[worst]:.3g} (m or rad) in row '{cons.row_names[worst]}' "
                        "after Newton; check the frames, the link lengths or the starting guess",
                        phi, cons.row_names)


def projection(jac_rows: np.ndarray, part: Partition, basis: str = "partitioned") -> np.ndarray:
    """R (nv x f) with Phi_q R = 0.

    ``"partitioned"``: R = [I on z; -Phi_d^-1 Phi_z on the dependent coordinates], so the
    reduced coordinates are the independent joints themselves. ``"orthonormal"``: an orthonormal
    basis of the nullspace (from the SVD), best conditioned, coordinates without a joint name.
    """
    nv = jac_rows.shape[1]
    z, d = part.independent, part.dependent
    if basis == "orthonormal":
        if jac_rows.shape[0] == 0:
            return np.eye(nv)
        return sla.null_space(jac_rows, rcond=RANK_TOL)
    R = np.zeros((nv, len(z)))
    R[z, np.arange(len(z))] = 1.0
    if len(d):
        R[d] = -np.linalg.solve(jac_rows[:, d], jac_rows[:, z])
    return R
