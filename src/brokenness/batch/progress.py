"""The progress bar of a batch (rich): pairs done, rate, elapsed time, ETA, the last pair.

A module of its own so that a batch's worker processes, which import
:mod:`brokenness.batch.runner`, never load rich.
"""

from __future__ import annotations

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    Task,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Column
from rich.text import Text

__all__ = ["batch_progress"]


class _RateColumn(ProgressColumn):
    """Pairs per second (or seconds per pair when slower than one a second)."""

    def render(self, task: Task) -> Text:
        # over the whole run: rich's windowed speed jumps when two workers finish together
        elapsed = task.finished_time if task.finished else task.elapsed
        speed = task.completed / elapsed if task.completed and elapsed else None
        if not speed:
            return Text("-- pairs/s", style="progress.data.speed")
        if speed >= 1:
            return Text(f"{speed:.2f} pairs/s", style="progress.data.speed")
        return Text(f"{1.0 / speed:.1f} s/pair", style="progress.data.speed")


def batch_progress(console: Console | None, enabled: bool) -> Progress:
    """The batch's progress bar on ``console`` (default: a console on stderr).

    Parameters
    ----------
    console : rich.console.Console or None
    enabled : bool
        Show the bar; when false, the bar is not drawn, but its console still says the
        batch's messages (pairs already done, warnings).

    Returns
    -------
    rich.progress.Progress
    """
    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        _RateColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        TextColumn(
            "{task.fields[last]}",
            table_column=Column(no_wrap=True, overflow="ellipsis", min_width=10),
        ),
        console=console or Console(stderr=True),
        disable=not enabled,
        transient=False,
    )
