"""Why a true broken map is refused by its free space: the transforms, or the membership?

The measure refuses a map whose free space crosses the reference's walls at more than half
the chance rate (README step 9). Some heavily broken simulated maps are refused although
every partition found is true (its transform within 3 cells of a true part's). The free
space is given to the partition of its nearest wall, so it depends on which partition holds
each wall cell (the membership) as well as on the transforms. This script tells the two
apart: for each case given, the map's free-space ratio to chance and its upper bound at the
stopping rule's ``z`` (6), with

- ``found``: the partitions found (their transforms and their cells), as the measure judged;
- ``true members``: the found transforms, each true part's cells held by the found partition
  nearest its true transform (median displacement of its cells): a membership without
  errors, the same transforms;
- ``truth``: the true parts with their true transforms;

and the share of the assigned cells held by another partition than their true part's.
Cases whose map and reference have different resolutions are skipped (the measure works on
a resampled grid then).

Run: ``python benchmarks/free_space_membership.py --results R.json --cache DIR`` (every
simulated case of a ``realistic.py`` run that was refused on its free space with every
partition true), or ``... --cases DIR [DIR ...]`` for case folders of a ``realistic.py``
cache.
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import numpy as np

from brokenness import RigidTransform, compute_brokenness, load_map
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.evidence import ClearFree, contradiction
from brokenness.measure.partitions import Found

#: The stopping rule's ``z`` (``BrokennessOptions.significance``'s default).
Z = 6.0


def _judged(
    transforms: list[RigidTransform],
    labels: np.ndarray,
    points: np.ndarray,
    clear: ClearFree,
    index: ReferenceIndex,
) -> tuple[float, float]:
    found = [Found(t, np.flatnonzero(labels == i), 1.0, 0.0) for i, t in enumerate(transforms)]
    c = contradiction(found, points, clear, index)
    return float(c.ratio() or 0.0), float(c.upper_ratio(Z))


def diagnose(folder: Path) -> dict[str, object] | None:
    """The three ratios of one case folder (``None`` if its resolutions differ)."""
    warnings.simplefilter("ignore")
    m, r = load_map(folder / "map.yaml"), load_map(folder / "reference.yaml")
    if m.resolution != r.resolution:
        return None
    truth = json.loads((folder / "truth.json").read_text())
    true_labels = np.load(folder / "labels.npy")
    result = compute_brokenness(m, r)
    points = cell_points(m.occupied)
    x, y = points[:, 0].astype(np.intp), points[:, 1].astype(np.intp)
    index = ReferenceIndex.build(r)
    clear = ClearFree(m, float(result.parameters["working_threshold"]))
    found = [p.transform for p in result.partitions]
    found_of = result.labels[y, x]
    truth_of = true_labels[y, x]
    true_transforms = [RigidTransform.from_matrix(p["matrix"]) for p in truth["partitions"]]
    # each true part's cells to the found partition nearest its true transform
    nearest = {}
    for q, tq in enumerate(true_transforms):
        mine = points[truth_of == q]
        if mine.size and found:
            moved = [float(np.median(t.displacement(tq, mine))) for t in found]
            nearest[q] = int(np.argmin(moved))
    members = np.array([nearest.get(int(q), -1) for q in truth_of], dtype=np.int64)
    assigned = found_of >= 0
    other = assigned & (found_of != members)
    return {
        "case": folder.name,
        "measured": result.measured,
        "degree": result.degree,
        "expected": truth["expected_degree"],
        "found": _judged(found, found_of, points, clear, index),
        "true members": _judged(found, members, points, clear, index),
        "truth": _judged(true_transforms, truth_of, points, clear, index),
        "held by another partition": float(other.sum() / max(assigned.sum(), 1)),
    }


def refused_all_true(results: Path, cache: Path) -> list[Path]:
    """The simulated cases of a ``realistic.py`` run refused on their free space with every
    partition found true."""
    rows = json.loads(results.read_text())["rows"]
    return [
        cache / row["case"]
        for row in rows
        if row["case"].startswith("sim")
        and not row["measured"]
        and "free space" in (row.get("reason") or "")
        and row.get("partitions_true")
    ]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, help="a realistic.py results JSON")
    ap.add_argument("--cache", type=Path, help="its case cache")
    ap.add_argument("--cases", type=Path, nargs="*", default=[], help="case folders")
    args = ap.parse_args(argv)
    folders = list(args.cases)
    if args.results is not None:
        if args.cache is None:
            ap.error("--results needs --cache")
        folders += refused_all_true(args.results, args.cache)
    print("| case | degree (expected) | found | true members | truth | cells held by another |")
    print("|---|---|---|---|---|---|")
    for folder in folders:
        row = diagnose(folder)
        if row is None:
            print(f"| {folder.name} | (resolutions differ: skipped) | | | | |")
            continue
        ratios = [row[k] for k in ("found", "true members", "truth")]
        cells = " | ".join(f"{a:.3f} ({b:.3f})" for a, b in ratios)  # type: ignore[misc]
        print(
            f"| {row['case']} | {row['degree']} ({row['expected']}) | {cells} "
            f"| {row['held by another partition']:.0%} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
