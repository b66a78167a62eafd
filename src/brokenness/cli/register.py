"""``brokenness register REFERENCE MOVING``: the rigid transform that aligns two maps.

What it answers: the one rigid transform under which the most cells of MOVING land on
reference walls, and the next best distinct hypotheses (``--candidates``). The search is
that of :func:`brokenness.register` with its defaults (up to ``max(12, N)`` distinct
hypotheses examined and ranked; ``--candidates N`` only says how many of the ranking are
shown), so the answer is the same for every ``N`` up to 12 and is the Python API's for the
same maps. For an unbroken map that is *the* alignment. For a broken map it is the
alignment of one of its parts, usually the largest, but not necessarily (a smaller part
with straighter walls can give a sharper spectral peak); ``compute`` finds every part and
orders them by size.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ..registration.methods import METHODS
from ._common import INPUTS_HELP, add_map_options, add_verbosity, console, load_pair, plural

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``register``."""
    p = subparsers.add_parser(
        "register",
        help="rigid transform that aligns a map with a reference",
        description=(
            "Find the rotation and translation that map the cells (x = column, y = row, "
            "down) of MOVING onto REFERENCE (improved Fourier-Mellin registration by "
            "default). rotation is in degrees in the grid of cells, a positive angle "
            "turning clockwise on screen, and translation in reference cells; world is the "
            "same transform between the ROS world frames (degrees, a positive angle "
            "counter-clockwise, and metres, y up), shown when both maps have a resolution "
            "and an origin. The registration examines up to max(12, N) distinct hypotheses (N = "
            "--candidates) and ranks them by the cells of MOVING that agree with reference "
            "walls under each; the answer is the first of that ranking, the same for every "
            "N up to 12 and the same as brokenness.register(REFERENCE, MOVING) gives. For a "
            "broken map it is one part's alignment (usually, but not always, the largest "
            "part's; 'compute' finds every part). "
            f"{INPUTS_HELP}"
        ),
        epilog="exit status: 0 done; 2 bad input or options (one line on stderr)",
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
        help="number of distinct hypotheses to report, the first N of the ranking (default "
        "3); fewer when the method finds no more distinct ones (said so). Up to max(12, N) "
        "hypotheses are examined and ranked, so N does not change the answer up to 12",
    )
    add_map_options(p, "reference", "moving")
    add_verbosity(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load both maps, register, and print (or write) the result."""
    from ..limits import check_candidates
    from ._outputs import Output, check_outputs, check_seed

    check_outputs([Output("--json", args.json)], inputs=(args.reference, args.moving))
    check_seed(args.seed)
    from ..registration.api import register

    check_candidates(args.candidates, "--candidates")  # in [1, MAX_CANDIDATES]
    ref, moving = load_pair(args, "reference", "moving")
    # the API's search, whatever --candidates is (it only sets how many are reported)
    reg = register(ref, moving, method=args.method, seed=args.seed, max_candidates=args.candidates)
    record = reg.to_dict()
    record["reference"] = str(args.reference)
    record["moving"] = str(args.moving)
    fewer = None
    if len(reg.candidates) < args.candidates:
        fewer = (
            f"only {plural(len(reg.candidates), 'distinct hypothesis', 'distinct hypotheses')} "
            f"of the {args.candidates} asked for: the others the method found put the map's "
            "cells where one of these already does"
        )
        record["fewer_candidates"] = fewer
    if args.json == "-":
        json.dump(record, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    if args.json:
        from .._atomic import atomic_write_text

        atomic_write_text(Path(args.json), json.dumps(record, indent=2) + "\n")
    if args.quiet:
        return 0
    out = console()
    t = reg.transform
    out.print(
        f"rotation:    {t.rotation_deg + 0.0:.3f} deg (cells: x = column, y = row down; "
        "+ = clockwise on screen)"
    )
    out.print(f"translation: ({t.tx:.2f}, {t.ty:.2f}) cells")
    if t.scale != 1.0:
        out.print(f"scale:       {t.scale:.6g} (moving resolution / reference resolution)")
    if t.world is not None:
        w = t.world
        out.print(
            f"world:       {w.rotation_deg:.3f} deg counter-clockwise, ({w.tx:.3f}, {w.ty:.3f}) m"
        )
    out.print(f"confidence:  {reg.confidence:.2f}  ({reg.method}, {reg.seconds:.3f} s)")
    if len(reg.candidates) > 1 or args.verbose:
        out.print(f"{plural(len(reg.candidates), 'hypothesis', 'hypotheses')}, best first:")
        for i, c in enumerate(reg.candidates):
            ct = c.transform
            out.print(
                f"  {i}: rotation {ct.rotation_deg + 0.0:8.3f} deg, translation "
                f"({ct.tx:.2f}, {ct.ty:.2f}) cells, confidence {c.confidence:.2f}"
            )
    if fewer:
        out.print(f"note: {fewer}")
    return 0
