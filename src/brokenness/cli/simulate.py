"""``brokenness simulate --out DIR``: synthetic broken maps of known degree."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ._common import add_verbosity

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> None:
    """Register ``simulate``."""
    p = subparsers.add_parser(
        "simulate",
        help="make synthetic broken maps of known degree (bump noise)",
        description=(
            "Generate a building, drive a simulated laser robot through it, and map the run "
            "twice: with the true poses (the reference) and with bump noise on the pose "
            "estimate (the broken map; Birk 2010). Writes NAME.yaml/.pgm, "
            "NAME_reference.yaml/.pgm, NAME.json (seed, bumps, expected degree, each "
            "partition's true transform and share) and NAME_labels.npy per map. With --log, "
            "the run is a real CARMEN laser log with corrected poses instead of a building; "
            "with --plan, a tour planned through the free space of a map of your building."
        ),
        epilog="exit status: 0 done; 2 bad input or options (one line on stderr)",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first map (default 0)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument(
        "--degree",
        type=int,
        default=None,
        help="exact expected degree K (bumps redrawn until all K count)",
    )
    mode.add_argument(
        "--bumps",
        type=int,
        default=None,
        help="exactly K bumps, drawn once (the expected degree may be lower)",
    )
    mode.add_argument(
        "--bump-probability",
        type=float,
        default=None,
        metavar="P",
        help="the paper's model: each scan bumps with probability P",
    )
    p.add_argument(
        "--bump-radius",
        type=float,
        default=1.0,
        metavar="R",
        help="shift d ~ U[0, R] metres (default 1)",
    )
    p.add_argument(
        "--max-rotation",
        type=float,
        default=180.0,
        metavar="DEG",
        help="largest bump rotation, degrees (default 180: U[0, 360))",
    )
    p.add_argument(
        "--min-rotation",
        type=float,
        default=10.0,
        metavar="DEG",
        help="smallest bump rotation with --degree/--bumps, degrees (default 10)",
    )
    p.add_argument(
        "--size",
        type=float,
        default=15.0,
        metavar="METRES",
        help="building width and height (default 15)",
    )
    p.add_argument("--resolution", type=float, default=0.05, help="metres per cell (0.05)")
    p.add_argument(
        "--count",
        type=int,
        default=1,
        metavar="N",
        help="make N maps with seeds SEED..SEED+N-1 (default 1)",
    )
    p.add_argument("--name", default="sim", help="file name prefix (default 'sim')")
    source = p.add_mutually_exclusive_group()
    source.add_argument(
        "--log",
        metavar="PATH",
        default=None,
        help="a CARMEN log (FLASER/ROBOTLASER1, gzip or plain) with corrected poses: inject "
        "the bumps into its pose chain instead of simulating a building (--size is ignored)",
    )
    source.add_argument(
        "--plan",
        metavar="PATH",
        default=None,
        help="a map or floor plan of your building (ROS YAML, PGM, PNG; free cells are where "
        "the robot may go): tour it with the simulated laser instead of generating a "
        "building (--size is ignored)",
    )
    add_verbosity(p)
    p.set_defaults(func=run)


#: Most maps one ``simulate`` call writes.
MAX_COUNT = 100_000


def _check_sizes(args: argparse.Namespace) -> None:
    """Options that set sizes: checked (with the cells they imply) before any work."""
    import math

    from ..errors import ParameterError
    from ..limits import check_cells, resolution_in_range
    from ._outputs import Output, check_outputs

    check_outputs([Output("--out", args.out, folder=True)])
    if args.count > MAX_COUNT:
        raise ParameterError(f"--count must be at most {MAX_COUNT}, got {args.count}")
    if not resolution_in_range(args.resolution):
        raise ParameterError(f"--resolution must be in [1e-6, 1e4] metres, got {args.resolution}")
    if not (math.isfinite(args.size) and args.size > 0):
        raise ParameterError(f"--size must be a positive number of metres, got {args.size}")
    if args.log is None and args.plan is None:  # else the run's extent sets the size
        side = args.size / args.resolution
        check_cells(side, side, f"--size {args.size} at --resolution {args.resolution}: a map")
    for name in ("bump_radius", "max_rotation", "min_rotation", "bump_probability"):
        value = getattr(args, name)
        if value is not None and not math.isfinite(value):
            raise ParameterError(f"--{name.replace('_', '-')} must be finite, got {value}")


def run(args: argparse.Namespace) -> int:
    """Simulate ``--count`` maps and write them with their ground truth."""
    from ..errors import ParameterError
    from ..simulation.output import save_simulation
    from ..simulation.synthetic import simulate_broken_map

    if args.count < 1:
        raise ParameterError(f"--count must be at least 1, got {args.count}")
    if args.seed < 0:
        raise ParameterError(f"--seed must be >= 0, got {args.seed}")
    _check_sizes(args)
    bump_options = {
        "degree": args.degree,
        "bumps": args.bumps,
        "bump_probability": args.bump_probability,
        "bump_radius": args.bump_radius,
        "max_rotation": args.max_rotation,
        "min_rotation": args.min_rotation,
        "resolution": args.resolution,
    }
    log = None
    if args.log is not None:
        from pathlib import Path

        from ..io._files import check_regular
        from ..simulation.carmen import read_carmen

        check_regular(Path(args.log), "CARMEN log")  # no FIFO or device: it would never end

        log = read_carmen(args.log)
    plan = None
    if args.plan is not None:
        from ..io.load import load_map

        plan = load_map(args.plan)
    for seed in range(args.seed, args.seed + args.count):
        if log is not None:
            from ..simulation.carmen import broken_log_map

            sim = broken_log_map(log, seed=seed, **bump_options)
        elif plan is not None:
            from ..simulation.options import BumpOptions
            from ..simulation.plan_run import broken_plan_map

            options = {k: v for k, v in bump_options.items() if k != "resolution"}
            sim = broken_plan_map(
                plan, BumpOptions(seed=seed, **options), resolution=args.resolution
            )
        else:
            sim = simulate_broken_map(seed=seed, size=args.size, **bump_options)
        name = f"{args.name}_{seed:04d}"
        paths = save_simulation(sim, args.out, name)
        counted = sum(p.counted for p in sim.partitions)
        if args.quiet:
            continue
        print(
            f"{paths['map']}: expected degree {sim.expected_degree} "
            f"({len(sim.bumps)} bump{'' if len(sim.bumps) == 1 else 's'}; "
            f"{counted} of {len(sim.partitions)} partitions count), {sim.map.shape[1]}x"
            f"{sim.map.shape[0]} cells",
            file=sys.stdout,
        )
    return 0
