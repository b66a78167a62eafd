"""Checks of output paths and options, done before any computation.

Every subcommand names the files and folders it will write, and the files it reads, to
:func:`check_outputs` right after parsing, so that ``--overlay out.jpgx``, ``--overlay
nodir/o.png``, ``--json /proc/x.json`` or ``--repaired reference.yaml`` fails at once with
one line, not after minutes of computation (or as a raw ``Errno``, or by overwriting an
input).
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import BrokennessError, ParameterError

__all__ = [
    "MAP_SUFFIXES",
    "RESULT_SUFFIXES",
    "Output",
    "check_outputs",
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


@dataclass(frozen=True)
class Output:
    """A file or folder a command writes, as one of its options names it.

    Attributes
    ----------
    option : str
        The option, for messages (``"--json"``).
    path : str or None
        The path as given; ``None`` (option not given) and ``"-"`` (standard output) are
        not checked.
    suffixes : tuple of str, optional
        Accepted suffixes of a file, lower case with the dot; ``None`` accepts any.
    folder : bool
        A folder the command writes into (created if missing), not a file.
    writes : tuple of str
        Other files the option writes: a YAML map's image next to it, a folder's files
        with fixed names (``summary.csv``); checked against the inputs too.
    """

    option: str
    path: str | None
    suffixes: tuple[str, ...] | None = None
    folder: bool = False
    writes: tuple[str, ...] = ()


def check_outputs(outputs: Iterable[Output], inputs: Iterable[str] = ()) -> None:
    """Check every path a command will write, before it does any work.

    A file's folder must exist and take a new file (one is made and removed: the test that
    holds for every user and file system, ``/proc`` and read-only mounts included), its
    suffix must be one the writer supports, and the path must not be a folder, nor an
    existing special file other than a character device (``/dev/null``, written in place).
    A folder must be one, or be creatable. No path written may be one of the command's
    inputs (compared as files: links and ``..`` resolved) or the image a YAML input names,
    and no two outputs may be the same file.

    Parameters
    ----------
    outputs : iterable of Output
    inputs : iterable of str
        The files the command reads, as given.

    Raises
    ------
    ParameterError
        The first problem found, on one line naming the option.
    """
    given = [o for o in outputs if o.path is not None and o.path != "-"]
    for out in given:
        if out.folder:
            _check_folder(str(out.path), out.option)
        else:
            _check_file(str(out.path), out.option, out.suffixes)
    _check_distinct(given, _input_files(inputs))


def _check_file(path: str, option: str, suffixes: Sequence[str] | None) -> None:
    p = Path(path)
    if suffixes is not None and p.suffix.lower() not in suffixes:
        got = repr(p.suffix) if p.suffix else "no suffix"
        raise ParameterError(
            f"{option} {path}: unsupported file type ({got}; use {', '.join(suffixes)})"
        )
    if p.is_dir():
        raise ParameterError(f"{option} {path}: is a folder, not a file")
    with contextlib.suppress(OSError):
        mode = p.stat().st_mode
        if not (stat.S_ISREG(mode) or stat.S_ISCHR(mode)):
            raise ParameterError(f"{option} {path}: exists and is not a regular file")
    _writable_folder(p.parent if str(p.parent) else Path("."), path, option)


def _check_folder(path: str, option: str) -> None:
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise ParameterError(f"{option} {path}: exists and is not a folder")
        _writable_folder(p, path, option)
        return
    parent = p.absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ParameterError(f"{option} {path}: {parent} is not a folder")
    reason = _cannot_write_into(parent)
    if reason:
        raise ParameterError(
            f"{option} {path}: cannot create it, {parent} is not writable ({reason})"
        )


def _writable_folder(folder: Path, shown: str, option: str) -> None:
    if not folder.exists():
        raise ParameterError(f"{option} {shown}: folder {folder} does not exist")
    if not folder.is_dir():
        raise ParameterError(f"{option} {shown}: {folder} is not a folder")
    reason = _cannot_write_into(folder)
    if reason:
        raise ParameterError(  # the atomic write's words: "cannot write PATH: ..."
            f"{option}: cannot write {shown}: folder {folder} is not writable ({reason})"
        )


def _cannot_write_into(folder: Path) -> str | None:
    """Why no file can be made in ``folder`` (``None``: it can; one was made and removed).

    ``os.access`` says yes to root everywhere, and to anyone in ``/proc``; making a file is
    what the atomic write will do (:mod:`brokenness._atomic`), so it is the test.
    """
    try:
        fd, probe = tempfile.mkstemp(prefix=".brokenness-check-", dir=folder)
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)
    return None


def _input_files(inputs: Iterable[str]) -> list[tuple[Path, str]]:
    """Each input as ``(path, what it is)``, with the image each YAML map names."""
    files: list[tuple[Path, str]] = []
    for text in inputs:
        path = Path(text)
        files.append((path, f"is an input of this command ({text}): not overwritten"))
        image = _yaml_image(path)
        if image is not None:
            files.append((image, f"is the image of the input map {text}: not overwritten"))
    return files


def _yaml_image(path: Path) -> Path | None:
    """The image a ROS map YAML names, or ``None`` (not a YAML map, or unreadable: loading
    it will say why, after the outputs are checked)."""
    if path.suffix.lower() not in (".yaml", ".yml") or not path.is_file():
        return None
    from ..io.ros_yaml import read_map_yaml

    try:
        return read_map_yaml(path).image
    except BrokennessError:
        return None


def _same_file(a: Path, b: Path) -> bool:
    """``a`` and ``b`` are one file: the same inode when both exist, else the same path once
    links and ``..`` are resolved."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def _check_distinct(outputs: Sequence[Output], inputs: list[tuple[Path, str]]) -> None:
    """No output (nor a file it writes) is an input, or another output's file."""
    written: list[tuple[Path, str]] = []
    for out in outputs:
        base = Path(str(out.path))
        extra = [base / name if out.folder else Path(name) for name in out.writes]
        for path in ([] if out.folder else [base]) + extra:
            shown = out.path if path == base else f"{out.path} (writes {path})"
            for other, what in inputs + written:
                if _same_file(path, other):
                    raise ParameterError(f"{out.option} {shown}: {what}")
            written.append((path, f"is written by {out.option} too"))


def check_seed(seed: int | None) -> None:
    """A seed of the random-walk method must be in [0, 2**63) (numpy's generators' range).

    Raises
    ------
    ParameterError
    """
    if seed is not None and not 0 <= seed < 2**63:
        raise ParameterError(f"--seed must be in [0, 2**63), got {seed}")
