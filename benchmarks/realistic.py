"""A benchmark that looks like real use: broken maps as users have them, degrees 0-8.

Cases come from the eight Radish CARMEN logs with corrected poses
(``../shared/data/radish-corrected-carmen-logs/``; only the bundled Orebro log without it) and
from simulated buildings (:mod:`brokenness.simulation`). A case is ``(source, degree, seed)``;
everything else follows from it deterministically (``numpy.random.default_rng`` seeded with
the source's CRC-32, the seed, the degree and the attempt number):

1. **The run.** A log: its scans and corrected poses, 15 m mapping range (freiburg-079: every
   4th of its 4791 scans). A simulated building: ``generate_building(3000 + seed)`` of
   U[18, 30] x U[18, 30] m, explored by the default laser (181 beams, 270 degrees, 8 m), a
   scan every 0.4 m, with small pose noise.
2. **Resolutions.** Map and reference at 0.05 m in two thirds of the cases; in the others
   one at 0.05 m and the other at 0.1 m (both ways, alternating).
3. **The reference.** The run mapped with its true poses (the box of what it saw plus
   0.5 m), or, for a third of the simulated cases, the building's plan
   (:func:`brokenness.simulation.plan_map`: every wall and clutter object, seen or not).
4. **Bumps** after the paper's model: ``degree`` bumps spread over the run (jittered),
   ``theta ~ U[0, 2 pi)``, ``d ~ U[0, 1 m]`` in a uniform direction; each bump is a pure
   shift (``theta = 0``) with probability 1/4. The draw is kept only if every partition
   counts by the simulator's honest rule (:mod:`brokenness.simulation.ground_truth`) with a
   5 % minimum share, every partition's cells move by at least 0.5 m on average between
   its transform and every other partition's (clearly off), and, in the final map, every
   partition still holds at least 5 % of the occupied cells; otherwise the case is redrawn
   (attempt 1, 2, ... up to 100).
5. **The map in its own frame**: the bumped run drawn in a frame turned by U[0, 2 pi) and
   shifted by U[-30, 30] m per axis (the SLAM run started anywhere;
   :func:`brokenness.simulation.map_in_frame`), on a grid cropped to what it saw, three-state
   (free by ray casting, unknown elsewhere).
6. **Files.** Map and reference are written as ROS YAML + PGM into
   ``benchmarks/results/realistic/<case>/`` (``--cache``) with ``truth.json`` (expected
   degree, bumps, frame, each partition's transform *map cell -> reference cell of the
   files as loaded*, i.e. with the own-frame turn and the resolution change, as a 3x3
   matrix and in the ``RigidTransform.to_dict`` form) and ``labels.npy`` (the partition
   of each occupied map cell, -1 elsewhere). Cases are generated once and reused
   (regenerated when missing or of another generator version).

Each case then runs through the public API as a user would:
``compute_brokenness(load_map(map.yaml), load_map(reference.yaml))``. Per case: the degree
(or not measured), **exact** (degree = expected), **all partitions true** (as many
partitions as true parts, and a one-to-one matching in which every true part's cells are put,
median, within 3 reference cells of where its true transform puts them by the matched
partition's transform), and the compute time. Tables per degree for real logs and simulated
buildings; per-case rows in ``benchmarks/results/realistic.json`` (``--tables-from`` redoes
the tables from such a file).

The negative controls of ``benchmarks/negative_controls.py`` (its quick subset with
``--quick``) are run too, after the cases, and their false claims counted in one line
(``--no-controls`` skips them).

Run: ``python benchmarks/realistic.py --quick --workers 1`` (25 cases: Orebro, Intel and
Freiburg-101 and two simulated buildings at degrees 0, 2, 4, 6, 8), or the full set
``python benchmarks/realistic.py --workers 2`` (8 logs x 9 degrees + 54 simulated cases);
``--degrees 0,3,8``, ``--seeds N`` (N seeds per log and 6 N simulated buildings per degree;
``--first-seed 1`` for a disjoint, held-out set),
``--logs intel,aces``; ``--compare earlier.json`` lists the cases and controls whose outcome
changed since an earlier run. ``--method random-walk`` (and ``--seed N``) runs the cases and
the controls with the paper's baseline registration instead of iFMI
(``compute_brokenness(..., method="random-walk", seed=N)``); the method and seed are
recorded in the summary of the results file (default ``realistic[_quick]_rw.json``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import warnings
import zlib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from functools import lru_cache, partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

sys.path.insert(0, str(Path(__file__).resolve().parent))

from cases import LOG_RANGE, LOGS, ROOT, TESTS_DATA  # noqa: E402

from brokenness import (  # noqa: E402
    OccupancyMap,
    RigidTransform,
    compute_brokenness,
    load_map,
    save_map,
)
from brokenness.masking import ReferenceIndex, cell_points  # noqa: E402
from brokenness.registration.methods import METHODS  # noqa: E402
from brokenness.simulation import (  # noqa: E402
    Building,
    LaserRun,
    draw_k_bumps,
    frame_truth,
    generate_building,
    map_in_frame,
    plan_map,
    simulate_plan_run,
    simulate_run,
)
from brokenness.simulation.bumps import rigid_matrix  # noqa: E402
from brokenness.simulation.ground_truth import broken_map_from_run, reference_map  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
#: Where cases are written (``--cache`` or ``BROKENNESS_BENCH_CACHE`` to share one between
#: worktrees: the files depend only on the case and :data:`GENERATOR_VERSION`).
CACHE = Path(os.environ.get("BROKENNESS_BENCH_CACHE", RESULTS / "realistic"))
#: Bumped into the cache: cases made by another version are regenerated.
GENERATOR_VERSION = 1

LOG_NAMES = (
    "aces",
    "csail",
    "fhw",
    "freiburg-079",
    "freiburg-101",
    "intel",
    "orebro",
    "seattle",
)
SIM = "sim"
#: Buildings known only as a map or floor plan (``cases.control_sources`` names): a tour is
#: planned through each and scanned (:func:`brokenness.simulation.simulate_plan_run`), as
#: broken maps of buildings that no rule was chosen on (``--plans``; the source
#: ``plan-<name>``, kind "plan").
PLAN_NAMES = (
    "building_31",
    "stata_basement",
    "willow_stage",
    "levinelobby",
    "depot",
    "warehouse",
)
PLAN = "plan-"
DEGREES = tuple(range(9))
SIM_PER_SEED = 6
QUICK_LOGS = ("orebro", "intel", "freiburg-101")
QUICK_DEGREES = (0, 2, 4, 6, 8)
QUICK_SIM_SEEDS = (0, 1)

FINE, COARSE = 0.05, 0.1
MIN_SHARE = 0.05  # every partition at least 5 % of the occupied cells
MIN_OFF_M = 0.5  # mean displacement between any two partitions' transforms, metres
BUMP_RADIUS = 1.0  # d ~ U[0, r], metres
PURE_SHIFT = 0.25  # chance that a bump is a pure shift
FRAME_SHIFT = 30.0  # own frame: shift ~ U[-30, 30] m per axis
MAX_ATTEMPTS = 100
TRUE_CELLS = 3.0  # "all partitions true": median displacement within 3 reference cells


@dataclass(frozen=True)
class Case:
    """One benchmark case; everything follows from ``(source, degree, seed)``.

    Attributes
    ----------
    source : str
        A Radish log name (``"intel"``...) or ``"sim"``.
    degree, seed : int
    map_resolution, reference_resolution : float
    reference : {"run", "plan"}
        The true-pose run mapped, or the simulated building's plan.
    """

    source: str
    degree: int
    seed: int
    map_resolution: float
    reference_resolution: float
    reference: str

    @property
    def name(self) -> str:
        """Folder name of the case."""
        return f"{self.source}_d{self.degree}_s{self.seed}"

    @property
    def kind(self) -> str:
        """``"real log"``, ``"simulated"`` or ``"plan"``."""
        return source_kind(self.source)


def source_kind(source: str) -> str:
    """The kind of a case's source: ``"real log"``, ``"simulated"`` or ``"plan"``."""
    if source == SIM:
        return "simulated"
    return "plan" if source.startswith(PLAN) else "real log"


