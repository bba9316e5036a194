"""Writing files atomically: a temporary file in the target's folder, renamed into place.

A failure half-way (disk full, ``ulimit -f``, an exception while serializing) leaves an existing
file untouched and no partial file behind: the rename is the only step that changes what a
reader sees, and ``os.replace`` is atomic within one file system.

The checks here (:func:`check_file_target`, :func:`check_folder_target`, :func:`check_ours`)
let a command refuse a bad output path before any work, so that bad input writes nothing.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from .exceptions import ArgumentError, ModelFileError


def as_path(path: Any, argument: str = "path") -> Path:
    """``path`` as a :class:`~pathlib.Path`.

    Raises:
        ArgumentError: not a ``str`` or ``os.PathLike``, empty, or with a NUL character.
    """
    if isinstance(path, bytes) or not isinstance(path, str | os.PathLike):
        raise ArgumentError(argument, "expected a file path (str or os.PathLike), got "
                                      f"{type(path).__name__}")
    text = os.fspath(path)
    if isinstance(text, bytes):
        raise ArgumentError(argument, "expected a file path as text, got a bytes path")
    if not text:
        raise ArgumentError(argument, "expected a file name, got an empty string")
    if "\0" in text:
        raise ArgumentError(argument, f"the path {text!r} contains a NUL character")
    path = Path(text)
    _check_name_lengths(path)
    return path


#: The longest file name and path most file systems take (Linux NAME_MAX and PATH_MAX) [bytes].
NAME_MAX, PATH_MAX = 255, 4096


def _check_name_lengths(path: Path) -> None:
    """ModelFileError for a name or path longer than the file system takes (the OS would say
    ENAMETOOLONG from the first call that touches it, inside any check)."""
    encoded = os.fsencode(path)
    if len(encoded) >= PATH_MAX:
        raise ModelFileError(f"{str(path)[:60]}...", f"path too long: {len(encoded)} bytes, "
                                                     f"the limit is {PATH_MAX - 1}")
    for part in path.parts:
        size = len(os.fsencode(part))
        if size > NAME_MAX:
            raise ModelFileError(path, f"file name too long: '{part[:40]}...' has {size} bytes, "
                                       f"the limit is {NAME_MAX}")


def _folder_of(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def _follow_link(path: Path) -> Path:
    """The file a symbolic link points to (writing replaces the target, not the link)."""
    return Path(os.path.realpath(path)) if path.is_symlink() else path


#: The first bytes of a gain file (:mod:`pinlin.gain_files`).
GAIN_MARKER = b"# pinlin gain:"
#: The first bytes of a time history in CSV (``pinlin simulate|response --out h.csv``): a
#: user's states file, whose header (``t,q:...,v:...``) a history's may equal, is then never
#: taken for one and replaced, nor a history read as a states file (its q: and v: columns are
#: deviations from the operating point; its y: and u: columns are values).
HISTORY_MARKER = b"# pinlin history:"
#: How the files pinlin writes begin, by suffix: an existing non-empty file at an output
#: path is replaced only if it begins so (an earlier result), never a file of another kind
#: (a user's notes named report.html, a link to a system file).
SIGNATURES: dict[str, tuple[bytes, ...]] = {
    ".html": (b"<!DOCTYPE html>",),
    ".htm": (b"<!DOCTYPE html>",),
    ".png": (b"\x89PNG",),
    ".gif": (b"GIF87a", b"GIF89a"),
    ".xml": (b"<!-- Written by pinlin export-mjcf",),   # pinlin.mjcf.MJCF_MARKER
    ".npz": (b"PK\x03\x04", b"PK\x05\x06"),
    ".mat": (b"MATLAB",),
    ".json": (b"{",),
    ".csv": (HISTORY_MARKER, GAIN_MARKER),
}


#: Data formats whose signature any file of that kind has (every JSON object starts with
#: "{", every .npz is a zip): what pinlin's own files hold besides (a model's or trajectory's
#: names, a history's columns).
_MODEL_ARRAYS = ("A", "B", "C", "D", "E", "F", "G", "M", "C_damp", "K", "Bu", "f0", "q", "v",
                 "u", "a", "y", "t", "lam", "meta", "state_names", "input_names", "output_names")
#: (members every such archive has, members it may have): a model or trajectory model, a
#: simulation history. An archive (or a .mat file) with any other member is the user's,
#: whatever it shares (a model loaded in MATLAB and saved back with the user's results).
_NPZ_MEMBERS = {
    "model": ({"A.npy", "meta.npy", "state_names.npy"}, {f"{k}.npy" for k in _MODEL_ARRAYS}),
    "history": ({"t.npy", "names.npy", "values.npy"}, {"t.npy", "names.npy", "values.npy"})}
_JSON_START = b'{\n "state_names"'
_KIND_NAMES = {"model": "model (linear or trajectory)", "history": "time history",
               "gain": "gain"}
#: The kinds of pinlin's files that share a suffix, told apart by their content.
_KINDS = {".npz": ("model", "history"), ".csv": ("history", "gain")}


#: The text chunk every PNG pinlin writes carries (``metadata=PNG_METADATA`` for matplotlib),
#: the comment of every GIF, and what an HTML report says near its top.
PNG_METADATA = {"Software": "pinlin"}
PNG_TEXT = b"Software\x00pinlin"
GIF_COMMENT = b"Written by pinlin"
_HTML_TITLE = b"<title>pinlin "
#: Bytes read from the head of a file to find those markers (text chunks precede the image
#: data; a GIF's comment follows its colour table of at most 768 bytes).
_HEAD = 8192


def _pinlin_content(target: Path, suffix: str, kind: str | None = None) -> bool:
    """Whether ``target`` (a file of the kind ``suffix`` names) holds what pinlin writes there:
    pinlin's marker in a PNG, GIF or HTML head and in a CSV's first line, the arrays of a
    model, trajectory or history in an .npz or .mat (read from the archive's listing, not the
    data), a model's first key in .json; other kinds are told by their head alone. ``kind``
    ("model": a model or trajectory model, "history": a time history, "gain": a gain file)
    narrows an .npz or .csv to what the caller writes: a history does not replace a saved
    model or a gain, nor a model or a gain a history."""
    import zipfile

    try:
        if suffix == ".npz":
            with zipfile.ZipFile(target) as archive:
                names = set(archive.namelist())
            kinds = _NPZ_MEMBERS.values() if kind is None else (_NPZ_MEMBERS[kind],)
            return any(required <= names <= allowed for required, allowed in kinds)
        if suffix == ".mat":
            from scipy.io import whosmat

            try:
                names = {name for name, _, _ in whosmat(str(target))}
            except Exception:  # noqa: BLE001 - scipy's reader of a foreign file raises many
                return False   # kinds (NotImplementedError for v7.3, zlib.error, IndexError)
            return {"state_names", "meta"} <= names <= set(_MODEL_ARRAYS)
        with target.open("rb") as fh:
            head = fh.read(_HEAD)
        if suffix == ".json":
            return head.startswith(_JSON_START)
        if suffix == ".png":
            return PNG_TEXT in head
        if suffix == ".gif":
            return GIF_COMMENT in head
        if suffix in (".html", ".htm"):
            return _HTML_TITLE in head
        if suffix == ".csv":
            if head.startswith(GAIN_MARKER):
                return kind in (None, "gain")
            return head.startswith(HISTORY_MARKER) and kind in (None, "history")
    except (OSError, ValueError, zipfile.BadZipFile):
        return False
    return True


def check_replaceable(path: Path, target: Path, kind: str | None = None) -> None:
    """Refuse to replace an existing non-empty ``target`` (``path``, links followed) that does
    not begin as the files pinlin writes with its suffix begin (:data:`SIGNATURES`), or, for
    the data formats, does not hold pinlin's own names (:func:`_pinlin_content`)."""
    if os.path.lexists(target) and not target.is_file() and not target.is_dir():
        raise ModelFileError(path, "exists and is not a regular file (a pipe, socket, device "
                                   "or a loop of links); pinlin does not replace it")
    heads = SIGNATURES.get(path.suffix.lower())      # the kind the caller writes
    if heads is None or not target.is_file():
        return
    try:
        with target.open("rb") as fh:
            start = fh.read(max(len(h) for h in heads))
    except OSError as exc:
        raise ModelFileError(path, f"cannot read it: {exc.strerror or exc}") from None
    if start and not (any(start.startswith(h) for h in heads)
                      and _pinlin_content(target, path.suffix.lower(), kind)):
        where = f" (a link to '{target}')" if target != path else ""
        other = next((k for k in _KINDS.get(path.suffix.lower(), ()) if k != kind
                      and _pinlin_content(target, path.suffix.lower(), k)), None) \
            if kind is not None else None
        if other is not None:   # pinlin's, of another kind: say which
            raise ModelFileError(path, f"exists{where} and holds a saved {_KIND_NAMES[other]}, "
                                       f"not a {_KIND_NAMES[kind]}; pinlin does not replace "
                                       "one with the other: move it or choose another name")
        raise ModelFileError(path, f"exists{where} and is not a {path.suffix} file of the "
                                   "kind pinlin writes; pinlin does not replace it: move it "
                                   "or choose another name")


