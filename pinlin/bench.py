"""``pinlin bench``: what accuracy costs in time.

For each system, in one run: the analytic model, 3- and 5-point differences over a sweep of
steps h, and MuJoCo's ``mjd_transitionFD`` forward and centered over the same sweep of its eps
(continuous A recovered exactly from the Euler step, see :mod:`pinlin.mjcf`). Error: max |A - A_an|
/ max |A_an| against the analytic A; the analytic model's own error is estimated as the error of
fd5 at its best step (the bottom of its V-curve: the two agree to that level, so neither is
further from the truth than their difference plus fd5's own error). Time: median wall time of
one complete ``pinlin.linearize`` (operating point included; error estimate off) or one
``continuous_state_matrix`` call (state set, ``mjd_transitionFD``, recovery).

Writes ``accuracy_vs_time.md`` and one PNG per system (V-curves and a Pareto plot) into the
output folder.
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .bench_report import plot, read_report, report  # noqa: F401  (re-exported: old home)
from .files import check_folder_target, check_ours

#: Steps h (fd3, fd5) and eps (MuJoCo), half-decades from 1e-2 to 1e-9.
STEPS = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9,
         1e-9)
#: The best step of each method is then searched on a finer grid, tenth-decades spanning half
#: a decade either side of the sweep's best (the bottom of a V-curve sampled every half decade
#: can sit up to a factor ~3 above the true minimum).
FINE = tuple(10.0 ** (k / 10) for k in range(-5, 6) if k != 0)
ROBOTS = ("ur5", "panda", "kinova", "talos_arm", "solo12", "talos")
MECHANISMS = ("four_bar", "delta")
HUMANOID = "talos"
#: Most timing repeats per point: each repeat lasts at least 20 ms, and a run times about 130
#: points per system.
MAX_REPEATS = 1000
#: First line of the report; an existing file of that name that does not start so is the
#: user's and is never replaced.
REPORT_MARKER = "# What accuracy costs in time"


@dataclass
class Curve:
    """Error and median time [s] per step of one method."""

    method: str
    steps: list[float] = field(default_factory=list)
    errors: list[float] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    #: (h, error, time) at the best step of the fine search around the sweep's best, or None.
    refined: tuple[float, float, float] | None = None

    def sweep_best(self) -> tuple[float, float, float]:
        """(h, error, time) at the smallest error of the half-decade sweep."""
        k = int(np.argmin(self.errors))
        return self.steps[k], self.errors[k], self.times[k]

    def best(self) -> tuple[float, float, float]:
        """(h, error, time) at the smallest error found, fine search included."""
        coarse = self.sweep_best()
        if self.refined is not None and self.refined[1] < coarse[1]:
            return self.refined
        return coarse

    def refine(self, error_at: Callable[[float], float],
               time_at: Callable[[float], float]) -> None:
        """Search the best step on :data:`FINE` around the sweep's best (same procedure for
        every method); the time is measured again at the step found."""
        h0 = self.sweep_best()[0]
        fine = [(error_at(h0 * f), h0 * f) for f in FINE]
        err, h = min(fine)
        self.refined = (h, err, time_at(h))


@dataclass
class SystemResult:
    name: str
    nv: int
    kind: str
    analytic_time: float
    analytic_error: float = float("nan")
    aba_agreement: float = float("nan")
    curves: dict[str, Curve] = field(default_factory=dict)
    note: str = ""
    ratios: dict[str, float] = field(default_factory=dict)


def median_time(fn: Callable[[], object], repeats: int, min_time: float = 0.02) -> float:
    """Median of ``repeats`` timings, each averaging enough calls to last ``min_time`` [s]."""
    fn()
    t0 = time.perf_counter()
    fn()
    once = max(time.perf_counter() - t0, 1e-7)
    calls = max(1, int(min_time / once))
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        samples.append((time.perf_counter() - t0) / calls)
    return statistics.median(samples)


class Progress:
    """A one-line progress bar on stderr."""

    def __init__(self, total: int, enabled: bool = True) -> None:
        self.total, self.done, self.enabled = total, 0, enabled

    def step(self, label: str) -> None:
        self.done += 1
        if not self.enabled:
            return
        width = 30
        filled = int(width * self.done / self.total)
        sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} "
                         f"{label:<40.40s}")
        sys.stderr.flush()
        if self.done == self.total:
            sys.stderr.write("\n")

    def close(self) -> None:
        """End a bar left part-drawn (a run stopped by an error), so that the error message
        starts on a line of its own."""
        if self.enabled and 0 < self.done < self.total:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self.enabled = False


def check_scene(name: str):
    """(scene, kind) used by the benchmark and the validation: a scene file, a bundled scene or
    a robot; a floating-base robot falls freely at rest from a rotated base pose."""
    from .scene import Scene, bundled_scenes

    if name.endswith((".toml", ".urdf")):
        scene = Scene.resolve(name)
        return scene, ("mechanism (loops)" if scene.loops else "scene file")
    if name in bundled_scenes():
        scene = Scene.load(bundled_scenes()[name])
        return scene, ("mechanism (loops)" if scene.loops else "bundled scene")
    scene = Scene.from_robot(name)
    if scene.system.base_joint is not None:
        # A floating base under gravity is not an equilibrium: the model of the free fall at
        # rest, with a rotated base so that frame conventions are exercised.
        scene = Scene.from_robot(name, operating_point={
            "allow_non_equilibrium": True,
            "q": {scene.system.base_joint: {"position": [0.1, -0.2, 1.0],
                                            "rpy": [0.2, -0.1, 0.5]}}})
        return scene, "floating base"
    return scene, "fixed base"


def report_label(name: str) -> str:
    """The name a system has in the report and its plot file: a scene or URDF file's stem,
    else the bundled scene or robot name."""
    path = Path(name)
    return path.stem if path.suffix in (".toml", ".urdf") else path.name


def measure(name: str, repeats: int, progress: Progress) -> SystemResult:
    """All methods on one system."""
    from . import mjcf
    from .linearization import linearize

    scene, kind = check_scene(name)
    system = scene.system
    ref = linearize(scene)
    scale = float(np.abs(ref.A).max())
    t_an = median_time(lambda: linearize(scene), repeats)
    result = SystemResult(report_label(name), system.nv, kind, t_an)

    def error(A: np.ndarray) -> float:
        return float(np.abs(A - ref.A).max()) / scale

    for backend in ("fd3", "fd5"):
        curve = Curve(backend)
        for h in STEPS:
            def run(h=h, backend=backend):
                return linearize(scene, derivatives=backend, step=h, estimate_error=False)
            curve.steps.append(h)
            curve.errors.append(error(run().A))
            curve.times.append(median_time(run, repeats))
            progress.step(f"{name} {backend} h={h:.0e}")

        def run_at(h, backend=backend):
            return linearize(scene, derivatives=backend, step=h, estimate_error=False)
        curve.refine(lambda h, run_at=run_at: error(run_at(h).A),
                     lambda h, run_at=run_at: median_time(lambda: run_at(h), repeats))
        progress.step(f"{name} {backend} fine search")
        result.curves[backend] = curve
    result.analytic_error = result.curves["fd5"].best()[1]
    result.aba_agreement = _aba_agreement(system, ref)
    try:
        if system.constraints:
            raise mjcf.MujocoError("MuJoCo's loop equalities act on the dependent coordinates "
                                   "(a different, soft model); see pinlin validate")
        ms = mjcf.build(system, visual=False)  # visual geoms would only add kinematics time
    except mjcf.MujocoError as exc:
        result.note = str(exc)
        for _ in range(2 * len(STEPS) + 2):
            progress.step(f"{name} MuJoCo: n/a")
        return result
    op = ref.operating_point
    for label, centered in (("mujoco forward", False), ("mujoco centered", True)):
        curve = Curve(label)
        for h in STEPS:
            def run_mj(h=h, centered=centered):
                return mjcf.continuous_state_matrix(ms, system, op, eps=h, centered=centered)
            curve.steps.append(h)
            curve.errors.append(error(run_mj()))
            curve.times.append(median_time(run_mj, repeats))
            progress.step(f"{name} {label} eps={h:.0e}")

        def mj_at(h, centered=centered):
            return mjcf.continuous_state_matrix(ms, system, op, eps=h, centered=centered)
        curve.refine(lambda h, mj_at=mj_at: error(mj_at(h)),
                     lambda h, mj_at=mj_at: median_time(lambda: mj_at(h), repeats))
        progress.step(f"{name} {label} fine search")
        result.curves[label] = curve
    if name == HUMANOID:
        result.ratios = _interleaved_ratios(scene, ms, op, result, repeats)
    return result


def _aba_agreement(system, ref) -> float:
    """max |A - A_aba| / max |A| with A_aba from ``pin.computeABADerivatives``, a second analytic
    algorithm (ABA differentiated, not RNEA derivatives and M^-1): the two share no
    truncation, so their difference measures the analytic model's rounding. NaN where pinlin
    adds terms Pinocchio's ABA lacks (loops, rotation, springs, damping)."""
    import pinocchio as pin

    if (system.constraints or system.rotation is not None or system.has_springs
            or system.has_damping):
        return float("nan")
    op, nv = ref.operating_point, system.nv
    tau = system.input_matrix @ op.u
    data = pin.Data(system.model)
    pin.computeABADerivatives(system.model, data, op.q, op.v, tau)
    A = np.zeros_like(ref.A)
    A[:nv, nv:] = np.eye(nv)
    A[nv:, :nv] = data.ddq_dq
    A[nv:, nv:] = data.ddq_dv
    return float(np.abs(A - ref.A).max() / np.abs(ref.A).max())


