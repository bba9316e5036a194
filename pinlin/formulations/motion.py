"""Constrained systems at a moving state: the independent-coordinate model of eqs. 9.8-9.11
with every velocity term.

The state is given (``solve = "none"`` or ``linearize(q=, v=, u=)``). pinlin closes the loops
(:func:`pinlin.assembly.assemble`, z held), projects the given velocity onto the nullspace of
Phi_q (the consistent velocity closest to the one given, in one unit; the size of the
correction is reported), and solves the constrained dynamics there (a KKT system)::

    M a - G^T lam = tau - b,   G a = -gamma,   gamma = Phi_qq[v, v]

for the acceleration a0 and the constraint forces lam0 (G: the independent rows of Phi_q).
With z the independent coordinates (the partitioned basis), the motion is q = q(z),
v = R(q) z', a = q'' and z'' = a[z]. Differentiating the KKT system at (q0, v0, a0, lam0)::

    M da - G^T dlam = -K dq - C dv + S du
    G da            = -c_q dq - c_v dv

with c_q = Phi_qq[a0, .] + d gamma / dq and c_v = 2 Phi_qq[v0, .], which
gives da = F_q dq + F_v dv + F_u du, where K and C are dH/dq and dH/dv at the moving state
(Coriolis, damping, springs, and the geometric stiffness -lam0^T Phi_qq: pinlin's
:func:`~pinlin.derivatives.second_order_terms`). Along the mechanism dq = R dz and
dv = R dz' + W dz, where W dz = (dR/dz dz) z' has W[z] = 0 and G W = -Phi_qq[v0, .] R (from
differentiating G R = 0). Hence, in x = [dz; dz']::

    A = [[0, I], [(F_q R + F_v W)[z], (F_v R)[z]]],   B = [[0], [F_u[z]]],   f0 = [z0'; a0[z]]

At rest (v0 = 0, a0 = 0) c_q = c_v = W = 0 and this is the static model R^T M R, R^T K R.
Where :func:`pinlin.loop_kernels.plan` applies (no steady rotation, point closures moved by
1-DoF joints) every term is analytic, d gamma / dq (a third derivative of the loop closure)
included, and the model is computed by :mod:`pinlin.formulations.moving_batch` (the code a
trajectory runs on its stacks, here with one point). Elsewhere Pinocchio gives every term
analytically except d gamma / dq, taken by five-point central differences of gamma (step
1e-3: truncation ~h^4, rounding ~eps |gamma| / h, about 1e-12 relative). Floating bases
(Lie-group joints) and welds, where Phi_qq is not symmetric, take
:mod:`pinlin.formulations.moving_manifold`. The orthonormal basis and the canonical
formulation at a moving state are not supported yet, nor numerical derivatives for floating
bases and welds, nor the penalty formulation of welds (in the penalty formulation a floating
base's point contacts take both halves of Phi_qq from
:func:`pinlin.formulations.moving_manifold.coordinate_derivatives`).
tests/test_moving_loops.py checks the model against central differences of Pinocchio's own
constrained forward dynamics on the mechanism.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .. import loop_kernels as lk
from ..arrays import read_only
from ..assembly import Partition, assemble_guess, partition, projection, unit_factors
from ..chart import kinematic_block
from ..derivatives import second_order_terms
from ..equilibrium import ConstrainedPoint
from ..exceptions import ModelError
from ..linear_model import LinearModel
from ..operating_point import OperatingPoint, force_scale, residual_tolerance
from . import moving_batch, moving_manifold
from .constrained import (
    SENSITIVITY_CHECK,
    _warn_sensitive,
    constrained_effects,
    sensitivity_across,
)
from .independent import output_matrices

#: Step of the five-point differences of gamma(q) [rad or m].
GAMMA_STEP = 1e-3


def moving_point(system, q_guess: np.ndarray, v0: np.ndarray, u0: np.ndarray
                 ) -> tuple[OperatingPoint, ConstrainedPoint]:
    """The operating point of a constrained system at a given state: q assembled (z held),
    v projected onto the nullspace of Phi_q, (a0, lam0) from the constrained dynamics.

    Raises:
        AssemblyError: the loops cannot be closed from ``q_guess``.
        ModelError: weld loops (not supported at a moving state yet).
    """
    q0, jac, _ = assemble_guess(system, q_guess, cache=False)  # Phi_q from Newton's last pass
    part = partition(system, q0, jac)
    return state_at(system, q0, v0, u0, part, jac)


def project_velocity(G: np.ndarray, v0: np.ndarray, columns: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(v, correction): the projection of ``v0`` [rad/s or m/s] onto the nullspace of G (the
    independent rows of Phi_q), the consistent velocity closest to the one given, and the
    correction v0 - v. Closest in one unit: with ``columns`` the column factors of
    :func:`pinlin.assembly.unit_factors` (a linear coordinate's L, else 1; None: all 1),
    |(v0 - v) / columns| is least, v = v0 - c G_c^T (G_c G_c^T)^-1 G v0 with G_c = G c, so the
    projection of a slider's or a floating base's velocity does not depend on the robot's
    size."""
    if not len(G):
        return v0.copy(), np.zeros_like(v0)
    Gc = G if columns is None else G * columns
    correction = Gc.T @ np.linalg.lstsq(Gc @ Gc.T, G @ v0, rcond=None)[0]
    if columns is not None:
        correction *= columns
    return v0 - correction, correction


