"""Degree and the largest partition's share against time, events marked (matplotlib, Agg).

Only :class:`matplotlib.figure.Figure` with the Agg canvas is used, never ``pyplot`` (as in
:mod:`brokenness.report.plots`). Frames not measured are drawn as grey ticks on the time
axis, not as a degree; breaks are red dashed lines, repairs green dotted ones.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from .._atomic import atomic_write_bytes
from ..errors import ParameterError
from .frames import EVENT_BREAK, TimelineResult

__all__ = ["plot_timeline", "timeline_figure"]

_BREAK, _REPAIR, _LINE, _SHARE, _GREY = "#D55E00", "#009E73", "#0072B2", "#E69F00", "#999999"


def timeline_figure(result: TimelineResult, *, title: str | None = None) -> Figure:
    """The figure: degree (top) and largest partition's share (bottom) against time."""
    fig = Figure(figsize=(7.0, 4.2))
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    measured = [f for f in result.frames if f.measured and f.degree is not None]
    missing = [f for f in result.frames if not f.measured]
    if measured:
        t = [f.time for f in measured]
        top.step(t, [f.degree for f in measured], where="post", color=_LINE, lw=1.5)
        top.plot(t, [f.degree for f in measured], "o", color=_LINE, ms=3, label="degree")
        bottom.plot(
            t,
            [f.largest_fraction for f in measured],
            "-o",
            color=_SHARE,
            ms=3,
            lw=1.2,
            label="largest partition",
        )
    if missing:
        top.plot(
            [f.time for f in missing],
            [0] * len(missing),
            "|",
            color=_GREY,
            ms=10,
            label="not measured",
        )
    for e in result.events:
        colour, style = (_BREAK, "--") if e.kind == EVENT_BREAK else (_REPAIR, ":")
        for ax in (top, bottom):
            ax.axvline(e.time, color=colour, ls=style, lw=1.2)
        top.annotate(
            e.kind,
            (e.time, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(3, -12),
            textcoords="offset points",
            color=colour,
            fontsize=8,
        )
    top.set_ylabel("degree")
    top.yaxis.set_major_locator(MaxNLocator(integer=True))
    top.set_ylim(bottom=-0.3, top=max([1] + [f.degree or 0 for f in measured]) + 0.5)
    top.legend(loc="upper left", fontsize=8, frameon=False)
    bottom.set_ylabel("largest share")
    bottom.set_ylim(0, 1.05)
    bottom.set_xlabel("time since the first map message (s)")
    top.set_title(
        title or f"brokenness over the run: {Path(result.bag).name} {result.topic}", fontsize=10
    )
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def plot_timeline(
    result: TimelineResult,
    path: str | os.PathLike[str],
    *,
    dpi: int = 100,
    title: str | None = None,
) -> Path:
    """Draw :func:`timeline_figure` into a file (``.png``, ``.pdf``, ``.svg``...), atomically.

    Raises
    ------
    ParameterError
        For an unsupported suffix.
    """
    p = Path(os.fspath(path))
    kind = p.suffix.lower().lstrip(".")
    supported = FigureCanvasAgg.get_supported_filetypes()
    if kind not in supported:
        raise ParameterError(
            f"{p}: a plot must be written to one of .{', .'.join(sorted(supported))}"
        )
    fig = timeline_figure(result, title=title)
    buf = io.BytesIO()
    meta = {
        "png": {"Software": None},
        "pdf": {"CreationDate": None, "Producer": None},
        "svg": {"Date": None},
    }.get(kind)
    fig.savefig(buf, format=kind, dpi=dpi, metadata=meta)
    atomic_write_bytes(p, buf.getvalue())
    return p
