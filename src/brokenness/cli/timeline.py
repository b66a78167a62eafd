"""``brokenness timeline BAG REFERENCE``: when did the map break, and was it repaired?

Measures every map message on ``--topic`` of a ROS 1 or ROS 2 bag against REFERENCE
(optionally thinned with ``--every`` or ``--period``), prints the events (where the degree
rose: a new partition, how large, rotated and shifted by how much against the largest; where
it fell: a repair) and writes the timeline as CSV, JSON and a plot when asked. With
``--save-results DIR`` one result zip per message is written as it is done, and a re-run
skips the messages already there (resume).

Exit codes: 0 done; 2 bad input, options or output paths (one line, before any work); 3 no
message could be measured; 130 interrupted (the result zips written so far stay).
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from ..registration.methods import METHODS
from ._common import add_verbosity
from .main import EXIT_NOT_MEASURED, EXIT_OK

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``timeline``."""
    p = subparsers.add_parser(
        "timeline",
        help="brokenness of every map message of a bag: when it broke, when it was repaired",
        description=(
            "Measure the brokenness of every nav_msgs/OccupancyGrid message on --topic of BAG "
            "(ROS 1 .bag, ROS 2 folder, .db3 or .mcap) against REFERENCE, and report where "
            "the degree rises (a new partition) and falls (a repair). Early maps are measured "
            "on what they show, or reported not measured when too little is there yet."
        ),
        epilog="exit status: 0 done; 2 bad input or options; 3 no message could be measured",
    )
    p.add_argument("bag", help="the bag with the map messages")
    p.add_argument("reference", help="the reference map (ground truth)")
    p.add_argument("--topic", default="/map", help="map topic (default /map)")
    thin = p.add_mutually_exclusive_group()
    thin.add_argument("--every", type=int, default=1, metavar="N", help="every N-th message")
    thin.add_argument(
        "--period", type=float, default=None, metavar="SECONDS", help="one message per period"
    )
    p.add_argument("--csv", metavar="PATH", help="one row per message")
    p.add_argument("--json", metavar="PATH", help="the whole timeline as JSON ('-': stdout)")
    p.add_argument("--plot", metavar="PNG", help="degree and largest share against time")
    p.add_argument(
        "--save-results",
        metavar="DIR",
        help="one result zip per message (resumable: messages already there are skipped)",
    )
    p.add_argument(
        "--workers", type=int, default=1, metavar="N", help="parallel processes (default 1)"
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDR", default=None, help="a Dask scheduler")
    where.add_argument(
        "--local-cluster", action="store_true", help="a Dask LocalCluster of --workers"
    )
    p.add_argument("--method", choices=METHODS, default="ifmi", help="registration")
    p.add_argument("--threshold", type=float, default=2.0, help="masking threshold c (cells)")
    p.add_argument(
        "--min-occupied-cells",
        type=int,
        default=None,
        metavar="N",
        help="fewer occupied cells: not measured yet (default 200)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_verbosity(p)
    p.set_defaults(func=run)


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def run(args: argparse.Namespace) -> int:
    """Compute the timeline, print its events, write what was asked for."""
    from ..io import load_map
    from ..limits import check_threshold
    from ..timeline import timeline, write_timeline_csv, write_timeline_json
    from ..timeline.measure import DEFAULT_MIN_OCCUPIED
    from ._common import console as make_console
    from ._outputs import Output, check_outputs, figure_suffixes

    # every output checked before any work, as compute does
    check_outputs(
        [
            Output("--csv", args.csv, (".csv",)),
            Output("--json", args.json),
            Output("--plot", args.plot, figure_suffixes() if args.plot else None),
            Output("--save-results", args.save_results, folder=True),
        ],
        inputs=(args.bag, args.reference),
    )
    check_threshold(args.threshold)
    ref = load_map(args.reference)
    check_threshold(args.threshold, ref.shape)
    console = make_console(stderr=True)
    result = timeline(
        args.bag,
        ref,
        topic=args.topic,
        every=args.every,
        period=args.period,
        save_results=args.save_results,
        workers=args.workers,
        scheduler=args.scheduler,
        local_cluster=args.local_cluster,
        min_occupied_cells=(
            DEFAULT_MIN_OCCUPIED if args.min_occupied_cells is None else args.min_occupied_cells
        ),
        options={"method": args.method, "threshold": args.threshold},
        progress=False if (args.no_progress or args.quiet) else None,
        console=console,
    )
    if args.csv:
        write_timeline_csv(result, args.csv)
    if args.plot:
        from ..timeline.plot import plot_timeline

        plot_timeline(result, args.plot)
    if args.json == "-":
        json.dump(result.to_dict(), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    elif args.json:
        write_timeline_json(result, args.json)
    if args.json != "-" and not args.quiet:
        n = len(result.frames)
        print(
            f"{n} message(s): {result.count('measured')} measured, "
            f"{result.count('not measured')} not measured, {result.count('reused')} unchanged "
            f"(reused), {result.count('resumed')} resumed, {result.count('error')} failed; "
            f"{result.seconds:.1f} s"
        )
        last = result.frames[-1] if result.frames else None
        if last is not None:
            degree = "not measured" if last.degree is None else str(last.degree)
            print(
                f"final map (message {last.message_index}, t={last.time:.1f} s): degree "
                f"{degree}, largest partition {_fmt(last.largest_fraction, '.1%')}"
            )
        if result.events:
            print("events:")
            for e in result.events:
                print(f"  {e.describe()}")
        else:
            print("events: none (the degree never changed)")
    for f in result.frames:  # errors are said even with --quiet
        if f.error is not None:
            print(f"  failed: message {f.message_index}: {f.error}", file=sys.stderr)
    return EXIT_OK if result.count("measured") else EXIT_NOT_MEASURED
