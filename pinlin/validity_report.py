"""The result of :func:`pinlin.validity` (:class:`Validity`, one :class:`Case` per mode or
direction) and its text and figures:

- :func:`notes`: what the user should know (not an equilibrium, failed simulations, ...);
- :func:`table`: one summary row per case (radius, how it was found, order), then each case's
  error-vs-amplitude rows;
- :func:`plot`: ``<stem>_histories.png``, the nonlinear and linear deviations Dnl, Dlin of the
  dominant coordinate at each case's radius beside the running relative error; and
  ``<stem>_errors.png``, the relative error e against the amplitude on log-log axes with the
  tolerance line, the radius of each case and its order p (e ~ a^(p-1)).

Figures use matplotlib's Agg backend and are written atomically (:mod:`pinlin.files`).
"""

from __future__ import annotations

import enum
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .exceptions import ArgumentError
from .files import PNG_METADATA, all_or_nothing, make_folder, write_bytes_atomic
from .linear_model import LinearModel
from .modal import ModalAnalysis

#: Most cases drawn in the histories figure (one row each).
MAX_ROWS = 12


class Bound(enum.Enum):
    """Where the tolerance was crossed."""

    FOUND = "found"            #: between two amplitudes; the radius is interpolated, checked
    ABOVE_RANGE = "above"      #: error within tolerance at every amplitude: radius >= largest
    BELOW_RANGE = "below"      #: beyond tolerance at the smallest amplitude: radius < smallest


#: The kinds (:meth:`pinlin.ModalAnalysis.kind`) of a mode whose eigenvalue has an imaginary
#: part (:meth:`pinlin.ModalAnalysis.oscillates`).
OSCILLATING = ("oscillatory", "undamped", "unstable osc.")


