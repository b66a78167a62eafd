"""File-level helpers shared by the map readers and writers.

Every error raised here names the file it is about and fits on one line, so that the
command-line interface can print it as is.
"""

from __future__ import annotations

import errno
import math
import os
import reprlib
import stat
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from .. import _atomic
from ..errors import MapError, MapFormatError, MapSizeError, ParameterError
from ..limits import max_file_bytes

__all__ = [
    "PATH_CHARS",
    "REASON_CHARS",
    "SHOWN_CHARS",
    "MapWarning",
    "as_path",
    "atomic_write_bytes",
    "check_regular",
    "file_kind",
    "one_line",
    "path_text",
    "read_file_bytes",
    "require_file",
    "shown",
    "stat_path",
]

#: Longest echo of a value (read from a file, or passed as an argument) in a message.
SHOWN_CHARS: int = 80
#: Longest echo of another library's error text (a parser's, a bag reader's) in a message.
REASON_CHARS: int = 240
#: Longest echo of a path in a message: far longer than any real path is in practice; a
#: longer one keeps its start and its end (the file name).
PATH_CHARS: int = 512


class MapWarning(UserWarning):
    """A map loaded or saved, but something about it is probably not what its author meant.

    Examples: a Nav2 map whose ``free_thresh`` turns the 205-grey "unknown" pixels into free
    space, or a map saved to a ROS YAML without a known resolution.
    """


def one_line(text: object, limit: int | None = None) -> str:
    """Collapse any message (for instance a multi-line YAML parser error) onto one line.

    Parameters
    ----------
    text : object
    limit : int, optional
        At most this many characters (the end cut to ``...``); no limit by default. Give
        :data:`REASON_CHARS` for another library's error text, which may echo its input.

    Returns
    -------
    str
    """
    return _clip(" ".join(str(text).split()), limit)


def _clip(text: str, limit: int | None) -> str:
    """``text`` cut to at most ``limit`` characters, the cut marked with ``...``."""
    if limit is None or len(text) <= limit:
        return text
    return text[: max(limit - 3, 0)] + "..."


def shown(value: object, limit: int = SHOWN_CHARS) -> str:
    """A short one-line ``repr`` of a value, for an error message.

    Every value a message echoes goes through this: a long string keeps its start and end, a
    list or a mapping its first items, nesting is cut to ``...`` (:mod:`reprlib`), and the
    result has at most ``limit`` characters. A newline shows as ``\\n``. So a hostile file (a
    500 kB string, a list of a billion items) cannot make a message long, and the work is
    bounded however large the value.

    Parameters
    ----------
    value : object
    limit : int
        Longest result (default :data:`SHOWN_CHARS`).

    Returns
    -------
    str

    Examples
    --------
    >>> shown("a" * 1000, limit=20)
    "'aaaaaaa...aaaaaaaa'"
    >>> shown([[1, 2], [3, [4, [5]]]])
    '[[1, 2], [3, [4, [...]]]]'
    >>> shown(10**5000)
    '<int of about 5001 digits>'
    """
    short = reprlib.Repr()
    short.maxlevel = 3
    short.maxstring = short.maxother = short.maxlong = limit
    for name in ("maxlist", "maxtuple", "maxdict", "maxset", "maxfrozenset", "maxdeque"):
        setattr(short, name, 6)
    try:
        text = short.repr(value)
    except Exception:  # a repr that fails (an int too long to print, a broken __repr__...)
        text = _unprintable(value)
    if not text.isprintable():  # a repr of something else than a str may hold newlines
        text = " ".join(text.split())
    return _clip(text, limit)


def _unprintable(value: object) -> str:
    """What :func:`shown` says of a value whose ``repr`` fails."""
    if isinstance(value, int):  # Python refuses to print an int of more than 4300 digits
        digits = math.floor(abs(value).bit_length() * math.log10(2)) + 1
        return f"<int of about {digits} digits>"
    return f"<{type(value).__name__}>"


