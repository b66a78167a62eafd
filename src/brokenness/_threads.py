"""The threading policy of worker processes: one thread each, the processes are the parallelism.

By default OpenCV (the registration's DFTs, the morphology), OpenBLAS and OpenMP each start
a thread per core in every process: two workers on two cores would run four or more busy
threads, fighting over the cores and the caches. A batch's and a timeline's local workers
therefore run on one thread each:

* :func:`one_thread` (in a worker process): ``cv2.setNumThreads(1)``. OpenCV reads its
  setting whenever it runs, so this works after ``cv2`` is loaded.
* :func:`single_threaded_children` (in the parent, around the start of the worker
  processes or of the fork server they come from): ``OMP_NUM_THREADS``,
  ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``, ``VECLIB_MAXIMUM_THREADS`` and
  ``NUMEXPR_NUM_THREADS`` set to 1 in the environment the children inherit, since these
  libraries size their thread pools once, when numpy loads them. The parent's own
  environment is restored afterwards; a variable the user set is left as it is.

The command line's own process (``brokenness ...``, :func:`single_threaded_process` before
it loads numpy or OpenCV) runs on one thread too: ``brokenness compute``, a batch with
``--workers 1`` and a timeline computed in-process. The measure's operations are many and
small (point lookups, FFTs of pooled 256-384 cell images, grids of a map's box), and the
libraries' thread pools give them no speed: on two cores, OpenCV's and OpenBLAS's pools took
1.2-1.6x the CPU of one thread for about the same wall time on maps of 600² to 4000² cells
(one thread: 0.86-1.05x the wall time), and at 10000² the same CPU for about 8 % less wall
time (README, "Speed and memory"). A variable the user set is left as it is
(``OPENCV_FOR_THREADS_NUM=2 brokenness compute ...`` gives OpenCV two threads).
:func:`~brokenness.cli.main.main` called from Python leaves its host's threads as they are.

Either way the results are the same, bit for bit: no call on the measure's path gives other
bits on another number of threads (``tests/test_thread_determinism.py``).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from collections.abc import Iterator, Sequence
from typing import Any

__all__ = [
    "OPENCV_THREADS_VAR",
    "THREAD_ENV_VARS",
    "forkserver_context",
    "one_thread",
    "single_threaded_children",
    "single_threaded_process",
]

#: Environment variables that size the thread pools of numpy's BLAS, OpenMP and numexpr.
THREAD_ENV_VARS: tuple[str, ...] = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)


#: OpenCV's variable for the size of its thread pool, read when ``cv2`` loads.
OPENCV_THREADS_VAR = "OPENCV_FOR_THREADS_NUM"


def single_threaded_process() -> None:
    """This process: numpy's BLAS, OpenMP and OpenCV on one thread, when they load.

    Sets each of :data:`THREAD_ENV_VARS` and :data:`OPENCV_THREADS_VAR` that is not already
    set to ``"1"``, for good (the command line calls it first thing; the variables reach
    the processes it starts too). A library already loaded keeps its pool: call it before
    numpy and ``cv2`` are imported.
    """
    for name in (*THREAD_ENV_VARS, OPENCV_THREADS_VAR):
        os.environ.setdefault(name, "1")


def one_thread() -> None:
    """In a worker process: OpenCV on one thread."""
    try:
        import cv2

        cv2.setNumThreads(1)
    except (ImportError, AttributeError):  # pragma: no cover - cv2 is a dependency
        pass


@contextlib.contextmanager
def single_threaded_children() -> Iterator[None]:
    """Processes started inside the block load numpy's BLAS and OpenMP with one thread.

    Sets each of :data:`THREAD_ENV_VARS` that is not already set to ``"1"`` and removes it
    again when the block ends.
    """
    added = [name for name in THREAD_ENV_VARS if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


def forkserver_context(preload: Sequence[str] = ()) -> Any:
    """The ``forkserver`` multiprocessing context, its server started single-threaded.

    The fork server (one per parent process, started on first use and kept) imports
    ``preload`` once, so that every worker forked from it starts warm; it is started here,
    inside :func:`single_threaded_children`, so that its numpy, and every worker's, has one
    BLAS thread. A server already running is reused as it is.
    """
    from multiprocessing import forkserver

    ctx = multiprocessing.get_context("forkserver")
    if preload:
        ctx.set_forkserver_preload(list(preload))
    with single_threaded_children():
        forkserver.ensure_running()
    return ctx
