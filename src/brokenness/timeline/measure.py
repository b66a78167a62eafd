"""One frame: the brokenness of one map message (runs in a worker), and its digest.

:func:`measure_frame` is a plain top-level function, so it runs the same in this process, in
a process pool and on a Dask worker. It never raises for a bad map: an error becomes a frame
that is not measured, with ``error`` set.

Early maps of a run show only a part of the reference. They are measured on what they show
(``compute_brokenness`` registers the part with the whole reference); a map with fewer than
``min_occupied_cells`` occupied cells is *not measured* ("too little mapped yet"), never a
degree 0 it could not support, and neither is a map of which no part agrees with the
reference.
"""

from __future__ import annotations

import hashlib
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import NothingFoundWarning
from ..grid import OccupancyMap
from ..measure.result import NOT_OCCUPIED, UNASSIGNED, BrokennessResult
from .frames import TimelineFrame

__all__ = ["DEFAULT_MIN_OCCUPIED", "FrameJob", "FrameOptions", "map_digest", "measure_frame"]

#: Fewer occupied cells than this: not measured yet (about 10 m of wall at 5 cm a cell).
DEFAULT_MIN_OCCUPIED = 200


def map_digest(m: OccupancyMap) -> str:
    """A hash of what the measurement depends on: states, shape, resolution, origin."""
    h = hashlib.blake2b(digest_size=16)
    h.update(repr((m.shape, m.resolution, m.origin)).encode())
    h.update(np.ascontiguousarray(m.states).tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class FrameOptions:
    """Options shared by every frame of a timeline.

    Attributes
    ----------
    compute : dict
        Keyword options of :func:`brokenness.compute_brokenness`.
    min_occupied_cells : int
        Below this, a map is not measured (too little mapped yet).
    save_dir : str or None
        Folder for one result zip per frame (``brokenness.report.save_results``).
    dpi : int
        Resolution of the overlays in the result zips.
    info : dict
        Extra ``info.json`` entries of every result zip (bag, topic...).
    """

    compute: dict[str, Any] = field(default_factory=dict, hash=False)
    min_occupied_cells: int = DEFAULT_MIN_OCCUPIED
    save_dir: str | None = None
    dpi: int = 100
    info: dict[str, Any] = field(default_factory=dict, hash=False)


@dataclass(frozen=True)
class FrameJob:
    """What a worker needs to know about a message besides its map."""

    message_index: int
    stamp_ns: int
    time: float
    header_stamp: float | None
    digest: str

    @property
    def result_name(self) -> str:
        """File name of its result zip."""
        return f"frame_{self.message_index:06d}.zip"


def _too_little(m: OccupancyMap, minimum: int, method: str, started: float) -> BrokennessResult:
    labels = np.full(m.shape, NOT_OCCUPIED, np.int16)
    labels[m.occupied] = UNASSIGNED
    n = m.n_occupied
    return BrokennessResult(
        degree=None,
        partitions=(),
        labels=labels,
        occupied_cells=n,
        unassigned_cells=n,
        method=method,
        parameters={"min_occupied_cells": minimum},
        seconds=time.perf_counter() - started,
        measured=False,
        reason=f"too little mapped yet: {n} occupied cells, fewer than {minimum}",
    )


def measure_frame(
    m: OccupancyMap, reference: OccupancyMap, job: FrameJob, options: FrameOptions
) -> TimelineFrame:
    """The frame of one map message (and its result zip when ``options.save_dir`` is set)."""
    from ..measure import compute_brokenness

    started = time.perf_counter()
    try:
        if m.n_occupied < options.min_occupied_cells:
            result = _too_little(
                m,
                options.min_occupied_cells,
                str(options.compute.get("method", "ifmi")),
                started,
            )
        else:
            with warnings.catch_warnings():  # the frame says it
                warnings.simplefilter("ignore", NothingFoundWarning)
                result = compute_brokenness(m, reference, **options.compute)
        name = None
        if options.save_dir is not None:
            from ..report.results import save_results

            info = {
                **options.info,
                "timeline": {
                    "message_index": job.message_index,
                    "stamp_ns": job.stamp_ns,
                    "time": job.time,
                    "header_stamp": job.header_stamp,
                    "digest": job.digest,
                },
                "parameters": {**options.compute, **result.parameters},
                "timings": {"total_seconds": time.perf_counter() - started},
            }
            save_results(
                Path(options.save_dir) / job.result_name,
                result,
                m,
                reference,
                info=info,
                dpi=options.dpi,
            )
            name = job.result_name
    except Exception as exc:  # one bad message must not stop the timeline
        from ..batch.runner import one_line

        return _failed(job, m, one_line(exc), time.perf_counter() - started)
    return TimelineFrame.from_result(
        result,
        message_index=job.message_index,
        stamp_ns=job.stamp_ns,
        time=job.time,
        header_stamp=job.header_stamp,
        digest=job.digest,
        seconds=time.perf_counter() - started,
        result_file=name,
    )


def _failed(job: FrameJob, m: OccupancyMap | None, message: str, seconds: float) -> TimelineFrame:
    n = 0 if m is None else m.n_occupied
    return TimelineFrame(
        message_index=job.message_index,
        stamp_ns=job.stamp_ns,
        time=job.time,
        header_stamp=job.header_stamp,
        measured=False,
        degree=None,
        reason=f"error: {message}",
        partitions=(),
        occupied_cells=n,
        unassigned_cells=n,
        seconds=seconds,
        digest=job.digest,
        error=message,
    )


def frame_from_record(record: Any, job: FrameJob) -> TimelineFrame | None:
    """A frame read back from a result zip of an earlier run (``None``: not this message)."""
    tl = (record.info or {}).get("timeline") or {}
    if tl.get("digest") != job.digest or tl.get("message_index") != job.message_index:
        return None
    from .frames import TimelinePartition

    s = record.stats
    occupied = int(s.get("occupied_cells") or 0)
    return TimelineFrame(
        message_index=job.message_index,
        stamp_ns=job.stamp_ns,
        time=job.time,
        header_stamp=job.header_stamp,
        measured=record.measured,
        degree=record.degree,
        reason=s.get("reason"),
        partitions=tuple(TimelinePartition.from_dict(d) for d in s.get("partitions") or []),
        occupied_cells=occupied,
        unassigned_cells=int(s.get("unassigned_cells") or 0),
        seconds=0.0,
        digest=job.digest,
        result_file=job.result_name,
        resumed=True,
    )
