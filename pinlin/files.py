"""Writing files atomically: a temporary file in the target's folder, renamed into place.

A failure half-way (disk full, ``ulimit -f``, an exception while serializing) leaves an existing
file untouched and no partial file behind: the rename is the only step that changes what a
reader sees, and ``os.replace`` is atomic within one file system.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

from .exceptions import ModelFileError


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    The temporary file keeps ``path``'s suffix (some writers choose the format from it) and is
    removed if the block raises. Permissions follow the umask, as for a plain ``open``.

    Raises:
        ModelFileError: the folder does not exist or cannot be written, or the write fails.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ModelFileError(path, "cannot write: it is a folder")
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                                        dir=folder)
    except FileNotFoundError:
        raise ModelFileError(path, f"cannot write: folder '{folder}' does not exist") from None
    except OSError as exc:
        raise ModelFileError(path, f"cannot write: {exc.strerror or exc}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        raise ModelFileError(path, f"cannot write: {exc.strerror or exc}") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def write_atomic(path: str | Path, writer: Callable[[IO[bytes]], None]) -> None:
    """Write ``path`` atomically through ``writer(binary_file)``."""
    with atomic_path(path) as tmp, tmp.open("wb") as fh:
        writer(fh)
        fh.flush()
        os.fsync(fh.fileno())


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_atomic(path, lambda fh: fh.write(text.encode("utf-8")))