@dataclass(frozen=True, eq=False)
class Case:
    """The sweep of one mode or direction (read-only arrays).

    Attributes:
        label: ``"mode 3"`` (its row in :meth:`ModalAnalysis.table`) or ``"direction ..."``.
        index: Eigenvalue index in ``Validity.modes`` (None for a direction).
        eigenvalue: lambda [1/s] (None for a direction).
        kind: :meth:`ModalAnalysis.kind` of the mode, or ``"direction"``.
        direction: (2n,) initial state per unit amplitude [rad or m], largest weighted
            |position| entry 1 (``Validity.weights``).
        unit: Unit of the amplitudes: ``"rad or L"``, a length's in units of ``Validity.length``
            (``"rad/s or L/s"`` for a pure velocity); ``"rad or m"`` (``"rad/s or m/s"``) where
            no coordinate is a length.
        horizon: T [s]; ``horizon_rule``: how it was chosen.
        amplitudes: (k,) increasing, in ``unit``.
        errors, position_errors, velocity_errors: (k,) e, e_q, e_v (inf: simulation failed).
        failures: (k,) the failed simulation's message, else "".
        radius: Largest amplitude within tolerance (``bound`` says how it was found), in unit.
        bound: :class:`Bound`.
        error_at_radius: e at ``radius``.
        excursions: (n,) |joint excursions| at t = 0 at the radius [rad or m], radius |d_q|.
        peak: max_t max_j w_j |Dnl_qj| at the radius, in rad or L (the positions' unit, for a
            velocity direction too; grows past the radius when unstable).
        slope: Order p of the error (:mod:`pinlin.validity`); NaN with fewer than two points.
        diagnosis: What p says.
        reference_drift: max_t max_j w_j |z_nl(t; 0)|, the unperturbed motion (0 at
            equilibrium).
        t, nonlinear, linear: Time [s] and Dnl, Dlin (N, 2n) at the radius (None if none ran).
        notes: What the simulations met (a spring of a continuous joint past its wrap).
    """

    label: str
    index: int | None
    eigenvalue: complex | None
    kind: str
    direction: np.ndarray
    unit: str
    horizon: float
    horizon_rule: str
    amplitudes: np.ndarray
    errors: np.ndarray
    position_errors: np.ndarray
    velocity_errors: np.ndarray
    failures: tuple[str, ...]
    radius: float
    bound: Bound
    error_at_radius: float
    excursions: np.ndarray
    peak: float
    slope: float
    diagnosis: str
    reference_drift: float
    t: np.ndarray | None = None
    nonlinear: np.ndarray | None = None
    linear: np.ndarray | None = None
    notes: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Validity:
    """Result of :func:`validity`; print it (or :meth:`table`) for a summary.

    Attributes:
        name: The scene's name.
        model: The linear model compared (independent formulation, analytic derivatives).
        modes: Its :func:`pinlin.modal` analysis (``Case.index`` refers to it).
        tolerance: Relative error bound; periods, time_constants: the horizon's settings.
        cases: One :class:`Case` per mode or direction.
        equilibrium: Whether the point is an equilibrium (f0 absent or zero).
        drift: max |f0| [rad/s, m/s, rad/s^2 or m/s^2] (0 at an equilibrium).
        notes: What the user should know (equilibrium, failures, first-order errors).
        seconds: Wall time [s]; simulations: nonlinear simulations run.
        coordinate_names: The model's position coordinates (joint names).
        length: L [m], the unit of a length in the amplitudes (the robot's characteristic
            length at the point), or None where no coordinate of the model is a length.
        weights: (n,) w_j, 1 per rad and 1/L per m of each position coordinate (and of its
            velocity): errors and amplitudes are measured in w_j-weighted entries.
    """

    name: str
    model: LinearModel
    modes: ModalAnalysis
    tolerance: float
    periods: float
    time_constants: float
    cases: tuple[Case, ...]
    equilibrium: bool
    drift: float
    notes: tuple[str, ...]
    seconds: float
    simulations: int
    coordinate_names: tuple[str, ...] = field(default=())
    length: float | None = None
    weights: np.ndarray | None = None

    @property
    def radius(self) -> np.ndarray:
        """(cases,) the validity radius of each case, in its ``unit``."""
        return np.array([c.radius for c in self.cases])

    @property
    def slope(self) -> np.ndarray:
        """(cases,) the order p of each case's error (:mod:`pinlin.validity`)."""
        return np.array([c.slope for c in self.cases])

    def case(self, label: str) -> Case:
        """The case named ``label`` (``"mode 1"``, ``"direction q:elbow"``)."""
        for c in self.cases:
            if c.label == label:
                return c
        raise ArgumentError("label", f"no case {label!r:.60}; expected one of "
                                     f"{', '.join(c.label for c in self.cases)}")

    def table(self, sweeps: bool = True) -> str:
        """The summary (and each case's error-vs-amplitude rows when ``sweeps``)."""
        return table(self, sweeps)

    def plot(self, folder: str | Path, stem: str | None = None) -> tuple[Path, Path]:
        """Write ``<stem>_histories.png`` (nonlinear vs linear at each radius) and
        ``<stem>_errors.png`` (error vs amplitude, log-log) atomically into ``folder``."""
        return plot(self, folder, stem or self.name)

    def __str__(self) -> str:
        return self.table(sweeps=False)


def notes(cases: list[Case], drift: float, tol: float, first_order: float) -> list[str]:
    """What the user should know about a validity sweep (``Validity.notes``); orders below
    ``first_order`` are first order."""
    out = []
    if drift > 0.0:
        out.append(f"not an equilibrium: max |f0| = {drift:.3g} (x' = f0 + A x); errors "
                   "compare the deviations from the unperturbed motions, and a model made away "
                   "from an equilibrium leaves errors of first order in the amplitude")
    first = [c.label for c in cases if c.slope < first_order and not c.notes]
    if first and drift == 0.0:
        out.append(f"first-order error at an equilibrium ({', '.join(first)}): the linear "
                   "model does not match the simulated dynamics")
    for c in cases:
        out += [f"{c.label}: {note}" for note in c.notes]
        failed = [f for f in c.failures if f]
        if failed:
            out.append(f"{c.label}: {len(failed)} simulation(s) failed, counted beyond "
                       f"tolerance; first: {failed[0]}")
        if c.bound is Bound.BELOW_RANGE:
            out.append(f"{c.label}: error {c.errors[0]:.3g} > {tol:g} already at the "
                       f"smallest amplitude {c.amplitudes[0]:g} {c.unit}")
    return out


