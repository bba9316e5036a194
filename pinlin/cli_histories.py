"""The pieces the timed motion commands share (``pinlin simulate``, ``pinlin response``,
``pinlin validity``): the time grid of --t-end and --dt, NAME=VALUE options such as --x0, and
the time histories (``--out`` .csv or .npz) and plots (``--plot``) they write, both or
neither."""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import numpy as np

from .cli_format import strict_float
from .exceptions import ArgumentError, ModelFileError
from .files import all_or_nothing

#: Formats of the time histories ``simulate`` and ``response`` write.
HISTORY_FORMATS = (".csv", ".npz")


def times(args: argparse.Namespace) -> np.ndarray:
    """The time grid 0, dt, 2 dt, ..., t_end [s] of --t-end and --dt (t_end itself last, also
    where --dt does not divide it)."""
    if not (np.isfinite(args.t_end) and args.t_end > 0):
        raise ArgumentError("--t-end", f"expected a duration > 0 [s], got {args.t_end:g}")
    if not (np.isfinite(args.dt) and 0 < args.dt <= args.t_end):
        raise ArgumentError("--dt", f"expected an output step in (0, --t-end] [s], got "
                                    f"{args.dt:g}")
    count = np.floor(args.t_end / args.dt + 1e-9) + 1.0
    if not count <= 1_000_000:  # a float: --t-end 1e300 / --dt 0.01 overflows no int
        raise ArgumentError("--dt", f"--t-end / --dt gives {count:.3g} output times; at most "
                                    "1000000 (raise --dt or shorten --t-end)")
    grid = np.arange(int(count)) * args.dt
    if args.t_end - grid[-1] > 1e-9 * args.dt:
        grid = np.append(grid, args.t_end)
    return grid


def assignments(values: list[str] | None, names: tuple[str, ...], option: str,
                 prefix: str) -> dict[str, str]:
    """NAME=VALUE pairs, each NAME one of ``names`` (``prefix`` may be left out)."""
    out: dict[str, str] = {}
    for item in values or []:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name or not value.strip():
            raise ArgumentError(option, f"expected NAME=VALUE, got {item!r}")
        if name not in names and f"{prefix}{name}" in names:
            name = f"{prefix}{name}"
        if name not in names:
            shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "")
            raise ArgumentError(option, f"{name!r} is not one of {shown}")
        if name in out:
            raise ArgumentError(option, f"{name!r} is given twice ({out[name]} and "
                                        f"{value.strip()}); give each name once")
        out[name] = value.strip()
    return out


def number(text: str, option: str) -> float:
    try:
        value = strict_float(text)
    except ValueError:
        raise ArgumentError(option, f"expected a number, got {text!r}") from None
    if not np.isfinite(value):
        raise ArgumentError(option, f"expected a finite number, got {text!r}")
    return value


def initial_state(model, values: list[str] | None) -> np.ndarray | None:
    """--x0 NAME=VALUE pairs as a state deviation (the model's state names)."""
    given = assignments(values, model.state_names, "--x0", "q:")
    if not given:
        return None
    x0 = np.zeros(len(model.state_names))
    for name, value in given.items():
        x0[model.state_names.index(name)] = number(value, "--x0")
    return x0


def check_history_out(path: str | None, option: str = "--out") -> Path | None:
    from .files import check_file_target

    if path is None:
        return None
    out = Path(path)
    if out.suffix not in HISTORY_FORMATS:
        raise ModelFileError(out, f"unknown format '{out.suffix}' for time histories; "
                                  f"expected {' or '.join(HISTORY_FORMATS)}")
    check_file_target(out, kind="history")
    return out


def check_plot(path: str | None) -> Path | None:
    from .files import check_file_target

    if path is None:
        return None
    out = Path(path)
    if out.suffix != ".png":
        raise ModelFileError(out, "expected a .png file for the plot")
    check_file_target(out)
    return out


def write_history(path: Path, t: np.ndarray, columns: dict[str, np.ndarray]) -> None:
    """t and named columns as CSV (the marker line :data:`pinlin.files.HISTORY_MARKER`, then a
    header row) or NPZ (arrays t, names, values)."""
    from .files import HISTORY_MARKER, write_bytes_atomic, write_text_atomic

    names = list(columns)
    values = np.column_stack([t] + [columns[n] for n in names])
    if path.suffix == ".csv":
        marker = (HISTORY_MARKER.decode() + " t [s]; the states (q:, v:, nl:) as "
                  "deviations from the operating point, outputs y: and inputs u: as values "
                  "(SI units); not a states file")
        lines = [marker, ",".join(["t", *names])]
        lines += [",".join(f"{x:.17g}" for x in row) for row in values]
        write_text_atomic(path, "\n".join(lines) + "\n")
    else:
        buf = io.BytesIO()
        np.savez(buf, t=t, names=np.array(names, dtype=str), values=values[:, 1:])
        write_bytes_atomic(path, buf.getvalue())


def plot_histories(path: Path, title: str, t: np.ndarray,
                    curves: list[tuple[str, np.ndarray, np.ndarray, str]]) -> None:
    """One panel per state group (positions, velocities): curves (label, t, y, style)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .files import PNG_METADATA, write_bytes_atomic

    fig, ax = plt.subplots(figsize=(7, 4))
    for label, tc, y, style in curves[:24]:
        ax.plot(tc, y, style, label=label, linewidth=1.0)
    ax.set_xlabel("t [s]")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    if len(curves) <= 12:
        ax.legend(fontsize=7, ncol=2)
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=90, metadata=PNG_METADATA)
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())


def write_results(out: Path | None, plot: Path | None, t: np.ndarray,
                   columns: dict[str, np.ndarray], title: str,
                   curves: list[tuple[str, np.ndarray, np.ndarray, str]]) -> list[str]:
    """The time histories (``--out``) and their plot (``--plot``), both or neither
    (:func:`pinlin.files.all_or_nothing`), before anything is printed: a failed write prints
    one line, not the result. The lines that say what was written."""
    written = []
    with all_or_nothing():
        if out is not None:
            write_history(out, t, columns)
            written.append(f"time histories written to {out}")
        if plot is not None:
            plot_histories(plot, title, t, curves)
            written.append(f"plot written to {plot}")
    return written


__all__ = ["HISTORY_FORMATS", "assignments", "check_history_out", "check_plot",
           "initial_state", "number", "plot_histories", "times", "write_history",
           "write_results"]
