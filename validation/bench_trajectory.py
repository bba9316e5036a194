"""What a trajectory of linear models costs: per point, and on two cores.

Floating-base Talos (nv = 38, 76 states, 32 inputs), random moving states (configurations
integrate(neutral, dq) with dq in [-1.5, 1.5], velocities in [-2, 2] rad/s or m/s, inputs in
[-5, 5] N*m), in one run, timings interleaved round by round, medians:

1. Per point, N = 1000: ``pinlin.linearize_trajectory`` (one process) divided by
   ``pin.computeABADerivatives`` alone at the same states (a Python loop over the points, the
   same generalized forces). Target <= 1.15. Also pinlin's own batch kernels alone (``aba``,
   ``computeMinverse``, ``computeRNEADerivatives``, one product: :mod:`pinlin.batch`), and the
   floor any dense result has: those kernels writing their outputs into freshly allocated A
   and B stacks (the memory the result needs: 65 kB a point, which the OS must hand out
   zeroed).
2. ``workers=2`` against one process at N = 10 000 (target >= 1.8x), the pool started (it is
   kept for later calls with the same number of workers), and the first call, which starts
   it.
3. The crossover: speed-up of ``workers=2`` (pool started) for N from 25 to 3200 points; below
   the crossover one process is faster.
4. Mechanisms (issue 15, section 2): the four-bar (nv = 3) and the delta (nv = 12), their
   trajectories (every point assembled from the previous one, velocities projected, models in
   the independent coordinates of point 0) against the open chain of the same nv (the same
   URDF and effects without the loops: the batch kernel), per point, N = 200, interleaved.
   Target <= 2.

Usage: python validation/bench_trajectory.py [--rounds 7] [--out validation/reports]
Writes bench_trajectory.md there. Machine noise moves absolute times by tens of percent;
ratios taken within one round move less.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

import pinlin
from pinlin import parallel
from pinlin.batch import generalized_forces
from pinlin.files import write_text_atomic

HERE = Path(__file__).resolve().parent


def states(scene: pinlin.Scene, N: int, seed: int):
    system = scene.system
    model, rng = system.model, np.random.default_rng(seed)
    neutral = pin.neutral(model)
    q = np.array([pin.integrate(model, neutral, rng.uniform(-1.5, 1.5, model.nv))
                  for _ in range(N)])
    return q, rng.uniform(-2, 2, (N, system.nv)), rng.uniform(-5, 5, (N, len(system.actuated)))


def timed(fn: Callable[[], object]) -> float:
    t0 = time.perf_counter()
    result = fn()
    elapsed = time.perf_counter() - t0
    del result
    return elapsed


def rounds(fns: dict[str, Callable[[], object]], count: int) -> dict[str, list[float]]:
    """Each function once per round, in turn, ``count`` rounds (after one warm-up round)."""
    for fn in fns.values():
        fn()
    times: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(count):
        for name, fn in fns.items():
            times[name].append(timed(fn))
    return times


def per_point(scene: pinlin.Scene, n_rounds: int) -> dict[str, float]:
    system = scene.system
    model, data, nv = system.model, pin.Data(system.model), system.nv
    N = 1000
    q, v, u = states(scene, N, 0)
    tau = generalized_forces(system, q, v, u)
    n, m = 2 * nv, len(system.actuated)
    cols = system.actuated_columns

    def kernel():
        for k in range(N):
            pin.computeABADerivatives(model, data, q[k], v[k], tau[k])

    WORLD = pin.Convention.WORLD
    KC = np.empty((nv, 2 * nv))

    def kernels():   # pinlin's batch kernels (pinlin.batch), nothing written out
        for k in range(N):
            a = pin.aba(model, data, q[k], v[k], tau[k], WORLD)
            Minv = pin.computeMinverse(model, data)
            dq, dv, _ = pin.computeRNEADerivatives(model, data, q[k], v[k], a)
            KC[:, :nv] = dq
            KC[:, nv:] = dv
            np.matmul(Minv, KC)

    def kernel_into(A, B):   # the kernels' outputs written into the stacks, nothing else
        lower, Bv = A[:, nv:], B[:, nv:]
        for k in range(N):
            a = pin.aba(model, data, q[k], v[k], tau[k], WORLD)
            Minv = pin.computeMinverse(model, data)
            Bv[k] = Minv[:, cols]
            dq, dv, _ = pin.computeRNEADerivatives(model, data, q[k], v[k], a)
            KC[:, :nv] = dq
            KC[:, nv:] = dv
            np.matmul(Minv, KC, out=lower[k])
            np.negative(lower[k], out=lower[k])
        A[:, np.arange(nv), nv + np.arange(nv)] = 1.0
        return A, B

    def floor():
        return kernel_into(np.zeros((N, n, n)), np.zeros((N, n, m)))

    def batch():
        return pinlin.linearize_trajectory(scene, q, v, u)

    stacks = np.zeros((N, n, n)), np.zeros((N, n, m))

    def floor_reused():   # the floor with stacks written before: no page to hand out
        return kernel_into(*stacks)

    previous = batch()

    def reused():   # an optimizer's loop: the new models into the previous call's arrays
        return pinlin.linearize_trajectory(scene, q, v, u, out=previous)

    traj = batch()
    assert traj.info["path"] == "batch"
    np.testing.assert_allclose(traj.A[0, nv:], floor()[0][0, nv:], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(reused().A, traj.A)
    times = rounds({"kernel": kernel, "kernels": kernels, "floor": floor, "batch": batch,
                    "floor_reused": floor_reused, "reused": reused}, n_rounds)
    out = {f"{k}_us": 1e6 * statistics.median(t) / N for k, t in times.items()}
    for name in ("kernels", "floor", "batch", "floor_reused", "reused"):
        out[f"{name}_ratio"] = statistics.median(
            [a / b for a, b in zip(times[name], times["kernel"], strict=True)])
    return out


def speed_up(scene: pinlin.Scene, N: int, n_rounds: int, seed: int = 1,
             pool=None, steps: int = 3_000_000) -> dict[str, float]:
    """One process against workers=2 (pool started), interleaved; with a fork ``pool`` of
    two, the machine's ceiling in the same rounds (:func:`capacity`)."""
    q, v, u = states(scene, N, seed)
    fns = {"serial": lambda: pinlin.linearize_trajectory(scene, q, v, u),
           "workers": lambda: pinlin.linearize_trajectory(scene, q, v, u, workers=2)}
    if pool is not None:
        fns["spin_serial"] = lambda: (_spin(steps), _spin(steps))
        fns["spin_pair"] = lambda: pool.map(_spin, [steps, steps])
    times = rounds(fns, n_rounds)
    out = {"serial_s": statistics.median(times["serial"]),
           "workers_s": statistics.median(times["workers"]),
           "speed_up": statistics.median([a / b for a, b in zip(times["serial"],
                                                                times["workers"],
                                                                strict=True)])}
    if pool is not None:
        out["capacity"] = statistics.median([a / b for a, b in zip(
            times["spin_serial"], times["spin_pair"], strict=True)])
    return out