def _crc(text: str) -> int:
    return zlib.crc32(text.encode("utf-8"))


def make_case(source: str, degree: int, seed: int) -> Case:
    """The case of ``(source, degree, seed)``: resolutions and reference kind, deterministic.

    A third of the cases get different resolutions (map 0.1 m / reference 0.05 m and the
    reverse, alternating); a third of the simulated ones the plan as reference.
    """
    k = (_crc(source) + 7 * seed + degree) % 6
    res = {0: (COARSE, FINE), 1: (FINE, COARSE)}.get(k, (FINE, FINE))
    ref = "plan" if source == SIM and seed % 3 == 1 else "run"
    return Case(source, degree, seed, res[0], res[1], ref)


def case_list(
    *,
    quick: bool = False,
    degrees: tuple[int, ...] | None = None,
    seeds: int = 1,
    logs: tuple[str, ...] | None = None,
    first_seed: int = 0,
    plans: tuple[str, ...] = (),
) -> list[Case]:
    """The cases: ``seeds`` per available log and ``6 seeds`` simulated, for each degree.

    Log seeds ``first_seed .. first_seed + seeds - 1``, simulated buildings
    ``6 first_seed .. 6 (first_seed + seeds) - 1`` (``first_seed=1``: a set disjoint from
    the default one, e.g. held out while tuning on it). ``quick``: Orebro, Intel and
    Freiburg-101 (those available) and simulated seeds 0 and 1, at degrees 0, 2, 4, 6, 8
    (unless ``degrees`` says otherwise).
    """
    available = [n for n in LOG_NAMES if _log_path(n) is not None]
    if quick:
        names = [n for n in (logs or QUICK_LOGS) if n in available]
        degs = degrees or QUICK_DEGREES
        sim_seeds: tuple[int, ...] = QUICK_SIM_SEEDS
        log_seeds: tuple[int, ...] = (0,)
    else:
        names = [n for n in (logs or LOG_NAMES) if n in available]
        degs = degrees or DEGREES
        sim_seeds = tuple(range(SIM_PER_SEED * first_seed, SIM_PER_SEED * (first_seed + seeds)))
        log_seeds = tuple(range(first_seed, first_seed + seeds))
    out = [make_case(n, d, s) for n in names for d in degs for s in log_seeds]
    if logs is None or SIM in logs:
        out += [make_case(SIM, d, s) for d in degs for s in sim_seeds]
    out += [make_case(PLAN + n, d, s) for n in plans for d in degs for s in log_seeds]
    return out


