"""The one result type of pinlin: a named linear state-space model.

First order (Rowell's conventions)::

    x' = A x + B u + E u'
    y  = C x + D u + F u'

Second order (mechanical systems, x = [dq; v])::

    M dq'' + C_damp dq' + K dq = Bu du

where M is the mass matrix [kg, kg*m^2], C_damp the velocity matrix (damping plus gyroscopic
terms), K the stiffness (gravity, springs, geometric) and Bu the input matrix. Every state, input
and output has a name. Models are saved and loaded as ``.npz``, MATLAB ``.mat`` or ``.json``.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .exceptions import ModelFileError, PinlinError, ShapeError
from .operating_point import OperatingPoint

_FIRST_ORDER = ("A", "B", "C", "D", "E", "F")
_SECOND_ORDER = ("M", "C_damp", "K", "Bu")
_CONSTRAINT = ("G",)
_FORMATS = (".npz", ".mat", ".json")


@functools.lru_cache(maxsize=512)
def _valid_names(names: tuple) -> bool:
    """Whether a tuple holds distinct strings (cached: models of one system share their names)."""
    return all(type(s) is str for s in names) and len(set(names)) == len(names)


def _matrix(name: str, value: Any, shape: tuple[int, int]) -> np.ndarray:
    if (isinstance(value, np.ndarray) and value.dtype == np.float64 and value.shape == shape
            and not value.flags.writeable):
        return value  # already immutable: sharing it is safe
    arr = np.array(value, dtype=float)  # a copy: the model owns its arrays
    if arr.ndim == 1 and 0 in shape:
        arr = arr.reshape(shape)
    if arr.shape != shape:
        raise ShapeError(f"{name} must be {shape[0]}x{shape[1]} to match the names given, "
                         f"got {'x'.join(map(str, arr.shape))}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class LinearModel:
    """A linear state-space model with named signals.

    Attributes:
        A, B, C, D: First-order matrices (n x n, n x m, p x n, p x m).
        state_names, input_names, output_names: Signal names (n, m, p).
        E, F: Input-derivative matrices (n x m, p x m), or None when absent.
        M, C_damp, K, Bu: Second-order matrices for mechanical models (nv = n/2), else None.
        operating_point: The point the model is taken about (mechanical models).
        name: Model name (scene or graph name).
        G: Constraint Jacobian Phi_q (independent rows, m x n/2) of a model in dependent
            coordinates (penalty, canonical), used to tell constraint modes from physical ones;
            None otherwise.
        info: Metadata: formulation, derivatives, effects in play, notes, whether velocity
            terms are present (``velocity_terms``), error estimates.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    E: np.ndarray | None = None
    F: np.ndarray | None = None
    M: np.ndarray | None = None
    C_damp: np.ndarray | None = None
    K: np.ndarray | None = None
    Bu: np.ndarray | None = None
    operating_point: OperatingPoint | None = None
    G: np.ndarray | None = None
    name: str = ""
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        names = {}
        for k in ("state_names", "input_names", "output_names"):
            v = getattr(self, k)
            if not (type(v) is tuple and _valid_names(v)):
                v = tuple(str(s) for s in v)
                object.__setattr__(self, k, v)
                if not _valid_names(v):
                    raise ShapeError(f"{k} has duplicates")
            names[k] = v
        n, m, p = (len(names[k]) for k in ("state_names", "input_names", "output_names"))
        shapes = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m), "E": (n, m), "F": (p, m)}
        for key, shape in shapes.items():
            value = getattr(self, key)
            if value is not None:
                object.__setattr__(self, key, _matrix(key, value, shape))
        second = [getattr(self, k) is not None for k in _SECOND_ORDER]
        if any(second):
            if not all(second) or n % 2:
                raise ShapeError("M, C_damp, K and Bu come together, with an even state size")
            nv = n // 2
            for key, shape in {"M": (nv, nv), "C_damp": (nv, nv), "K": (nv, nv),
                               "Bu": (nv, m)}.items():
                object.__setattr__(self, key, _matrix(key, getattr(self, key), shape))
        if self.G is not None:
            G = np.asarray(self.G, dtype=float)
            if G.ndim != 2 or 2 * G.shape[1] != n:
                raise ShapeError(f"G must have n/2 = {n // 2} columns, got shape {G.shape}")
            object.__setattr__(self, "G", _matrix("G", G, G.shape))
        object.__setattr__(self, "info", dict(self.info))

    @classmethod
    def assembled(cls, **fields: Any) -> LinearModel:
        """A model from a formulation that built it consistent: read-only float64 arrays of
        matching shapes, tuples of distinct names, a fresh ``info`` dict. Skips the checks of
        the public constructor (they cost as much as a small linearization); every field of
        the dataclass must be given.
        """
        obj = object.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    # ----------------------------------------------------------------------------------------
    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    @property
    def n_outputs(self) -> int:
        return len(self.output_names)

    @property
    def has_second_order(self) -> bool:
        return self.M is not None

    def __repr__(self) -> str:
        extra = " with E" if self.E is not None else ""
        return (f"LinearModel({self.name!r}: {self.n_states} states, {self.n_inputs} inputs, "
                f"{self.n_outputs} outputs{extra})")

    # ----------------------------------------------------------------------------------------
    def standard_form(self) -> LinearModel:
        """Remove the input-derivative terms with x' = x - E u (Rowell, eqs. 90-93).

        Returns the model in the new state x' with B' = B + A E and D' = D + C E; an output
        feed-through of u' (F) stays, y = C x' + D' u + F u' (eq. 93). Returns self when E is
        None.
        """
        if self.E is None or not np.any(self.E):
            return self
        F = self.F if self.F is not None and np.any(self.F) else None
        return LinearModel(self.A, self.B + self.A @ self.E, self.C, self.D + self.C @ self.E,
                           tuple(f"{s}'" for s in self.state_names), self.input_names,
                           self.output_names, F=F, name=self.name,
                           info={**self.info, "standard_form": "x' = x - E u"})

    def to_control(self):
        """python-control ``StateSpace`` with the signal names (E folded by
        :meth:`standard_form`). Needs the ``control`` extra."""
        try:
            import control
        except ImportError:
            raise PinlinError("python-control is not installed: pip install 'pinlin[control]'") \
                from None
        model = self.standard_form()
        if model.F is not None and np.any(model.F):
            raise PinlinError(f"model '{self.name}': outputs with an input-derivative term "
                              "(F u') have no python-control StateSpace")
        return control.ss(model.A, model.B, model.C, model.D, name=self.name or None,
                          states=list(model.state_names), inputs=list(model.input_names),
                          outputs=list(model.output_names))

    # ----------------------------------------------------------------------------------------
    def _arrays(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in _FIRST_ORDER + _SECOND_ORDER + _CONSTRAINT
                if getattr(self, k) is not None}

    def save(self, path: str | Path) -> Path:
        """Write the model; the format follows the suffix: ``.npz``, ``.mat`` or ``.json``.

        Raises:
            ModelFileError: unknown suffix or the file cannot be written.
        """
        path = Path(path)
        if path.suffix not in _FORMATS:
            raise ModelFileError(path, f"unknown model format '{path.suffix}'; expected "
                                       f"{', '.join(_FORMATS)}")
        names = {"state_names": list(self.state_names), "input_names": list(self.input_names),
                 "output_names": list(self.output_names)}
        meta = _jsonable({"name": self.name, "info": self.info,
                          "operating_point": (self.operating_point.as_dict()
                                              if self.operating_point is not None else None)})
        try:
            if path.suffix == ".json":
                doc = {**names, **meta, **{k: v.tolist() for k, v in self._arrays().items()}}
                path.write_text(json.dumps(doc, indent=1))
            elif path.suffix == ".npz":
                with path.open("wb") as fh:
                    np.savez(fh, **self._arrays(),
                             **{k: np.array(v, dtype=str) for k, v in names.items()},
                             meta=np.array(json.dumps(meta)))
            else:
                from scipy.io import savemat

                savemat(path, {**self._arrays(),
                               **{k: np.array(v, dtype=object) for k, v in names.items()},
                               "meta": json.dumps(meta)}, oned_as="column")
        except OSError as exc:
            raise ModelFileError(path, f"cannot write: {exc.strerror or exc}") from None
        return path

    @classmethod
    def load(cls, path: str | Path) -> LinearModel:
        """Read a model written by :meth:`save`.

        Raises:
            ModelFileError: missing file, unknown suffix or unreadable content.
        """
        path = Path(path)
        if path.suffix not in _FORMATS:
            raise ModelFileError(path, f"unknown model format '{path.suffix}'")
        if not path.is_file():
            raise ModelFileError(path, "file not found")
        try:
            if path.suffix == ".json":
                doc = json.loads(path.read_text())
                meta = doc
            elif path.suffix == ".npz":
                with np.load(path, allow_pickle=False) as z:
                    doc = {k: z[k] for k in z.files}
                meta = json.loads(str(doc.pop("meta")))
            else:
                from scipy.io import loadmat

                raw = loadmat(path, squeeze_me=False)
                doc = {k: v for k, v in raw.items() if not k.startswith("__")}
                for k in ("state_names", "input_names", "output_names"):
                    doc[k] = [str(np.asarray(s).ravel()[0]) for s in np.asarray(doc[k]).ravel()]
                meta = json.loads(str(np.asarray(doc.pop("meta")).ravel()[0]))
            kwargs = {k: np.asarray(doc[k], float)
                      for k in _FIRST_ORDER + _SECOND_ORDER + _CONSTRAINT if k in doc}
            if "G" in kwargs and kwargs["G"].ndim == 1:  # zero rows read back flat
                kwargs["G"] = kwargs["G"].reshape(-1, len(doc["state_names"]) // 2)
            op = meta.get("operating_point")
            return cls(**kwargs,
                       state_names=[str(s) for s in doc["state_names"]],
                       input_names=[str(s) for s in doc["input_names"]],
                       output_names=[str(s) for s in doc["output_names"]],
                       operating_point=_op_from_dict(op) if op else None,
                       name=meta.get("name", ""), info=meta.get("info", {}))
        except (KeyError, ValueError, TypeError, OSError) as exc:
            raise ModelFileError(path, f"not a pinlin model file: {exc}") from None


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, Sequence) and not isinstance(obj, str):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _op_from_dict(d: Mapping[str, Any]) -> OperatingPoint:
    def arr(key):
        return None if d.get(key) is None else np.asarray(d[key], float)

    return OperatingPoint(q=arr("q"), v=arr("v"), u=arr("u"), a=arr("a"),
                          residual=arr("residual"), equilibrium=bool(d["equilibrium"]),
                          tolerance=float(d["tolerance"]), y=arr("y"), lam=arr("lam"),
                          notes=tuple(d.get("notes", ())),
                          lam_names=tuple(d.get("lam_names", ())))
