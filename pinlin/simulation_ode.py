"""The scene's equations of motion as first-order ODEs in vector-space coordinates, for
:func:`pinlin.simulate`::

    M(q) v' + b(q, v) = S u + tau_spring(q) - D v  (- Phi_q^T lam with constraints)

with exactly the scene's effects (gravity, springs, viscous damping, armature in M, steady
rotation through :meth:`pinlin.System.rnea`, loops, contacts held at their anchors and
mimic couplings; no joint limits, friction, or contacts that lift off or slip). Each class
offers ``initial_state(dx0)``, ``rhs(t, s, u)``, ``state(s) -> (q, v)`` and
``after_step(s)``, which returns a state in new coordinates (and why) when the integrator must
restart in them.

:class:`OpenChain` (floating bases included). Runge-Kutta stages add states linearly, which
is only valid in a vector space, so the state is s = (dq, v) in a chart
q = ``pin.integrate(q_ref, dq)``, with d(dq)/dt = J(dq) v, J = ``pin.dDifference(q_ref, q,
ARG1)`` (the inverse right Jacobian of the exponential map on Lie-group joints, the identity
on the others). The chart is exact for rotation angles below pi; after an accepted step where
an angle of the chart (free flyer, spherical, planar or continuous joint) exceeds
:data:`CHART_LIMIT`, it is re-centred (q_ref := q, dq := 0). q stays on the manifold (unit
quaternions) by construction; ``q + dq`` is never formed.

:class:`Mechanism` (loops, contacts, mimic couplings; standing robots, welds included). The
state is s = (c_z, v_z): c = ``pin.difference(q_ref, q)`` is the chart of :class:`OpenChain`
and z the independent coordinates (the partition of :func:`pinlin.assembly.partition` at
q0, any joints, a floating base's too); v_z their velocities. Each evaluation closes the
loops by Newton on the dependent chart coordinates c_d with c_z held (d Phi / d c =
Phi_q ``pin.dIntegrate(q_ref, c, ARG1)``; warm-started from the last configuration with the
first-order predictor R dc_z, iterated to rounding level), sets v = R(q) v_z with R the
partitioned nullspace basis (G R = 0, G the independent rows of Phi_q) and solves the KKT
system of :mod:`pinlin.formulations.motion`, M a - G^T lam = tau - b, G a = -Phi_qq[v, v],
for v_z' = a[z]; c_z' = (J(c) v)[z] as for open chains. The motion stays on the constraint
manifold by construction, with no Baumgarte terms and no projection to tune: |Phi(q)| is
Newton's rounding level and |Phi_q v| the rounding of R at every state, whatever the
horizon. The chart is re-centred as for open chains (with 1-DoF joints only it is additive
and never is); where the dependent block of G becomes ill-conditioned (near a singular
position of z; :data:`PARTITION_RATIO` times worse than a fresh choice) z is re-chosen
(pivoted QR) after the step.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import scipy.linalg as sla

from .arrays import complement
from .assembly import choose_independent, in_one_unit, partition
from .coordinates import FREE_FLYER, SPHERICAL, linear_coordinates
from .exceptions import ModelError, ShapeError
from .operating_point import OperatingPoint
from .system import System

#: Largest rotation angle of the chart before it is re-centred [rad] (the log map is exact
#: below pi; its Jacobian's condition grows like 1 / sin(angle / 2) near pi).
CHART_LIMIT = 1.0
#: z is re-chosen when its dependent block of Phi_q is this many times worse conditioned than
#: a fresh choice's.
PARTITION_RATIO = 10.0
#: Newton iterations allowed to close the loops at one state.
NEWTON_ITERATIONS = 30
#: Newton stops once max |Phi_i| / row scale_i is below this (each position row against the
#: mechanism's size L, :attr:`pinlin.constraints.ConstraintSet.row_scale`; rounding: ~eps).
#: An absolute 1e-14 m asked a 15 um four-bar for 1e-9 of its size: 50x the steps, and its
#: motion off by 1e-7 (the stall test below fired instead).
NEWTON_TOLERANCE = 1e-14
#: Newton also stops where a step no longer shrinks the residual, once it is below this, and
#: the loops count as closed below :data:`NEWTON_FAIL` (both relative, as NEWTON_TOLERANCE).
NEWTON_STALL = 1e-10
NEWTON_FAIL = 1e-9
PLANAR = "JointModelPlanar"
#: (where, why) of a failure to close the loops, for the messages of :class:`Mechanism`.
_ALONG = ("along the motion", "the mechanism reached a singular position")
_AT_START = ("at the initial state", "dx0 moves the independent coordinates where the "
             "dependent ones cannot follow (a configuration the loops or contacts cannot reach)")


def chart_angles(system: System) -> list[np.ndarray]:
    """Per Lie-group joint, the chart coordinates that are rotation angles (a free flyer's or
    spherical joint's three, a planar joint's or continuous joint's one) [indices into v]."""
    angles = []
    for j in system.joints.values():
        first = {FREE_FLYER: 3, SPHERICAL: 0, PLANAR: 2}.get(j.kind)
        if first is not None:
            size = 3 if j.kind in (FREE_FLYER, SPHERICAL) else 1
            angles.append(np.arange(j.idx_v + first, j.idx_v + first + size))
        elif j.nq != j.nv:
            angles.append(np.arange(j.idx_v, j.idx_v + j.nv))
    return angles


def beyond_chart(c: np.ndarray, angles: list[np.ndarray]) -> bool:
    """Whether a rotation angle of the chart coordinates ``c`` (:func:`chart_angles`) exceeds
    :data:`CHART_LIMIT`: the chart is re-centred after such a step."""
    return any(np.linalg.norm(c[i]) > CHART_LIMIT for i in angles)


def chart_rate(model: pin.Model, q_ref: np.ndarray, q: np.ndarray, v: np.ndarray,
               lie: bool) -> np.ndarray:
    """d/dt of the chart coordinates c = difference(q_ref, q): ``pin.dDifference(q_ref, q,
    ARG1) v`` (v itself when every joint is a vector space, ``lie`` False)."""
    return pin.dDifference(model, q_ref, q, pin.ArgumentPosition.ARG1) @ v if lie else v


def continuous_angles(system: System) -> np.ndarray:
    """Velocity indices of the continuous joints (an unbounded 1-DoF rotation stored as cos
    and sin, nq = 2: Pinocchio's JointModelRUBX/Y/Z, or RevoluteUnboundedUnaligned for any
    other axis), whose difference from q0 wraps at pi. (A planar joint's angle wraps too,
    through the SE(2) log; its translation, taken with it, is not additive over re-centrings:
    it stays in the log map, as a free flyer's and a spherical joint's rotations do.)"""
    return np.array([j.idx_v for j in system.joints.values() if j.nv == 1 and j.nq == 2],
                    dtype=int)


def spring_wraps(system: System, q0: np.ndarray, X: np.ndarray, t: np.ndarray) -> list[str]:
    """Notes on the springs of continuous joints whose deflection q - rest passed +-pi in the
    simulated states ``X`` (angles from ``q0`` in turns, :func:`continuous_angles`) at times
    ``t`` [s]: such a spring acts on difference(rest, q), wrapped to (-pi, pi] (the joint's
    configuration has no winding count, :meth:`pinlin.System.spring_torque`), so its force
    reverses there."""
    turning = continuous_angles(system)
    turning = turning[system.stiffness[turning] != 0.0]
    if not turning.size:
        return []
    deflection = pin.difference(system.model, system.q_rest, q0)[turning] + X[:, turning]
    notes = []
    for column, i in enumerate(turning):
        beyond = np.flatnonzero(np.abs(deflection[:, column]) > np.pi)
        if beyond.size:
            k = int(beyond[0])
            notes.append(f"the spring on continuous joint '{system.coordinate_names[i]}' "
                         f"passed its wrap: q - rest = {deflection[k, column]:.4g} rad at "
                         f"t = {t[k]:.4g} s, beyond pi, where the spring (acting on q - rest "
                         "wrapped to (-pi, pi]) reverses its force; make the joint revolute "
                         "for a wound spring")
    return notes


class OpenChain:
    """s = (dq, v) in the chart about q_ref (module docstring)."""

    def __init__(self, system: System, op: OperatingPoint) -> None:
        self.system, self.model, self.op = system, system.model, op
        self.nv = system.nv
        self.q_ref = op.q.copy()
        self.centred = True   # q_ref is q0
        self.lie = system.nq != system.nv
        self.angles = chart_angles(system)
        self.offset = np.zeros(self.nv)   # chart displacements summed over re-centrings

    def initial_state(self, dx0: np.ndarray) -> tuple[np.ndarray, list[str]]:
        if dx0.size != 2 * self.nv:
            raise ShapeError(f"dx0 must have 2 nv = {2 * self.nv} entries, got {dx0.size}")
        dq = dx0[:self.nv]
        self.centred = not beyond_chart(dq, self.angles)
        self.offset = np.zeros(self.nv)
        if self.centred:   # at q0: x = dq exactly, resolved relative to itself near q0
            self.q_ref = self.op.q.copy()
        else:              # a rotation beyond the chart: centred at q
            self.q_ref = pin.integrate(self.model, self.op.q, dq)
            self.offset = dq.copy()
            dq = np.zeros(self.nv)
        return np.concatenate([dq, self.op.v + dx0[self.nv:]]), []

    def model_state(self, s: np.ndarray) -> np.ndarray:
        """x = [difference(q0, q); v - v0] at chart state ``s`` (what a feedback reads). While
        the chart is centred at q0 (always, with 1-DoF joints only) it is dq itself, exactly
        (difference(q0, integrate(q0, dq)) = dq for rotations below pi): as smooth in s as s
        is, where forming q = q0 + dq first would round at eps |q| (noise that a high gain
        amplifies into the right-hand side). After a re-centring it is computed through q.
        A rotation of more than pi from q0 wraps (the log map), a continuous joint's too
        (:attr:`pinlin.Simulation.x` follows that one in turns, :meth:`travelled`)."""
        nv = self.nv
        if self.centred:
            dq = s[:nv].copy()
        else:
            dq = pin.difference(self.model, self.op.q, pin.integrate(self.model, self.q_ref,
                                                                     s[:nv]))
        return np.concatenate([dq, s[nv:] - self.op.v])

    def rhs(self, t: float, s: np.ndarray, u: np.ndarray) -> np.ndarray:
        system, nv = self.system, self.nv
        dq, v = s[:nv], s[nv:]
        q = pin.integrate(self.model, self.q_ref, dq)
        tau = system.applied_force(q, v, u)
        if system.rotation is None:
            a = pin.aba(self.model, system.data, q, v, tau)
        else:
            a = sla.solve(system.mass_matrix(q), tau - system.rnea(q, v, np.zeros(nv)),
                          assume_a="pos")
        return np.concatenate([chart_rate(self.model, self.q_ref, q, v, self.lie), a])

    def state(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return pin.integrate(self.model, self.q_ref, s[:self.nv]), s[self.nv:].copy()

    def travelled(self, s: np.ndarray) -> np.ndarray:
        """The chart coordinates at ``s`` plus their values at every earlier re-centring (nv):
        a 1-DoF joint's whole change from q0, a continuous joint's angle counted in turns
        (difference(q0, q) wraps it at pi)."""
        return self.offset + s[:self.nv]

    def linear_state(self) -> np.ndarray:
        """Which entries of s are lengths [m] and linear velocities [m/s] (the others are
        angles [rad] and rates [rad/s])."""
        linear = linear_coordinates(self.system)
        return np.concatenate([linear, linear])

    def after_step(self, s: np.ndarray) -> tuple[np.ndarray, str] | None:
        """A re-centred state when the chart's angles exceed CHART_LIMIT, else None."""
        if not beyond_chart(s, self.angles):
            return None
        self.offset = self.offset + s[:self.nv]
        self.q_ref = pin.integrate(self.model, self.q_ref, s[:self.nv])
        self.centred = False
        return np.concatenate([np.zeros(self.nv), s[self.nv:]]), "chart"


class Mechanism:
    """s = (c_z, v_z): independent chart coordinates and velocities; q(c_z) closed by Newton
    (module docstring)."""

    def __init__(self, system: System, op: OperatingPoint) -> None:
        self.system, self.model, self.op = system, system.model, op
        self.cons, self.nv = system.constraints, system.nv
        self.q_ref = op.q.copy()
        self.centred = True   # q_ref is q0
        self.lie = system.nq != system.nv
        self.angles = chart_angles(system)
        jac = self.cons.jacobian(op.q)
        part = partition(system, op.q, jac)
        self.rows, self.dropped = part.rows, part.dropped
        self.row_scale = self.cons.row_scale[part.rows]
        m = len(part.rows)
        self._kkt = np.zeros((self.nv + m, self.nv + m))  # [[M, -G^T], [G, 0]], refilled
        self._use(part.independent)
        self.columns = part.independent  # of z in x, fixed at q0
        self.cache: tuple[np.ndarray, ...] = ()
        self._where = _ALONG  # (where, why) for error messages
        self.offset = np.zeros(self.nv)   # chart displacements summed over re-centrings

    def _use(self, independent: np.ndarray) -> None:
        self.z, self.d = np.asarray(independent), complement(self.nv, independent)

    def initial_state(self, dx0: np.ndarray) -> tuple[np.ndarray, list[str]]:
        nv, nz = self.nv, self.z.size
        if dx0.size == 2 * nz and nz != nv:
            dz, dzdot = dx0[:nz], dx0[nz:]
        elif dx0.size == 2 * nv:
            dz, dzdot = dx0[:nv][self.z], dx0[nv:][self.z]
        else:
            raise ShapeError(f"dx0 must have 2 nv = {2 * nv} entries (all coordinates) or 2 nz "
                             f"= {2 * nz} (the independent ones), got {dx0.size}")
        self.q_ref = self.op.q.copy()
        self.offset = np.zeros(nv)
        self.centred = True   # q_ref = q0: the chart coordinates c are x's positions
        G = self.cons.jacobian(self.op.q)[self.rows]
        self.cache = (np.zeros(nz), np.zeros(nv), self.op.q, G, self._basis(G))
        s = np.concatenate([dz, self.op.v[self.z] + dzdot])
        self._where = _AT_START
        q, v = self.state(s)
        self._where = _ALONG
        if self.lie:  # the chart starts at q: dDifference's log map wraps angles beyond pi
            G, R = self.cache[3:]       # q's, from self.state(s)
            s = self._recentre(q, G, R, v)
        notes = []
        if dx0.size == 2 * nv and np.any(dx0):
            dq = pin.difference(self.model, pin.integrate(self.model, self.op.q, dx0[:nv]), q)
            dv = v - self.op.v - dx0[nv:]
            notes.append(f"dx0 given in all coordinates: its independent part kept, the loops "
                         f"closed (|dq| changed by {np.linalg.norm(dq):.3g}) and v = R z' "
                         f"(|dv| changed by {np.linalg.norm(dv):.3g})")
        return s, notes

    def _configure(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, G, R) at chart state s: Newton on the dependent chart coordinates c_d, c_z held,
        from the last configuration and its first-order predictor."""
        cz = s[:self.z.size]
        cz_c, c, q, G, R = self.cache
        if np.array_equal(cz, cz_c):
            return q, G, R
        cons, rows, model, d = self.cons, self.rows, self.model, self.d
        c = c.copy()
        c[d] += (R @ (cz - cz_c))[d]
        c[self.z] = cz
        previous = np.inf
        for _ in range(NEWTON_ITERATIONS):
            q = pin.integrate(model, self.q_ref, c)
            phi, G = cons.residual_and_jacobian(q)
            phi, G = phi[rows], G[rows]
            best = float((np.abs(phi) / self.row_scale).max(initial=0.0))
            # Converged at rounding level, or a step no longer shrinks the residual.
            if best <= NEWTON_TOLERANCE or (best < NEWTON_STALL and best > 0.25 * previous):
                break
            previous = best
            # d Phi / d c: G times d q / d c of the chart q = integrate(q_ref, c).
            jac = G @ pin.dIntegrate(model, self.q_ref, c, pin.ArgumentPosition.ARG1) \
                if self.lie else G
            try:
                c[d] -= np.linalg.solve(jac[:, d], phi)
            except np.linalg.LinAlgError:
                break
            if not np.all(np.isfinite(c)):
                break
        if not best < NEWTON_FAIL:
            raise ModelError(f"scene '{self.system.scene.name}': the loops do not close "
                             f"{self._where[0]} (residual "
                             f"{float(np.abs(phi).max(initial=0.0)):.3g} m or rad after Newton): "
                             f"{self._where[1]}")
        R = self._basis(G)
        self.cache = (cz.copy(), c, q, G, R)
        return q, G, R

    def _recentre(self, q: np.ndarray, G: np.ndarray, R: np.ndarray, v: np.ndarray
                  ) -> np.ndarray:
        """Centre the chart at the configuration q (q_ref := q, c := 0; G and R are q's, and
        the cache holds q's c) and return the state there, (0, v[z])."""
        self.offset = self.offset + self.cache[1]
        self.q_ref = q.copy()
        self.centred = False
        self.cache = (np.zeros(self.z.size), np.zeros(self.nv), q, G, R)
        return np.concatenate([np.zeros(self.z.size), v[self.z]])

    def _basis(self, G: np.ndarray) -> np.ndarray:
        """Partitioned nullspace basis R (nv x nz): R[z] = I, G R = 0."""
        R = np.zeros((self.nv, self.z.size))
        R[self.z, np.arange(self.z.size)] = 1.0
        if self.d.size:
            try:
                R[self.d] = -np.linalg.solve(G[:, self.d], G[:, self.z])
            except np.linalg.LinAlgError:
                raise ModelError(f"scene '{self.system.scene.name}': the constraints' Jacobian "
                                 f"is singular {self._where[0]}: {self._where[1]}") from None
        return R

    def state(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q, _, R = self._configure(s)
        return q, R @ s[self.z.size:]

    def linear_state(self) -> np.ndarray:
        """Which entries of s (the current independent coordinates and their rates) are
        lengths [m] and linear velocities [m/s]."""
        linear = linear_coordinates(self.system)[self.z]
        return np.concatenate([linear, linear])

    def travelled(self, s: np.ndarray) -> np.ndarray:
        """:meth:`OpenChain.travelled`: the chart coordinates c at ``s`` (all nv) plus their
        values at every earlier re-centring."""
        self._configure(s)
        return self.offset + self.cache[1]

    def model_state(self, s: np.ndarray) -> np.ndarray:
        """x = [difference(q0, q); v - v0] at state ``s`` (all nv coordinates; what a feedback
        reads): the chart coordinates c themselves while the chart is centred at q0 (always
        with 1-DoF joints only), else through q, as :meth:`OpenChain.model_state`."""
        q, _, R = self._configure(s)
        v = R @ s[self.z.size:]
        dq = self.cache[1].copy() if self.centred else \
            pin.difference(self.model, self.op.q, q)
        return np.concatenate([dq, v - self.op.v])

    def rhs(self, t: float, s: np.ndarray, u: np.ndarray) -> np.ndarray:
        system, nv = self.system, self.nv
        q, G, R = self._configure(s)
        v = R @ s[self.z.size:]
        rhs = np.concatenate([system.applied_force(q, v, u) - system.rnea(q, v, np.zeros(nv)),
                              -self.cons.bias_acceleration(q, v)[self.rows]])
        kkt = self._kkt
        kkt[:nv, :nv] = system.mass_matrix(q)
        kkt[:nv, nv:] = -G.T
        kkt[nv:, :nv] = G
        try:
            a = np.linalg.solve(kkt, rhs)[:nv]
        except np.linalg.LinAlgError:
            raise ModelError(f"scene '{self.system.scene.name}': the equations of motion are "
                             f"singular {self._where[0]} (M singular on the constraints' "
                             "nullspace)") from None
        cdot = chart_rate(self.model, self.q_ref, q, v, self.lie)
        return np.concatenate([cdot[self.z], a[self.z]])

    def after_step(self, s: np.ndarray) -> tuple[np.ndarray, str] | None:
        """A state in new coordinates, else None: the chart re-centred (q_ref := q) where an
        angle of it exceeds CHART_LIMIT, as for open chains; new independent coordinates
        where the dependent block of G is PARTITION_RATIO times worse conditioned than that
        of a fresh choice (pivoted QR of G, actuated joints preferred as independent): near a
        singular position of the current z, errors in z are amplified by that condition
        number in the dependent coordinates."""
        q, G, R = self._configure(s)
        v = R @ s[self.z.size:]
        if beyond_chart(self.cache[1], self.angles):
            return self._recentre(q, G, R, v), "chart"
        if not self.d.size:
            return None
        G1 = in_one_unit(self.system, G, self.rows)   # as partition() measures it
        current = np.linalg.cond(G1[:, self.d])
        if current <= PARTITION_RATIO:  # a fresh choice cannot beat it by the ratio
            return None
        independent = choose_independent(self.system, G1)   # partition()'s fresh choice
        if current <= PARTITION_RATIO * np.linalg.cond(G1[:, complement(self.nv, independent)]):
            return None
        self._use(independent)
        c = pin.difference(self.model, self.q_ref, q)
        self.cache = (c[self.z], c, q, G, self._basis(G))
        return np.concatenate([c[self.z], v[self.z]]), "partition"

    def drift(self, q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
        return (float(np.abs(self.cons.residual(q)).max()),
                float(np.abs(self.cons.jacobian(q) @ v).max()))


__all__ = ["CHART_LIMIT", "Mechanism", "OpenChain"]
