"""The one result type of pinlin: a named linear state-space model.

First order (Rowell's conventions)::

    x' = A x + B u + E u'            (+ f0 away from an equilibrium)
    y  = C x + D u + F u'

x and u are deviations from the operating point; f0 is x' there (the drift: [v0; a0] for a
mechanical model at a moving state), zero or absent at an equilibrium. A discrete model
(:meth:`LinearModel.discretize`, ``dt`` > 0) reads x[k+1] = f0 + A x[k] + B u[k].

Second order (mechanical systems, x = [dq; v])::

    M dq'' + C_damp dq' + K dq = Bu du

where M is the mass matrix [kg, kg*m^2], C_damp the velocity matrix (damping plus gyroscopic
terms), K the stiffness (gravity, springs, geometric) and Bu the input matrix. Every state, input
and output has a name. Models are saved and loaded as ``.npz``, MATLAB ``.mat`` or ``.json``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .arrays import real_array, restore_read_only
from .exceptions import ArgumentError, PinlinError, ShapeError
from .fields import clean, show
from .files import as_path, check_file_target, write_bytes_atomic
from .model_checks import (
    check_drift,
    check_finite,
    check_point_sizes,
    check_second_order,
    distinct_names,
    matrix_field,
    name_tuple,
)
from .model_files import MATRICES, NAME_FIELDS, jsonable, model_format, read_model, serialize
from .operating_point import OperatingPoint

_SECOND_ORDER = ("M", "C_damp", "K", "Bu")
_jsonable = jsonable  # its name here before pinlin.model_files


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
        f0: The drift at the operating point (size n): x' = f0 + A x + B u (discrete: the
            state change over one step), or None at an equilibrium.
        dt: Sample time [s] of a discrete model; 0 for a continuous one (python-control's
            convention).
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
    f0: np.ndarray | None = None
    dt: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise ArgumentError("name", f"expected a str, got {type(self.name).__name__}")
        if not clean(self.name):
            raise ArgumentError("name", f"expected a name without control characters (tab, "
                                        f"newline: it appears in one-line messages), got "
                                        f"{show(self.name)}")
        names = {}
        for k in NAME_FIELDS:
            value = getattr(self, k)
            names[k] = (value if type(value) is tuple and distinct_names(value)
                        else name_tuple(k, value, self.name))
            object.__setattr__(self, k, names[k])
        n, m, p = (len(names[k]) for k in NAME_FIELDS)
        shapes = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m), "E": (n, m), "F": (p, m)}
        for key, shape in shapes.items():
            value = getattr(self, key)
            if value is not None or key in "ABCD":
                object.__setattr__(self, key, matrix_field(key, value, shape))
        second = [getattr(self, k) is not None for k in _SECOND_ORDER]
        if any(second):
            if not all(second) or n % 2:
                raise ShapeError("M, C_damp, K and Bu come together, with an even state size")
            nv = n // 2
            for key, shape in {"M": (nv, nv), "C_damp": (nv, nv), "K": (nv, nv),
                               "Bu": (nv, m)}.items():
                object.__setattr__(self, key, matrix_field(key, getattr(self, key), shape))
        if self.G is not None:
            G = real_array(self.G, "G", "a matrix of real numbers")
            if G.ndim != 2 or 2 * G.shape[1] != n:
                raise ShapeError(f"G must have n/2 = {n // 2} columns, got shape {G.shape}")
            object.__setattr__(self, "G", matrix_field("G", G, G.shape))
        if self.f0 is not None:
            f0 = real_array(self.f0, "f0", f"{n} real numbers (the drift)")
            vector = f0.size == n and (f0.ndim == 1 or (f0.ndim == 2 and 1 in f0.shape))
            f0 = matrix_field("f0", f0.reshape(-1, 1) if vector else f0, (n, 1))
            object.__setattr__(self, "f0", f0.reshape(n))
        dt = self.dt
        if isinstance(dt, bool) or not isinstance(dt, int | float | np.floating) \
                or not (math.isfinite(dt) and dt >= 0):
            raise ArgumentError("dt", f"expected a sample time >= 0 [s] (0: continuous), got "
                                      f"{dt!r}")
        object.__setattr__(self, "dt", float(dt))
        check_finite(self.__dict__, self.name)
        check_second_order(self)
        if self.operating_point is not None and not isinstance(self.operating_point,
                                                                OperatingPoint):
            raise ArgumentError("operating_point", "expected an OperatingPoint or None, got "
                                                   f"{type(self.operating_point).__name__}")
        check_point_sizes(self)
        check_drift(self)
        if not isinstance(self.info, Mapping):
            raise ArgumentError("info", f"expected a mapping, got {type(self.info).__name__}")
        object.__setattr__(self, "info", dict(self.info))

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickling: the fields as pickled, the arrays read-only again (pickle hands numpy
        arrays back writeable)."""
        restore_read_only(self, state)

    @classmethod
    def assembled(cls, **fields: Any) -> LinearModel:
        """A model from a formulation that built it consistent: read-only float64 arrays of
        matching shapes, tuples of distinct names, a fresh ``info`` dict. Skips the shape and
        type checks of the public constructor (they cost as much as a small linearization);
        every field of the dataclass must be given. Two checks stay, both cheap: the names
        are distinct (what is saved must load) and every matrix is finite.

        Raises:
            ModelError: repeated names, or NaN or inf in a matrix (naming it and the model).
        """
        model = fields["name"]
        fields.setdefault("f0", None)
        fields.setdefault("dt", 0.0)
        for k in NAME_FIELDS:
            names = fields[k]
            if not (type(names) is tuple and distinct_names(names)):
                fields[k] = name_tuple(k, names, model)  # raises naming what is wrong
        check_finite(fields, model)
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

    @property
    def is_discrete(self) -> bool:
        return self.dt > 0

    def __repr__(self) -> str:
        extra = " with E" if self.E is not None else ""
        extra += f", discrete dt = {self.dt:g} s" if self.dt else ""
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
                           info={**self.info, "standard_form": "x' = x - E u"},
                           f0=self.f0, dt=self.dt)  # x' - E u drifts as x does

    def discretize(self, dt: float, method: str = "zoh") -> LinearModel:
        """The discrete model over sample time ``dt`` [s]: x[k+1] = f0_d + A_d x[k] + B_d u[k],
        y[k] = C x[k] + D u[k] (see :mod:`pinlin.discretization` for the methods).

        Args:
            dt: Sample time [s], > 0.
            method: ``"zoh"`` (input held over the step; exact for the linear model, by the
                matrix exponential of an augmented matrix) or ``"euler"`` (the semi-implicit
                Euler step of MuJoCo and most simulators: v first, then dq with the new v;
                mechanical models in x = [dq; v] only).

        Raises:
            ArgumentError: ``dt`` not a positive finite number, an unknown method, a model
                that is already discrete, or ``"euler"`` on a model without the [dq; v]
                structure.
            ModelError: input-derivative terms (E): discretize :meth:`standard_form` instead.
        """
        from .discretization import discretize

        return discretize(self, dt, method)

    def closed_loop(self, K: object) -> LinearModel:
        """This model under the state feedback u = -K x + r (K: n_inputs x n_states, as
        ``control.lqr`` returns it): A - B K, C - D K, and for a mechanical model the
        stiffness K + Bu K_q and damping C_damp + Bu K_v (:mod:`pinlin.closed_loop`).
        ``pinlin.simulate(scene, ..., feedback=K)`` runs the same loop on the nonlinear
        dynamics."""
        from .closed_loop import closed_loop

        return closed_loop(self, K)

    def to_control(self):
        """python-control ``StateSpace`` with the signal names (E folded by
        :meth:`standard_form`). Needs the ``control`` extra."""
        try:
            import control
        except ImportError:
            raise PinlinError("python-control is not installed: pip install 'pinlin[control]'") \
                from None
        if self.f0 is not None and np.any(self.f0):
            raise PinlinError(f"model '{self.name}' has a drift f0 (x' = f0 + A x + B u, not an "
                              "equilibrium): a python-control StateSpace has no such term; use "
                              "model.A, model.B and model.f0")
        model = self.standard_form()
        if model.F is not None and np.any(model.F):
            raise PinlinError(f"model '{self.name}': outputs with an input-derivative term "
                              "(F u') have no python-control StateSpace")
        return control.ss(model.A, model.B, model.C, model.D, self.dt, name=self.name or None,
                          states=list(model.state_names), inputs=list(model.input_names),
                          outputs=list(model.output_names))

    # ----------------------------------------------------------------------------------------
    def _arrays(self) -> dict[str, np.ndarray]:
        """The matrices present, by name; the vector f0 as a 1 x n matrix (files hold 2-D
        arrays only)."""
        out = {k: getattr(self, k) for k in MATRICES if getattr(self, k) is not None}
        if "f0" in out:
            out["f0"] = out["f0"].reshape(1, -1)
        return out

    def save(self, path: str | Path) -> Path:
        """Write the model; the format follows the suffix: ``.npz``, ``.mat`` or ``.json``.

        The file is written atomically (a temporary file beside it, renamed into place): a
        failure leaves an existing file as it was and no partial file behind. Whatever this
        writes, :meth:`load` reads back.

        Raises:
            ArgumentError: ``path`` is not a path.
            ModelFileError: unknown suffix, ``info`` that JSON cannot hold, or the file cannot
                be written (folder missing, disk full, file size limit).
        """
        path = as_path(path)
        fmt = model_format(path)
        check_file_target(path, kind="model")
        write_bytes_atomic(path, self._serialized(path, fmt))
        return path

    def _serialized(self, path: Path, fmt: str) -> bytes:
        """The file's content in format ``fmt`` (in memory: nothing touches the disk yet)."""
        return serialize(path, fmt, self._arrays(), {k: getattr(self, k) for k in NAME_FIELDS},
                         self.name, self.info, self.operating_point, self.dt)

    @classmethod
    def load(cls, path: str | Path) -> LinearModel:
        """Read a model written by :meth:`save` (never unpickles anything).

        Raises:
            ArgumentError: ``path`` is not a path.
            ModelFileError: missing file, a folder, unknown suffix, or content that is not a
                model pinlin wrote (corrupt archive, wrong shapes or types, NaN or inf,
                repeated names); the message names the file and what is wrong.
        """
        return read_model(path, cls)
