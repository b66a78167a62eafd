"""Frame invariance: the same map in another grid frame gets the same degree and partitions.

A SLAM run starts anywhere, so the frame of a map's grid is arbitrary, and the degree must
not depend on it. Each case of ``realistic.py`` (read from its cache; missing cases are drawn
first, as that script draws them), and of ``drawn_buildings.py`` with ``--drawn-seeds``, is
computed through the public API with its map as it is, and in the other frames of
:mod:`brokenness.measure.frames` (the grid turned by 180, 90 and 270 degrees, exactly, and
shifted by unknown rows and columns). Each result is compared with the one in the map's
own frame:

- *status*: measured in both or in neither;
- *degree*: the same degree (or both not measured);
- *partitions*: as many partitions, matched one-to-one: the transform of one in the other
  frame, composed with the change of frame, puts the original partition's cells within
  :data:`SAME_PLACE` cells (median) of where the original's transform puts them (the
  tolerance of ``realistic.py``'s "all partitions true");
- *all true*: every true part found, as ``realistic.py`` counts it, in each frame.

The turned and shifted maps hold the same cells, so every difference comes from the
measure itself: the registration's pooled images and the tiles of the settle step are laid
on the grid, and ties are broken in the grid's order.

The same runs give what the option ``frames=k`` of :func:`brokenness.compute_brokenness`
gives (:func:`with_frames`: a map not measured in its own frame is not measured, one with no
partition in doubt keeps its own frame's result; else, of the first ``k`` frames' results
measured at the own frame's degree, the one that :func:`brokenness.measure.frames.best_of`
keeps): the second table, all partitions true and the exact degree for ``k = 1..5``.

``--controls`` runs the negative controls of ``negative_controls.py`` (``--quick``: its
subset of about 20) in every frame instead: the degrees claimed per frame and with
``frames=k``.

Usage::

    python benchmarks/frame_invariance.py --sets 0-2 --workers 2 [--drawn-seeds 8] [--out F]
    python benchmarks/frame_invariance.py --controls --workers 2 --out F  (about 50 minutes)

Output: the two tables per kind of case (simulated, real log, drawn), and a JSON file of
every case's outcomes (``benchmarks/results/frame_invariance.json`` unless ``--out``).
About 2.5 minutes a set on 2 cores (five computations a case).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import realistic  # noqa: E402

from brokenness import (  # noqa: E402
    BrokennessResult,
    RigidTransform,
    compute_brokenness,
    load_map,
)
from brokenness.measure import frames  # noqa: E402
from brokenness.measure.frames import in_frame  # noqa: E402

#: A partition in another frame is the same when it puts the original's cells within this
#: many cells (median) of where the original puts them: the tolerance of a true partition.
SAME_PLACE = realistic.TRUE_CELLS
#: The frames other than the map's own (``brokenness.measure.frames.FRAMES``: a half turn,
#: a quarter turn each way, then a shift).
FRAMES = frames.FRAMES[1:]


def same_partitions(
    original: BrokennessResult, other: BrokennessResult, cells: RigidTransform
) -> bool:
    """Whether ``other`` (of the map moved by ``cells``) holds ``original``'s partitions: the
    test of a true partition (``realistic.all_partitions_true``), ``original``'s partitions
    and labels taking the place of the true parts."""
    return realistic.all_partitions_true(
        [q.transform.compose(cells) for q in other.partitions],
        [p.transform for p in original.partitions],
        np.asarray(original.labels),
        SAME_PLACE,
    )


def _outcome(
    result: BrokennessResult,
    cells: RigidTransform,
    truths: list[RigidTransform],
    labels: np.ndarray,
) -> dict[str, Any]:
    """Status, degree and whether every true part is found (``labels`` and ``truths`` of
    the map in its own frame, ``cells`` the change of frame)."""
    found = [p.transform.compose(cells) for p in result.partitions]
    return {
        "measured": bool(result.measured),
        "degree": result.degree,
        "all_true": bool(result.measured) and realistic.all_partitions_true(found, truths, labels),
        "unassigned_cells": result.unassigned_cells,
        "contradiction": result.contradiction,
        "partitions": len(result.partitions),
        "in_doubt": frames.in_doubt(result),
    }


def evaluate(folder: str) -> dict[str, Any]:
    """One case in its own frame and in every frame of :data:`FRAMES`; its row."""
    warnings.simplefilter("ignore")
    path = Path(folder)
    truth = json.loads((path / "truth.json").read_text())
    labels = np.load(path / "labels.npy")
    truths = [RigidTransform.from_matrix(p["matrix"]) for p in truth["partitions"]]
    m, r = load_map(path / "map.yaml"), load_map(path / "reference.yaml")
    start = time.process_time()
    original = compute_brokenness(m, r)
    row: dict[str, Any] = {
        "case": path.name,
        "source": truth["case"]["source"],
        "expected_degree": truth["expected_degree"],
        "occupied_cells": original.occupied_cells,
        "own frame": _outcome(original, RigidTransform.identity(), truths, labels),
    }
    for frame in FRAMES:
        moved, cells = in_frame(m, frame)
        result = compute_brokenness(moved, r)
        row[frame] = {
            **_outcome(result, cells, truths, labels),
            "same_partitions": same_partitions(original, result, cells),
        }
    row["cpu_seconds"] = time.process_time() - start
    return row


def table(rows: list[dict[str, Any]]) -> str:
    """Per kind of case and frame: cases, the same status, degree and partitions as in
    the map's own frame, and every partition true (in the map's own frame in brackets)."""
    out = [
        "| cases | frame | n | same status | same degree | same partitions | all true |",
        "|---|---|---|---|---|---|---|",
    ]
    for kind in ("simulated", "real log", "plan"):
        sel = [r for r in rows if realistic.source_kind(r["source"]) == kind]
        own = sum(bool(r["own frame"]["all_true"]) for r in sel)
        for frame in FRAMES if sel else ():
            status = sum(r[frame]["measured"] == r["own frame"]["measured"] for r in sel)
            degree = sum(r[frame]["degree"] == r["own frame"]["degree"] for r in sel)
            same = sum(bool(r[frame]["same_partitions"]) for r in sel)
            true = sum(bool(r[frame]["all_true"]) for r in sel)
            out.append(
                f"| {kind} | {frame} | {len(sel)} | {status} | {degree} | {same} | {true} ({own}) |"
            )
    return "\n".join(out)


def with_frames(row: dict[str, Any], k: int) -> dict[str, Any]:
    """The outcome ``compute_brokenness(..., frames=k)`` gives: the map's own frame if it is
    not measured there or has no partition in doubt (:func:`brokenness.measure.frames.in_doubt`),
    else of the first ``k`` frames, the one :func:`brokenness.measure.frames.best_of` keeps
    (measured, at the own frame's degree). Since step 11 (session 38) every frame's result
    here went through the public API, so a map measured with a partition in doubt was
    replicated in each frame, where the library replicates only the own frame's: for those
    maps this can keep fewer frames than ``frames=k`` does."""
    own = row["own frame"]
    if not own["measured"] or not own.get("in_doubt", True):
        return dict(own)
    keys = ["own frame", *FRAMES][:k]
    results = [SimpleNamespace(**row[key]) for key in keys]
    return dict(row[keys[frames.best_of(results)]])  # type: ignore[arg-type]


def frames_table(rows: list[dict[str, Any]]) -> str:
    """Per kind of case: all partitions true and the exact degree with ``frames=k``."""
    ks = range(1, len(FRAMES) + 2)
    head = " | ".join(f"frames={k}" for k in ks)
    out = [f"| cases | n | {head} |", "|---|---|" + "---|" * len(ks)]
    for kind in ("simulated", "real log", "plan"):
        sel = [r for r in rows if realistic.source_kind(r["source"]) == kind]
        if not sel:
            continue
        cells = []
        for k in ks:
            chosen = [with_frames(r, k) for r in sel]
            true = sum(bool(c["all_true"]) for c in chosen)
            pairs = zip(chosen, sel, strict=True)
            exact = sum(c["degree"] == r["expected_degree"] for c, r in pairs)
            cells.append(f"{true}, {exact}")
        out.append(f"| {kind} (all true, exact) | {len(sel)} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def evaluate_control(job: tuple[str, str, str, str]) -> dict[str, Any]:
    """One negative control (map, reference names and files) in its own frame and in every
    frame of :data:`FRAMES`: each frame's status, degree, unassigned cells, contradiction."""
    warnings.simplefilter("ignore")
    name_map, name_ref, path_map, path_ref = job
    m, r = load_map(path_map), load_map(path_ref)
    row: dict[str, Any] = {"pair": f"{name_map} vs {name_ref}", "occupied_cells": m.n_occupied}
    for frame in frames.FRAMES:
        result = compute_brokenness(in_frame(m, frame)[0], r)
        row["own frame" if frame == "own" else frame] = {
            "measured": bool(result.measured),
            "degree": result.degree,
            "unassigned_cells": result.unassigned_cells,
            "contradiction": result.contradiction,
            "partitions": len(result.partitions),
        }
    return row


def controls_table(rows: list[dict[str, Any]]) -> str:
    """Degrees claimed on the negative controls, per frame and with ``frames=k``."""
    keys = ("own frame", *FRAMES)
    out = [
        "| controls | "
        + " | ".join(keys)
        + " | "
        + " | ".join(f"frames={k}" for k in range(1, len(keys) + 1))
        + " |",
        "|---|" + "---|" * (2 * len(keys)),
    ]
    per_frame = [sum(bool(r[key]["measured"]) for r in rows) for key in keys]
    with_k = [
        sum(bool(with_frames(r, k)["measured"]) for r in rows) for k in range(1, len(keys) + 1)
    ]
    out.append(f"| {len(rows)} claimed | " + " | ".join(map(str, per_frame + with_k)) + " |")
    return "\n".join(out)


def run_controls(args: argparse.Namespace) -> int:
    """``--controls``: the negative controls of ``negative_controls.py`` in every frame."""
    from cases import control_sources, negative_control_pairs, save_control_maps
    from negative_controls import CACHE as CONTROLS

    sources = control_sources()
    pairs = negative_control_pairs(args.quick, sources)
    paths = save_control_maps(sorted({n for p in pairs for n in p}), CONTROLS, sources)
    jobs = [(a, b, str(paths[a]), str(paths[b])) for a, b in pairs]
    start = time.perf_counter()
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        rows = list(pool.map(evaluate_control, jobs, chunksize=2))
    print(f"{len(rows)} controls, {time.perf_counter() - start:.0f} s")
    print(controls_table(rows))
    for r in rows:
        claimed = [k for k in ("own frame", *FRAMES) if r[k]["measured"]]
        if claimed:
            print(f"  {r['pair']}: " + ", ".join(f"{k}: {r[k]['degree']}" for k in claimed))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"controls": True, "rows": rows}, indent=1))
    print(f"results: {args.out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--sets", default="0", help="realistic sets (first seeds), e.g. 0 or 0-2; '' for none"
    )
    ap.add_argument("--cache", type=Path, default=realistic.CACHE)
    ap.add_argument("--drawn-seeds", type=int, default=0, help="drawn buildings too (seeds)")
    ap.add_argument("--drawn-cache", type=Path, default=realistic.RESULTS / "drawn")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=realistic.RESULTS / "frame_invariance.json")
    ap.add_argument(
        "--controls", action="store_true", help="the negative controls instead of the cases"
    )
    ap.add_argument("--quick", action="store_true", help="with --controls: about 20 pairs")
    args = ap.parse_args(argv)
    if args.controls:
        return run_controls(args)
    first, _, last = args.sets.partition("-")
    seeds = range(int(first), int(last or first) + 1) if args.sets else range(0)
    cases = [(c, str(args.cache)) for s in seeds for c in realistic.case_list(first_seed=s)]
    if args.drawn_seeds:
        from drawn_buildings import DRAWN

        drawn = realistic.case_list(logs=("none",), seeds=args.drawn_seeds, plans=tuple(DRAWN))
        cases += [(case, str(args.drawn_cache)) for case in drawn]
    start = time.perf_counter()
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        made = pool.map(realistic._generate_job, cases)
        folders = [folder for _, folder, _ in made if folder is not None]
        rows = list(pool.map(evaluate, folders, chunksize=2))
    print(f"{len(rows)} cases, {time.perf_counter() - start:.0f} s")
    print(table(rows))
    print(frames_table(rows))
    for r in rows:  # the cases whose partitions differ in some frame
        changed = [f for f in FRAMES if not r[f]["same_partitions"]]
        if changed:
            own = r["own frame"]["degree"]
            print(
                f"  {r['case']}: degree {own}; "
                + ", ".join(f"{f}: {r[f]['degree']}" for f in changed)
            )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"sets": args.sets, "rows": rows}, indent=1))
    print(f"results: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
