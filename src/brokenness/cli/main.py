"""``brokenness`` command line: one subcommand per part of the library.

Each subcommand lives in its own module of :mod:`brokenness.cli` and exposes
``add_parser(subparsers)``, which registers it and sets ``func`` to a ``run(args) -> int``.
Exit status: 0 success; 2 an error the user can fix (bad files, bad options), reported on one
line; 3 the degree was not measured (the evidence does not show that the map is of the
reference's place: :attr:`brokenness.BrokennessResult.measured`); 130 interrupted; 141
when the reader of a pipe went away (``brokenness compare ... | head``), quietly.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import warnings
from collections.abc import Sequence
from typing import Any, NoReturn, TextIO

from .. import __version__
from .._memory import small_pages
from .._threads import single_threaded_process
from ..errors import BrokennessError

__all__ = ["console", "main"]

#: Subcommand modules, in the order ``--help`` lists them.
SUBCOMMANDS: tuple[str, ...] = (
    "compute",
    "register",
    "simulate",
    "batch",
    "compare",
    "report",
    "timeline",
)

EXIT_OK = 0
EXIT_BAD_INPUT = 2
#: ``compute``: the degree was not measured (the map may not be of the reference's place).
EXIT_NOT_MEASURED = 3
#: The output pipe was closed by its reader (128 + SIGPIPE, as a shell tool killed by it).
EXIT_BROKEN_PIPE = 141


#: Longest error message the command line prints (the rest is cut to an ellipsis): a value
#: echoed from a hostile file or option cannot make the line long.
MAX_ERROR_CHARS = 400


def _error_line(prog: str, message: object) -> str:
    """``"PROG: error: MESSAGE\\n"``, the message on one line of at most
    :data:`MAX_ERROR_CHARS` characters.

    Every character that is not printable (a newline, a carriage return, a tab, an escape
    sequence's ESC, a Unicode line separator) is shown escaped, as in a Python string
    (``\\n``), so that a path holding one still reads as that path and the message stays
    on its line; a longer message is cut, the cut marked with ``...``.

    Examples
    --------
    >>> _error_line("brokenness compute", "no such file: 'a\\nb.yaml'")
    "brokenness compute: error: no such file: 'a\\\\nb.yaml'\\n"
    """
    text = "".join(
        c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in str(message)
    )
    if len(text) > MAX_ERROR_CHARS:
        text = text[: MAX_ERROR_CHARS - 3] + "..."
    return f"{prog}: error: {text}\n"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, exit 2 (argparse's default code)
        self.exit(EXIT_BAD_INPUT, _error_line(self.prog, message))


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    parser = _Parser(
        prog="brokenness",
        description="How structurally broken is an occupancy-grid map? (Birk, ICRA 2010)",
        epilog=(
            "exit status: 0 done; 1 batch: some pairs failed (error rows in its summary); "
            "2 bad input, option or output path (one line on stderr, before any work); "
            "3 not measured (the map may not be of the reference's place); 130 interrupted "
            "(Ctrl-C; SIGTERM for batch); 141 output pipe closed. Inputs: ROS map_server YAML "
            "(+ PGM/PNG), PGM, PNG and other images, .npy arrays, ROS bags (--topic). Every "
            "subcommand takes -q/--quiet and -v/--verbose. Limits: BROKENNESS_MAX_CELLS (cells "
            "per map, default 100000000), BROKENNESS_WORKER_MEMORY (address space per batch "
            "worker process with --workers 2 or more, e.g. 4G); see the README's Reliability "
            "section"
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
    text = " ".join(str(message).split())
    print(f"brokenness: warning: {text}", file=file or sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    # no huge pages for the computation, the saving's grids too (brokenness._memory); a
    # subcommand that evaluates elsewhere (batch: its workers) says where itself
    pages = small_pages() if getattr(args, "small_pages", True) else contextlib.nullcontext()
    with warnings.catch_warnings(), pages:
        warnings.showwarning = _show_warning
        return _run(args)


def console() -> int:
    """The ``brokenness`` command (and ``python -m brokenness``): :func:`main` in a process of
    its own, whose libraries run on one thread each unless the user set their variables
    (:func:`brokenness._threads.single_threaded_process`; numpy and OpenCV are not loaded
    yet here)."""
    single_threaded_process()
    return main()


def _run(args: argparse.Namespace) -> int:
    prog = f"brokenness {args.command}"
    try:
        code = int(args.func(args))
        sys.stdout.flush()  # a closed pipe shows here, not at exit
        return code
    except BrokennessError as exc:
        sys.stderr.write(_error_line(prog, exc))
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # an OSError: before the general case
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except OSError as exc:  # unwritable output path, disk full...
        sys.stderr.write(_error_line(prog, exc))
        return EXIT_BAD_INPUT
    except MemoryError:
        message = (
            "out of memory (the input is too large for this machine; see BROKENNESS_MAX_CELLS)"
        )
        sys.stderr.write(_error_line(prog, message))
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("brokenness: interrupted", file=sys.stderr)
        return 130


def _silence_stdout() -> None:
    """After a broken pipe: no second error when Python flushes stdout at exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # stdout replaced (tests) or closed
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