# -- generation -----------------------------------------------------------------------------
def _log_path(name: str) -> Path | None:
    for p in (
        LOGS / f"{name}-corrected.log.gz",
        TESTS_DATA / "carmen" / f"{name}-corrected.log.gz",
    ):
        if p.is_file():
            return p
    return None


@dataclass(frozen=True, eq=False)
class _Prepared:
    run: LaserRun
    extent: tuple[float, float, float, float]
    building: Building | None


def _plan_map(name: str) -> OccupancyMap:
    """The map of building ``name``: a control source of ``cases.py`` (the six of
    :data:`PLAN_NAMES`) or a plan drawn by ``drawn_buildings.py``."""
    import cases

    sources = cases.control_sources()
    if name in sources:
        return sources[name].build()
    import drawn_buildings

    return drawn_buildings.DRAWN[name]()


@lru_cache(maxsize=4)
def _prepare(source: str, seed: int) -> _Prepared:
    """The run of a log (seed ignored) or of simulated building ``seed``."""
    if source.startswith(PLAN):
        plan = _plan_map(source[len(PLAN) :])
        rng = np.random.default_rng([_crc(source), seed, 11])
        run, extent = simulate_plan_run(plan, rng=rng)
        return _Prepared(run, extent, None)
    if source == SIM:
        rng = np.random.default_rng([3000 + seed, 77])
        width, height = (float(v) for v in rng.uniform(18.0, 30.0, 2))
        building = generate_building(
            3000 + seed, width=width, height=height, truth_resolution=0.025
        )
        run = simulate_run(building, rng=np.random.default_rng([3000 + seed, 1]))
        return _Prepared(run, (0.0, 0.0, building.width, building.height), building)
    from brokenness.simulation.carmen import log_run, read_carmen

    path = _log_path(source)
    if path is None:
        raise FileNotFoundError(f"no log {source}")
    log = read_carmen(path)
    if log.n_scans > 2000:  # freiburg-079: every 4th scan keeps the generation time sane
        log = log.select(np.arange(0, log.n_scans, 4))
    run, extent = log_run(log, max_range=LOG_RANGE)
    return _Prepared(run, extent, None)


@lru_cache(maxsize=4)
def _true_reference(source: str, seed: int, resolution: float) -> tuple[OccupancyMap, Any]:
    prep = _prepare(source, seed)
    ref = reference_map(prep.run, prep.extent, resolution)
    return ref, ReferenceIndex.build(ref)


def _bumps(case: Case, n_scans: int, attempt: int) -> list[Any]:
    rng = np.random.default_rng([_crc(case.source), case.seed, case.degree, attempt])
    bumps = draw_k_bumps(n_scans, case.degree, radius=BUMP_RADIUS, max_rotation=math.pi, rng=rng)
    shift = rng.random(len(bumps)) < PURE_SHIFT
    return [replace(b, theta=0.0) if s else b for b, s in zip(bumps, shift, strict=True)]