def check_file_target(path: str | Path, what: str = "write", kind: str | None = None) -> Path:
    """Refuse a file path that cannot be written, before any work; returns it as a Path
    (``kind``: what the caller writes, for :func:`check_replaceable`).

    Raises:
        ArgumentError: ``path`` is not a path.
        ModelFileError: it names a folder, its folder does not exist, a component of its
            folder is a file, it is a link to a file that does not exist, or it is an existing
            file of another kind (:func:`check_replaceable`).
    """
    path = as_path(path)
    target = _follow_link(path)
    if target.is_dir():
        raise ModelFileError(path, f"cannot {what}: it is a folder, expected a file name")
    if target != path and not os.path.lexists(target):
        raise ModelFileError(path, f"cannot {what}: it is a link to '{target}', which does not "
                                   "exist; pinlin does not create a file through a link: "
                                   "remove the link or choose another name")
    check_replaceable(path, target, kind)
    folder = _folder_of(target)
    if not folder.is_dir():
        blocker = _existing_non_folder(folder)
        if blocker is not None:
            raise ModelFileError(path, f"cannot {what}: '{blocker}' is a file, not a folder")
        raise ModelFileError(path, f"cannot {what}: folder '{folder}' does not exist")
    return path


def _existing_non_folder(folder: Path) -> Path | None:
    """The first component of ``folder`` that exists and is not a folder, if any."""
    for part in reversed([folder, *folder.parents]):
        if part.exists() and not part.is_dir():
            return part
    return None


