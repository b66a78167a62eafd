"""Run a manifest: evaluate many map/reference pairs in parallel, resumably.

Each pair is evaluated by :func:`evaluate_pair`, a plain top-level function that loads both
maps, computes the brokenness, and writes the pair's result zip (atomically) into the output
folder. The same function runs in-process (``workers=1``), in a local process pool
(:class:`concurrent.futures.ProcessPoolExecutor`), or on a Dask cluster
(``scheduler="tcp://host:8786"`` or ``local_cluster=True``); the files are the same either
way. With Dask the workers write the files themselves, so the maps and the output folder
must be on a file system they share with the client (always true for a local cluster).

A pair that fails becomes an error row (its one-line message is also written to
``<pair>.error.json`` so that ``brokenness compare`` can count failures); the others go on.
A pair whose result zip exists is not evaluated again (resume); as every zip is written
atomically, nothing finished is lost when a run is killed. At the end a summary table of
every pair, done now or before, is written as ``summary.csv`` and ``summary.md``.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._atomic import atomic_write_bytes as atomic_write
from ..errors import BrokennessError, NothingFoundWarning, ParameterError
from ..limits import MAX_WORKERS, max_cells
from .manifest import OVERLAY_KINDS, Manifest, Pair, pairs_of

if TYPE_CHECKING:
    from rich.console import Console

    from ..report.results import ResultRecord

__all__ = [
    "BatchLockedError",
    "BatchSummary",
    "PairOptions",
    "RowResult",
    "evaluate_pair",
    "run_batch",
    "summary_markdown",
]

STATUS_DONE = "done"
STATUS_SKIPPED = "skipped"
STATUS_ERROR = "error"
STATUS_NOT_RUN = "not run"
#: The pair was evaluated, but its degree was not measured (``BrokennessResult.measured``).
STATUS_NOT_MEASURED = "not measured"


@dataclass(frozen=True)
class PairOptions:
    """Options shared by every pair of a batch.

    Attributes
    ----------
    compute : dict
        Keyword options for :func:`brokenness.compute_brokenness` (a pair's ``method`` and
        ``seed`` labels override them).
    dpi : int
        Resolution of the overlay pictures in the result files (``overlays="figure"``).
    overlays : {"fast", "figure", "none"}
        The overlay picture of each result zip: ``"fast"`` (default) the raster picture of
        :mod:`brokenness.report.fast_overlay` (numpy and Pillow, about 20 ms for a map of
        700 x 700 cells); ``"figure"`` the matplotlib figure of
        :func:`brokenness.report.render_overlay` (a few hundred ms); ``"none"`` no picture.
    """

    compute: dict[str, Any] = field(default_factory=dict, hash=False)
    dpi: int = 100
    overlays: str = "fast"


@dataclass(frozen=True)
class RowResult:
    """One row of the batch summary.

    Attributes
    ----------
    id : str
        The pair's stable id.
    row : int
        Position in the manifest (1-based).
    status : str
        ``"done"`` (evaluated now), ``"not measured"`` (evaluated, but the evidence does not
        show that the map is of the reference's place: no degree), ``"error"`` or ``"not
        run"`` (interrupted). A result found from an earlier run keeps its status (done or
        not measured) and has ``resumed`` set.
    map, reference : str
        Paths as written in the manifest.
    labels : dict
        The pair's labels.
    result : str or None
        File name of the result zip in the output folder.
    degree, n_partitions, largest_fraction, unassigned_fraction, psi_map, psi_repaired
        Figures from the result (``None`` for errors).
    seconds : float or None
        Time to load, compute and save.
    error : str or None
        One-line message of a failure.
    resumed : bool
        The result was there from an earlier run (not evaluated again).
    warnings : tuple of str
        Warnings raised while evaluating the pair (one line each).
    """

    id: str
    row: int
    status: str
    map: str
    reference: str
    labels: dict[str, str] = field(default_factory=dict, hash=False)
    result: str | None = None
    degree: int | None = None
    n_partitions: int | None = None
    largest_fraction: float | None = None
    unassigned_fraction: float | None = None
    psi_map: float | None = None
    psi_repaired: float | None = None
    seconds: float | None = None
    error: str | None = None
    resumed: bool = False
    warnings: tuple[str, ...] = ()

    @classmethod
    def from_record(cls, pair: Pair, record: ResultRecord, status: str) -> RowResult:
        """A row from a result file of ``pair`` (``status`` skipped: resumed, status kept)."""
        s = record.stats
        timings = record.info.get("timings") or {}
        resumed = status == STATUS_SKIPPED
        if resumed:
            status = STATUS_DONE
        if not record.measured and status == STATUS_DONE:
            status = STATUS_NOT_MEASURED
        return cls(
            id=pair.id,
            row=pair.row,
            status=status,
            map=pair.map_text,
            reference=pair.reference_text,
            labels=dict(pair.labels),
            result=pair.result_name,
            degree=record.degree,
            n_partitions=len(s.get("partitions") or []),
            largest_fraction=s.get("largest_fraction"),
            unassigned_fraction=s.get("unassigned_fraction"),
            psi_map=s.get("psi_map"),
            psi_repaired=s.get("psi_repaired"),
            seconds=timings.get("total_seconds"),
            resumed=resumed,
        )

    @classmethod
    def failed(cls, pair: Pair, message: str, seconds: float | None = None) -> RowResult:
        """An error row for ``pair``."""
        return cls(
            id=pair.id,
            row=pair.row,
            status=STATUS_ERROR,
            map=pair.map_text,
            reference=pair.reference_text,
            labels=dict(pair.labels),
            seconds=seconds,
            error=message,
        )


@dataclass(frozen=True)
class BatchSummary:
    """The outcome of :func:`run_batch`.

    Attributes
    ----------
    rows : tuple of RowResult
        One per pair, in manifest order.
    csv_path, markdown_path : Path
        The summary tables written into the output folder.
    """

    rows: tuple[RowResult, ...]
    csv_path: Path
    markdown_path: Path

    def count(self, status: str) -> int:
        """Number of rows with ``status``; ``"skipped"``: the rows resumed from an earlier
        run, which ``"done"`` and ``"not measured"`` then leave out."""
        if status == STATUS_SKIPPED:
            return sum(1 for r in self.rows if r.resumed)
        return sum(1 for r in self.rows if r.status == status and not r.resumed)


# -- one pair ---------------------------------------------------------------------------------
def one_line(exc: BaseException) -> str:
    """A one-line message for an exception (type name added unless it is ours)."""
    if isinstance(exc, MemoryError):
        limit = os.environ.get(WORKER_MEMORY_ENV)
        where = f" (over {WORKER_MEMORY_ENV}={limit})" if limit else ""
        return f"out of memory{where}: MemoryError"
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if isinstance(exc, BrokennessError) else f"{type(exc).__name__}: {text}"


def _error_path(out_dir: Path, pair: Pair) -> Path:
    return out_dir / f"{pair.stem}.error.json"


def evaluate_pair(pair: Pair, out_dir: str | os.PathLike[str], options: PairOptions) -> RowResult:
    """Evaluate one pair and write its result zip into ``out_dir``.

    Never raises for a bad pair: any error becomes an error row (and
    ``<pair>.error.json`` in ``out_dir``), so that a batch goes on.

    Parameters
    ----------
    pair : Pair
    out_dir : path-like
        Existing output folder.
    options : PairOptions

    Returns
    -------
    RowResult
    """
    out = Path(out_dir)
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught_warnings:
        warnings.simplefilter("default")  # each warning once per pair, said by the parent
        return _evaluate(pair, out, options, start, caught_warnings)


def _evaluate(
    pair: Pair,
    out: Path,
    options: PairOptions,
    start: float,
    caught_warnings: list[warnings.WarningMessage],
) -> RowResult:
    from ..io import load_map
    from ..limits import check_measurable, check_threshold
    from ..measure import compute_brokenness
    from ..report.results import save_results

    try:
        m = load_map(pair.map)
        ref = m if _same_file(pair.map, pair.reference) else load_map(pair.reference)
        loaded = time.perf_counter()
        _check_pair(m, ref)
        kwargs = {**options.compute, **pair.compute_options()}
        check_measurable(m.n_occupied, pair.map_text)
        check_threshold(kwargs.get("threshold", 2.0), ref.shape)
        with warnings.catch_warnings():  # the row's status says it
            warnings.simplefilter("ignore", NothingFoundWarning)
            result = compute_brokenness(m, ref, **kwargs)
        if not result.measured or (result.degree or 0) >= MIRROR_CHECK_DEGREE:
            _check_mirrored(m, ref, kwargs)
        info = {
            "labels": dict(pair.labels),
            "pair": {
                "id": pair.id,
                "map": pair.map_text,
                "reference": pair.reference_text,
                "manifest_row": pair.row,
            },
            "parameters": kwargs | dict(result.parameters),
            "timings": {
                "load_seconds": loaded - start,
                "total_seconds": time.perf_counter() - start,
            },
        }
        record = save_results(
            out / pair.result_name,
            result,
            m,
            ref,
            info=info,
            dpi=options.dpi,
            overlay=options.overlays,
        )
    except Exception as exc:  # a failing pair must not stop the batch
        message = one_line(exc)
        seconds = time.perf_counter() - start
        record_error(out, pair, message)
        return RowResult.failed(pair, message, seconds)
    _error_path(out, pair).unlink(missing_ok=True)
    caught = tuple(dict.fromkeys(" ".join(str(w.message).split()) for w in caught_warnings))
    return replace(RowResult.from_record(pair, record, STATUS_DONE), warnings=caught)


#: From this degree on (or when not measured), a pair is checked for a mirrored map.
MIRROR_CHECK_DEGREE = 3


def _check_pair(m: Any, ref: Any) -> None:
    """Warn when only one of the two maps knows its resolution."""
    from ..io import MapWarning
    from ..io.pairing import geometry_warning

    message = geometry_warning(m, ref)
    if message:
        warnings.warn(message, MapWarning, stacklevel=2)


def _check_mirrored(m: Any, ref: Any, kwargs: Mapping[str, Any]) -> None:
    """Warn when the map fits the reference far better mirrored (rows in the wrong order)."""
    from ..io import MapWarning
    from ..measure.mirror import mirror_check

    try:
        check = mirror_check(m, ref, threshold=float(kwargs.get("threshold", 2.0)))
    except BrokennessError:
        return
    if check.far_better_mirrored:
        warnings.warn(check.message(), MapWarning, stacklevel=2)


def _same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def record_error(out_dir: Path, pair: Pair, message: str) -> None:
    """Write ``<pair>.error.json`` (best effort: the row carries the message anyway)."""
    doc = {
        "format": "brokenness-error",
        "labels": dict(pair.labels),
        "pair": {"id": pair.id, "map": pair.map_text, "reference": pair.reference_text},
        "error": message,
    }
    try:
        atomic_write(_error_path(out_dir, pair), (json.dumps(doc, indent=2) + "\n").encode())
    except OSError:
        pass


# -- executors --------------------------------------------------------------------------------
Submit = Callable[[Sequence[Pair], Callable[[RowResult], None]], None]


def _run_inline(pairs: Sequence[Pair], out: Path, options: PairOptions, done: Callable) -> None:
    from .._memory import small_pages

    with small_pages():  # this process computes: no huge pages (brokenness._memory)
        for pair in pairs:
            done(evaluate_pair(pair, out, options))


# -- local worker processes -------------------------------------------------------------------
#: Environment variable limiting the address space of each local worker process (bytes, or
#: with a K/M/G suffix): a pair that needs more fails with a MemoryError row instead of
#: waking the OOM killer.
WORKER_MEMORY_ENV = "BROKENNESS_WORKER_MEMORY"
#: Seconds between two checks of a worker that its batch process is still alive.
PARENT_CHECK_SECONDS = 0.5
#: Modules the fork server imports once, so that every worker starts warm (and the overlay
#: module of the batch's kind, :func:`_preload`): every module :func:`evaluate_pair` uses
#: (the packages of :mod:`brokenness` load their modules on first use), and the image
#: plugins Pillow loads on its first read or write of a file.
_PRELOAD = (
    "brokenness.batch.runner",
    "brokenness.io.load",
    "brokenness.io.pairing",
    "brokenness.measure.recursion",
    "brokenness.measure.mirror",
    "brokenness.registration.api",
    "brokenness.registration.ifmi",
    "brokenness.report.results",
    "PIL.BmpImagePlugin",
    "PIL.GifImagePlugin",
    "PIL.JpegImagePlugin",
    "PIL.PngImagePlugin",
    "PIL.PpmImagePlugin",
)


def _preload(options: PairOptions) -> tuple[str, ...]:
    if options.overlays == "figure":
        return (*_PRELOAD, "brokenness.report.overlay")  # matplotlib, once
    if options.overlays == "fast":
        return (*_PRELOAD, "brokenness.report.fast_overlay")
    return _PRELOAD


_PR_SET_PDEATHSIG = 1


def parse_memory(text: str) -> int:
    """Bytes from ``"4G"``, ``"512M"``, ``"1500000000"``... (binary units).

    Raises
    ------
    ParameterError
        If ``text`` is not a positive size.

    Examples
    --------
    >>> parse_memory("2G")
    2147483648
    """
    units = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
    t = text.strip().upper().removesuffix("B").removesuffix("I")
    unit = t[-1:] if t[-1:] in units else ""
    try:
        value = float(t[: len(t) - len(unit)]) * units[unit]
    except ValueError:
        value = -1.0
    if not (1 <= value < 2**63):
        raise ParameterError(f"{WORKER_MEMORY_ENV} must be a size such as 4G, got {text!r}")
    return int(value)


def _check_environment(n_workers: int, dask: bool) -> None:
    """The environment settings a batch depends on, checked once before any work.

    ``$BROKENNESS_MAX_CELLS`` (read by every pair's checks: a bad value would fail every
    pair) and ``$BROKENNESS_WORKER_MEMORY`` are refused with one line when bad, whatever the
    number of workers. The memory limit bounds the processes of a local pool only
    (``n_workers`` > 1): where the pairs run in this process, or on a Dask cluster, a
    warning says that it is not applied.

    Raises
    ------
    ParameterError
    """
    max_cells()
    limit = os.environ.get(WORKER_MEMORY_ENV)
    if not limit:
        return
    parse_memory(limit)
    if dask:
        where = "a Dask cluster's workers have their own (dask worker --memory-limit)"
    elif n_workers == 1:
        where = "with one worker the pairs are evaluated in this process"
    else:
        return
    warnings.warn(
        f"{WORKER_MEMORY_ENV}={limit} is not applied: it limits the worker processes of "
        f"workers > 1 only; {where}",
        UserWarning,
        stacklevel=3,
    )


def _alive(pid: int) -> bool:
    """True while process ``pid`` exists and is not a zombie."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            state = fh.read().rsplit(b")", 1)[-1].split()[0]
    except (OSError, IndexError):
        return True
    return state not in (b"Z", b"X")


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(PARENT_CHECK_SECONDS)
        if not _alive(parent_pid):
            os._exit(1)  # the batch is gone: stop computing for nobody


