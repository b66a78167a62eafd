"""``brokenness batch MANIFEST --out DIR``: evaluate every map/reference pair of a manifest.

One result zip per pair is written into ``DIR`` as soon as the pair is done, then
``summary.csv`` and ``summary.md`` for the whole manifest. Pairs whose result zip is already
in ``DIR`` are skipped, so re-running the same command after a crash or Ctrl-C resumes.

Exit codes: 0 when every pair has a result (evaluated now or before); 1 when the batch ran
to the end but some pairs failed (bad map file...): their error rows are in the summary and
in ``<pair>.error.json``, and re-running retries exactly those; 2 when nothing could be run
(bad manifest, bad option, output folder locked by another batch, unreachable Dask
scheduler); 130 on Ctrl-C or SIGTERM (the summary is written once the workers have stopped).
"""

from __future__ import annotations

import argparse
import signal
from typing import Any

from ..registration.methods import METHODS
from ._common import INPUTS_HELP, add_verbosity, console, plural

__all__ = ["EXIT_PAIRS_FAILED", "add_parser", "run"]

#: Exit code when the batch completed but at least one pair became an error row.
EXIT_PAIRS_FAILED = 1


def add_parser(subparsers: Any) -> None:
    """Register ``batch``."""
    p = subparsers.add_parser(
        "batch",
        help="evaluate many map/reference pairs listed in a manifest",
        description=(
            "Evaluate every map/reference pair of MANIFEST (CSV with columns map, reference "
            "and any labels such as system, dataset, noise; or YAML) in parallel. Writes one "
            "result zip per pair into --out as it finishes, and summary.csv / summary.md at the "
            "end. Pairs already done are not evaluated again (resume; their rows keep their "
            f"status, marked 'resumed'). {INPUTS_HELP}"
        ),
        epilog=(
            "exit status: 0 every pair has a result; 1 some pairs failed (see the summary); "
            "2 bad input or options (a bad manifest...; one line on stderr); 130 interrupted"
        ),
    )
    p.add_argument("manifest", help="CSV or YAML list of pairs (paths relative to it)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="parallel processes, or workers of --local-cluster (default: number of CPUs)",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--scheduler",
        metavar="ADDR",
        default=None,
        help="run on an existing Dask cluster (tcp://host:8786); maps and DIR must be on a "
        "file system the workers share",
    )
    where.add_argument(
        "--local-cluster",
        action="store_true",
        help="start a Dask LocalCluster on 127.0.0.1 with --workers processes",
    )
    p.add_argument(
        "--method",
        choices=METHODS,
        default=None,
        help="registration method (default ifmi; a 'method' column of the manifest wins)",
    )
    p.add_argument(
        "--threshold",
        type=float,
        default=None,
        help="masking threshold c in reference cells (default 2)",
    )
    p.add_argument(
        "--min-partition-fraction",
        type=float,
        default=None,
        help="smallest partition as a share of the occupied cells (default 0.02)",
    )
    p.add_argument(
        "--frames",
        type=int,
        default=None,
        metavar="K",
        help="grid frames of each map to measure in (1-5; default 1; see 'compute --frames')",
    )
    p.add_argument(
        "--overlays",
        choices=("fast", "figure", "none"),
        default=None,
        help="the overlay picture in each result zip: fast (default; drawn with numpy and "
        "Pillow, one pixel per cell up to 1600 pixels, a text legend: about 20 ms a pair), "
        "figure (the matplotlib figure of 'compute --overlay', a few hundred ms a pair) or "
        "none (no picture); overrides a YAML manifest's 'overlays'",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_verbosity(p)
    # the pairs are evaluated by the runner, which turns huge pages off where it computes
    # (in this process with --workers 1): this process need not load numpy
    p.set_defaults(func=run, small_pages=False)


def _compute_options(args: argparse.Namespace) -> dict[str, Any]:
    """Only the options given on the command line (the manifest's own apply otherwise)."""
    given = {
        "method": args.method,
        "threshold": args.threshold,
        "min_partition_fraction": args.min_partition_fraction,
        "frames": args.frames,
    }
    return {k: v for k, v in given.items() if v is not None}


def _terminated(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    """Run the batch and print where the results are."""
    from ..batch import read_manifest, run_batch
    from ..batch.runner import (
        STATUS_DONE,
        STATUS_ERROR,
        STATUS_NOT_MEASURED,
        STATUS_SKIPPED,
        SUMMARY_NAMES,
    )
    from ..limits import check_threshold
    from ._outputs import Output, check_outputs

    check_outputs([Output("--out", args.out, folder=True, writes=SUMMARY_NAMES)], (args.manifest,))
    if args.threshold is not None:
        check_threshold(args.threshold)
    manifest = read_manifest(args.manifest)  # ManifestError -> exit 2 before any work
    previous = signal.signal(signal.SIGTERM, _terminated)  # stop cleanly, as on Ctrl-C
    try:
        summary = run_batch(
            manifest,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            local_cluster=args.local_cluster,
            options=_compute_options(args),
            progress=not (args.no_progress or args.quiet),
            console=lambda: console(stderr=True),  # rich loads while the workers start
            overlays=args.overlays,
        )
    finally:
        signal.signal(signal.SIGTERM, previous)
    from rich.markup import escape

    done, skipped = summary.count(STATUS_DONE), summary.count(STATUS_SKIPPED)
    not_measured = summary.count(STATUS_NOT_MEASURED)
    failed = [r for r in summary.rows if r.status == STATUS_ERROR]
    if args.quiet:
        return EXIT_PAIRS_FAILED if failed else 0
    out = console()
    out.print(
        f"{plural(len(summary.rows), 'pair')}: {done} evaluated, {not_measured} not measured, "
        f"{skipped} already done, {len(failed)} failed"
    )
    if args.verbose:
        for row in summary.rows:
            what = (
                row.error
                if row.error
                else f"degree {row.degree}"
                if row.degree is not None
                else row.status
            )
            mark = " (resumed)" if row.resumed else ""
            out.print(f"  row {row.row} ({escape(row.map)}): {escape(str(what))}{mark}")
    for row in failed[:10]:
        where = f"row {row.row} ({escape(row.map)})"
        out.print(f"  [red]failed[/red] {where}: {escape(row.error or '')}")
    if len(failed) > 10:
        out.print(f"  ... and {len(failed) - 10} more (see the summary)")
    out.print(f"summary: {escape(str(summary.csv_path))}, {escape(str(summary.markdown_path))}")
    return EXIT_PAIRS_FAILED if failed else 0