def _spin(steps: int) -> int:
    total = 0
    for i in range(steps):
        total += i
    return total


def spin_pool():
    """A started fork pool of two for the machine's ceiling: the same pure-Python loop twice,
    one after the other in one process against side by side in two, in the rounds of
    :func:`speed_up` (2.0 on two free cores; less where the cores share execution units or
    the host steals time)."""
    import multiprocessing

    pool = multiprocessing.get_context("fork").Pool(2)
    pool.map(_spin, [10, 10])
    return pool


def first_call(scene: pinlin.Scene, N: int) -> float:
    """workers=2 with no pool started: the pool's start included [s] (median of 3)."""
    q, v, u = states(scene, N, 2)
    samples = []
    for _ in range(3):
        parallel.shutdown()
        samples.append(timed(lambda: pinlin.linearize_trajectory(scene, q, v, u, workers=2)))
    return statistics.median(samples)


def instructions(scene: pinlin.Scene, mode: str, N: int = 1000) -> None:
    """The work of part 1 once, for an instruction count: ``setup`` (imports, states, a
    40-point warm-up), ``kernel`` (setup and the kernel loop) or ``batch`` (setup and
    ``linearize_trajectory``)."""
    system = scene.system
    model, data = system.model, pin.Data(system.model)
    q, v, u = states(scene, N, 0)
    tau = generalized_forces(system, q, v, u)
    pinlin.linearize_trajectory(scene, q[:40], v[:40], u[:40])
    pin.computeABADerivatives(model, data, q[0], v[0], tau[0])
    if mode == "kernel":
        for k in range(N):
            pin.computeABADerivatives(model, data, q[k], v[k], tau[k])
    elif mode == "batch":
        pinlin.linearize_trajectory(scene, q, v, u)


