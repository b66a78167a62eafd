"""Speed and accuracy of the random-walk (BCMM) registration baseline.

Run from the repository root::

    python benchmarks/bench_random_walk.py            # synthetic maps of 300..2400 cells
    python benchmarks/bench_random_walk.py --real     # also the maps in tests/data

For every map it reports the evaluations of Delta per second (a batch of 12 transforms at a
time, as the walk does), and the time (reference preparation included, and shown on its
own), number of evaluations and steps, and error of a full registration with default
options of the map against a copy of itself rotated by 37 degrees and shifted: how the
time grows with the map's size. Numbers depend on the
machine and its load; nothing here is asserted.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from brokenness.registration import _rw_scoring as scoring
from brokenness.registration.random_walk import RandomWalkRegistrar, _transform_arrays
from brokenness.transform import RigidTransform


def rooms(n: int) -> np.ndarray:
    """A synthetic floor plan, ``n x n`` cells: outer walls, inner walls, two obstacles."""
    s = np.full((n, n), -1, np.int8)
    m = n // 10
    s[m : n - m, m : n - m] = 0
    occ = np.zeros((n, n), np.uint8)
    w = max(1, n // 100)
    cv2.rectangle(occ, (m, m), (n - m - 1, n - m - 1), 1, w)
    cv2.line(occ, (n // 2, m), (n // 2, int(n * 0.6)), 1, w)
    cv2.line(occ, (m, int(n * 0.4)), (int(n * 0.35), int(n * 0.4)), 1, w)
    cv2.line(occ, (int(n * 0.6), int(n * 0.7)), (n - m, int(n * 0.7)), 1, w)
    cv2.rectangle(occ, (int(n * 0.65), int(n * 0.2)), (int(n * 0.75), int(n * 0.3)), 1, -1)
    cv2.circle(occ, (int(n * 0.3), int(n * 0.75)), n // 20, 1, -1)
    s[occ > 0] = 1
    return s


def moved_copy(reference: np.ndarray, angle_deg: float, shift: tuple[float, float]):
    """A copy of ``reference`` seen in a rotated frame, on a canvas that holds all of it.

    Returns ``(moving, true)`` with ``true`` mapping moving cells onto reference cells.
    """
    rows, cols = reference.shape
    side = int(math.ceil(math.hypot(rows, cols))) + 4
    theta = math.radians(angle_deg)
    c, s = math.cos(theta), math.sin(theta)
    centre_m = np.array([side / 2.0 + shift[0], side / 2.0 + shift[1]])
    centre_r = np.array([cols / 2.0, rows / 2.0])
    t = centre_r - np.array([c * centre_m[0] - s * centre_m[1], s * centre_m[0] + c * centre_m[1]])
    true = RigidTransform(theta, t[0], t[1])
    out = cv2.warpAffine(
        (reference + 1).astype(np.uint8),
        true.matrix[:2],
        (side, side),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderValue=0,
    )
    return out.astype(np.int8) - 1, true


def error(found: RigidTransform, true: RigidTransform, moving: np.ndarray) -> tuple[float, float]:
    """(rotation error in degrees, largest displacement of a known moving cell in cells)."""
    rows, cols = np.nonzero(moving >= 0)
    pts = np.column_stack([cols, rows])[:: max(1, rows.size // 5000)]
    rot = abs(math.degrees(math.remainder(found.rotation - true.rotation, 2 * math.pi)))
    return rot, float(found.displacement(true, pts).max())


def bench(name: str, reference: np.ndarray, seed: int | None) -> None:
    moving, true = moved_copy(reference, 37.0, (5.0, -3.0))
    reg = RandomWalkRegistrar(seed=seed)
    prepared = reg.prepare_reference(reference)
    tables = scoring.subsample_tables(
        scoring.build_tables(moving, moving.size), reg.options.max_points
    )
    st = np.column_stack([np.linspace(-1, 1, 12), np.full(12, 50.0), np.full(12, 60.0)])
    arrays = _transform_arrays(st, tables.centroid)
    n = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < 1.0:
        scoring.score(prepared.tables, tables, *arrays, 1e-3)
        n += 12
    rate = n / (time.perf_counter() - t0)
    reports = []
    t0 = time.perf_counter()
    reg = RandomWalkRegistrar(seed=seed, progress=reports.append)
    prepared = reg.prepare_reference(reference)
    t_prep = time.perf_counter() - t0
    cands = reg.candidates(prepared, moving, 5)
    seconds = time.perf_counter() - t0
    last = reports[-1]
    rot, disp = error(cands[0].transform, true, moving)
    print(
        f"{name:>12} {reference.shape[1]:>4}x{reference.shape[0]:<4} "
        f"{rate:6.0f} eval/s | registration {seconds:6.2f} s (reference {t_prep:5.2f} s), "
        f"{last.evaluations:6d} evals, {last.step:4d} steps | rot err {rot:4.2f} deg, "
        f"max disp {disp:5.2f} cells, omega {cands[0].acceptance:.3f}",
        flush=True,
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", action="store_true", help="also the maps in tests/data")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--sizes", type=int, nargs="+", default=[300, 600, 1200, 2400])
    args = parser.parse_args(argv)
    for n in args.sizes:
        bench(f"rooms({n})", rooms(n), args.seed)
    if args.real:
        from brokenness.io import load_map

        data = Path(__file__).resolve().parents[1] / "tests" / "data"
        for stem in ("tb3_sandbox", "depot", "building_31"):
            m = load_map(data / f"{stem}.yaml")
            bench(stem, m.states, args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
