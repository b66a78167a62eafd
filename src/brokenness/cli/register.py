"""``brokenness register REFERENCE MOVING``: the rigid transform that aligns two maps."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ..registration.methods import METHODS

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``register``."""
    p = subparsers.add_parser(
        "register",
        help="rigid transform that aligns a map with a reference",
        description=(
            "Find the rotation and translation that map the cells (x = column, y = row) of "
            "MOVING onto REFERENCE (improved Fourier-Mellin registration by default). Maps: "
            "ROS map YAML, PGM, PNG (and other images), .npy."
        ),
    )
    p.add_argument("reference", help="the reference map")
    p.add_argument("moving", help="the map to align with the reference")
    p.add_argument("--json", metavar="PATH", help="write the result as JSON to PATH ('-': stdout)")
    p.add_argument("--method", choices=METHODS, default="ifmi", help="registration (default ifmi)")
    p.add_argument("--seed", type=int, default=None, help="seed of the random-walk method")
    p.add_argument(
        "--candidates",
        type=int,
        default=3,
        metavar="N",
        help="number of ranked hypotheses to report (default 3)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load both maps, register, and print (or write) the result."""
    from ..io import load_map
    from ._outputs import check_output_file, check_seed

    if args.json and args.json != "-":
        check_output_file(args.json, "--json")
    check_seed(args.seed)
    from ..registration.api import register

    ref = load_map(args.reference)
    moving = load_map(args.moving)
    reg = register(ref, moving, method=args.method, seed=args.seed, max_candidates=args.candidates)
    record = reg.to_dict()
    record["reference"] = str(args.reference)
    record["moving"] = str(args.moving)
    if args.json == "-":
        json.dump(record, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    if args.json:
        from .._atomic import atomic_write_text

        atomic_write_text(Path(args.json), json.dumps(record, indent=2) + "\n")
    t = reg.transform
    print(f"rotation:    {t.rotation_deg + 0.0:.3f} deg (cells: x = column, y = row)")
    print(f"translation: ({t.tx:.2f}, {t.ty:.2f}) cells")
    if t.scale != 1.0:
        print(f"scale:       {t.scale:.6g} (moving resolution / reference resolution)")
    if t.world is not None:
        w = t.world
        print(
            f"world:       {w.rotation_deg:.3f} deg counter-clockwise, ({w.tx:.3f}, {w.ty:.3f}) m"
        )
    print(f"confidence:  {reg.confidence:.2f}  ({reg.method}, {reg.seconds:.3f} s)")
    return 0
