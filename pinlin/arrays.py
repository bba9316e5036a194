"""Small array helpers shared by the modules."""

from __future__ import annotations

import numpy as np


def read_only(arr: np.ndarray) -> np.ndarray:
    """Mark ``arr`` read-only and return it. A LinearModel shares read-only arrays instead of
    copying them, so constant matrices (S, C = I) are built once per system."""
    arr.setflags(write=False)
    return arr


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
