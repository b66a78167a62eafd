"""Negative controls: a map of one place against the reference of another must get no degree.

The pairs, their sources and how each map is made are described in ``benchmarks/cases.py``
(real map files, the Radish CARMEN logs mapped at 0.1 m, random walls, clutter, noise and
simulated buildings). Every map is first written as ROS YAML + PGM into
``benchmarks/results/controls/`` (once; kept as a cache) and loaded back with
:func:`brokenness.load_map`, then ``compute_brokenness(map, reference)`` runs through the
public API with its defaults. A control passes when the result is *not measured*
(``measured == False``, ``degree is None``); a degree on a control is a **false claim**.

Besides the controls, the pairs of two different real maps of *one* place (the two Willow
Garage maps, the Intel / ACES / CSAIL grids against the maps of their logs) are run and
listed apart: those should be measured (their degree is not known; the Willow SLAM map,
544 occupied cells, may honestly be too thin to measure).

Output: a table (pair, map cells, reference cells, measured, degree, largest share,
seconds) on stdout and ``benchmarks/results/negative_controls.json`` (``_quick.json`` with
``--quick``; ``--out``).

Run: ``python benchmarks/negative_controls.py [--quick] [--workers 2] [--max-seconds S]``
(``--method random-walk [--seed N]``: with the paper's baseline registration; results
then default to ``negative_controls[_quick]_rw.json``).
``--quick`` is a fixed subset of about 20 pairs; the full set is every pair of different
places (a few hundred); ``--real-only`` keeps the pairs of real maps and logs.
``--turn DEGREES`` turns every map by that angle about its centre and shifts it first
(:func:`cases.turned_map`, nearest neighbour): a map in a frame of its own at an angle no
quarter turn of the grid reaches, as a SLAM run that starts anywhere makes it (the maps as
stored are mostly axis-aligned with their references). ``--max-seconds`` caps the total
run: pairs not started by then are reported as skipped.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from cases import (  # noqa: E402
    ROOT,
    control_sources,
    negative_control_pairs,
    real_sources,
    same_place_pairs,
    save_control_maps,
    turned_map,
)

from brokenness import compute_brokenness, load_map  # noqa: E402
from brokenness.registration.methods import METHODS  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
CACHE = RESULTS / "controls"


def run_pair(
    job: tuple[str, str, str, str, str],
    method: str = "ifmi",
    seed: int | None = None,
    turn: float = 0.0,
) -> dict[str, Any]:
    """Load both maps from their YAML files and compute (``compute_brokenness(...,
    method=method, seed=seed)``), the map first turned by ``turn`` degrees and shifted
    (:func:`cases.turned_map`) unless ``turn`` is 0; one JSON-ready row."""
    group, name_map, name_ref, path_map, path_ref = job
    warnings.simplefilter("ignore")
    m, r = load_map(path_map), load_map(path_ref)
    if turn:
        m = turned_map(m, turn)
    row: dict[str, Any] = {
        "group": group,
        "pair": f"{name_map} vs {name_ref}",
        "map": name_map,
        "reference": name_ref,
        "map_cells": list(m.shape),
        "reference_cells": list(r.shape),
        "map_resolution": m.resolution,
        "reference_resolution": r.resolution,
        "turn": turn,
    }
    walks: list[Any] = []  # the random walk's last report of each walk
    extra: dict[str, Any] = {}
    if method == "random-walk":
        extra["registration_options"] = {"progress": lambda p: walks.append(p) if p.done else None}
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        res = compute_brokenness(m, r, method=method, seed=seed, **extra)
    except Exception as exc:  # a crash is recorded, not fatal to the run
        row.update(error=f"{type(exc).__name__}: {exc}", seconds=time.perf_counter() - t0)
        return row
    if method == "random-walk":
        from realistic import walk_usage

        row["walks"] = walk_usage(walks)
    row.update(
        measured=bool(res.measured),
        degree=res.degree,
        partitions=len(res.partitions),
        largest_share=float(res.largest_fraction),
        contradiction=res.contradiction,
        contradiction_bound=res.contradiction_bound,
        unassigned_share=float(res.unassigned_fraction),
        reason=res.reason,
        seconds=time.perf_counter() - t0,
        cpu_seconds=time.process_time() - c0,  # this worker's CPU time, all its threads
    )
    return row


def _cells(shape: list[int]) -> str:
    return f"{shape[1]}x{shape[0]}"


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown table of the rows (one line per pair)."""
    lines = [
        "| pair | map cells | reference cells | measured | degree | largest share | s | CPU s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['pair']} | | | error: {r['error']} | | | | |")
            continue
        if r.get("skipped"):
            lines.append(f"| {r['pair']} | | | skipped (time cap) | | | | |")
            continue
        deg = "-" if r["degree"] is None else str(r["degree"])
        lines.append(
            f"| {r['pair']} | {_cells(r['map_cells'])} | {_cells(r['reference_cells'])} "
            f"| {'yes' if r['measured'] else 'no'} | {deg} | {100 * r['largest_share']:.0f} % "
            f"| {r['seconds']:.2f} | {r.get('cpu_seconds', float('nan')):.2f} |"
        )
    return "\n".join(lines)


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Counts: controls run, false claims (measured), errors, skipped; same-place measured."""
    ctl = [r for r in rows if r["group"] == "control" and "measured" in r]
    same = [r for r in rows if r["group"] == "same place" and "measured" in r]
    by_kind: dict[str, list[int]] = {}
    for r in ctl:
        kind = r.get("kind", "")
        v = by_kind.setdefault(kind, [0, 0])
        v[0] += 1
        v[1] += int(r["measured"])
    return {
        "controls": len(ctl),
        "false_claims": sum(r["measured"] for r in ctl),
        "false_claims_by_kind": {k: {"pairs": v[0], "false": v[1]} for k, v in by_kind.items()},
        "errors": sum("error" in r for r in rows),
        "skipped": sum(bool(r.get("skipped")) for r in rows),
        "same_place": len(same),
        "same_place_measured": sum(r["measured"] for r in same),
        "median_seconds": float(np.median([r["seconds"] for r in ctl])) if ctl else None,
        "median_cpu_seconds": (float(np.median([r["cpu_seconds"] for r in ctl])) if ctl else None),
        "max_cpu_seconds": float(max(r["cpu_seconds"] for r in ctl)) if ctl else None,
        "total_compute_seconds": float(sum(r.get("seconds", 0.0) for r in rows)),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a fixed subset of about 20 pairs")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--max-seconds", type=float, default=1200.0, help="cap of the whole run")
    ap.add_argument(
        "--out", type=Path, default=None, help="default results/negative_controls[_quick].json"
    )
    ap.add_argument("--no-same-place", action="store_true", help="skip the same-place pairs")
    ap.add_argument("--method", choices=METHODS, default="ifmi", help="registration (default ifmi)")
    ap.add_argument(
        "--seed", type=int, default=None, help="seed of the random walk (default: its own)"
    )
    ap.add_argument(
        "--turn",
        type=float,
        default=0.0,
        metavar="DEGREES",
        help="turn every map by this angle about its centre (and shift it) first: maps in "
        "frames of their own (default 0: as stored)",
    )
    ap.add_argument("--real-only", action="store_true", help="only the pairs of real maps and logs")
    args = ap.parse_args(argv)
    if args.out is None:
        suffix = ("_quick" if args.quick else "") + ("" if args.method == "ifmi" else "_rw")
        args.out = RESULTS / f"negative_controls{suffix}.json"
    warnings.simplefilter("ignore")
    start = time.perf_counter()
    sources = control_sources()
    controls = negative_control_pairs(args.quick, sources)
    if args.real_only:
        real = set(real_sources(sources))
        controls = [p for p in controls if set(p) <= real]
    same = [] if args.no_same_place else same_place_pairs(sources)
    if args.quick:
        same = [p for p in same if p in (("willow_slam", "willow_stage"),)]
    names = sorted({n for p in controls + same for n in p})
    paths = save_control_maps(names, CACHE, sources)
    print(
        f"{len(controls)} controls, {len(same)} same-place pairs, {len(names)} maps "
        f"(cached in {CACHE.relative_to(ROOT)}; {time.perf_counter() - start:.1f} s)",
        flush=True,
    )
    jobs = [("control", a, b, str(paths[a]), str(paths[b])) for a, b in controls]
    jobs += [("same place", a, b, str(paths[a]), str(paths[b])) for a, b in same]
    rows: dict[int, dict[str, Any]] = {}
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        pending: dict[Future[dict[str, Any]], int] = {}
        queue = list(enumerate(jobs))
        while queue or pending:
            while queue and len(pending) < 2 * max(1, args.workers):
                i, job = queue.pop(0)
                if time.perf_counter() - start > args.max_seconds:
                    rows[i] = {
                        "group": job[0],
                        "pair": f"{job[1]} vs {job[2]}",
                        "map": job[1],
                        "reference": job[2],
                        "skipped": True,
                    }
                    continue
                pending[pool.submit(run_pair, job, args.method, args.seed, args.turn)] = i
            if not pending:
                continue
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                rows[pending.pop(f)] = f.result()
    ordered = [rows[i] for i in range(len(jobs))]
    for r in ordered:
        r["kind"] = f"{sources[r['map']].kind} vs {sources[r['reference']].kind}"
    ctl = [r for r in ordered if r["group"] == "control"]
    same_rows = [r for r in ordered if r["group"] == "same place"]
    print("\nNegative controls (must not be measured):\n")
    print(table(ctl))
    if same_rows:
        print("\nSame place, different maps (should be measured):\n")
        print(table(same_rows))
    s = summary(ordered)
    s["wall_seconds"] = time.perf_counter() - start
    s["workers"] = args.workers
    s["quick"] = args.quick
    s["method"] = args.method
    s["seed"] = args.seed
    s["turn"] = args.turn
    s["real_only"] = args.real_only
    print(
        f"\nfalse claims: {s['false_claims']} of {s['controls']} controls "
        f"(errors {s['errors']}, skipped {s['skipped']}); same place measured: "
        f"{s['same_place_measured']} of {s['same_place']}; wall {s['wall_seconds']:.0f} s "
        f"on {args.workers} worker(s)"
    )
    print("\n| map vs reference | pairs | false claims |\n|---|---|---|")
    for kind, v in sorted(s["false_claims_by_kind"].items()):
        print(f"| {kind} | {v['pairs']} | {v['false']} |")
    print(f"| all | {s['controls']} | {s['false_claims']} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        json.dumps({"summary": s, "rows": ordered}, indent=1, allow_nan=False) + "\n"
    )
    print(f"results: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
