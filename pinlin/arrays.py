"""Small array helpers shared by the modules."""

from __future__ import annotations

import numpy as np

from .exceptions import ArgumentError


def read_only(arr: np.ndarray) -> np.ndarray:
    """Mark ``arr`` read-only and return it. A LinearModel shares read-only arrays instead of
    copying them, so constant matrices (S, C = I) are built once per system."""
    arr.setflags(write=False)
    return arr


def sum_of_squares(arr: np.ndarray) -> float:
    """sum x^2 over the entries of ``arr`` by one BLAS ``ddot`` (no floating-point warning for
    inf * 0: a NaN or inf entry makes the sum NaN or inf). ddot reads C order: a column-major
    array (Pinocchio's M) is read through its transpose, the same entries, not copied."""
    return float(np.vdot(arr, arr) if arr.flags.c_contiguous else np.vdot(arr.T, arr.T))


def is_complex(value: object) -> bool:
    """Whether ``value`` holds complex numbers (``float()`` of them would drop the imaginary
    parts with a mere warning); False for what numpy cannot read as an array at all, which
    the caller's own conversion then refuses."""
    try:
        return bool(np.iscomplexobj(value))
    except (ValueError, TypeError, OverflowError):
        return False


def complement(n: int, index: np.ndarray) -> np.ndarray:
    """The indices in range(n) not in ``index``, ascending (a mask: np.setdiff1d sorts)."""
    keep = np.ones(n, dtype=bool)
    keep[index] = False
    return np.flatnonzero(keep)


#: What each numpy dtype kind that is not a real number holds, in an error message.
_NOT_NUMBERS = {"c": "complex entries", "b": "booleans (True/False)", "U": "text",
                "S": "text", "M": "dates or times", "m": "dates or times", "V": "records"}


def non_numbers(value: object) -> str | None:
    """What makes ``value`` other than real numbers ("complex entries", "booleans
    (True/False)", "text", "masked entries", ...), for the caller's message; None for real
    numbers (integers, floats), and for what numpy cannot read as an array at all (the
    caller's own conversion refuses that). ``np.array(v, dtype=float)`` would otherwise read
    "1e3" as 1000, True as 1, a masked entry as the value under its mask, and drop imaginary
    parts."""
    if type(value) is np.ndarray and value.dtype.kind in "fiu":
        return None  # the usual case, without a second conversion
    if isinstance(value, np.ma.MaskedArray) and np.ma.getmaskarray(value).any():
        return "masked entries"
    if isinstance(value, list | tuple):     # numpy reads [True, 0] as integers
        stack = list(value)
        while stack:
            item = stack.pop()
            if isinstance(item, list | tuple):
                stack.extend(item)
            elif isinstance(item, bool | np.bool_):
                return "booleans (True/False)"
            elif isinstance(item, str | bytes):
                return "text"
            elif isinstance(item, complex | np.complexfloating):
                return "complex entries"
            elif item is None:   # numpy reads None as NaN
                return "None (missing values)"
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError, OverflowError):
        return None
    kind = arr.dtype.kind
    if kind != "O":
        return _NOT_NUMBERS.get(kind)
    for item in arr.flat:
        if isinstance(item, str | bytes):
            return "text"
        if isinstance(item, bool | np.bool_):
            return "booleans (True/False)"
        if isinstance(item, complex | np.complexfloating):
            return "complex entries"
        if item is None:
            return "None (missing values)"
    return None


def real_array(value: object, name: str, expected: str) -> np.ndarray:
    """``value`` as a new float64 array of real numbers (any shape: the caller checks it, and
    finiteness).

    Raises:
        ArgumentError: naming ``name``: "expected <expected>, got complex entries" (booleans,
            text, masked entries: :func:`non_numbers`; ``np.array(v, dtype=float)`` would drop
            the imaginary parts or read them as numbers), or what numpy cannot read as numbers
            (a dict, a ragged list, an int beyond float64).
    """
    bad = non_numbers(value)
    if bad:
        raise ArgumentError(name, f"expected {expected}, got {bad}")
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentError(name, f"expected {expected}, got {type(value).__name__} "
                                  f"{value!r:.60}") from None


def sample_times(t: object) -> np.ndarray:
    """``t`` as sample times [s]: a new 1-D float64 array, finite and strictly increasing, at
    least one entry (a number is one time); the steps between them finite too (two times of
    +-1e308 have an infinite span).

    Raises:
        ArgumentError: naming ``t`` and what is wrong.
    """
    arr = real_array(t, "t", "a 1-D sequence of sample times [s]")
    if arr.ndim == 0:   # one time, as a number
        arr = arr.reshape(1)
    if arr.ndim != 1 or arr.size == 0:
        raise ArgumentError("t", "expected a 1-D sequence of sample times [s] (at least one)")
    with np.errstate(all="ignore"):   # inf - inf of a bad sample, refused just below
        steps = np.diff(arr)
    if not np.all(np.isfinite(arr)) or np.any(steps <= 0):
        raise ArgumentError("t", "expected finite, strictly increasing sample times [s]")
    if not np.all(np.isfinite(steps)):
        raise ArgumentError("t", f"the span from {arr[0]:g} to {arr[-1]:g} s between two "
                                 "samples exceeds float64's range; give times within "
                                 "+-8.9e307 s of each other")
    return arr


def restore_read_only(obj: object, state: dict) -> None:
    """``obj.__dict__`` from a pickled ``state``, its arrays read-only again (pickle hands
    numpy arrays back writeable): the ``__setstate__`` of the frozen models."""
    obj.__dict__.update(state)
    for value in state.values():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
