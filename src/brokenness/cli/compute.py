"""``brokenness compute MAP REFERENCE``: the degree of brokenness of one map."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
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
    p.add_argument("--topic", default=None, help="map topic when MAP or REFERENCE is a ROS bag")
    p.set_defaults(func=run)


def check_outputs(args: argparse.Namespace) -> None:
    """Every file ``compute`` will write, checked before the maps are even loaded."""
    from ._outputs import MAP_SUFFIXES, RESULT_SUFFIXES, check_output_file, figure_suffixes

    if args.json and args.json != "-":
        check_output_file(args.json, "--json")
    if args.overlay:
        check_output_file(args.overlay, "--overlay", figure_suffixes())
    if args.save_results:
        check_output_file(args.save_results, "--save-results", RESULT_SUFFIXES)
    if args.repaired:
        check_output_file(args.repaired, "--repaired", MAP_SUFFIXES)


def run(args: argparse.Namespace) -> int:
    """Load the maps, compute, and write what was asked for."""
    from ..io import load_map
    from ..limits import check_measurable, check_threshold
    from ._outputs import check_seed

    check_outputs(args)
    check_seed(args.seed)
    check_threshold(args.threshold)  # the neighbourhood it implies, before any map is read
    m = load_map(args.map, topic=args.topic)
    ref = load_map(args.reference, topic=args.topic)
    check_measurable(m.n_occupied, args.map)
    check_threshold(args.threshold, ref.shape)
    with warnings.catch_warnings():  # said once, below, as the result's reason
        warnings.simplefilter("ignore", NothingFoundWarning)
        result = compute_brokenness(
            m,
            ref,
            method=args.method,
            seed=args.seed,
            threshold=args.threshold,
            min_partition_fraction=args.min_partition_fraction,
        )
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
        table.add_row(*row)
    console.print(table)
    console.print(
        f"unassigned: {result.unassigned_cells} of {result.occupied_cells} occupied cells "
        f"({100 * result.unassigned_fraction:.1f}%)"
    )
