"""Assembly of closed loops: independent constraint rows, the choice of independent
coordinates z, Newton on Phi(q) = 0 with z held, and the velocity projection R (chapter 9.1.1).

Coordinates are velocity (tangent-space) indices throughout; a configuration moves by
``pin.integrate``, so a floating base's six coordinates (body-frame twist, a Lie group) take
part like any joint's: Newton may move them and the partition may make them dependent or
independent (states then named ``q:root_joint[i]``). Redundant rows (a planar loop closed by a
3-D point constraint has one; two point contacts on one rigid body share their distance) are
found by a column-pivoted QR of Phi_q^T and dropped.

Many operating points (a gain schedule sweeping a crank): each new guess is solved by Newton
from that guess, to max |Phi| <= :data:`ASSEMBLY_TOL` (relative to the mechanism's size),
exactly as a single call would; a guess solved before comes back from the
:class:`AssemblyCache` of the constraint set, bit for bit. The small dense solves call LAPACK
directly (:mod:`pinlin.lapack_direct`).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import scipy.linalg as sla
from scipy.linalg import lapack

from .arrays import complement
from .coordinates import characteristic_length, linear_coordinates
from .exceptions import AssemblyError, SceneError
from .lapack_direct import condition_2, lstsq, pivoted_qr

#: Rank threshold relative to the largest pivot of the constraint Jacobian.
RANK_TOL = 1e-9
#: Assembly converges when max |Phi| is below this, relative to the mechanism's size: each
#: position row [m] against its length scale, each rotation row [rad] against 1
#: (:meth:`pinlin.constraints.ConstraintSet.closure_error`); 1e-12 m for a mechanism of 1 m.
ASSEMBLY_TOL = 1e-12
#: Solved assemblies kept per constraint set (:class:`AssemblyCache`).
CACHE_SIZE = 256
#: Relative difference below which two columns of a pivoted QR count as a tie, settled by
#: their order (:func:`tie_break`).
TIE_BREAK = 1e-6


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
            coordinates, in one unit (:func:`in_one_unit`; large near a singular, e.g.
            toggle, position); NaN when the partition was made unchecked (a starting
            guess).
    """

    rows: np.ndarray
    dropped: tuple[str, ...]
    independent: np.ndarray
    dependent: np.ndarray
    chosen: bool
    condition: float


def unit_factors(system) -> tuple[np.ndarray, np.ndarray] | None:
    """(row factors (m,), column factors (nv,)) that put Phi_q in one unit, or None where its
    entries share one already.

    Phi_q mixes units where a mechanism has linear coordinates [m] beside angular ones
    [rad] (a slider, a floating base) or a weld's rotation rows [rad] beside position rows
    [m]: m/rad, m/m, rad/rad and rad/m. A column pivot, a rank decision or a condition number
    of that matrix then depends on the robot's size (a floating base standing on its feet
    chose its own translations as independent coordinates at 256 m, and a 4 mm slider-crank
    reported its dependent block 6e4 times worse conditioned than at 1 m). Rows that are
    angles times L and columns of linear coordinates times L (L the robot's characteristic
    length at the scene's posture, :func:`pinlin.coordinates.characteristic_length`) put every
    entry in m per rad: the choices scale with the robot. One L per scene, at its own
    posture (not at each call's q: the unit stays put while the robot moves), computed once
    in Pinocchio data of its own and shared by the scene's constraint sets however anchored
    (:meth:`pinlin.constraints.ConstraintSet.anchored_at`)."""
    cons = system.constraints
    shared = cons._unit_factors   # one list for the scene's constraint sets
    if not shared:
        rows = cons.linear_rows
        columns = linear_coordinates(system)
        if (rows.all() or not rows.any()) and (columns.all() or not columns.any()):
            shared[:] = [None]
        else:
            length = characteristic_length(system, system.scene_configuration,
                                           own_data=True)[0]
            factors = (np.where(rows, 1.0, length), np.where(columns, length, 1.0))
            for arr in factors:
                arr.setflags(write=False)
            shared[:] = factors
    return None if shared[0] is None else (shared[0], shared[1])