def _clearly_off(
    transforms: list[RigidTransform], labels: NDArray[np.int16], resolution: float
) -> float:
    """Smallest mean displacement (metres) of a partition's cells between two transforms."""
    worst = math.inf
    for j, tj in enumerate(transforms):
        pts = cell_points(labels == j)
        for i, ti in enumerate(transforms):
            if i != j and len(pts):
                worst = min(worst, float(ti.displacement(tj, pts).mean()) * resolution)
    return worst


@dataclass(frozen=True, eq=False)
class Drawn:
    """A case drawn in memory (before its files are written).

    Attributes
    ----------
    case : Case
    map, reference : OccupancyMap
    labels : ndarray of int16
        The true partition of each occupied map cell, -1 elsewhere.
    errors : list of ndarray
        World error ``E_j`` (3x3) of each partition.
    frame : ndarray
        The own frame (3x3 world matrix) the map is drawn in.
    info : dict
        JSON-ready: attempt, rejected draws, frame, bumps, shares.
    """

    case: Case
    map: OccupancyMap
    reference: OccupancyMap
    labels: NDArray[np.int16]
    errors: list[NDArray[np.float64]]
    frame: NDArray[np.float64]
    info: dict[str, Any]

    def truths(
        self, map_: OccupancyMap | None = None, reference: OccupancyMap | None = None
    ) -> list[RigidTransform]:
        """Each partition's true transform, map cell -> reference cell (of these maps)."""
        m = self.map if map_ is None else map_
        r = self.reference if reference is None else reference
        return [frame_truth(m, r, e, self.frame) for e in self.errors]


def draw_case(
    case: Case, rejected: list[str] | None = None, first_attempt: int = 0
) -> Drawn | None:
    """Draw ``case`` (steps 1-5 of the module docstring); None if no draw fitted.

    ``rejected``, when given, receives why each rejected draw was rejected. Each attempt
    draws its own bumps (seeded by the case and the attempt), so starting at
    ``first_attempt``, the attempt a case's ``truth.json`` records, draws the same case
    without the rejected attempts before it (a test's shortcut).
    """
    prep = _prepare(case.source, case.seed)
    ref_run, index = _true_reference(case.source, case.seed, case.reference_resolution)
    run = prep.run
    n_scans = len(run.true_poses)
    why: list[str] = [] if rejected is None else rejected
    for attempt in range(first_attempt, MAX_ATTEMPTS):
        bumps = _bumps(case, n_scans, attempt)
        broken, expected, parts, labels0, judged, bp = broken_map_from_run(
            run,
            ref_run,
            bumps,
            extent=prep.extent,
            index=index,
            min_partition_fraction=MIN_SHARE,
        )
        if expected != case.degree:
            why.append(f"{attempt}: honest degree {expected}")
            continue
        off = _clearly_off([p.transform for p in parts], labels0, case.reference_resolution)
        if case.degree and off < MIN_OFF_M:
            why.append(f"{attempt}: two partitions only {off:.2f} m apart")
            continue
        rng = np.random.default_rng([_crc(case.source), case.seed, case.degree, attempt, 5])
        phi = float(rng.uniform(0.0, 2.0 * math.pi))
        tx, ty = (float(v) for v in rng.uniform(-FRAME_SHIFT, FRAME_SHIFT, 2))
        frame = rigid_matrix(phi, tx, ty)
        m, labels = map_in_frame(
            bp.poses,
            run.ranges,
            run.angles,
            max_range=run.laser.max_range,
            resolution=case.map_resolution,
            frame=frame,
            segment=bp.segment,
        )
        counts = np.bincount(labels[labels >= 0], minlength=case.degree + 1)
        shares = counts / max(int(counts.sum()), 1)
        if shares.min() < MIN_SHARE:
            why.append(f"{attempt}: a partition holds {100 * shares.min():.1f} % in the map")
            continue
        reference = ref_run
        if case.reference == "plan":
            assert prep.building is not None
            reference = plan_map(prep.building, case.reference_resolution)
        info = {
            "attempt": attempt,
            "rejected": why,
            "frame": {"rotation_deg": math.degrees(phi), "translation_m": [tx, ty]},
            "bumps": [b.to_dict() for b in judged],
            "occupied_cells": int(counts.sum()),
            "cells": counts.tolist(),
            "shares": shares.tolist(),
        }
        return Drawn(case, m, reference, labels, list(bp.errors), frame, info)
    return None


