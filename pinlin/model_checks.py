"""Checks of a :class:`~pinlin.linear_model.LinearModel`'s fields: names distinct and
printable, matrices real, finite and of the sizes the names give, second-order matrices
consistent with A and B, operating-point vectors of the model's sizes. Each refusal is a
:class:`~pinlin.PinlinError` naming the model and the field."""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .arrays import non_numbers, sum_of_squares
from .exceptions import ArgumentError, ModelError, ShapeError
from .fields import clean, show
from .model_files import MATRICES

if TYPE_CHECKING:
    from .linear_model import LinearModel


@functools.lru_cache(maxsize=512)
def valid_names(names: tuple) -> bool:
    """Whether a tuple holds distinct non-blank strings without control characters (cached:
    models of one system share their names)."""
    return (all(type(s) is str and s.strip() for s in names) and len(set(names)) == len(names)
            and clean("".join(names)))


#: Name tuples already found distinct, by id (the tuple itself is kept, so its id cannot be
#: reused while it is here): a system's names are checked once, not hashed on every model.
_DISTINCT: dict[int, tuple] = {}
_DISTINCT_MAX = 1024


def distinct_names(names: tuple) -> bool:
    """:func:`valid_names` for any tuple (False for unhashable items)."""
    if _DISTINCT.get(id(names)) is names:
        return True
    try:
        ok = valid_names(names)
    except TypeError:
        return False
    if ok:
        if len(_DISTINCT) >= _DISTINCT_MAX:
            _DISTINCT.clear()
        _DISTINCT[id(names)] = names
    return ok


def name_tuple(key: str, value: Any, model: str) -> tuple[str, ...]:
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
    if not valid_names(names):
        raise ModelError(duplicates_message(key, names, model))
    return names


def duplicates_message(key: str, names: Sequence[str], model: str) -> str:
    seen: dict[str, int] = {}
    for s in names:
        seen[s] = seen.get(s, 0) + 1
    repeated = ", ".join(f"'{s}' ({k} times)" for s, k in seen.items() if k > 1)
    return (f"model '{model}': {key} are not distinct: {repeated}; every state, input and "
            "output needs its own name (a file saved with repeated names could not be read "
            "back)")


def matrix_field(name: str, value: Any, shape: tuple[int, int]) -> np.ndarray:
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
#: input matrix S), by id: :func:`check_finite` skips them. The array itself is kept, so its
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


#: How many times n eps cond(M) a second-order residual may reach (:func:`check_second_order`).
SECOND_ORDER_MARGIN = 100.0


def check_second_order(model: LinearModel) -> None:
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
        # A singular M allows any residual, even where a block has no scale (M = 0: inf * 0).
        limit = tolerance * scale if math.isfinite(tolerance) else math.inf
        # A product of finite entries may overflow (inf, or inf - inf = NaN): refused, as the
        # model's dynamics could not be checked (M = 1e200 against A = 1e200).
        if not residual <= limit or (not math.isfinite(residual) and allowed < math.inf):
            raise ModelError(
                f"model '{model.name}': its second-order matrices describe other dynamics than "
                f"A and B (x = [dq; v], A = [[., I], [-M^-1 K, -M^-1 C_damp]], B = [[0], "
                f"[M^-1 Bu]]): {what} is {residual:.3g}, above the {limit:.3g} rounding "
                f"allows (cond(M) = {cond:.3g}); give M, C_damp, K and Bu of the same "
                "dynamics, or none of them")


def check_point_sizes(model: LinearModel) -> None:
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


def check_drift(model: LinearModel) -> None:
    """Refuse a continuous model whose drift's upper half is not the operating point's
    velocity: with states [q:...; v:...] over all of v's coordinates (an open chain, or a
    penalty model's dependent coordinates), x = [dq; v - v0] gives dq' = v0 at the point
    (the chart's derivative is the identity there), so f0[:n/2] = v0, as pinlin builds it
    (a copy). A model with other states (a mechanism's independent ones, a canonical model's
    momenta) or none of v is not checked. Rounding of a copy made elsewhere is allowed
    (1e-12 of the larger).

    Raises:
        ModelError: naming the model and the largest difference.
    """
    op, f0, half = model.operating_point, model.f0, model.n_states // 2
    if f0 is None or op is None or op.v is None or model.dt or np.size(op.v) != half:
        return
    names = model.state_names
    if not (all(n.startswith("q:") for n in names[:half])
            and all(n.startswith("v:") for n in names[half:])):
        return
    v, upper = np.asarray(op.v, dtype=float), f0[:half]
    gap = float(np.abs(upper - v).max(initial=0.0))
    if gap > 1e-12 * max(float(np.abs(v).max(initial=0.0)),
                         float(np.abs(upper).max(initial=0.0))):
        raise ModelError(f"model '{model.name}': the upper half of f0 is dq' = v0 at the "
                         f"operating point, but differs from operating_point.v by {gap:.3g} "
                         "(rad/s or m/s); give the drift of this point's velocity")


def check_finite(fields: Mapping[str, Any], model: str) -> None:
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
