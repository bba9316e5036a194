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

import platform
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .files import check_folder_target, check_ours, make_folder, write_atomic, write_text_atomic

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
        ms = mjcf.build(system)
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


# ------------------------------------------------------------------------------------------------
def _fmt_time(t: float) -> str:
    return f"{t * 1e3:.3f}" if t < 1 else f"{t * 1e3:.0f}"


def report(results: list[SystemResult], out: Path, command: str) -> str:
    import pinocchio as pin

    lines = [
        "# What accuracy costs in time",
        "",
        f"Produced by `{command}` on {platform.machine()} ({platform.processor() or 'cpu'}), "
        f"pin {pin.__version__}, MuJoCo {_mujoco_version()}, numpy {np.__version__}. "
        "Error: max |A - A_analytic| / max |A_analytic|. Each method's best step is taken "
        "from the half-decade sweep and then searched on tenth-decades within half a decade "
        "either side (the same search for every method). The analytic model's own error is "
        "estimated as fd5's best agreement with it; as a second estimate, its agreement with "
        "`pin.computeABADerivatives` (a different analytic algorithm, so the difference is "
        "rounding of one or the other) is listed beside. Time: median of one complete "
        "`pinlin.linearize` (operating point included, error estimate off) or one MuJoCo "
        "`continuous_state_matrix` (state set + `mjd_transitionFD` + exact recovery of A from "
        "the Euler step). Floating bases: rotated base, free fall at rest (a0 != 0). "
        "Mechanisms: MuJoCo's soft loop equalities give a different (dependent-coordinate) "
        "model, not compared here.",
        "",
        "## Headline (best step of each method)",
        "",
        "| system | nv | analytic [ms] | analytic error (est., fd5) | analytic vs ABA derivatives "
        "| fd3 best: h, error, ms "
        "| fd5 best: h, error, ms | MuJoCo fwd best: eps, error, ms "
        "| MuJoCo ctr best: eps, error, ms |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        cells = []
        for key in ("fd3", "fd5", "mujoco forward", "mujoco centered"):
            if key in r.curves:
                h, e, t = r.curves[key].best()
                cells.append(f"{h:.1e}, {e:.1e}, {_fmt_time(t)}")
            else:
                cells.append("n/a")
        lines.append(f"| {r.name} ({r.kind}) | {r.nv} | {_fmt_time(r.analytic_time)} | "
                     f"{r.analytic_error:.1e} | {_fmt_error(r.aba_agreement)} | "
                     + " | ".join(cells) + " |")
    hum = next((r for r in results if r.name == HUMANOID), None)
    if hum is not None and hum.ratios:
        _, emc, _ = hum.curves["mujoco centered"].best()
        lines += [
            "",
            f"## Targets on the floating-base humanoid ({HUMANOID}, nv = {hum.nv})",
            "",
            "Time ratios measured round by round (analytic, fd5 and MuJoCo timed back to back "
            "in each round, median of the per-round ratios).",
            "",
            "| ratio | measured | target |",
            "|---|---|---|",
            f"| time fd5 (best h) / time analytic | {hum.ratios['fd5']:.1f} | >= 30 |",
            f"| time MuJoCo centered (best eps) / time analytic | "
            f"{hum.ratios['mujoco centered']:.1f} | >= 10 |",
            f"| error of MuJoCo centered (best eps) / analytic error estimate | "
            f"{emc / hum.analytic_error:.2g} | >= 1000 |",
            f"| the same with the ABA cross-check as the analytic error | "
            f"{emc / hum.aba_agreement:.2g} | - |",
            f"| error of fd5 at the default step / analytic error estimate | "
            f"{_error_at(hum.curves['fd5'], 1e-3) / hum.analytic_error:.2g} | - |",
        ]
    lines += ["", "## Sweeps", ""]
    for r in results:
        lines += [f"### {r.name} ({r.kind}, nv = {r.nv})", "",
                  f"![{r.name}](accuracy_vs_time/{r.name}.png)", "",
                  "| h / eps | " + " | ".join(f"{k} error | {k} ms" for k in r.curves) + " |",
                  "|---|" + "---|---|" * len(r.curves)]
        for i, h in enumerate(STEPS):
            cells = [f"{c.errors[i]:.1e} | {_fmt_time(c.times[i])}" for c in r.curves.values()]
            lines.append(f"| {h:.0e} | " + " | ".join(cells) + " |")
        fine = [f"{c.refined[1]:.1e} at {c.refined[0]:.2e} | {_fmt_time(c.refined[2])}"
                if c.refined else "- | -" for c in r.curves.values()]
        lines.append("| fine search | " + " | ".join(fine) + " |")
        lines.append(f"\nanalytic: {_fmt_time(r.analytic_time)} ms, error estimate "
                     f"{r.analytic_error:.1e}" + (f". MuJoCo: {r.note}" if r.note else "") + "\n")
    text = "\n".join(lines) + "\n"
    make_folder(out)
    write_text_atomic(out / "accuracy_vs_time.md", text)
    return text


def _fmt_error(e: float) -> str:
    return "n/a" if not np.isfinite(e) else f"{e:.1e}"


def _error_at(curve: Curve, h: float) -> float:
    k = int(np.argmin(np.abs(np.log10(np.array(curve.steps)) - np.log10(h))))
    return curve.errors[k]


def _mujoco_version() -> str:
    import mujoco

    return mujoco.__version__


def plot(results: list[SystemResult], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    folder = make_folder(out / "accuracy_vs_time")
    style = {"fd3": "o-", "fd5": "s-", "mujoco forward": "v--", "mujoco centered": "^--"}
    for r in results:
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
        for key, c in r.curves.items():
            line, = ax1.loglog(c.steps, c.errors, style[key], label=key)
            if c.refined is not None:
                ax1.loglog([c.refined[0]], [c.refined[1]], "x", color=line.get_color(), ms=9)
            ax2.loglog(np.array(c.times) * 1e3, c.errors, style[key].replace("-", ""), label=key)
        ax1.axhline(r.analytic_error, color="k", lw=1, ls=":", label="analytic (est.)")
        ax1.set_xlabel("step h / eps")
        ax1.set_ylabel("max |A - A_analytic| / max |A_analytic|")
        ax1.set_title(f"{r.name}: error versus step")
        ax1.invert_xaxis()
        ax2.loglog([r.analytic_time * 1e3], [r.analytic_error], "k*", ms=14, label="analytic")
        ax2.set_xlabel("median time [ms]")
        ax2.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax2.set_title(f"{r.name}: error versus time")
        for ax in (ax1, ax2):
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
        fig.tight_layout()
        try:
            write_atomic(folder / f"{r.name}.png",
                         lambda fh, fig=fig: fig.savefig(fh, format="png", dpi=90))
        finally:
            plt.close(fig)


def run(systems: list[str], repeats: int = 5, out_dir: str | Path = "validation/reports",
        progress: bool = True, command: str = "pinlin bench") -> list[SystemResult]:
    """Measure ``systems`` (robot or bundled scene names, scene or URDF files), write the
    report and plots (atomically) into ``out_dir``.

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
    text = report(results, out, command)
    print(text)
    return results


def main(argv: list[str] | None = None) -> int:
    """``python validation/accuracy_vs_time.py`` and ``pinlin bench`` share this parser."""
    from .cli import main as cli_main

    return cli_main(["bench", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