def check_folder_target(folder: str | Path, argument: str = "out_dir") -> Path:
    """Refuse an output folder that is a file or cannot be created, before any work.

    A folder that does not exist yet is fine when it can be created (no component of it is a
    file); nothing is created here.

    Raises:
        ArgumentError: ``folder`` is not a path or is empty.
        ModelFileError: it, or a component of it, is a file.
    """
    folder = as_path(folder, argument)
    if folder.is_dir():
        return folder
    blocker = _existing_non_folder(folder)
    if blocker == folder:
        raise ModelFileError(folder, "cannot write reports here: it is a file, not a folder")
    if blocker is not None:
        raise ModelFileError(folder, f"cannot create the folder: '{blocker}' is a file")
    return folder


def make_folder(folder: str | Path) -> Path:
    """Create ``folder`` (and its parents) if needed.

    Raises:
        ModelFileError: it cannot be created.
    """
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ModelFileError(folder, f"cannot create the folder: {exc.strerror or exc}") \
            from None
    return folder


def check_ours(path: str | Path, marker: str | bytes) -> None:
    """Refuse to replace an existing file that pinlin did not write.

    A file that pinlin writes again and again (a report, an index, a plot) starts with
    ``marker`` (text, or bytes such as PNG's signature); an existing file at that path that
    does not is the user's, and is left alone.

    Raises:
        ModelFileError: ``path`` exists and does not start with ``marker`` (or is a folder).
    """
    path = Path(path)
    if not os.path.lexists(path):
        return
    if path.is_dir():
        raise ModelFileError(path, "cannot write the report: a folder has its name")
    head = marker.encode("utf-8") if isinstance(marker, str) else marker
    try:
        with path.open("rb") as fh:
            start = fh.read(len(head))
    except OSError as exc:
        raise ModelFileError(path, f"cannot read it: {exc.strerror or exc}") from None
    if start != head:
        shown = marker if isinstance(marker, str) else marker.decode("latin-1").strip("\x89")
        why = f"it does not start with \"{shown}\""
    elif not _pinlin_content(path, path.suffix.lower()):
        why = "it lacks the mark pinlin leaves in its files"
    else:
        return
    raise ModelFileError(path, f"exists and was not written by pinlin ({why}); pinlin does "
                               "not overwrite it: move it or choose another folder")


