"""Fresh negative controls: simulated buildings that no rule of the measure was chosen on.

``negative_controls.py`` runs simulated buildings 201-204 against each other, and those
pairs were looked at while the rules of the measure were chosen (README, Benchmarks): a
claim-free run on them says less about a building never seen. This script draws buildings
of the same generator with other seeds (206-213 by default; 205 is a control of
``negative_controls.py``) and runs, through the public API with its defaults:

- every ordered pair of two different seeds, the unbroken map of one against the true-pose
  reference of the other (the two share the generator's shell and grid of rooms: the
  nearest kind of control the project has);
- the map of each seed broken by 4 bumps against the reference of the next seed;

each in the five grid frames of :mod:`brokenness.measure.frames` (the map as it is, turned
by 180, 90 and 270 degrees, shifted). A degree on any of them is a **false claim**.

Run: ``python benchmarks/fresh_controls.py [--seeds 206-213] [--workers 2] [--out F]``
(about 15 minutes on 2 cores with the default seeds). Output: the claims on stdout, a
table of claims per frame, and ``benchmarks/results/fresh_controls.json`` (every run: seeds,
frame, measured, degree, the replication's degree, the reason, seconds) unless ``--out``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from cases import simulated_map, simulated_reference

from brokenness import compute_brokenness
from brokenness.measure.frames import FRAMES, in_frame

RESULTS = Path(__file__).resolve().parent / "results"
#: The broken maps' degree (each against the next seed's reference).
BROKEN_DEGREE = 4

Job = tuple[int, int, int, str]  # map seed, map degree, reference seed, frame


def jobs(seeds: list[int]) -> list[Job]:
    """Every run, in a fixed order: the unbroken pairs, then the broken maps; each in
    every frame."""
    out = [(a, 0, b, f) for a in seeds for b in seeds if a != b for f in FRAMES]
    nxt = {a: seeds[(i + 1) % len(seeds)] for i, a in enumerate(seeds)}
    out += [(a, BROKEN_DEGREE, nxt[a], f) for a in seeds for f in FRAMES]
    return out


def run(job: Job) -> dict[str, Any]:
    """One run: the map of seed ``a`` (degree ``da``) in ``frame`` against the reference of
    seed ``b``; one JSON-ready row."""
    a, da, b, frame = job
    warnings.simplefilter("ignore")
    m, reference = simulated_map(a, da), simulated_reference(b)  # cached in each worker
    moved, _ = in_frame(m, frame)
    t0 = time.perf_counter()
    r = compute_brokenness(moved, reference)
    return {
        "map_seed": a,
        "map_degree": da,
        "reference_seed": b,
        "frame": frame,
        "measured": bool(r.measured),
        "degree": r.degree,
        "replication_degree": r.parameters.get("replication_degree"),
        "contradiction": r.contradiction,
        "contradiction_bound": r.contradiction_bound,
        "reason": r.reason,
        "seconds": time.perf_counter() - t0,
    }


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    seeds = list(range(int(lo), int(hi or lo) + 1))
    if len(seeds) < 2:
        raise SystemExit("--seeds needs at least two seeds (as 206-213)")
    return seeds


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=_seeds, default=_seeds("206-213"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "fresh_controls.json")
    args = ap.parse_args(argv)
    todo = jobs(args.seeds)
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(args.workers) as pool:
        for row in pool.map(run, todo):
            rows.append(row)
            if row["measured"]:
                print(
                    f"claim: map {row['map_seed']} (degree {row['map_degree']}) against "
                    f"{row['reference_seed']}, {row['frame']}: degree {row['degree']}",
                    flush=True,
                )
    claims = Counter(r["frame"] for r in rows if r["measured"])
    runs = Counter(r["frame"] for r in rows)
    print("\n| frame | runs | claimed |\n|---|---|---|")
    for frame in FRAMES:
        print(f"| {frame} | {runs[frame]} | {claims[frame]} |")
    print(f"| all | {len(rows)} | {sum(claims.values())} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"seeds": args.seeds, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
