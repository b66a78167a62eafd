"""Parse and map time of every Radish CARMEN log, and whether each maps to single walls.

For each ``*.log.gz`` in ``../shared/data/radish-corrected-carmen-logs/`` (or ``--logs DIR``):

- ``parse s``: :func:`~brokenness.simulation.carmen.read_carmen` (gunzip + parse), best of
  ``--repeat`` runs;
- ``map s``: :func:`~brokenness.simulation.carmen.map_log` at ``--resolution`` (default
  0.05 m) with the log's whole range (``--max-range`` to cap it), best of ``--repeat``;
- the single-wall measure of :func:`~brokenness.simulation.carmen.wall_check` (0.1 m cells,
  2 cells tolerance, 10 m range): ``cross-half`` (second half's walls on the first half's,
  where the first half saw; near 1 = single walls), ``half-in-full`` and ``Psi half/full``;
- ``bumped``: ``cross-half`` again after a 3 degree turn of the pose estimate a quarter into
  the run (doubled walls), to show the measure's contrast.

The machine is shared; times are wall-clock seconds of one process. Run:
``python benchmarks/bench_carmen.py [--repeat N] [--resolution R] [--max-range M]``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from brokenness.simulation.carmen import CarmenLog, map_log, read_carmen, wall_check

ROOT = Path(__file__).resolve().parents[1]
LOGS = ROOT.parent / "shared" / "data" / "radish-corrected-carmen-logs"


def turned(log: CarmenLog, degrees: float = 3.0) -> np.ndarray:
    """The log's poses with the estimate turned by ``degrees`` from a quarter of the run on."""
    k = log.n_scans // 4
    p = log.poses.copy()
    t = math.radians(degrees)
    c, s = math.cos(t), math.sin(t)
    dx, dy = p[k:, 0] - p[k, 0], p[k:, 1] - p[k, 1]
    p[k:, 0], p[k:, 1] = p[k, 0] + c * dx - s * dy, p[k, 1] + s * dx + c * dy
    p[k:, 2] += t
    return p


def best(fn, repeat: int):  # noqa: ANN001, ANN201
    """(fastest wall time, last result) of ``repeat`` calls."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=Path, default=LOGS)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--resolution", type=float, default=0.05)
    ap.add_argument("--max-range", type=float, default=None)
    args = ap.parse_args()
    paths = sorted(args.logs.glob("*.log*"))
    if not paths:
        print(f"no logs in {args.logs}; nothing to measure")
        return 0
    rng = "whole range" if args.max_range is None else f"{args.max_range:g} m range"
    print(f"map: {args.resolution:g} m cells, {rng}; wall check: 0.1 m cells, 2 cells, 10 m\n")
    print(
        "| log | scans | beams | max range m | parse s | map s | map cells | occupied "
        "| cross-half | half-in-full | Psi half/full | bumped cross-half |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for path in paths:
        t_parse, log = best(lambda p=path: read_carmen(p), args.repeat)
        t_map, m = best(
            lambda lg=log: map_log(lg, resolution=args.resolution, max_range=args.max_range),
            args.repeat,
        )
        check = wall_check(log)
        bumped = wall_check(log, poses=turned(log))
        name = path.name.split(".")[0]
        rows, cols = m.shape
        print(
            f"| {name} | {log.n_scans} | {log.n_beams} | {log.max_range:g} | {t_parse:.3f} "
            f"| {t_map:.2f} | {cols}x{rows} | {m.n_occupied} | {check.cross_half:.3f} "
            f"| {check.half_in_full:.3f} | {check.psi_half_full:.2f} "
            f"| {bumped.cross_half:.3f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