def generate(case: Case, cache: Path = CACHE) -> Path | None:
    """Write the files of ``case`` (when missing); its folder, or None if no draw fitted."""
    folder = cache / case.name
    truth_path = folder / "truth.json"
    if truth_path.is_file():
        old = json.loads(truth_path.read_text())
        if old.get("generator_version") == GENERATOR_VERSION and old.get("case") == asdict(case):
            if old.get("ok", True):
                return folder
            if old.get("max_attempts", 0) >= MAX_ATTEMPTS:
                return None
    rejected: list[str] = []
    drawn = draw_case(case, rejected)
    folder.mkdir(parents=True, exist_ok=True)
    if drawn is None:
        truth_path.write_text(
            json.dumps(
                {
                    "generator_version": GENERATOR_VERSION,
                    "case": asdict(case),
                    "ok": False,
                    "max_attempts": MAX_ATTEMPTS,
                    "rejected": rejected,
                },
                indent=1,
            )
        )
        return None
    m, reference, info = drawn.map, drawn.reference, drawn.info
    save_map(m, folder / "map.yaml")
    save_map(reference, folder / "reference.yaml")
    loaded_map, loaded_ref = load_map(folder / "map.yaml"), load_map(folder / "reference.yaml")
    truths = drawn.truths(loaded_map, loaded_ref)
    np.save(folder / "labels.npy", drawn.labels, allow_pickle=False)
    truth = {
        "generator_version": GENERATOR_VERSION,
        "case": asdict(case),
        "ok": True,
        "expected_degree": case.degree,
        "attempt": info["attempt"],
        "rejected": info["rejected"],
        "frame": info["frame"],
        "bumps": info["bumps"],
        "map": {"shape": list(m.shape), "resolution": m.resolution, "origin": list(m.origin)},
        "reference": {
            "kind": case.reference,
            "shape": list(reference.shape),
            "resolution": reference.resolution,
            "origin": list(reference.origin or ()),
        },
        "occupied_cells": info["occupied_cells"],
        "partitions": [
            {
                "index": j,
                "cells": info["cells"][j],
                "share": info["shares"][j],
                "transform": t.to_dict(),
                "matrix": t.matrix.tolist(),
            }
            for j, t in enumerate(truths)
        ],
    }
    truth_path.write_text(json.dumps(truth, indent=1, allow_nan=False) + "\n")
    return folder


def _generate_job(job: tuple[Case, str]) -> tuple[Case, str | None, float]:
    warnings.simplefilter("ignore")
    case, cache = job
    t0 = time.perf_counter()
    folder = generate(case, Path(cache))
    return case, None if folder is None else str(folder), time.perf_counter() - t0


# -- evaluation -----------------------------------------------------------------------------
def all_partitions_true(
    found: list[RigidTransform],
    truths: list[RigidTransform],
    labels: NDArray[np.int16],
    tolerance: float = TRUE_CELLS,
) -> bool:
    """As many found partitions as true parts, matched one to one within ``tolerance``.

    Found partition ``p`` fits true part ``q`` when it puts ``q``'s cells (median) within
    ``tolerance`` reference cells of where ``q``'s true transform puts them.
    """
    if len(found) != len(truths):
        return False
    return one_to_one(partition_fits(found, truths, labels, tolerance))


def one_to_one(fits: NDArray[np.bool_]) -> bool:
    """Whether the found partitions (rows of ``fits``) and the true parts (columns) can be
    paired one to one, each pair fitting (a square ``fits`` of :func:`partition_fits`)."""
    rows, cols = linear_sum_assignment(~fits)
    return bool(fits[rows, cols].all())


def partition_fits(
    found: list[RigidTransform],
    truths: list[RigidTransform],
    labels: NDArray[np.int16],
    tolerance: float = TRUE_CELLS,
) -> NDArray[np.bool_]:
    """``fits[p, q]``: found partition ``p`` puts true part ``q``'s cells (median) within
    ``tolerance`` reference cells of where ``q``'s true transform puts them."""
    fits = np.zeros((len(found), len(truths)), dtype=bool)
    for q, tq in enumerate(truths):
        pts = cell_points(labels == q)
        for p, tp in enumerate(found):
            fits[p, q] = float(np.median(tp.displacement(tq, pts))) <= tolerance
    return fits