def state_at(system, q0: np.ndarray, v0: np.ndarray, u0: np.ndarray, part: Partition,
             jac: np.ndarray) -> tuple[OperatingPoint, ConstrainedPoint]:
    """The operating point at an assembled configuration ``q0`` whose constraint Jacobian is
    ``jac`` (all rows) and partition ``part``: v0 [rad/s or m/s] projected
    (:func:`project_velocity`), (a0, lam0) from the constrained dynamics with inputs ``u0``
    [N*m or N]. What :func:`moving_point` does once the loops are closed; trajectories call
    it with the partition of their first point."""
    cons = system.constraints
    plan = lk.plan(system)
    st = None
    if plan is not None:  # the stacked kernels with N = 1 (as a trajectory's points)
        st = moving_batch.states(system, plan, q0[None], v0[None], u0[None], part.rows)
        G = st.jac[0][part.rows]
        v, correction, a0, lam = st.v[0], st.correction[0], st.a[0], st.lam[0]
        M0 = st.M[0]
    else:
        G = jac[part.rows]
        factors = unit_factors(system)
        v, correction = project_velocity(G, v0, None if factors is None else factors[1])
        a0, lam_k = _constrained_dynamics(system, q0, v, u0, G, part)
        lam = np.zeros(cons.size)
        lam[part.rows] = lam_k
        M0 = system.mass_matrix(q0)
    applied = system.applied_force(q0, v, u0)
    bias = system.rnea(q0, v, np.zeros(system.nv))
    # Measured against the terms in balance, not their sum (:func:`residual_tolerance`).
    tol = residual_tolerance(max(force_scale(applied), system.static_scale(q0, bias)))
    # The force left unbalanced once the constraint forces act, M a0: an equilibrium where
    # nothing moves and it vanishes to the tolerance of an open chain's given state.
    residual = M0 @ a0
    equilibrium = not np.any(v) and float(np.abs(residual).max(initial=0.0)) <= tol
    zn = ", ".join(system.coordinate_names[i] for i in part.independent) or "none (held)"
    closed = "contacts held" if cons.contacts and not system.scene.loops else "loops closed"
    notes = [f"state given (solve = \"none\"), {closed}: independent coordinates {zn}; "
             f"the velocity given was projected onto the constraint nullspace (correction "
             f"|dv| = {np.linalg.norm(correction):.3g}); |a0| = {np.linalg.norm(a0):.6g}; "
             + ("an equilibrium (v0 = 0, |M a0| within the tolerance)" if equilibrium else
                "the model is affine, x' = f0 + A x + B u")]
    if part.dropped:
        notes.append(f"redundant constraint rows dropped: {', '.join(part.dropped)}")
    op = OperatingPoint(q=q0, v=v, u=u0, a=a0, residual=residual,
                        equilibrium=equilibrium, tolerance=tol, lam=lam, notes=tuple(notes),
                        lam_names=cons.row_names)
    return op, ConstrainedPoint(part, G, st)


