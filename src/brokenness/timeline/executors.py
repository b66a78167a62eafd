"""Where frames are measured: in this process, a local process pool, or a Dask cluster.

Each executor takes one map at a time (``submit``) and calls ``done(frame)`` as frames
finish. At most ``workers`` maps are in flight: ``submit`` waits for one to finish first,
so memory stays at one map per worker (plus the one being read from the bag). The reference
is sent to each worker once (pool initializer; Dask ``scatter(broadcast=True)``), not with
every map. The patterns are those of :mod:`brokenness.batch.runner` (forkserver pool, Dask
local cluster or scheduler address, one-line errors for a lost worker), and so is the
threading policy (:mod:`brokenness._threads`: one thread per worker process; the timeline's
reading and this process's OpenCV keep their defaults).
"""

from __future__ import annotations

import concurrent.futures as cf
from collections.abc import Callable
from typing import Any

from .._threads import forkserver_context, one_thread, single_threaded_children
from ..grid import OccupancyMap
from .frames import TimelineFrame
from .measure import FrameJob, FrameOptions, _failed, measure_frame

__all__ = ["DaskExecutor", "InlineExecutor", "PoolExecutor", "make_executor"]

Done = Callable[[TimelineFrame], None]

_REFERENCE: OccupancyMap | None = None  # a pool worker's reference, set once per process


def _init_worker(reference: OccupancyMap) -> None:
    global _REFERENCE
    one_thread()
    _REFERENCE = reference


def _cluster_task(
    m: OccupancyMap, reference: OccupancyMap, job: FrameJob, options: FrameOptions
) -> TimelineFrame:
    """A frame on a worker of the local cluster (one thread per worker process)."""
    one_thread()
    return measure_frame(m, reference, job, options)


def _pool_task(m: OccupancyMap, job: FrameJob, options: FrameOptions) -> TimelineFrame:
    assert _REFERENCE is not None, "worker not initialised"
    return measure_frame(m, _REFERENCE, job, options)


def _one_line(exc: BaseException) -> str:
    from ..batch.runner import one_line

    return one_line(exc)


class InlineExecutor:
    """Measure each frame right away, in this process."""

    def __init__(self, reference: OccupancyMap, options: FrameOptions, done: Done) -> None:
        self._ref, self._options, self._done = reference, options, done

    def submit(self, m: OccupancyMap, job: FrameJob) -> None:
        self._done(measure_frame(m, self._ref, job, self._options))

    def drain(self) -> None:
        pass

    def close(self) -> None:
        pass


class PoolExecutor:
    """A local process pool (``forkserver``: workers do not inherit the progress thread)."""

    def __init__(
        self, reference: OccupancyMap, options: FrameOptions, done: Done, workers: int
    ) -> None:
        ctx = forkserver_context()  # one BLAS/OpenMP thread in each worker
        self._pool = cf.ProcessPoolExecutor(
            max_workers=workers, mp_context=ctx, initializer=_init_worker, initargs=(reference,)
        )
        self._options, self._done, self._limit = options, done, workers
        self._pending: dict[cf.Future[TimelineFrame], FrameJob] = {}

    def _collect(self, return_when: str) -> None:
        finished, _ = cf.wait(list(self._pending), return_when=return_when)
        for fut in finished:
            job = self._pending.pop(fut)
            try:
                frame = fut.result()
            except Exception as exc:  # a worker died (out of memory, killed...)
                frame = _failed(job, None, f"worker failed: {_one_line(exc)}", 0.0)
            self._done(frame)

    def submit(self, m: OccupancyMap, job: FrameJob) -> None:
        while len(self._pending) >= self._limit:
            self._collect(cf.FIRST_COMPLETED)
        self._pending[self._pool.submit(_pool_task, m, job, self._options)] = job

    def drain(self) -> None:
        while self._pending:
            self._collect(cf.FIRST_COMPLETED)

    def close(self) -> None:
        # after drain: wait for the workers to exit; on an error or Ctrl-C: do not
        self._pool.shutdown(wait=not self._pending, cancel_futures=True)


class DaskExecutor:
    """A Dask cluster: a running scheduler, or a ``LocalCluster`` started here."""

    def __init__(
        self,
        reference: OccupancyMap,
        options: FrameOptions,
        done: Done,
        workers: int,
        *,
        scheduler: str | None,
        local_cluster: bool,
        connect_timeout: float = 10.0,
    ) -> None:
        from ..batch.cluster import dask_client, import_distributed

        self._dd = distributed = import_distributed()
        with single_threaded_children():  # a local cluster's worker processes
            self._client, self._cluster = dask_client(
                scheduler, local_cluster, workers, connect_timeout
            )
        n = len(self._client.scheduler_info().get("workers", {})) or workers
        self._limit = max(1, n)
        self._ref = self._client.scatter(reference, broadcast=True, hash=False)
        self._options, self._done = options, done
        self._pending: dict[Any, FrameJob] = {}
        self._finished = distributed.as_completed([], loop=self._client.loop)

    def _collect(self) -> None:
        fut = next(self._finished)  # blocks until one of the pending frames is done
        job = self._pending.pop(fut)
        try:
            frame = fut.result()
        except Exception as exc:  # worker lost, killed...
            frame = _failed(job, None, f"worker failed: {_one_line(exc)}", 0.0)
        fut.release()
        self._done(frame)

    def submit(self, m: OccupancyMap, job: FrameJob) -> None:
        while len(self._pending) >= self._limit:
            self._collect()
        data = self._client.scatter(m, hash=False)
        fut = self._client.submit(
            _cluster_task if self._cluster is not None else measure_frame,
            data,
            self._ref,
            job,
            self._options,
            key=f"brokenness-frame-{job.message_index}-{job.digest[:8]}",
            pure=False,
        )
        self._pending[fut] = job
        self._finished.add(fut)

    def drain(self) -> None:
        while self._pending:
            self._collect()

    def close(self) -> None:
        try:
            if self._pending:
                self._client.cancel(list(self._pending))
            self._client.close()
        finally:
            if self._cluster is not None:
                self._cluster.close()


def make_executor(
    reference: OccupancyMap,
    options: FrameOptions,
    done: Done,
    *,
    workers: int,
    scheduler: str | None,
    local_cluster: bool,
    connect_timeout: float = 10.0,
) -> InlineExecutor | PoolExecutor | DaskExecutor:
    """The executor asked for (Dask when a scheduler or a local cluster is given)."""
    if scheduler or local_cluster:
        return DaskExecutor(
            reference,
            options,
            done,
            workers,
            scheduler=scheduler,
            local_cluster=local_cluster,
            connect_timeout=connect_timeout,
        )
    if workers == 1:
        return InlineExecutor(reference, options, done)
    return PoolExecutor(reference, options, done, workers)
