"""``brokenness`` command line: one subcommand per part of the library.

Each subcommand lives in its own module of :mod:`brokenness.cli` and exposes
``add_parser(subparsers)``, which registers it and sets ``func`` to a ``run(args) -> int``.
Exit status: 0 success; 2 an error the user can fix (bad files, bad options), reported on one
line; 3 the degree was not measured (the evidence does not show that the map is of the
reference's place: :attr:`brokenness.BrokennessResult.measured`); 130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from collections.abc import Sequence
from typing import Any, NoReturn, TextIO

from .. import __version__
from ..errors import BrokennessError

__all__ = ["main"]

#: Subcommand modules, in the order ``--help`` lists them.
SUBCOMMANDS: tuple[str, ...] = ("compute", "register", "simulate", "batch", "compare")

EXIT_OK = 0
EXIT_BAD_INPUT = 2
#: ``compute``: the degree was not measured (the map may not be of the reference's place).
EXIT_NOT_MEASURED = 3


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, exit 2 (argparse's default code)
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    parser = _Parser(
        prog="brokenness",
        description="How structurally broken is an occupancy-grid map? (Birk, ICRA 2010)",
        epilog=(
            "exit status: 0 done; 2 bad input or options (one line on stderr); "
            "3 not measured (the map may not be of the reference's place); 130 interrupted"
        ),
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in SUBCOMMANDS:
        importlib.import_module(f"{__package__}.{name}").add_parser(sub)
    return parser


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: Any = None,
) -> None:
    """Warnings on the command line: one line each, without source code."""
    print(f"brokenness: warning: {message}", file=file or sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.func(args))
    except BrokennessError as exc:
        print(f"brokenness {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:  # unwritable output path, disk full...
        print(f"brokenness {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("brokenness: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
