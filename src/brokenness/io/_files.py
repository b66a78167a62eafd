"""File-level helpers shared by the map readers and writers.

Every error raised here names the file it is about and fits on one line, so that the
command-line interface can print it as is.
"""

from __future__ import annotations

from pathlib import Path

from .. import _atomic
from ..errors import MapError, MapFormatError

__all__ = ["MapWarning", "atomic_write_bytes", "one_line", "read_file_bytes", "require_file"]


class MapWarning(UserWarning):
    """A map loaded or saved, but something about it is probably not what its author meant.

    Examples: a Nav2 map whose ``free_thresh`` turns the 205-grey "unknown" pixels into free
    space, or a map saved to a ROS YAML without a known resolution.
    """


def one_line(text: object) -> str:
    """Collapse any message (for instance a multi-line YAML parser error) onto one line."""
    return " ".join(str(text).split())


def require_file(path: Path) -> None:
    """Raise :class:`MapError` unless ``path`` is an existing regular file.

    Parameters
    ----------
    path : Path
        The file to check.

    Raises
    ------
    MapError
        If the path does not exist or is a directory.
    """
    if not path.exists():
        raise MapError(f"{path}: no such file")
    if path.is_dir():
        raise MapError(f"{path}: is a directory, not a map file")


def read_file_bytes(path: Path) -> bytes:
    """Read a whole file, turning every OS failure into a one-line :class:`MapError`.

    Raises
    ------
    MapError
        Missing, a directory, not readable (permissions) or another OS error.
    MapFormatError
        If the file is empty.
    """
    require_file(path)
    try:
        data = path.read_bytes()
    except PermissionError:
        raise MapError(f"{path}: cannot read the file (permission denied)") from None
    except OSError as exc:
        raise MapError(f"{path}: cannot read the file ({one_line(exc.strerror or exc)})") from None
    if not data:
        raise MapFormatError(f"{path}: empty file")
    return data


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
