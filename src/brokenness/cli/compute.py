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
from typing import Any

from ..errors import NothingFoundWarning
from ..grid import OccupancyMap
from ..measure import BrokennessResult, compute_brokenness
from ..registration.methods import METHODS
from .main import EXIT_NOT_MEASURED, EXIT_OK

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``compute``."""
    p = subparsers.add_parser(
        "compute",
        help="degree of brokenness of a map against a reference",
        description=(
            "Split MAP into partitions that each agree with REFERENCE under their own rigid "
            "transform (Birk 2010, Algorithm 1) and report the degree of brokenness "
            "(partitions - 1). Maps: ROS map YAML, PGM, PNG (and other images), .npy."
        ),
        epilog=(
            "exit status: 0 measured; 2 bad input or options; 3 not measured: no part of the "
            "map agrees with the reference well enough (not the same place?), degree null"
        ),
    )
    p.add_argument("map", help="the map under test")
    p.add_argument("reference", help="the reference map (ground truth)")
    p.add_argument("--json", metavar="PATH", help="write the result as JSON to PATH ('-': stdout)")
    p.add_argument("--overlay", metavar="PNG", help="draw the partitions over the reference")
    p.add_argument("--save-results", metavar="ZIP", help="write a self-contained result record")
    p.add_argument("--repaired", metavar="MAP", help="write the map with each partition moved back")
    p.add_argument("--method", choices=METHODS, default="ifmi", help="registration (default ifmi)")
    p.add_argument("--seed", type=int, default=None, help="seed of the random-walk method")
    p.add_argument(
        "--threshold",
        type=float,
        default=2.0,
        help="masking threshold c in reference cells (Manhattan; default 2)",
    )
    p.add_argument(
        "--min-partition-fraction",
        type=float,
        default=0.02,
        help="smallest partition as a share of the occupied cells (default 0.02)",
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
    p.add_argument("--topic", default=None, help="map topic when MAP or REFERENCE is a ROS bag")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load the maps, compute, and write what was asked for."""
    from ..io import load_map

    m = load_map(args.map, topic=args.topic)
    ref = load_map(args.reference, topic=args.topic)
    budget = getattr(args, "time_budget", None)
    if budget is not None and not (budget > 0 and math.isfinite(budget)):
        from ..errors import ParameterError

        raise ParameterError(f"--time-budget must be a positive number of seconds, got {budget}")
    options: dict[str, Any] = {}
    if args.method == "random-walk" and budget is not None:
        options["time_budget"] = budget
    with _walk_progress(args.method == "random-walk") as progress, warnings.catch_warnings():
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
        )
    # The progress display is not a parameter of the result (nor JSON): keep it out of the
    # record, the JSON and the saved results.
    (result.parameters.get("registration_options") or {}).pop("progress", None)
    status = EXIT_OK if result.measured else EXIT_NOT_MEASURED
    if args.overlay:
        from ..report.overlay import render_overlay

        render_overlay(result, m, ref, args.overlay)
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
            info={"map": args.map, "reference": args.reference, "command": "compute"},
        )
    if args.json == "-":
        json.dump(_json_record(result, args), sys.stdout, indent=2)
        sys.stdout.write("\n")
        return status
    if args.json:
        _write_json(Path(args.json), _json_record(result, args))
    _print_summary(result, m, ref)
    return status


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


def _print_summary(result: BrokennessResult, m: OccupancyMap, ref: OccupancyMap) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    if not result.measured:
        console.print(
            f"[bold]degree of brokenness: not measured[/bold] ({result.reason}; method "
            f"{result.method}, {result.seconds:.3f} s)"
        )
        return
    console.print(
        f"[bold]degree of brokenness: {result.degree}[/bold]  "
        f"({len(result.partitions)} partition(s), method {result.method}, "
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
    console.print(table)
    console.print(
        f"unassigned: {result.unassigned_cells} of {result.occupied_cells} occupied cells "
        f"({100 * result.unassigned_fraction:.1f}%)"
    )
