"""What one closed-loop linearization costs, relative to the open chain of the same tree.

A gain schedule calls ``pinlin.linearize(scene, q=...)`` at a new operating point each time.
This script sweeps the independent coordinates of the bundled four-bar (nv = 3, one
independent coordinate) and delta robot (nv = 12, three) over ``--points`` new points per
round, each point a configuration never solved before in the process (a round-dependent
offset of 1e-7 rad keeps every guess new, so the assembly cache of
:mod:`pinlin.assembly` never hits), and times each call.

The denominator is ``pinlin.linearize`` of the same URDF tree without the loop closures: the
same Pinocchio model (nv = 3 and 12), the same effects (gravity, springs) and outputs, every
joint actuated so that the inputs hold it at rest (the open-chain path: generalized gravity,
M^-1, RNEA derivatives), linearized at the very configurations the loop sweep assembled (also
new to it each round). Timings are interleaved round by round (loop sweep, then tree sweep)
and the ratio is the median over rounds of the per-round ratios. Target: ratio <= 3.

A second table shows what the assembly cache saves where a schedule comes back to points it
has solved (the same sweep repeated): the same calls with the cache on and off.

Usage: python validation/bench_loops.py [--rounds 15] [--points 50]
Writes validation/reports/bench_loops.md.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

import pinlin
from pinlin.assembly import _newton, assembly_cache, named_independent
from pinlin.equilibrium import solve_constrained
from pinlin.files import write_text_atomic
from pinlin.formulations.constrained import linearize_reduced
from pinlin.operating_point import configuration
from pinlin.scene import Scene, bundled_scenes

REPORT = Path(__file__).resolve().parent / "reports" / "bench_loops.md"
TARGET = 3.0
#: Amplitude of the sweep of each independent coordinate about the scene's value [rad].
SPAN = 0.6


def tree_scene(scene: Scene) -> Scene:
    """The scene's URDF tree without its loops: same effects and outputs, every joint
    actuated (held at rest by its inputs)."""
    eff = scene.effects
    data: dict = {"name": f"{scene.name}_tree", "urdf": str(scene.urdf),
                  "effects": {"gravity": list(eff.gravity)}, "inputs": {"actuated": "all"}}
    if eff.springs:
        data["effects"]["springs"] = {k: {"stiffness": v.stiffness, "rest": v.rest}
                                      for k, v in eff.springs.items()}
    if scene.outputs is not None:
        data["outputs"] = {"frames": list(scene.outputs.frames),
                           "joints": list(scene.outputs.joints)}
    return Scene.from_dict(data)


def guesses(scene: Scene, points: int, offset: float) -> list[np.ndarray]:
    """``points`` configurations: the scene's configuration (its guess) with each independent
    coordinate i swept to its value + SPAN sin(2 pi k / points + i + 0.3) + offset [rad]
    (distinct points: the phase 0.3 keeps sin from repeating a value within a sweep)."""
    system = scene.system
    guess = configuration(system)
    zq = [system.joint(n).idx_q for n in scene.operating_point.independent]
    out = []
    for k in range(points):
        q = guess.copy()
        for i, iq in enumerate(zq):
            q[iq] = guess[iq] + SPAN * np.sin(2 * np.pi * k / points + i + 0.3) + offset
        out.append(q)
    return out


def sweep_time(fn: Callable[[np.ndarray], object], qs: list[np.ndarray]) -> float:
    """Mean time per call of ``fn`` over the configurations ``qs`` [s]."""
    t0 = time.perf_counter()
    for q in qs:
        fn(q)
    return (time.perf_counter() - t0) / len(qs)


def measure(name: str, rounds: int, points: int) -> dict:
    """Interleaved per-call times of the loop scene and its tree over new points."""
    path = bundled_scenes()[name]
    scene = Scene.load(path)
    helper = Scene.load(path)  # assembles the tree's configurations in its own cache
    tree = tree_scene(scene)
    nv = scene.system.nv
    assert tree.system.nv == nv
    pinlin.linearize(scene), pinlin.linearize(tree)  # build systems, warm caches
    ratios, t_loop, t_tree, t_sched, t_tree_sched, r_sched = [], [], [], [], [], []
    for r in range(rounds):
        qs = guesses(scene, points, 1e-7 * (r + 1))
        assembled = [pinlin.operating_point(helper, q=q).q for q in qs]
        a = sweep_time(lambda q: pinlin.linearize(scene, q=q), qs)
        b = sweep_time(lambda q: pinlin.linearize(tree, q=q), assembled)
        # The same sweep as one gain schedule (v and u left out: rest points, u solved).
        c = sweep_time(lambda Q: pinlin.linearize_trajectory(scene, Q), [np.array(qs)]) / points
        d = sweep_time(lambda Q: pinlin.linearize_trajectory(tree, Q),
                       [np.array(assembled)]) / points
        ratios.append(a / b)
        t_loop.append(a)
        t_tree.append(b)
        t_sched.append(c)
        t_tree_sched.append(d)
        r_sched.append(c / b)
    cache = assembly_cache(scene.system)
    hits, misses = cache.hits, cache.misses  # the new-point sweeps
    # Repeated sweep: the same points again (cache hits), with the cache on and off.
    qs = guesses(scene, points, 0.0)
    for q in qs:
        pinlin.linearize(scene, q=q)
    on, off = [], []
    for _ in range(rounds):
        on.append(sweep_time(lambda q: pinlin.linearize(scene, q=q), qs))
        cache.size = 0
        cache.clear()
        off.append(sweep_time(lambda q: pinlin.linearize(scene, q=q), qs))
        cache.size = 256
        for q in qs:
            pinlin.linearize(scene, q=q)
    # Where a new point's time goes (cache off): Newton from the guess, the rest of the
    # operating point (partitions and condition, statics), the model (derivatives, geometric
    # stiffness, projection, first-order form, outputs, checks).
    system = scene.system
    cache.size = 0
    cache.clear()
    z = named_independent(system)[0]
    qs = guesses(scene, points, 1e-5)
    points_cp = [solve_constrained(system, q) for q in qs]
    newton, point, build = [], [], []
    for _ in range(rounds):
        newton.append(sweep_time(lambda q: _newton(system, q, z, 50), qs))
        point.append(sweep_time(lambda q: solve_constrained(system, q), qs))
        t0 = time.perf_counter()
        for op, cp in points_cp:
            linearize_reduced(system, op, cp)
        build.append((time.perf_counter() - t0) / len(points_cp))
    cache.size = 256
    model = pinlin.linearize(scene)
    return {"name": name, "nv": nv, "nz": model.A.shape[0] // 2,
            "newton": statistics.median(newton), "point": statistics.median(point),
            "build": statistics.median(build),
            "ratio": statistics.median(ratios), "loop": statistics.median(t_loop),
            "sched": statistics.median(t_sched), "tree_sched": statistics.median(t_tree_sched),
            "ratio_sched": statistics.median(r_sched),
            "tree": statistics.median(t_tree), "repeat_on": statistics.median(on),
            "repeat_off": statistics.median(off), "hits": hits, "misses": misses}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--points", type=int, default=50)
    args = parser.parse_args()
    results = [measure(name, args.rounds, args.points) for name in ("four_bar", "delta")]

    lines = [
        "# Closed loops at new operating points vs the open chain of the same tree",
        "",
        f"Measured by `python validation/bench_loops.py --rounds {args.rounds} --points "
        f"{args.points}` on {platform.processor() or platform.machine()}, pin "
        f"{pin.__version__}, numpy {np.__version__}: {args.points} new points per round "
        f"(independent coordinates swept by +-{SPAN} rad), loop and tree sweeps interleaved "
        "round by round, medians over rounds.",
        "",
        "| scene | nv (tree) | reduced | `linearize` per call | open tree per call | ratio | "
        "target | met |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['name']} | {r['nv']} | {r['nz']} | {r['loop'] * 1e6:.0f} us | "
            f"{r['tree'] * 1e6:.0f} us | **{r['ratio']:.2f}** | <= {TARGET:g} | "
            f"{'yes' if r['ratio'] <= TARGET else 'no'} |")
    lines += [
        "",
        "The open tree is the scene's own URDF with its `[[loops]]` removed, every joint "
        "actuated (so that its inputs hold the configuration at rest), the same gravity, "
        "springs and outputs, linearized at the configurations the loop sweep assembled.",
        "",
        "## The same sweep as one gain schedule",
        "",
        "`pinlin.linearize_trajectory(scene, q)` with v and u left out linearizes every point "
        "at rest with its holding inputs solved, each point equal to the single call at its "
        "assembled configuration (`tests/test_rest_schedule.py`); the mechanism is assembled "
        "from point to point (a start predicted along the constraint manifold), so the "
        "schedule also stays on one assembly branch. Timed in the same rounds, per point of "
        f"the {args.points}-point sweep (the call's fixed cost included):",
        "",
        "| scene | schedule per point | / open tree `linearize` per call | open tree's own "
        "schedule per point |",
        "|---|---|---|---|",
    ]
    for r in results:
        lines.append(f"| {r['name']} | {r['sched'] * 1e6:.0f} us | **{r['ratio_sched']:.2f}** | "
                     f"{r['tree_sched'] * 1e6:.0f} us |")
    lines += [
        "",
        "## Where a new point's time goes (medians, same sweep, cache off)",
        "",
        "| scene | Newton assembly from the guess | whole operating point (incl. Newton) | "
        "model from the point |",
        "|---|---|---|---|",
    ]
    for r in results:
        lines.append(f"| {r['name']} | {r['newton'] * 1e6:.0f} us | {r['point'] * 1e6:.0f} us | "
                     f"{r['build'] * 1e6:.0f} us |")
    lines += [
        "",
        "## A schedule that comes back to solved points (assembly cache)",
        "",
        "| scene | per call, cache on | per call, cache off | saved |",
        "|---|---|---|---|",
    ]
    for r in results:
        lines.append(f"| {r['name']} | {r['repeat_on'] * 1e6:.0f} us | "
                     f"{r['repeat_off'] * 1e6:.0f} us | "
                     f"{100 * (1 - r['repeat_on'] / r['repeat_off']):.0f} % |")
    lines += [
        "",
        "A guess solved before returns its assembly bit for bit (Newton from the same guess "
        "is deterministic); a new guess is always solved from itself, never from a nearby "
        "solved point, which could pick another assembly branch than the guess does "
        "(`tests/test_loop_cache.py`). Cache counts over the new-point sweeps: "
        + ", ".join(f"{r['name']} {r['hits']} hits / {r['misses']} misses" for r in results)
        + ".",
        "",
    ]
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(REPORT, "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