def open_chain(name: str, folder: Path) -> pinlin.Scene:
    """The bundled mechanism ``name`` without its loops (the same URDF, effects, inputs and
    outputs): an open chain of the same nv, written to ``folder``."""
    src = Path(pinlin.__file__).resolve().parent.parent / "urdf" / f"{name}.toml"
    lines, skip = [], False
    for line in src.read_text().splitlines():
        if line.startswith("[[loops]]"):
            skip = True
            continue
        if skip and line.startswith("[") and not line.startswith("[[loops]]"):
            skip = False
        if skip or line.startswith("independent"):
            continue
        lines.append(line.replace(f'urdf = "{name}.urdf"', f'urdf = "{src.with_suffix(".urdf")}"'))
    path = folder / f"{name}_open.toml"
    path.write_text("\n".join(lines) + "\n")
    return pinlin.Scene.load(path)


def mechanism_states(scene: pinlin.Scene, N: int, seed: int):
    """N states of a mechanism: its independent coordinates swept by 0.5 rad (sines), the
    dependent ones at their rest values (each point is assembled), random velocities and
    inputs."""
    system = scene.system
    rest = pinlin.linearize(scene)
    z = [system.coordinate_names.index(c) for c in rest.info["independent"]]
    rng = np.random.default_rng(seed)
    Q = np.tile(rest.operating_point.q, (N, 1))
    s = np.linspace(0, 1, N)[:, None]
    Q[:, z] += 0.5 * np.sin(2 * np.pi * s + rng.uniform(0, 2 * np.pi, len(z)))
    return (Q, rng.uniform(-2, 2, (N, system.nv)),
            rng.uniform(-1, 1, (N, len(system.actuated))))


def mechanisms(n_rounds: int, N: int = 200) -> dict[str, dict[str, float]]:
    """Per point: each mechanism's trajectory and its open chain's, interleaved."""
    import tempfile

    out: dict[str, dict[str, float]] = {}
    fns: dict[str, Callable[[], object]] = {}
    with tempfile.TemporaryDirectory() as folder:
        for name in ("four_bar", "delta"):
            scene = pinlin.Scene.resolve(name)
            chain = open_chain(name, Path(folder))
            assert chain.system.nv == scene.system.nv and not chain.system.constraints
            q, v, u = mechanism_states(scene, N, 3)
            qo, vo, uo = states(chain, N, 3)
            fns[f"{name}:loops"] = (lambda s=scene, a=(q, v, u):
                                    pinlin.linearize_trajectory(s, *a))
            fns[f"{name}:open"] = (lambda s=chain, a=(qo, vo, uo):
                                   pinlin.linearize_trajectory(s, *a))
        times = rounds(fns, n_rounds)
    for name in ("four_bar", "delta"):
        loops, chain = times[f"{name}:loops"], times[f"{name}:open"]
        out[name] = {"nv": pinlin.Scene.resolve(name).system.nv,
                     "loops_us": 1e6 * statistics.median(loops) / N,
                     "open_us": 1e6 * statistics.median(chain) / N,
                     "ratio": statistics.median([a / b for a, b in zip(loops, chain,
                                                                       strict=True)])}
    return out