def path_text(path: object) -> str:
    """A path as a message shows it: as is, or escaped and shortened when it must be.

    A path of printable characters shows unchanged; one holding a newline, a tab or another
    non-printable character (or bytes that are not valid in the file system's encoding)
    shows as its ``repr``, so the message stays on one line. A path longer than
    :data:`PATH_CHARS` keeps its start and its end (the file name).

    Parameters
    ----------
    path : str, bytes or path-like

    Returns
    -------
    str

    Examples
    --------
    >>> path_text("maps/a.yaml")
    'maps/a.yaml'
    >>> path_text("maps/a\\nb.png")
    "'maps/a\\\\nb.png'"
    """
    text = os.fsdecode(path) if isinstance(path, str | bytes | os.PathLike) else str(path)
    if not text.isprintable():
        text = repr(text)
    if len(text) > PATH_CHARS:
        half = (PATH_CHARS - 3) // 2
        text = text[:half] + "..." + text[len(text) - half :]
    return text


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
        kind = "None" if path is None else f"a {type(path).__name__}"
        raise ParameterError(
            f"the {what} must be a file path (str or os.PathLike), got {kind}"
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


def stat_path(path: Path) -> os.stat_result:
    """``os.stat(path)`` (following symbolic links); every failure a one-line MapError.

    Parameters
    ----------
    path : Path

    Returns
    -------
    os.stat_result

    Raises
    ------
    MapError
        Missing (or a dangling symbolic link), a symbolic link loop, permission denied on the
        way (a folder of the path that cannot be entered), an invalid name.
    """
    name = path_text(path)
    try:
        return os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            try:
                target = path_text(os.readlink(path))
            except OSError:
                target = "a missing file"
            raise MapError(f"{name}: no such file (broken symbolic link to {target})") from None
        raise MapError(f"{name}: no such file") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise MapError(f"{name}: symbolic link loop (too many levels of links)") from None
        if exc.errno == errno.EACCES:
            raise MapError(f"{name}: cannot read the file (permission denied)") from None
        if exc.errno == errno.ENOTDIR:
            raise MapError(f"{name}: no such file (a part of the path is not a folder)") from None
        reason = one_line(exc.strerror or exc, REASON_CHARS)
        raise MapError(f"{name}: cannot access the file ({reason})") from None
    except ValueError as exc:  # embedded NUL byte
        raise MapError(f"{name}: invalid file name ({one_line(exc, REASON_CHARS)})") from None


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
        way, or not a regular file (see :func:`stat_path`).
    """
    st = stat_path(path)
    name = path_text(path)
    if stat.S_ISDIR(st.st_mode):
        raise MapError(f"{name}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise MapError(f"{name}: is {file_kind(st.st_mode)}, not a regular file: refused as {what}")
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
    name = path_text(path)
    try:
        fd = open_nonblocking(path)
    except PermissionError:
        raise MapError(f"{name}: cannot read the file (permission denied)") from None
    except OSError as exc:
        reason = one_line(exc.strerror or exc, REASON_CHARS)
        raise MapError(f"{name}: cannot read the file ({reason})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise MapError(f"{name}: is {file_kind(st.st_mode)}, not a regular file")
        _check_size(path, st.st_size, cap, what)
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = _read_capped(fh, st.st_size, cap)
    except OSError as exc:
        reason = one_line(exc.strerror or exc, REASON_CHARS)
        raise MapError(f"{name}: cannot read the file ({reason})") from None
    finally:
        os.close(fd)
    if len(data) > cap:
        raise MapSizeError(f"{name}: the {what} is larger than the limit of {cap} bytes")
    if not data:
        raise MapFormatError(f"{name}: empty file")
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
            f"{path_text(path)}: the {what} has {size} bytes, more than the limit of {cap} bytes"
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
    if not os.path.isdir(folder):  # False (not PermissionError) for a folder not to be entered
        raise MapError(
            f"{path_text(path)}: cannot write, folder {path_text(folder)} does not exist "
            "(or cannot be entered)"
        )
    try:
        _atomic.atomic_write_bytes(path, data)
    except OSError as exc:
        reason = one_line(exc.strerror or exc, REASON_CHARS)
        raise MapError(f"{path_text(path)}: cannot write ({reason})") from None
