"""The stacked arrays of a trajectory's linear models, computed for a range of its points.

Every way of running a trajectory (one process, worker processes on shared memory, a
``concurrent.futures`` executor) calls :func:`fill` on arrays laid out by :class:`Layout`; it
writes the models of points ``lo:hi`` in place. Two paths:

- **batch** (analytic derivatives, no steady rotation): per point (chapter 9.1.1 with
  R = I) ``pin.aba`` with the generalized force tau = S u + tau_spring(q) - D v of the
  scene gives the acceleration, ``pin.computeMinverse``
  M^-1 from the same recursion's workspace, ``pin.computeRNEADerivatives`` at (q, v, ddq) the
  stiffness and velocity terms, and one product the lower block row::

      A = [[K0(v), I], -M^-1 [K, C_damp]],   K = dtau_dq + diag(k),  C_damp = dtau_dv + diag(c),
      B = [[0], [M^-1 S]],   f0 = [v; ddq],

  k and c the spring stiffness and damping; K0(v) is the Lie-group block of
  :mod:`pinlin.chart`, built for all points at once with numpy. No LinearModel, no names, no
  per-point checks: :func:`check` looks at the whole stack once at the end. These three calls
  and the product cost less than one ``pin.computeABADerivatives`` (which forms the same RNEA
  derivatives and M^-1 inside, Talos at moving states: about 0.9 of it). The lower block row
  is the single call's product -M^-1 [K, C_damp] of the same factors; its acceleration is
  M^-1 times the RNEA residual, equal to ``aba``'s to rounding. ``computeMinverse(model,
  data)`` reads what ``aba`` left only when ``aba`` ran in the WORLD convention: after the
  default LOCAL one it returns a wrong M^-1, silently (Pinocchio 4.1).
- **per point**: :func:`pinlin.linearize` at each point (steady rotation, ``fd3``/``fd5``), its
  matrices copied into the stack.

Output matrices: C and D are constant when the output is the state or joint coordinates
(stored once); frame outputs need the frame Jacobian at every point
(:func:`pinlin.formulations.independent.output_matrices`, as :func:`pinlin.linearize` does).

Second-order matrices (``second_order=True``, opt-in): M, C_damp and K of every point, as
:func:`pinlin.linearize` gives them (Bu = S is constant). On the batch path they cost three
copies: ``computeRNEADerivatives`` returns M with the derivatives, and K and C_damp are the
factors of the product above; C_damp is zero where the point has no velocity terms (v = 0, no
damping).

The arrays handed to :func:`fill` must be zero-filled (``np.zeros``, a fresh shared-memory
file): the structural zeros of A and B are not written again.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from .batch_screen import SECOND_ORDER, at_point, check, may_warn, scaled_traces, screen, suspect
from .chart import PLANAR
from .conditioning import WARN_CONDITION
from .coordinates import FREE_FLYER, SPHERICAL
from .exceptions import PinlinError
from .system import System

#: Points per block of the batch kernel: a block's results (Talos: 65 kB a point) are screened
#: for NaN and inf while they are still in the cache.
BLOCK = 32
#: ``pin.aba``'s convention that lets ``pin.computeMinverse(model, data)`` reuse its workspace.
WORLD = pin.Convention.WORLD


@dataclass(frozen=True)
class Options:
    """How the models are computed (picklable: it travels to worker processes).

    Attributes:
        derivatives: ``"analytic"``, ``"fd3"`` or ``"fd5"``.
        step: Finite-difference step(s) for fd3/fd5 (see :func:`pinlin.linearize`), or None.
        frozen: For a mechanism, the partition of the trajectory's point 0
            (:class:`pinlin.trajectory_loops.FrozenPartition`); None for an open chain.
        second_order: Also compute M, C_damp and K per point (open chains only).
    """

    derivatives: str = "analytic"
    step: float | Mapping[str, float] | None = None
    #: A mechanism's partition, frozen at point 0 (:mod:`pinlin.trajectory_loops`), or None.
    frozen: Any = None
    #: Whether M, C_damp and K are stored per point (:class:`Layout` ``second_order``).
    second_order: bool = False


def batch_path(system: System, options: Options) -> bool:
    """Whether the batch path applies: an open chain, analytic derivatives and no steady
    rotation."""
    return options.derivatives == "analytic" and system.rotation is None \
        and options.frozen is None


@dataclass(frozen=True)
class Layout:
    """Names, shapes and byte offsets of a trajectory's arrays (inputs and results).

    Inputs: ``q`` (N, nq), ``v`` (N, nv), ``u`` (N, nu). Results: ``A`` (N, n, n), ``B``
    (N, n, nu), ``f0`` (N, n) (its second half is the acceleration a), ``bad`` (N,) (1 where
    a point failed the screening of :func:`fill`, for :func:`check`), and where they vary from
    point to point ``C``
    (N, p, n) (``frames``: frame outputs) and ``y`` (N, p). n = 2 nv for an open chain.

    A mechanism (``m`` > 0 constraint rows, :mod:`pinlin.trajectory_loops`) has n = ``nx``
    = 2 nz states, one more input ``cond`` (N,) (the condition of Phi_d at each point) and
    the results ``vp`` (N, nv) (projected velocities), ``acc`` (N, nv) (accelerations),
    ``lam`` (N, m) (constraint forces) and ``dv`` (N,) (size of the velocity correction);
    its C varies whenever the scene names outputs. Where the assembly computed them, the
    closure frames' Jacobians at the assembled points come as one more input ``J``
    (N, F, 6, nv), so that the model pass does not compute them again.

    With ``second_order`` (open chains), the results ``M``, ``C_damp`` and ``K`` (N, nv, nv)
    [kg, kg*m^2; N*m*s/rad ...; N*m/rad ...]: the mass, velocity and stiffness matrices.
    """

    points: int
    nq: int
    nv: int
    nu: int
    p: int
    frames: bool
    has_y: bool
    nx: int = 0
    m: int = 0
    second_order: bool = False
    closure_frames: int = 0

    @classmethod
    def of(cls, system: System, points: int, nz: int | None = None,
           second_order: bool = False, closure_frames: int = 0) -> Layout:
        """The layout of ``points`` points; ``nz``: a mechanism's independent coordinates;
        ``second_order``: with the stacks M, C_damp, K; ``closure_frames``: a mechanism's
        closure frames whose Jacobians the assembly hands on (input ``J``)."""
        spec = system.outputs
        loops = nz is not None
        n = 2 * (system.nv if nz is None else nz)
        p = n if spec is None else len(spec.names)
        frames = spec is not None and (bool(spec.frames) or loops)
        return cls(points, system.nq, system.nv, len(system.actuated), p, frames,
                   spec is not None, n if loops else 0,
                   system.constraints.size if loops else 0, bool(second_order),
                   int(closure_frames) if loops else 0)

    @property
    def n(self) -> int:
        """Number of states."""
        return self.nx or 2 * self.nv

    @property
    def inputs(self) -> tuple[str, ...]:
        """Names of the arrays the caller fills before :func:`fill`."""
        if self.closure_frames:
            return ("q", "v", "u", "cond", "J")
        return ("q", "v", "u", "cond") if self.nx else ("q", "v", "u")

    def shapes(self, points: int | None = None) -> dict[str, tuple[int, ...]]:
        N = self.points if points is None else points
        n = self.n
        out = {"q": (N, self.nq), "v": (N, self.nv), "u": (N, self.nu), "A": (N, n, n),
               "B": (N, n, self.nu), "f0": (N, n), "bad": (N,)}
        if self.nx:
            out.update({"cond": (N,), "vp": (N, self.nv), "acc": (N, self.nv),
                        "lam": (N, self.m), "dv": (N,)})
        if self.closure_frames:
            out["J"] = (N, self.closure_frames, 6, self.nv)
        if self.frames:
            out["C"] = (N, self.p, n)
        if self.has_y:
            out["y"] = (N, self.p)
        if self.second_order:
            for key in SECOND_ORDER:
                out[key] = (N, self.nv, self.nv)
        return out

    def offsets(self) -> tuple[dict[str, int], int]:
        """Byte offset of each array in one buffer (64-byte aligned), and the total size."""
        offsets, total = {}, 0
        for name, shape in self.shapes().items():
            offsets[name] = total
            total += -(-int(np.prod(shape)) * 8 // 64) * 64
        return offsets, max(total, 64)

    def views(self, buffer: Any) -> dict[str, np.ndarray]:
        """The arrays as views of ``buffer`` (at least :meth:`offsets` bytes)."""
        offsets, _ = self.offsets()
        return {name: np.ndarray(shape, dtype=np.float64, buffer=buffer, offset=offsets[name])
                for name, shape in self.shapes().items()}

    def allocate(self, points: int | None = None) -> dict[str, np.ndarray]:
        """Zero-filled arrays in ordinary memory (``points``: a chunk's size instead of N)."""
        return {name: np.zeros(shape) for name, shape in self.shapes(points).items()}


class _Plan(NamedTuple):
    """What the batch path needs of a system, fixed for it."""

    lie: tuple[tuple[str, int], ...]  # (kind, idx_v) of the free-flyer, spherical, planar joints
    spring_cols: np.ndarray  # velocity indices with a spring
    spring_q: tuple[tuple[int, int, bool], ...]  # (idx_q, idx_v, continuous) per spring
    damping_cols: np.ndarray


def _plan(system: System) -> _Plan:
    lie = tuple((j.kind, j.idx_v) for j in system.joints.values()
                if j.kind in (FREE_FLYER, SPHERICAL, PLANAR))
    springs = np.flatnonzero(system.stiffness)
    spring_q = tuple((j.idx_q, j.idx_v, j.continuous) for j in system.joints.values()
                     if j.nv == 1 and system.stiffness[j.idx_v] != 0.0)
    return _Plan(lie, springs, spring_q, np.flatnonzero(system.damping))


def generalized_forces(system: System, q: np.ndarray, v: np.ndarray, u: np.ndarray,
                       plan: _Plan | None = None) -> np.ndarray:
    """tau = S u + tau_spring(q) - D v per point (rows) [N*m or N]: the force the scene applies
    besides gravity and inertia, for ``pin.aba``. Springs act on 1-DoF joints, where
    ``pin.difference(q_rest, q)`` is q - q_rest (an angle difference on a continuous joint)."""
    plan = _plan(system) if plan is None else plan
    tau = np.zeros((q.shape[0], system.nv))
    tau[:, system.actuated] = u
    if system.has_damping:
        tau -= system.damping * v
    rest = system.q_rest
    for iq, iv, continuous in plan.spring_q:
        if continuous:  # (cos, sin): the angle of the relative rotation
            c0, s0 = rest[iq], rest[iq + 1]
            c, s = q[:, iq], q[:, iq + 1]
            dq = np.arctan2(c0 * s - s0 * c, c0 * c + s0 * s)
        else:
            dq = q[:, iq] - rest[iq]
        tau[:, iv] -= system.stiffness[iv] * dq
    return tau


def kinematic_rows(A: np.ndarray, v: np.ndarray, plan: _Plan) -> None:
    """Write the kinematic block row [K0(v), I] into the zero-filled stack ``A`` (points
    in the first axis, matching the rows of ``v``): I on every point, and on the free-flyer,
    spherical and planar joints the block -1/2 ad(v) of :func:`pinlin.chart.kinematic_block`,
    for all points at once."""
    h, nv = v.shape
    if not h:
        return
    diagonal = np.arange(nv)
    A[:, diagonal, nv + diagonal] = 1.0
    for kind, i in plan.lie:
        if kind == FREE_FLYER:  # -1/2 [[w^, u^], [0, w^]], v = [u; w]
            lin, ang = v[:, i:i + 3], v[:, i + 3:i + 6]
            _skew_into(A[:, i:i + 3, i:i + 3], ang)
            _skew_into(A[:, i:i + 3, i + 3:i + 6], lin)
            _skew_into(A[:, i + 3:i + 6, i + 3:i + 6], ang)
        elif kind == SPHERICAL:  # -1/2 w^
            _skew_into(A[:, i:i + 3, i:i + 3], v[:, i:i + 3])
        else:  # planar, v = [vx, vy, wz]: -1/2 [[0, -wz, vy], [wz, 0, -vx], [0, 0, 0]]
            vx, vy, wz = v[:, i], v[:, i + 1], v[:, i + 2]
            A[:, i, i + 1] = 0.5 * wz
            A[:, i, i + 2] = -0.5 * vy
            A[:, i + 1, i] = -0.5 * wz
            A[:, i + 1, i + 2] = 0.5 * vx


def _skew_into(out: np.ndarray, w: np.ndarray) -> None:
    """out[k] = -1/2 skew(w[k]) for every k (out: (h, 3, 3) views, zero on the diagonal)."""
    out[:, 0, 1] = 0.5 * w[:, 2]
    out[:, 0, 2] = -0.5 * w[:, 1]
    out[:, 1, 0] = -0.5 * w[:, 2]
    out[:, 1, 2] = 0.5 * w[:, 0]
    out[:, 2, 0] = 0.5 * w[:, 1]
    out[:, 2, 1] = -0.5 * w[:, 0]


def fill(system: System, arrays: Mapping[str, np.ndarray], lo: int, hi: int,
         options: Options) -> None:
    """Compute the models of points ``lo:hi`` into ``arrays`` (:meth:`Layout.views` or
    :meth:`Layout.allocate`, zero-filled; inputs q, v, u already there) and screen them:
    ``bad[k]`` = 1 where point k has NaN or inf, or where M(q_k) may be singular to working
    precision (:func:`pinlin.batch_screen.suspect`); :func:`check` decides those points
    exactly (``System.mass_inverse``).

    Raises:
        PinlinError: per-point path only, from :func:`pinlin.linearize` (a singular mass
            matrix, ...), its message starting with the point's index.
    """
    if hi <= lo:
        return
    if options.frozen is not None:
        from .trajectory_loops import fill as fill_loops

        fill_loops(system, arrays, lo, hi, options.frozen, options.derivatives, options.step)
        return
    if not batch_path(system, options):
        _fill_per_point(system, arrays, lo, hi, options)
        return
    plan = _plan(system)
    Q, V, U = arrays["q"][lo:hi], arrays["v"][lo:hi], arrays["u"][lo:hi]
    tau = generalized_forces(system, Q, V, U, plan)
    kinematic_rows(arrays["A"][lo:hi], V, plan)
    arrays["f0"][lo:hi, :system.nv] = V
    diagonals = np.empty((2, min(BLOCK, hi - lo), system.nv))  # diag M, diag M^-1 per point
    limit = system._refuse_limit
    for start in range(lo, hi, BLOCK):  # blocks small enough to screen while in cache
        stop = min(hi, start + BLOCK)
        _fill_batch(system, arrays, start, stop, plan, tau[start - lo:stop - lo], diagonals,
                    options.second_order)
        if system.outputs is not None:
            _fill_outputs(system, arrays, start, stop)
        m_diag, minv_diag = diagonals[:, :stop - start]
        traces = scaled_traces(m_diag, minv_diag)
        refused = suspect(traces, minv_diag, limit)
        screen(system, arrays, start, stop, refused, may_warn(traces, WARN_CONDITION) & ~refused)


def _fill_batch(system: System, arrays: Mapping[str, np.ndarray], lo: int, hi: int,
                plan: _Plan, tau: np.ndarray, diagonals: np.ndarray,
                second_order: bool = False) -> None:
    """The lower block rows of A and B and the acceleration of points lo:hi, whose
    generalized forces are ``tau`` (the diagonals of M and M^-1 into ``diagonals[0]`` and
    ``[1]``); with
    ``second_order``, also M, C_damp and K (module docstring), as :func:`pinlin.linearize`
    forms them, and its one product -M^-1 [K, C_damp]. A singular M gives NaN or inf here
    without a floating-point warning: :func:`check` names the point."""
    model, data, nv = system.model, system.data, system.nv
    Q, V = arrays["q"], arrays["v"]
    A, B, f0 = arrays["A"], arrays["B"], arrays["f0"]
    lower, Bv, acc = A[:, nv:, :], B[:, nv:], f0[:, nv:]
    cols = system.actuated_columns
    ks, cs = plan.spring_cols, plan.damping_cols
    stiffness, damping = system.stiffness[ks], system.damping[cs]
    m_diag, minv_diag = diagonals[:, :hi - lo]
    KC = np.empty((nv, 2 * nv))  # -[K, C_damp] of one point (negation is exact)
    negK, negC = KC[:, :nv], KC[:, nv:]
    rows = _product_rows(nv)
    if second_order:
        M, C, K = arrays["M"], arrays["C_damp"], arrays["K"]
    with np.errstate(invalid="ignore", over="ignore"):
        for k in range(lo, hi):
            acc[k] = pin.aba(model, data, Q[k], V[k], tau[k - lo], WORLD)
            Minv = pin.computeMinverse(model, data)  # from aba's WORLD-convention workspace
            Bv[k] = Minv[:, cols]
            minv_diag[k - lo] = Minv.diagonal()
            dq, dv, M_k = pin.computeRNEADerivatives(model, data, Q[k], V[k], acc[k])
            m_diag[k - lo] = M_k.diagonal()
            np.negative(dq, out=negK)
            np.negative(dv, out=negC)
            if ks.size:  # springs act on 1-DoF joints: d(difference)/d(dq) = 1
                KC[ks, ks] -= stiffness
            if cs.size:
                KC[cs, nv + cs] -= damping
            out = lower[k]  # computeRNEADerivatives leaves Minv as it was
            for r in rows:
                np.matmul(Minv[r], KC, out=out[r])
            if second_order:
                np.negative(negK, out=K[k])
                np.negative(negC, out=C[k])
                M[k] = M_k
    if not second_order:
        return
    below = np.tril_indices(nv, -1)  # Pinocchio 4 fills both triangles, older ones the upper
    Mb = M[lo:hi]
    Mb[:, below[0], below[1]] = Mb[:, below[1], below[0]]
    if not cs.size:  # no velocity terms at a point at rest without damping: C_damp = 0 exactly
        C[lo:hi][~V[lo:hi].any(axis=1)] = 0.0


#: Multiply-adds of one matrix product below which OpenBLAS runs it on the calling thread
#: (its default threshold: m n k < 65536 * 4; half of that, for margin).
ONE_THREAD_PRODUCT = 131072


def _product_rows(nv: int) -> list[slice]:
    """Row blocks of the product M^-1 [K, C_damp] (nv x nv times nv x 2nv), each small enough
    for OpenBLAS to run on the calling thread: one block up to nv = 40, more beyond, single
    rows from nv = 256 (a row of a larger system is itself above the threshold). A bigger
    product starts OpenBLAS's threads, which in worker processes oversubscribe the cores
    (nv = 90, two workers on two cores: products 2.5x slower)."""
    height = max(1, ONE_THREAD_PRODUCT // max(1, 2 * nv * nv))
    return [slice(r, min(r + height, nv)) for r in range(0, max(nv, 1), height)]


def _fill_per_point(system: System, arrays: Mapping[str, np.ndarray], lo: int, hi: int,
                    options: Options) -> None:
    """:func:`pinlin.linearize` at each point of lo:hi (it checks M^-1 and finiteness)."""
    from .linearization import linearize

    Q, V, U = arrays["q"], arrays["v"], arrays["u"]
    A, B, f0 = arrays["A"], arrays["B"], arrays["f0"]
    C, y = arrays.get("C"), arrays.get("y")
    step = options.step if options.derivatives != "analytic" else None
    for k in range(lo, hi):
        try:
            model = linearize(system, q=Q[k], v=V[k], u=U[k], derivatives=options.derivatives,
                              step=step, estimate_error=False)
        except PinlinError as exc:
            raise at_point(exc, k) from None
        A[k] = model.A
        B[k] = model.B
        if options.second_order:
            for key in SECOND_ORDER:
                arrays[key][k] = getattr(model, key)
        f0[k] = 0.0 if model.f0 is None else model.f0   # (reused arrays: every entry written)
        if y is not None:
            y[k] = model.operating_point.y
        if C is not None:
            C[k] = model.C


class _State(NamedTuple):
    q: np.ndarray
    v: np.ndarray


def _fill_outputs(system: System, arrays: Mapping[str, np.ndarray], lo: int, hi: int) -> None:
    """C (frame outputs: the frame Jacobian at each point) and the output values y, as
    :func:`pinlin.formulations.independent.output_matrices` gives them to a single model."""
    from .formulations.independent import output_matrices

    Q, V, y = arrays["q"], arrays["v"], arrays["y"]
    C = arrays.get("C")
    for k in range(lo, hi):
        Ck, _, _, yk = output_matrices(system, _State(Q[k], V[k]))  # type: ignore[arg-type]
        y[k] = yk
        if C is not None:
            C[k] = Ck


def constant_outputs(system: System, q: np.ndarray, v: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(C, D) of a point, for the outputs whose matrices do not vary along a trajectory."""
    from .formulations.independent import output_matrices

    C, D, _, _ = output_matrices(system, _State(q, v))  # type: ignore[arg-type]
    return C, D


__all__ = ["BLOCK", "SECOND_ORDER", "Layout", "Options", "at_point", "batch_path", "check",
           "constant_outputs", "fill", "generalized_forces", "kinematic_rows"]