def in_one_unit(system, G: np.ndarray, rows: np.ndarray | None = None,
                columns: np.ndarray | None = None) -> np.ndarray:
    """``G``, the rows ``rows`` (default all) and columns ``columns`` (default all) of Phi_q,
    in one unit (:func:`unit_factors`); ``G`` itself where Phi_q has one already. A stack
    (..., rows, columns) is scaled alike."""
    factors = unit_factors(system)
    if factors is None:
        return G
    r, c = factors
    return G * (r if rows is None else r[rows])[:, None] * (c if columns is None else c[columns])


def independent_rows(jac: np.ndarray, groups: list[tuple[str, str, range]], source
                     ) -> np.ndarray:
    """Rows of ``jac`` that are linearly independent (pivoted QR of jac^T), in order.

    Args:
        jac: The constraint Jacobian (m x nv), in one unit (:func:`in_one_unit`).
        groups: (scene field, description, rows) of each loop and contact
            (:attr:`pinlin.constraints.ConstraintSet.groups`).
        source: The scene file, for messages.

    Raises:
        SceneError: a loop or contact contributes no independent row at all.
    """
    if jac.shape[0] == 0:
        return np.zeros(0, dtype=int)
    diag, piv = pivoted_qr(jac.T * tie_break(jac.shape[0]))
    scale = diag[0] if diag.size else 0.0
    floor = RANK_TOL * max(scale, 1e-300)     # |entries| below it count as zero
    rank = int(np.count_nonzero(diag > floor))
    keep = np.sort(piv[:rank])
    kept = set(keep.tolist())
    for fld, what, own in groups:
        if not kept.intersection(own):
            why = ("its frames cannot move (a contact) or move relative to each other (a "
                   "loop) at this configuration: its rows of the constraint Jacobian are "
                   "zero" if not np.abs(jac[list(own)]).max(initial=0.0) > floor
                   else "every row repeats others")
            raise SceneError(source, fld, f"{what} adds no independent constraint: {why}")
    return keep


def partition(system, q: np.ndarray, jac: np.ndarray | None = None, check: bool = True
              ) -> Partition:
    """Independent rows and coordinates at ``q`` (the scene's ``independent`` or a choice).

    pinlin's choice: dependent coordinates are the pivots of a column-pivoted QR of the
    independent rows of Phi_q in one unit (:func:`in_one_unit`), its columns weighted by
    :func:`preference`: unactuated coordinates are preferred as dependent, so that actuated
    joints stay independent where the mechanism allows (a standing robot's floating base is
    dependent, its states are joints). Rows, pivots and the condition number are those of
    Phi_q in one unit: the same for the robot at any size.

    Raises:
        SceneError: the scene's ``independent`` list has the wrong size, names an unknown joint,
            or its coordinates cannot parametrize the mechanism at ``q`` (Phi_d singular;
            checked when ``check``, i.e. at an assembled configuration).
    """
    cons = system.constraints
    src = system.scene.source
    jac = cons.jacobian(q) if jac is None else jac
    scaled = in_one_unit(system, jac)   # the choices and the condition, in one unit
    rows = independent_rows(scaled, cons.groups, src)
    kept = set(rows.tolist())
    dropped = tuple(n for k, n in enumerate(cons.row_names) if k not in kept)
    G = scaled[rows]
    nv, m = system.nv, len(rows)
    names = system.scene.operating_point.independent
    if names:
        independent, dependent = named_independent(system)
        if len(independent) != nv - m:
            raise SceneError(src, "operating_point.independent",
                             f"expected {nv - m} coordinates (the mechanism has {nv} "
                             f"coordinates and {m} independent constraints), got "
                             f"{len(independent)}")
        chosen = False
    elif m == 0:
        independent, chosen = np.arange(nv), False
        dependent = complement(nv, independent)
    else:
        independent, chosen = choose_independent(system, G), True
        dependent = complement(nv, independent)
    if not check:
        return Partition(rows, dropped, independent, dependent, chosen, float("nan"))
    cond = condition_2(G[:, dependent]) if m else 1.0
    if not np.isfinite(cond) or cond > 1e12:
        names_z = ", ".join(system.coordinate_names[i] for i in independent)
        raise SceneError(src, "operating_point.independent",
                         f"coordinates [{names_z}] cannot parametrize the mechanism at this "
                         f"configuration (the Jacobian of the others is singular, condition "
                         f"{cond:.3g}); name other independent joints or move q")
    return Partition(rows, dropped, independent, dependent, chosen, cond)