def _dominant(result: Validity, c: Case) -> int:
    """Index of the case's largest weighted position entry (its dominant coordinate)."""
    n = len(result.coordinate_names)
    w = np.ones(n) if result.weights is None else result.weights
    return int(np.argmax(np.abs(c.direction[:n]) * w))


def _eigenvalue(c: Case) -> str:
    if c.eigenvalue is None:
        return "-"
    lam = c.eigenvalue   # as the mode table says: +-j where the mode oscillates, Re 0 undamped
    re = "0" if c.kind == "undamped" else f"{lam.real:+.4g}"
    return f"{re} +- {abs(lam.imag):.4g}j" if c.kind in OSCILLATING else re


def _percent(e: float) -> str:
    return "failed" if not math.isfinite(e) else f"{100 * e:.3g}%"


def table(result: Validity, sweeps: bool = True) -> str:
    """The summary of ``result`` (module docstring)."""
    point = "equilibrium" if result.equilibrium else f"NOT an equilibrium (|f0| = " \
                                                     f"{result.drift:.3g})"
    loop = result.model.info.get("closed_loop")   # "u = -K x + r, K of shape (m, n)"
    what = f"the closed loop {loop.split(',')[0]} of '{result.name}'" if loop else \
        f"'{result.name}'"
    lines = [f"Validity of the linear model of {what} ({point}): relative error "
             f"<= {_percent(result.tolerance)} over {result.periods:g} periods "
             f"({result.time_constants:g} time constants for real modes); "
             f"{result.simulations} simulations, {result.seconds:.1f} s"]
    if result.length is not None:
        lines.append(f"amplitudes in rad, and in units of L = {result.length:.4g} m (the "
                     "robot's characteristic length) for lengths")
    head = (f"{'case':<22} {'kind':<13} {'eigenvalue [1/s]':>22} {'T [s]':>8} "
            f"{'radius':>10} {'unit':<8} {'bound':<6} {'e(radius)':>9} {'peak':>9} "
            f"{'order':>5}  dominant coordinate")
    lines += [head, "-" * len(head)]
    for c in result.cases:
        dom = result.coordinate_names[_dominant(result, c)] if result.coordinate_names else "-"
        unit = c.unit.replace(" or ", "|")
        order = "-" if not math.isfinite(c.slope) else f"{c.slope:.2f}"
        bound = {"found": "=", "above": ">=", "below": "<"}[c.bound.value]
        lines.append(f"{c.label:<22.22} {c.kind:<13} {_eigenvalue(c):>22} {c.horizon:>8.3g} "
                     f"{c.radius:>10.4g} {unit:<8} {bound:<6} "
                     f"{_percent(c.error_at_radius):>9} {c.peak:>9.3g} {order:>5}  {dom}")
    for note in result.notes:
        lines.append(f"note: {note}")
    if sweeps:
        for c in result.cases:
            lines += ["", f"{c.label}: horizon {c.horizon:.4g} s ({c.horizon_rule}); "
                          f"{c.diagnosis}",
                      f"  {'amplitude':>10}  {'error':>10}  {'positions':>10}  "
                      f"{'velocities':>10}"]
            for a, e, eq, ev in zip(c.amplitudes, c.errors, c.position_errors,
                                    c.velocity_errors, strict=True):
                mark = " <- radius" if a == c.radius else ""
                lines.append(f"  {a:>10.4g}  {e:>10.3e}  {eq:>10.3e}  {ev:>10.3e}{mark}")
    return "\n".join(lines)


def _save(fig: object, path: Path) -> None:
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format="png", dpi=70,  # type: ignore[attr-defined]
                    metadata=PNG_METADATA)
    finally:
        plt.close(fig)  # type: ignore[arg-type]
    write_bytes_atomic(path, buffer.getvalue())


def plot_paths(folder: Path, stem: str) -> tuple[Path, Path]:
    """The two figures :func:`plot` writes into ``folder``."""
    return folder / f"{stem}_histories.png", folder / f"{stem}_errors.png"


