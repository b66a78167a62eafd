"""Gather result files for comparison: result zips, batch output folders, their error files.

:func:`collect_results` turns the paths given to ``brokenness compare`` into a flat list of
:class:`ResultEntry`: one per result zip (written by :func:`brokenness.report.save_results`,
``brokenness compute --save-results`` or ``brokenness batch``) and one per
``<pair>.error.json`` of a batch folder (a failed pair, counted as a failure). Only the small
JSON members of a zip are used, so the maps themselves are not needed.
"""

from __future__ import annotations

import math
import os
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import BrokennessError
from ..limits import MAX_TEXT_BYTES
from .results import ResultFileError, load_results, parse_json

__all__ = ["ERROR_SUFFIX", "ResultEntry", "collect_results", "label_names", "sort_key"]

#: Suffix of the error file a batch writes for a failed pair.
ERROR_SUFFIX = ".error.json"


@dataclass(frozen=True)
class ResultEntry:
    """One evaluated (or failed) map, as far as comparison tables and plots need it.

    Attributes
    ----------
    path : Path
        The result zip or error file.
    labels : dict of str to str
        The run's labels (system, dataset, noise...); empty for a single ``compute`` run.
    degree : int or None
        Degree of brokenness; ``None`` for a failure or when it was not measured.
    measured : bool
        False for a result whose degree was not measured (the map may not be of the
        reference's place) and for a failure.
    partition_fractions : tuple of float
        Share of the occupied cells of each partition, largest first.
    psi_map, psi_repaired : float or None
        Picture distances of the aligned and the repaired map to the reference.
    error : str or None
        The message of a failed pair.
    method : str or None
        Registration method of the computation (``None`` for a failure).
    parameters : dict
        Parameters of the computation (``info.json``), empty for a failure.
    """

    path: Path
    labels: dict[str, str] = field(default_factory=dict, hash=False)
    degree: int | None = None
    measured: bool = False
    partition_fractions: tuple[float, ...] = ()
    psi_map: float | None = None
    psi_repaired: float | None = None
    error: str | None = None
    method: str | None = None
    parameters: dict[str, Any] = field(default_factory=dict, hash=False)

    @property
    def failed(self) -> bool:
        """True for a pair that has no result."""
        return self.error is not None

    @property
    def largest_fraction(self) -> float | None:
        """Share of the occupied cells in the largest partition."""
        return self.partition_fractions[0] if self.partition_fractions else None


def _float(value: Any) -> float | None:
    try:
        return None if value is None else float(value)
    except (TypeError, ValueError):
        return None


def _labels(value: Any) -> dict[str, str]:
    if not isinstance(value, dict):
        return {}
    return {str(k): str(v) for k, v in value.items() if v is not None and str(v) != ""}


def _from_zip(path: Path) -> ResultEntry:
    record = load_results(path)  # every field read here checked there (types, the degree)
    stats = record.stats
    degree = record.degree
    return ResultEntry(
        path=path,
        labels=_labels(record.info.get("labels")),
        degree=degree,
        measured=degree is not None,
        partition_fractions=tuple(float(p["fraction"]) for p in stats.get("partitions") or []),
        psi_map=_float(stats.get("psi_map")),
        psi_repaired=_float(stats.get("psi_repaired")),
        method=record.info.get("method") or None,
        parameters=dict(record.info.get("parameters") or {}),
    )


def _from_error_file(path: Path) -> ResultEntry:
    from ..io._files import read_file_bytes

    try:
        doc = parse_json(read_file_bytes(path, MAX_TEXT_BYTES, "batch error file"))
    except BrokennessError as exc:
        raise ResultFileError(str(exc)) from None
    except ValueError as exc:  # bad JSON, not UTF-8, non-finite numbers
        raise ResultFileError(f"{path}: unreadable error file ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != "brokenness-error":
        raise ResultFileError(f"{path}: not a brokenness error file")
    message = " ".join(str(doc.get("error") or "unknown error").split())
    return ResultEntry(path=path, labels=_labels(doc.get("labels")), error=message)


def _files_in(folder: Path) -> list[Path]:
    files = [p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")]
    return sorted(p for p in files if p.suffix.lower() == ".zip" or p.name.endswith(ERROR_SUFFIX))


def _one(path: Path) -> ResultEntry:
    if path.name.endswith(ERROR_SUFFIX):
        return _from_error_file(path)
    if path.suffix.lower() != ".zip" and not zipfile.is_zipfile(path):
        raise ResultFileError(f"{path}: not a result zip")
    return _from_zip(path)


def collect_results(paths: Iterable[str | os.PathLike[str]]) -> list[ResultEntry]:
    """Read result zips and error files, and every one of them in the folders given.

    Parameters
    ----------
    paths : iterable of path-like
        Result zips, ``*.error.json`` files, or folders holding them (a ``brokenness
        batch`` output folder; not searched recursively). A file given twice counts once.

    Returns
    -------
    list of ResultEntry
        In the order given, a folder's files sorted by name.

    Raises
    ------
    ResultFileError
        For a missing path, a file that is not a regular file or not a result zip, a damaged
        zip (see :func:`brokenness.report.load_results`), a folder without result files, or
        no paths at all.

    Examples
    --------
    >>> entries = collect_results(["results/"])  # doctest: +SKIP
    >>> sum(e.failed for e in entries)  # doctest: +SKIP
    """
    files: list[Path] = []
    for item in paths:
        p = Path(os.fspath(item))
        if p.is_dir():
            found = _files_in(p)
            if not found:
                raise ResultFileError(f"{p}: no result files (*.zip) in this folder")
            files += found
        elif p.is_file():
            files.append(p)
        elif not os.path.lexists(p):
            raise ResultFileError(f"{p}: no such result file or folder")
        else:  # a FIFO, a device, a symbolic link loop...: say which
            from ..io._files import check_regular

            try:
                check_regular(p, "result file")
            except BrokennessError as exc:
                raise ResultFileError(str(exc)) from None
            files.append(p)
    if not files:
        raise ResultFileError("no result files given")
    seen: set[Path] = set()
    entries = []
    for f in files:
        key = f.resolve()
        if key not in seen:
            seen.add(key)
            entries.append(_one(f))
    return entries


def label_names(entries: Sequence[ResultEntry]) -> list[str]:
    """Every label name used by some entry, in first-seen order."""
    names: dict[str, None] = {}
    for e in entries:
        names.update(dict.fromkeys(e.labels))
    return list(names)


def sort_key(value: str | None) -> tuple[int, float, str]:
    """Order label values: numbers numerically first, then text, missing values last."""
    if value is None or value == "":
        return (2, 0.0, "")
    try:
        number = float(value)
    except ValueError:
        return (1, 0.0, value)
    return (0, number, value) if math.isfinite(number) else (1, 0.0, value)
