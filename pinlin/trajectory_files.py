"""Trajectory files: the states a trajectory visits (input) and its stacked models (output).

**States** (``pinlin trajectory SCENE FILE``), one point per row:

- ``.npz``: arrays ``q`` (N, nq), ``v`` (N, nv), ``u`` (N, nu) and optionally ``t`` (N,) [s];
  no other member; never unpickled. ``q`` without ``v`` and ``u``: a schedule of rest points
  (the holding inputs solved at each, :mod:`pinlin.rest_schedule`).
- ``.csv``: a header line naming the columns, then one line of numbers per point. Columns
  (any order, all required but ``t``; :func:`trajectory_columns` lists them for a scene):
  ``t`` [s]; ``q:<joint>`` for a joint with one configuration entry, ``q:<joint>[i]``
  (i = 0 .. nq-1) for the others (a free flyer's [x, y, z, qx, qy, qz, qw], a continuous
  joint's [cos, sin]); ``v:<coordinate>`` and ``u:<coordinate>`` named as the model's states
  and inputs (``v:root_joint[3]``, ``u:elbow_joint``) [SI units]. Lines starting with ``#``
  and blank lines are skipped, but a file whose first line is ``# pinlin history:`` (a time
  history pinlin wrote: deviations, not states) is refused. Without any ``v:`` and ``u:``
  column: a schedule of rest points, as for ``.npz``.

**Models** (:meth:`TrajectoryModel.save`): ``.npz`` or MATLAB ``.mat`` holding ``A``, ``B``,
``C``, ``D``, ``f0``, ``q``, ``v``, ``u``, ``a``, ``y``, ``t`` when there are times and
``lam`` for a mechanism, ``M``, ``C_damp``, ``K`` (N, n/2, n/2) and ``Bu`` for a model with
second-order matrices (``second_order=True``), the
signal names and a JSON ``meta`` (kind, name, info, dt). C, D, y and Bu that do not vary are
stored once, with a first axis of 1. Written atomically; read as
:mod:`pinlin.model_files` reads single models (headers checked before anything is allocated,
no pickles).
"""

from __future__ import annotations

import csv
import difflib
import io
import json
import math
import re
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from .exceptions import ModelFileError, PinlinError
from .fields import written_float
from .files import HISTORY_MARKER, as_path, check_file_target, write_atomic

# The readers of single-model files do the checking (npy headers, no pickles, MATLAB cells).
from .model_files import _READERS, _check_npy_headers, _read_names, jsonable
from .system import System

KIND = "pinlin trajectory model"
STATE_FORMATS = (".npz", ".csv")
MODEL_FORMATS = (".npz", ".mat")
_NAMES = ("state_names", "input_names", "output_names")
_STACKS = ("A", "B", "C", "D", "f0", "q", "v", "u", "a")
_SECOND_ORDER = ("M", "C_damp", "K", "Bu")  # all or none
_OPTIONAL = ("t", "y", "lam", *_SECOND_ORDER)
_CONSTANT = ("C", "D", "y", "Bu")  # may be stored once


def trajectory_columns(system: System) -> tuple[list[str], list[str], list[str]]:
    """The CSV column names of a scene's configurations, velocities and inputs."""
    q = [f"q:{j.name}" if j.nq == 1 else f"q:{j.name}[{i}]" for j in system.joints.values()
         for i in range(j.nq)]
    return q, [f"v:{c}" for c in system.coordinate_names], list(system.input_names)


def _file(path: Path, formats: Sequence[str], what: str) -> bytes:
    if path.suffix not in formats:
        found = f"'{path.suffix}'" if path.suffix else "no suffix"
        raise ModelFileError(path, f"unknown {what} format ({found}); expected "
                                   f"{' or '.join(formats)}")
    if path.is_dir():
        raise ModelFileError(path, f"is a folder, expected a {what} file")
    if not path.is_file():
        raise ModelFileError(path, "file not found" if not path.exists() else
                                   "not a regular file")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise ModelFileError(path, f"cannot read: {exc.strerror or exc}") from None


# --------------------------------------------------------------------------------------------
# States


