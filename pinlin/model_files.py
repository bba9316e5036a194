"""Model files: a :class:`~pinlin.linear_model.LinearModel` saved as .npz, MATLAB .mat or .json.

A file holds the matrices (:data:`MATRICES`, those present), the signal names
(:data:`NAME_FIELDS`) and the metadata: the model's name, its ``info`` and its operating point,
as JSON (a member ``meta`` of ``.npz`` and ``.mat`` files, top-level keys of a ``.json`` file).
Reading never unpickles anything and checks what it reads before it allocates: an ``.npz``
member's header must declare no more bytes than the member holds, and no object arrays. Every
fault of a file (corrupt or truncated archive, nesting, wrong types or shapes) is a
:class:`~pinlin.exceptions.ModelFileError` naming the file and what is wrong.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
import zlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import IO, Any, TypeVar

import numpy as np

from .arrays import non_numbers
from .exceptions import ModelFileError, PinlinError
from .files import as_path
from .mat_check import MatStructureError, check_mat_elements
from .operating_point import OperatingPoint

#: The matrices a model may have, in the order they are written: first order (A, B, C, D, E,
#: F), second order (M, C_damp, K, Bu) and the constraint Jacobian G.
MATRICES = ("A", "B", "C", "D", "E", "F", "M", "C_damp", "K", "Bu", "G", "f0")
#: The signal-name fields of a model.
NAME_FIELDS = ("state_names", "input_names", "output_names")
#: The file formats, by suffix.
FORMATS = (".npz", ".mat", ".json")

Model = TypeVar("Model")


def model_format(path: Path) -> str:
    """The format of model file ``path``: its suffix, one of :data:`FORMATS`.

    Raises:
        ModelFileError: any other suffix.
    """
    if path.suffix not in FORMATS:
        found = f"'{path.suffix}'" if path.suffix else "no suffix"
        raise ModelFileError(path, f"unknown model format ({found}); expected "
                                   f"{', '.join(FORMATS[:-1])} or {FORMATS[-1]}")
    return path.suffix


def serialize(path: Path, fmt: str, arrays: Mapping[str, np.ndarray],
              names: Mapping[str, Sequence[str]], name: str, info: Mapping[str, Any],
              operating_point: OperatingPoint | None, dt: float = 0.0) -> bytes:
    """A model file's content in format ``fmt``, in memory (nothing touches the disk).

    Args:
        path: The file it is meant for (for messages).
        fmt: One of :data:`FORMATS`.
        arrays: The model's matrices present, by name (:data:`MATRICES`).
        names: The signal names, by field (:data:`NAME_FIELDS`).
        name, info, operating_point, dt: The metadata, written as JSON (``dt``: the sample
            time [s] of a discrete model, 0 for a continuous one).

    Raises:
        ModelFileError: ``info`` or the operating point is not JSON data.
    """
    names = {k: list(v) for k, v in names.items()}
    try:
        meta = jsonable({"name": name, "info": info, "dt": float(dt),
                         "operating_point": (operating_point.as_dict()
                                             if operating_point is not None else None)})
        meta_text = json.dumps(meta)
        if fmt == ".json":
            doc = {**names, **meta, **{k: v.tolist() for k, v in arrays.items()}}
            return json.dumps(doc, indent=1).encode("utf-8")
    except (TypeError, ValueError, RecursionError) as exc:
        raise ModelFileError(path, "cannot save: the model's info or operating point is "
                                   f"not JSON data: {exc}") from None
    buf = io.BytesIO()
    if fmt == ".npz":
        np.savez(buf, **arrays,
                 **{k: np.array(v, dtype=str).reshape(len(v)) for k, v in names.items()},
                 meta=np.array(meta_text))
    else:
        from scipy.io import savemat

        cells = {}
        for k, v in names.items():
            cell = np.empty(len(v), dtype=object)
            cell[:] = v
            cells[k] = cell
        savemat(buf, {**arrays, **cells, "meta": meta_text}, oned_as="column")
    return buf.getvalue()


def read_model(path: str | Path, build: Callable[..., Model]) -> Model:
    """Read a model file written by :func:`serialize` (never unpickles anything).

    Args:
        path: The file.
        build: Called with the model's fields as keywords (the matrices present, the names,
            ``operating_point``, ``name``, ``info``); it checks them (a
            :class:`~pinlin.exceptions.PinlinError` when they are inconsistent).

    Raises:
        ArgumentError: ``path`` is not a path.
        ModelFileError: missing file, a folder, unknown suffix, or content that is not a model
            pinlin wrote (corrupt archive, wrong shapes or types, NaN or inf, repeated names);
            the message names the file and what is wrong.
    """
    path = as_path(path)
    fmt = model_format(path)
    if path.is_dir():
        raise ModelFileError(path, "is a folder, expected a model file")
    if not path.exists():
        raise ModelFileError(path, "file not found")
    if not path.is_file():
        raise ModelFileError(path, "not a regular file")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ModelFileError(path, f"cannot read: {exc.strerror or exc}") from None
    try:
        doc, meta = _READERS[fmt](path, raw)
        return build(**_model_fields(path, doc, meta))
    except ModelFileError:
        raise
    except PinlinError as exc:  # the constructor's checks: shapes, names, NaN
        raise ModelFileError(path, f"inconsistent model: {exc}") from None
    except MemoryError:
        raise _bad(path, "too large to load into memory") from None


def _model_fields(path: Path, doc: Mapping[str, Any], meta: Mapping[str, Any]
                  ) -> dict[str, Any]:
    """The model's fields from parsed file content (matrices as arrays or nested lists)."""
    if meta.get("kind") == "pinlin trajectory model":
        raise _bad(path, "it is a trajectory model file (one model per point): load it with "
                         "pinlin.TrajectoryModel.load")
    known = {*MATRICES, *NAME_FIELDS, *(_META_KEYS if doc is meta else ())}
    unknown = sorted(k for k in doc if k not in known)
    if unknown:
        raise _bad(path, f"unknown key {unknown[0]!r:.60}; a model file holds "
                       f"{', '.join(MATRICES)}, the names and its metadata")
    unknown = [] if doc is meta else sorted(k for k in meta if k not in _META_KEYS)
    if unknown:
        raise _bad(path, f"unknown metadata key {unknown[0]!r:.60}; expected "
                       f"{', '.join(_META_KEYS)}")
    missing = [k for k in ("A", "B", "C", "D", *NAME_FIELDS) if k not in doc]
    if missing:
        raise _bad(path, f"missing {', '.join(repr(k) for k in missing)} (expected A, B, C, "
                       "D and the state, input and output names)")
    names = {k: _read_names(path, k, doc[k]) for k in NAME_FIELDS}
    kwargs = {k: _read_matrix(path, k, doc[k]) for k in MATRICES if k in doc}
    if "G" in kwargs and kwargs["G"].ndim == 1 and kwargs["G"].size == 0:
        kwargs["G"] = kwargs["G"].reshape(0, len(names["state_names"]) // 2)
    name = meta.get("name", "")
    if not isinstance(name, str):
        raise _bad(path, f"field 'name' must be a string, got {type(name).__name__}")
    info = meta.get("info", {})
    if info is None:
        info = {}
    if not isinstance(info, Mapping):
        raise _bad(path, f"field 'info' must be a table, got {type(info).__name__}")
    op = meta.get("operating_point")
    if op is not None and not isinstance(op, Mapping):
        raise _bad(path, f"field 'operating_point' must be a table, got {type(op).__name__}")
    try:
        point = _op_from_dict(op) if op is not None else None
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise _bad(path, f"field 'operating_point' is malformed: {_describe(exc)}") from None
    dt = meta.get("dt", 0.0)
    if isinstance(dt, bool) or not isinstance(dt, int | float):
        raise _bad(path, f"field 'dt' must be a number of seconds, got {type(dt).__name__}")
    return {**kwargs, **names, "operating_point": point, "name": name, "info": info,
            "dt": float(dt)}


_META_KEYS = ("name", "info", "dt", "operating_point")


def _bad(path: Path, reason: str) -> ModelFileError:
    """The error for file content that is not a model pinlin wrote."""
    return ModelFileError(path, f"not a pinlin model file: {reason}")


def _describe(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if isinstance(exc, KeyError):
        text = f"missing {text}"
    return text[:200] or type(exc).__name__


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object's members; a key given twice is refused (json keeps the last)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"key {key!r:.60} appears twice")
        out[key] = value
    return out


def _parse_int(text: str) -> int | float:
    """JSON integers; one too long for a float becomes inf (refused later as non-finite)
    rather than an OverflowError or Python's digit-limit ValueError."""
    return int(text) if len(text) <= 300 else float(text)


def _read_json(path: Path, raw: bytes) -> tuple[Mapping[str, Any], Mapping[str, Any]]:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _bad(path, f"not UTF-8 text: {exc}") from None
    try:
        doc = json.loads(text, parse_int=_parse_int, object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as exc:
        raise _bad(path, f"not valid JSON: {exc}") from None
    except ValueError as exc:
        raise _bad(path, f"not valid JSON: {exc}") from None
    except RecursionError:
        raise _bad(path, "not valid JSON: nested too deeply") from None
    if not isinstance(doc, dict):
        raise _bad(path, f"expected a JSON object with A, B, C, D and the names, got "
                       f"{_json_kind(doc)}")
    return doc, doc


def _json_kind(value: Any) -> str:
    kinds = {list: "a list", str: "a string", bool: "a boolean", type(None): "null",
             int: "a number", float: "a number"}
    return kinds.get(type(value), type(value).__name__)


def _read_npz(path: Path, raw: bytes) -> tuple[Mapping[str, Any], Mapping[str, Any]]:
    if not zipfile.is_zipfile(io.BytesIO(raw)):
        raise _bad(path, "not an .npz archive (not a zip file: truncated or another format)")
    try:
        _check_npy_headers(path, raw)
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            if len(set(z.files)) != len(z.files):
                twice = next(k for k in z.files if z.files.count(k) > 1)
                raise _bad(path, f"member '{twice}' appears twice in the archive")
            doc = {}
            for k in z.files:
                try:
                    doc[k] = z[k]
                except ValueError as exc:
                    raise _bad(path, f"member '{k}': {_describe(exc)}") from None
    except ModelFileError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, RuntimeError,
            NotImplementedError, KeyError, zlib.error) as exc:
        raise _bad(path, f"corrupt .npz archive: {_describe(exc)}") from None
    if "meta" not in doc:
        raise _bad(path, "missing 'meta' (expected A, B, C, D, the names and meta)")
    meta = doc.pop("meta")
    if meta.dtype.kind != "U" or meta.size != 1:
        raise _bad(path, f"member 'meta' must be one string, got {meta.dtype} of shape "
                       f"{meta.shape}")
    return doc, _meta_from_text(path, str(meta.reshape(())))


_NPY_HEADERS = {(1, 0): np.lib.format.read_array_header_1_0,
                (2, 0): np.lib.format.read_array_header_2_0}


def npy_header(fh: IO[bytes], path: Path, bad: Callable[[Path, str], ModelFileError],
               what: str = "") -> tuple[tuple[int, ...], np.dtype, int]:
    """(shape, dtype, bytes of data it declares) of the .npy header at ``fh``'s position,
    read before numpy allocates anything; a format version pinlin does not read and object
    arrays (pickles) are refused by ``bad`` (``what`` begins the message, e.g. the member).
    A magic string that is not .npy raises numpy's ValueError."""
    version = np.lib.format.read_magic(fh)
    if version not in _NPY_HEADERS:
        raise bad(path, f"{what}.npy format version {version} is not one pinlin writes")
    shape, _, dtype = _NPY_HEADERS[version](fh)
    if dtype.hasobject:
        raise bad(path, f"{what}holds Python objects (a pickle), which pinlin never loads")
    return shape, dtype, math.prod(shape) * dtype.itemsize


def _check_npy_headers(path: Path, raw: bytes,
                       bad: Callable[[Path, str], ModelFileError] = _bad) -> None:
    """Read every array's .npy header before numpy allocates anything: refuse members that
    are not arrays (``np.load`` returns a member without the .npy suffix as raw bytes),
    object arrays (pickles) and arrays whose header declares more bytes than the member holds
    (a small hostile file could otherwise make numpy allocate terabytes). ``bad`` makes the
    error (default: "not a pinlin model file: ...")."""
    with zipfile.ZipFile(io.BytesIO(raw)) as zf:
        for member in zf.infolist():
            if not member.filename.endswith(".npy"):   # np.load would hand back its bytes
                raise bad(path, f"member {member.filename!r:.60} is not an array (.npy)")
            key = member.filename.removesuffix(".npy")
            with zf.open(member) as fh:
                shape, _, needed = npy_header(fh, path, bad, f"member '{key}': ")
            if needed > member.file_size:
                raise bad(path, f"member '{key}': its header declares shape {shape} "
                                f"({needed} bytes) but it holds {member.file_size} bytes")


def _meta_from_text(path: Path, text: str) -> Mapping[str, Any]:
    try:
        meta = json.loads(text, parse_int=_parse_int, object_pairs_hook=_unique_keys)
    except (ValueError, RecursionError) as exc:
        raise _bad(path, f"'meta' is not valid JSON: {_describe(exc)}") from None
    if not isinstance(meta, dict):
        raise _bad(path, f"'meta' must be a JSON object, got {_json_kind(meta)}")
    return meta


def _read_mat(path: Path, raw: bytes) -> tuple[Mapping[str, Any], Mapping[str, Any]]:
    from scipy.io import loadmat

    try:
        check_mat_elements(raw)   # a bad type code would crash scipy's reader
    except MatStructureError as exc:
        raise _bad(path, f"not a MATLAB .mat file pinlin can read: {exc}") from None
    try:
        mat = loadmat(io.BytesIO(raw), squeeze_me=False)
    except Exception as exc:  # noqa: BLE001  scipy raises many kinds for a corrupt file
        raise _bad(path, f"not a MATLAB .mat file pinlin can read: {_describe(exc)}") from None
    doc: dict[str, Any] = {k: v for k, v in mat.items() if not k.startswith("__")}
    for k in NAME_FIELDS:
        if k in doc:
            doc[k] = _mat_cell(path, k, doc[k])
    if "meta" not in doc:
        raise _bad(path, "missing 'meta' (expected A, B, C, D, the names and meta)")
    meta = np.asarray(doc.pop("meta"))
    if meta.dtype.kind != "U" or meta.size != 1:
        raise _bad(path, "variable 'meta' must be one string")
    return doc, _meta_from_text(path, str(meta.ravel()[0]))


def _mat_cell(path: Path, key: str, cell: Any) -> list[str]:
    """Names from a MATLAB cell array of strings."""
    cell = np.asarray(cell)
    if cell.dtype != object:
        raise _bad(path, f"variable '{key}' must be a cell array of strings, got {cell.dtype}")
    out = []
    for item in cell.ravel():
        item = np.asarray(item)
        if item.dtype.kind != "U" or item.size > 1:
            raise _bad(path, f"variable '{key}' must hold strings, got {item.dtype}")
        out.append(str(item.ravel()[0]) if item.size else "")
    return out


_READERS = {".json": _read_json, ".npz": _read_npz, ".mat": _read_mat}


def _read_names(path: Path, key: str, value: Any) -> list[str]:
    if isinstance(value, np.ndarray):
        if value.size == 0:
            return []
        if value.dtype.kind != "U" or value.ndim != 1:
            raise _bad(path, f"'{key}' must be a list of strings, got {value.dtype} of shape "
                           f"{value.shape}")
        return [str(s) for s in value]
    if not isinstance(value, list) or not all(isinstance(s, str) for s in value):
        raise _bad(path, f"'{key}' must be a list of strings")
    return value


def _read_matrix(path: Path, key: str, value: Any) -> np.ndarray:
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "fiu":
            raise _bad(path, f"'{key}' must be a real matrix, got dtype {value.dtype}")
        arr = value.astype(float)
    else:
        if not isinstance(value, list):
            raise _bad(path, f"'{key}' must be a matrix (a list of rows), got "
                           f"{_json_kind(value)}")
        bad = non_numbers(value)
        if bad:
            raise _bad(path, f"'{key}' must hold numbers, got {bad}")
        try:
            arr = np.array(value, dtype=float)
        except (TypeError, ValueError, OverflowError) as exc:
            raise _bad(path, f"'{key}' is not a matrix of numbers: {_describe(exc)}") from None
    if arr.ndim != 2 and arr.size:
        raise _bad(path, f"'{key}' must be a 2-D matrix, got shape {arr.shape}")
    return arr


def jsonable(obj: Any) -> Any:
    """``obj`` as plain JSON data: mappings with string keys, lists, numbers, strings.

    Raises:
        TypeError: a mapping key that is not a string (JSON would turn 3 into "3").
        ValueError: an integer of more than 300 digits (read back as a float, or inf).
    """
    if isinstance(obj, Mapping):
        for k in obj:
            if not isinstance(k, str):
                raise TypeError(f"key {k!r:.60} is not a string (JSON object keys are)")
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, int) and not isinstance(obj, bool) and abs(obj) >= 10**300:
        raise ValueError("an integer of more than 300 digits would not load back as itself "
                         "(as a rounded float, or inf)")
    if isinstance(obj, Sequence) and not isinstance(obj, str):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


_OP_ARRAYS = ("q", "v", "u", "a", "residual", "y", "lam")
#: ``contact_forces`` is written for readers of the file; loading derives it from lam again.
_OP_KEYS = (*_OP_ARRAYS, "equilibrium", "tolerance", "notes", "lam_names", "contact_forces")


def _op_from_dict(d: Mapping[str, Any]) -> OperatingPoint:
    """The operating point of a model file, checked as pinlin writes it (ValueError naming
    the key otherwise: the caller says the field is malformed)."""
    unknown = sorted(k for k in d if k not in _OP_KEYS)
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r:.60}; expected {', '.join(_OP_KEYS)}")

    def arr(key: str, required: bool = False) -> np.ndarray | None:
        value = d.get(key)
        if value is None:
            if required:
                raise ValueError(f"missing '{key}'")
            return None
        bad = non_numbers(value)
        if bad:
            raise ValueError(f"'{key}' must hold numbers, got {bad}")
        out = np.asarray(value, float)
        if out.ndim != 1:
            raise ValueError(f"'{key}' must be a list of numbers, got shape {out.shape}")
        if not np.isfinite(out).all():
            raise ValueError(f"'{key}' has NaN or inf entries")
        return out

    def strings(key: str) -> tuple[str, ...]:
        value = d.get(key, ())
        if not isinstance(value, list | tuple) or not all(isinstance(x, str) for x in value):
            raise ValueError(f"'{key}' must be a list of strings")
        return tuple(value)

    equilibrium, tolerance = d.get("equilibrium"), d.get("tolerance")
    if not isinstance(equilibrium, bool):
        raise ValueError(f"'equilibrium' must be true or false, got {equilibrium!r:.60}")
    if isinstance(tolerance, bool) or not isinstance(tolerance, int | float) \
            or not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"'tolerance' must be a number >= 0, got {tolerance!r:.60}")
    lam, lam_names = arr("lam"), strings("lam_names")
    if len(lam_names) != (0 if lam is None else lam.size):
        raise ValueError(f"'lam_names' must name each of the {0 if lam is None else lam.size} "
                         f"entries of 'lam', got {len(lam_names)} names")
    v, u, a, residual = arr("v"), arr("u"), arr("a"), arr("residual")
    for key, value in (("v", v), ("a", a), ("residual", residual)):
        if value is not None and v is not None and value.size != v.size:
            raise ValueError(f"'{key}' must have as many entries as 'v' ({v.size}), got "
                             f"{value.size}")
    return OperatingPoint(q=arr("q", True), v=v, u=u, a=a, residual=residual,
                          equilibrium=equilibrium, tolerance=float(tolerance), y=arr("y"),
                          lam=lam, notes=strings("notes"), lam_names=lam_names)
