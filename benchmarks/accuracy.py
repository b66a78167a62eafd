"""How often ``compute_brokenness`` finds the true degree, and the true partitions.

Two sets of simulated maps (``simulate_broken_map``, degrees 2-5, 20 seeds each): seeds
1000-1019, on which the settings were chosen, and seeds 0-19, held out. A map counts as
*exact* when the degree found is the expected one, and as *all true* when, besides, every
partition found is a distinct true one: the transform it was found with puts its cells
(median) within 3 cells of where the transform of the true partition most of them belong
to puts them. Also the broken building-31 cases of ``bench_compute.py`` (2 x 3 rectangles,
honest degree 4, and 3 x 2, degree 5) at four angles.

Run: ``python benchmarks/accuracy.py [--workers 2]`` (about a minute on 2 cores).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

from bench_compute import broken_case, fit, grid_regions  # noqa: E402

from brokenness import compute_brokenness, load_map, simulate_broken_map  # noqa: E402

SETS = {"seeds 1000-1019": range(1000, 1020), "seeds 0-19 (held out)": range(20)}
DEGREES = (2, 3, 4, 5)


def _all_true(result, sim) -> bool:
    used = set()
    for p in result.partitions:
        rows, cols = np.nonzero(result.labels == p.index)
        truth = sim.labels[rows, cols]
        truth = truth[truth >= 0]
        if truth.size == 0:
            return False
        q = int(np.bincount(truth).argmax())
        true_transform = next(t.transform for t in sim.partitions if t.index == q)
        pts = np.column_stack([cols, rows]).astype(float)
        if q in used or np.median(p.transform.displacement(true_transform, pts)) > 3.0:
            return False
        used.add(q)
    return True


def _one(job: tuple[int, int]) -> tuple[int, int, bool, bool, float]:
    warnings.simplefilter("ignore")
    seed, degree = job
    sim = simulate_broken_map(seed=seed, degree=degree)
    t0 = time.perf_counter()
    result = compute_brokenness(sim.map, sim.reference)
    seconds = time.perf_counter() - t0
    exact = result.degree == sim.expected_degree
    return seed, degree, exact, exact and _all_true(result, sim), seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    jobs = [(s, d) for seeds in SETS.values() for d in DEGREES for s in seeds]
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(_one, jobs))
    print("| set | exact (degrees 2, 3, 4, 5) | all true (degrees 2, 3, 4, 5) |")
    print("|---|---|---|")
    for name, seeds in SETS.items():
        mine = [r for r in results if r[0] in seeds]
        exact = [sum(r[2] for r in mine if r[1] == d) for d in DEGREES]
        true = [sum(r[3] for r in mine if r[1] == d) for d in DEGREES]
        print(
            f"| {name} | {', '.join(map(str, exact))} ({sum(exact)}/80) "
            f"| {', '.join(map(str, true))} ({sum(true)}/80) |"
        )
    print(
        f"\nsummed compute time of the {len(results)} maps: "
        f"{sum(r[4] for r in results):.1f} s ({args.workers} workers)\n"
    )

    ref = fit(load_map(ROOT / "tests" / "data" / "building_31.yaml"), 520)
    print("| building 31, 600x600 | 10 deg | 15 deg | 20 deg | 25 deg |")
    print("|---|---|---|---|---|")
    for rows, cols in ((2, 3), (3, 2)):
        cells = []
        for angle in (10.0, 15.0, 20.0, 25.0):
            m, expected = broken_case(ref, grid_regions(ref.shape, rows, cols), angle, pad=40)
            cells.append(f"{compute_brokenness(m, ref).degree} (expected {expected})")
        print(f"| {rows} x {cols} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
