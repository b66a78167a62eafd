"""``brokenness.timeline``: the brokenness of every map message of a bag, and the events.

The bag is read lazily, one map at a time (:func:`brokenness.io.rosbag.iter_bag_maps`); the
reference is loaded once and sent to each worker once. What does not change between
messages is not computed again: a map identical to the previous message's (same digest of
states, shape, resolution and origin) reuses its frame (``same_as``), and with
``save_results`` a message whose result zip of an earlier run is there (same digest) is read
back instead of measured (resume, as ``brokenness batch`` does).
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from dataclasses import replace
from numbers import Integral
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ParameterError
from ..grid import OccupancyMap
from ..limits import MAX_WORKERS, max_cells
from .events import find_events
from .executors import make_executor
from .frames import TimelineFrame, TimelineResult
from .measure import DEFAULT_MIN_OCCUPIED, FrameJob, FrameOptions, frame_from_record, map_digest

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress

__all__ = ["timeline"]


def _progress(console: Console | None, enabled: bool) -> Progress:
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        TextColumn("{task.fields[last]}"),
        console=console or Console(stderr=True),
        disable=not enabled,
        transient=False,
    )


def _expected_total(bag: Path, topic: str, every: int, period: float | None) -> int | None:
    from ..io.rosbag import count_bag_maps

    n = count_bag_maps(bag, topic)
    if n is None or period is not None:
        return None
    return -(-n // every) + (1 if n > 1 and (n - 1) % every else 0)


def _resumed(save_dir: Path | None, job: FrameJob) -> TimelineFrame | None:
    if save_dir is None:
        return None
    path = save_dir / job.result_name
    if not path.is_file():
        return None
    from ..report.results import ResultFileError, load_results

    try:
        return frame_from_record(load_results(path), job)
    except ResultFileError:
        return None  # damaged: measure again (the new file replaces it atomically)


def timeline(
    bag: str | os.PathLike[str],
    reference: OccupancyMap | str | os.PathLike[str],
    *,
    topic: str = "/map",
    every: int = 1,
    period: float | None = None,
    save_results: str | os.PathLike[str] | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    local_cluster: bool = False,
    min_occupied_cells: int = DEFAULT_MIN_OCCUPIED,
    dpi: int = 100,
    options: Mapping[str, Any] | None = None,
    progress: bool | None = False,
    console: Console | None = None,
    connect_timeout: float = 10.0,
) -> TimelineResult:
    """The brokenness of every map message on ``topic`` of a bag, against one reference.

    Parameters
    ----------
    bag : path-like
        ROS 1 ``.bag``, rosbag2 folder, or rosbag2 ``.db3`` / ``.mcap`` file.
    reference : OccupancyMap or path-like
        The ground truth (any map :func:`brokenness.load_map` reads). Loaded once.
    topic : str
        The ``nav_msgs/OccupancyGrid`` topic.
    every : int
        Measure every ``every``-th message (the last one always).
    period : float, optional
        Instead, at most one message per ``period`` seconds of bag time (the last always).
    save_results : path-like, optional
        Folder (created) for one result zip per measured message, ``frame_NNNNNN.zip``
        (``NNNNNN`` = the message's index on the topic), as :func:`brokenness.report.
        save_results` writes them. Messages whose zip is there from an earlier run of the
        same bag are read back, not measured again (resume).
    workers : int
        Processes (local pool) or Dask workers (local cluster); 1 measures in this process.
    scheduler : str, optional
        A running Dask scheduler (``tcp://host:8786``): the bag is read here, maps are sent
        to the workers; ``save_results`` must be on a file system they share.
    local_cluster : bool
        Start a Dask ``LocalCluster`` with ``workers`` processes, close it afterwards.
    min_occupied_cells : int
        A map with fewer occupied cells is *not measured* ("too little mapped yet").
    dpi : int
        Resolution of the overlay picture in each result zip (drawing it is most of the
        cost of ``save_results``).
    options : mapping, optional
        Keyword options of :func:`brokenness.compute_brokenness` (method, threshold...).
    progress : bool or None
        Progress bar on stderr (rich); ``None``: when the console is a terminal.
    console : rich.console.Console, optional
        Where the progress bar goes.
    connect_timeout : float
        Seconds to wait for the Dask scheduler.

    Returns
    -------
    TimelineResult
        One frame per message kept (message order) and the events (breaks, repairs).

    Raises
    ------
    MapError, MapFormatError
        Bad bag (a FIFO, a device or a socket among its files is refused before anything is
        opened), no such topic, bad reference.
    ParameterError
        Bad options (``every``, ``period``: see :func:`brokenness.io.rosbag.thinning`),
        a bad ``$BROKENNESS_MAX_CELLS``, missing Dask, a scheduler address that is none
        or cannot be reached.

    Notes
    -----
    With ``workers > 1`` the local pool starts its processes with ``forkserver``: a script
    calling this needs the usual ``if __name__ == "__main__":`` guard.

    Examples
    --------
    >>> tl = timeline("run.bag", "ground_truth.yaml", every=5)  # doctest: +SKIP
    >>> [e.describe() for e in tl.events]  # doctest: +SKIP
    ['t=61.0 s (message 30): break, degree 0 -> 1; 18.2% of the map, +21.3 deg, 1.45 m off']
    """
    from ..io import load_map
    from ..io.rosbag import check_bag, iter_bag_maps, thinning

    started = time.perf_counter()
    if every != 1 and period is not None:
        raise ParameterError("give either every or period, not both")
    thinning(every, period)
    if scheduler and local_cluster:
        raise ParameterError("give either a scheduler address or local_cluster, not both")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be a positive integer, got {workers!r}")
    if workers > MAX_WORKERS:
        raise ParameterError(f"workers must be at most {MAX_WORKERS}, got {workers}")
    if not isinstance(min_occupied_cells, Integral) or isinstance(min_occupied_cells, bool):
        raise ParameterError(f"min_occupied_cells must be an integer, got {min_occupied_cells!r}")
    if min_occupied_cells < 0:
        raise ParameterError(f"min_occupied_cells must be >= 0, got {min_occupied_cells!r}")
    max_cells()  # $BROKENNESS_MAX_CELLS, read by every frame's checks: a bad value, once, now
    if scheduler or local_cluster:  # a bad address, a missing package: before the bag is read
        from ..batch.cluster import check_scheduler, import_distributed

        if scheduler:
            check_scheduler(scheduler)
        import_distributed()
    compute = dict(options or {})
    ref = reference if isinstance(reference, OccupancyMap) else load_map(reference)
    bag_path = check_bag(bag)  # before any worker starts: no FIFO or device
    save_dir = None if save_results is None else Path(os.fspath(save_results))
    if save_dir is not None:
        save_dir.mkdir(parents=True, exist_ok=True)
    ref_text = str(reference) if not isinstance(reference, OccupancyMap) else (ref.source or "")
    fopts = FrameOptions(
        compute=compute,
        min_occupied_cells=int(min_occupied_cells),
        save_dir=None if save_dir is None else str(save_dir),
        dpi=int(dpi),
        info={"timeline_bag": {"bag": str(bag), "topic": topic, "reference": ref_text}},
    )
    if progress is None:
        from rich.console import Console

        progress = (console or Console(stderr=True)).is_terminal
    total = _expected_total(bag_path, topic, every, period) if progress else None

    frames: dict[int, TimelineFrame] = {}
    order: list[FrameJob] = []
    same_as: dict[int, int] = {}
    with _progress(console, bool(progress)) as bar:
        task = bar.add_task("timeline", total=total, last="")

        def done(frame: TimelineFrame) -> None:
            frames[frame.message_index] = frame
            if frame.error is not None:
                outcome = "[red]error[/red]"
            elif frame.degree is None:
                outcome = "not measured"
            else:
                outcome = f"degree {frame.degree}"
            bar.update(task, advance=1, last=f"message {frame.message_index}: {outcome}")

        executor = make_executor(
            ref,
            fopts,
            done,
            workers=workers,
            scheduler=scheduler,
            local_cluster=local_cluster,
            connect_timeout=connect_timeout,
        )
        try:
            first_stamp: int | None = None
            last: tuple[str, int] | None = None  # digest and index of the previous message
            for item in iter_bag_maps(bag_path, topic, every=every, period=period):
                if first_stamp is None:
                    first_stamp = item.stamp_ns
                job = FrameJob(
                    message_index=item.index,
                    stamp_ns=item.stamp_ns,
                    time=(item.stamp_ns - first_stamp) / 1e9,
                    header_stamp=item.header_stamp,
                    digest=map_digest(item.map),
                )
                order.append(job)
                if last is not None and last[0] == job.digest:
                    same_as[job.message_index] = last[1]  # unchanged: reuse
                    bar.update(task, advance=1, last=f"message {item.index}: unchanged")
                    continue
                last = (job.digest, job.message_index)
                previous = _resumed(save_dir, job)
                if previous is not None:
                    done(previous)
                    continue
                executor.submit(item.map, job)
                del item
            executor.drain()
        finally:
            executor.close()

    ordered = []
    for job in order:
        if job.message_index in same_as:
            root = frames[same_as[job.message_index]]
            ordered.append(
                replace(
                    root,
                    message_index=job.message_index,
                    stamp_ns=job.stamp_ns,
                    time=job.time,
                    header_stamp=job.header_stamp,
                    seconds=0.0,
                    same_as=root.message_index,
                    result_file=None,
                    resumed=False,
                )
            )
        else:
            ordered.append(frames[job.message_index])
    parameters = {
        "every": every,
        "period": period,
        "min_occupied_cells": int(min_occupied_cells),
        "compute": compute,
        "workers": workers,
    }
    return TimelineResult(
        bag=str(bag),
        topic=topic,
        reference=ref_text,
        frames=tuple(ordered),
        events=find_events(ordered),
        parameters=parameters,
        seconds=time.perf_counter() - started,
    )
