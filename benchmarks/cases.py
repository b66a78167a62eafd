"""Negative controls: pairs of maps of *different* places, which must get no degree.

A map of one place against the reference of another is not "broken": it is not a map of that
place at all, and ``compute_brokenness`` must say so (``measured == False``, ``degree is
None``). This module lists such pairs, builds their maps, and is imported by
``benchmarks/negative_controls.py`` and by the tests (``tests/_controls.py``).

Sources (:func:`control_sources`), each with the *place* it shows:

- real map files, loaded with :func:`brokenness.load_map` as a user would: MIT building 31
  and the Stata basement, the Willow Garage SLAM map (0.1 m) and Stage map (``willow-full``,
  0.1 m, no YAML), Levine lobby, the Nav2 depot, warehouse and TurtleBot3 sandbox, and the
  Intel / ACES / CSAIL grids (PGM without YAML: 0.05 m assumed, as the data README says);
- the eight Radish CARMEN logs, mapped with their corrected poses by
  :func:`brokenness.simulation.carmen.map_log` at 0.1 m with a 15 m mapping range (the bundled
  Orebro log also without ``../shared``);
- synthetic maps, seeded: random wall segments (any angle, and axis-aligned: the harder
  case, since buildings are mostly axis-aligned too), random clutter (boxes and blobs),
  salt-and-pepper noise, and simulated buildings of other seeds
  (:func:`brokenness.simulate_broken_map`: the true-pose reference, and the map).

Maps whose resolution is finer than 0.1 m and that have more than :data:`BIG_SIDE` cells a
side are resampled to 0.1 m (:func:`brokenness.resample_to_resolution`), to bound the time of
the cross product; the others stay at their own resolution, so pairs of different
resolutions are common.

Pairs (:func:`negative_control_pairs`): every ordered pair of two real sources of different
places (both ways), plus every synthetic source against a few real and simulated
references and a few real maps against the synthetic references, plus simulated buildings
against each other. Pairs of one place (the two Willow maps, the Intel / ACES / CSAIL grids
and the logs of the same buildings) are *not* controls: :func:`same_place_pairs` lists them,
and they should be measured. ``quick=True`` picks a small deterministic subset.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from brokenness import OccupancyMap, load_map, resample_to_resolution, simulate_broken_map
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.report.repair import align_map
from brokenness.transform import RigidTransform

ROOT = Path(__file__).resolve().parents[1]
#: The shared data folder (``../shared/data`` next to the repository; override with
#: ``BROKENNESS_SHARED_DATA``).
SHARED = Path(os.environ.get("BROKENNESS_SHARED_DATA", ROOT.parent / "shared" / "data"))
TESTS_DATA = ROOT / "tests" / "data"
LOGS = SHARED / "radish-corrected-carmen-logs"

#: Maps finer than 0.1 m with more cells than this on a side are resampled to 0.1 m.
BIG_SIDE = 800
#: Resolution of the CARMEN-log maps and of resampled big maps (metres).
COARSE = 0.1
#: Mapping range of the CARMEN-log maps (metres).
LOG_RANGE = 15.0
#: Version of the control maps (their cache folder); bump it when a source changes.
CONTROLS_VERSION = 1

#: Radish log name -> place (the Intel, ACES and CSAIL logs are the places of the PGM grids).
LOG_PLACES = {
    "aces": "aces",
    "csail": "csail",
    "fhw": "fhw",
    "freiburg-079": "freiburg-079",
    "freiburg-101": "freiburg-101",
    "intel": "intel",
    "orebro": "orebro",
    "seattle": "seattle",
}


@dataclass(frozen=True)
class ControlSource:
    """One map of a control: its name, the place it shows, and how to build it.

    Attributes
    ----------
    name : str
        Unique, file-name safe.
    place : str
        What it is a map of; two sources of the same place never form a control.
    kind : {"real", "log", "synthetic", "simulated"}
    build : callable
        Returns the :class:`~brokenness.OccupancyMap` (deterministic).
    """

    name: str
    place: str
    kind: str
    build: Callable[[], OccupancyMap]


def _coarse(m: OccupancyMap) -> OccupancyMap:
    """Resample to :data:`COARSE` when finer and bigger than :data:`BIG_SIDE` cells a side."""
    if m.resolution is not None and m.resolution < COARSE and max(m.shape) > BIG_SIDE:
        return resample_to_resolution(m, COARSE)
    return m


def _file(path: Path, **kwargs: object) -> Callable[[], OccupancyMap]:
    def build() -> OccupancyMap:
        return _coarse(load_map(path, **kwargs))  # type: ignore[arg-type]

    return build


def _log(path: Path) -> Callable[[], OccupancyMap]:
    def build() -> OccupancyMap:
        from brokenness.simulation.carmen import map_log, read_carmen

        return map_log(read_carmen(path), resolution=COARSE, max_range=LOG_RANGE)

    return build


# -- synthetic maps ---------------------------------------------------------------------------
def _canvas(size: int) -> np.ndarray:
    return np.full((size, size), FREE, dtype=np.int8)


def random_walls(
    seed: int,
    *,
    size: int = 400,
    segments: int = 60,
    axis_aligned: bool = False,
    resolution: float = 0.05,
) -> OccupancyMap:
    """Random wall segments (lines 1-2 cells thick, 20-200 cells long) on a free square.

    ``axis_aligned`` draws only horizontal and vertical segments, like most building walls.
    Everything not a wall is free (a map whose robot saw all of it).
    """
    rng = np.random.default_rng([seed, 11, int(axis_aligned)])
    img = np.zeros((size, size), dtype=np.uint8)
    starts = rng.uniform(0, size, (segments, 2))
    lengths = rng.uniform(20, 200, segments)
    if axis_aligned:
        angles = rng.integers(0, 4, segments) * (math.pi / 2)
    else:
        angles = rng.uniform(0, 2 * math.pi, segments)
    ends = starts + lengths[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])
    thick = rng.integers(1, 3, segments)
    for a, b, t in zip(starts, ends, thick, strict=True):  # one cv2 call per segment
        cv2.line(img, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), 1, int(t))
    states = _canvas(size)
    states[img > 0] = OCCUPIED
    return OccupancyMap(states, resolution, (0.0, 0.0, 0.0), f"random_walls({seed})")


def random_clutter(
    seed: int, *, size: int = 400, objects: int = 150, resolution: float = 0.05
) -> OccupancyMap:
    """Random clutter: filled boxes at random angles and round blobs, 2-15 cells across."""
    rng = np.random.default_rng([seed, 12])
    img = np.zeros((size, size), dtype=np.uint8)
    centres = rng.uniform(0, size, (objects, 2))
    half = rng.uniform(1, 7.5, (objects, 2))
    angle = rng.uniform(0, 180, objects)
    round_ = rng.random(objects) < 0.3
    for c, h, a, r in zip(centres, half, angle, round_, strict=True):
        if r:
            cv2.circle(img, (int(c[0]), int(c[1])), max(1, int(h[0])), 1, -1)
        else:
            box = cv2.boxPoints(((float(c[0]), float(c[1])), (2 * h[0], 2 * h[1]), float(a)))
            cv2.fillPoly(img, [np.rint(box).astype(np.int32)], 1)
    states = _canvas(size)
    states[img > 0] = OCCUPIED
    return OccupancyMap(states, resolution, (0.0, 0.0, 0.0), f"random_clutter({seed})")


def salt_and_pepper(
    seed: int, *, size: int = 400, density: float = 0.02, resolution: float = 0.05
) -> OccupancyMap:
    """Isolated occupied cells (``density`` of them) on free space, some unknown cells."""
    rng = np.random.default_rng([seed, 13])
    u = rng.random((size, size))
    states = _canvas(size)
    states[u < density] = OCCUPIED
    states[u > 1.0 - density] = UNKNOWN
    return OccupancyMap(states, resolution, (0.0, 0.0, 0.0), f"salt_and_pepper({seed})")


@lru_cache(maxsize=8)
def _simulated(seed: int, degree: int) -> tuple[OccupancyMap, OccupancyMap]:
    sim = simulate_broken_map(seed=seed, degree=degree)
    return sim.map, sim.reference


def simulated_map(seed: int, degree: int = 0) -> OccupancyMap:
    """The (broken, when ``degree`` > 0) map of simulated building ``seed``."""
    return _simulated(seed, degree)[0]


def simulated_reference(seed: int) -> OccupancyMap:
    """The true-pose reference of simulated building ``seed``."""
    return _simulated(seed, 0)[1]


def turned_map(m: OccupancyMap, degrees: float) -> OccupancyMap:
    """``m`` turned by ``degrees`` (counter-clockwise on screen) about its centre and shifted
    by a few cells, on a canvas that holds all of it (unknown around it): a map in a frame of
    its own at any angle, as a SLAM run that starts anywhere makes it. Each cell takes the
    state of the nearest cell of ``m`` (:func:`brokenness.report.repair.align_map`: the same
    cells on any number of threads)."""
    h, w = m.shape
    a = math.radians(degrees)
    c, s = abs(math.cos(a)), abs(math.sin(a))
    width, height = math.ceil(w * c + h * s) + 20, math.ceil(w * s + h * c) + 20
    matrix = cv2.getRotationMatrix2D((w / 2.0, h / 2.0), degrees, 1.0)
    matrix[0, 2] += (width - w) / 2.0 + 7.0  # and a shift that is no whole turn of the grid
    matrix[1, 2] += (height - h) / 2.0 + 3.0
    canvas = OccupancyMap(np.full((height, width), UNKNOWN, np.int8), resolution=m.resolution)
    return align_map(m, RigidTransform.from_matrix(matrix), canvas)


# -- the sources and pairs ----------------------------------------------------------------------
def _first(*paths: Path) -> Path | None:
    return next((p for p in paths if p.is_file()), None)


def control_sources() -> dict[str, ControlSource]:
    """Every control source available here (``../shared/data`` sources only when present)."""
    out: dict[str, ControlSource] = {}

    def add(name: str, place: str, kind: str, build: Callable[[], OccupancyMap]) -> None:
        out[name] = ControlSource(name, place, kind, build)

    files: list[tuple[str, str, Path | None, dict[str, object]]] = [
        (
            "building_31",
            "mit-building-31",
            _first(TESTS_DATA / "building_31.yaml"),
            {},
        ),
        (
            "stata_basement",
            "mit-stata",
            _first(SHARED / "mit-stata-basement-and-building31" / "stata_basement.yaml"),
            {},
        ),
        (
            "willow_slam",
            "willow",
            _first(TESTS_DATA / "willow-2010-02-18-0.10.yaml"),
            {},
        ),
        (
            "willow_stage",
            "willow",
            _first(SHARED / "willow-garage-stage-maps" / "willow-full.pgm"),
            {"resolution": 0.1, "origin": (0.0, 0.0, 0.0)},
        ),
        (
            "levinelobby",
            "penn-levine",
            _first(SHARED / "penn-levine-lobby" / "levinelobby.yaml"),
            {},
        ),
        ("depot", "nav2-depot", _first(TESTS_DATA / "depot.yaml"), {}),
        (
            "warehouse",
            "nav2-warehouse",
            _first(SHARED / "nav2-sim-maps" / "warehouse.yaml"),
            {},
        ),
        ("tb3_sandbox", "tb3-world", _first(TESTS_DATA / "tb3_sandbox.yaml"), {}),
    ]
    for grid in ("intel", "aces", "csail"):
        files.append(
            (
                f"{grid}_pgm",
                grid,
                _first(SHARED / "slam-benchmark-maps-intel-aces-csail" / f"{grid}.pgm"),
                {"resolution": 0.05, "origin": (0.0, 0.0, 0.0)},
            )
        )
    for name, place, path, kwargs in files:
        if path is not None:
            add(name, place, "real", _file(path, **kwargs))
    for log, place in LOG_PLACES.items():
        path = _first(
            LOGS / f"{log}-corrected.log.gz", TESTS_DATA / "carmen" / f"{log}-corrected.log.gz"
        )
        if path is not None:
            add(f"log_{log}", place, "log", _log(path))
    for seed in (1, 2):
        add(f"walls_{seed}", f"walls-{seed}", "synthetic", lambda s=seed: random_walls(s))
        add(
            f"walls_axis_{seed}",
            f"walls-axis-{seed}",
            "synthetic",
            lambda s=seed: random_walls(s, axis_aligned=True),
        )
    add("clutter_1", "clutter-1", "synthetic", lambda: random_clutter(1))
    add("noise_1", "noise-1", "synthetic", lambda: salt_and_pepper(1))
    for seed in (201, 202, 203, 204):
        add(f"sim_ref_{seed}", f"sim-{seed}", "simulated", lambda s=seed: simulated_reference(s))
        add(f"sim_map_{seed}", f"sim-{seed}", "simulated", lambda s=seed: simulated_map(s))
    add("sim_map_205_d3", "sim-205", "simulated", lambda: simulated_map(205, 3))
    return out


def real_sources(sources: dict[str, ControlSource]) -> list[str]:
    """The names of the real maps and logs among ``sources``."""
    return [n for n, s in sources.items() if s.kind in ("real", "log")]


def negative_control_pairs(
    quick: bool = False, sources: dict[str, ControlSource] | None = None
) -> list[tuple[str, str]]:
    """``(map, reference)`` names of the negative controls, in a fixed order.

    Full: every ordered pair of real sources (files and logs) of different places; every
    synthetic source against the references ``building_31``, ``log_orebro``, ``intel_pgm``
    (when present) and ``sim_ref_201``, and the maps ``building_31``, ``log_orebro`` and
    ``sim_map_202`` against the synthetic references; simulated maps against references of
    other simulated buildings. ``quick``: a fixed subset of about 20 pairs (every kind of
    control, real pairs both ways).
    """
    sources = control_sources() if sources is None else sources
    real = real_sources(sources)
    synthetic = [n for n, s in sources.items() if s.kind == "synthetic"]
    pairs: list[tuple[str, str]] = []
    if quick:
        wanted_real = [
            ("building_31", "willow_slam"),
            ("willow_slam", "building_31"),
            ("depot", "building_31"),
            ("tb3_sandbox", "building_31"),
            ("log_orebro", "building_31"),
            ("building_31", "log_orebro"),
            ("depot", "log_orebro"),
            ("log_intel", "log_aces"),
            ("log_fhw", "log_freiburg-101"),
            ("stata_basement", "intel_pgm"),
            ("csail_pgm", "log_seattle"),
            ("levinelobby", "depot"),
        ]
        pairs += [(a, b) for a, b in wanted_real if a in sources and b in sources]
        pairs += [
            ("walls_1", "building_31"),
            ("walls_axis_1", "log_orebro"),
            ("clutter_1", "building_31"),
            ("noise_1", "building_31"),
            ("building_31", "walls_axis_1"),
            ("sim_map_201", "sim_ref_202"),
            ("sim_map_205_d3", "sim_ref_203"),
        ]
        return pairs
    for a in real:
        for b in real:
            if sources[a].place != sources[b].place:
                pairs.append((a, b))
    refs = [r for r in ("building_31", "log_orebro", "intel_pgm", "sim_ref_201") if r in sources]
    maps = [m for m in ("building_31", "log_orebro", "sim_map_202") if m in sources]
    for s in synthetic:
        pairs += [(s, r) for r in refs]
        pairs += [(m, s) for m in maps]
    sims = [201, 202, 203, 204]
    for a in sims:
        for b in sims:
            if a != b:
                pairs.append((f"sim_map_{a}", f"sim_ref_{b}"))
    pairs += [("sim_map_205_d3", f"sim_ref_{b}") for b in sims]
    return pairs


def same_place_pairs(sources: dict[str, ControlSource] | None = None) -> list[tuple[str, str]]:
    """``(map, reference)`` of two different real maps of one place (not controls).

    The Willow SLAM map against the Stage map (both ways), and each of the Intel / ACES /
    CSAIL grids against the map of the log of the same building (both ways). These should be
    measured (their degree is not known).
    """
    sources = control_sources() if sources is None else sources
    real = real_sources(sources)
    return [(a, b) for a in real for b in real if a != b and sources[a].place == sources[b].place]


def save_control_maps(
    names: list[str], cache: Path, sources: dict[str, ControlSource] | None = None
) -> dict[str, Path]:
    """Write the maps of ``names`` as ROS YAML + PGM into ``cache`` (when missing).

    Returns ``name -> YAML path``. The files are what the benchmark loads back with
    :func:`brokenness.load_map`, so every map goes through the file format a user has. They
    go into ``cache / f"v{CONTROLS_VERSION}"``: bump the version when a source changes.
    """
    from brokenness import save_map

    sources = control_sources() if sources is None else sources
    cache = cache / f"v{CONTROLS_VERSION}"
    cache.mkdir(parents=True, exist_ok=True)
    out = {}
    for name in names:
        path = cache / f"{name}.yaml"
        if not path.is_file():
            save_map(sources[name].build(), path)
        out[name] = path
    return out
