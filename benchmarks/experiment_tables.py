"""The paper's Tables I and II, redone: expected vs computed degree and time, per method.

Two sets, as in Birk (2010), section IV:

- **R1**: a seeded synthetic building explored by the simulated robot; the reference and
  broken versions with 1..5 bumps (the paper used USARSim maps of degree 0..5);
- **R2**: a real laser log with SLAM-corrected poses (Radish, via ``../shared/data``, intel by
  default; the small orebro log bundled in ``tests/data/carmen`` when ``../shared`` is
  absent), mapped at 0.1 m, and broken versions with 1..3 bumps injected into the pose chain
  (the paper used ap_hill_07b, degree 0..3).

Each map is measured against its reference with every registration method of the project
(iFMI, the paper's method, and the random-walk map merging baseline, "BCMM"): computed degree
and wall-clock seconds, like the paper's ``n_comp``, ``t_BCMM`` and ``t_iFMI`` columns.
``--grid-walk`` adds the random walk without the spectral start poses (coarse grid starts
only), to show what the pure stochastic search finds. With
``--seeds N`` it also reports, per expected degree, how often iFMI finds it exactly over N
simulated maps (the random walk is too slow for that many).

Run::

    python benchmarks/experiment_tables.py [--out out/experiments] [--seed 0] [--seeds 20]
        [--no-random-walk] [--grid-walk] [--log PATH]

Writes ``tables.md`` and ``tables.csv`` (and the maps, as ROS YAML + PGM with their ground
truth, under ``--out``); prints the Markdown.
"""

from __future__ import annotations

import argparse
import csv
import io
import time
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from brokenness import compute_brokenness
from brokenness.registration.methods import METHODS
from brokenness.simulation import save_simulation, simulate_broken_map
from brokenness.simulation.carmen import broken_log_map, read_carmen

ROOT = Path(__file__).resolve().parents[1]
SHARED_LOGS = ROOT.parent / "shared" / "data" / "radish-corrected-carmen-logs"
BUNDLED_LOG = ROOT / "tests" / "data" / "carmen" / "orebro-corrected.log.gz"


#: Column label -> (method, registration options). "random-walk (grid)" is the pure
#: stochastic search: start poses from the coarse grid only, no spectral hints.
VARIANTS: dict[str, tuple[str, dict[str, object]]] = {
    "ifmi": ("ifmi", {}),
    "random-walk": ("random-walk", {}),
    "random-walk (grid)": ("random-walk", {"spectral_starts": 0}),
}


def _run(sim, methods: Iterable[str], seed: int) -> dict[str, tuple[int, float]]:
    out = {}
    for label in methods:
        method, options = VARIANTS[label]
        t0 = time.perf_counter()
        result = compute_brokenness(
            sim.map, sim.reference, method=method, seed=seed, registration_options=options
        )
        out[label] = (result.degree, time.perf_counter() - t0)
    return out


def _rows(name: str, sims, methods, seed: int, out_dir: Path) -> list[dict[str, object]]:
    rows = []
    for i, sim in enumerate(sims):
        label = f"{name} ({'reference' if i == 0 else f'M{i}'})"
        save_simulation(sim, out_dir, f"{name}_{i}")
        row: dict[str, object] = {"map": label, "expected": sim.expected_degree}
        for method, (degree, seconds) in _run(sim, methods, seed).items():
            row[f"n_comp {method}"] = degree
            row[f"t_{method} (s)"] = round(seconds, 3)
        rows.append(row)
        print(f"  {label}: {row}", flush=True)
    return rows


def _markdown(rows: list[dict[str, object]]) -> str:
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(str(r[k]) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def _csv(rows: list[dict[str, object]]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def _pass_rates(n_seeds: int) -> str:
    lines = ["| expected degree | exact | within 1 | median s (iFMI) |", "|---|---|---|---|"]
    for degree in range(6):
        found, times = [], []
        for seed in range(n_seeds):
            sim = simulate_broken_map(seed=1000 + seed, degree=degree)
            t0 = time.perf_counter()
            found.append(compute_brokenness(sim.map, sim.reference).degree - sim.expected_degree)
            times.append(time.perf_counter() - t0)
        err = np.abs(np.array(found))
        lines.append(
            f"| {degree} | {np.count_nonzero(err == 0)}/{n_seeds} "
            f"| {np.count_nonzero(err <= 1)}/{n_seeds} | {np.median(times):.2f} |"
        )
        print(lines[-1], flush=True)
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "experiments")
    parser.add_argument("--seed", type=int, default=0, help="seed of the two sets")
    parser.add_argument("--seeds", type=int, default=0, help="also the iFMI pass rate over N maps")
    parser.add_argument("--no-random-walk", action="store_true", help="iFMI only (fast)")
    parser.add_argument("--log", type=Path, default=None, help="CARMEN log of set R2")
    parser.add_argument(
        "--grid-walk",
        action="store_true",
        help="also the random walk without spectral start poses (slower)",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    methods = ["ifmi"] if args.no_random_walk else list(METHODS)
    if args.grid_walk:
        methods.append("random-walk (grid)")
    args.out.mkdir(parents=True, exist_ok=True)

    print("set R1: synthetic building, degrees 0..5", flush=True)
    r1 = [simulate_broken_map(seed=args.seed, degree=k) for k in range(6)]
    rows1 = _rows("R1", r1, methods, args.seed, args.out)

    log_path = args.log or (
        SHARED_LOGS / "intel-corrected.log.gz" if SHARED_LOGS.exists() else BUNDLED_LOG
    )
    print(f"set R2: {log_path.name}, degrees 0..3", flush=True)
    log = read_carmen(log_path)
    r2 = [broken_log_map(log, seed=args.seed, degree=k, resolution=0.1) for k in range(4)]
    rows2 = _rows("R2", r2, methods, args.seed, args.out)

    text = (
        f"Table I (R1: synthetic building, seed {args.seed})\n\n{_markdown(rows1)}\n\n"
        f"Table II (R2: {log_path.name} at 0.1 m, seed {args.seed})\n\n{_markdown(rows2)}\n"
    )
    if args.seeds:
        text += f"\niFMI over {args.seeds} simulated maps per degree\n\n{_pass_rates(args.seeds)}\n"
    (args.out / "tables.md").write_text(text)
    (args.out / "tables.csv").write_text(_csv(rows1 + rows2))
    print()
    print(text)


if __name__ == "__main__":
    main()