def evaluate(folder: Path, method: str = "ifmi", seed: int | None = None) -> dict[str, Any]:
    """Compute one case through the public API (``compute_brokenness(..., method=method,
    seed=seed)``); its row."""
    warnings.simplefilter("ignore")
    truth = json.loads((folder / "truth.json").read_text())
    labels = np.load(folder / "labels.npy")
    truths = [RigidTransform.from_matrix(p["matrix"]) for p in truth["partitions"]]
    m, r = load_map(folder / "map.yaml"), load_map(folder / "reference.yaml")
    case = truth["case"]
    row: dict[str, Any] = {
        "case": folder.name,
        **case,
        "kind": source_kind(case["source"]),
        "expected_degree": truth["expected_degree"],
        "map_cells": list(m.shape),
        "reference_cells": list(r.shape),
        "occupied_cells": truth["occupied_cells"],
        "smallest_share": min(p["share"] for p in truth["partitions"]),
    }
    walks: list[Any] = []  # the random walk's last report of each walk
    extra: dict[str, Any] = {}
    if method == "random-walk":
        extra["registration_options"] = {"progress": lambda p: walks.append(p) if p.done else None}
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        res = compute_brokenness(m, r, method=method, seed=seed, **extra)
    except Exception as exc:
        row.update(error=f"{type(exc).__name__}: {exc}", seconds=time.perf_counter() - t0)
        return row
    if method == "random-walk":
        row["walks"] = walk_usage(walks)
    seconds = time.perf_counter() - t0
    found = [p.transform for p in res.partitions]
    partitions_true = all_partitions_true(found, truths, labels)
    row.update(
        seconds=seconds,
        cpu_seconds=time.process_time() - c0,  # this worker's CPU time, all its threads
        measured=bool(res.measured),
        degree=res.degree,
        reason=res.reason,
        contradiction=res.contradiction,
        contradiction_bound=res.contradiction_bound,
        exact=res.degree == truth["expected_degree"],
        all_true=bool(res.measured) and partitions_true,
        partitions_true=partitions_true,
        unassigned_share=float(res.unassigned_fraction),
        partitions=[
            p.transform.to_dict()
            | {
                "cells": p.cells,
                "contradiction": p.contradiction,
                "contradiction_bound": p.contradiction_bound,
                "true": bool(fit.any()),  # fits some true part (not necessarily one to one)
            }
            for p, fit in zip(res.partitions, partition_fits(found, truths, labels), strict=True)
        ],
    )
    return row


def walk_usage(walks: list[Any]) -> dict[str, Any]:
    """The random walk's work in one call, from its last progress report of each walk: walks
    and evaluations of the plain and the wider registrar (the one with a shared budget) in
    units of one plain walk (:attr:`WalkOptions.nominal_evaluations`), and whether the
    search's budget was spent (by the walks of either: the plain ones are counted too)."""
    from brokenness.registration.random_walk import WalkOptions

    options = WalkOptions()
    unit = options.nominal_evaluations
    plain = [p for p in walks if p.budget_left is None]
    wider = [p for p in walks if p.budget_left is not None]
    used = sum(p.evaluations for p in walks) / unit  # the plain walks are counted too
    return {
        "plain_walks": len(plain),
        "plain_units": sum(p.evaluations for p in plain) / unit,
        "wider_walks": len(wider),
        "wider_units": sum(p.evaluations for p in wider) / unit,
        "budget_spent": options.search_budget is not None and used >= options.search_budget,
    }


def _evaluate_job(folder: str, method: str = "ifmi", seed: int | None = None) -> dict[str, Any]:
    return evaluate(Path(folder), method, seed)


