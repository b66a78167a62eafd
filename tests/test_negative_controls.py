"""Negative controls: pairs that must not get a degree (the map is not of the reference's
place), and the contradiction measure that tells them apart."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

import brokenness
from brokenness import OccupancyMap, RigidTransform, compute_brokenness, load_map
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.evidence import MAP_RATIO, ClearFree, contradiction
from brokenness.measure.explained import MAP_SHARE
from brokenness.measure.partitions import Found

DATA = Path(__file__).parent / "data"


def _load(name: str) -> OccupancyMap:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # depot's Nav2 grey warning
        return load_map(DATA / name)


def _random_walls(shape: tuple[int, int], n: int, seed: int) -> OccupancyMap:
    """Seeded random wall segments (0.5-6 m at 5 cm), free around them."""
    rng = np.random.default_rng(seed)
    img = np.zeros(shape, np.uint8)
    for _ in range(n):
        x0, y0 = int(rng.integers(0, shape[1])), int(rng.integers(0, shape[0]))
        angle, length = rng.uniform(0, np.pi), rng.uniform(10, 120)
        x1, y1 = int(x0 + length * np.cos(angle)), int(y0 + length * np.sin(angle))
        cv2.line(img, (x0, y0), (x1, y1), 1, 1)
    return OccupancyMap.from_array(img.astype(bool), resolution=0.05)


def _not_measured(m: OccupancyMap, ref: OccupancyMap) -> brokenness.BrokennessResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", brokenness.NothingFoundWarning)
        return compute_brokenness(m, ref)


@pytest.mark.parametrize(
    ("map_name", "reference_name"),
    [
        ("building_31.yaml", "willow-2010-02-18-0.10.yaml"),
        ("willow-2010-02-18-0.10.yaml", "building_31.yaml"),
        ("depot.yaml", "building_31.yaml"),
        ("building_31.yaml", "depot.yaml"),
        ("tb3_sandbox.yaml", "building_31.yaml"),
    ],
)
def test_a_map_of_another_building_gets_no_degree(map_name, reference_name):
    """Before the contradiction test these got degrees 10, 2, 11, 1 and 3."""
    result = _not_measured(_load(map_name), _load(reference_name))
    assert not result.measured and result.degree is None, result.partitions
    assert result.contradiction is not None and result.contradiction_bound is not None
    assert result.contradiction_bound > result.contradiction
    assert result.to_dict()["contradiction_bound"] == result.contradiction_bound
    # the decision rests on the share of the map its partitions hold, or on the upper bound
    # of the free space's ratio, above the limit
    assert result.reason is not None
    by_share = result.reason.startswith("only")
    assert by_share or result.contradiction_bound > MAP_RATIO
    if by_share:
        assert 1.0 - result.unassigned_fraction < MAP_SHARE


def test_random_walls_get_no_degree():
    """Random wall segments against a real building (degree 7 before)."""
    ref = _load("building_31.yaml")
    result = _not_measured(_random_walls(ref.shape, 60, 1), ref)
    assert not result.measured and result.degree is None


def test_another_simulated_building_gets_no_degree():
    """Two buildings of the same generator (rooms of the same sizes): degree 4 before."""
    one = brokenness.simulate_broken_map(seed=1, degree=0)
    other = brokenness.simulate_broken_map(seed=2, degree=0)
    result = _not_measured(one.map, other.reference)
    assert not result.measured and result.degree is None


def test_another_simulated_building_measured_on_partitions_in_doubt_is_measured_again():
    """Simulated building 203's map turned 180 degrees against 202's reference: degree 5
    before step 11 (its free space's upper bound 0.485, under the limit of 0.5), on six
    partitions of which four, holding about two thirds of the map, were in doubt. Measured
    again with its grid turned back (the map's own frame, which refuses it), it is refused
    (step 11, session 38)."""
    from _controls import simulated_map, simulated_reference

    from brokenness.measure.frames import in_frame, partitions_in_doubt

    turned, _ = in_frame(simulated_map(203), "turned 180")
    result = _not_measured(turned, simulated_reference(202))
    assert not result.measured and result.degree is None
    assert result.parameters["replication_frame"] == "turned 180"
    assert result.parameters["replication_degree"] is None
    assert "turned 180" in result.reason
    assert partitions_in_doubt(result)  # what sent it to be measured again


def test_a_building_no_rule_was_chosen_on_measured_with_partitions_in_doubt_is_refused():
    """Simulated building 206's unbroken map against 211's reference, in the map's own
    frame: two buildings of the generator that no rule of the measure was chosen on
    (``benchmarks/fresh_controls.py``). Before session 39 it got degree 6 (free space at
    0.42 of chance, upper bound 0.489), with partitions holding 55 % of the map shown in
    place and five in doubt, so session 38's step 11 did not ask for it again; asked with
    every map that has a partition in doubt, the grid turned 180 degrees refuses it."""
    from _controls import simulated_map, simulated_reference

    from brokenness.measure.frames import partitions_in_doubt

    result = _not_measured(simulated_map(206), simulated_reference(211))
    assert not result.measured and result.degree is None
    assert result.parameters["replication_frame"] == "turned 180"
    assert result.parameters["replication_degree"] is None
    assert partitions_in_doubt(result)


def test_another_simulated_building_in_another_grid_frame_gets_no_degree():
    """Simulated building 202's map against 201's reference: refused in the map's own frame,
    but turned by a quarter turn (the same cells) it got degree 7, its free space at 0.41
    of chance (upper bound 0.48, under the limit of 0.5), its partitions wall pieces from all
    over the map (sessions 32 and 35), and turned a half turn further (step 11) degree 7
    again (sessions 38-42: a strict xfail). The two are other partitionings: the half-turned
    frame places none of its partitioned cells where the quarter-turned one does, and since
    session 43 the replication must place half of them alike."""
    from _controls import simulated_map, simulated_reference

    from brokenness.measure.frames import REPLICATED_SHARE, in_frame

    m, ref = simulated_map(202), simulated_reference(201)
    assert not _not_measured(m, ref).measured  # its own frame refuses it
    turned, _ = in_frame(m, "turned 90")
    result = _not_measured(turned, ref)
    assert not result.measured and result.degree is None, result.degree
    assert result.parameters["replication_degree"] is not None  # measured there, elsewhere
    assert result.parameters["replication_placed_alike"] < REPLICATED_SHARE
    assert "on other partitions" in (result.reason or "")


def test_a_fresh_simulated_building_fitted_on_a_shared_shell_gets_no_degree():
    """Fresh simulated building 217's map against 216's reference (the two share the
    generator's shell; seeds no rule was chosen on, session 46): in the map's own frame the
    shell and most rooms fit at nearly the identity (46 % of the map, its free space well
    in place), and five wall pieces elsewhere, three of them in doubt, got degree 5. The
    half-turned frame placed half of the partitioned cells alike (the shell again), none of
    those in doubt: the replication must find the partitions in doubt again."""
    from _controls import simulated_map, simulated_reference

    result = _not_measured(simulated_map(217), simulated_reference(216))
    assert not result.measured and result.degree is None, result.degree
    assert result.parameters["replication_placed_alike"] >= 0.5
    assert result.parameters["replication_placed_alike_in_doubt"] < 0.5
    assert "of the cells of its partitions in doubt placed alike" in (result.reason or "")


def test_positive_pairs_stay_measured():
    """The bundled broken example and a map against itself keep their degree."""
    example = Path(__file__).parents[1] / "examples"
    result = compute_brokenness(
        load_map(example / "broken_building_31.yaml"), load_map(example / "building_31.yaml")
    )
    assert result.measured and result.degree == 2
    assert result.contradiction is not None and result.contradiction < 0.2
    bound = result.contradiction_bound
    assert bound is not None and result.contradiction < bound <= MAP_RATIO
    b31 = _load("building_31.yaml")
    assert compute_brokenness(b31, b31).degree == 0


def _room_states() -> np.ndarray:
    states = np.full((100, 140), UNKNOWN, np.int8)
    states[10:90, 10:130] = FREE
    states[10, 10:130] = states[89, 10:130] = OCCUPIED
    states[10:90, 10] = states[10:90, 129] = OCCUPIED
    states[10:60, 70] = OCCUPIED  # an inner wall
    return states


def test_contradiction_is_zero_aligned_and_high_when_misplaced():
    """Free space moved onto the reference's walls contradicts; aligned, it never does."""
    room = OccupancyMap(_room_states())
    index = ReferenceIndex.build(room)
    points = cell_points(room.occupied)
    every = np.arange(points.shape[0])
    aligned = contradiction(
        [Found(RigidTransform(), every, 1.0, 0.0)], points, ClearFree(room, 2.0), index
    )
    assert aligned.contradicting.sum() == 0 and aligned.counted.sum() > 1000
    assert aligned.ratio() == 0.0
    # shifted by 30 cells, the inner wall of the reference crosses the map's free space
    shifted = contradiction(
        [Found(RigidTransform(0.0, 30.0, 0.0), every, 1.0, 0.0)],
        points,
        ClearFree(room, 2.0),
        index,
    )
    assert shifted.contradicting.sum() > 100
    assert shifted.ratio() is not None and shifted.ratio() > 0.25
    # chance rate: the occupied share of the known reference cells
    assert aligned.chance == pytest.approx(
        np.count_nonzero(room.occupied) / np.count_nonzero(room.known)
    )


def _room_in_two() -> tuple[OccupancyMap, ReferenceIndex, np.ndarray, np.ndarray, np.ndarray]:
    """The room as map and reference; the inner wall's cells apart from the rest."""
    room = OccupancyMap(_room_states())
    points = cell_points(room.occupied)
    inner = np.flatnonzero((points[:, 0] == 70) & (points[:, 1] > 10) & (points[:, 1] < 60))
    rest = np.setdiff1d(np.arange(points.shape[0]), inner)
    return room, ReferenceIndex.build(room), points, inner, rest


def test_the_walls_that_bound_the_free_space_own_it():
    """The room's outer walls lie just outside the box of its free cells: they still own the
    free space in front of them, and free cells next to them are not clear (before, only the
    inner wall's partition owned free space, and every free cell next to an outer wall was
    counted as clear)."""
    room, index, points, inner, rest = _room_in_two()
    two = [Found(RigidTransform(), rest, 1.0, 0.0), Found(RigidTransform(), inner, 1.0, 0.0)]
    split = contradiction(two, points, ClearFree(room, 2.0), index)
    assert split.counted[0] > 2 * split.counted[1] > 0
    whole = contradiction(
        [Found(RigidTransform(), np.arange(points.shape[0]), 1.0, 0.0)],
        points,
        ClearFree(room, 2.0),
        index,
    )
    # clear: farther than 2c = 4 cells from every wall, in the 78 x 118 free interior
    clear = np.zeros((100, 140), bool)
    clear[15:85, 15:125] = True
    clear[10:65, 65:76] = False  # around the inner wall (rows 10-59, column 70)
    assert int(whole.counted.sum()) == pytest.approx(np.count_nonzero(clear), rel=0.05)


# -- the benchmark's fixtures (tests/_controls.py): controls and heavily broken real maps ------
def _true_matches(result, case, tolerance: float = 3.0) -> int:
    """How many found partitions match a distinct true part: one to one, each putting the
    part's cells (median) within ``tolerance`` reference cells of its true place (the
    benchmark's criterion)."""
    from scipy.optimize import linear_sum_assignment

    found = [p.transform for p in result.partitions]
    fits = np.zeros((len(found), len(case.truths)), dtype=bool)
    for q, truth in enumerate(case.truths):
        pts = cell_points(case.labels == q)
        for j, t in enumerate(found):
            fits[j, q] = float(np.median(t.displacement(truth, pts))) <= tolerance
    rows, cols = linear_sum_assignment(~fits)
    return int(fits[rows, cols].sum())


def test_benchmark_controls_are_not_measured():
    from _controls import negative_controls

    for control in negative_controls():
        result = _not_measured(control.map, control.reference)
        assert not result.measured and result.degree is None, control.name


def test_heavily_broken_real_log_maps_get_their_true_partitions():
    """The Orebro log at 0.1 m in its own frame, broken into 7 and 9 parts of at least 5 %
    each: measured with the exact degree. The degree-8 map gets every part at its true place
    (before the wider search of session 15, three of its 5-7 % parts were lost: degree 5).
    The degree-6 map has one known shortfall: one of its 5 % parts is held by a partition at a
    wrong place (the README's "Current status"), so one partition there may be wrong, not
    more, and nothing beyond the expected degree."""
    from _controls import broken_real_log_maps

    for case in broken_real_log_maps():
        result = compute_brokenness(case.map, case.reference)
        assert result.measured, (case.name, result.reason)
        assert result.degree == case.expected_degree, case.name
        wrong_allowed = 1 if case.expected_degree == 6 else 0
        assert _true_matches(result, case) >= len(result.partitions) - wrong_allowed, case.name


def _all_true(cases) -> None:  # noqa: ANN001
    """Each case measured, with the exact degree and every part at its true place."""
    for case in cases:
        result = compute_brokenness(case.map, case.reference)
        assert result.measured, (case.name, result.reason)
        assert result.degree == case.expected_degree, case.name
        assert _true_matches(result, case) == len(case.truths), case.name


def test_a_small_part_held_at_a_twin_of_its_place_is_moved_to_its_own():
    """A part of 6-7 % of the cells, registered where a turned twin of its room is: its walls
    fit there within a few cells of its true place, and its free space crosses the reference's
    walls there. Its neighbourhood registered alone gives the true place, and the free space
    takes it (session 18; before, the degree was exact and that partition wrong)."""
    from _controls import twin_placed_simulated_maps

    _all_true(twin_placed_simulated_maps())


def test_a_twin_that_explains_as_many_cells_gives_way_to_a_clearer_free_space():
    """A part of 7 % of a drawn office's cells held 700 cells off its place, where its walls
    explain exactly as many cells as at its place (the recovery finds the true transform):
    the count cannot choose, the free space can (0.43 of the chance rate at the twin, 0.03
    at its place). Session 28; before, the degree was exact and that partition wrong."""
    from _controls import tied_twin_drawn_maps

    _all_true(tied_twin_drawn_maps())


def test_a_twin_whose_free_space_shows_it_in_place_gives_way_to_the_part_registered_alone():
    """A part of 4.5 % of a drawn atrium's cells held 144 cells off, at the half-turned twin
    of its room, where its free space crosses the reference's walls at 0.46 of the chance
    rate (not in doubt). Its own cells registered alone give its place, which explains 105
    more cells of the map. Session 41; before, the degree was exact and that partition
    wrong."""
    from _controls import twin_room_drawn_maps

    _all_true(twin_room_drawn_maps())


def test_two_touching_pieces_of_one_part_registered_together_give_its_place():
    """A simulated building broken into 9 parts, against its plan: two parts of 6-7 % held at
    twins of their rooms and a third (10 %) split in two, one piece at a twin, for a degree
    of 9. Registered alone, no piece's cells (nor its neighbourhood) gave the part's place;
    the two doubtful partitions that touch in the map, registered together, give it (session
    29; before, the degree was 9 with three partitions wrong)."""
    from _controls import split_piece_simulated_maps

    _all_true(split_piece_simulated_maps())


def test_a_doubtful_piece_registered_with_the_partition_it_touches_gives_its_place():
    """A drawn office broken into 9 parts came out degree 10, with a part split in two
    pieces at twins; only one piece's free space failed on its own. Registered together
    with the partition it touches, it gives the part's place (session 29; before, the
    degree was 10)."""
    from _controls import split_piece_drawn_maps

    _all_true(split_piece_drawn_maps())


def test_a_part_whose_suspects_are_too_few_is_placed_from_the_region_around_them():
    """A part of 7 % of the cells that four partitions found before it take most of: 147 of
    its 626 cells are left as dense suspects, too few to count a placement on, and no
    registration gives its place. The region around them, placed with all its cells, does,
    and the part is counted by the cells it takes over the whole map (session 30; before,
    the degree came out one short)."""
    from _controls import region_placed_simulated_maps

    _all_true(region_placed_simulated_maps())


def test_a_small_part_scattered_among_suspects_is_found_from_its_region():
    """A part of 5 % of the cells that the partitions found before it take most of: its
    remaining cells are two fifths of the suspects, mixed with other parts' borders, and the
    suspects registered alone give no hypothesis near its place. The region around the group
    of suspects, registered with all its cells, does, and the part is counted (session 22;
    before, the degree came out one short)."""
    from _controls import lost_part_simulated_maps

    _all_true(lost_part_simulated_maps())


def test_a_part_at_a_twin_is_moved_by_a_rival_refitted_on_its_cells():
    """A part of 7 % of the cells held at a twin of its room 406 cells off: the relocation
    finds a rival 1.7 cells from its place, which makes fewer cells agree than the twin does
    (9 fewer over the map) and was refused; refitted on the partition's cells (as the settle
    step refits its own candidates) it lands within half a cell, makes 14 more agree, and is
    taken (session 22; before, the degree was exact and that partition wrong)."""
    from _controls import refit_rival_simulated_maps

    _all_true(refit_rival_simulated_maps())


def test_a_map_whose_parts_overlap_heavily_is_refused_rather_than_misread():
    """Four partitions of a simulated building whose free space overlaps in the map's frame:
    every part is found at its true place, but charged to its nearest wall's partition the
    free space crosses the reference's walls at about half the chance rate, and the upper
    bound is above the limit: the degree is refused, with the free-space reason (the price of
    the test's margin against maps of other places; docs/benchmark-history.md, "What
    sessions 13 and 14 changed")."""
    from _controls import broken_simulated_maps

    for case in broken_simulated_maps():
        with pytest.warns(brokenness.NothingFoundWarning, match="not measured"):
            result = compute_brokenness(case.map, case.reference)
        assert not result.measured and result.degree is None, case.name
        assert "free space crosses the reference's walls" in result.reason, case.name
        assert result.contradiction is not None and result.contradiction_bound is not None
        assert result.contradiction < result.contradiction_bound
        assert result.contradiction_bound > MAP_RATIO
        assert _true_matches(result, case) == len(case.truths), case.name


def test_a_part_whose_suspects_give_no_rotation_is_placed_at_its_walls():
    """Two heavily broken maps of a real log (CSAIL, degree 7): a part of 6-8 % of the cells
    is left as suspects mixed with other parts' borders, and their registration gives no
    hypothesis within 20 degrees of its rotation. Placed at the rotations that turn their
    walls onto the reference's (the Hough spectra), every translation counted, they give the
    part's place within a cell (session 23; before, one map came out a degree short and the
    other held the part at a twin)."""
    from _controls import placed_part_real_log_maps

    _all_true(placed_part_real_log_maps())


def test_a_part_found_at_its_place_replaces_its_twin():
    """A 5 % part of a real-log map held at a twin of its room 950 cells off: the recovery
    finds its true place among the suspects (0.1 cells off), and every cell given to its best
    partition, the new partition takes the part's cells from the twin and leaves the twin too
    few of its own. The map keeps its count of partitions, with the part in place (session
    23; before, the new partition was refused because the count did not grow, and the twin
    stayed)."""
    from _controls import twin_replaced_real_log_maps

    _all_true(twin_replaced_real_log_maps())


def test_pieces_of_one_part_held_at_twins_are_one_partition():
    """A part of 21 % of a drawn atrium's cells (five corridors 72 degrees apart) held as
    three partitions, each at a twin of its place among the turned arms: together they
    explain what the part does, so no count of explained cells tells them from it. One
    transform, a piece's followed by a turn of the reference onto itself, explains all three:
    step 10 makes them one partition (session 37; degree 7 for 5 before)."""
    from _controls import split_part_drawn_maps

    _all_true(split_part_drawn_maps())