def _create_temp(target: Path) -> Path:
    """An empty new file beside ``target`` (mode 0o666 less the umask, as ``open`` gives)."""
    folder = _folder_of(target)
    stem = target.name[:64]          # keep the temporary name within NAME_MAX
    suffix = target.suffix[:16]      # some writers choose the format from the suffix
    for _ in range(100):
        tmp = folder / f".{stem}.{secrets.token_hex(4)}.tmp{suffix}"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"no free temporary name in '{folder}'")


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    The temporary file keeps ``path``'s suffix (some writers choose the format from it) and is
    removed if the block raises. A new file gets the permissions ``open`` would give (0o666
    less the umask); an existing file keeps its permissions (and owner, where allowed). A
    symbolic link is followed: the file it points to is replaced, the link stays.

    Raises:
        ArgumentError: ``path`` is not a path.
        ModelFileError: ``path`` is a folder, its folder does not exist or is a file, or the
            write fails (disk full, file size limit, ...).
    """
    path = check_file_target(path)
    target = _follow_link(path)
    try:
        before = target.stat() if target.exists() else None
        tmp = _create_temp(target)
    except OSError as exc:
        raise ModelFileError(path, f"cannot write: {exc.strerror or exc}") from None
    handed_over = False
    try:
        yield tmp
        if _PENDING:        # inside all_or_nothing(): renamed with the others at its end
            _PENDING[-1].append((tmp, target, before, path))
            handed_over = True
        else:
            _commit(tmp, target, before)
    except OSError as exc:
        raise ModelFileError(path, f"cannot write: {exc.strerror or exc}") from None
    finally:
        if not handed_over:
            with contextlib.suppress(OSError):
                tmp.unlink()


def _commit(tmp: Path, target: Path, before: os.stat_result | None) -> None:
    """Give ``tmp`` the permissions (and owner) of the file it replaces, and rename it."""
    if before is not None:
        os.chmod(tmp, stat.S_IMODE(before.st_mode))
        with contextlib.suppress(OSError):
            os.chown(tmp, before.st_uid, before.st_gid)
    os.replace(tmp, target)


#: Files written inside :func:`all_or_nothing` blocks, waiting for their rename (innermost last).
_PENDING: list[list[tuple[Path, Path, os.stat_result | None, Path]]] = []


@contextlib.contextmanager
def all_or_nothing() -> Iterator[None]:
    """Files written atomically inside the block appear together when it ends, or none of them
    does: each is written to its temporary file as usual, and the renames wait until the block
    has written them all (a command that writes a history and a plot keeps neither when the
    second write fails). An exception in the block removes the temporary files.

    Raises:
        ModelFileError: a rename fails (the files not yet renamed are removed).
    """
    pending: list[tuple[Path, Path, os.stat_result | None, Path]] = []
    _PENDING.append(pending)
    try:
        yield
    except BaseException:
        for tmp, *_ in pending:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise
    finally:
        _PENDING.pop()
    for k, (tmp, target, before, path) in enumerate(pending):
        try:
            _commit(tmp, target, before)
        except OSError as exc:
            for rest, *_ in pending[k:]:
                with contextlib.suppress(OSError):
                    rest.unlink()
            raise ModelFileError(path, f"cannot write: {exc.strerror or exc}") from None


def write_atomic(path: str | Path, writer: Callable[[IO[bytes]], object]) -> None:
    """Write ``path`` atomically through ``writer(binary_file)`` (flushed and synced to disk
    before the rename).

    Raises:
        ModelFileError: as :func:`atomic_path`; an exception ``writer`` raises that is not an
            OSError passes through unchanged (and nothing is written).
    """
    with atomic_path(path) as tmp, tmp.open("wb") as fh:
        writer(fh)
        fh.flush()
        os.fsync(fh.fileno())


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    write_atomic(path, lambda fh: fh.write(data))


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes_atomic(path, text.encode("utf-8"))