def choose_independent(system, G: np.ndarray) -> np.ndarray:
    """pinlin's independent coordinates (ascending velocity indices) for the independent rows
    ``G`` of Phi_q in one unit (:func:`in_one_unit`): the columns a pivoted QR of G weighted
    by :func:`preference` does not take as dependent (its first len(G) pivots)."""
    return np.sort(pivoted_qr(G * preference(system))[1][G.shape[0]:])


def preference(system) -> np.ndarray:
    """Column weights (nv,) [-] of the partition's pivoted QR, which takes the heaviest
    columns of Phi_q (in one unit, :func:`in_one_unit`) as dependent: a floating base's or
    a slider's unactuated translations 1e3, other unactuated coordinates 1, actuated ones
    1e-3. Actuated joints stay independent where the mechanism allows (a standing robot's
    states are its joints), and of a floating base the contacts fix the position first (a
    box balanced on a point keeps its three rotations as states). Pure numbers, so the
    choice does not depend on the robot's size; ties go to the earlier coordinate
    (:func:`tie_break`), so it does not depend on the machine either."""
    weight = np.where(linear_coordinates(system), 1e3, 1.0)
    weight[system.actuated] = 1e-3
    return weight * tie_break(system.nv)


def tie_break(n: int) -> np.ndarray:
    """Weights 1 + TIE_BREAK (n - i) / n (n,) that settle a pivoted QR's ties in favour of the
    earlier column: a symmetric robot's legs have columns of equal norm, and rounding (another
    CPU's, another BLAS's) would pick among them, so its states would change from machine to
    machine (solo12 standing: 14 choices under relative perturbations of 1e-15). Columns
    within TIE_BREAK of each other are then taken in order; LAPACK's downdated column norms
    are accurate to about sqrt(eps) (1.5e-8), well inside it."""
    return 1.0 + TIE_BREAK * np.arange(n, 0, -1) / max(n, 1)


def named_independent(system) -> tuple[np.ndarray, np.ndarray]:
    """(z, dependent) velocity indices of the scene's ``operating_point.independent`` joints,
    resolved once per constraint set (a fixed property of the scene).

    Raises:
        UnknownNameError: a name is not a joint of the robot.
    """
    cons = system.constraints
    cached = getattr(cons, "_named_independent", None)
    if cached is None:
        z: list[int] = []
        for name in system.scene.operating_point.independent:
            j = system.joint(name, "operating_point.independent")
            z.extend(range(j.idx_v, j.idx_v + j.nv))
        independent = np.array(sorted(z), dtype=int)
        cached = (independent, complement(system.nv, independent))
        for arr in cached:
            arr.setflags(write=False)
        cons._named_independent = cached
    return cached


