"""Partial overlap: broken maps that extend past their reference.

A map and its reference need not cover the same area: the floor plan leaves out a wing that
the robot explored, or the reference run went less far. The map's cells beyond the
reference are evidence of nothing, and must not come out as partitions.

Every case of the realistic benchmark (``realistic.py``; generated into its cache when
missing: ``--seeds``, ``--first-seed``, ``--logs``, ``--degrees`` as there) is measured
against its reference *cropped*: a band along one side of the reference's grid removed, so
that ``keep`` of its extent across that side is left (``--keep 0.6,0.8``; the side follows from
the case's name, deterministically). The cropped reference is written as ROS YAML + PGM beside
the case (``reference_keep<k>_<side>.yaml``) and the pair runs through the public API as
``realistic.py`` runs its cases. A true part is *visible* when at least 5 % of the map's
occupied cells (the benchmark's smallest part) land on known cells of the cropped reference
under its true transform. Per case:

* **spurious**: a partition found that fits no true part (within 3 reference cells, median,
  of where the part's true transform puts the part's cells), a partition made of cells beyond
  the reference;
* **too many**: a degree over the visible parts' count less one;
* **visible all true**: as many partitions as visible parts, matched one to one, each fitting
  its part (``realistic.py``'s "all partitions true" over the visible parts);
* not measured.

Run: ``python benchmarks/partial_reference.py --workers 2`` (seed 0: 126 cases, two crops
each); ``--out`` for the rows (default ``results/partial_reference.json``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
import zlib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import realistic  # noqa: E402

from brokenness import (  # noqa: E402
    UNKNOWN,
    OccupancyMap,
    RigidTransform,
    compute_brokenness,
    load_map,
    save_map,
)
from brokenness.masking import cell_points  # noqa: E402

SIDES = ("left", "right", "top", "bottom")


def crop_reference(
    reference: OccupancyMap, keep: float, side: str
) -> tuple[OccupancyMap, int, int]:
    """``reference`` with a band along ``side`` removed, ``keep`` of its extent across that
    side left; and ``(col0, row0)``, the cell of the original grid at the crop's top-left."""
    rows, cols = reference.shape
    r0, r1, c0, c1 = 0, rows, 0, cols
    if side == "left":
        c0 = cols - round(keep * cols)
    elif side == "right":
        c1 = round(keep * cols)
    elif side == "top":
        r0 = rows - round(keep * rows)
    else:
        r1 = round(keep * rows)
    x, y, yaw = reference.origin
    if yaw != 0.0:
        raise ValueError("a reference with a turned origin is not cropped here")
    res = reference.resolution
    cropped = OccupancyMap(
        np.ascontiguousarray(reference.states[r0:r1, c0:c1]),
        res,
        (x + c0 * res, y + (rows - r1) * res, 0.0),
    )
    return cropped, c0, r0


def evaluate(job: tuple[str, float]) -> dict[str, Any]:
    """One case against its reference cropped to ``keep``; its row."""
    warnings.simplefilter("ignore")
    folder, keep = Path(job[0]), job[1]
    truth = json.loads((folder / "truth.json").read_text())
    labels = np.load(folder / "labels.npy")
    side = SIDES[zlib.crc32(folder.name.encode()) % len(SIDES)]
    reference, c0, r0 = crop_reference(load_map(folder / "reference.yaml"), keep, side)
    path = folder / f"reference_keep{round(100 * keep)}_{side}.yaml"
    save_map(reference, path)
    shift = RigidTransform(0.0, -float(c0), -float(r0))  # original reference cells -> cropped
    truths = [shift.compose(RigidTransform.from_matrix(p["matrix"])) for p in truth["partitions"]]
    h, w = reference.shape
    n_cells = int(np.count_nonzero(labels >= 0))
    visible = []
    for q, tq in enumerate(truths):
        at = np.rint(tq.apply(cell_points(labels == q))).astype(np.intp)
        x, y = at[:, 0], at[:, 1]
        inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        seen = np.count_nonzero(reference.states[y[inside], x[inside]] != UNKNOWN)
        visible.append(seen >= realistic.MIN_SHARE * n_cells)
    row: dict[str, Any] = {
        "case": folder.name,
        "kind": realistic.source_kind(truth["case"]["source"]),
        "keep": keep,
        "side": side,
        "expected_degree": truth["expected_degree"],
        "visible_parts": int(sum(visible)),
    }
    t0 = time.perf_counter()
    res = compute_brokenness(load_map(folder / "map.yaml"), load_map(path))
    found = [p.transform for p in res.partitions]
    fits = realistic.partition_fits(found, truths, labels)
    seen_fits = fits[:, np.asarray(visible, dtype=bool)]
    matched = (
        bool(res.measured) and len(found) == seen_fits.shape[1] and realistic.one_to_one(seen_fits)
    )
    row.update(
        seconds=time.perf_counter() - t0,
        measured=bool(res.measured),
        degree=res.degree,
        partitions=len(found),
        spurious=bool(res.measured) and bool((~fits.any(axis=1)).any()),
        too_many=bool(res.measured) and len(found) > max(1, int(sum(visible))),
        visible_all_true=matched,
        unassigned_share=float(res.unassigned_fraction),
    )
    return row


def table(rows: list[dict[str, Any]]) -> str:
    """Counts per kind and kept share."""
    lines = [
        "| kind | keep | cases | measured | spurious partition | too many | visible all true |",
        "|---|---|---|---|---|---|---|",
    ]
    for kind in sorted({r["kind"] for r in rows}):
        for keep in sorted({r["keep"] for r in rows}):
            sel = [r for r in rows if r["kind"] == kind and r["keep"] == keep]
            if not sel:
                continue
            count = {k: sum(bool(r[k]) for r in sel) for k in ("measured", "spurious", "too_many")}
            true = sum(r["visible_all_true"] for r in sel)
            lines.append(
                f"| {kind} | {keep:g} | {len(sel)} | {count['measured']} | {count['spurious']} "
                f"| {count['too_many']} | {true} |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--keep", type=str, default="0.6,0.8", help="shares of the extent kept")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--logs", type=str, default=None, help="e.g. intel,aces,sim")
    ap.add_argument("--degrees", type=str, default=None, help="e.g. 0,3,8")
    ap.add_argument("--cache", type=Path, default=realistic.CACHE)
    ap.add_argument("--out", type=Path, default=realistic.RESULTS / "partial_reference.json")
    args = ap.parse_args(argv)
    keeps = [float(k) for k in args.keep.split(",")]
    if not all(0.0 < k < 1.0 for k in keeps):
        ap.error("--keep: shares between 0 and 1")
    cases = realistic.case_list(
        degrees=tuple(int(d) for d in args.degrees.split(",")) if args.degrees else None,
        seeds=args.seeds,
        logs=tuple(args.logs.split(",")) if args.logs else None,
        first_seed=args.first_seed,
    )
    workers = max(1, args.workers)
    with ProcessPoolExecutor(workers) as pool:
        made = list(pool.map(realistic._generate_job, [(c, str(args.cache)) for c in cases]))
        folders = [f for _, f, _ in made if f is not None]
        rows = list(pool.map(evaluate, [(f, k) for f in folders for k in keeps]))
    print(table(rows))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"rows": rows}, indent=1, allow_nan=False) + "\n")
    print(f"results: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