def _interleaved_ratios(scene, ms, op, result: SystemResult, repeats: int) -> dict[str, float]:
    """Time ratios to the analytic model measured round by round (each round times the three
    methods back to back), median over rounds: machine noise hits both sides alike."""
    from . import mjcf
    from .linearization import linearize

    h5 = result.curves["fd5"].best()[0]
    hm = result.curves["mujoco centered"].best()[0]
    fns = {
        "analytic": lambda: linearize(scene),
        "fd5": lambda: linearize(scene, derivatives="fd5", step=h5, estimate_error=False),
        "mujoco centered": lambda: mjcf.continuous_state_matrix(ms, scene.system, op, eps=hm,
                                                                centered=True),
    }
    rounds: dict[str, list[float]] = {"fd5": [], "mujoco centered": []}
    for _ in range(max(5, 3 * repeats)):
        t = {k: median_time(f, 1) for k, f in fns.items()}
        for k in rounds:
            rounds[k].append(t[k] / t["analytic"])
    return {k: statistics.median(v) for k, v in rounds.items()}


def run(systems: list[str], repeats: int = 5, out_dir: str | Path = "validation/reports",
        progress: bool = True, command: str = "pinlin bench", *, merge: bool = True
        ) -> list[SystemResult]:
    """Measure ``systems`` (robot or bundled scene names, scene or URDF files), write the
    report and plots (atomically) into ``out_dir``, print the report and where it is.

    With ``merge`` (the default), an existing ``accuracy_vs_time.md`` keeps the rows and
    sections of the systems not measured now (:func:`pinlin.bench_report.report`), so that
    ``pinlin bench ur5`` updates the ur5 rows only.

    Everything that can be refused is refused before the long run and before anything is
    written: ``repeats``, the systems, an output folder that is a file, an existing
    ``accuracy_vs_time.md`` that pinlin did not write.

    Args:
        repeats: Timing repeats per point, 1 to :data:`MAX_REPEATS`.

    Raises:
        ArgumentError: ``repeats`` or ``systems`` out of range.
        UnknownRobotError, SceneError, ...: a system that does not resolve to a scene.
        ModelFileError: the output folder cannot be used, or a file cannot be written.
    """
    from .exceptions import ArgumentError

    if (isinstance(repeats, bool) or not isinstance(repeats, int | np.integer)
            or not 1 <= repeats <= MAX_REPEATS):
        raise ArgumentError("repeats", f"--repeats must be >= 1 and <= {MAX_REPEATS} (timing "
                                       f"repeats per point), got {repeats!r}")
    if isinstance(systems, str) or not all(isinstance(n, str) for n in systems):
        raise ArgumentError("systems", "expected a list of robot or scene names")
    systems = list(dict.fromkeys(systems))  # a system named twice is measured once
    if not systems:
        raise ArgumentError("systems", "name at least one robot or scene")
    labels: dict[str, str] = {}
    for name in systems:
        key = report_label(name)
        if key in labels:
            raise ArgumentError("systems", f"'{labels[key]}' and '{name}' would both be "
                                           f"reported as '{key}'")
        labels[key] = name
    out = check_folder_target(out_dir, "out_dir")
    check_folder_target(out / "accuracy_vs_time", "out_dir")
    check_ours(out / "accuracy_vs_time.md", REPORT_MARKER)
    for key in labels:
        check_ours(out / "accuracy_vs_time" / f"{key}.png", b"\x89PNG")
    for name in systems:  # fail before the long run, not in the middle of it
        check_scene(name)
    bar = Progress(len(systems) * 4 * (len(STEPS) + 1), progress)
    try:
        results = [measure(name, int(repeats), bar) for name in systems]
    finally:
        bar.close()
    plot(results, out)  # the plots first: the report that links them is the last write
    text = report(results, out, command, merge=merge)
    print(text)
    kept = len(read_report(out / "accuracy_vs_time.md")[0]) - len(results)
    print(f"Report written to {out / 'accuracy_vs_time.md'} ({len(results)} systems measured"
          + (f", {kept} kept from an earlier run" if kept else "") + f"; plots in "
          f"{out / 'accuracy_vs_time'})")
    return results


def main(argv: list[str] | None = None) -> int:
    """``python validation/accuracy_vs_time.py`` and ``pinlin bench`` share this parser."""
    from .cli import main as cli_main

    return cli_main(["bench", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
