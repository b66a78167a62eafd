"""Comparison plots for a paper: degree vs noise per system, found vs expected degree,
distribution of partition sizes.

Every point of a degree plot is the mean over its results, with the standard deviation as
error bar and the number of results (n) written next to it. When the results carry an
expected degree (the label :data:`EXPECTED_LABEL`, as simulated sets do), a panel plots the
degree found against it, with the line y = x of a perfect measure.

Only :class:`matplotlib.figure.Figure` with the Agg canvas is used, never ``pyplot``: the
functions work on a headless machine and leave no global state behind. Series use the
colour-blind safe Okabe-Ito colours of the overlay and differ by marker too, so that the
figure also reads in black and white.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..errors import ParameterError
from .collect import ResultEntry, label_names, sort_key
from .overlay import partition_colour

__all__ = [
    "EXPECTED_LABEL",
    "NOISE_LABELS",
    "comparison_figure",
    "numeric_label",
    "plot_degree_vs",
    "plot_partition_sizes",
    "write_plot",
]

#: Label names taken as the x axis of the degree plot when none is named (first match).
NOISE_LABELS: tuple[str, ...] = ("noise", "noise_level", "sigma", "level", "error")
#: Label of the expected (true) degree of a result (simulated maps).
EXPECTED_LABEL = "expected_degree"
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*")
_ALL = "all"


def _float(text: str | None) -> float | None:
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _is_numeric(entries: Sequence[ResultEntry], label: str) -> bool:
    values = [e.labels[label] for e in entries if label in e.labels]
    return bool(values) and all(_float(v) is not None for v in values)


def numeric_label(entries: Sequence[ResultEntry], label: str | None = None) -> str | None:
    """The label to put on the x axis of the degree plot.

    Parameters
    ----------
    entries : sequence of ResultEntry
    label : str, optional
        A label name to use; it must be numeric wherever it is set.

    Returns
    -------
    str or None
        ``label``, or else the first of :data:`NOISE_LABELS` (any case) that the results use
        with numbers only; ``None`` when there is none.

    Raises
    ------
    ParameterError
        If ``label`` is not used or not numeric.
    """
    ok = [e for e in entries if not e.failed]
    if label is not None:
        if not any(label in e.labels for e in ok):
            raise ParameterError(f"no result has the label {label!r}")
        if not _is_numeric(ok, label):
            raise ParameterError(f"the label {label!r} is not a number in every result")
        return label
    names = {n.lower(): n for n in label_names(ok)}
    for candidate in NOISE_LABELS:
        name = names.get(candidate)
        if name is not None and _is_numeric(ok, name):
            return name
    return None


def _series(entries: Sequence[ResultEntry], label: str | None) -> dict[str, list[ResultEntry]]:
    groups: dict[str, list[ResultEntry]] = {}
    for e in entries:
        key = e.labels.get(label, "(none)") if label else _ALL
        groups.setdefault(key, []).append(e)
    return {k: groups[k] for k in sorted(groups, key=sort_key)}


def _style(i: int) -> dict[str, object]:
    return {"color": partition_colour(i), "marker": _MARKERS[i % len(_MARKERS)]}


def plot_degree_vs(
    ax: Axes, entries: Sequence[ResultEntry], x_label: str, series_label: str | None = None
) -> None:
    """Mean degree (error bars: standard deviation) against a numeric label, per series.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    entries : sequence of ResultEntry
        Failures are left out.
    x_label : str
        Numeric label for the x axis (e.g. ``noise``).
    series_label : str, optional
        One line per value of this label (e.g. ``system``); one line for all otherwise.
    """
    ok = [e for e in entries if e.measured and _float(e.labels.get(x_label)) is not None]
    series = _series(ok, series_label)
    xs_all = sorted({_float(e.labels[x_label]) or 0.0 for e in ok})
    span = (xs_all[-1] - xs_all[0]) if len(xs_all) > 1 else 1.0
    # dodge the series a little so that error bars at the same x do not hide each other
    width = 0.012 * span * (len(series) - 1)
    for i, (name, members) in enumerate(series.items()):
        by_x: dict[float, list[float]] = {}
        for e in members:
            by_x.setdefault(_float(e.labels[x_label]) or 0.0, []).append(float(e.degree or 0))
        xs = np.array(sorted(by_x))
        means = np.array([np.mean(by_x[x]) for x in xs])
        stds = np.array([np.std(by_x[x]) for x in xs])
        offset = -width / 2 + (width * i / (len(series) - 1) if len(series) > 1 else 0.0)
        style = _style(i)
        ax.errorbar(
            xs + offset,
            means,
            yerr=stds,
            capsize=3,
            linewidth=1.5,
            markersize=6,
            label=name if series_label else None,
            **style,  # type: ignore[arg-type]
        )
        for x, mean, std in zip(xs, means, stds, strict=True):
            ax.annotate(
                f"n={len(by_x[float(x)])}",
                (x + offset, mean + std),
                xytext=(3, 3),
                textcoords="offset points",
                fontsize="x-small",
                color=str(style["color"]),
            )
    if x_label == EXPECTED_LABEL and xs_all:
        lo, hi = xs_all[0], xs_all[-1]
        if hi - lo < 1:  # a single expected degree: half a degree either side, a visible line
            lo, hi = lo - 0.5, hi + 0.5
        ax.plot([lo, hi], [lo, hi], linestyle="--", color="0.45", linewidth=1.0, label="y = x")
        ax.set_ylabel("degree found")
    ax.set_xlabel(x_label)
    if x_label != EXPECTED_LABEL:
        ax.set_ylabel("degree of brokenness")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylim(bottom=-0.25)
    ax.grid(True, alpha=0.3)
    if series_label or x_label == EXPECTED_LABEL:
        ax.legend(title=series_label, fontsize="small", title_fontsize="small")
    n = len(ok)
    ax.set_title(f"Degree vs {x_label} (mean \N{PLUS-MINUS SIGN} s.d., n = {n})", fontsize="medium")


def plot_partition_sizes(
    ax: Axes, entries: Sequence[ResultEntry], series_label: str | None = None, bins: int = 20
) -> None:
    """Histogram of partition sizes (share of the occupied cells), per series.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    entries : sequence of ResultEntry
        Failures are left out.
    series_label : str, optional
        One histogram outline per value of this label.
    bins : int
        Bins over [0, 1].
    """
    ok = [e for e in entries if not e.failed]
    edges = np.linspace(0.0, 1.0, bins + 1)
    series = _series(ok, series_label)
    for i, (name, members) in enumerate(series.items()):
        fractions = [f for e in members for f in e.partition_fractions]
        counts, _ = np.histogram(fractions, bins=edges)
        style = _style(i)
        ax.stairs(
            counts,
            edges,
            color=style["color"],
            linewidth=1.8,
            linestyle=("-", "--", ":", "-.")[i % 4],
            label=f"{name} ({len(fractions)})" if series_label else None,
        )
    ax.set_xlim(-0.01, 1.01)  # the outline of a full bin stays off the spines
    ax.set_xlabel("partition size (share of occupied cells)")
    ax.set_ylabel("partitions")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    if series_label:
        ax.legend(title=series_label, fontsize="small", title_fontsize="small")
    ax.set_title(f"Partition sizes ({len(ok)} maps)", fontsize="medium")


def comparison_figure(
    entries: Sequence[ResultEntry],
    *,
    x_label: str | None = None,
    series_label: str | None = None,
    width_inches: float = 10.0,
) -> Figure:
    """The comparison figure: degree vs a numeric label (if any) and partition sizes.

    Parameters
    ----------
    entries : sequence of ResultEntry
        From :func:`brokenness.report.collect_results`.
    x_label : str, optional
        Numeric label of the degree plot; by default the first of :data:`NOISE_LABELS`
        the results have. Results with a numeric :data:`EXPECTED_LABEL` add a panel of
        the degree found against the expected one (line y = x). Without either the figure
        has only the partition-size panel.
    series_label : str, optional
        Label that makes the series; default ``system`` when the results have it.
    width_inches : float

    Returns
    -------
    matplotlib.figure.Figure
        With an Agg canvas; save it with ``fig.savefig``.

    Raises
    ------
    ParameterError
        If there is no successful result, or a named label is unusable.
    """
    ok = [e for e in entries if not e.failed]
    if not ok:
        raise ParameterError("nothing to plot: there is no successful result")
    names = label_names(ok)
    if series_label is None:
        series_label = "system" if "system" in names else None
    elif series_label not in names:
        raise ParameterError(f"no result has the label {series_label!r}")
    x = numeric_label(ok, x_label)
    expected = EXPECTED_LABEL if x != EXPECTED_LABEL and _is_numeric(ok, EXPECTED_LABEL) else None
    degree_panels = [v for v in (x, expected) if v is not None]
    panels = len(degree_panels) + 1
    width = width_inches * (0.55 + 0.45 * (panels - 1))
    fig = Figure(figsize=(width, 0.42 * width_inches), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, panels, squeeze=False)[0]
    for ax, label in zip(axes, degree_panels, strict=False):
        plot_degree_vs(ax, ok, label, series_label)
    plot_partition_sizes(axes[-1], ok, series_label)
    return fig


def write_plot(
    entries: Sequence[ResultEntry],
    path: str | os.PathLike[str],
    *,
    dpi: int = 200,
    x_label: str | None = None,
    series_label: str | None = None,
) -> Path:
    """Draw :func:`comparison_figure` into a file (``.png``, ``.pdf``, ``.svg``...).

    Raises
    ------
    ParameterError
        For an unsupported suffix or nothing to plot.
    OSError
        If the file cannot be written.
    """
    from .results import atomic_write

    p = Path(path)
    kind = p.suffix.lower().lstrip(".")
    supported = FigureCanvasAgg.get_supported_filetypes()
    if kind not in supported:
        raise ParameterError(
            f"{p}: a plot must be written to one of .{', .'.join(sorted(supported))}"
        )
    fig = comparison_figure(entries, x_label=x_label, series_label=series_label)
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format=kind, dpi=dpi, metadata=_metadata(kind))
    atomic_write(p, buf.getvalue())
    return p


def _metadata(kind: str) -> dict[str, None] | None:
    # no creation date / software version in the file: same results -> same bytes
    if kind == "png":
        return {"Software": None}
    if kind == "pdf":
        return {"CreationDate": None, "Producer": None}
    if kind == "svg":
        return {"Date": None}
    return None
