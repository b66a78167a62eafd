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

import concurrent.futures as cf
import csv
import io
import json
import logging
import multiprocessing
import os
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

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
from rich.text import Text

from ..errors import BrokennessError, NothingFoundWarning, ParameterError
from ..report.results import ResultFileError, ResultRecord, atomic_write, load_results
from .manifest import Manifest, Pair, pairs_of

__all__ = [
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
        Resolution of the overlay pictures in the result files.
    """

    compute: dict[str, Any] = field(default_factory=dict, hash=False)
    dpi: int = 100


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
        show that the map is of the reference's place: no degree), ``"skipped"`` (result
        existed), ``"error"`` or ``"not run"`` (interrupted).
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

    @classmethod
    def from_record(cls, pair: Pair, record: ResultRecord, status: str) -> RowResult:
        """A row from a result file of ``pair``."""
        s = record.stats
        timings = record.info.get("timings") or {}
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
        """Number of rows with ``status``."""
        return sum(1 for r in self.rows if r.status == status)


# -- one pair ---------------------------------------------------------------------------------
def one_line(exc: BaseException) -> str:
    """A one-line message for an exception (type name added unless it is ours)."""
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
    from ..io import load_map
    from ..measure import compute_brokenness
    from ..report.results import save_results

    out = Path(out_dir)
    start = time.perf_counter()
    try:
        m = load_map(pair.map)
        ref = load_map(pair.reference)
        loaded = time.perf_counter()
        kwargs = {**options.compute, **pair.compute_options()}
        with warnings.catch_warnings():  # the row's status says it
            warnings.simplefilter("ignore", NothingFoundWarning)
            result = compute_brokenness(m, ref, **kwargs)
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
        record = save_results(out / pair.result_name, result, m, ref, info=info, dpi=options.dpi)
    except Exception as exc:  # a failing pair must not stop the batch
        message = one_line(exc)
        seconds = time.perf_counter() - start
        record_error(out, pair, message)
        return RowResult.failed(pair, message, seconds)
    _error_path(out, pair).unlink(missing_ok=True)
    return RowResult.from_record(pair, record, STATUS_DONE)


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


# -- progress ---------------------------------------------------------------------------------
class _RateColumn(ProgressColumn):
    """Pairs per second (or seconds per pair when slower than one a second)."""

    def render(self, task: Task) -> Text:
        speed = task.finished_speed or task.speed
        if not speed:
            return Text("-- pairs/s", style="progress.data.speed")
        if speed >= 1:
            return Text(f"{speed:.2f} pairs/s", style="progress.data.speed")
        return Text(f"{1.0 / speed:.1f} s/pair", style="progress.data.speed")


def _progress(console: Console | None, enabled: bool) -> Progress:
    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        _RateColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        TextColumn("{task.fields[last]}"),
        console=console or Console(stderr=True),
        disable=not enabled,
        transient=False,
    )


# -- executors --------------------------------------------------------------------------------
Submit = Callable[[Sequence[Pair], Callable[[RowResult], None]], None]


def _run_inline(pairs: Sequence[Pair], out: Path, options: PairOptions, done: Callable) -> None:
    for pair in pairs:
        done(evaluate_pair(pair, out, options))


def _run_pool(
    pairs: Sequence[Pair], out: Path, options: PairOptions, done: Callable, workers: int
) -> None:
    # forkserver: workers do not inherit the threads (progress refresh) of this process
    ctx = multiprocessing.get_context("forkserver")
    with cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        futures = {pool.submit(evaluate_pair, p, out, options): p for p in pairs}
        try:
            for fut in cf.as_completed(futures):
                pair = futures[fut]
                try:
                    row = fut.result()
                except Exception as exc:  # a worker died (out of memory, killed...)
                    row = RowResult.failed(pair, f"worker failed: {one_line(exc)}")
                    record_error(out, pair, row.error or "")
                done(row)
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ParameterError(
            "running on a Dask cluster needs the optional packages dask and distributed: "
            "pip install 'brokenness[dask]'"
        ) from None
    return distributed


def _run_dask(
    pairs: Sequence[Pair],
    out: Path,
    options: PairOptions,
    done: Callable,
    *,
    scheduler: str | None,
    local_cluster: bool,
    workers: int,
    connect_timeout: float = 10.0,
) -> None:
    distributed = _import_distributed()
    cluster = None
    try:
        if local_cluster:
            try:
                cluster = distributed.LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            except (OSError, RuntimeError, TimeoutError) as exc:
                raise ParameterError(
                    f"cannot start a local Dask cluster: {one_line(exc)}"
                ) from None
            client = distributed.Client(cluster, set_as_default=False)
        else:
            try:
                client = distributed.Client(
                    scheduler, timeout=connect_timeout, set_as_default=False
                )
            except (OSError, TimeoutError, ValueError) as exc:
                raise ParameterError(
                    f"cannot connect to the Dask scheduler at {scheduler}: {one_line(exc)}"
                ) from None
        with client:
            futures = {
                client.submit(
                    evaluate_pair, p, out, options, key=f"brokenness-pair-{p.id}", pure=False
                ): p
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
    finally:
        if cluster is not None:
            cluster.close()


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
    fixed = ["id", "status", "map", "reference"]
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

    statuses = (STATUS_DONE, STATUS_NOT_MEASURED, STATUS_SKIPPED, STATUS_ERROR)
    counts = {s: sum(1 for r in rows if r.status == s) for s in statuses}
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


def _write_summary(out: Path, rows: Sequence[RowResult]) -> tuple[Path, Path]:
    csv_path, md_path = out / "summary.csv", out / "summary.md"
    atomic_write(csv_path, summary_csv(rows).encode())
    atomic_write(md_path, summary_markdown(rows).encode())
    return csv_path, md_path


# -- the batch --------------------------------------------------------------------------------
def _previous(pair: Pair, out: Path) -> RowResult | None:
    path = out / pair.result_name
    if not path.is_file():
        return None
    try:
        record = load_results(path)
    except ResultFileError:
        return None  # damaged: evaluate again (the new file replaces it atomically)
    return RowResult.from_record(pair, record, STATUS_SKIPPED)


def run_batch(
    manifest: Manifest | str | os.PathLike[str] | Sequence[Pair],
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    local_cluster: bool = False,
    options: PairOptions | Mapping[str, Any] | None = None,
    progress: bool = True,
    console: Console | None = None,
    connect_timeout: float = 10.0,
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
    console : rich.console.Console, optional
        Where the progress bar goes.

    Notes
    -----
    The local pool starts its processes with ``forkserver``, which imports the caller's
    main module in each worker: a script that calls ``run_batch(..., workers=2)`` needs the
    usual ``if __name__ == "__main__":`` guard (without it every pair fails with a
    ``BrokenProcessPool`` error row). The ``brokenness batch`` command has it.
    connect_timeout : float
        Seconds to wait for the Dask scheduler at ``scheduler``.

    Returns
    -------
    BatchSummary

    Raises
    ------
    ManifestError
        If the manifest is bad.
    ParameterError
        For bad options, a missing Dask, or an unreachable scheduler.

    Notes
    -----
    The local pool starts its workers with the ``forkserver`` method, which imports the
    calling script again: a script that calls ``run_batch`` with ``workers > 1`` must do so
    under ``if __name__ == "__main__":`` (as every multiprocessing program must), otherwise
    every pair ends as a "worker failed" error row.

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
    if options is None:
        opts = PairOptions(dict(man.options))
    elif isinstance(options, PairOptions):
        opts = replace(options, compute={**man.options, **options.compute})
    else:
        opts = PairOptions({**man.options, **dict(options)})
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    rows: dict[str, RowResult] = {}
    todo: list[Pair] = []
    for pair in man.pairs:
        prev = _previous(pair, out)
        if prev is None:
            todo.append(pair)
        else:
            rows[pair.id] = prev

    def finish() -> BatchSummary:
        ordered = tuple(
            rows.get(p.id)
            or RowResult(p.id, p.row, STATUS_NOT_RUN, p.map_text, p.reference_text, p.labels)
            for p in man.pairs
        )
        csv_path, md_path = _write_summary(out, ordered)
        return BatchSummary(ordered, csv_path, md_path)

    with _progress(console, progress) as bar:
        task = bar.add_task("brokenness", total=len(todo), last="")
        if len(rows):
            bar.console.print(f"{len(rows)} pair(s) already done in {out}: skipped")

        def done(row: RowResult) -> None:
            rows[row.id] = row
            if row.error is not None:
                outcome = "[red]error[/red]"
            elif row.degree is None:
                outcome = "not measured"
            else:
                outcome = f"degree {row.degree}"
            last = f"{Path(row.map).name}: {outcome}"
            bar.update(task, advance=1, last=last)

        try:
            if not todo:
                pass
            elif scheduler or local_cluster:
                _run_dask(
                    todo,
                    out,
                    opts,
                    done,
                    scheduler=scheduler,
                    local_cluster=local_cluster,
                    workers=n_workers,
                    connect_timeout=connect_timeout,
                )
            elif n_workers == 1 or len(todo) == 1:
                _run_inline(todo, out, opts, done)
            else:
                _run_pool(todo, out, opts, done, min(n_workers, len(todo)))
        except KeyboardInterrupt:
            finish()  # what is done is on disk; record it before leaving
            raise
    return finish()
