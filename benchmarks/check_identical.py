"""Same results, bit for bit: every field of ``compute_brokenness`` on a fixed set of maps.

Runs :func:`brokenness.compute_brokenness` on

- the bundled example pair (``examples/broken_building_31.yaml`` against ``building_31.yaml``);
- the test data: each bundled map against itself, the negative controls and the broken
  Orebro log maps of ``tests/_controls.py``;
- the maps of ``bench_scale.py`` at 1000² for degrees 0-8 and at 2000² for degrees 2, 5, 8;
- a handful of cached realistic cases (``benchmarks/results/realistic/<case>/{map,reference}
  .yaml``, read in place, from this checkout or the main one beside it), when present;

and writes one JSON object per case with every field of the result: the degree, whether it was
measured and why not, the contradiction, the cells, each partition's transform, cells,
confidence, offsets and contradiction, and a SHA-256 of the label image. Floats are written
with :meth:`float.hex`, so two files are equal only if the results are equal bit for bit.
Timings (``seconds``, ``step_seconds``) are left out.

Run: ``python benchmarks/check_identical.py --out new.json [--against base.json]``
(``--quick`` leaves out the 2000² maps and the realistic cases; ``--stats`` adds the figures
of the result file's ``stats.json``, Psi among them, and the SHA-256 of its bytes). With
``--against`` it lists every field that differs and exits with status 1 if any does.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "tests"))

from brokenness import BrokennessResult, OccupancyMap, compute_brokenness, load_map  # noqa: E402

#: cached realistic cases (a few per kind of building and degree), when present
REALISTIC = (
    "aces_d3_s0",
    "csail_d6_s0",
    "fhw_d8_s1",
    "intel_d5_s1",
    "freiburg-079_d7_s0",
    "orebro_d2_s1",
    "seattle_d4_s0",
    "sim_d8_s10",
)

Pair = tuple[OccupancyMap, OccupancyMap]


def _plain(value: Any) -> Any:
    """``value`` as JSON with every float as its hex string."""
    if isinstance(value, float):
        return value.hex()
    if isinstance(value, np.floating):
        return float(value).hex()
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def record(result: BrokennessResult) -> dict[str, Any]:
    """Every field of ``result`` but the timings."""
    labels = np.ascontiguousarray(result.labels)
    parts = []
    for p in result.partitions:
        d = p.to_dict()
        d.pop("step_seconds")
        parts.append(d)
    params = dict(result.parameters)
    return _plain(
        {
            "degree": result.degree,
            "measured": result.measured,
            "reason": result.reason,
            "contradiction": result.contradiction,
            "occupied_cells": result.occupied_cells,
            "unassigned_cells": result.unassigned_cells,
            "method": result.method,
            "parameters": params,
            "labels": f"{labels.dtype}{labels.shape}:"
            + hashlib.sha256(labels.tobytes()).hexdigest(),
            "partitions": parts,
        }
    )


def stats_record(result: BrokennessResult, m: OccupancyMap, ref: OccupancyMap) -> dict[str, Any]:
    """What a result file adds to the result: every figure of its ``stats.json`` (Psi of
    the map and of the repaired map...) and the SHA-256 of its exact bytes."""
    from brokenness.report.results import _dumps, build_stats

    stats = build_stats(result, m, ref)
    return {
        "stats_json": hashlib.sha256(_dumps(stats)).hexdigest(),
        "stats": _plain({k: stats[k] for k in ("psi_map", "psi_repaired", "map", "reference")}),
    }


def _realistic_root() -> Path | None:
    for root in (
        HERE / "results" / "realistic",
        ROOT.parent / "main" / "benchmarks" / "results" / "realistic",
    ):
        if root.is_dir():
            return root
    return None


def cases(quick: bool) -> Iterator[tuple[str, Callable[[], Pair]]]:
    """(name, builder of the pair) for every case of the set."""
    ex = ROOT / "examples"
    yield (
        "example",
        lambda: (
            load_map(ex / "broken_building_31.yaml"),
            load_map(ex / "building_31.yaml"),
        ),
    )
    data = ROOT / "tests" / "data"
    for name in ("building_31", "depot", "tb3_sandbox", "willow-2010-02-18-0.10"):

        def itself(name: str = name) -> Pair:
            m = load_map(data / f"{name}.yaml")
            return m, m

        yield f"itself:{name}", itself
    import _controls

    for c in _controls.negative_controls():
        yield f"control:{c.name}", lambda c=c: (c.map, c.reference)
    for b in _controls.broken_real_log_maps():
        yield f"orebro:{b.name}", lambda b=b: (b.map, b.reference)
    import bench_scale

    base = bench_scale.willow()
    sizes = [(1000, d) for d in range(9)]
    if not quick:
        sizes += [(2000, d) for d in (2, 5, 8)]
    for size, degree in sizes:

        def scale(size: int = size, degree: int = degree) -> Pair:
            m, ref, _ = bench_scale.make_case(base, size, degree)
            return m, ref

        yield f"scale:{size}:{degree}", scale
    root = _realistic_root()
    if root is not None and not quick:
        for name in REALISTIC:
            folder = root / name
            if (folder / "map.yaml").exists():
                yield (
                    f"realistic:{name}",
                    lambda f=folder: (
                        load_map(f / "map.yaml"),
                        load_map(f / "reference.yaml"),
                    ),
                )


def compare(new: dict[str, Any], old: dict[str, Any]) -> list[str]:
    """Every path at which ``new`` and ``old`` differ."""
    out: list[str] = []

    def walk(a: Any, b: Any, path: str) -> None:
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b)):
                if k not in a or k not in b:
                    out.append(f"{path}.{k}: only in {'new' if k in a else 'old'}")
                else:
                    walk(a[k], b[k], f"{path}.{k}")
        elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            for i, (x, y) in enumerate(zip(a, b, strict=True)):
                walk(x, y, f"{path}[{i}]")
        elif a != b:
            out.append(f"{path}: {b!r} -> {a!r}")

    walk(new, old, "")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="JSON file to write")
    parser.add_argument("--against", help="an earlier JSON to compare with")
    parser.add_argument("--quick", action="store_true", help="the small cases only")
    parser.add_argument("--only", help="run the cases whose name contains this")
    parser.add_argument(
        "--stats",
        action="store_true",
        help="also the figures of the result file's stats.json (Psi...) and its SHA-256",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    results: dict[str, Any] = {}
    t_all = time.perf_counter()
    for name, build in cases(args.quick):
        if args.only and args.only not in name:
            continue
        m, ref = build()
        t0 = time.perf_counter()
        result = compute_brokenness(m, ref)
        results[name] = record(result)
        if args.stats:
            results[name].update(stats_record(result, m, ref))
        print(
            f"{name}: degree {results[name]['degree']} ({time.perf_counter() - t0:.2f} s)",
            flush=True,
        )
    Path(args.out).write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")
    print(f"{len(results)} cases in {time.perf_counter() - t_all:.1f} s -> {args.out}")
    if args.against:
        old = json.loads(Path(args.against).read_text())
        if args.only or args.quick:
            old = {k: v for k, v in old.items() if k in results}
        diffs = compare(results, old)
        for d in diffs:
            print("DIFF", d)
        print(f"{len(diffs)} difference(s) against {args.against}")
        if diffs:
            sys.exit(1)


if __name__ == "__main__":
    main()
