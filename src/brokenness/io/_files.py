"""File-level helpers shared by the map readers and writers.

Every error raised here names the file it is about and fits on one line, so that the
command-line interface can print it as is.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from .. import _atomic
from ..errors import MapError, MapFormatError, MapSizeError, ParameterError
from ..limits import max_file_bytes

__all__ = [
    "MapWarning",
    "as_path",
    "atomic_write_bytes",
    "check_regular",
    "file_kind",
    "one_line",
    "read_file_bytes",
    "require_file",
]


class MapWarning(UserWarning):
    """A map loaded or saved, but something about it is probably not what its author meant.

    Examples: a Nav2 map whose ``free_thresh`` turns the 205-grey "unknown" pixels into free
    space, or a map saved to a ROS YAML without a known resolution.
    """


def one_line(text: object) -> str:
    """Collapse any message (for instance a multi-line YAML parser error) onto one line."""
    return " ".join(str(text).split())


def as_path(path: object, what: str = "path") -> Path:
    """``path`` as a :class:`~pathlib.Path`; anything but a str, bytes or path-like is refused.

    Parameters
    ----------
    path : object
    what : str
        What the path is, for the message (``"path"``, ``"bag"``...).

    Returns
    -------
    Path

    Raises
    ------
    ParameterError
        If ``path`` is None or not a file path.
    """
    try:
        name = os.fspath(path)  # type: ignore[call-overload]
    except TypeError:
        shown = "None" if path is None else f"a {type(path).__name__}"
        raise ParameterError(
            f"the {what} must be a file path (str or os.PathLike), got {shown}"
        ) from None
    return Path(os.fsdecode(name))


_CHUNK_BYTES = 1 << 24  # a file that grows while it is read: read on in 16 MiB chunks

_KINDS: tuple[tuple[Callable[[int], bool], str], ...] = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def file_kind(mode: int) -> str:
    """What a ``st_mode`` is, in words (``"a FIFO (named pipe)"``, ``"a regular file"``...)."""
    if stat.S_ISREG(mode):
        return "a regular file"
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def check_regular(path: Path, what: str = "map file") -> os.stat_result:
    """Stat ``path`` (following symbolic links) and require a regular file.

    Nothing is opened: a FIFO, a device (``/dev/zero``...), a socket or a directory is refused
    before any read could block or run forever.

    Parameters
    ----------
    path : Path
    what : str
        What the file should be, for the message (``"map file"``, ``"manifest"``...).

    Returns
    -------
    os.stat_result

    Raises
    ------
    MapError
        Missing (or a dangling symbolic link), a symbolic link loop, permission denied on the
        way, or not a regular file.
    """
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            target = os.readlink(path)
            raise MapError(f"{path}: no such file (broken symbolic link to {target})") from None
        raise MapError(f"{path}: no such file") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise MapError(f"{path}: symbolic link loop (too many levels of links)") from None
        if exc.errno == errno.EACCES:
            raise MapError(f"{path}: cannot read the file (permission denied)") from None
        if exc.errno == errno.ENOTDIR:
            raise MapError(f"{path}: no such file (a part of the path is not a folder)") from None
        reason = one_line(exc.strerror or exc)
        raise MapError(f"{path}: cannot access the file ({reason})") from None
    except ValueError as exc:  # embedded NUL byte
        raise MapError(f"{path}: invalid file name ({one_line(exc)})") from None
    if stat.S_ISDIR(st.st_mode):
        raise MapError(f"{path}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise MapError(f"{path}: is {file_kind(st.st_mode)}, not a regular file: refused as {what}")
    return st


def require_file(path: Path) -> None:
    """Raise :class:`MapError` unless ``path`` is an existing regular file.

    Parameters
    ----------
    path : Path
        The file to check.

    Raises
    ------
    MapError
        If the path does not exist, is a directory, a FIFO, a device or a socket, or a
        symbolic link loop (see :func:`check_regular`).
    """
    check_regular(path)


def read_file_bytes(path: Path, limit: int | None = None, what: str = "map file") -> bytes:
    """Read a whole regular file of at most ``limit`` bytes; OS failures become one-line errors.

    The file is checked with :func:`check_regular` before it is opened, opened without
    blocking, checked again on the open descriptor (so a file swapped for a FIFO in between is
    still refused), and read only if its size is within the limit; at most ``limit + 1`` bytes
    are ever read.

    Parameters
    ----------
    path : Path
    limit : int, optional
        Largest size in bytes (default :func:`brokenness.limits.max_file_bytes`).
    what : str
        What the file should be, for messages.

    Raises
    ------
    MapError
        Missing, not a regular file, not readable (permissions) or another OS error.
    MapSizeError
        If the file is larger than ``limit``.
    MapFormatError
        If the file is empty.
    """
    cap = max_file_bytes() if limit is None else int(limit)
    st = check_regular(path, what)
    _check_size(path, st.st_size, cap, what)
    try:
        fd = open_nonblocking(path)
    except PermissionError:
        raise MapError(f"{path}: cannot read the file (permission denied)") from None
    except OSError as exc:
        raise MapError(f"{path}: cannot read the file ({one_line(exc.strerror or exc)})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise MapError(f"{path}: is {file_kind(st.st_mode)}, not a regular file")
        _check_size(path, st.st_size, cap, what)
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = _read_capped(fh, st.st_size, cap)
    except OSError as exc:
        raise MapError(f"{path}: cannot read the file ({one_line(exc.strerror or exc)})") from None
    finally:
        os.close(fd)
    if len(data) > cap:
        raise MapSizeError(f"{path}: the {what} is larger than the limit of {cap} bytes")
    if not data:
        raise MapFormatError(f"{path}: empty file")
    return data


def _read_capped(fh: BinaryIO, expected: int, cap: int) -> bytes:
    """At most ``cap + 1`` bytes of ``fh``, allocating about ``expected`` bytes first.

    ``fh.read(n)`` allocates ``n`` bytes at once, so the limit itself is never asked for:
    the size ``fstat`` gave, then (only if the file grew since) chunks up to the limit.
    """
    first = min(expected, cap) + 1
    data = fh.read(first)
    if len(data) < first:  # the end of the file, where fstat said (or before)
        return data
    parts, total = [data], len(data)
    while total <= cap:
        more = fh.read(min(cap + 1 - total, _CHUNK_BYTES))
        if not more:
            break
        parts.append(more)
        total += len(more)
    return b"".join(parts)


def open_nonblocking(path: Path) -> int:
    """``os.open`` for reading that never blocks (``O_NONBLOCK``: a FIFO cannot hang it)."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    return os.open(path, flags | getattr(os, "O_CLOEXEC", 0))


def _check_size(path: Path, size: int, cap: int, what: str) -> None:
    if size > cap:
        raise MapSizeError(
            f"{path}: the {what} has {size} bytes, more than the limit of {cap} bytes"
        )


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: a temporary file in the same folder, then rename.

    A reader never sees a half-written file, and a failed write leaves any previous file
    untouched. A new file gets mode 0644; an existing file keeps its mode.

    Raises
    ------
    MapError
        If the folder does not exist or cannot be written.
    """
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise MapError(f"{path}: cannot write, folder {folder} does not exist")
    try:
        _atomic.atomic_write_bytes(path, data)
    except OSError as exc:
        raise MapError(f"{path}: cannot write ({one_line(exc.strerror or exc)})") from None
