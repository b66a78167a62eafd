"""``brokenness compute MAP REFERENCE``: the degree of brokenness of one map."""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import NothingFoundWarning
from ..registration.methods import METHODS
from ._common import (
    INPUTS_HELP,
    add_map_options,
    add_verbosity,
    check_dpi,
    console,
    load_pair,
    plural,
)
from .main import EXIT_NOT_MEASURED, EXIT_OK

if TYPE_CHECKING:
    from ..grid import OccupancyMap
    from ..measure import BrokennessResult

#: A degree from which ``compute`` checks whether the map fits better mirrored.
MIRROR_CHECK_DEGREE = 3  # as the batch (brokenness.batch.runner)

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``compute``."""
    p = subparsers.add_parser(
        "compute",
        help="degree of brokenness of a map against a reference",
        description=(
            "Split MAP into partitions that each agree with REFERENCE under their own rigid "
            "transform (Birk 2010, Algorithm 1) and report the degree of brokenness "
            f"(partitions - 1). {INPUTS_HELP} Conventions: rot° and shift (cells) map "
            "cells (x = column, y = row down) of MAP onto REFERENCE, a positive rot° turning "
            "clockwise on screen; world rot° and shift (m) are the same transform in the ROS "
            "world frames (y up, counter-clockwise), hence of opposite sign."
        ),
        epilog=(
            "exit status: 0 measured; 2 bad input or options (one line on stderr); 3 not "
            "measured: no part of the map agrees with the reference well enough (not the "
            "same place?), degree null. --repaired writes by its suffix: .yaml (ROS map, "
            "+ .pgm), .pgm, .png or .npy (OccupancyGrid values, ROS row order)."
        ),
    )
    p.add_argument("map", help="the map under test")
    p.add_argument("reference", help="the reference map (ground truth)")
    p.add_argument("--json", metavar="PATH", help="write the result as JSON to PATH ('-': stdout)")
    p.add_argument("--overlay", metavar="PNG", help="draw the partitions over the reference")
    p.add_argument(
        "--overlay-mode",
        choices=("overlay", "split"),
        default="overlay",
        help="overlay: the partitions drawn over the reference, in the map's frame; split: "
        "two panels, the map coloured by partition in its own frame and each partition "
        "moved by its transform onto the reference",
    )
    p.add_argument("--dpi", type=int, default=150, help="resolution of --overlay (default 150)")
    p.add_argument("--title", default=None, help="title of the --overlay picture")
    p.add_argument(
        "--save-results", metavar="ZIP", help="write a self-contained result record (zip)"
    )
    p.add_argument(
        "--results-overlay",
        choices=("figure", "fast", "none"),
        default="figure",
        help="the overlay picture in the --save-results zip: figure (default; the matplotlib "
        "figure of --overlay), fast (numpy and Pillow, as a batch writes it: a fraction of the "
        "time on large maps) or none",
    )
    p.add_argument(
        "--label",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="label stored with --save-results, as a manifest column (repeatable)",
    )
    p.add_argument(
        "--repaired",
        metavar="MAP",
        help="write the map with each partition moved back (.yaml, .pgm, .png or .npy)",
    )
    p.add_argument("--method", choices=METHODS, default="ifmi", help="registration (default ifmi)")
    p.add_argument("--seed", type=int, default=None, help="seed of the random-walk method")
    p.add_argument(
        "--threshold",
        type=float,
        default=2.0,
        help=(
            "masking threshold c in cells of the working grid: the finer of the two maps' "
            "(Manhattan; default 2; a map coarser than the reference by more raises it to "
            "the side of a map cell)"
        ),
    )
    p.add_argument(
        "--min-partition-fraction",
        type=float,
        default=0.02,
        help="smallest partition as a share of the occupied cells (default 0.02)",
    )
    p.add_argument(
        "--frames",
        type=int,
        default=1,
        metavar="K",
        help=(
            "grid frames of MAP to measure in (1-5, default 1: its own): a map measured in "
            "its own frame with a partition whose free space does not show its place is "
            "also measured turned by a half turn, a quarter turn each way, shifted, and the "
            "partitioning that explains the most is kept (up to K times the time; see the "
            "README, 'Frames')"
        ),
    )
    p.add_argument(
        "--time-budget",
        type=float,
        default=None,
        metavar="SECONDS",
        help=(
            "random-walk only: stop each registration's walk after SECONDS (results then "
            "depend on the machine; the default iteration budget alone is deterministic)"
        ),
    )
    add_map_options(p)
    add_verbosity(p)
    p.set_defaults(func=run)


def _check_outputs(args: argparse.Namespace) -> None:
    """Every file ``compute`` will write, checked before the maps are even loaded (none may
    be one of the two maps, or the image a YAML map names)."""
    from ._outputs import MAP_SUFFIXES, RESULT_SUFFIXES, Output, check_outputs, figure_suffixes

    repaired = Path(args.repaired) if args.repaired else None
    image = (  # save_map writes a YAML map's image next to it
        (str(repaired.with_suffix(".pgm")),)
        if repaired is not None and repaired.suffix.lower() in (".yaml", ".yml")
        else ()
    )
    check_outputs(
        [
            Output("--json", args.json),
            Output("--overlay", args.overlay, figure_suffixes() if args.overlay else None),
            Output("--save-results", args.save_results, RESULT_SUFFIXES),
            Output("--repaired", args.repaired, MAP_SUFFIXES, writes=image),
        ],
        inputs=(args.map, args.reference),
    )


def parse_labels(items: list[str]) -> dict[str, str]:
    """``["k=v", ...]`` as a dict (ParameterError on an item without ``=`` or key)."""
    from ..errors import ParameterError

    labels: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ParameterError(f"--label must be KEY=VALUE, got {item!r}")
        labels[key.strip()] = value.strip()
    return labels


def run(args: argparse.Namespace) -> int:
    """Load the maps, compute, and write what was asked for."""
    from ..errors import ParameterError
    from ..limits import check_measurable, check_threshold
    from ..measure import compute_brokenness
    from ..measure.options import MAX_FRAMES
    from ._outputs import check_seed

    _check_outputs(args)
    check_seed(args.seed)
    if not 1 <= args.frames <= MAX_FRAMES:
        raise ParameterError(f"--frames must be from 1 to {MAX_FRAMES}, got {args.frames}")
    check_threshold(args.threshold)  # the neighbourhood it implies, before any map is read
    labels = parse_labels(args.label)
    check_dpi(args.dpi)
    budget = getattr(args, "time_budget", None)
    if budget is not None and not (budget > 0 and math.isfinite(budget)):
        raise ParameterError(f"--time-budget must be a positive number of seconds, got {budget}")
    m, ref = load_pair(args)
    check_measurable(m.n_occupied, args.map)
    check_threshold(args.threshold, ref.shape)
    options: dict[str, Any] = {}
    if args.method == "random-walk" and budget is not None:
        options["time_budget"] = budget
    walk = args.method == "random-walk" and not args.quiet
    with (
        _busy(args, m),
        _walk_progress(walk) as progress,
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("ignore", NothingFoundWarning)  # said once, below, as the reason
        if progress is not None:
            options["progress"] = progress
        result = compute_brokenness(
            m,
            ref,
            method=args.method,
            seed=args.seed,
            threshold=args.threshold,
            min_partition_fraction=args.min_partition_fraction,
            registration_options=options or None,
            frames=args.frames,
        )
    # The progress display is not a parameter of the result (nor JSON): keep it out of the
    # record, the JSON and the saved results.
    (result.parameters.get("registration_options") or {}).pop("progress", None)
    status = EXIT_OK if result.measured else EXIT_NOT_MEASURED
    if not result.measured or (result.degree or 0) >= MIRROR_CHECK_DEGREE:
        _warn_if_mirrored(m, ref, args)
    if args.overlay:
        from ..report.overlay import render_overlay

        render_overlay(
            result, m, ref, args.overlay, dpi=args.dpi, title=args.title, mode=args.overlay_mode
        )
    if args.repaired:
        from ..report.repair import write_repaired

        write_repaired(args.repaired, result, m, ref)
    if args.save_results:
        from ..report.results import save_results

        save_results(
            args.save_results,
            result,
            m,
            ref,
            info={
                "map": args.map,
                "reference": args.reference,
                "command": "compute",
                "labels": labels,
            },
            overlay=args.results_overlay,
        )
    if args.json == "-":
        json.dump(_json_record(result, args), sys.stdout, indent=2)
        sys.stdout.write("\n")
        return status
    if args.json:
        _write_json(Path(args.json), _json_record(result, args))
    if not args.quiet:
        _print_summary(result, m, ref, verbose=args.verbose)
    return status


def _busy(args: argparse.Namespace, m: OccupancyMap) -> Any:
    """A spinner on a terminal (stderr) while a large map computes (the random walk shows its
    own progress bar)."""
    import contextlib

    slow = m.states.size >= 4_000_000 and args.method != "random-walk"  # the walk: a bar
    if args.quiet or not sys.stderr.isatty() or not slow:
        return contextlib.nullcontext()
    rows, cols = m.shape
    return console(stderr=True).status(f"computing the brokenness of a {cols}x{rows} map...")


def _warn_if_mirrored(m: OccupancyMap, ref: OccupancyMap, args: argparse.Namespace) -> None:
    """Warn (one line) when the map fits the reference far better with its rows reversed."""
    from ..errors import BrokennessError
    from ..measure.mirror import mirror_check

    try:
        check = mirror_check(m, ref, threshold=args.threshold)
    except BrokennessError:  # nothing to register: the result says why
        return
    if check.far_better_mirrored:
        from ..io import MapWarning

        warnings.warn(check.message(), MapWarning, stacklevel=2)


@contextmanager
def _walk_progress(wanted: bool) -> Iterator[Callable[[Any], None] | None]:
    """A progress callback for the random walk, shown with rich on stderr when it is a TTY.

    Yields ``None`` (no display) when not ``wanted`` or stderr is not a terminal, so that
    pipes and log files get no control characters.
    """
    if not wanted or not sys.stderr.isatty():
        yield None
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(
        TextColumn("random walk, registration {task.fields[call]}"),
        BarColumn(),
        TextColumn("step {task.completed}/{task.total}"),
        TextColumn("best Delta {task.fields[delta]:.2f}, omega {task.fields[omega]:.3f}"),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        task = bar.add_task("walk", total=1, call=0, delta=0.0, omega=0.0)

        def show(p: Any) -> None:
            bar.update(
                task,
                completed=p.max_steps if p.done else p.step,
                total=p.max_steps,
                call=p.call,
                delta=p.best_delta,
                omega=p.best_acceptance,
            )

        yield show


def _json_record(result: BrokennessResult, args: argparse.Namespace) -> dict[str, Any]:
    record = result.to_dict()
    record["map"] = str(args.map)
    record["reference"] = str(args.reference)
    return record


def _write_json(path: Path, record: dict[str, Any]) -> None:
    from .._atomic import atomic_write_text

    atomic_write_text(path, json.dumps(record, indent=2) + "\n")


def _frames_line(result: BrokennessResult, out: Any) -> None:
    """With ``--frames`` 2 or more: every frame's degree and the frame kept."""
    if "frame_degrees" not in result.parameters:
        return
    tried = result.parameters["frame_degrees"]
    if len(tried) == 1:
        why = "not measured there" if tried[0] is None else "no partition in doubt"
        out.print(f"frames: {result.parameters['frames']}; only the map's own tried ({why})")
        return
    degrees = ", ".join("not measured" if d is None else str(d) for d in tried)
    out.print(
        f"frames: {result.parameters['frames']} (degrees {degrees}); kept the "
        f"{result.parameters['frame']} frame's result (at the own frame's degree, the fewest "
        "cells unassigned)"
    )


