"""A MATLAB (level 5) .mat file's structure, checked before scipy reads it.

``scipy.io.loadmat`` trusts the file's structure: an unknown type code (one flipped bit, 16 ->
24) or an array whose class byte says sparse where a string follows crashes the process inside
scipy's compiled reader, where no exception can catch it (measured with scipy 1.17.1).
:func:`check_mat_elements` therefore walks the file first and admits only what a pinlin
model file holds, each element complete and of the size its header implies:

- numeric arrays (double, single, integer classes; real or complex; logical), whose data
  elements have a numeric type and exactly prod(dims) entries;
- character arrays (a string per variable or per cell), whose data have a character type
  (for fixed-width characters exactly prod(dims) of them, for UTF-8 between 1 and 4 bytes
  each);
- cell arrays of such arrays (the signal names), exactly prod(dims) cells;

at the top level each variable as an array element or a compressed one holding one. Anything
else (structs, objects, sparse matrices, function handles, an unknown type or class, sizes
that run past their container, a compressed element that does not inflate) is refused with a
:class:`MatStructureError` saying what and where. What the arrays mean is left to scipy and
pinlin's reader, whose errors can be caught.
"""

from __future__ import annotations

import math
import struct
import zlib

#: MATLAB's data types and their item sizes (miINT8 ... miUTF32; 8, 10 and 11 reserved).
NUMERIC_TYPES = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8}
CHARACTER_TYPES = frozenset({1, 2, 4, 16, 17, 18})
#: Bytes per character of the fixed-width character types (UTF-8, 16, has a variable width).
CHARACTER_WIDTHS = {1: 1, 2: 1, 4: 2, 17: 2, 18: 4}
MI_INT8, MI_INT32, MI_UINT32, MI_MATRIX, MI_COMPRESSED, MI_UTF8 = 1, 5, 6, 14, 15, 16
MI_TYPES = frozenset({*NUMERIC_TYPES, MI_MATRIX, MI_COMPRESSED, 16, 17, 18})
#: Array classes admitted: cell, char, and the numeric classes double ... uint64.
CELL, CHAR = 1, 4
NUMERIC_CLASSES = frozenset(range(6, 16))
CLASS_NAMES = {2: "struct", 3: "object", 5: "sparse", 16: "function handle", 17: "opaque"}
COMPLEX_FLAG = 0x0800
#: Bytes of the file header (text, subsystem offset, version, endian indicator).
HEADER = 128
#: Cells within cells beyond this are refused (pinlin writes one level).
MAX_DEPTH = 4
#: A compressed element may inflate to at most this many bytes (and to no more than the
#: memory limit of :mod:`pinlin.resources`).
MAX_INFLATED = 1 << 31


class MatStructureError(ValueError):
    """The file is not a .mat file of the kind pinlin writes (the message says where)."""


def check_mat_elements(raw: bytes) -> None:
    """Walk the variables of the .mat file content ``raw`` (module docstring). A v7.3
    (HDF5) file is left to scipy, which refuses it without parsing it.

    Raises:
        MatStructureError: what is wrong, and at which byte.
    """
    if len(raw) < HEADER:
        raise MatStructureError("shorter than a .mat file header (128 bytes)")
    if 0 in raw[:4]:   # scipy's test for a level 4 file (no text header)
        raise MatStructureError("a level 4 .mat file (no header text); pinlin reads level 5")
    order = {b"IM": "<", b"MI": ">"}.get(bytes(raw[126:128]))
    if order is None:
        raise MatStructureError("no level 5 .mat endian indicator at byte 126")
    major = raw[125] if order == "<" else raw[124]   # scipy reads the major version so
    if major == 2:
        return   # v7.3 (HDF5): scipy refuses it without parsing
    if major != 1:
        raise MatStructureError(f"unknown .mat format version {major} (byte "
                                f"{125 if order == '<' else 124}); pinlin reads level 5")
    for mtype, data, where in _elements(memoryview(raw)[HEADER:], order, HEADER):
        if mtype == MI_COMPRESSED:
            inner = list(_elements(memoryview(_inflate(data, where)), order, 0))
            if len(inner) != 1 or inner[0][0] != MI_MATRIX:
                raise MatStructureError(f"the compressed element at byte {where} does not "
                                        "hold exactly one array")
            _array(inner[0][1], order, where, 0)
        elif mtype == MI_MATRIX:
            _array(data, order, where, 0)
        else:
            raise MatStructureError(f"a data element of type {mtype} at byte {where} outside "
                                    "any array")


