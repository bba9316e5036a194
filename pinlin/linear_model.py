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

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .arrays import non_numbers, real_array, restore_read_only, sum_of_squares
from .exceptions import ArgumentError, ModelError, PinlinError, ShapeError
from .fields import clean, show
from .files import as_path, check_file_target, write_bytes_atomic
from .model_files import MATRICES, NAME_FIELDS, jsonable, model_format, read_model, serialize
from .operating_point import OperatingPoint

_SECOND_ORDER = ("M", "C_damp", "K", "Bu")
_jsonable = jsonable  # its name here before pinlin.model_files


@functools.lru_cache(maxsize=512)
def _valid_names(names: tuple) -> bool:
    """Whether a tuple holds distinct non-blank strings without control characters (cached:
    models of one system share their names)."""
    return (all(type(s) is str and s.strip() for s in names) and len(set(names)) == len(names)
            and clean("".join(names)))


#: Name tuples already found distinct, by id (the tuple itself is kept, so its id cannot be
#: reused while it is here): a system's names are checked once, not hashed on every model.
_DISTINCT: dict[int, tuple] = {}
_DISTINCT_MAX = 1024


def _distinct(names: tuple) -> bool:
    """:func:`_valid_names` for any tuple (False for unhashable items)."""
    if _DISTINCT.get(id(names)) is names:
        return True
    try:
        ok = _valid_names(names)
    except TypeError:
        return False
    if ok:
        if len(_DISTINCT) >= _DISTINCT_MAX:
            _DISTINCT.clear()
        _DISTINCT[id(names)] = names
    return ok


def _names(key: str, value: Any, model: str) -> tuple[str, ...]:
    """``value`` as a tuple of distinct strings.

    Raises:
        ArgumentError: not a sequence of names (a bare string, None, a number).
        ModelError: a name appears more than once.
    """
    if isinstance(value, str | bytes) or not isinstance(value, Sequence | np.ndarray):
        raise ArgumentError(key, f"expected a sequence of names, got {type(value).__name__}")
    odd = next((s for s in value if not isinstance(s, str)), None)
    if odd is not None:
        raise ArgumentError(key, f"expected names as strings, got {type(odd).__name__}")
    names = tuple(str(s) for s in value)
    if not all(s.strip() for s in names):
        at = next(k for k, s in enumerate(names) if not s.strip())
        raise ArgumentError(key, f"the name at position {at} is empty or blank: every signal "
                                 f"needs a name that a file can carry and a user can select")
    odd = next((s for s in names if not clean(s)), None)
    if odd is not None:
        raise ArgumentError(key, f"name {show(odd)} has control characters (a line break, a tab, "
                                 "a line separator): "
                                 "they would break the one-line messages and the CSV and "
                                 "MATLAB files that carry names")
    if not _valid_names(names):
        raise ModelError(_duplicates_message(key, names, model))
    return names


def _duplicates_message(key: str, names: Sequence[str], model: str) -> str:
    seen: dict[str, int] = {}
    for s in names:
        seen[s] = seen.get(s, 0) + 1
    repeated = ", ".join(f"'{s}' ({k} times)" for s, k in seen.items() if k > 1)
    return (f"model '{model}': {key} are not distinct: {repeated}; every state, input and "
            "output needs its own name (a file saved with repeated names could not be read "
            "back)")


def _matrix(name: str, value: Any, shape: tuple[int, int]) -> np.ndarray:
    if (isinstance(value, np.ndarray) and value.dtype == np.float64 and value.shape == shape
            and not value.flags.writeable):
        return value  # already immutable: sharing it is safe
    if value is None:
        raise ArgumentError(name, "expected a matrix, got None")
    bad = non_numbers(value)
    if bad:
        raise ArgumentError(name, f"expected a matrix of real numbers, got {bad}")
    try:
        arr = np.array(value, dtype=float)  # a copy: the model owns its arrays
    except (TypeError, ValueError, OverflowError) as exc:
        raise ArgumentError(name, f"expected a matrix of real numbers: {exc}") from None
    if arr.ndim == 1 and 0 in shape:
        arr = arr.reshape(shape) if arr.size == 0 else arr
    if arr.shape != shape:
        raise ShapeError(f"{name} must be {shape[0]}x{shape[1]} to match the names given, "
                         f"got {'x'.join(map(str, arr.shape))}")
    arr.flags.writeable = False
    return arr


#: Read-only matrices finite by construction (a system's C = I, D = 0, zero velocity terms,
#: input matrix S), by id: :func:`_check_finite` skips them. The array itself is kept, so its
#: id cannot be reused while it is here (``get(id) is arr``); at most _FINITE_MAX entries.
_FINITE: dict[int, np.ndarray] = {}
_FINITE_MAX = 256