class AssemblyCache:
    """Assemblies already solved for one constraint set: (guess, z indices) -> (q0, Phi_q(q0)).

    Newton from a given guess is deterministic, so a guess seen before gets back bit for bit
    what solving again would give: a gain schedule or a repeated ``linearize`` that comes back
    to a configuration skips the assembly, and nothing else changes. A guess not seen before
    is solved from that guess: starting from a nearby solved point instead could land on
    another assembly branch than the guess picks (tests/test_loop_cache.py shows one) and the
    model would depend on the call history.

    Held by the :class:`~pinlin.constraints.ConstraintSet` (one per system and contact
    anchoring, so no entry crosses scenes or anchors), shared by threads (a lock guards the
    table; the arrays are read-only), at most :data:`CACHE_SIZE` entries, least recently used
    dropped first.
    """

    def __init__(self, size: int = CACHE_SIZE) -> None:
        self.size = size
        self._table: OrderedDict[bytes, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self._lock = threading.Lock()
        self.hits = self.misses = 0

    @staticmethod
    def key(q_guess: np.ndarray, independent: np.ndarray) -> bytes:
        return np.ascontiguousarray(q_guess, dtype=float).tobytes() + b"|" + \
            np.ascontiguousarray(independent, dtype=np.int64).tobytes()

    def get(self, key: bytes) -> tuple[np.ndarray, np.ndarray] | None:
        with self._lock:
            found = self._table.get(key)
            if found is None:
                self.misses += 1
                return None
            self._table.move_to_end(key)
            self.hits += 1
            return found

    def put(self, key: bytes, q0: np.ndarray, jac: np.ndarray) -> None:
        q0, jac = q0.copy(), jac.copy()
        q0.setflags(write=False)
        jac.setflags(write=False)
        with self._lock:
            self._table[key] = (q0, jac)
            self._table.move_to_end(key)
            while len(self._table) > self.size:
                self._table.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._table.clear()
            self.hits = self.misses = 0


def assembly_cache(system) -> AssemblyCache:
    """The :class:`AssemblyCache` of the system's constraint set, made on first use."""
    cons = system.constraints
    cache = getattr(cons, "_assembly_cache", None)
    if cache is None:
        with _CACHE_LOCK:
            cache = getattr(cons, "_assembly_cache", None)
            if cache is None:
                cache = cons._assembly_cache = AssemblyCache()
    return cache


_CACHE_LOCK = threading.Lock()


def assemble(system, q_guess: np.ndarray, independent: np.ndarray, *, max_iter: int = 50
             ) -> np.ndarray:
    """Close the loops from ``q_guess`` by Newton on the dependent coordinates, z held.

    Raises:
        AssemblyError: no convergence; the message gives the residual and the worst row.
    """
    return assemble_with_jacobian(system, q_guess, independent, max_iter=max_iter,
                                  cache=False)[0]


def assemble_with_jacobian(system, q_guess: np.ndarray, independent: np.ndarray, *,
                           max_iter: int = 50, cache: bool = True,
                           start: tuple[np.ndarray, np.ndarray] | None = None
                           ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`assemble`, with Phi_q at the assembled q0 (m x nv) from the same kinematics
    pass; ``cache``: look the guess up in (and add it to) the :class:`AssemblyCache`;
    ``start``: (Phi, Phi_q) at ``q_guess`` when the caller has them.

    Raises:
        AssemblyError: no convergence; the message gives the residual and the worst row.
    """
    store = assembly_cache(system) if cache else None
    if store is not None:
        key = store.key(q_guess, independent) + max_iter.to_bytes(4, "little")
        found = store.get(key)
        if found is not None:
            return found[0].copy(), found[1].copy()
    q, jac = _newton(system, q_guess, independent, max_iter, start)
    q, jac = _unwound(system, q, q_guess, jac)
    if store is not None:
        store.put(key, q, jac)
    return q, jac


def _unwound(system, q: np.ndarray, q_guess: np.ndarray, jac: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """(q, Phi_q(q)) with each revolute angle (1-DoF rotation stored as an angle) moved by
    whole turns to lie within pi of its guess. Newton from a guess near a singular position
    jumps far (Phi_d nearly singular): the five-bar assembled from guesses within +-pi at
    angles of up to 468 rad, closed but wound 74 turns from the guess. Whole turns change no
    position (only the angle's rounding, ~|q| eps); an angle within pi of its guess is left
    as it is, bit for bit."""
    if not float(np.abs(q - q_guess).max(initial=0.0)) > math.pi:
        return q, jac
    out = q.copy()
    for joint in system.joints.values():
        if joint.nq == 1 and joint.nv == 1 and joint.kind.startswith("JointModelR") \
                and not joint.kind.startswith("JointModelRUB"):
            i = joint.idx_q
            out[i] -= 2.0 * math.pi * round((out[i] - q_guess[i]) / (2.0 * math.pi))
    if np.array_equal(out, q):
        return q, jac
    return out, system.constraints.residual_and_jacobian(out)[1]


def assemble_guess(system, q_guess: np.ndarray, *, cache: bool = True,
                   start: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray, Partition | None]:
    """:func:`assemble_with_jacobian` with the scene's independent coordinates, or pinlin's
    choice at the guess when the scene names none: (q0, Phi_q(q0), the guess's unchecked
    partition, or None where the scene names z and no partition of the guess is needed).
    ``start``: (Phi, Phi_q) at ``q_guess`` when the caller has them.

    Raises:
        SceneError: the scene names a list of the wrong size (the guess's partition says so
            rather than Newton's failure).
        AssemblyError: no convergence.
    """
    if start is None:
        start = system.constraints.residual_and_jacobian(q_guess)
    if system.scene.operating_point.independent:
        try:
            q0, jac = assemble_with_jacobian(system, q_guess, named_independent(system)[0],
                                             cache=cache, start=start)
        except AssemblyError:
            partition(system, q_guess, start[1], check=False)
            raise
        return q0, jac, None
    part = partition(system, q_guess, start[1], check=False)  # conditioning: once assembled
    q0, jac = assemble_with_jacobian(system, q_guess, part.independent, cache=cache,
                                     start=start)
    return q0, jac, part


def cached_assembly(system, q_guess: np.ndarray, independent: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray] | None:
    """(q0, Phi_q(q0)) of a guess solved before with these z indices (fresh copies), else
    None (:class:`AssemblyCache`)."""
    store = assembly_cache(system)
    found = store.get(store.key(q_guess, independent) + (50).to_bytes(4, "little"))
    return None if found is None else (found[0].copy(), found[1].copy())


def _newton(system, q_guess: np.ndarray, independent: np.ndarray, max_iter: int,
            start: tuple[np.ndarray, np.ndarray] | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """Newton with backtracking on Phi(q) = 0 over the dependent coordinates: (q0, Phi_q(q0))."""
    cons = system.constraints
    model = system.model
    q = np.array(q_guess, dtype=float)
    dependent = complement(system.nv, independent)
    phi, jac = cons.residual_and_jacobian(q) if start is None else start
    best = cons.closure_error(phi)
    dq = np.zeros(system.nv)
    for _ in range(max_iter):
        if best <= ASSEMBLY_TOL:
            return q, jac
        dq[dependent] = lstsq(jac.take(dependent, axis=1), -phi)
        # Backtracking keeps Newton from leaving the basin of the branch the guess picked.
        for scale in (1.0, 0.5, 0.25, 0.125, 0.0625):
            trial = pin.integrate(model, q, scale * dq)
            phi_t, jac_t = cons.residual_and_jacobian(trial)
            worst_t = cons.closure_error(phi_t)
            if worst_t < best:
                q, phi, jac, best = trial, phi_t, jac_t, worst_t
                break
        else:
            break
    if best <= 1e3 * ASSEMBLY_TOL:
        return q, jac
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
        _, _, x, info = lapack.dgesv(jac_rows[:, d], jac_rows[:, z])  # np.linalg.solve's
        if info != 0:
            raise np.linalg.LinAlgError("Singular matrix")
        R[d] = -x
    return R
