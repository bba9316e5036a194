"""Why a mass matrix is singular: the coordinate that carries no inertia, or the motion that
meets none and the bodies it moves, for :meth:`pinlin.System.mass_inverse`'s refusal."""

from __future__ import annotations

from typing import NoReturn

import numpy as np
import pinocchio as pin

from .conditioning import refuse_condition, scaled_condition, singular_to_working_precision
from .exceptions import ModelError


def raise_singular(system, q: np.ndarray, liftable: bool) -> NoReturn:
    """A :class:`ModelError` that says why M(q) is singular: the coordinate whose row of M
    is zero, or else the motion (eigenvector of M's smallest eigenvalue) that meets no
    inertia and the bodies it moves; ``liftable``: M^-1 is finite, so
    ``allow_ill_conditioned`` would give a model (the message offers it)."""
    M = system.mass_matrix(q)
    where = f"scene '{system.scene.name}': the mass matrix is singular at q0: "
    zero = np.flatnonzero(~(np.abs(M).max(axis=1) > 0.0))  # NaN counts as zero
    if zero.size:
        bad = int(zero[0])
        more = ""
        if zero.size > 1:
            others = [system.coordinate_names[i] for i in zero[1:4]]
            k = zero.size - 1
            more = (f", nor {'does' if k == 1 else 'do'} {k} other coordinate"
                    f"{'' if k == 1 else 's'} ({', '.join(others)}"
                    f"{', ...' if zero.size > 4 else ''})")
        raise ModelError(f"{where}coordinate '{system.coordinate_names[bad]}' carries no "
                         f"inertia (row {bad} of M is zero){more}; give the bodies it moves "
                         "mass or armature")
    scaled = scaled_condition(M)
    condition = f"{scaled:.1e}" if np.isfinite(scaled) else "infinite"
    precision = "singular to working precision" if liftable else "singular"
    w, V = np.linalg.eigh(M)
    mode = V[:, 0] / V[np.argmax(np.abs(V[:, 0])), 0]
    order = np.argsort(-np.abs(mode), kind="stable")
    motion = ", ".join(f"{system.coordinate_names[k]} {mode[k]:+.3g}" for k in order[:4]
                       if abs(mode[k]) >= 0.01)
    bodies, still, rotational = _moved_bodies(system, q, mode)
    one = len(bodies) == 1
    if bodies and still:
        have = (f"{'it has' if one else 'they have'} no rotational inertia" if rotational == 0
                else f"{'its' if one else 'their'} rotational inertia is at most "
                     f"{rotational:.1e} kg*m^2")
        why = (f"it turns {_join(bodies)} about axes through "
               f"{'its centre' if one else 'their centres'} of mass, and {have} about "
               f"{'it' if one else 'them'}")
        fix = "give them rotational inertia (or the joints armature)"
    else:
        why = (f"it moves {_join(bodies) or 'no body'}, whose inertia along it is "
               f"{max(w[0], 0.0) / w[-1]:.0e} of the rest")
        fix = "give the bodies it moves inertia (or the joints armature)"
    lift = (", or pass allow_ill_conditioned=True (--allow-ill-conditioned on the command "
            "line) to linearize anyway") if liftable else ""
    raise ModelError(
        f"scene '{system.scene.name}': the mass matrix is {precision} at q0 (scaled to unit "
        f"diagonal, its condition number is {condition}, at or above 0.1/(n eps) = "
        f"{refuse_condition(system.nv):.1e}: not one digit of its inverse is reliable): the "
        f"motion [{motion}] meets a generalized inertia of {w[0]:.1e} against {w[-1]:.3g} "
        f"for the heaviest motion: {why}; {fix}{lift}")


def _moved_bodies(system, q: np.ndarray, mode: np.ndarray
                  ) -> tuple[list[str], bool, float]:
    """The bodies with mass that velocity ``mode`` (size nv) moves at q, as "'name' (mass kg)",
    heaviest first; whether each turns about its own centre of mass (its centre's speed below
    1e-6 of the fastest body's spatial velocity); and the largest rotational inertia about the
    axis it turns about [kg*m^2]."""
    model = system.model
    data = pin.Data(model)
    pin.forwardKinematics(model, data, q, mode)
    body = {}
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY:
            body.setdefault(frame.parentJoint, frame.name)
    speeds = [np.linalg.norm(data.v[j].vector) for j in range(1, model.njoints)]
    fast = max(speeds, default=0.0)
    moved: list[tuple[float, str]] = []
    still, rotational = True, 0.0
    for j, speed in enumerate(speeds, start=1):
        inertia = model.inertias[j]
        if speed <= 1e-6 * fast or inertia.mass <= 0.0:
            continue
        w, v = data.v[j].angular, data.v[j].linear
        v_com = v + np.cross(w, inertia.lever)
        still &= bool(np.linalg.norm(v_com) <= 1e-6 * fast)
        if w @ w > 0.0:
            rotational = max(rotational, float(w @ inertia.inertia @ w / (w @ w)))
        moved.append((inertia.mass, f"'{body.get(j, model.names[j])}' ({inertia.mass:.3g} kg)"))
    moved.sort(key=lambda item: -item[0])
    return [name for _, name in moved], still, rotational


def _join(items: list[str]) -> str:
    """"a", "a and b", "a, b and c"."""
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1] \
        if items else ""


def checked_inverse(system, q: np.ndarray, M: np.ndarray, Minv: np.ndarray,
                    allow_ill_conditioned: bool = False) -> np.ndarray:
    """Minv = M(q)^-1 as computed, once M (only its upper triangle and diagonal are read) and
    Minv pass :meth:`pinlin.System.mass_inverse`'s checks (see :mod:`pinlin.conditioning`);
    raises as that method says (:func:`raise_singular`)."""
    diag = Minv.diagonal()
    n = diag.size
    if not n:
        return Minv
    # The usual case in one dot product and one min: n sum M_ii Minv_ii = tr(Ms) tr(Ms^-1)
    # >= cond_2(Ms) for M^-1 positive definite, Ms the unit-diagonal scaling of M. A sum
    # that is finite leaves no inf or NaN on the diagonal (an inf term makes it +-inf or
    # NaN); the checks below then take the same branch as this one. (np.vdot: BLAS ddot,
    # which raises no floating-point warning for inf * 0, unlike the matmul ufunc.)
    bound = n * float(np.vdot(M.diagonal(), diag))
    if 0.0 < bound < system._refuse_limit and diag.min() > 0.0:   # False for NaN
        return Minv
    # A coordinate that moves no inertia makes its row of M^-1 inf or NaN, diagonal included
    # (NaN compares False).
    if not (diag.max() < np.inf and diag.min() > -np.inf):
        raise_singular(system, q, liftable=False)
    condition = singular_to_working_precision(np.triu(M) + np.triu(M, 1).T, bound)
    if condition is None and diag.min() <= 0.0:  # M^-1 indefinite although M is not
        condition = float("inf")
    if condition is not None and not allow_ill_conditioned:
        raise_singular(system, q, liftable=True)
    return Minv