def known_finite(arr: np.ndarray) -> np.ndarray:
    """Mark ``arr`` read-only and record that it is finite (checked here, once), so that models
    sharing it skip the check; returns it. For constant matrices built once per system."""
    arr.setflags(write=False)
    if not np.isfinite(arr).all():
        raise ModelError("a constant matrix has NaN or inf entries")
    if len(_FINITE) >= _FINITE_MAX:
        _FINITE.clear()
    _FINITE[id(arr)] = arr
    return arr


#: How many times n eps cond(M) a second-order residual may reach (:func:`_check_second_order`).
SECOND_ORDER_MARGIN = 100.0


def _check_second_order(model: LinearModel) -> None:
    """Refuse a continuous model whose second-order matrices describe other dynamics than A
    and B: x = [dq; v] with A = [[., I], [-M^-1 K, -M^-1 C_damp]] and B = [[0], [M^-1 Bu]]
    (the upper-left block is zero at rest, a Lie-group term at a moving state: not checked).
    :func:`pinlin.modal` and the modal energies read M, K and C_damp in place of A, so a model
    whose matrices disagree would give other eigenvalues than A has.

    The residuals M A21 + K, M A22 + C_damp and M B2 - Bu are zero up to the rounding of
    the M^-1 the lower rows were formed with: |E| <= n eps |M^-1| for a backward stable
    inverse gives |M (M^-1 + E) K + ... | <= n eps cond(M) (|M| |A2| + |[K, C_damp]|), the
    bound used (Frobenius norms, 2-norm condition) with a margin of
    :data:`SECOND_ORDER_MARGIN`. A model pinlin built is consistent to ~eps cond(M); a model
    with other M, K, C_damp or states in another order misses it by orders of magnitude.

    Raises:
        ModelError: naming the model, the block and the residual.
    """
    M = model.M
    if M is None or model.dt or not M.shape[0]:
        return
    nv = M.shape[0]
    A, B = model.A, model.B
    eps = float(np.finfo(float).eps)
    try:
        cond = float(np.linalg.cond(M))
    except np.linalg.LinAlgError:
        cond = math.inf
    # A singular M (a model linearized with allow_ill_conditioned) allows any residual: its
    # rows were formed with an inverse that has no correct digit, and it must still load.
    allowed = SECOND_ORDER_MARGIN * nv * eps * cond if math.isfinite(cond) else math.inf
    exact = 100.0 * nv * eps   # the structural blocks: rounding of the entries alone
    norm = np.linalg.norm
    with np.errstate(all="ignore"):   # overflow is refused below, by name
        checks = (   # (block, residual, scale, relative tolerance)
            ("A[:nv, nv:] (the identity)", norm(A[:nv, nv:] - np.eye(nv)), float(nv) ** 0.5,
             exact),
            ("B[:nv] (zero)", norm(B[:nv]), norm(B), exact),
            ("M A[nv:, :nv] + K", norm(M @ A[nv:, :nv] + model.K),
             norm(M) * norm(A[nv:, :nv]) + norm(model.K), allowed),
            ("M A[nv:, nv:] + C_damp", norm(M @ A[nv:, nv:] + model.C_damp),
             norm(M) * norm(A[nv:, nv:]) + norm(model.C_damp), allowed),
            ("M B[nv:] - Bu", norm(M @ B[nv:] - model.Bu),
             norm(M) * norm(B[nv:]) + norm(model.Bu), allowed),
        )
    for what, residual, scale, tolerance in checks:
        limit = tolerance * scale
        # A product of finite entries may overflow (inf, or inf - inf = NaN): refused, as the
        # model's dynamics could not be checked (M = 1e200 against A = 1e200).
        if not residual <= limit or (not math.isfinite(residual) and allowed < math.inf):
            raise ModelError(
                f"model '{model.name}': its second-order matrices describe other dynamics than "
                f"A and B (x = [dq; v], A = [[., I], [-M^-1 K, -M^-1 C_damp]], B = [[0], "
                f"[M^-1 Bu]]): {what} is {residual:.3g}, above the {limit:.3g} rounding "
                f"allows (cond(M) = {cond:.3g}); give M, C_damp, K and Bu of the same "
                "dynamics, or none of them")


