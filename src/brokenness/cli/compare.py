"""``brokenness compare RESULTS...``: tables and plots over many result files.

RESULTS are result zips (``brokenness compute --save-results``, ``brokenness batch``) or
folders of them, such as a batch output folder, whose ``*.error.json`` files count as
failures. Results are grouped by their labels (the manifest's columns, ``compute --label``)
and, unless ``--pool``, by the method and the parameters that differ between them.
"""

from __future__ import annotations

import argparse
from typing import Any

from ._common import add_verbosity, check_dpi, console, plural

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``compare``."""
    p = subparsers.add_parser(
        "compare",
        help="tables and plots over many result files",
        description=(
            "Group result zips (or folders of them, e.g. batch output folders) by their labels "
            "(manifest columns, compute --label) and report per group the number of results "
            "with a degree (n), those not measured and the failures, mean, median, s.d., min "
            "and max degree, mean largest-partition share and mean Psi. Results computed with "
            "different methods or parameters are kept apart (extra columns 'method' and "
            "'parameters') unless --pool. Optionally write the table (.csv or .md) and a "
            "figure (.png, .pdf, .svg): degree vs a numeric noise label per system (n per "
            "point; the line y = x when results carry an expected_degree label), and the "
            "distribution of partition sizes."
        ),
        epilog="exit status: 0 done; 2 bad input or options (one line on stderr)",
    )
    p.add_argument("results", nargs="+", metavar="RESULTS", help="result zips or folders")
    p.add_argument(
        "--group-by",
        nargs="+",
        metavar="LABEL",
        default=None,
        help="labels to group by (default: every label except seed)",
    )
    p.add_argument(
        "--pool",
        action="store_true",
        help="pool results computed with different methods or parameters into one group",
    )
    p.add_argument("--table", metavar="PATH", help="write the table to PATH (.csv or .md)")
    p.add_argument("--plot", metavar="PATH", help="write the figure to PATH (.png, .pdf, .svg)")
    p.add_argument(
        "--x",
        dest="x_label",
        metavar="LABEL",
        default=None,
        help="numeric label on the x axis of the degree plot (default: noise if present)",
    )
    p.add_argument(
        "--series",
        dest="series_label",
        metavar="LABEL",
        default=None,
        help="label that makes the series of the plots (default: system if present)",
    )
    p.add_argument("--dpi", type=int, default=200, help="resolution of a PNG plot (default 200)")
    add_verbosity(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Collect the results, print the table, write what was asked for."""
    from ..report.collect import collect_results
    from ..report.plots import write_plot
    from ..report.tables import group_table, rich_table, table_format, write_table
    from ._outputs import Output, check_outputs, figure_suffixes

    if args.table:
        table_format(args.table)  # a bad suffix fails before any work
    check_dpi(args.dpi)
    check_outputs(
        [
            Output("--table", args.table, (".csv", ".md", ".markdown")),
            Output("--plot", args.plot, figure_suffixes() if args.plot else None),
        ],
        inputs=args.results,
    )
    entries = collect_results(args.results)
    table = group_table(entries, args.group_by, pool=args.pool)
    failed = sum(e.failed for e in entries)
    title = f"{plural(len(entries) - failed, 'result')}, {plural(failed, 'failure')}"
    shown = rich_table(table, title=title)
    out = console()
    if not args.quiet:
        out.print(shown)
    if args.table:
        path = write_table(table, args.table)
        if not args.quiet:
            out.print(f"table: {path}")
    if args.plot:
        path = write_plot(
            entries,
            args.plot,
            dpi=args.dpi,
            x_label=args.x_label,
            series_label=args.series_label,
        )
        if not args.quiet:
            out.print(f"plot: {path}")
    return 0
