"""Gain files: a state-feedback gain K (u = -K x) for the command line's ``--feedback``.

Two formats:

- ``.csv``, named: a header line ``input,<state>,<state>,...`` naming the linear model's
  states (``q:elbow``, ``v:elbow``, as ``model.state_names``), then one line per input,
  starting with its name (``u:elbow``, as ``model.input_names``) and giving its gains
  [N*m/rad, N*m*s/rad, or N/m ...]. Rows and columns in any order; every state and every input
  exactly once. Lines starting with ``#`` and blank lines are skipped, but for the design
  point :func:`write_gain` records, ``# q0 = ...`` and ``# v0 = ...`` (comma-separated, as
  the model's operating point q and v): where present it must be the model's (q and v to
  1e-9 relative, as :func:`pinlin.simulate` checks a pair (K, model)). The names are
  checked against the model: a gain written for another scene or formulation (a canonical
  model's ``p:`` states), or about another point, is refused instead of being applied to the
  wrong coordinates.
- ``.npy``: the matrix alone (n_inputs x n_states, in the model's orders), as ``np.save``
  writes ``control.lqr``'s K; never unpickled. Only its shape is checked.

:func:`write_gain` writes the named form (atomically) from Python.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np

from .closed_loop import gain_matrix, same_point
from .exceptions import ArgumentError, ModelFileError
from .files import GAIN_MARKER, as_path, check_file_target, write_text_atomic
from .linear_model import LinearModel
from .model_files import npy_header
from .trajectory_files import _content_lines, _csv_fields, _file, csv_number, csv_text, text_lines

GAIN_FORMATS = (".csv", ".npy")
#: The header's first field.
ROW_LABEL = "input"
#: The first line of a gain file pinlin writes (what lets it replace its own file).
MARKER = GAIN_MARKER.decode()


def read_gain(path: str | Path, model: LinearModel) -> np.ndarray:
    """The gain K (n_inputs x n_states, in ``model``'s orders) of a gain file.

    Raises:
        ArgumentError: ``path`` is not a path, or ``model`` not a LinearModel.
        ModelFileError: missing file, another suffix, a pickled or corrupt .npy, a wrong
            shape, names that are not the model's (naming the line and the name), text that
            is not a finite number (naming line and column), a design point that is not the
            model's.
    """
    path = as_path(path)
    _check_model(model)
    raw = _file(path, GAIN_FORMATS, "gain")
    if path.suffix == ".npy":
        K = _read_npy(path, raw)
        want = (model.n_inputs, model.n_states)
        if K.shape != want:
            raise ModelFileError(path, f"holds a {'x'.join(map(str, K.shape))} array; model "
                                       f"'{model.name}' needs {want[0]} x {want[1]} (inputs x "
                                       "states)")
        return K
    return _read_csv(path, raw, model)


def write_gain(path: str | Path, K: object, model: LinearModel) -> Path:
    """Write ``K`` (n_inputs x n_states of ``model``) as a named .csv gain file (17
    significant digits: read back bit for bit; names quoted where they hold a comma or a
    quote). Replaces only a gain file pinlin wrote, never a time history or a user's file.

    Raises:
        ArgumentError: ``model`` is not a LinearModel, or ``K`` is not a finite real matrix of
            its size (naming the first entry that is not finite).
        ModelFileError: not a .csv path, or a file there that is not a gain pinlin wrote.
    """
    path = as_path(path)
    _check_model(model)
    if path.suffix != ".csv":
        raise ModelFileError(path, "a gain file is written as .csv (names checked on "
                                   "reading); np.save writes the bare .npy form")
    K = gain_matrix(K, model.n_inputs, [model.n_states], "K")
    check_file_target(path, kind="gain")
    point = model.operating_point
    out = io.StringIO()
    out.write(f"{MARKER} u = -K x about the operating point of '{model.name}'\n")
    if point is not None:
        for key in ("q", "v"):
            out.write(f"# {key}0 = {','.join(repr(float(x)) for x in getattr(point, key))}\n")
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow((ROW_LABEL, *model.state_names))
    writer.writerows((name, *(repr(float(k)) for k in row))
                     for name, row in zip(model.input_names, K, strict=True))
    write_text_atomic(path, out.getvalue())
    return path


def _named(field: str, names: tuple[str, ...]) -> str:
    """A CSV field naming a state or an input: as written where that is a name (a URDF
    name may end in a space), else without the spaces around it."""
    return field if field in names else field.strip()


def _check_model(model: object) -> None:
    if not isinstance(model, LinearModel):
        raise ArgumentError("model", f"expected the pinlin LinearModel the gain belongs to, "
                                     f"got {type(model).__name__}")


def _read_npy(path: Path, raw: bytes) -> np.ndarray:
    """The array of a .npy file, its header read first: no pickles, and no allocation beyond
    the bytes the file holds."""
    fh = io.BytesIO(raw)
    try:
        shape, dtype, needed = npy_header(fh, path, ModelFileError)
    except ValueError as exc:
        raise ModelFileError(path, f"not a .npy array: {exc}") from None
    if dtype.kind not in "fiu" or len(shape) != 2:
        raise ModelFileError(path, f"holds a {len(shape)}-D array of {dtype}; expected a 2-D "
                                   "array of numbers (inputs x states)")
    if needed != len(raw) - fh.tell():
        raise ModelFileError(path, f"its header declares shape {shape} ({needed} bytes of "
                                   f"data) but the file holds {len(raw) - fh.tell()} bytes "
                                   "after it")
    try:
        K = np.load(io.BytesIO(raw), allow_pickle=False).astype(float)
    except (ValueError, OSError, EOFError) as exc:
        raise ModelFileError(path, f"not a .npy array: {exc}") from None
    if not np.all(np.isfinite(K)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(K))[0])
        raise ModelFileError(path, f"entry {list(bad)} is {K[bad]}, not a finite number")
    return K


def _read_csv(path: Path, raw: bytes, model: LinearModel) -> np.ndarray:
    text = csv_text(path, raw)
    lines = _content_lines(text)
    if not lines:
        raise ModelFileError(path, f"empty: expected a header '{ROW_LABEL},<state>,...' "
                                   "naming the model's states, then one line per input")
    states, inputs = model.state_names, model.input_names
    head_line = lines[0][0]
    header = [_named(c, states) for c in _csv_fields(path, *lines[0])]
    if header[0] != ROW_LABEL:
        raise ModelFileError(path, f"line {head_line}: the header starts with "
                                   f"{header[0]!r:.40}; expected '{ROW_LABEL}' (the column of "
                                   "input names), then the states, e.g. "
                                   f"'{ROW_LABEL},{','.join(states[:2])},...'")
    column = _index(path, head_line, header[1:], states, "state", model.name)
    _check_point(path, text, model)
    K = np.full((len(inputs), len(states)), np.nan)
    seen: dict[str, int] = {}
    for number, line in lines[1:]:
        fields = _csv_fields(path, number, line)
        fields[0] = _named(fields[0], inputs)
        if len(fields) != len(header):
            raise ModelFileError(path, f"line {number}: {len(fields)} values, the header "
                                       f"names {len(header)} columns")
        name = fields[0]
        if name in seen:
            raise ModelFileError(path, f"line {number}: input '{name}' appears twice (first "
                                       f"on line {seen[name]})")
        seen[name] = number
        if name not in inputs:
            raise ModelFileError(path, f"line {number}: {name!r:.40} is not an input of model "
                                       f"'{model.name}'; expected one of "
                                       f"{', '.join(inputs) or '(none: it has no inputs)'}")
        row = inputs.index(name)
        for k, cell in enumerate(fields[1:]):
            K[row, column[k]] = csv_number(path, f"line {number}, column '{header[1 + k]}'",
                                           cell)
    missing = [name for name in inputs if name not in seen]
    if missing:
        raise ModelFileError(path, f"no line for input{'s' if len(missing) > 1 else ''} "
                                   f"{', '.join(missing)} of model '{model.name}'")
    return K


_POINT_LINE = re.compile(r"\s*#+\s*([qv]0)\s*[=:](.*)", re.IGNORECASE)


def _check_point(path: Path, text: str, model: LinearModel) -> None:
    """The design point of the comment lines ``# q0 = ...`` and ``# v0 = ...`` (written by
    :func:`write_gain`; optional) against the model's operating point, as
    :func:`pinlin.simulate` checks a pair (K, model): a gain designed about the upright
    pendulum is not applied to the hanging one. A comment that reads like one (``## Q0: ...``)
    is held to the same rule rather than skipped."""
    point = model.operating_point
    seen: dict[str, int] = {}
    for number, line in enumerate(text_lines(text), start=1):
        match = _POINT_LINE.fullmatch(line)
        if match is None:
            continue
        key, values = match.group(1).lower(), match.group(2)
        if key in seen:
            raise ModelFileError(path, f"line {number}: a second design point {key} (the first "
                                       f"on line {seen[key]})")
        seen[key] = number
        there = np.array([csv_number(path, f"line {number}, design point {key}", cell)
                          for cell in values.split(",")])
        if point is None:
            raise ModelFileError(path, f"line {number}: the gain names its design point "
                                       f"{key}, and model '{model.name}' has no operating "
                                       "point to check it against (delete the line to apply "
                                       "the gain anyway)")
        here = getattr(point, key[0])
        if there.shape != here.shape:
            raise ModelFileError(path, f"line {number}: the design point {key} has "
                                       f"{there.size} entries; model '{model.name}' has "
                                       f"{here.size} (a gain for another robot or joint type)")
        if not same_point(there, here):
            k = int(np.abs(there - here).argmax())
            raise ModelFileError(path, f"line {number}: the gain was designed about another "
                                       f"point: {key}[{k}] = {float(there[k])!r} in the file, "
                                       f"{float(here[k])!r} for model '{model.name}' (delete "
                                       "the line to apply the gain there anyway)")


def _index(path: Path, line: int, names: list[str], expected: tuple[str, ...], what: str,
           model: str) -> list[int]:
    """Column -> position in ``expected`` of the header's ``names``: each exactly once."""
    for k, name in enumerate(names):
        if name in names[:k]:
            raise ModelFileError(path, f"line {line}: {what} '{name}' appears twice")
        if name not in expected:
            raise ModelFileError(path, f"line {line}: {name!r:.40} is not a {what} of model "
                                       f"'{model}'; expected {', '.join(expected)}")
    missing = [name for name in expected if name not in names]
    if missing:
        raise ModelFileError(path, f"line {line}: missing {what}{'s' if len(missing) > 1 else ''}"
                                   f" {', '.join(missing[:4])}"
                                   f"{f' and {len(missing) - 4} more' if len(missing) > 4 else ''}"
                                   f" of model '{model}'")
    return [expected.index(name) for name in names]


__all__ = ["GAIN_FORMATS", "read_gain", "write_gain"]