def _check_point_sizes(model: LinearModel) -> None:
    """Refuse an operating point whose vectors do not fit the model: u with other than one
    entry per input, y other than one per output, v fewer than the n/2 coordinates of the
    states [dq; v] (a mechanism's states are its independent coordinates, fewer than v's),
    a or residual other than v's size, q fewer than v.

    Raises:
        ShapeError: naming the vector, its size and what the model needs.
    """
    op = model.operating_point
    if op is None:
        return
    sizes = {key: None if getattr(op, key) is None else np.size(getattr(op, key))
             for key in ("q", "v", "u", "y", "a", "residual")}
    need = {"u": (model.n_inputs, "one per input"), "y": (model.n_outputs, "one per output")}
    for key, (size, what) in need.items():
        if sizes[key] is not None and sizes[key] != size:
            raise ShapeError(f"model '{model.name}': operating_point.{key} has {sizes[key]} "
                             f"entries, expected {size} ({what})")
    nv, nq = sizes["v"], sizes["q"]
    for key in ("a", "residual"):
        if sizes[key] is not None and nv is not None and sizes[key] != nv:
            raise ShapeError(f"model '{model.name}': operating_point.{key} has {sizes[key]} "
                             f"entries, expected v's {nv}")
    if nv is not None and nv < model.n_states // 2:
        raise ShapeError(f"model '{model.name}': operating_point.v has {nv} entries, fewer "
                         f"than the {model.n_states // 2} coordinates of the states")
    if nq is not None and nq < (nv or 0):
        raise ShapeError(f"model '{model.name}': operating_point.q has {nq} entries, fewer "
                         f"than v's {nv} (a configuration has at least one entry per "
                         "velocity)")


def _check_finite(fields: Mapping[str, Any], model: str) -> None:
    """Refuse NaN or inf in any matrix present.

    One BLAS dot product x.x per matrix, added up: NaN or inf make the total non-finite, and
    ``ddot`` raises no floating-point warning, so no ``errstate`` is needed (a total that
    overflows from finite entries, |x| > 1e154, is told apart by the exact test that
    follows). About 0.5 to 1.5 us per matrix; the constant matrices a system shares between
    its models (:func:`known_finite`) are skipped.

    Raises:
        ModelError: naming the matrix, the model and the first non-finite entry.
    """
    total = 0.0
    known = _FINITE.get
    for arr in map(fields.get, MATRICES):
        if arr is None or known(id(arr)) is arr:
            continue
        total += sum_of_squares(arr)
    if math.isfinite(total):
        return
    for key in MATRICES:
        arr = fields.get(key)
        if arr is None:
            continue
        bad = ~np.isfinite(arr)
        if not bad.any():
            continue  # finite entries whose sum overflows
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ModelError(f"model '{model}': matrix {key} has {int(bad.sum())} non-finite "
                         f"entr{'y' if bad.sum() == 1 else 'ies'} (NaN or inf), the first at "
                         f"{key}{list(where)} = {arr[where]}; a model with NaN or inf is "
                         "never returned")


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
            names[k] = (value if type(value) is tuple and _distinct(value)
                        else _names(k, value, self.name))
            object.__setattr__(self, k, names[k])
        n, m, p = (len(names[k]) for k in NAME_FIELDS)
        shapes = {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m), "E": (n, m), "F": (p, m)}
        for key, shape in shapes.items():
            value = getattr(self, key)
            if value is not None or key in "ABCD":
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
            G = real_array(self.G, "G", "a matrix of real numbers")
            if G.ndim != 2 or 2 * G.shape[1] != n:
                raise ShapeError(f"G must have n/2 = {n // 2} columns, got shape {G.shape}")
            object.__setattr__(self, "G", _matrix("G", G, G.shape))
        if self.f0 is not None:
            f0 = real_array(self.f0, "f0", f"{n} real numbers (the drift)")
            vector = f0.size == n and (f0.ndim == 1 or (f0.ndim == 2 and 1 in f0.shape))
            f0 = _matrix("f0", f0.reshape(-1, 1) if vector else f0, (n, 1))
            object.__setattr__(self, "f0", f0.reshape(n))
        dt = self.dt
        if isinstance(dt, bool) or not isinstance(dt, int | float | np.floating) \
                or not (math.isfinite(dt) and dt >= 0):
            raise ArgumentError("dt", f"expected a sample time >= 0 [s] (0: continuous), got "
                                      f"{dt!r}")
        object.__setattr__(self, "dt", float(dt))
        _check_finite(self.__dict__, self.name)
        _check_second_order(self)
        if self.operating_point is not None and not isinstance(self.operating_point,
                                                                OperatingPoint):
            raise ArgumentError("operating_point", "expected an OperatingPoint or None, got "
                                                   f"{type(self.operating_point).__name__}")
        _check_point_sizes(self)
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
            if not (type(names) is tuple and _distinct(names)):
                fields[k] = _names(k, names, model)  # raises naming what is wrong
        _check_finite(fields, model)
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
