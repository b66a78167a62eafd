"""A timeline as a table (CSV, one row per frame) and as JSON (everything)."""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

from .._atomic import atomic_write_bytes
from .frames import TimelineFrame, TimelineResult

__all__ = ["CSV_COLUMNS", "timeline_csv", "write_timeline_csv", "write_timeline_json"]

#: Columns of the CSV, in order.
CSV_COLUMNS: tuple[str, ...] = (
    "message_index",
    "stamp_ns",
    "time",
    "measured",
    "degree",
    "n_partitions",
    "largest_fraction",
    "occupied_cells",
    "unassigned_fraction",
    "partitions",
    "event",
    "same_as",
    "resumed",
    "seconds",
    "result_file",
    "reason",
)


def _num(value: float | None) -> str:
    return "" if value is None else f"{value:.6g}"


def _partitions(f: TimelineFrame) -> str:
    """``share rotation-offset displacement`` of each partition, ``;``-separated."""
    out = []
    for p in f.partitions:
        shift = (
            f"{p.displacement_m:.3f}m" if p.displacement_m is not None else f"{p.displacement:.2f}c"
        )
        out.append(f"{p.fraction:.4f} {p.rotation_offset_deg:+.2f}deg {shift}")
    return "; ".join(out)


def timeline_csv(result: TimelineResult) -> str:
    """The CSV text: one row per frame; ``event`` is ``break`` / ``repair`` where one is seen."""
    events = {e.message_index: e.kind for e in result.events}
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for f in result.frames:
        w.writerow(
            [
                f.message_index,
                f.stamp_ns,
                f"{f.time:.6f}",
                int(f.measured),
                "" if f.degree is None else f.degree,
                len(f.partitions),
                _num(f.largest_fraction),
                f.occupied_cells,
                _num(f.unassigned_fraction),
                _partitions(f),
                events.get(f.message_index, ""),
                "" if f.same_as is None else f.same_as,
                int(f.resumed),
                f"{f.seconds:.4f}",
                f.result_file or "",
                f.reason or "",
            ]
        )
    return buf.getvalue()


def write_timeline_csv(result: TimelineResult, path: str | os.PathLike[str]) -> Path:
    """Write :func:`timeline_csv` atomically."""
    p = Path(os.fspath(path))
    atomic_write_bytes(p, timeline_csv(result).encode())
    return p


def write_timeline_json(result: TimelineResult, path: str | os.PathLike[str]) -> Path:
    """Write :meth:`TimelineResult.to_dict` as JSON atomically."""
    p = Path(os.fspath(path))
    text = json.dumps(result.to_dict(), indent=2, allow_nan=False) + "\n"
    atomic_write_bytes(p, text.encode())
    return p
