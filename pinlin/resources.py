"""Memory pinlin will need for a model, estimated before anything large is allocated.

Why: Pinocchio's ``Data`` grows as nv^3. ``DataTpl``'s constructor (pin 4.1) allocates, besides
O(nv^2) matrices, four second-order derivative tensors of nv x nv x nv doubles
(``d2tau_dqdq``, ``d2tau_dvdv``, ``d2tau_dqdv``, ``d2tau_dadq``) and zero-fills them, so they
are resident at once: 32 nv^3 bytes. A 300-link chain needs 0.9 GB per ``Data``, a 1000-link
chain 32 GB, and ``model.createData()`` briefly holds two copies (the Python binding copies the
``Data`` it builds; ``pin.Data(model)`` does not), so the kernel kills the process instead of
Python raising ``MemoryError``.

The estimate (:func:`data_bytes`, :func:`system_bytes`) is derived from the constructor's member
list; the per-joint and constant terms are measured (heap growth of ``pin.Data(model)``, glibc
``mallinfo2``, on serial chains of 1..250 links with and without a free flyer and on eleven
example-robot-data robots: the formula is 0.2-2.5 % above the measurement from 75 links up,
2-17 % above between 25 and 75, and up to 2.8 times for the smallest models, where it is kilobytes).
Pinocchio's own sources (``DataTpl`` constructor, ``include/pinocchio/multibody/data.hxx``)
list the members; the nv^3 and nv^2 coefficients come from there, not from the fit.

The limit, in bytes, is the first of:

1. the value set from Python with :func:`set_memory_limit` (undone with
   :func:`restore_memory_limit`), or for a block with the context manager
   :func:`memory_limit_override`;
2. the environment variable ``PINLIN_MEMORY_LIMIT``: bytes, or a number with suffix ``K``,
   ``M``, ``G`` or ``T`` (powers of 1024, case-insensitive), e.g. ``8G`` or ``1.5G``;
3. :data:`DEFAULT_FRACTION` (half) of the memory this process may use: the physical memory
   (``os.sysconf``), or the cgroup's limit when a container sets a lower one.

:func:`check_system_memory` raises :class:`~pinlin.exceptions.ResourceError` when the estimate
exceeds the limit; it costs a few microseconds.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import re
from collections.abc import Iterator
from pathlib import Path

from .exceptions import ArgumentError, ResourceError

ENV_VAR = "PINLIN_MEMORY_LIMIT"

#: Fraction of the usable memory that is the default limit.
DEFAULT_FRACTION = 0.5

#: Limit when the machine's memory cannot be read [bytes] (4 GiB).
FALLBACK_LIMIT = 4 * 1024**3

_SUFFIX = {"": 1, "K": 1024, "M": 1024**2, "G": 1024**3, "T": 1024**4}
_SIZE = re.compile(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([KMGT]?)\s*", re.IGNORECASE)

# The limit set from Python or the CLI: (bytes, name of the argument that set it), or None.
_override: tuple[int, str] | None = None

# Per-Data terms [bytes] measured on pin 4.1 (see the module docstring), rounded up.
_DATA_PER_NV = 4096
_DATA_PER_JOINT = 10240
_DATA_CONSTANT = 32768
# Model, URDF parse (urdfdom tree + Pinocchio's supports/subtrees, O(njoints^2) for a chain;
# measured peak 33-48 njoints^2 bytes at 300-3000 links) [bytes].
_MODEL_PER_JOINT2 = 48
_MODEL_PER_JOINT = 16384
# pinlin's own dense matrices while linearizing and analysing (A, B, M, K, eigenvectors, ...):
# measured peak 185-265 nv^2 bytes (tracemalloc, chains of 100 and 200 links); 4x margin.
_WORK_PER_NV2 = 1024


# ------------------------------------------------------------------------------------------------
# The estimate

def data_bytes(nv: int, njoints: int) -> int:
    """Bytes one ``pinocchio.Data`` of a model allocates (pin 4.1).

    Args:
        nv: Velocity dimension of the model.
        njoints: Joints of the model, the universe included (``model.njoints``).

    Returns:
        The estimate [bytes]: 32 nv^3 for the four nv x nv x nv derivative tensors, 8 bytes times
        6 nv^2 (``kinematic_hessians``) + 10 nv^2 (``M``, ``Minv``, ``C``, ``U``, ``sDUiJt``,
        ``dtau_dq``, ``dtau_dv``, ``ddq_dq``, ``ddq_dv``, ``ddq_dtau``) + 2 nv^2 (measured:
        pin 4.1 holds 16 nv^2 bytes more than pin 3.7's member list) + 6 njoints nv (``Fcrb``)
        + 10 (njoints - 1) nv (``jointTorqueRegressor``), 4 nv (nv + 1) / 2 for
        ``supports_fromRow`` (a chain, the worst case), and measured per-coordinate, per-joint
        and constant terms for the rest (6 x nv matrices, spatial quantities per joint).
    """
    nv, nj = int(nv), int(njoints)
    return (32 * nv**3
            + 8 * (18 * nv * nv + 6 * nj * nv + 10 * max(nj - 1, 0) * nv)
            + 2 * nv * (nv + 1)
            + _DATA_PER_NV * nv + _DATA_PER_JOINT * nj + _DATA_CONSTANT)


def model_bytes(njoints: int, nbodies: int | None = None) -> int:
    """Bytes a Pinocchio model and the URDF parse that builds it take at their peak.

    Args:
        njoints: Joints of the model, the universe included.
        nbodies: Links in the URDF (fixed joints make links without joints); default
            ``njoints``.
    """
    n = max(int(njoints), int(nbodies) if nbodies is not None else 0)
    return _MODEL_PER_JOINT2 * n * n + _MODEL_PER_JOINT * n


def system_bytes(nv: int, njoints: int, *, rotating: bool = False) -> int:
    """Peak bytes of a :class:`~pinlin.system.System` and one linearization of it.

    The system holds one ``Data`` of the model and, for a rotating scene, one of the model with
    the spin joint prepended (nv + 1, njoints + 1), each made by ``pin.Data(model)`` (no
    temporary copy, unlike ``model.createData()``).

    Args:
        nv: Velocity dimension of the scene's model.
        njoints: Joints of the scene's model, the universe included.
        rotating: The scene has a steady rotation.
    """
    model = model_bytes(njoints)
    datas = data_bytes(nv, njoints)
    if rotating:
        datas += data_bytes(nv + 1, njoints + 1)
        model += model_bytes(njoints + 1)
    return model + datas + _WORK_PER_NV2 * nv * nv


# ------------------------------------------------------------------------------------------------
# The limit

def parse_size(text: str) -> int:
    """Bytes from ``"123"``, ``"64K"``, ``"512M"``, ``"8G"``, ``"1.5G"``, ``"1T"`` (suffixes are
    powers of 1024, case-insensitive; a fraction needs a suffix).

    Raises:
        ValueError: anything else, or a size below one byte.
    """
    match = _SIZE.fullmatch(text)
    if match is None:
        raise ValueError(f"{text!r} is not a size")
    number, suffix = match.groups()
    if "." in number and not suffix:
        raise ValueError(f"{text!r}: a plain number of bytes must be an integer")
    value = int(float(number) * _SUFFIX[suffix.upper()]) if "." in number else \
        int(number) * _SUFFIX[suffix.upper()]
    if value < 1:
        raise ValueError(f"{text!r} is below one byte")
    return value


_SIZE_HELP = ("bytes, or a number with suffix K, M, G or T (powers of 1024), e.g. 8G or 1.5G")


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None   # cgroup v2 writes "max" for no limit


@functools.cache
def usable_memory() -> tuple[int | None, str]:
    """(bytes, description) of the memory this process may use: the physical memory, or the
    cgroup's limit when lower; (None, reason) when neither can be read."""
    physical = None
    with contextlib.suppress(AttributeError, OSError, ValueError):
        physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        if physical <= 0:
            physical = None
    cgroup = _read_int("/sys/fs/cgroup/memory.max") or \
        _read_int("/sys/fs/cgroup/memory/memory.limit_in_bytes")
    if cgroup is not None and (physical is None or cgroup < physical):
        return cgroup, f"the container's {format_bytes(cgroup)} memory limit"
    if physical is not None:
        return physical, f"the {format_bytes(physical)} of physical memory"
    return None, "the machine's memory could not be read"


def default_memory_limit() -> int:
    """:data:`DEFAULT_FRACTION` of :func:`usable_memory` [bytes], or :data:`FALLBACK_LIMIT`."""
    total, _ = usable_memory()
    return FALLBACK_LIMIT if total is None else int(DEFAULT_FRACTION * total)


def memory_limit_source() -> tuple[int, str]:
    """(limit [bytes], where it comes from, in words).

    Raises:
        ResourceError: ``PINLIN_MEMORY_LIMIT`` is set but malformed.
    """
    if _override is not None:
        value, argument = _override
        if argument == "limit":
            return value, "set by pinlin.resources.set_memory_limit"
        return value, f"set by {argument}"
    env = os.environ.get(ENV_VAR)
    if env is not None:
        try:
            return parse_size(env), f"{ENV_VAR}={env.strip()}"
        except ValueError as exc:
            raise ResourceError(f"environment variable {ENV_VAR}={env!r}: {exc}; expected "
                                f"{_SIZE_HELP}, or unset it for the default (half of the "
                                "memory)") from None
    total, what = usable_memory()
    if total is None:
        return FALLBACK_LIMIT, f"default {format_bytes(FALLBACK_LIMIT)} ({what})"
    return default_memory_limit(), f"default: {DEFAULT_FRACTION:g} of {what}"


def memory_limit() -> int:
    """The memory limit in force [bytes] (see the module docstring for the order)."""
    return memory_limit_source()[0]


def _as_limit(limit: int | str | None, argument: str) -> int | None:
    if limit is None:
        return None
    if isinstance(limit, bool) or not isinstance(limit, int | str):
        raise ArgumentError(argument, f"expected an int (bytes), a string such as '8G' or None, "
                                      f"got {type(limit).__name__}")
    if isinstance(limit, str):
        try:
            return parse_size(limit)
        except ValueError as exc:
            raise ArgumentError(argument, f"{exc}; expected {_SIZE_HELP}") from None
    if limit < 1:
        raise ArgumentError(argument, f"expected a positive number of bytes, got {limit}")
    return limit


def set_memory_limit(limit: int | str | None, *, argument: str = "limit"
                     ) -> tuple[int, str] | None:
    """Set the memory limit for this process, over ``PINLIN_MEMORY_LIMIT`` and the default.

    Args:
        limit: Bytes (int), a size string such as ``"8G"`` (suffixes K, M, G, T: powers of
            1024), or None to go back to ``PINLIN_MEMORY_LIMIT`` or the default.
        argument: The name errors give the value, and the one the advice in a
            :class:`ResourceError` names (e.g. ``--memory-limit`` for the CLI).

    Returns:
        The previous setting (opaque; None when there was none), to restore it with
        :func:`restore_memory_limit`.

    Raises:
        ArgumentError: ``limit`` is not a positive size.
    """
    global _override
    value = _as_limit(limit, argument)
    previous, _override = _override, (None if value is None else (value, argument))
    return previous


def restore_memory_limit(previous: tuple[int, str] | None) -> None:
    """Put back a setting :func:`set_memory_limit` returned."""
    global _override
    _override = previous


@contextlib.contextmanager
def memory_limit_override(limit: int | str | None, *, argument: str = "limit"
                          ) -> Iterator[None]:
    """Use ``limit`` (as :func:`set_memory_limit` takes it) inside a ``with`` block only."""
    previous = set_memory_limit(limit, argument=argument)
    try:
        yield
    finally:
        restore_memory_limit(previous)


# ------------------------------------------------------------------------------------------------
# The check

def format_bytes(n: float) -> str:
    """``n`` bytes in binary units, e.g. ``"29.9 GiB"``."""
    for unit, scale in (("TiB", 1024**4), ("GiB", 1024**3), ("MiB", 1024**2), ("KiB", 1024)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{int(n)} B"


def _suggestion(needed: int) -> str:
    """A PINLIN_MEMORY_LIMIT value just above ``needed``."""
    for suffix, scale in (("G", 1024**3), ("M", 1024**2)):
        if needed >= scale:
            return f"{math.ceil(needed * 1.05 / scale)}{suffix}"
    return f"{math.ceil(needed * 1.05 / 1024)}K"


def check_memory(needed: int, what: str, detail: str = "") -> None:
    """Raise :class:`ResourceError` if ``needed`` bytes exceed the limit.

    Args:
        needed: Estimated peak [bytes].
        what: What needs it, naming the file, e.g. ``"robot.urdf: the model (nv = 1000)"``.
        detail: Where the size comes from, appended in parentheses.
    """
    limit, source = memory_limit_source()
    if needed <= limit:
        return
    why = f" ({detail})" if detail else ""
    size = _suggestion(needed)
    python = f"pinlin.resources.set_memory_limit('{size}')"
    if _override is None:
        how = f"{ENV_VAR}={size} (bytes or suffix K, M, G, T) or {python}"
    elif _override[1] == "limit":
        how = python
    else:
        how = f"{_override[1]} {size}"
    raise ResourceError(
        f"{what} would need about {format_bytes(needed)} of memory{why}, above the limit of "
        f"{format_bytes(limit)} ({source}); raise it with {how}, or use a smaller model",
        needed=float(needed), limit=float(limit))


def check_system_memory(nv: int, njoints: int, *, rotating: bool = False, what: str) -> None:
    """Refuse a model whose :class:`~pinlin.system.System` would exceed the memory limit.

    Args:
        nv: Velocity dimension of the model.
        njoints: Joints of the model, the universe included.
        rotating: The scene has a steady rotation (one more ``Data``).
        what: The source, naming the file, e.g. the URDF path or ``robot 'ur5'``.

    Raises:
        ResourceError: the estimate (:func:`system_bytes`) exceeds :func:`memory_limit`;
            the message gives both and how to raise the limit.
    """
    needed = system_bytes(nv, njoints, rotating=rotating)
    n_data = 2 if rotating else 1
    check_memory(needed, f"{what}: the model (nv = {nv}, {njoints - 1} joints)",
                 f"Pinocchio's Data takes 32 nv^3 bytes and this scene holds {n_data}")