def read_states(path: str | Path, system: System
                ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """(q, v, u, t) of a trajectory file for ``system`` (t None when absent; v and u None
    when the file has configurations alone: a schedule of rest points). Sizes and values
    are checked by :func:`pinlin.linearize_trajectory`; here only the file's form.

    Raises:
        ArgumentError: ``path`` is not a path.
        ModelFileError: missing file, another suffix, a corrupt or pickled .npz, unknown or
            missing members or columns, text that is not a number (naming line and column).
    """
    path = as_path(path)
    raw = _file(path, STATE_FORMATS, "trajectory")
    if path.suffix == ".npz":
        return _read_npz_states(path, raw, len(system.input_names))
    return _read_csv_states(path, raw, system)


def _read_npz_states(path: Path, raw: bytes, nu: int
                     ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None,
                                np.ndarray | None]:
    """:func:`read_states` of an .npz; ``nu``: the scene's inputs (none: u may be left out,
    as a .csv has no u columns then)."""
    if not zipfile.is_zipfile(io.BytesIO(raw)):
        raise ModelFileError(path, "not an .npz archive (not a zip file)")
    try:
        _check_npy_headers(path, raw, ModelFileError)
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            if len(set(z.files)) != len(z.files):   # a dict would keep the last silently
                twice = next(k for k in z.files if z.files.count(k) > 1)
                raise ModelFileError(path, f"member '{twice}' appears twice in the archive")
            doc = {k: z[k] for k in z.files}
    except ModelFileError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise ModelFileError(path, f"corrupt .npz archive: {exc}") from None
    unknown = sorted(set(doc) - {"q", "v", "u", "t"})
    if unknown:
        raise ModelFileError(path, f"unknown member {unknown[0]!r}; expected arrays q (N, nq), "
                                   "v (N, nv), u (N, nu) and optionally t (N,)")
    missing = [k for k in ("q", "v", "u") if k not in doc]
    if missing == ["u"] and nu == 0 and doc["q"].ndim:   # a scene without inputs
        doc["u"], missing = np.zeros((len(doc["q"]), 0)), []
    if missing and missing != ["v", "u"]:
        raise ModelFileError(path, f"missing {', '.join(map(repr, missing))}; expected arrays "
                                   "q (N, nq), v (N, nv), u (N, nu) and optionally t (N,), or "
                                   "q alone (a schedule of rest points)")
    for key, arr in doc.items():
        if arr.dtype.kind not in "fiu":
            raise ModelFileError(path, f"member '{key}' must hold numbers, got {arr.dtype}")
        if arr.ndim == 0 and key != "t":    # a single time is the t of one point
            raise ModelFileError(path, f"member '{key}' is a single number; expected an array "
                                       f"of shape {_SHAPES[key]}, one row per point")
    t = doc.get("t")
    if t is not None and t.ndim > 1:     # (N, 1) or (2, 2) was flattened, as the API refuses
        raise ModelFileError(path, f"member 't' must be a list of times (N,), got shape "
                                   f"{t.shape}")
    return doc["q"], doc.get("v"), doc.get("u"), (None if t is None else t.reshape(-1))


_SHAPES = {"q": "(N, nq)", "v": "(N, nv)", "u": "(N, nu)", "t": "(N,)"}


def text_lines(text: str) -> list[str]:
    """The lines of a text file as its writer meant them: split at \\n, \\r\\n and \\r only
    (``str.splitlines`` also splits at form feeds, NEL and U+2028, which a comment may hold:
    its tail was then read as a header or as data)."""
    return _LINE_BREAK.split(text.removesuffix("\n").removesuffix("\r")) if text else []


_LINE_BREAK = re.compile(r"\r\n|\r|\n")


def _content_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of a CSV text's lines that are neither blank nor comments."""
    return [(i, line) for i, line in enumerate(text_lines(text), start=1)
            if line.strip() and not line.lstrip().startswith("#")]


def csv_location(path: str | Path, system: System, argument: str, row: int,
                 columns: tuple[int, ...]) -> str:
    """"line N, column 'name'" (or "columns 'a'-'b'") in a states CSV file for point ``row``
    and the ``columns`` of array ``argument`` (q, v, u or t) as :func:`read_states` read them:
    for messages about a value that the file held."""
    text = Path(path).read_bytes().decode("utf-8-sig")
    line = _content_lines(text)[1 + row][0]
    q_cols, v_cols, u_cols = trajectory_columns(system)
    names = {"q": q_cols, "v": v_cols, "u": u_cols, "t": ["t"]}[argument]
    if len(columns) == 1:
        return f"line {line}, column '{names[columns[0]]}'"
    return f"line {line}, columns '{names[columns[0]]}'-'{names[columns[-1]]}'"


def _csv_fields(path: Path, number: int, line: str) -> list[str]:
    """The fields of line ``number`` of a states CSV file. Each line is one record (a quoted
    field that runs on to the next line, which no number does, leaves both lines with too few
    values); a field beyond the csv module's limit is refused, naming the line."""
    try:
        return next(csv.reader([line]))
    except csv.Error as exc:
        raise ModelFileError(path, f"line {number}: not a line of CSV values: {exc}") from None


def csv_text(path: Path, raw: bytes) -> str:
    """A CSV file's bytes as text (UTF-8, a byte-order mark dropped)."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ModelFileError(path, f"not UTF-8 text: {exc}") from None


def csv_number(path: Path, where: str, cell: str) -> float:
    """The finite number in a CSV ``cell``; ``where`` ("line 3, column 'q:elbow'") names it
    in the error."""
    try:
        value = written_float(cell)   # not float(): "1_0" is no number a CSV writes
    except ValueError:
        raise ModelFileError(path, f"{where}: {cell.strip()!r:.40} is not a number") from None
    if not math.isfinite(value):
        raise ModelFileError(path, f"{where}: {cell.strip()!r:.40} is not a finite number")
    return value


def _read_csv_states(path: Path, raw: bytes, system: System
                     ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None,
                                np.ndarray | None]:
    text = csv_text(path, raw)
    if text.startswith(HISTORY_MARKER.decode()):
        raise ModelFileError(path, "is a time history pinlin wrote (its first line says so): "
                                   "its q: and v: columns are deviations from an operating "
                                   "point, not the configurations and velocities of a states "
                                   "file")
    lines = _content_lines(text)
    if not lines:
        raise ModelFileError(path, "empty: expected a header line naming the columns, then "
                                   "one line per point")
    q_cols, v_cols, u_cols = trajectory_columns(system)
    known = [*q_cols, *v_cols, *u_cols, "t"]
    head_line, header = lines[0][0], [c.strip() for c in _csv_fields(path, *lines[0])]
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise ModelFileError(path, f"line {head_line}: column '{name}' appears twice")
        seen.add(name)
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1)
            hint = f"did you mean '{close[0]}'?" if close else \
                f"expected t, {q_cols[0]}..., v:..., u:... (see pinlin.trajectory_columns)"
            raise ModelFileError(path, f"line {head_line}: unknown column '{name}' for scene "
                                       f"'{system.scene.name}'; {hint}")
    rest = not seen.intersection(v_cols) and not seen.intersection(u_cols)
    missing = [c for c in (*q_cols, *([] if rest else [*v_cols, *u_cols])) if c not in seen]
    if missing:
        more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
        raise ModelFileError(path, f"line {head_line}: missing column"
                                   f"{'s' if len(missing) > 1 else ''} "
                                   f"{', '.join(missing[:3])}{more}")
    if len(lines) == 1:
        raise ModelFileError(path, "no data: expected one line of numbers per point after "
                                   "the header")
    values = np.empty((len(lines) - 1, len(header)))
    for row, (number, line) in enumerate(lines[1:]):
        fields = _csv_fields(path, number, line)
        if len(fields) != len(header):
            raise ModelFileError(path, f"line {number}: {len(fields)} values, the header "
                                       f"names {len(header)} columns")
        for col, cell in enumerate(fields):
            values[row, col] = csv_number(path, f"line {number}, column '{header[col]}'", cell)
    index = {name: i for i, name in enumerate(header)}

    def columns(names: list[str]) -> np.ndarray:
        return values[:, [index[c] for c in names]] if names else np.zeros((len(values), 0))

    t = values[:, index["t"]] if "t" in index else None
    if rest:  # q alone: a schedule of rest points
        return columns(q_cols), None, None, t
    return columns(q_cols), columns(v_cols), columns(u_cols), t


# --------------------------------------------------------------------------------------------
# Models


def _stored(arr: np.ndarray) -> np.ndarray:
    """A stack that repeats one entry (a broadcast view) as that entry with a first axis of
    1; others unchanged."""
    if arr.ndim and arr.shape[0] > 1 and arr.strides[0] == 0:
        return np.ascontiguousarray(arr[:1])
    return arr


def save_trajectory_model(model: Any, path: str | Path) -> Path:
    """Write ``model`` (a :class:`~pinlin.trajectory.TrajectoryModel`) as .npz or .mat."""
    path = as_path(path)
    if path.suffix not in MODEL_FORMATS:
        found = f"'{path.suffix}'" if path.suffix else "no suffix"
        raise ModelFileError(path, f"unknown trajectory model format ({found}); expected "
                                   f"{' or '.join(MODEL_FORMATS)}")
    check_file_target(path, kind="model")
    arrays = {k: _stored(getattr(model, k)) for k in _STACKS}
    for key in _OPTIONAL:
        if getattr(model, key, None) is not None:
            arrays[key] = _stored(getattr(model, key))
    try:
        meta = json.dumps(jsonable({"kind": KIND, "version": 1, "name": model.name,
                                    "info": model.info, "dt": model.dt}))
    except (TypeError, ValueError) as exc:
        raise ModelFileError(path, f"cannot save: the model's info is not JSON data: {exc}") \
            from None
    names = {k: list(getattr(model, k)) for k in _NAMES}

    def write(fh: IO[bytes]) -> None:
        if path.suffix == ".npz":
            np.savez(fh, **arrays, **{k: np.array(v, dtype=str).reshape(len(v))
                                      for k, v in names.items()}, meta=np.array(meta))
            return
        from scipy.io import savemat

        cells = {}
        for k, v in names.items():
            cells[k] = np.empty(len(v), dtype=object)
            cells[k][:] = v
        savemat(fh, {**arrays, **cells, "meta": meta}, oned_as="column")

    write_atomic(path, write)
    return path


def load_trajectory_model(path: str | Path, cls: type) -> Any:
    """Read a file written by :func:`save_trajectory_model` into ``cls``."""
    path = as_path(path)
    raw = _file(path, MODEL_FORMATS, "trajectory model")
    try:
        doc, meta = _READERS[path.suffix](path, raw)
    except MemoryError:
        raise ModelFileError(path, "too large to load into memory") from None
    if meta.get("kind") != KIND:
        raise ModelFileError(path, "not a pinlin trajectory model file (a single model's? "
                                   "read it with pinlin.LinearModel.load)")
    if meta.get("version") != 1 or isinstance(meta.get("version"), bool):
        raise ModelFileError(path, f"format version {meta.get('version')!r:.40} is not one this "
                                   "pinlin reads (1)")
    unknown = sorted(set(meta) - {"kind", "version", "name", "info", "dt"})
    if unknown:
        raise ModelFileError(path, f"unknown metadata key {unknown[0]!r:.60}; expected kind, "
                                   "version, name, info, dt")
    missing = [k for k in (*_STACKS, *_NAMES) if k not in doc]
    if missing:
        raise ModelFileError(path, f"missing {', '.join(map(repr, missing))}")
    unknown = sorted(set(doc) - {*_STACKS, *_OPTIONAL, *_NAMES})
    if unknown:
        raise ModelFileError(path, f"unknown member {unknown[0]!r:.60}; a trajectory model "
                                   f"file holds {', '.join((*_STACKS, *_OPTIONAL))} and the "
                                   f"names")
    fields: dict[str, Any] = {k: _read_names(path, k, doc[k]) for k in _NAMES}
    for key in (*_STACKS, *_OPTIONAL):
        if key not in doc:
            continue
        arr = np.asarray(doc[key])
        if arr.dtype.kind not in "fiu":
            raise ModelFileError(path, f"'{key}' must hold numbers, got {arr.dtype}")
        fields[key] = arr.astype(float)
    A = fields["A"]
    if A.ndim != 3:
        raise ModelFileError(path, f"'A' must be a stack of matrices (N, n, n), got shape "
                                   f"{A.shape}")
    N = A.shape[0]
    if "t" in fields:   # (N,), or the column (N, 1) a .mat file keeps
        t = fields["t"]
        if t.ndim == 2 and t.shape[1] == 1 and path.suffix == ".mat":
            t = t.reshape(-1)
        if t.ndim != 1:
            raise ModelFileError(path, f"'t' must be a list of times (N,), got shape {t.shape}")
        fields["t"] = t   # finite, increasing: the constructor checks
    n, m, p = (len(fields[k]) for k in _NAMES)
    half = n // 2  # second-order matrices: the coordinates of the states
    for key, shape in (("u", (N, m)), ("B", (N, n, m)), ("D", (1, p, m)),
                       ("Bu", (1, half, m)), ("M", (N, half, half)),
                       ("C_damp", (N, half, half)), ("K", (N, half, half))):
        if key in fields and fields[key].size == 0:  # MATLAB keeps no shape for empties
            fields[key] = fields[key].reshape(shape)
    for key in _CONSTANT:
        arr = fields.get(key)
        if arr is not None and arr.ndim and arr.shape[0] == 1 and N > 1:
            arr.setflags(write=False)
            fields[key] = np.broadcast_to(arr, (N, *arr.shape[1:]))
    name, info, dt = meta.get("name", ""), meta.get("info", {}), meta.get("dt", 0.0)
    try:
        return cls(**fields, name=name, info=info, dt=dt)
    except PinlinError as exc:
        raise ModelFileError(path, f"inconsistent trajectory model: {exc}") from None


__all__ = ["KIND", "load_trajectory_model", "read_states", "save_trajectory_model",
           "trajectory_columns"]
