"""Comparison tables: results grouped by their labels (system, dataset, noise...).

One row per group of results that share the values of the grouping labels: the number of
results, failures, mean, median, standard deviation, minimum and maximum degree, the mean
share of the largest partition, and the mean picture distances Psi of the aligned and of
the repaired map. Written as CSV or Markdown (by the file's suffix) and shown in the
terminal with rich.

Results computed with different methods or parameters are never pooled silently: unless
asked to (``pool=True``), the method and the parameters that differ between the results
(:data:`RUN_COLUMNS`) are grouped by as well, as if they were labels.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError
from .collect import ResultEntry, label_names, sort_key
from .results import atomic_write

__all__ = [
    "FIGURES",
    "GroupRow",
    "GroupTable",
    "RUN_COLUMNS",
    "group_table",
    "rich_table",
    "table_csv",
    "table_markdown",
    "write_table",
]

#: Figure columns of a table, after the label columns.
FIGURES: tuple[str, ...] = (
    "results",
    "not_measured",
    "failed",
    "mean_degree",
    "median_degree",
    "sd_degree",
    "min_degree",
    "max_degree",
    "mean_largest_fraction",
    "mean_psi_map",
    "mean_psi_repaired",
)
#: Labels that lead a default grouping, in this order (the rest follow as first seen).
_FIRST_LABELS = ("system", "method", "dataset")
_SHORT = {
    "results": "n",
    "not_measured": "not measured",
    "failed": "failed",
    "mean_degree": "deg mean",
    "median_degree": "deg median",
    "sd_degree": "deg s.d.",
    "min_degree": "min",
    "max_degree": "max",
    "mean_largest_fraction": "largest",
    "mean_psi_map": "\N{GREEK CAPITAL LETTER PSI} map",
    "mean_psi_repaired": "\N{GREEK CAPITAL LETTER PSI} repaired",
}
_SUFFIXES = {".csv": "csv", ".md": "markdown", ".markdown": "markdown"}
#: Grouping columns made from how a result was computed, not from its labels: its method
#: and the parameters that differ between the results compared (``k=v; k=v``).
RUN_COLUMNS: tuple[str, ...] = ("method", "parameters")
#: Parameters that differ from run to run by design, never a reason to keep results apart.
_RUN_SPECIFIC = frozenset(
    {
        "seed",
        "working_resolution",
        "working_threshold",
        "wall_thickness",
        "frame",
        "frame_degrees",
        # what step 11 found, for the maps it measured again (not an option of the run)
        "replication_frame",
        "replication_degree",
        "replication_placed_alike",
        "replication_placed_alike_in_doubt",
    }
)


@dataclass(frozen=True)
class GroupRow:
    """Figures of one group of results.

    Attributes
    ----------
    key : tuple of str or None
        The group's value of each grouping label (``None``: the label is not set).
    results : int
        Results with a degree (failures and results not measured not counted): the figures
        below are over these.
    not_measured : int
        Results whose degree was not measured (the map may not be of the reference's place).
    failed : int
        Failed pairs (batch error files).
    mean_degree, median_degree : float or None
    sd_degree : float or None
        Sample standard deviation of the degrees (``None`` under two results).
    min_degree, max_degree : int or None
    mean_largest_fraction : float or None
        Mean share of the occupied cells in the largest partition.
    mean_psi_map, mean_psi_repaired : float or None
        Mean Psi of the aligned map and of the repaired map against the reference.
    """

    key: tuple[str | None, ...]
    results: int
    not_measured: int
    failed: int
    mean_degree: float | None
    median_degree: float | None
    sd_degree: float | None
    min_degree: int | None
    max_degree: int | None
    mean_largest_fraction: float | None
    mean_psi_map: float | None
    mean_psi_repaired: float | None

    def value(self, column: str) -> Any:
        """The figure named ``column``."""
        return getattr(self, column)


@dataclass(frozen=True)
class GroupTable:
    """Rows grouped by ``group_by`` (labels), sorted by their values."""

    group_by: tuple[str, ...]
    rows: tuple[GroupRow, ...]

    @property
    def columns(self) -> list[str]:
        """Label columns, then :data:`FIGURES`."""
        return list(self.group_by) + list(FIGURES)

    def records(self) -> list[dict[str, Any]]:
        """One dict per row, keyed by :attr:`columns`."""
        out = []
        for row in self.rows:
            rec: dict[str, Any] = dict(zip(self.group_by, row.key, strict=True))
            rec.update({c: row.value(c) for c in FIGURES})
            out.append(rec)
        return out


def _mean(values: Sequence[float]) -> float | None:
    return float(np.mean(values)) if len(values) else None


def _group_row(key: tuple[str | None, ...], members: Sequence[ResultEntry]) -> GroupRow:
    ok = [e for e in members if not e.failed and e.measured]
    degrees = [float(e.degree) for e in ok if e.degree is not None]
    largest = [e.largest_fraction for e in ok if e.largest_fraction is not None]
    psi_map = [e.psi_map for e in ok if e.psi_map is not None]
    psi_rep = [e.psi_repaired for e in ok if e.psi_repaired is not None]
    return GroupRow(
        key=key,
        results=len(ok),
        not_measured=sum(1 for e in members if not e.failed and not e.measured),
        failed=sum(1 for e in members if e.failed),
        mean_degree=_mean(degrees),
        median_degree=float(np.median(degrees)) if degrees else None,
        sd_degree=float(np.std(degrees, ddof=1)) if len(degrees) > 1 else None,
        min_degree=int(min(degrees)) if degrees else None,
        max_degree=int(max(degrees)) if degrees else None,
        mean_largest_fraction=_mean(largest),
        mean_psi_map=_mean(psi_map),
        mean_psi_repaired=_mean(psi_rep),
    )


def _parameter_text(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)


def run_settings(entries: Sequence[ResultEntry]) -> dict[str, dict[int, str]]:
    """The :data:`RUN_COLUMNS` that differ between the (successful) results.

    Returns ``{column: {id(entry): value}}`` for ``method`` when the results were computed
    with more than one method, and for ``parameters`` when some parameter (other than the
    seed) differs: the value lists those parameters as ``name=value; ...``. Failures have
    no setting; :func:`group_table` puts them with the results of their labels.
    """
    done = [e for e in entries if not e.failed]
    out: dict[str, dict[int, str]] = {}
    methods = {e.method or "" for e in done}
    if len(methods) > 1:
        out["method"] = {id(e): e.method or "?" for e in done}
    names = sorted({k for e in done for k in e.parameters} - _RUN_SPECIFIC)
    varying = [k for k in names if len({_parameter_text(e.parameters.get(k)) for e in done}) > 1]
    if varying:
        out["parameters"] = {
            id(e): "; ".join(f"{k}={_parameter_text(e.parameters.get(k))}" for k in varying)
            for e in done
        }
    return out


def group_table(
    entries: Sequence[ResultEntry],
    group_by: Sequence[str] | None = None,
    *,
    pool: bool = False,
) -> GroupTable:
    """Group results by labels and compute each group's figures.

    Parameters
    ----------
    entries : sequence of ResultEntry
        From :func:`brokenness.report.collect_results`.
    group_by : sequence of str, optional
        Label names. Default: every label the results have except ``seed`` (seeds are what
        a mean is taken over), ``system``, ``method`` and ``dataset`` first; no labels at
        all gives one group of everything.
    pool : bool
        Pool results computed with different methods or parameters. By default they are
        kept apart: the method and the differing parameters become grouping columns
        (:data:`RUN_COLUMNS`, after the labels) whenever the results differ in them.

    Returns
    -------
    GroupTable
        Groups sorted by their label values (numbers numerically).

    Raises
    ------
    ParameterError
        If a ``group_by`` label is used by none of the results.

    Examples
    --------
    >>> table = group_table(collect_results(["results/"]), ["system", "noise"])  # doctest: +SKIP
    """
    names = label_names(entries)
    if group_by is None:
        first = [n for n in _FIRST_LABELS if n in names]
        keys = tuple(first + [n for n in names if n not in first and n != "seed"])
    else:
        keys = tuple(dict.fromkeys(group_by))
        unknown = [k for k in keys if k not in names]
        if unknown:
            have = ", ".join(names) if names else "none"
            raise ParameterError(f"no result has the label {unknown[0]!r} (labels: {have})")
    settings = {} if pool else run_settings(entries)
    run_cols = tuple(c for c in RUN_COLUMNS if c in settings and c not in keys)
    groups: dict[tuple[str | None, ...], list[ResultEntry]] = {}
    failures: list[ResultEntry] = []
    for e in entries:
        if run_cols and e.failed:
            failures.append(e)
            continue
        key = tuple(e.labels.get(k) for k in keys)
        key += tuple(settings[c].get(id(e)) for c in run_cols)
        groups.setdefault(key, []).append(e)
    for e in failures:  # with the results of its labels when they were computed one way
        label_key = tuple(e.labels.get(k) for k in keys)
        same = [k for k in groups if k[: len(keys)] == label_key]
        key = same[0] if len(same) == 1 else label_key + (None,) * len(run_cols)
        groups.setdefault(key, []).append(e)
    ordered = sorted(groups, key=lambda key: [sort_key(v) for v in key])
    return GroupTable(keys + run_cols, tuple(_group_row(k, groups[k]) for k in ordered))


def _text(value: Any, float_format: str) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return format(value, float_format)
    return str(value)


def table_csv(table: GroupTable) -> str:
    """The table as CSV (full precision, empty cells for missing values)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(table.columns)
    for rec in table.records():
        writer.writerow([_text(rec[c], ".10g") for c in table.columns])
    return buf.getvalue()


def table_markdown(table: GroupTable) -> str:
    """The table as a GitHub-flavoured Markdown table (3 decimals)."""

    def esc(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")

    cols = table.columns
    align = ["---" if c in table.group_by else "---:" for c in cols]
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join(align) + "|"]
    for rec in table.records():
        lines.append("| " + " | ".join(esc(_text(rec[c], ".3f")) for c in cols) + " |")
    return "\n".join(lines) + "\n"


def write_table(table: GroupTable, path: str | os.PathLike[str]) -> Path:
    """Write the table as CSV (``.csv``) or Markdown (``.md``), atomically.

    Raises
    ------
    ParameterError
        For another suffix.
    OSError
        If the file cannot be written.
    """
    p = Path(path)
    kind = table_format(p)
    text = table_csv(table) if kind == "csv" else table_markdown(table)
    atomic_write(p, text.encode("utf-8"))
    return p


def table_format(path: str | os.PathLike[str]) -> str:
    """``"csv"`` or ``"markdown"`` from a file's suffix; :class:`ParameterError` otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in _SUFFIXES:
        raise ParameterError(f"{path}: a table must be written to a .csv or .md file")
    return _SUFFIXES[suffix]


def rich_table(table: GroupTable, title: str | None = None) -> Any:
    """The table as a :class:`rich.table.Table` for the terminal."""
    from rich.table import Table

    out = Table(
        title=title,
        header_style="bold",
        caption="n: results with a degree; deg: degree of brokenness (s.d. over the n, min, "
        "max); largest: mean share of the largest partition; "
        "\N{GREEK CAPITAL LETTER PSI}: picture distance to the reference (cells)",
    )
    for c in table.columns:
        if c in table.group_by:
            out.add_column(c, justify="left", no_wrap=True, min_width=len(c))
        else:
            name = _SHORT.get(c, c)
            out.add_column(name, justify="right", no_wrap=True, min_width=len(name))
    for rec in table.records():
        cells = [_text(rec[c], ".3f") for c in table.columns]
        out.add_row(*[c if c else "-" for c in cells])
    return out