def _threshold_line(result: BrokennessResult) -> str | None:
    """When the agreement threshold was raised for the map (a coarser map's cells, walls
    drawn thicker than the reference's): by how much and why (one line; ``None`` when not)."""
    asked = result.parameters.get("threshold")
    used = result.parameters.get("working_threshold")
    if asked is None or used is None or used <= asked:
        return None
    walls = result.parameters.get("wall_thickness")
    drawn = "" if walls is None else f"; the map draws its walls {walls} of its cells thick"
    return (
        f"threshold: {used:g} working cells, not {asked:g}: how far the map draws a wall "
        f"beyond the reference's drawing of it{drawn}"
    )


def _replication_line(result: BrokennessResult) -> str | None:
    """For a measured map with a partition in doubt: the frame it was measured in again, its
    degree there and the share of the partitioned cells placed alike (one line; ``None``
    when it was not needed)."""
    parameters = result.parameters
    if not result.measured or "replication_frame" not in parameters:
        return None
    alike = parameters.get("replication_placed_alike")
    same = "" if alike is None else f", {alike:.0%} of the partitioned cells placed alike"
    in_doubt = parameters.get("replication_placed_alike_in_doubt")
    if in_doubt is not None:
        same += f" ({in_doubt:.0%} of those in doubt)"
    return (
        f"measured again with the grid {parameters['replication_frame']} degrees "
        f"(a partition is in doubt): degree {parameters['replication_degree']} there{same}"
    )


