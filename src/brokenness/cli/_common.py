"""What several subcommands share: loading a map pair with its options, the console."""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._lazy import lazy_exports
from ..errors import ParameterError

if TYPE_CHECKING:
    from ..grid import OccupancyMap
    from ..io.pairing import geometry_warning

__all__ = [
    "INPUTS_HELP",
    "add_map_options",
    "add_verbosity",
    "console",
    "geometry_warning",
    "load_pair",
    "parse_origin",
    "plural",
]

# numpy only when a subcommand loads maps (``brokenness batch`` itself never does)
__getattr__, __dir__ = lazy_exports(__name__, {"geometry_warning": "brokenness.io.pairing"})

#: The input formats, for help texts.
INPUTS_HELP = (
    "Maps: ROS map_server YAML (+ PGM/PNG), PGM, PNG and other images, .npy arrays, ROS bags "
    "(ROS 1 .bag, ROS 2 folder / .db3 / .mcap; the map on --topic)."
)


def plural(n: int, word: str, many: str | None = None) -> str:
    """``"1 map"``, ``"2 maps"``."""
    return f"{n} {word if n == 1 else (many or word + 's')}"


def console(*, stderr: bool = False) -> Any:
    """A rich Console that never cuts piped or redirected output to 80 columns.

    On a terminal it takes the terminal's width; otherwise the width is unlimited in effect
    (tables are as wide as their content), and no colour codes are written.
    """
    from rich.console import Console

    class _Console(Console):
        def on_broken_pipe(self) -> None:  # rich exits with 1; the command line says 141
            self.quiet = True
            raise BrokenPipeError(32, "Broken pipe")

    stream = sys.stderr if stderr else sys.stdout
    tty = stream.isatty()
    width = None if tty else 10_000
    return _Console(file=stream, width=width, soft_wrap=not tty, highlight=False)


#: ``--dpi`` of a picture or plot: at least this (a smaller one draws nothing legible) ...
MIN_DPI = 10
#: ... and at most this (a larger one would allocate a huge canvas).
MAX_DPI = 1200


def check_dpi(dpi: int) -> None:
    """Refuse a ``--dpi`` outside ``MIN_DPI..MAX_DPI`` (a :class:`ParameterError`)."""
    if not MIN_DPI <= dpi <= MAX_DPI:
        raise ParameterError(f"--dpi must be between {MIN_DPI} and {MAX_DPI}, got {dpi}")


def add_verbosity(p: argparse.ArgumentParser) -> None:
    """``-q/--quiet`` and ``-v/--verbose``."""
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="print only errors and warnings (and a report asked for on stdout: --json -)",
    )
    group.add_argument(
        "-v", "--verbose", action="store_true", help="say more (timings, what was loaded)"
    )


def parse_origin(text: str) -> tuple[float, float, float]:
    """``"X,Y,YAW"`` (metres, metres, radians; YAW may be left out) as a tuple."""
    parts = [v for v in text.replace(" ", ",").split(",") if v]
    try:
        values = [float(v) for v in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y[,YAW] numbers, got {text!r}") from None
    if len(values) == 2:
        values.append(0.0)
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected X,Y[,YAW], got {text!r}")
    return values[0], values[1], values[2]


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected metres per cell, got {text!r}") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"a resolution must be positive, got {text!r}")
    return value


def add_map_options(
    p: argparse.ArgumentParser, first: str = "map", second: str = "reference"
) -> None:
    """Geometry, row order and topic of the two input maps."""
    for who in (first, second):
        p.add_argument(
            f"--{who}-resolution",
            type=_positive,
            metavar="M",
            help=f"metres per cell of the {who} (overrides its file; needed for bare images)",
        )
        p.add_argument(
            f"--{who}-origin",
            type=parse_origin,
            metavar="X,Y[,YAW]",
            help=f"world pose of the {who}'s lower-left corner (m, m, rad; as in a ROS YAML)",
        )
    p.add_argument(
        "--row-order",
        choices=("ros", "image"),
        default=None,
        help=(
            ".npy maps: 'ros' when row 0 is the bottom row (nav_msgs/OccupancyGrid data), "
            "'image' when it is the top row. Default: ros for OccupancyGrid values "
            "(-1, 0..100), image for bool, 3-state (-1/0/1) and float arrays"
        ),
    )
    p.add_argument(
        "--topic", default=None, help="map topic when an input is a ROS bag (default /map)"
    )


def _is_npy(path: str) -> bool:
    return Path(path).suffix.lower() == ".npy"


def load_pair(
    args: argparse.Namespace, first: str = "map", second: str = "reference"
) -> tuple[OccupancyMap, OccupancyMap]:
    """Load the two maps named by ``args.<first>`` and ``args.<second>``.

    The same file is read once (its warnings said once). Warns when only one of the two
    knows its resolution (:func:`geometry_warning`).
    """
    from ..io import load_map
    from ..io.pairing import geometry_warning

    paths = (getattr(args, first), getattr(args, second))
    row_order = getattr(args, "row_order", None)
    if row_order is not None and not any(_is_npy(p) for p in paths):
        raise ParameterError("--row-order applies to .npy maps only")
    if getattr(args, "topic", None) is not None and not any(_is_bag(p) for p in paths):
        raise ParameterError("--topic applies to ROS bags only")
    maps: list[OccupancyMap] = []
    for who, path in zip((first, second), paths, strict=True):
        res = getattr(args, f"{who}_resolution", None)
        origin = getattr(args, f"{who}_origin", None)
        if (
            maps
            and _same_file(paths[0], path)
            and (res, origin)
            == (
                getattr(args, f"{first}_resolution", None),
                getattr(args, f"{first}_origin", None),
            )
        ):
            maps.append(maps[0])
            continue
        maps.append(
            load_map(
                path,
                topic=getattr(args, "topic", None),
                resolution=res,
                origin=origin,
                row_order=row_order if _is_npy(path) else None,
            )
        )
    message = geometry_warning(maps[0], maps[1], first, second)
    if message:
        from ..io import MapWarning

        warnings.warn(message, MapWarning, stacklevel=2)
    return maps[0], maps[1]


def _is_bag(path: str) -> bool:
    from ..io.load import is_rosbag

    return is_rosbag(Path(path))


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False
