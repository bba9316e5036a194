"""What the command line prints and how it reads file names: matrices with their row and
column names, operating points, poles, plurals (the parsing itself is in :mod:`pinlin.cli`)."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .exceptions import ArgumentError
from .fields import written_float

if TYPE_CHECKING:
    from .coordinates import JointInfo
    from .scene import Scene

#: Width of printed matrices: wider ones are printed in labelled blocks of columns.
MATRIX_WIDTH = 100


@contextmanager
def options_named(options: dict[str, str]) -> Iterator[None]:
    """Re-raise a library ArgumentError naming its command-line option (``dx0`` is --x0)."""
    try:
        yield
    except ArgumentError as exc:
        if exc.argument not in options:
            raise
        raise ArgumentError(options[exc.argument], exc.reason) from None


def strict_float(text: str) -> float:
    """A number given on the command line (:func:`pinlin.fields.written_float`: no
    underscores or non-ASCII digits; a ValueError, as ``float``'s)."""
    return written_float(text)


strict_float.__name__ = "float"   # argparse's message: "invalid float value: '1_0'"


def scene_of(target: str) -> Scene:
    """:meth:`pinlin.Scene.resolve` of the command line's SCENE_OR_ROBOT, its errors naming
    that argument (the library's name for it is ``target``)."""
    from .scene import Scene

    with options_named({"target": "SCENE_OR_ROBOT", "name": "SCENE_OR_ROBOT"}):
        return Scene.resolve(target)


def mode_rows(modes, numbers: list[int] | None, option: str) -> list[int] | None:
    """Eigenvalue indices of the mode-table rows ``numbers`` (1 = first row, as printed) of a
    :class:`pinlin.ModalAnalysis`; a row named twice or beyond the table is refused."""
    if numbers is None:
        return None
    if len(set(numbers)) != len(numbers):
        raise ArgumentError(option, f"names a mode twice: {' '.join(map(str, numbers))}")
    keep = modes.modes()
    out = []
    for k in numbers:
        if not 1 <= k <= len(keep):
            raise ArgumentError(option, f"no mode {k}: the mode table of "
                                        f"'{modes.model.name}' has rows 1 to {len(keep)}"
                                if keep else f"no mode {k}: the model has no modes")
        out.append(keep[k - 1])
    return out


def plural(count: int, word: str, plural: str | None = None) -> str:
    """"1 input", "2 inputs" (``plural`` for irregular words)."""
    return f"{count} {word if count == 1 else plural or word + 's'}"


def file_name(option: str) -> Callable[[str], str]:
    """argparse ``type`` for an output option: an empty value is refused at once (it would
    otherwise be taken as "no file" and silently save nothing)."""

    def check(text: str) -> str:
        if not text.strip():
            raise ArgumentError(option, "needs a file name, got an empty string")
        if text.endswith(("/", os.sep)):   # Path() would drop the slash and write a file
            raise ArgumentError(option, f"needs a file name, got {text!r}, which names a "
                                        "folder")
        return text

    return check


def folder_name(value: str, option: str) -> str:
    if not value.strip():
        raise ArgumentError(option, "needs a folder name, got an empty string")
    return value


def check_out(path: Path, formats: Sequence[str], kind: str = "model") -> None:
    """Refuse an --out path before any work, so that a failure writes nothing: a format not in
    ``formats`` (suffixes), a folder, a folder that does not exist or is a file, no
    permission."""
    from .exceptions import ModelFileError
    from .files import check_file_target

    if path.suffix not in formats:
        names = list(formats)
        listed = ", ".join(names[:-1]) + " or " + names[-1] if len(names) > 1 else names[0]
        raise ModelFileError(path, f"unknown {kind} format '{path.suffix}'; expected {listed}")
    check_file_target(path, kind="model")     # both callers write a (trajectory) model
    parent = path.parent if str(path.parent) else Path(".")
    if not os.access(parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise ModelFileError(path, "cannot write: permission denied")


def _fmt(values: np.ndarray) -> str:
    return np.array2string(np.asarray(values), precision=6, suppress_small=True,
                           max_line_width=100)


def _number(x: float) -> str:
    """A matrix entry: 6 significant digits, exact zeros (also -0) as 0."""
    return "0" if x == 0 else f"{x:.6g}"


def _vector(values: np.ndarray) -> str:
    """[a b c] with 6 significant digits."""
    return "[" + " ".join(_number(float(x)) for x in values) + "]"


def format_matrix(key: str, matrix: np.ndarray, rows: Sequence[str], columns: Sequence[str],
                  width: int = MATRIX_WIDTH) -> str:
    """``key =`` and the matrix with its row and column names, in blocks of whole columns
    that fit in ``width`` characters; each block after the first of several names its
    columns (``A, columns 9-16 of 76 (v:...):``). Entries print with 6 significant digits;
    an exact zero as ``0`` and a nonzero entry below 1e-12 of the largest (rounding noise, for
    a matrix computed in float64) as ``~0``."""
    matrix = np.asarray(matrix)
    n_rows, n_cols = matrix.shape
    head = f"{key} = ({n_rows} x {n_cols})"
    if matrix.size == 0:
        return f"{head} empty"
    noise = 1e-12 * float(np.abs(matrix).max())
    cells = [[_number(float(x)) if not 0 < abs(x) < noise else "~0" for x in row]
             for row in matrix]
    label = max(len(r) for r in rows)
    widths = [max(len(columns[j]), *(len(cells[i][j]) for i in range(n_rows)))
              for j in range(n_cols)]
    blocks: list[tuple[int, int]] = []
    start, used = 0, label
    for j, w in enumerate(widths):
        if j > start and used + 2 + w > width:
            blocks.append((start, j))
            start, used = j, label
        used += 2 + w
    blocks.append((start, n_cols))
    lines = [head]
    for a, b in blocks:
        if len(blocks) > 1:
            lines.append(f"{key}, columns {a + 1}-{b} of {n_cols} ({columns[a]} .. "
                         f"{columns[b - 1]}):")
        lines.append(" " * label + "".join(f"  {columns[j]:>{widths[j]}}" for j in range(a, b)))
        for i in range(n_rows):
            lines.append(f"{rows[i]:<{label}}" + "".join(f"  {cells[i][j]:>{widths[j]}}"
                                                          for j in range(a, b)))
    return "\n".join(lines)


def _joint_value(j: JointInfo, values: np.ndarray) -> str:
    """A joint's configuration as a person reads it: angle, position and rpy, or the value."""
    import pinocchio as pin

    from .coordinates import FREE_FLYER, SPHERICAL

    if j.continuous:
        return f"{float(np.arctan2(values[1], values[0])):.6g} (angle)"
    if j.kind in (FREE_FLYER, SPHERICAL):
        quat = values[3:7] if j.kind == FREE_FLYER else values[:4]
        rpy = pin.rpy.matrixToRpy(pin.Quaternion(np.asarray(quat, float)).matrix())
        where = f"position {_vector(values[:3])} m, " if j.kind == FREE_FLYER else ""
        return f"{where}rpy {_vector(rpy)} rad"
    return _fmt(values) if j.nq > 1 else f"{values[0]:.6g}"


def print_operating_point(model, system) -> None:
    op = model.operating_point
    print(f"scene '{model.name}': nq = {system.nq}, nv = {system.nv}, "
          f"{plural(model.n_inputs, 'input')}, {plural(model.n_outputs, 'output')}; "
          f"base {model.info['base']}")
    effects = model.info["effects"]
    print(f"effects in play: {', '.join(effects) if effects else 'none'}")
    extra = ""
    if "alpha" in model.info:
        extra = (f", alpha = {model.info['alpha']:g}, mu = {model.info['mu']:g}, "
                 f"Omega = {model.info['omega']:g} rad/s")
    elif "basis" in model.info:
        extra = f", {model.info['basis']} basis"
    steps = ""
    if "step" in model.info:
        steps = " (steps " + ", ".join(f"{k} {v:g}" for k, v in model.info["step"].items()) + ")"
    print(f"linear model: {model.info['formulation']} formulation, "
          f"{model.info['derivatives']} derivatives{steps}{extra}")
    if "error_estimate" in model.info:
        print(f"error estimate of A (relative, truncation + rounding): "
              f"{model.info['error_estimate']:.1e}")
    print("operating point:")
    for name, j in system.joints.items():
        print(f"  q[{name}] = {_joint_value(j, op.q[j.idx_q:j.idx_q + j.nq])}")
    for name, u in zip(model.input_names, op.u, strict=True):
        print(f"  {name} = {u:.6g}")
    if op.lam is not None:
        for name, lam in zip(op.lam_names, op.lam, strict=True):
            print(f"  lam[{name}] = {lam:.6g}")
    worst = float(np.abs(op.residual).max(initial=0.0)) if op.residual is not None else 0.0
    state = "equilibrium" if op.equilibrium else "NOT an equilibrium"
    print(f"  residual max |r| = {worst:.3e} (tolerance {op.tolerance:.1e}): {state}")
    for note in op.notes:
        print(f"  note: {note}")


def format_poles(A: np.ndarray) -> str:
    """The eigenvalues of A, slowest first, a conjugate pair once as ``re +- im j``; "none"
    for a model without states."""
    if A.size == 0:
        return "none"
    lam = np.linalg.eigvals(A)
    lam = lam[np.lexsort((-lam.imag, lam.real, np.abs(lam)))]
    shown = []
    for x in lam:
        if x.imag < 0 and np.any(np.isclose(lam, x.conjugate(), rtol=1e-12, atol=0.0)):
            continue  # printed with its partner
        re = _number(float(x.real))
        shown.append(f"{re} +- {_number(float(x.imag))}j" if x.imag > 0 else re)
    return ", ".join(shown)
