"""Small, fast fixtures for regression tests: negative controls and heavily broken real maps.

Helpers only (no assertions about what ``compute_brokenness`` returns today). Built from the
files bundled in ``tests/data`` and by the same code as the benchmarks
(``benchmarks/cases.py``, ``benchmarks/realistic.py``), so a test and a benchmark row mean the
same thing:

- :func:`negative_controls`: pairs of maps of *different* places, which must come back
  ``measured == False`` (``degree is None``): building 31 against the Willow Garage SLAM map
  (degree 10 before issue 16), the Nav2 depot against building 31, random axis-aligned
  walls against the Orebro log's map, and one simulated building against another's
  reference.
- :func:`broken_real_log_maps`: the Orebro log (bundled) at 0.1 m broken into 7 and 9
  partitions of at least 5 % each (bumps after the paper's model, some pure shifts), drawn in
  its own frame (turned and shifted), cropped, three-state, with the true transform of every
  partition (map cell -> reference cell) and the label image.
- :func:`broken_simulated_maps`: a simulated building broken into 4 partitions whose free
  space overlaps in the map's frame (case ``sim_d3_s17`` of the benchmark's fresh set): its
  parts are all found, and the contradiction test refuses the degree ("not the same place?").
- :func:`lost_part_simulated_maps`: a simulated building broken into 7 partitions (case
  ``sim_d6_s23`` of the benchmark's held-out sets) whose smallest part (5 % of the cells)
  loses most of its cells to the partitions found before it; what is left of it is
  scattered among other parts' suspects, and only the regions around them, registered with
  all their cells, give its transform (session 22).
- :func:`refit_rival_simulated_maps`: a simulated building broken into 7 partitions (case
  ``sim_d6_s26`` of the benchmark's held-out sets), whose 7 % part is held at a twin of its
  room 406 cells off; the relocation finds a rival 1.7 cells from its place, which makes
  fewer cells agree than the twin until it is refitted on the partition's cells (session
  22). The slowest fixture to draw (7-12 s).
- :func:`placed_part_real_log_maps`: two maps of the CSAIL log (bundled) broken into 8
  partitions (cases ``csail_d7_s7`` and ``csail_d7_s9`` of the benchmark's held-out set 7 and
  set 9), in which a part of 6-8 % of the cells is left as suspects mixed with other parts'
  borders, and neither the suspects nor their groups registered alone give a hypothesis
  within 20 degrees of its rotation; placed at the rotations of their walls, they give its
  place (session 23; before, one came out a degree short, the other held the part at a
  twin).
- :func:`twin_replaced_real_log_maps`: the Orebro log at 5 cm broken into 8 partitions (case
  ``orebro_d7_s7`` of the benchmark's held-out set 7), in which a 5 % part is first held at a
  twin of its room 950 cells off; its true place, found among the suspects, takes its cells
  from the twin and leaves the twin too few of its own (session 23; before, the new
  partition was refused because the count of partitions did not grow).
- :func:`twin_placed_simulated_maps`: two simulated buildings (cases ``sim_d4_s28`` and
  ``sim_d7_s10`` of the held-out sets) in which a small part (6-7 % of the cells) was held at
  a turned twin of its place until the settled partitions were registered alone again, with
  their neighbourhoods (session 18).
- :func:`split_part_drawn_maps`: the atrium drawn by ``benchmarks/drawn_buildings.py`` (a
  hall with five corridors 72 degrees apart) broken into 6 partitions (case
  ``plan-atrium_d5_s0``), in which a part of 21 % of the cells was held as three pieces,
  each at a twin of its place among the turned arms, and the degree came out 7 (session 27;
  a join of such pieces fixed it and was not kept, for its cost); step 10 makes the pieces
  one partition (session 37).
- :func:`tied_twin_drawn_maps`: the open-plan office drawn by ``benchmarks/drawn_buildings.py``
  broken into 8 partitions (case ``plan-office_d7_s0``), in which a part of 7 % of the cells
  was held 700 cells off, where it explains as many cells as at its true place (which the
  recovery finds), while its free space crosses the reference's walls there at 0.43 of the
  chance rate, and at 0.03 at its place (session 28: the settle step now breaks such a
  tie of the count by the free space; before, the degree was exact and that partition
  wrong).
- :func:`split_piece_simulated_maps`: a simulated building broken into 9 partitions, against
  its plan (case ``sim_d8_s43`` of the held-out set 7), in which two parts of 6-7 % were
  held at twins and a third (10 %) was split in two, one piece at a twin: degree 9, three
  partitions wrong. Two doubtful partitions that touch in the map, registered together,
  give the part's transform (session 29). Drawn from its accepted attempt (41) on.
- :func:`split_piece_drawn_maps`: the open-plan office drawn by
  ``benchmarks/drawn_buildings.py`` broken into 9 partitions, at 0.1 m against its run at
  5 cm (case ``plan-office_d8_s0``), which came out degree 10: a part split in two pieces at
  twins, only one of them doubtful. A doubtful partition registered together with the
  partition it touches gives the part's place (session 29). Drawn from attempt 69 on.
- :func:`region_placed_simulated_maps`: a simulated building broken into 8 partitions,
  against its plan (case ``sim_d7_s25`` of set 4), whose 7 % part loses most of its cells
  to four partitions found before it: 147 of its 626 cells are left as dense suspects,
  fewer than a partition holds, and no registration of them, of all the suspects or of
  their regions gives its place. The region around them, placed with all its cells at the
  rotations of its walls, does, and the part is counted by the cells it takes (session
  30; before, the degree came out one short). Drawn from its accepted attempt (13) on.
- :func:`twin_room_drawn_maps`: the drawn atrium broken into 7 partitions (case
  ``plan-atrium_d6_s5``), in which a part of 4.5 % of the cells was held 144 cells off, at
  the half-turned twin of its room, where its free space crossed the reference's walls at
  0.46 of the chance rate, so it was not in doubt and its cells were never registered
  alone; they give its place second among their hypotheses (session 41: step 8 registers
  every partition's own cells alone; before, the degree was exact and that partition
  wrong). Drawn from its accepted attempt (5) on.

Each fixture but two takes well under 5 s to build (the Orebro log is read once per process).
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

_BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
if str(_BENCH) not in sys.path:
    sys.path.insert(0, str(_BENCH))

from cases import TESTS_DATA, random_walls, simulated_map, simulated_reference  # noqa: E402
from realistic import Case, draw_case  # noqa: E402

from brokenness import MapWarning, OccupancyMap, RigidTransform, load_map  # noqa: E402

__all__ = [
    "BrokenCase",
    "Control",
    "broken_real_log_maps",
    "broken_simulated_maps",
    "lost_part_simulated_maps",
    "negative_controls",
    "orebro_map",
    "placed_part_real_log_maps",
    "refit_rival_simulated_maps",
    "split_part_drawn_maps",
    "tied_twin_drawn_maps",
    "twin_replaced_real_log_maps",
    "twin_room_drawn_maps",
]


@dataclass(frozen=True, eq=False)
class Control:
    """A negative control: a map and the reference of another place."""

    name: str
    map: OccupancyMap
    reference: OccupancyMap


@dataclass(frozen=True, eq=False)
class BrokenCase:
    """A broken map of known degree with its ground truth.

    Attributes
    ----------
    name : str
    map, reference : OccupancyMap
    expected_degree : int
    truths : list of RigidTransform
        Partition ``j``'s true transform, map cell -> reference cell.
    labels : ndarray of int16
        The true partition of each occupied map cell, -1 elsewhere.
    shares : list of float
        Each partition's share of the occupied cells.
    """

    name: str
    map: OccupancyMap
    reference: OccupancyMap
    expected_degree: int
    truths: list[RigidTransform]
    labels: NDArray[np.int16]
    shares: list[float]


def orebro_map(resolution: float = 0.1) -> OccupancyMap:
    """The bundled Orebro log mapped with its corrected poses (15 m range)."""
    from brokenness.simulation.carmen import map_log, read_carmen

    log = read_carmen(TESTS_DATA / "carmen" / "orebro-corrected.log.gz")
    return map_log(log, resolution=resolution, max_range=15.0)


def negative_controls() -> list[Control]:
    """Four pairs of maps of different places (each builds in well under a second or two)."""
    b31 = load_map(TESTS_DATA / "building_31.yaml")
    with warnings.catch_warnings():  # the Nav2 trap (205 grey read as free), as ROS reads it
        warnings.simplefilter("ignore", MapWarning)
        depot = load_map(TESTS_DATA / "depot.yaml")
    return [
        Control(
            "building_31 vs willow_slam", b31, load_map(TESTS_DATA / "willow-2010-02-18-0.10.yaml")
        ),
        Control("depot vs building_31", depot, b31),
        Control(
            "random axis-aligned walls vs orebro", random_walls(1, axis_aligned=True), orebro_map()
        ),
        Control("simulated 201 vs simulated 202", simulated_map(201), simulated_reference(202)),
    ]


#: (degree, seed) of the broken Orebro maps: 7 and 9 partitions, every one at least 5 %
#: (seeds whose first draws fit, so that they build fast).
BROKEN_OREBRO = ((6, 5), (8, 3))


def broken_real_log_maps() -> list[BrokenCase]:
    """The Orebro log at 0.1 m, degrees 6 and 8, in its own frame (see the module docstring)."""
    return [
        _drawn(
            f"orebro degree {degree} (seed {seed}, 0.1 m, own frame)",
            Case("orebro", degree, seed, 0.1, 0.1, "run"),
        )
        for degree, seed in BROKEN_OREBRO
    ]


def _drawn(name: str, case: Case, attempt: int = 0) -> BrokenCase:
    """The benchmark's case ``case`` drawn (map, reference, truths, labels), named ``name``;
    its draws tried from ``attempt`` on (the benchmark's accepted attempt of a case that
    rejects many: the same case, drawn without them)."""
    drawn = draw_case(case, first_attempt=attempt)
    if drawn is None:  # pragma: no cover - the draws are fixed by the seed
        raise RuntimeError(f"{name}: no draw fitted")
    return BrokenCase(
        name,
        drawn.map,
        drawn.reference,
        case.degree,
        drawn.truths(),
        drawn.labels,
        list(drawn.info["shares"]),
    )


def broken_simulated_maps() -> list[BrokenCase]:
    """A simulated building at 5 cm, degree 3, in its own frame (see the module docstring)."""
    case = Case("sim", 3, 17, 0.05, 0.05, "run")
    return [_drawn("simulated degree 3 (seed 17, 5 cm, own frame)", case)]


def lost_part_simulated_maps() -> list[BrokenCase]:
    """A simulated building of degree 6 in its own frame, against the run at 0.1 m (see the
    module docstring)."""
    case = Case("sim", 6, 23, 0.05, 0.1, "run")
    return [_drawn("simulated degree 6 (seed 23, 5 cm, run at 0.1 m)", case)]


def refit_rival_simulated_maps() -> list[BrokenCase]:
    """A simulated building of degree 6 at 5 cm in its own frame, against the run (see the
    module docstring)."""
    case = Case("sim", 6, 26, 0.05, 0.05, "run")
    return [_drawn("simulated degree 6 (seed 26, 5 cm, run)", case)]


def placed_part_real_log_maps() -> list[BrokenCase]:
    """Two maps of the CSAIL log at 5 cm, degree 7, in their own frame (see the module
    docstring)."""
    return [
        _drawn(
            f"csail degree 7 (seed {seed}, 5 cm, own frame)",
            Case("csail", 7, seed, 0.05, 0.05, "run"),
        )
        for seed in (7, 9)
    ]


def twin_replaced_real_log_maps() -> list[BrokenCase]:
    """The Orebro log at 5 cm, degree 7, in its own frame (see the module docstring)."""
    return [
        _drawn("orebro degree 7 (seed 7, 5 cm, own frame)", Case("orebro", 7, 7, 0.05, 0.05, "run"))
    ]


def split_part_drawn_maps() -> list[BrokenCase]:
    """The drawn atrium at 5 cm, degree 5, in its own frame (see the module docstring)."""
    case = Case("plan-atrium", 5, 0, 0.05, 0.05, "run")
    return [_drawn("drawn atrium degree 5 (seed 0, 5 cm, own frame)", case)]


def tied_twin_drawn_maps() -> list[BrokenCase]:
    """The drawn office at 5 cm, degree 7, in its own frame (see the module docstring)."""
    case = Case("plan-office", 7, 0, 0.05, 0.05, "run")
    return [_drawn("drawn office degree 7 (seed 0, 5 cm, own frame)", case)]


def twin_placed_simulated_maps() -> list[BrokenCase]:
    """Simulated buildings of degrees 4 and 7 in their own frame, against their plans (see the
    module docstring)."""
    return [
        _drawn("simulated degree 4 (seed 28, 5 cm, plan)", Case("sim", 4, 28, 0.05, 0.05, "plan")),
        _drawn(
            "simulated degree 7 (seed 10, 5 cm, plan at 0.1 m)",
            Case("sim", 7, 10, 0.05, 0.1, "plan"),
        ),
    ]


def split_piece_simulated_maps() -> list[BrokenCase]:
    """A simulated building of degree 8 at 5 cm in its own frame, against its plan (see the
    module docstring)."""
    case = Case("sim", 8, 43, 0.05, 0.05, "plan")
    return [_drawn("simulated degree 8 (seed 43, 5 cm, plan)", case, attempt=41)]


def region_placed_simulated_maps() -> list[BrokenCase]:
    """A simulated building of degree 7 at 5 cm in its own frame, against its plan (see the
    module docstring)."""
    case = Case("sim", 7, 25, 0.05, 0.05, "plan")
    return [_drawn("simulated degree 7 (seed 25, 5 cm, plan)", case, attempt=13)]


def split_piece_drawn_maps() -> list[BrokenCase]:
    """The drawn office at 0.1 m, degree 8, in its own frame, against its run at 5 cm (see
    the module docstring)."""
    case = Case("plan-office", 8, 0, 0.1, 0.05, "run")
    return [_drawn("drawn office degree 8 (seed 0, 0.1 m, run at 5 cm)", case, attempt=69)]


def twin_room_drawn_maps() -> list[BrokenCase]:
    """The drawn atrium at 5 cm, degree 6, in its own frame (see the module docstring)."""
    case = Case("plan-atrium", 6, 5, 0.05, 0.05, "run")
    return [_drawn("drawn atrium degree 6 (seed 5, 5 cm, own frame)", case, attempt=5)]