def report(results: dict, args: argparse.Namespace) -> str:
    pp, big = results["per_point"], results["big"]
    lines = [
        "# Trajectories: cost per point and on two cores",
        "",
        "Written by `python validation/bench_trajectory.py"
        + (f" --rounds {args.rounds}" if args.rounds != 7 else "") + "` "
        f"({platform.node() and 'this machine'}: {os.cpu_count()} cores, "
        f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        f"pin {pin.__version__}, numpy {np.__version__}; load average "
        f"{results['load'][0]:.1f} before, {results['load'][1]:.1f} after). Floating-base "
        "Talos (nv = 38), random moving states; timings interleaved round by round, "
        f"{args.rounds} rounds, medians.",
        "",
        "## 1. One process, N = 1000 points",
        "",
        "| what | time per point | / computeABADerivatives |",
        "| --- | ---: | ---: |",
        f"| `pin.computeABADerivatives` alone (Python loop) | {pp['kernel_us']:.1f} us | 1 |",
        f"| pinlin's batch kernels alone (`aba`, `computeMinverse`, `computeRNEADerivatives`, "
        f"one product) | {pp['kernels_us']:.1f} us | {pp['kernels_ratio']:.3f} |",
        f"| those kernels writing into fresh A, B stacks (the floor of a dense result) | "
        f"{pp['floor_us']:.1f} us | {pp['floor_ratio']:.3f} |",
        f"| `pinlin.linearize_trajectory` | {pp['batch_us']:.1f} us | "
        f"**{pp['batch_ratio']:.3f}** |",
        f"| the floor loop writing into stacks written before (no fresh page) | "
        f"{pp['floor_reused_us']:.1f} us | {pp['floor_reused_ratio']:.3f} |",
        f"| `linearize_trajectory(..., out=previous)`, the arrays of the previous call reused | "
        f"{pp['reused_us']:.1f} us | **{pp['reused_ratio']:.3f}** |",
        "",
        f"Target: <= 1.15. The result of 1000 points is {results['bytes'] / 1e6:.0f} MB (A and "
        "B dense), which the OS hands out zeroed: the floor row measures that cost with the "
        "kernels' own outputs written in and nothing else. What `linearize_trajectory` adds on "
        f"top ({pp['batch_ratio'] - pp['floor_ratio']:+.3f}) is the kinematic rows, f0, the "
        "diagonals of M and M^-1 (the mass check), the screening for NaN and the checks of "
        "the input arrays. An "
        "optimizer that re-linearizes the same horizon (iLQR, DDP) passes the previous result "
        "as `out=` (`pinlin.trajectory_buffers`): the pages are then handed out once, and the "
        "last two rows compare that call with the floor loop on stacks written before.",
        "",
        f"## 2. Two worker processes, N = {big['N']}",
        "",
        "| | time | speed-up |",
        "| --- | ---: | ---: |",
        f"| one process | {big['serial_s']:.3f} s | 1 |",
        f"| `workers=2`, pool started | {big['workers_s']:.3f} s | **{big['speed_up']:.2f}x** |",
        f"| `workers=2`, first call (starts the pool) | {results['first_big']:.3f} s | "
        f"{big['serial_s'] / results['first_big']:.2f}x |",
        f"| this machine's ceiling, same rounds: two pure-Python loops in two processes | | "
        f"{results['capacity']:.2f}x |",
        "",
        "Target: >= 1.8x, against the ceiling in the last row (what any two processes gain on "
        "this machine at the time of the run). The pool is kept for later calls with the same "
        "number of workers; "
        "a forked pool starts in "
        f"{1e3 * results['start_s']:.0f} ms (first call at N = {results['small_N']} minus the "
        "same call with the pool started).",
        "",
        "## 3. Crossover (pool started)",
        "",
        "| N | one process | per point | workers=2 | per point | speed-up |",
        "| ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    rows = {**results["crossover"], big["N"]: big}
    crossover_rows = results["crossover"]
    for N, row in rows.items():
        lines.append(f"| {N} | {1e3 * row['serial_s']:.2f} ms | "
                     f"{1e6 * row['serial_s'] / N:.0f} us | {1e3 * row['workers_s']:.2f} ms | "
                     f"{1e6 * row['workers_s'] / N:.0f} us | {row['speed_up']:.2f}x |")
    if isinstance(results["crossover_N"], int):
        lines += ["", f"Below about **{results['crossover_N']} points** one process is faster "
                  "(with the pool started; add the pool's start to the first call).", ""]
    else:
        lines += ["", f"Up to {max(crossover_rows)} points one process was faster at every N "
                  "measured (with the pool started; add the pool's start to the first call).",
                  ""]
    mech = results["mechanisms"]
    lines += ["## 4. Mechanisms against the open chain of the same nv, N = 200 points", "",
              "| scene | nv | trajectory with loops, per point | open chain, per point | "
              "ratio |", "| --- | ---: | ---: | ---: | ---: |"]
    for name, row in mech.items():
        lines.append(f"| {name} | {row['nv']} | {row['loops_us']:.0f} us | "
                     f"{row['open_us']:.1f} us | **{row['ratio']:.1f}** |")
    worst = max(row["ratio"] for row in mech.values())
    best = min(row["ratio"] for row in mech.values())
    verdict = "Met." if worst <= 2 else f"Not met ({best:.1f}x to {worst:.1f}x)."
    lines += ["", f"Target: <= 2. {verdict} " + MECHANISM_NOTES, "", NOTES]
    return "\n".join(lines)


MECHANISM_NOTES = """(Before the stacked kernels: 22x and 41x.) The open chain is the batch
kernels of part 1 per point plus its outputs. A mechanism's point now costs, from
Python, only Pinocchio calls: assembly (:mod:`pinlin.trajectory_assembly`: the closure check of
all given points from frame positions, then per point Newton from a start predicted along the
manifold's tangent and the previous step's curvature, 2 kinematics passes on a smooth sweep (one
Newton step, then the check), each one ``computeJointJacobians`` and a frame Jacobian per
closure frame, and a LAPACK ``gesv`` per step; the frame Jacobians of its last pass are kept for
the model), then ``crba``, ``nonLinearEffects`` and ``computeRNEADerivatives``
(:mod:`pinlin.formulations.moving_batch`; the output frames' Jacobians and positions are read
from the data that last call leaves). Everything else runs on stacks of 64 points: the
projection, gamma, Phi_qq[v, .], Phi_qq[a, .], the geometric stiffness and d gamma / dq
*analytically* from the frame Jacobians (:mod:`pinlin.loop_kernels`; formerly 4 nv evaluations
of gamma by five-point differences), the two KKT solves, R, W and A, B. What is left is mostly
the serial assembly (about half of a point: 2 kinematics passes and their small numpy calls,
about 10 us each for the delta's six closure frames, of which the Pinocchio calls are ~5 us: a
frame Jacobian costs 0.4 us, so reading them from one ``data.J`` access would save little) and
the numpy calls on small stacks; 2x looks out of reach from Python."""


NOTES = """## Reading these figures

- **Memory, not Python, is what separates the batch from the kernel.** The kernel leaves its
  outputs in Pinocchio's cache-resident workspace; the batch must put 65 kB per point into
  fresh memory, which the OS zeroes on first touch. The floor row (the batch's kernels
  writing their outputs into fresh stacks) shows that cost alone. Counted in instructions,
  which no other process can disturb, the batch executes 0.91x the instructions of the
  `computeABADerivatives` loop (501 k against 552 k per point, N = 1000; valgrind's
  callgrind, page zeroing by the OS not counted): its kernels (`aba`, `computeMinverse`,
  `computeRNEADerivatives`, one product) do less than `computeABADerivatives` does, and the
  per-point Python bookkeeping, copies and checks fit in the difference (before those
  kernels: 1.09x, 609 k against 558 k). Reproduce: for MODE in setup, kernel and batch,
  `valgrind --tool=callgrind $(python -c "import sys; print(sys.executable)")
  validation/bench_trajectory.py --instructions MODE` (about a minute each) and take the
  differences of the totals ("Collected") from setup's, divided by 1000.
- **Shared memory is expensive on this machine.** Its pages are 4 kB tmpfs pages (transparent
  huge pages are off for shmem here), measured at about 3 us per page handed out against
  about 0.5 us per 4 kB of an anonymous huge page (48 ms against 7.5 ms for 65 MB). For Talos
  a worker therefore spends about as much on its result pages as on the kernel, which is why
  two workers lose below a few thousand points (each call also costs a task round trip per
  chunk, a few hundred microseconds).
- **Large fresh allocations are slow and erratic on this VM.** One process's per-point cost
  grows with N (the table above: 60-70 us at N <= 3200, far more at N = 10 000, where each
  call allocates 660 MB that the VM backs anew); the speed-up at N = 10 000 is therefore
  larger than the kernels alone would give (2 at most) and moves from run to run (1.8x to
  2.4x seen). Compare ratios within one run only.
- A persistent shared arena (result pages reused across calls, zeroed by the workers) would
  remove the shared-page cost; it is not implemented.
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--out", default=str(HERE / "reports"))
    parser.add_argument("--points", type=int, default=10_000, help="N of part 2")
    parser.add_argument("--instructions", choices=("setup", "kernel", "batch"),
                        help="run only this, once, on 1000 points (for callgrind; see the "
                             "report's notes)")
    args = parser.parse_args()
    scene = pinlin.Scene.from_robot("talos")
    if args.instructions:
        instructions(scene, args.instructions)
        return
    load0 = os.getloadavg()[0]
    results: dict = {"per_point": per_point(scene, args.rounds)}
    nv, m = scene.system.nv, len(scene.system.actuated)
    results["bytes"] = 1000 * 8 * (4 * nv * nv + 2 * nv * m)
    print("per point:", {k: round(v, 3) for k, v in results["per_point"].items()}, flush=True)
    with spin_pool() as pool:
        results["big"] = {"N": args.points, **speed_up(scene, args.points, args.rounds,
                                                       pool=pool)}
    results["capacity"] = results["big"]["capacity"]
    print("big:", results["big"], flush=True)
    results["small_N"] = 50
    first_small = first_call(scene, results["small_N"])
    results["first_big"] = first_call(scene, args.points)
    crossover: dict[int, dict[str, float]] = {}
    for N in (25, 50, 100, 200, 400, 800, 1600, 3200):
        crossover[N] = speed_up(scene, N, max(args.rounds, 9), seed=N)
        print(N, crossover[N], flush=True)
    results["crossover"] = crossover
    results["start_s"] = max(0.0, first_small - crossover[results["small_N"]]["workers_s"])
    faster = [N for N, row in crossover.items() if row["speed_up"] > 1.0]
    results["crossover_N"] = min(faster) if faster else "none measured"
    results["mechanisms"] = mechanisms(args.rounds)
    print("mechanisms:", results["mechanisms"], flush=True)
    results["load"] = (load0, os.getloadavg()[0])
    text = report(results, args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "bench_trajectory.md", text)
    print(text)
    parallel.shutdown()


if __name__ == "__main__":
    main()
