"""``brokenness report RESULTS... --html out.html``: one self-contained page of results."""

from __future__ import annotations

import argparse
from typing import Any

from ._common import add_verbosity, console

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``report``."""
    p = subparsers.add_parser(
        "report",
        help="one self-contained HTML page for many result files",
        description=(
            "Write one HTML page for result zips (or folders of them, e.g. batch output "
            "folders): the summary table (sortable: click a header), the grouped table and "
            "figure of 'compare', and per result its overlay, partitions and parameters. "
            "Everything is inline: the page opens offline, as one file."
        ),
        epilog="exit status: 0 done; 2 bad input or options (one line on stderr)",
    )
    p.add_argument("results", nargs="+", metavar="RESULTS", help="result zips or folders")
    p.add_argument("--html", required=True, metavar="PATH", help="the page to write")
    p.add_argument("--title", default="brokenness results", help="title of the page")
    add_verbosity(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Collect the results and write the page."""
    from ..report.html import write_html
    from ._outputs import Output, check_outputs

    check_outputs([Output("--html", args.html)], inputs=args.results)
    path = write_html(args.results, args.html, title=args.title)
    if not args.quiet:
        console().print(f"report: {path}")
    return 0