def _evidence_line(result: BrokennessResult) -> str:
    """The free-space evidence the measured degree rests on, and its limit (one line)."""
    from ..measure.evidence import MAP_RATIO

    def percent(share: float) -> str:
        return f"{100 * share:.1f} %" if share < 0.1 else f"{100 * share:.0f} %"

    ratio, bound = result.contradiction, result.contradiction_bound
    seen = "too few free cells for a rate" if ratio is None else f"{percent(ratio)} of chance"
    upper = "" if bound is None else f", at most {percent(bound)}"
    return (
        f"evidence: the map's free space crosses reference walls at {seen}{upper} "
        f"(measured when at most {percent(MAP_RATIO)})"
    )


def _doubt_line(result: BrokennessResult) -> str | None:
    """The partitions whose own free space does not show that they are in place (one line;
    ``None`` when there is none): the least certain places of a measured degree."""
    from ..measure.evidence import MAP_RATIO
    from ..measure.frames import partitions_in_doubt

    named = [
        f"{p.index} (too little free space to tell)"
        if p.contradiction_bound is None
        else f"{p.index} (at most {100 * p.contradiction_bound:.0f} %)"
        for p in partitions_in_doubt(result)
    ]
    if not named:
        return None
    which, whose = ("partition", "its own") if len(named) == 1 else ("partitions", "each one's")
    return (
        f"in doubt: {which} {', '.join(named)}: {whose} free space does not show that it is "
        f"in place (a bound over {100 * MAP_RATIO:.0f} % of chance)"
    )