def _elements(buf: memoryview, order: str, offset: int):
    """(type, data, file byte) of each data element that fills ``buf``."""
    pos, end = 0, len(buf)
    while pos < end:
        if end - pos < 8:
            raise MatStructureError(f"a truncated element tag at byte {offset + pos}")
        first, second = struct.unpack_from(order + "II", buf, pos)
        if first >> 16:   # small data element: 2-byte size, 2-byte type, 4 bytes of data
            mtype, size, start, stop = first & 0xFFFF, first >> 16, pos + 4, pos + 8
            if size > 4:
                raise MatStructureError(f"a small element of {size} bytes at byte "
                                        f"{offset + pos} (at most 4)")
        else:
            mtype, size, start = first, second, pos + 8
            stop = start + size + (0 if mtype == MI_COMPRESSED else -size % 8)
        if mtype not in MI_TYPES:
            raise MatStructureError(f"unknown data type {mtype} at byte {offset + pos}")
        if start + size > end:
            raise MatStructureError(f"an element at byte {offset + pos} declares {size} "
                                    "bytes, past the end of what holds it")
        yield mtype, buf[start:start + size], offset + pos
        pos = min(stop, end)   # the last element's padding may be missing


def _array(buf: memoryview, order: str, where: int, depth: int) -> None:
    """Check one array element's content: flags, dimensions, name, then by class."""
    if depth > MAX_DEPTH:
        raise MatStructureError(f"cells nested more than {MAX_DEPTH} deep at byte {where}")
    parts = list(_elements(buf, order, where + 8))
    if len(parts) < 3 or parts[0][0] != MI_UINT32 or len(parts[0][1]) != 8 \
            or parts[1][0] not in (MI_INT32, MI_UINT32) or len(parts[1][1]) % 4 \
            or len(parts[1][1]) < 8 or parts[2][0] not in (MI_INT8, MI_UTF8):
        raise MatStructureError(f"the array at byte {where} lacks its flags, dimensions or "
                                "name")
    flags = struct.unpack_from(order + "I", parts[0][1])[0]
    kind = flags & 0xFF
    code = "i" if parts[1][0] == MI_INT32 else "I"   # other writers store them unsigned
    dims = struct.unpack(f"{order}{len(parts[1][1]) // 4}{code}", parts[1][1])
    if min(dims) < 0:
        raise MatStructureError(f"the array at byte {where} has a negative dimension {dims}")
    count = math.prod(dims)
    rest = parts[3:]
    if kind == CELL:
        if len(rest) != count or any(t != MI_MATRIX for t, _, _ in rest):
            raise MatStructureError(f"the cell array at byte {where} does not hold its "
                                    f"{count} cells")
        for _, data, at in rest:
            _array(data, order, at, depth + 1)
        return
    if kind == CHAR:
        kind_, size = (rest[0][0], len(rest[0][1])) if len(rest) == 1 else (0, 0)
        width = CHARACTER_WIDTHS.get(kind_)
        if count and (len(rest) != 1 or kind_ not in CHARACTER_TYPES
                      or (width and size != width * count)
                      or (kind_ == MI_UTF8 and not count <= size <= 4 * count)):
            raise MatStructureError(f"the character array at byte {where} does not hold its "
                                    f"{count} characters")
        return
    if kind in NUMERIC_CLASSES:
        want = 2 if flags & COMPLEX_FLAG else 1
        if len(rest) != want or any(t not in NUMERIC_TYPES or len(data) != count
                                    * NUMERIC_TYPES[t] for t, data, _ in rest):
            raise MatStructureError(f"the numeric array at byte {where} does not hold its "
                                    f"{count} entries")
        return
    name = CLASS_NAMES.get(kind)
    raise MatStructureError(f"the array at byte {where} is of MATLAB class "
                            f"{name or f'code {kind}'}; a pinlin model file holds numeric "
                            "matrices, strings and cells of strings")


def _inflate(data: memoryview, where: int) -> bytes:
    from .resources import memory_limit

    most = min(MAX_INFLATED, memory_limit())
    inflater = zlib.decompressobj()
    try:
        out = inflater.decompress(data, most)
    except zlib.error as exc:
        raise MatStructureError(f"the compressed element at byte {where} does not inflate: "
                                f"{exc}") from None
    if inflater.unconsumed_tail:
        raise MatStructureError(f"the compressed element at byte {where} inflates beyond "
                                f"{most} bytes")
    return out


__all__ = ["MatStructureError", "check_mat_elements"]