def _kkt(M: np.ndarray, G: np.ndarray) -> np.ndarray:
    """The KKT matrix [[M, -G^T], [G, 0]] (solved by LAPACK's gesv: the LU factorization
    with partial pivoting that ``scipy.linalg.lu_factor`` gives, in one call)."""
    m, nv = G.shape
    out = np.zeros((nv + m, nv + m))
    out[:nv, :nv] = M
    out[:nv, nv:] = -G.T
    out[nv:, :nv] = G
    return out


def _constrained_dynamics(system, q, v, u, G, part) -> tuple[np.ndarray, np.ndarray]:
    """(a, lam_k) with M a - G^T lam = tau - b, G a = -gamma."""
    nv = system.nv
    M = system.mass_matrix(q)
    rhs = np.concatenate([system.applied_force(q, v, u) - system.rnea(q, v, np.zeros(nv)),
                          -system.constraints.bias_acceleration(q, v)[part.rows]])
    sol = np.linalg.solve(_kkt(M, G), rhs)
    return sol[:nv], sol[nv:]


def linearize_moving(system, op: OperatingPoint, cp: ConstrainedPoint, *,
                     derivatives: str = "analytic", step=None,
                     estimate_error: bool = True, check_sensitivity: bool = True
                     ) -> LinearModel:
    """Independent-coordinate model of a constrained system at a moving state (module
    docstring), partitioned basis; ``derivatives`` "fd3"/"fd5": numerical derivatives
    (:mod:`pinlin.formulations.moving_fd`, with ``step`` and ``estimate_error`` as for
    :func:`pinlin.linearize`). Near a singular position (Phi_d's condition above
    ``SENSITIVITY_CHECK``) the model is rebuilt at the configurations the assembly cannot tell
    apart from q0, as at rest (:func:`moving_sensitivity`; ``check_sensitivity``)."""
    cons = system.constraints
    part, G = cp.partition, cp.jacobian
    rows, z = part.rows, part.independent
    nv, nz = system.nv, len(z)
    plan = lk.plan(system)
    numeric: dict = {}
    if derivatives != "analytic":
        from .moving_fd import numerical_moving

        A, B, f0, R, W, S, numeric = numerical_moving(system, op, part, G, derivatives, step,
                                                      estimate_error)
    elif plan is not None:  # the stacked kernels with N = 1 (as a trajectory's points)
        st = cp.stack  # the point's own stack (moving_point), else rebuilt from op
        if st is None:
            st = moving_batch.given(system, plan, op.q, op.v, op.a, op.lam)
        mats = moving_batch.models(system, plan, st, rows, z, part.dependent)
        A, B, f0, R, W = mats.A[0], mats.B[0], mats.f0[0], mats.R[0], mats.W[0]
        S = system.input_matrix
    elif moving_manifold.applies(system):  # floating bases, welds
        A, B, f0, R, W, S = moving_manifold.model(system, op, part, G)
    else:
        A, B, f0, R, W, S = _per_point(system, op, part, G)
    coords = [system.coordinate_names[i] for i in z]
    states = tuple([f"q:{c}" for c in coords] + [f"v:{c}" for c in coords])
    Cout, _, out_names, y0 = output_matrices(system, op)
    if system.outputs is None:
        Cout, out_names, y0 = np.eye(2 * nz), states, np.zeros(2 * nz)
    else:  # y = h(q, v): dy = C_q dq + C_v dv with dq = R dz, dv = R dz' + W dz
        Cq, Cv = Cout[:, :nv], Cout[:, nv:]
        Cout = np.hstack([Cq @ R + Cv @ W, Cv @ R])
    info = {
        "formulation": "independent", "derivatives": derivatives, "basis": "partitioned",
        "effects": constrained_effects(system),
        "velocity_terms": True, "base": "free" if system.base_joint else "fixed",
        "notes": list(op.notes), "independent": coords,
        "constraint_rows": [cons.row_names[i] for i in rows],
        "dropped_rows": list(part.dropped), "R": R.tolist(),
        "condition": {"constraint_jacobian": part.condition}, **numeric,
    }
    if check_sensitivity and part.condition > SENSITIVITY_CHECK:
        change, move = moving_sensitivity(system, op, cp, A)
        info["condition"]["operating_point_sensitivity"] = change
        _warn_sensitive(system, change, move)
    # Built here with consistent shapes: the trusted constructor keeps the finite and
    # distinct-name checks and skips the rest (as linearize_reduced).
    return LinearModel.assembled(
        A=read_only(A), B=read_only(B), C=read_only(Cout),
        D=read_only(np.zeros((Cout.shape[0], S.shape[1]))), E=None, F=None,
        state_names=states, input_names=system.input_names, output_names=tuple(out_names),
        M=None, C_damp=None, K=None, Bu=None, G=None, operating_point=op.with_outputs(y0),
        name=system.scene.name, info=info, f0=read_only(np.array(f0, dtype=float)), dt=0.0)