def plot(result: Validity, folder: str | Path, stem: str) -> tuple[Path, Path]:
    """Write the two figures of ``result`` into ``folder`` (created if needed); their paths."""
    import matplotlib

    matplotlib.use("Agg")
    folder = make_folder(folder)
    paths = plot_paths(folder, stem)
    with all_or_nothing():      # both figures, or neither
        _save(_histories(result), paths[0])
        _save(_errors(result), paths[1])
    return paths


def _histories(result: Validity) -> object:
    import matplotlib.pyplot as plt

    cases = [c for c in result.cases if c.t is not None and c.nonlinear is not None][:MAX_ROWS]
    rows = max(len(cases), 1)
    fig, axes = plt.subplots(rows, 2, figsize=(10, 2.3 * rows + 0.6), squeeze=False,
                             gridspec_kw={"width_ratios": [3, 2]})
    n = len(result.coordinate_names)
    for row, c in zip(axes, cases, strict=False):
        j = _dominant(result, c)
        name = result.coordinate_names[j]
        w = np.ones(2 * n) if result.weights is None else np.tile(result.weights, 2)
        row[0].plot(c.t, c.nonlinear[:, j], "-", lw=1.4, label="nonlinear (simulate)")
        row[0].plot(c.t, c.linear[:, j], "--", lw=1.2, label="linear (exact)")
        row[0].set_ylabel(f"d{name} [{'rad' if w[j] == 1.0 else 'm'}]")
        row[0].set_title(f"{c.label} ({c.kind}): a = {c.radius:.3g} {c.unit}, "
                         f"e = {_percent(c.error_at_radius)}", fontsize=9)
        row[0].grid(True, alpha=0.3)
        row[0].legend(fontsize=7, loc="upper right")
        for cols, what, color in ((slice(0, n), "positions", "C3"),
                                  (slice(n, 2 * n), "velocities", "C2")):
            diff = (np.abs(c.nonlinear - c.linear) * w)[:, cols].max(axis=1)
            peak = (np.abs(c.linear) * w)[:, cols].max()
            if peak > 0:
                row[1].plot(c.t, 100 * np.maximum.accumulate(diff) / peak, color=color, lw=1.2,
                            label=f"{what} (max so far)")
        row[1].axhline(100 * result.tolerance, color="k", ls=":", lw=1, label="tolerance")
        row[1].set_ylabel("running error [%]")
        row[1].grid(True, alpha=0.3)
        row[1].legend(fontsize=7, loc="upper left")
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    fig.suptitle(f"{result.name}: nonlinear vs linear motion at the validity radius",
                 fontsize=10)
    fig.tight_layout()
    return fig


def _errors(result: Validity) -> object:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.8))
    for k, c in enumerate(result.cases):
        ok = np.isfinite(c.errors) & (c.errors > 0)
        order = "?" if not math.isfinite(c.slope) else f"{c.slope:.2f}"
        color = f"C{k % 10}"
        ax.loglog(c.amplitudes[ok], c.errors[ok], "o-", ms=4, color=color,
                  label=f"{c.label} ({c.kind}), order {order}")
        if c.amplitudes[0] <= c.radius <= c.amplitudes[-1]:
            ax.axvline(c.radius, color=color, ls=":", lw=1)
        failed = ~np.isfinite(c.errors)
        if failed.any():
            ax.plot(c.amplitudes[failed], np.full(failed.sum(), 1.0), "x", color=color)
    ax.axhline(result.tolerance, color="k", ls="--", lw=1,
               label=f"tolerance {_percent(result.tolerance)}")
    units = sorted({c.unit for c in result.cases if not c.unit.startswith("rad/s")}) or \
        sorted({c.unit for c in result.cases})
    length = "" if result.length is None else f", L = {result.length:.3g} m"
    ax.set_xlabel(f"amplitude a (largest joint excursion) [{' | '.join(units)}{length}]")
    ax.set_ylabel("relative error e = max|Dnl - Dlin| / max|Dlin|" if result.length is None
                  else "relative error e = max w|Dnl - Dlin| / max w|Dlin|")
    ax.set_title(f"{result.name}: error vs amplitude (order p: e ~ a^(p-1))", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


__all__ = ["Bound", "Case", "Validity", "notes", "plot", "table"]
