"""Checks of output paths and options, done before any computation.

Every subcommand validates the files and folders it will write with :func:`check_output_file`
and :func:`check_output_folder` right after parsing, so that ``--overlay out.jpgx`` or
``--overlay nodir/o.png`` fails at once with one line, not after minutes of computation (or
as a raw ``Errno``).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from ..errors import ParameterError

__all__ = [
    "MAP_SUFFIXES",
    "RESULT_SUFFIXES",
    "check_output_file",
    "check_output_folder",
    "check_seed",
    "figure_suffixes",
]

#: Suffixes :func:`brokenness.save_map` writes.
MAP_SUFFIXES: tuple[str, ...] = (".yaml", ".yml", ".pgm", ".png", ".npy")
#: Suffix of a result record.
RESULT_SUFFIXES: tuple[str, ...] = (".zip",)


def figure_suffixes() -> tuple[str, ...]:
    """Suffixes matplotlib can save a figure as (``.png``, ``.pdf``, ``.svg``...)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    return tuple(sorted("." + k for k in FigureCanvasAgg.get_supported_filetypes()))


def _writable_folder(folder: Path, shown: str, option: str) -> None:
    if not folder.exists():
        raise ParameterError(f"{option} {shown}: folder {folder} does not exist")
    if not folder.is_dir():
        raise ParameterError(f"{option} {shown}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ParameterError(f"{option} {shown}: folder {folder} is not writable")


def check_output_file(path: str, option: str, suffixes: Iterable[str] | None = None) -> Path:
    """Validate a file that a command will write: folder exists and is writable, suffix known.

    Parameters
    ----------
    path : str
        The path as given on the command line.
    option : str
        The option's name, for the message (``"--overlay"``).
    suffixes : iterable of str, optional
        Accepted suffixes, lower case with the dot; ``None`` accepts any.

    Returns
    -------
    Path

    Raises
    ------
    ParameterError
        Unsupported suffix, a missing or read-only folder, or a path that is a folder.
    """
    p = Path(path)
    if suffixes is not None:
        allowed = tuple(suffixes)
        if p.suffix.lower() not in allowed:
            got = repr(p.suffix) if p.suffix else "no suffix"
            raise ParameterError(
                f"{option} {path}: unsupported file type ({got}; use {', '.join(allowed)})"
            )
    if p.is_dir():
        raise ParameterError(f"{option} {path}: is a folder, not a file")
    _writable_folder(p.parent if str(p.parent) else Path("."), path, option)
    return p


def check_output_folder(path: str, option: str) -> Path:
    """Validate a folder that a command will write into (created if missing).

    The folder, or its nearest existing parent when it is to be created, must be a writable
    folder.

    Raises
    ------
    ParameterError
    """
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise ParameterError(f"{option} {path}: exists and is not a folder")
        _writable_folder(p, path, option)
        return p
    parent = p.absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ParameterError(f"{option} {path}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ParameterError(f"{option} {path}: cannot create it, {parent} is not writable")
    return p


def check_seed(seed: int | None) -> None:
    """A seed of the random-walk method must be in [0, 2**63) (numpy's generators' range).

    Raises
    ------
    ParameterError
    """
    if seed is not None and not 0 <= seed < 2**63:
        raise ParameterError(f"--seed must be in [0, 2**63), got {seed}")