def _print_summary(
    result: BrokennessResult, m: OccupancyMap, ref: OccupancyMap, *, verbose: bool = False
) -> None:
    from rich.table import Table

    out = console()
    if verbose:
        out.print(f"map: {m!r}\nreference: {ref!r}")
    if not result.measured:
        out.print(
            f"[bold]degree of brokenness: not measured[/bold] ({result.reason}; method "
            f"{result.method}, {result.seconds:.3f} s)"
        )
        _frames_line(result, out)
        return
    out.print(
        f"[bold]degree of brokenness: {result.degree}[/bold]  "
        f"({plural(len(result.partitions), 'partition')}, method {result.method}, "
        f"{result.seconds:.3f} s)"
    )
    metres = any(p.transform.world is not None for p in result.partitions)
    table = Table(box=None, header_style="bold", pad_edge=False, collapse_padding=True)
    headers = ["#", "cells", "share", "rot°", "shift (cells)"]
    headers += ["world rot°", "shift (m)"] if metres else []
    headers += ["off°", "off m" if metres else "off", "conf"]
    omega = any(p.acceptance is not None for p in result.partitions)
    headers += ["omega"] if omega else []
    for col in headers:
        table.add_column(col, justify="right", no_wrap=True)
    for p in result.partitions:
        t = p.transform
        row = [str(p.index), str(p.cells), f"{100 * p.fraction:.1f}%", f"{t.rotation_deg:.2f}"]
        row.append(f"{t.tx:.1f}, {t.ty:.1f}")
        if metres:
            w = t.world
            row += ["", ""] if w is None else [f"{w.rotation_deg:.2f}", f"{w.tx:.2f}, {w.ty:.2f}"]
        off = p.displacement_m if metres and p.displacement_m is not None else p.displacement
        row += [f"{p.rotation_offset_deg:.2f}", f"{off:.2f}", f"{p.confidence:.2f}"]
        if omega:
            row.append("" if p.acceptance is None else f"{p.acceptance:.3f}")
        table.add_row(*row)
    out.print(table)
    out.print(
        f"unassigned: {result.unassigned_cells} of {result.occupied_cells} occupied cells "
        f"({100 * result.unassigned_fraction:.1f}%)"
    )
    out.print(_evidence_line(result))
    for line in (_threshold_line(result), _doubt_line(result), _replication_line(result)):
        if line is not None:
            out.print(line)
    _frames_line(result, out)
    note = "rot°/shift (cells): map cells onto reference cells, y down, + = clockwise on screen"
    if metres:
        note += "; world rot°/shift (m): ROS world frames, y up, + = counter-clockwise"
    out.print(note)
    if verbose:
        steps = ", ".join(f"{1000 * s:.0f}" for s in result.step_seconds)
        out.print(f"step times (ms): {steps}")
