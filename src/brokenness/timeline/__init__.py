"""Brokenness over a SLAM run: every map message of a bag against one reference.

- :mod:`.frames`: the results (:class:`TimelineResult`, :class:`TimelineFrame`,
  :class:`TimelineEvent`, :class:`TimelinePartition`), frozen dataclasses;
- :mod:`.measure`: one frame (the not-measured rule for early maps, the map digest);
- :mod:`.events`: where the degree rises (a break) and falls (a repair);
- :mod:`.executors`: in this process, a process pool, or Dask, one map per worker;
- :mod:`.run`: :func:`timeline`, reading the bag lazily, reuse and resume;
- :mod:`.output`: CSV and JSON; :mod:`.plot`: degree and largest share against time.

``brokenness.timeline`` (the package attribute) is the function :func:`timeline`; import
the rest from here: ``from brokenness.timeline import TimelineResult``.
"""

from __future__ import annotations

from typing import Any

from .events import find_events
from .frames import (
    EVENT_BREAK,
    EVENT_REPAIR,
    TimelineEvent,
    TimelineFrame,
    TimelinePartition,
    TimelineResult,
)
from .output import timeline_csv, write_timeline_csv, write_timeline_json
from .run import timeline

__all__ = [
    "EVENT_BREAK",
    "EVENT_REPAIR",
    "TimelineEvent",
    "TimelineFrame",
    "TimelinePartition",
    "TimelineResult",
    "find_events",
    "plot_timeline",
    "timeline",
    "timeline_csv",
    "write_timeline_csv",
    "write_timeline_json",
]


def __getattr__(name: str) -> Any:
    if name == "plot_timeline":  # matplotlib only when a plot is asked for
        from .plot import plot_timeline

        return plot_timeline
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