def tables(rows: list[dict[str, Any]]) -> str:
    """Per source kind and degree: cases, exact, all true, not measured, median seconds."""
    out = []
    for kind in ("real log", "simulated", "plan"):
        mine = [r for r in rows if r["kind"] == kind and "measured" in r]
        if not mine:
            continue
        out += [
            f"\n{kind}:\n",
            "| degree | cases | exact | all partitions true | not measured | median s |",
            "|---|---|---|---|---|---|",
        ]
        degs = sorted({r["expected_degree"] for r in mine})
        for d in degs + ["all"]:
            sel = [r for r in mine if d == "all" or r["expected_degree"] == d]
            n = len(sel)
            out.append(
                f"| {d} | {n} | {sum(r['exact'] for r in sel)} "
                f"| {sum(r['all_true'] for r in sel)} "
                f"| {sum(not r['measured'] for r in sel)} "
                f"| {np.median([r['seconds'] for r in sel]):.2f} |"
            )
    done = [r for r in rows if "measured" in r]
    if done:
        out += [
            "\nper source (all degrees) and per case kind:\n",
            "| source | cases | exact | all partitions true | not measured | median s |",
            "|---|---|---|---|---|---|",
        ]
        groups: dict[str, list[dict[str, Any]]] = {}
        for r in done:
            groups.setdefault(r["source"], []).append(r)
        for r in done:
            if r["map_resolution"] != r["reference_resolution"]:
                groups.setdefault("(map and reference resolutions differ)", []).append(r)
            if r["reference"] == "plan":
                groups.setdefault("(plan as reference)", []).append(r)
        for name, sel in groups.items():
            out.append(
                f"| {name} | {len(sel)} | {sum(r['exact'] for r in sel)} "
                f"| {sum(r['all_true'] for r in sel)} "
                f"| {sum(not r['measured'] for r in sel)} "
                f"| {np.median([r['seconds'] for r in sel]):.2f} |"
            )
    errors = [r for r in rows if "error" in r]
    if errors:
        out.append(
            f"\nerrors: {len(errors)}: " + "; ".join(f"{r['case']}: {r['error']}" for r in errors)
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="25 cases, a few minutes on 1 worker")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--degrees", type=str, default=None, help="e.g. 0,3,8")
    ap.add_argument("--seeds", type=int, default=1, help="seeds per log (6x simulated)")
    ap.add_argument(
        "--first-seed", type=int, default=0, help="1: a set disjoint from the default (held out)"
    )
    ap.add_argument("--logs", type=str, default=None, help="e.g. intel,aces,sim")
    ap.add_argument(
        "--plans",
        type=str,
        default="",
        help="buildings known as a map, toured and scanned: all, or some of "
        + ",".join(PLAN_NAMES),
    )
    ap.add_argument(
        "--out", type=Path, default=None, help="default results/realistic[_quick][_rw].json"
    )
    ap.add_argument("--tables-from", type=Path, default=None, help="only print the tables")
    ap.add_argument("--cache", type=Path, default=CACHE, help="folder of the generated cases")
    ap.add_argument(
        "--method",
        choices=METHODS,
        default="ifmi",
        help="registration of compute_brokenness (cases and controls); default ifmi",
    )
    ap.add_argument(
        "--seed", type=int, default=None, help="seed of the random walk (default: its own)"
    )
    ap.add_argument(
        "--compare", type=Path, default=None, help="list the cases that changed since this run"
    )
    ap.add_argument(
        "--no-controls",
        action="store_true",
        help="skip the negative controls (negative_controls.py; its quick subset with --quick)",
    )
    args = ap.parse_args(argv)
    if args.tables_from is not None:
        saved = json.loads(args.tables_from.read_text())
        s = saved.get("summary", {})
        print(f"method {s.get('method', 'ifmi')}, seed {s.get('seed')}")
        print(tables(saved["rows"]))
        print(failures(saved["rows"]))
        if saved.get("controls"):
            print(_controls_line(saved["controls"]))
        return 0
    if args.out is None:  # the random walk's results apart from iFMI's
        suffix = ("_quick" if args.quick else "") + ("" if args.method == "ifmi" else "_rw")
        args.out = RESULTS / f"realistic{suffix}.json"
    warnings.simplefilter("ignore")
    degrees = tuple(int(d) for d in args.degrees.split(",")) if args.degrees else None
    logs = tuple(args.logs.split(",")) if args.logs else None
    plans = PLAN_NAMES if args.plans == "all" else tuple(n for n in args.plans.split(",") if n)
    cases = case_list(
        quick=args.quick,
        degrees=degrees,
        seeds=args.seeds,
        logs=logs,
        first_seed=args.first_seed,
        plans=plans,
    )
    start = time.perf_counter()
    workers = max(1, args.workers)
    # phase 1: generate what is missing (cases of one source run in one process, in order)
    with ProcessPoolExecutor(workers) as pool:
        made = list(
            pool.map(
                _generate_job,
                [(c, str(args.cache)) for c in cases],
                chunksize=max(1, len(cases) // (4 * workers)),
            )
        )
    gen_seconds = time.perf_counter() - start
    failed = [c.name for c, f, _ in made if f is None]
    folders = [f for _, f, _ in made if f is not None]
    print(
        f"{len(cases)} cases ({len(failed)} could not be drawn: {', '.join(failed) or '-'}); "
        f"generation {gen_seconds:.0f} s (cache {args.cache})",
        flush=True,
    )
    control_jobs: list[tuple[str, str, str, str, str]] = []
    if not args.no_controls:
        import negative_controls as nc
        from cases import negative_control_pairs, save_control_maps

        pairs = negative_control_pairs(quick=args.quick)
        paths = save_control_maps(sorted({n for p in pairs for n in p}), nc.CACHE)
        control_jobs = [("control", a, b, str(paths[a]), str(paths[b])) for a, b in pairs]
    # phase 2: compute (nothing else running in the pool)
    t1 = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        run_case = partial(_evaluate_job, method=args.method, seed=args.seed)
        rows = list(pool.map(run_case, folders))
        compute_wall = time.perf_counter() - t1
        run_control = partial(_control_job, method=args.method, seed=args.seed)
        controls = list(pool.map(run_control, control_jobs))
    print(f"method {args.method}, seed {args.seed}")
    print(tables(rows))
    print(failures(rows))
    if controls:
        print(_controls_line(controls))
    if args.compare is not None:
        print(compare(json.loads(args.compare.read_text()), rows, controls))
    summary = {
        "cases": len(cases),
        "not_drawn": failed,
        "generation_seconds": gen_seconds,
        "compute_wall_seconds": compute_wall,
        "workers": workers,
        "quick": args.quick,
        "method": args.method,
        "seed": args.seed,
    }
    print(
        f"\ncompute: {compute_wall:.0f} s wall on {workers} worker(s), "
        f"{sum(r.get('seconds', 0.0) for r in rows):.0f} s summed"
    )
    timed = [r for r in rows if "cpu_seconds" in r]
    if timed:
        print(
            f"per map: median {np.median([r['seconds'] for r in timed]):.1f} s wall, "
            f"{np.median([r['cpu_seconds'] for r in timed]):.1f} s CPU "
            f"(max {max(r['seconds'] for r in timed):.1f} s wall, "
            f"{max(r['cpu_seconds'] for r in timed):.1f} s CPU)"
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        json.dumps(
            {"summary": summary, "rows": rows, "controls": controls}, indent=1, allow_nan=False
        )
        + "\n"
    )
    print(f"results: {args.out}")
    return 0


def _outcome(r: dict[str, Any]) -> str:
    if "error" in r:
        return "error"
    if not r["measured"]:
        return "not measured"
    return f"{r['degree']}{' (all true)' if r['all_true'] else ''}"


def failures(rows: list[dict[str, Any]]) -> str:
    """The cases whose partitions are not all true: ``case: expected -> found``."""
    bad = [r for r in rows if not r.get("all_true")]
    items = [f"{r['case']}: {r['expected_degree']} -> {_outcome(r)}" for r in bad]
    return f"\nnot all true ({len(bad)}): " + ("; ".join(items) or "-")


def compare(old: dict[str, Any], rows: list[dict[str, Any]], controls: list[dict[str, Any]]) -> str:
    """Cases (and controls) whose outcome differs from those of an earlier results file."""
    before = {r["case"]: r for r in old.get("rows", [])}
    lines = []
    for r in rows:
        o = before.get(r["case"])
        if o is not None and _outcome(o) != _outcome(r):
            lines.append(
                f"{r['case']} (expected {r['expected_degree']}): {_outcome(o)} -> {_outcome(r)}"
            )
    ctl_before = {r["pair"]: r for r in old.get("controls", [])}
    for r in controls:
        o = ctl_before.get(r["pair"])
        if o is not None and "measured" in o and "measured" in r:
            a = "-" if not o["measured"] else o["degree"]
            b = "-" if not r["measured"] else r["degree"]
            if a != b:
                lines.append(f"control {r['pair']}: {a} -> {b}")
    return f"\nchanged since the earlier run ({len(lines)}):\n" + ("\n".join(lines) or "-")


def _control_job(
    job: tuple[str, str, str, str, str], method: str = "ifmi", seed: int | None = None
) -> dict[str, Any]:
    import negative_controls as nc

    return nc.run_pair(job, method, seed)


def _controls_line(controls: list[dict[str, Any]]) -> str:
    """One line: false claims (degrees given) on the negative controls."""
    done = [r for r in controls if "measured" in r]
    false = [r for r in done if r["measured"]]
    worst = sorted(false, key=lambda r: -(r["degree"] or 0))[:3]
    return (
        f"\nnegative controls: {len(false)} false claims of {len(done)} "
        f"(errors {len(controls) - len(done)}); highest: "
        + (", ".join(f"{r['pair']} {r['degree']}" for r in worst) or "-")
        + " (details: benchmarks/negative_controls.py)"
    )


if __name__ == "__main__":
    sys.exit(main())