def moving_sensitivity(system, op: OperatingPoint, cp: ConstrainedPoint, A: np.ndarray
                       ) -> tuple[float, np.ndarray]:
    """:func:`pinlin.formulations.constrained.assembly_sensitivity` at a moving state: the
    analytic model rebuilt at q0 -/+ d w (velocities, accelerations, forces and inputs held;
    Phi_q at the moved configuration). Near a fold the velocity terms grow like v^2 over the
    distance to it squared, so a moving state is far more sensitive than rest there (a
    four-bar 1e-9 rad from its rocker's limit at 0.1 rad/s: 1.8e-3 against 4e-7 at rest).

    Returns:
        (max |A(+) - A(-)| / (2 max |A|), the move d w [rad or m], nv).
    """
    return sensitivity_across(system, op, cp, A, lambda moved, moved_cp: linearize_moving(
        system, moved, moved_cp, check_sensitivity=False).A)


def _per_point(system, op: OperatingPoint, part: Partition, G: np.ndarray):
    """(A, B, f0, R, W, S) of :func:`linearize_moving` by Pinocchio point by point (systems
    the stacked kernels do not cover: a steady rotation, closures moved by multi-DoF joints);
    d gamma / dq by five-point differences."""
    cons = system.constraints
    rows, z = part.rows, part.independent
    terms = second_order_terms(system, op, "analytic")
    S = system.input_matrix
    c_q = cons.jacobian_variation(op.q, op.a)[rows] + _gamma_derivative(system, op)[rows]
    phi_v = cons.jacobian_variation(op.q, op.v)[rows]  # Phi_qq[v0, .]
    R = projection(G, part)
    A, B, W, _ = kkt_model(_kkt(terms.M, G), terms.K, terms.C, S, c_q, 2.0 * phi_v, phi_v, G,
                           part, R)
    f0 = np.concatenate([op.v[z], op.a[z]])
    return A, B, f0, R, W, S


