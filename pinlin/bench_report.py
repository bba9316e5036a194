"""The report of ``pinlin bench``: ``accuracy_vs_time.md`` and one PNG per system under
``accuracy_vs_time/``, written atomically. The report merges into an existing one: the rows and
sweep sections of systems not measured again are kept in place, and the header names them.
"""

from __future__ import annotations

import platform
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .files import PNG_METADATA, make_folder, write_atomic, write_text_atomic

if TYPE_CHECKING:
    from .bench import Curve, SystemResult


def _fmt_time(t: float) -> str:
    return f"{t * 1e3:.3f}" if t < 1 else f"{t * 1e3:.0f}"


def _headline_row(r: SystemResult) -> str:
    cells = []
    for key in ("fd3", "fd5", "mujoco forward", "mujoco centered"):
        if key in r.curves:
            h, e, t = r.curves[key].best()
            cells.append(f"{h:.1e}, {e:.1e}, {_fmt_time(t)}")
        else:
            cells.append("n/a")
    return (f"| {r.name} ({r.kind}) | {r.nv} | {_fmt_time(r.analytic_time)} | "
            f"{r.analytic_error:.1e} | {_fmt_error(r.aba_agreement)} | " + " | ".join(cells)
            + " |")


def _targets_section(hum: SystemResult) -> list[str]:
    from .bench import HUMANOID

    _, emc, _ = hum.curves["mujoco centered"].best()
    return [
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
        "",
    ]


def _sweep_section(r: SystemResult) -> list[str]:
    from .bench import STEPS

    lines = [f"### {r.name} ({r.kind}, nv = {r.nv})", "",
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
    return lines


def _system_of(heading: str) -> str:
    """System name of a headline cell or sweep heading: ``ur5 (fixed base, nv = 6)`` -> ur5."""
    return heading.strip().split(" (")[0]


def read_report(path: Path) -> tuple[dict[str, str], list[str] | None, dict[str, list[str]]]:
    """(headline rows, humanoid targets section, sweep sections) of an existing report, by
    system name in file order; empty if there is none."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return {}, None, {}
    rows: dict[str, str] = {}
    sweeps: dict[str, list[str]] = {}
    targets: list[str] | None = None
    section = ""
    current: list[str] | None = None
    for line in text.splitlines():
        if line.startswith("## "):
            section, current = line, None
            if line.startswith("## Targets"):
                targets = current = [line]
            continue
        if line.startswith("### ") and section.startswith("## Sweeps"):
            current = sweeps.setdefault(_system_of(line[4:]), [])
            current.append(line)
            continue
        if section.startswith("## Headline") and line.startswith("| ") \
                and not line.startswith("| system |"):
            rows[_system_of(line[2:].split(" |")[0])] = line
        elif current is not None:
            current.append(line)
    for block in ([targets] if targets else []) + list(sweeps.values()):
        while block and not block[-1].strip():
            block.pop()
        block.append("")
    return rows, targets, sweeps


def report(results: list[SystemResult], out: Path, command: str, merge: bool = True) -> str:
    """Write ``accuracy_vs_time.md`` (atomically) and return its text.

    With ``merge``, an existing report's rows and sections of systems not in ``results`` are
    kept in place (new systems are appended; the humanoid's targets are kept unless it was
    measured again), and the header names them: their times come from an earlier run,
    possibly on another machine, so times compare only within one run.
    """
    import pinocchio as pin

    from .bench import HUMANOID

    rows, targets, sweeps = read_report(out / "accuracy_vs_time.md") if merge else ({}, None, {})
    ran = {r.name for r in results}
    kept = [name for name in rows if name not in ran]
    for r in results:
        rows[r.name] = _headline_row(r)
        sweeps[r.name] = _sweep_section(r)
    hum = next((r for r in results if r.name == HUMANOID), None)
    if hum is not None:
        targets = _targets_section(hum) if hum.ratios else None
    note = (f" Rows of {', '.join(kept)} are kept from an earlier run (their times may come "
            "from another machine: compare times within one run only)." if kept else "")
    lines = [
        "# What accuracy costs in time",
        "",
        f"Produced by `{command}` on {platform.machine()} ({platform.processor() or 'cpu'}), "
        f"pin {pin.__version__}, MuJoCo {_mujoco_version()}, numpy {np.__version__}.{note} "
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
        *rows.values(),
        "",
    ]
    if targets:
        lines += targets
    lines += ["## Sweeps", ""]
    for name in rows:
        lines += sweeps.get(name, [])
    text = "\n".join(lines).rstrip("\n") + "\n"
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
                         lambda fh, fig=fig: fig.savefig(fh, format="png", dpi=90,
                                                                 metadata=PNG_METADATA))
        finally:
            plt.close(fig)


