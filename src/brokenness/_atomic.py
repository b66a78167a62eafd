"""Atomic file writes: a reader never sees a half-written file, even after a crash or Ctrl-C.

A failure is an :class:`AtomicWriteError` (an :class:`OSError`) that names the file asked
for, never the temporary file next to it: ``cannot write /proc/x.json: No such file or
directory``. Only regular files are replaced: a character device (``/dev/null``, a terminal)
is written in place, as a shell redirection would, and any other special file (a FIFO, a
socket, a block device) or a folder is refused, never replaced by a file.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

__all__ = [
    "AtomicWriteError",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_text",
    "sync_file",
]


class AtomicWriteError(OSError):
    """A file could not be written; ``filename`` is the file asked for (not the temporary one).

    Its text is one line: ``cannot write PATH: REASON``.
    """

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


def _write_error(exc: OSError, target: Path) -> AtomicWriteError:
    """``exc`` (about the temporary file, or without a file) as an error about ``target``."""
    reason = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
    return AtomicWriteError(exc.errno, reason, str(target))


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success it replaces ``path`` atomically.

    On any exception (KeyboardInterrupt included) the temporary file is removed and
    ``path`` is left as it was. A new file gets mode 0644, a replaced one keeps its mode.
    When ``path`` is a character device (``/dev/null``, a terminal) it is yielded itself and
    written in place: replacing it would put a file where the device was.

    Raises
    ------
    AtomicWriteError
        If ``path`` is a folder or a special file other than a character device, the
        temporary file cannot be made, or it cannot replace ``path``; an OSError of the body
        about the temporary file is raised as one too.
    """
    target = Path(path)
    try:
        # a new file gets the usual 0644 (mkstemp's 0600 would hide results from other
        # users); a file that is replaced keeps its mode
        kind = target.stat().st_mode if target.exists() else stat.S_IFREG | 0o644
    except OSError as exc:
        raise _write_error(exc, target) from None
    if stat.S_ISCHR(kind):  # /dev/null, a terminal: written in place, never replaced
        yield target
        return
    if not stat.S_ISREG(kind):
        code = errno.EISDIR if stat.S_ISDIR(kind) else errno.EINVAL
        reason = os.strerror(code) if code == errno.EISDIR else "not a regular file"
        raise AtomicWriteError(code, reason, str(target))
    mode = stat.S_IMODE(kind)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        os.close(fd)
    except OSError as exc:
        raise _write_error(exc, target) from None
    try:
        yield Path(tmp)
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, AtomicWriteError):
            if tmp in (exc.filename, exc.filename2):  # never show the temporary name
                raise _write_error(exc, target) from None
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically.

    Raises
    ------
    AtomicWriteError
        If the file cannot be written (no such folder, permission denied, disk full...).
    """
    with atomic_path(path) as tmp:
        try:
            with open(tmp, "wb") as fh:
                _write_and_sync(fh, data)
        except OSError as exc:
            raise _write_error(exc, Path(path)) from None


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def _write_and_sync(fh: IO[bytes], data: bytes) -> None:
    fh.write(data)
    fh.flush()
    sync_file(fh)


def sync_file(fh: IO[bytes]) -> None:
    """``os.fsync`` an open file; a device written in place (``/dev/null``), which cannot be
    synchronised (``EINVAL``), is left as it is."""
    try:
        os.fsync(fh.fileno())
    except OSError as exc:
        if exc.errno != errno.EINVAL:
            raise
