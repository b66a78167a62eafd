"""``brokenness compare RESULTS...``: tables and plots over many result files.

RESULTS are result zips (``brokenness compute --save-results``, ``brokenness batch``) or
folders of them, such as a batch output folder, whose ``*.error.json`` files count as
failures. Results are grouped by their labels (the manifest's columns).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``compare``."""
    p = subparsers.add_parser(
        "compare",
        help="tables and plots over many result files",
        description=(
            "Group result zips (or folders of them, e.g. batch output folders) by their labels "
            "and report per group the number of results and failures, mean and median degree, "
            "mean largest-partition share and mean Psi. Optionally write the table (.csv or "
            ".md) and a figure (.png, .pdf, .svg): degree vs a numeric noise label per system, "
            "and the distribution of partition sizes."
        ),
    )
    p.add_argument("results", nargs="+", metavar="RESULTS", help="result zips or folders")
    p.add_argument(
        "--group-by",
        nargs="+",
        metavar="LABEL",
        default=None,
        help="labels to group by (default: every label except seed)",
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
    p.set_defaults(func=run)


#: Largest ``--dpi`` of a plot (a larger one would allocate a huge canvas).
MAX_DPI = 1200


def run(args: argparse.Namespace) -> int:
    """Collect the results, print the table, write what was asked for."""
    from rich.console import Console

    from ..errors import ParameterError
    from ..report.collect import collect_results
    from ..report.plots import write_plot
    from ..report.tables import group_table, rich_table, table_format, write_table

    if args.table:
        table_format(args.table)  # a bad suffix fails before any work
    if not 0 < args.dpi <= MAX_DPI:
        raise ParameterError(f"--dpi must be in 1..{MAX_DPI}, got {args.dpi}")
    from ._outputs import check_output_file, figure_suffixes

    if args.table:
        check_output_file(args.table, "--table", (".csv", ".md", ".markdown"))
    if args.plot:
        check_output_file(args.plot, "--plot", figure_suffixes())
    entries = collect_results(args.results)
    table = group_table(entries, args.group_by)
    failed = sum(e.failed for e in entries)
    shown = rich_table(table, title=f"{len(entries) - failed} result(s), {failed} failure(s)")
    console = Console(file=sys.stdout)
    if not console.is_terminal:  # piped or redirected: the whole table, never cut to 80
        wide = Console(file=sys.stdout, width=10_000).measure(shown).maximum
        console = Console(file=sys.stdout, width=max(80, wide))
    console.print(shown)
    if args.table:
        console.print(f"table: {write_table(table, args.table)}")
    if args.plot:
        path = write_plot(
            entries,
            args.plot,
            dpi=args.dpi,
            x_label=args.x_label,
            series_label=args.series_label,
        )
        console.print(f"plot: {path}")
    return 0
