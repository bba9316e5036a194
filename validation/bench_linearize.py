"""What one linearization and one modal analysis cost, relative to the Pinocchio/SciPy floor.

Measured on Talos with a floating base (nv = 38), in one run, timings interleaved round by round
so that machine noise hits both sides of each ratio alike:

1. ``pinlin.linearize(scene)`` (operating point, derivatives, A, B, C, D, names; the scene's
   System is built once and cached, as in any repeated use) divided by
   ``pin.computeABADerivatives`` alone at the same state. Target <= 1.4 (issue 18).
2. ``pinlin.modal(model)`` at a static undamped point divided by ``scipy.linalg.eig`` on the
   76 x 76 A. Target <= 0.2. The static undamped point: Talos floating in zero gravity with
   servo springs on every joint (its 6 base modes are rigid), where the symmetric (K, M) path
   applies.

BLAS runs on one thread unless ``OPENBLAS_NUM_THREADS`` is set (as in
``validation/bench_modal.py``: on a shared two-core machine a second BLAS thread waits for a
core as often as it helps); the report records the setting.

Usage: python validation/bench_linearize.py [--rounds 15]
Writes validation/reports/bench_linearize.md.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads OpenBLAS

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
import scipy.linalg as sla  # noqa: E402

import pinlin  # noqa: E402
from pinlin.files import write_text_atomic  # noqa: E402

REPORT = Path(__file__).resolve().parent / "reports" / "bench_linearize.md"


def per_call(fn: Callable[[], object], calls: int) -> float:
    t0 = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - t0) / calls


def ratio(num: Callable[[], object], den: Callable[[], object], rounds: int, calls: int
          ) -> tuple[float, float, float]:
    """Median over rounds of (time num / time den), with each side's median time [s]."""
    num(), den()  # warm caches
    ratios, tn, td = [], [], []
    for _ in range(rounds):
        a = per_call(num, calls)
        b = per_call(den, calls)
        ratios.append(a / b)
        tn.append(a)
        td.append(b)
    return statistics.median(ratios), statistics.median(tn), statistics.median(td)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    args = parser.parse_args()
    load0 = os.getloadavg()[0]

    # 1. linearize vs computeABADerivatives: Talos under gravity, floating (not an equilibrium,
    #    opted in: the model of the falling robot at rest).
    scene = pinlin.Scene.from_robot("talos", operating_point={"allow_non_equilibrium": True})
    model = pinlin.linearize(scene)
    system = scene.system
    op = model.operating_point
    tau = np.zeros(system.nv)
    tau[system.actuated] = op.u
    data = system.model.createData()

    def aba_derivatives():
        pin.computeABADerivatives(system.model, data, op.q, op.v, tau)

    r1, t_lin, t_aba = ratio(lambda: pinlin.linearize(scene), aba_derivatives, args.rounds, 200)

    # The same numerical work without pinlin's Python: the floor any wrapper of these calls has.
    model_, nv, act = system.model, system.nv, system.actuated
    zero = np.zeros(nv)

    def bare_kernels():
        Minv = pin.computeMinverse(model_, data, op.q)
        residual = pin.computeGeneralizedGravity(model_, data, op.q).copy()
        residual[act] = 0.0
        dtau_dq, _, M = pin.computeRNEADerivatives(model_, data, op.q, zero, -(Minv @ residual))
        A = np.zeros((2 * nv, 2 * nv))
        A[:nv, nv:].flat[::nv + 1] = 1.0
        A[nv:, :nv] = -(Minv @ dtau_dq)
        B = np.zeros((2 * nv, len(act)))
        B[nv:] = Minv[:, act]
        return A, B, M.copy()

    np.testing.assert_allclose(bare_kernels()[0], model.A, rtol=0, atol=1e-9 * abs(model.A).max())
    r0, t_bare, _ = ratio(bare_kernels, aba_derivatives, args.rounds, 200)

    # The smallest complete wrapper: the same kernels plus what a model must carry (u0, the
    # residual check and its note, a0, the condition estimate, a named LinearModel and its
    # OperatingPoint), written flat in one function for a fixed-structure scene.
    unact, cols = system.unactuated, system.actuated_columns

    def flat_wrapper():
        Minv = pin.computeMinverse(model_, data, op.q)
        d = Minv.diagonal()
        tr = d.sum()
        if not (d.min() > 0.0 and tr < np.inf):
            raise RuntimeError("singular mass matrix")
        g = pin.computeGeneralizedGravity(model_, data, op.q).copy()
        residual = np.zeros(nv)
        free = g[unact]
        residual[unact] = free
        k = int(np.abs(free).argmax())
        tol = 1e-9 * max(1.0, float(np.abs(g).max()))
        a0 = -(Minv @ residual)
        notes = (f"not an equilibrium: residual {free[k]:.6g} along '{unact[k]}', "
                 f"|a0| = {np.sqrt(a0 @ a0):.6g}",)
        v = np.zeros(nv)
        K, _, M = pin.computeRNEADerivatives(model_, data, op.q, v, a0)
        K, M = K.copy(), M.copy()
        A = system.kinematic_rows.copy()
        A[nv:, :nv] = -(Minv @ K)
        B = np.zeros((2 * nv, len(act)))
        B[nv:] = Minv[:, cols]
        point = pinlin.OperatingPoint.trusted(
            q=op.q, v=v, u=g[cols], a=a0, residual=residual, equilibrium=abs(free[k]) <= tol,
            tolerance=tol, y=None, lam=None, notes=notes, lam_names=())
        C, D = system.state_output
        info = {"formulation": "independent", "derivatives": "analytic", "notes": list(notes),
                "condition": {"mass_matrix": float(M.trace() * tr / nv)}}
        for arr in (A, B, M, K):
            arr.setflags(write=False)
        return pinlin.LinearModel.assembled(
            A=A, B=B, C=C, D=D, state_names=system.state_names, input_names=system.input_names,
            output_names=system.state_names, E=None, F=None, G=None, M=M,
            C_damp=system.zero_velocity_terms, K=K, Bu=system.input_matrix,
            operating_point=point, name=system.scene.name, info=info)

    np.testing.assert_allclose(flat_wrapper().A, model.A, rtol=0, atol=1e-9 * abs(model.A).max())
    r_flat, t_flat, _ = ratio(flat_wrapper, aba_derivatives, args.rounds, 200)

    # 2. modal at a static undamped point vs scipy eig of the 2n x 2n A.
    joints = [n for n in system.joints if n != system.base_joint]
    servo = pinlin.Scene.from_robot("talos", effects={
        "armature": True, "springs": {j: {"stiffness": 200.0} for j in joints}})
    static = pinlin.linearize(servo)
    modes = pinlin.modal(static)
    assert modes.method == "symmetric", modes.method
    r2, t_modal, t_eig = ratio(lambda: pinlin.modal(static), lambda: sla.eig(static.A),
                               args.rounds, 10)

    lines = [
        "# Linearization and modal analysis cost (Talos, floating base, nv = 38)",
        "",
        f"Measured by `python validation/bench_linearize.py --rounds {args.rounds}` on "
        f"{platform.processor() or platform.machine()}, pin {pin.__version__}, "
        f"numpy {np.__version__}, OPENBLAS_NUM_THREADS="
        f"{os.environ.get('OPENBLAS_NUM_THREADS')}, load {load0:.1f} -> "
        f"{os.getloadavg()[0]:.1f}; median over rounds of interleaved timings.",
        "",
        "| ratio | value | target | numerator | denominator |",
        "|---|---|---|---|---|",
        f"| `pinlin.linearize` / `computeABADerivatives` | **{r1:.2f}** | <= 1.4 | "
        f"{t_lin * 1e6:.1f} us | {t_aba * 1e6:.1f} us |",
        f"| its kernels alone (no pinlin Python) / `computeABADerivatives` | {r0:.2f} | - | "
        f"{t_bare * 1e6:.1f} us | {t_aba * 1e6:.1f} us |",
        f"| the smallest complete wrapper, flat / `computeABADerivatives` | {r_flat:.2f} | - | "
        f"{t_flat * 1e6:.1f} us | {t_aba * 1e6:.1f} us |",
        f"| `pinlin.modal` (symmetric, static undamped) / `scipy.linalg.eig(A)` | **{r2:.3f}** | "
        f"<= 0.2 | {t_modal * 1e6:.0f} us | {t_eig * 1e6:.0f} us |",
        "",
        "`pinlin.linearize` computes the operating point (generalized gravity, and the "
        "acceleration of this non-equilibrium state), RNEA derivatives (which also give M), "
        "M^-1 by `computeMinverse`, one matrix product for the lower block row of A, and the "
        "named LinearModel. The kernels row times those Pinocchio calls and products alone: "
        "the difference to the first row is the Python that checks the operating point, "
        "names the signals and records the metadata. The flat-wrapper row does that minimum "
        "(u0, residual check and note, a0, condition estimate, named model and operating "
        "point) in one Python function without pinlin's generality (springs, damping, "
        "rotation, outputs, backends): it bounds from below what any Python wrapper over "
        "these kernels costs. The symmetric modal path solves the "
        "38 x 38 definite pencil (K, M) for its eigenvalues (LAPACK `dsygvd`, as "
        "`scipy.linalg.eigh`); the mode shapes and the 76 eigenvectors of A follow on first "
        "access. The ladder from nv = 2 to 38 and the general path are in "
        "[`bench_modal.md`](bench_modal.md).",
        "",
    ]
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(REPORT, "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