def kkt_model(kkt: np.ndarray, K: np.ndarray, C: np.ndarray | None, Bu: np.ndarray,
              c_q: np.ndarray, c_v: np.ndarray, phi_v: np.ndarray, G: np.ndarray,
              part: Partition, R: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, W, F_v) of the independent-coordinate model at a moving state from the
    second-order terms (K, C (None: zero), Bu), the constraint acceleration's derivatives
    (c_q, c_v, rows of G) and Phi_qq[v0, .] (``phi_v``): [F; L] = kkt^-1 [[-K, -C, Bu],
    [-c_q, -c_v, 0]], W = -Phi_d^-1 phi_v R, A = [[0, I], [(F_q R + F_v W)_z, (F_v R)_z]],
    B = [[0], [(F_u)_z]]."""
    nv, m = K.shape[0], G.shape[0]
    z, dep = part.independent, part.dependent
    rhs = np.vstack([np.hstack([-K, -(np.zeros((nv, nv)) if C is None else C), Bu]),
                     np.hstack([-c_q, -c_v, np.zeros((m, Bu.shape[1]))])])
    F = np.linalg.solve(kkt, rhs)[:nv]
    F_q, F_v, F_u = F[:, :nv], F[:, nv:2 * nv], F[:, 2 * nv:]
    nz = len(z)
    W = np.zeros((nv, nz))
    if len(dep):
        W[dep] = -np.linalg.solve(G[:, dep], phi_v @ R)
    A = np.zeros((2 * nz, 2 * nz))
    A[:nz, nz:] = np.eye(nz)
    A[nz:, :nz] = (F_q @ R + F_v @ W)[z]
    A[nz:, nz:] = (F_v @ R)[z]
    B = np.zeros((2 * nz, Bu.shape[1]))
    B[nz:] = F_u[z]
    return A, B, W, F_v


def linearize_moving_penalty(system, op: OperatingPoint, cp: ConstrainedPoint, *,
                             alpha: float | None = None, mu: float | None = None,
                             omega: float | None = None) -> LinearModel:
    """Penalty model (eq. 9.35 with every velocity term) of a constrained system at a moving
    state, in all coordinates x = [dq; v]::

        M q'' + b(q, q') = tau + Phi_q^T lam,  lam = -alpha (Phi'' + 2 mu Omega Phi' + Omega^2 Phi)

    with Phi'' = Phi_q q'' + gamma. Its own acceleration a_p at the state (which tends to the
    constrained a0 as 1/alpha) and lam_p come from the regularized KKT system
    [[M, -G^T], [G, I / alpha]] [a; lam] = [tau - b; -gamma] (well conditioned for any
    alpha). Linearized at (q0, v0, a_p, lam_p)::

        M_p = M + alpha G^T G,   C_p = C + alpha G^T (2 Phi_qq[v0, .] + 2 mu Omega G),
        K_p = K + alpha G^T (Phi_qq[a_p, .] + d gamma/dq + 2 mu Omega Phi_qq[v0, .] + Omega^2 G)

    (K with the geometric stiffness -lam_p^T Phi_qq), formed by the same stable elimination
    as at rest (:func:`~pinlin.formulations.constrained.penalty_first_order`); f0 = [v0; a_p].
    """
    from .constrained import _info, penalty_first_order, penalty_parameters
    from .penalty_error import penalty_error

    alpha, mu, omega = penalty_parameters(alpha, mu, omega)
    G, nv, S = cp.jacobian, system.nv, system.input_matrix
    N = kinematic_block(system, op.v)   # Lie-group joints at a moving state (pinlin.chart)

    def linearized(alpha: float):
        pop, terms, C, K_extra, C_extra = _moving_penalty_terms(system, op, cp, alpha, mu,
                                                                 omega)
        A, B = penalty_first_order(terms.M, C, terms.K, G, S, alpha, mu, omega,
                                   K_extra=K_extra, C_extra=C_extra)
        if N is not None:
            A[:nv, :nv] = N
        return A, B, pop, terms, C, K_extra, C_extra

    A, B, pop, terms, C, K_extra, C_extra = linearized(alpha)
    # The penalty's error: the same linearization with 2 alpha (its state a_p, lam_p too).
    error = penalty_error(A, linearized(2.0 * alpha)[0], G, alpha, system.scene.name)
    a_p = pop.a
    GtG = G.T @ G
    Cout, D, out_names, y0 = output_matrices(system, pop)
    info = _info(system, pop, cp, "penalty", "analytic", alpha=alpha, mu=mu, omega=omega,
                 penalty_error=error)
    return LinearModel(A=A, B=B, C=Cout, D=D, state_names=system.state_names,
                       input_names=system.input_names, output_names=out_names,
                       M=terms.M + alpha * GtG,
                       C_damp=C + alpha * G.T @ (C_extra + 2.0 * mu * omega * G),
                       K=terms.K + alpha * G.T @ (K_extra + omega**2 * G), Bu=S, G=G,
                       operating_point=pop.with_outputs(y0), name=system.scene.name, info=info,
                       f0=np.concatenate([op.v, a_p]))


def _moving_penalty_terms(system, op: OperatingPoint, cp: ConstrainedPoint, alpha: float,
                          mu: float, omega: float):
    """(the penalty model's own state (a_p, lam_p), its second-order terms, C, K_extra,
    C_extra) of :func:`linearize_moving_penalty` for this alpha."""
    cons = system.constraints
    G, rows = cp.jacobian, cp.partition.rows
    nv, m = system.nv, len(rows)
    M = system.mass_matrix(op.q)
    rhs = np.concatenate([system.applied_force(op.q, op.v, op.u)
                          - system.rnea(op.q, op.v, np.zeros(nv)),
                          -cons.bias_acceleration(op.q, op.v)[rows]])
    kkt = np.block([[M, -G.T], [G, np.eye(m) / alpha]])
    sol = np.linalg.solve(kkt, rhs)
    a_p, lam = sol[:nv], np.zeros(cons.size)
    lam[rows] = sol[nv:]
    pop = OperatingPoint.trusted(**{**op.__dict__, "a": a_p, "lam": lam})
    terms = second_order_terms(system, pop, "analytic")
    C = terms.C if terms.C is not None else np.zeros((nv, nv))
    if moving_manifold.applies(system):  # a floating base on point contacts: Phi_qq not
        dvel, dacc = moving_manifold.coordinate_derivatives(system, pop)  # symmetric
        K_extra = dacc[rows] + 2.0 * mu * omega * dvel[rows]
        C_extra = moving_manifold.velocity_derivative(system, pop)[rows]
    else:
        jv = cons.jacobian_variation(op.q, op.v)[rows]
        K_extra = (cons.jacobian_variation(op.q, a_p)[rows]
                   + _gamma_derivative(system, pop)[rows] + 2.0 * mu * omega * jv)
        C_extra = 2.0 * jv
    return pop, terms, C, K_extra, C_extra


def _gamma_derivative(system, op: OperatingPoint) -> np.ndarray:
    """d gamma / dq at (q0, v0) (m x nv), v held: analytic where
    :func:`pinlin.loop_kernels.plan` applies, else five-point central differences on the
    manifold (step :data:`GAMMA_STEP`)."""
    cons = system.constraints
    plan = lk.plan(system)
    if plan is not None:
        J = np.zeros((1, len(plan.frames), 6, system.nv))
        lk.frame_jacobians(system.model, system.data, op.q, plan.frames, J[0])
        return lk.bias_terms(plan, J, op.v[None])[2][0]
    h = GAMMA_STEP
    out = np.zeros((cons.size, system.nv))
    e = np.zeros(system.nv)
    for j in range(system.nv):
        e[j] = h
        g = {k: cons.bias_acceleration(pin.integrate(system.model, op.q, k * e), op.v)
             for k in (-2, -1, 1, 2)}
        e[j] = 0.0
        out[:, j] = (g[-2] - 8 * g[-1] + 8 * g[1] - g[2]) / (12 * h)
    return out


def singular_dynamics(system) -> ModelError:
    """The error for a constrained state whose KKT matrix [[M, -G^T], [G, 0]] is singular:
    some motion the constraints allow moves no inertia (LAPACK's exact singularity)."""
    return ModelError(f"scene '{system.scene.name}': the constrained dynamics are singular at "
                      "this state (the matrix [[M, -Phi_q^T], [Phi_q, 0]]: a motion the loops and "
                      "contacts allow moves no inertia); give the bodies the independent "
                      "coordinates move inertia (or the joints armature)")


def refuse_unsupported(system, formulation: str, basis: str | None, derivatives: str) -> None:
    """What this module cannot do yet, as a clear error."""
    if derivatives != "analytic" and formulation != "independent":
        raise ModelError(f"scene '{system.scene.name}': a constrained system at a moving state "
                         f"is linearized with numerical derivatives ({derivatives}) in the "
                         "independent formulation only; the penalty formulation there takes "
                         "analytic derivatives")
    if formulation == "canonical" or (basis not in (None, "partitioned")):
        raise ModelError(f"scene '{system.scene.name}': at a moving state a constrained system "
                         "is linearized in the independent formulation with the partitioned "
                         "basis or in the penalty formulation; the canonical formulation and "
                         "the orthonormal basis are not supported there yet")
    if moving_manifold.applies(system):
        what = ("a floating-base robot with contacts or loops" if system.base_joint else
                "a mechanism with Lie-group joints or welds")
        if derivatives != "analytic":
            raise ModelError(f"scene '{system.scene.name}': at a moving state {what} is "
                             "linearized with analytic derivatives only (fd3/fd5 are not "
                             "supported there yet)")
        if formulation == "penalty" and system.constraints.has_welds:
            raise ModelError(f"scene '{system.scene.name}': the penalty formulation at a "
                             "moving state takes point loops and contacts; with weld loops or "
                             "contacts use the independent formulation (the penalty "
                             "formulation of welds is not supported there yet)")
        if system.rotation is not None:
            raise ModelError(f"scene '{system.scene.name}': a steadily rotating scene with "
                             "Lie-group joints or welds is not supported at a moving state")


__all__ = ["linearize_moving", "linearize_moving_penalty", "moving_point",
           "project_velocity", "refuse_unsupported", "singular_dynamics", "state_at"]