def _worker_setup(parent_pid: int) -> None:
    """In a worker: ignore Ctrl-C (the batch process handles it), die with the batch process
    (a parent-death signal from the fork server, and a thread watching the batch process),
    run OpenCV on one thread (:mod:`brokenness._threads`: the workers are the parallelism),
    and apply ``$BROKENNESS_WORKER_MEMORY``."""
    import signal
    import threading

    from .._threads import one_thread

    one_thread()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the watching thread still does it
        pass
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    limit = os.environ.get(WORKER_MEMORY_ENV)
    if limit:
        import resource

        size = parse_memory(limit)
        resource.setrlimit(resource.RLIMIT_AS, (size, size))


_PR_SET_NAME = 15


def _name_process(name: str) -> None:
    """Set the process name ``ps`` and ``/proc/PID/comm`` show (Linux; 15 bytes)."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_NAME, ctypes.c_char_p(name.encode()[:15]), 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _worker_main(conn: Any, out: Path, options: PairOptions, parent_pid: int) -> None:
    """Body of a worker process: evaluate the pairs it is sent, one at a time.

    Receives a :class:`Pair` (or ``None``, or end of file: stop), sends back
    ``(row, go_on)``. A worker evaluates many pairs, so that each pair does not pay for a
    new process (a fork, and the page faults of a fresh heap: about a third of a small
    pair's time); after an exception that escaped :func:`evaluate_pair` (``go_on`` false)
    it exits, and the next pair gets a new process. While it evaluates a pair the process
    is named ``bk-<pair id>`` (``ps``, ``/proc/PID/comm``), so that one can see which pair
    each worker evaluates, and ``bk-idle`` between pairs.
    """
    setup_error: BaseException | None = None
    try:
        _worker_setup(parent_pid)
    except BaseException as exc:  # noqa: BLE001 - said in the row of the pair it is sent
        setup_error = exc
    try:
        while True:
            _name_process("bk-idle")
            try:
                pair = conn.recv()
            except (EOFError, OSError):
                return
            if pair is None:
                return
            _name_process(f"bk-{pair.id}")
            go_on = True
            try:
                if setup_error is not None:
                    raise setup_error
                row = evaluate_pair(pair, out, options)
            except BaseException as exc:  # noqa: BLE001 - anything becomes this pair's row
                row = RowResult.failed(pair, f"worker failed: {one_line(exc)}")
                record_error(out, pair, row.error or "")
                go_on = False
            conn.send((row, go_on))
            if not go_on:
                return
    finally:
        conn.close()


def _start_worker(ctx: Any, out: Path, options: PairOptions, parent: int) -> tuple[Any, Any]:
    """A new worker process and this side of its pipe."""
    mine, theirs = ctx.Pipe(duplex=True)
    proc = ctx.Process(
        target=_worker_main,
        args=(theirs, out, options, parent),
        name="brokenness-batch-worker",
        daemon=True,
    )
    proc.start()
    theirs.close()
    return mine, proc


def death_message(exitcode: int | None) -> str:
    """Why a worker ended without a result, from its exit code.

    Examples
    --------
    >>> death_message(-9)
    'worker killed by SIGKILL while evaluating this pair: out of memory?'
    """
    import signal

    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        hint = ": out of memory?" if -exitcode == signal.SIGKILL else ""
        return f"worker killed by {name} while evaluating this pair{hint}"
    return f"worker exited with status {exitcode} without a result"


def _run_pool(
    pairs: Sequence[Pair], out: Path, options: PairOptions, done: Callable, workers: int
) -> None:
    """Evaluate the pairs in worker processes, at most ``workers`` at a time.

    The workers come from a fork server (``forkserver``: they do not inherit the threads,
    such as the progress bar's, of this process) and each evaluates one pair after another
    (:func:`_worker_main`). A worker that dies (the OOM killer's SIGKILL, a crash) costs
    only the pair it was evaluating, whose error row says how it died; the next pairs go on
    in the other workers and in a new one. On any exception (Ctrl-C) the pairs not started
    are dropped, the workers are stopped and waited for, and only then does the exception
    go on: nothing is left running behind the caller.
    """
    from multiprocessing.connection import wait

    from .._threads import forkserver_context

    ctx = forkserver_context(_preload(options))  # one BLAS/OpenMP thread per worker
    pending = list(reversed(pairs))
    busy: dict[Any, tuple[Any, Pair, float]] = {}  # pipe -> (process, its pair, started)
    idle: list[tuple[Any, Any]] = []  # (pipe, process) of workers waiting for a pair
    parent = os.getpid()
    try:
        while pending or busy:
            while pending and len(busy) < workers:
                conn, proc = idle.pop() if idle else _start_worker(ctx, out, options, parent)
                if not proc.is_alive():  # died while idle: not the next pair's fault
                    conn.close()
                    proc.join()
                    continue
                pair = pending.pop()
                try:
                    conn.send(pair)
                except OSError:
                    conn.close()
                    proc.join()
                    pending.append(pair)
                    continue
                busy[conn] = (proc, pair, time.perf_counter())
            for ready in wait(list(busy)):
                pipe: Any = ready
                proc, pair, started = busy.pop(pipe)
                answer: Any
                try:
                    answer = pipe.recv()
                except Exception:  # noqa: BLE001 - EOF: the worker died before answering
                    answer = None
                row, go_on = answer if isinstance(answer, tuple) else (None, False)
                if go_on and isinstance(row, RowResult):
                    idle.append((pipe, proc))
                else:
                    pipe.close()
                    proc.join()
                if not isinstance(row, RowResult):
                    message = death_message(proc.exitcode)
                    row = RowResult.failed(pair, message, time.perf_counter() - started)
                    record_error(out, pair, message)
                done(row)
    finally:
        _stop(busy, idle)


def _stop(busy: Mapping[Any, tuple[Any, Pair, float]], idle: Sequence[tuple[Any, Any]]) -> None:
    """Stop the workers (idle ones: end of their pipe; busy ones: SIGTERM) and wait until
    every one has exited."""
    procs = []
    for conn, proc in idle:
        conn.close()  # the worker's recv ends: it exits
        procs.append(proc)
    for conn, (proc, _pair, _t) in busy.items():
        if proc.is_alive():
            proc.terminate()
        conn.close()
        procs.append(proc)
    for proc in procs:
        proc.join(5.0)
        if proc.is_alive():
            proc.kill()
            proc.join()


def _cluster_pair(pair: Pair, out_dir: Path, options: PairOptions) -> RowResult:
    """A pair on a worker of the local cluster (OpenCV on one thread, as a pool worker)."""
    from .._threads import one_thread

    one_thread()
    return evaluate_pair(pair, out_dir, options)


@contextlib.contextmanager
def _dask_session(
    scheduler: str | None, local_cluster: bool, workers: int, connect_timeout: float
) -> Iterator[tuple[Any, bool]]:
    """``(client, local)``: a client of the scheduler or of a local cluster started here,
    closed (with its cluster) when the block ends. Entered before the progress bar shows,
    so that a scheduler that cannot be reached is one line of error, nothing else."""
    from .._threads import single_threaded_children
    from .cluster import dask_client

    with single_threaded_children():  # a local cluster's worker processes
        client, cluster = dask_client(scheduler, local_cluster, workers, connect_timeout)
    try:
        with client:
            yield client, cluster is not None
    finally:
        if cluster is not None:
            cluster.close()


def _run_dask(
    pairs: Sequence[Pair], out: Path, options: PairOptions, done: Callable, session: Any
) -> None:
    """The pairs on the Dask cluster of ``session`` (:func:`_dask_session`)."""
    from .cluster import import_distributed

    distributed = import_distributed()
    client, local = session
    task = _cluster_pair if local else evaluate_pair
    futures = {
        client.submit(task, p, out, options, key=f"brokenness-pair-{p.id}", pure=False): p
        for p in pairs
    }
    try:
        for fut in distributed.as_completed(list(futures), loop=client.loop):
            pair = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # worker lost, killed...
                row = RowResult.failed(pair, f"worker failed: {one_line(exc)}")
                record_error(out, pair, row.error or "")
            done(row)
    except BaseException:
        client.cancel(list(futures))
        raise


# -- summary ----------------------------------------------------------------------------------
_FIGURES = (
    "degree",
    "n_partitions",
    "largest_fraction",
    "unassigned_fraction",
    "psi_map",
    "psi_repaired",
    "seconds",
)


def _columns(rows: Iterable[RowResult]) -> tuple[list[str], list[str]]:
    labels: dict[str, None] = {}
    for r in rows:
        labels.update(dict.fromkeys(r.labels))
    fixed = ["id", "status", "resumed", "map", "reference"]
    return fixed + list(labels) + list(_FIGURES) + ["result", "error"], list(labels)


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def _table(rows: Sequence[RowResult]) -> tuple[list[str], list[list[str]]]:
    columns, label_names = _columns(rows)
    body = []
    for r in rows:
        values: dict[str, Any] = {
            "id": r.id,
            "status": r.status,
            "resumed": "yes" if r.resumed else "",
            "map": r.map,
            "reference": r.reference,
            "result": r.result,
            "error": r.error,
        }
        values.update({k: r.labels.get(k) for k in label_names})
        values.update({k: getattr(r, k) for k in _FIGURES})
        body.append([_cell(values[c]) for c in columns])
    return columns, body


def summary_csv(rows: Sequence[RowResult]) -> str:
    """The summary as CSV text."""
    columns, body = _table(rows)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows(body)
    return buf.getvalue()


def summary_markdown(rows: Sequence[RowResult]) -> str:
    """The summary as a Markdown table, with a count line above it."""
    columns, body = _table(rows)

    def esc(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")

    statuses = (STATUS_DONE, STATUS_NOT_MEASURED, STATUS_ERROR)
    counts = {s: sum(1 for r in rows if r.status == s and not r.resumed) for s in statuses}
    counts[STATUS_SKIPPED] = sum(1 for r in rows if r.resumed)
    lines = [
        f"{len(rows)} pairs: {counts[STATUS_DONE]} done, {counts[STATUS_NOT_MEASURED]} not "
        f"measured, {counts[STATUS_SKIPPED]} skipped (done before), "
        f"{counts[STATUS_ERROR]} failed",
        "",
        "| " + " | ".join(columns) + " |",
        "|" + "|".join("---" for _ in columns) + "|",
    ]
    lines += ["| " + " | ".join(esc(v) for v in row) + " |" for row in body]
    return "\n".join(lines) + "\n"


#: The summary files a batch writes into its output folder.
SUMMARY_NAMES: tuple[str, str] = ("summary.csv", "summary.md")


def _write_summary(out: Path, rows: Sequence[RowResult]) -> tuple[Path, Path]:
    csv_path, md_path = (out / name for name in SUMMARY_NAMES)
    atomic_write(csv_path, summary_csv(rows).encode())
    atomic_write(md_path, summary_markdown(rows).encode())
    return csv_path, md_path


# -- the batch --------------------------------------------------------------------------------
def _previous(pair: Pair, out: Path, status: str = STATUS_SKIPPED) -> RowResult | None:
    """The row of ``pair``'s result zip in ``out``, or ``None`` if there is none or it is
    damaged (then the pair is evaluated again)."""
    path = out / pair.result_name
    if not path.is_file():
        return None
    from ..report.results import ResultFileError, load_results

    try:
        record = load_results(path)
        return RowResult.from_record(pair, record, status)
    except (ResultFileError, KeyError, TypeError, ValueError, OverflowError):
        return None  # damaged: evaluate again (the new file replaces it atomically)


#: File in the output folder that a running batch holds locked.
LOCK_NAME = ".brokenness-batch.lock"


class BatchLockedError(BrokennessError, RuntimeError):
    """Another batch is writing into the same output folder."""


@contextlib.contextmanager
def lock_folder(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out`` (``fcntl.flock`` of :data:`LOCK_NAME`).

    The lock is released when the block ends, and by the kernel when the process dies, so a
    killed batch never leaves a stale lock.

    Raises
    ------
    BatchLockedError
        If another process holds the lock.
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield
        return
    path = out / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
    except OSError as exc:
        reason = exc.strerror or exc
        raise ParameterError(f"{out}: cannot write into the output folder ({reason})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
            raise BatchLockedError(
                f"{out}: another batch (pid {holder}) is writing into this folder; wait for "
                "it to finish or use another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the lock


def check_options(options: Mapping[str, Any]) -> None:
    """Options of :func:`brokenness.compute_brokenness` for a batch, checked before any work.

    Raises
    ------
    ParameterError
        For an option ``compute_brokenness`` does not have, or one out of its range (a
        threshold, a ``min_partition_fraction`` outside [0, 1)...: every check of
        :class:`~brokenness.measure.BrokennessOptions`).
    """
    from dataclasses import fields

    from ..limits import check_threshold
    from ..measure import BrokennessOptions

    known = {f.name for f in fields(BrokennessOptions)}
    unknown = sorted(str(k) for k in options if k not in known)
    if unknown:
        raise ParameterError(
            f"unknown option(s) {', '.join(unknown)} (compute_brokenness takes "
            f"{', '.join(sorted(known))})"
        )
    if "threshold" in options:
        check_threshold(options["threshold"])
    given = dict(options)
    if given.get("registration_options", ()) is None:  # as compute_brokenness takes it
        given["registration_options"] = ()
    BrokennessOptions(**given)  # every option in its range, before any pair is started


def _check_overlays(kind: str) -> None:
    if kind not in OVERLAY_KINDS:
        raise ParameterError(f"overlays must be one of {', '.join(OVERLAY_KINDS)}, got {kind!r}")


def run_batch(
    manifest: Manifest | str | os.PathLike[str] | Sequence[Pair],
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    local_cluster: bool = False,
    options: PairOptions | Mapping[str, Any] | None = None,
    progress: bool = True,
    console: Console | Callable[[], Console] | None = None,
    connect_timeout: float = 10.0,
    overlays: str | None = None,
) -> BatchSummary:
    """Evaluate every pair of a manifest and write one result zip per pair plus a summary.

    Parameters
    ----------
    manifest : Manifest, path-like or sequence of Pair
        See :func:`brokenness.batch.read_manifest`.
    out_dir : path-like
        Output folder (created if needed). Pairs whose result zip is already there are
        skipped (resume).
    workers : int, optional
        Parallel processes (local pool) or Dask workers (local cluster). Default: the number
        of CPUs. 1 evaluates in this process.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``).
    local_cluster : bool
        Start a Dask ``LocalCluster`` on 127.0.0.1 with ``workers`` processes, and close it
        afterwards.
    options : PairOptions or mapping, optional
        Options of every pair; a mapping is taken as ``compute_brokenness`` keyword options.
        The manifest's own ``options`` come first, these override them.
    progress : bool
        Show a progress bar (rich) with rate and ETA on stderr.
    console : rich.console.Console or callable, optional
        Where the progress bar goes; or a function that makes it, called once the workers
        are starting (so that rich loads while they start: the command line's).

    connect_timeout : float
        Seconds to wait for the Dask scheduler at ``scheduler``.
    overlays : {"fast", "figure", "none"}, optional
        The overlay picture of every result zip (see :class:`PairOptions`). Default: that
        of ``options`` when it is a :class:`PairOptions`, else the manifest's
        (``overlays:`` of a YAML manifest), else ``"fast"``.

    Returns
    -------
    BatchSummary

    Raises
    ------
    ManifestError
        If the manifest is bad.
    ParameterError
        For bad options (unknown, or out of range), a bad ``$BROKENNESS_MAX_CELLS`` or
        ``$BROKENNESS_WORKER_MEMORY``, a missing Dask, or a scheduler address that is none
        or cannot be reached.
    BatchLockedError
        If another batch is writing into ``out_dir``.

    Notes
    -----
    With ``workers > 1`` the pairs are evaluated in ``workers`` worker processes, started
    by a ``forkserver``, each evaluating one pair after another (with OpenCV, BLAS and
    OpenMP on one thread: :mod:`brokenness._threads`). A worker that dies (SIGKILL from the OOM
    killer, a crash) costs only its pair: its error row says how it died ("worker killed by
    SIGKILL while evaluating this pair: out of memory?") and the other pairs go on. Workers
    ignore Ctrl-C and exit when the batch process dies; on Ctrl-C the pairs not started are
    dropped, the running workers are stopped, and the summary is written only once they have
    exited (a pair whose zip was written counts as done). ``$BROKENNESS_WORKER_MEMORY``
    (e.g. ``4G``) bounds each worker's address space. ``workers=1`` evaluates the pairs in
    this process, without that isolation (and without that bound: a warning says so, as on
    a Dask cluster). ``$BROKENNESS_MAX_CELLS`` and ``$BROKENNESS_WORKER_MEMORY`` are checked
    before any work: a bad value is a :class:`ParameterError`, not a failure of every pair.

    The output folder is locked (``.brokenness-batch.lock``) for the whole run: a second
    batch on the same folder is refused with :class:`BatchLockedError`. A damaged result zip
    found there (resume) is evaluated again.

    Examples
    --------
    >>> summary = run_batch("runs.csv", "results", workers=2)  # doctest: +SKIP
    >>> summary.count("error")  # doctest: +SKIP
    0
    """
    man = pairs_of(manifest)
    if scheduler and local_cluster:
        raise ParameterError("give either a scheduler address or local_cluster, not both")
    n_workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if n_workers < 1:
        raise ParameterError(f"workers must be at least 1, got {workers}")
    if n_workers > MAX_WORKERS:
        raise ParameterError(f"workers must be at most {MAX_WORKERS}, got {workers}")
    kind = overlays or (None if isinstance(options, PairOptions) else man.overlays)
    if options is None:
        opts = PairOptions(dict(man.options))
    elif isinstance(options, PairOptions):
        opts = replace(options, compute={**man.options, **options.compute})
    else:
        opts = PairOptions({**man.options, **dict(options)})
    if kind is not None:
        opts = replace(opts, overlays=kind)
    check_options(opts.compute)
    _check_overlays(opts.overlays)
    _check_environment(n_workers, bool(scheduler or local_cluster))
    if scheduler or local_cluster:  # a bad address, a missing package: one line, before any output
        from .cluster import check_scheduler, import_distributed

        if scheduler:
            check_scheduler(scheduler)
        import_distributed()
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ParameterError(f"{out}: cannot create the output folder ({exc.strerror})") from None
    with lock_folder(out):
        return _run_locked(
            man, out, opts, n_workers, scheduler, local_cluster, progress, console, connect_timeout
        )


def _run_locked(
    man: Manifest,
    out: Path,
    opts: PairOptions,
    n_workers: int,
    scheduler: str | None,
    local_cluster: bool,
    progress: bool,
    console: Console | Callable[[], Console] | None,
    connect_timeout: float,
) -> BatchSummary:
    rows: dict[str, RowResult] = {}
    todo: list[Pair] = []
    pool = n_workers > 1 and not (scheduler or local_cluster)
    if pool and sum(not (out / p.result_name).is_file() for p in man.pairs) > 1:
        from .._threads import forkserver_context

        # the fork server imports the pipeline while this process reads the earlier results
        forkserver_context(_preload(opts))
    for pair in man.pairs:
        prev = _previous(pair, out)
        if prev is None:
            todo.append(pair)
        else:
            rows[pair.id] = prev

    def finish() -> BatchSummary:
        # a pair without a row may still have finished (its worker wrote the zip, then was
        # stopped by Ctrl-C before it could answer): the files on disk decide
        ordered = tuple(
            rows.get(p.id)
            or _previous(p, out, STATUS_DONE)
            or RowResult(p.id, p.row, STATUS_NOT_RUN, p.map_text, p.reference_text, p.labels)
            for p in man.pairs
        )
        csv_path, md_path = _write_summary(out, ordered)
        return BatchSummary(ordered, csv_path, md_path)

    from .progress import batch_progress

    with contextlib.ExitStack() as stack:
        session = None
        if todo and (scheduler or local_cluster):  # connected before the bar shows
            session = stack.enter_context(
                _dask_session(scheduler, local_cluster, n_workers, connect_timeout)
            )
        if callable(console):
            console = console()
        bar = stack.enter_context(batch_progress(console, progress))
        task = bar.add_task("brokenness", total=len(todo), last="")
        if len(rows):
            n = len(rows)
            bar.console.print(
                f"{n} {'pair' if n == 1 else 'pairs'} already done in {out}: not evaluated again"
            )

        def done(row: RowResult) -> None:
            rows[row.id] = row
            if row.error is not None:
                outcome = "[red]error[/red]"
            elif row.degree is None:
                outcome = "not measured"
            else:
                outcome = f"degree {row.degree}"
            last = f"{Path(row.map).name}: {outcome}"
            for w in row.warnings:
                bar.console.print(
                    f"warning: {Path(row.map).name}: {w}", markup=False, highlight=False
                )
            bar.update(task, advance=1, last=last)

        try:
            if not todo:
                pass
            elif session is not None:
                _run_dask(todo, out, opts, done, session)
            elif n_workers == 1:
                _run_inline(todo, out, opts, done)
            else:
                _run_pool(todo, out, opts, done, min(n_workers, len(todo)))
        except KeyboardInterrupt:
            stack.close()  # the Dask cluster's workers stopped first, as a pool's are
            finish()  # what is done is on disk; record it before leaving
            raise
    return finish()
