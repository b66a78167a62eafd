"""Where else a partition's cells fit (:mod:`brokenness.measure.placement`).

Two rooms of the same shape in a reference, one of them split by a wall: a map of the
unsplit room fits both, and only its free space tells them apart. And the coarse count that
lets the search try every translation must never fall below the count at full resolution,
or a placement that explains enough cells could be missed.
"""

from __future__ import annotations

import numpy as np
import pytest
from _breaking import SETTINGS

from brokenness import OccupancyMap, RigidTransform
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.evidence import ClearFree, free_space
from brokenness.measure.partitions import Found
from brokenness.measure.placement import (
    CoarseAgreement,
    _best_shift,
    _coarse_peaks,
    _most_in_box,
    _templates,
    coarse_counts,
    free_placement,
)


def _outline(states: np.ndarray, top: int, left: int, bottom: int, right: int) -> None:
    states[top : bottom + 1, [left, right]] = OCCUPIED
    states[[top, bottom], left : right + 1] = OCCUPIED


def _reference(split: bool, side: int = 0) -> OccupancyMap:
    """Free space with two 61 x 71-cell rooms; the right one split by a wall if ``split``
    (unknown around it up to ``side`` cells a side)."""
    states = np.full((max(150, side), max(270, side)), UNKNOWN, np.int8)
    states[:150, :270] = FREE
    _outline(states, 30, 30, 90, 100)  # room A
    _outline(states, 30, 170, 90, 240)  # room B
    if split:
        states[30:91, 205] = OCCUPIED
    return OccupancyMap(states, 0.05)


def _room_map() -> OccupancyMap:
    """The room alone, free inside, unknown around."""
    states = np.full((90, 100), UNKNOWN, np.int8)
    states[10:71, 10:81] = FREE
    _outline(states, 10, 10, 70, 80)
    return OccupancyMap(states, 0.05)


AT_A = RigidTransform(0.0, 20.0, 20.0)
AT_B = RigidTransform(0.0, 160.0, 20.0)


def _placement(reference: OccupancyMap, held_at: RigidTransform) -> RigidTransform | None:
    room = _room_map()
    index = ReferenceIndex.build(reference)
    points = cell_points(room.occupied)
    found = [Found(held_at, np.arange(points.shape[0]), 1.0, 0.0)]
    free = free_space(found, points, ClearFree(room, SETTINGS.threshold), index)
    coarse = CoarseAgreement.of(index, SETTINGS.threshold)
    mine = free.points(free.owner == 0)
    return free_placement(points, held_at, [held_at.rotation], mine, index, coarse, SETTINGS)


def _at(placement: RigidTransform, room: RigidTransform) -> bool:
    """Whether ``placement`` puts the room's walls on those of ``room``'s placement (the room
    is symmetric: turned by 180 degrees about its centre it is the same room)."""
    centre = np.array([[45.0, 40.0]])
    moved, target = placement.apply(centre)[0], room.apply(centre)[0]
    turn = abs(np.degrees(placement.rotation)) % 180.0
    return bool(np.hypot(*(moved - target)) <= 1.5 and min(turn, 180.0 - turn) <= 1.0)


@pytest.mark.parametrize("side", [0, 2400])
def test_the_room_whose_free_space_fits_is_found_from_its_twin(side: int) -> None:
    # 2400 cells a side: coarse cells of 7, searched to the cell in two steps
    reference = _reference(split=True, side=side)
    assert CoarseAgreement.of(ReferenceIndex.build(reference), SETTINGS.threshold).pool == (
        7 if side else 4
    )
    placement = _placement(reference, held_at=AT_B)
    assert placement is not None
    assert _at(placement, AT_A)


def test_the_right_room_is_kept() -> None:
    # held in the room that fits, no other placement crosses fewer walls
    assert _placement(_reference(split=True), held_at=AT_A) is None


def test_twins_that_free_space_cannot_tell_apart_are_left_alone() -> None:
    assert _placement(_reference(split=False), held_at=AT_B) is None


@pytest.mark.parametrize("degrees", [0.0, 17.0, 90.0, 203.5])
def test_coarse_counts_are_never_below_full_resolution(
    corner: OccupancyMap, corner_index: ReferenceIndex, degrees: float
) -> None:
    threshold = SETTINGS.threshold
    coarse = CoarseAgreement.of(corner_index, threshold)
    assert coarse.pool == 4  # (pool - 1) / 2 < threshold
    # a wall-rich piece of the corner, as a partition's cells
    points = cell_points(corner.occupied[100:260, 120:300]) + [120.0, 100.0]
    angle = np.radians(degrees)
    ((counts, placement),) = coarse_counts(points, [angle], coarse)
    # the highest coarse counts (where the bound matters) and a spread of others
    order = np.argsort(counts, axis=None, kind="stable")[::-1]
    picked = np.concatenate([order[:12], order[12 :: max(1, order.size // 40)]])
    steps = np.arange(coarse.pool + 1)  # the translations a count stands for
    checked = 0
    for flat in picked.tolist():
        r, q = divmod(flat, counts.shape[1])
        lowest = placement(r, q)
        for dy in steps:
            for dx in steps:
                t = RigidTransform(angle, lowest.tx + dx, lowest.ty + dy)
                fine = np.count_nonzero(corner_index.occupied_agreement(t.apply(points), threshold))
                assert fine <= counts[r, q] + 1e-3
                checked += int(fine > 0)
    assert checked > 100  # the bound was tested where cells agree


@pytest.mark.parametrize("threshold", [1.0, 2.0, 3.5])
def test_coarse_counts_are_never_below_full_resolution_at_the_edges(threshold: float) -> None:
    # walls along the reference's first rows and columns, cells moved onto and past them
    rng = np.random.default_rng(7)
    states = np.full((120, 150), FREE, np.int8)
    states[rng.integers(0, 6, 400), rng.integers(0, 150, 400)] = OCCUPIED
    states[rng.integers(0, 120, 400), rng.integers(0, 6, 400)] = OCCUPIED
    index = ReferenceIndex.build(OccupancyMap(states, 0.05))
    coarse = CoarseAgreement.of(index, threshold)
    points = np.unique(rng.integers(0, 40, (300, 2)), axis=0).astype(np.float64)
    for angle in (0.0, 0.3, 2.0):
        ((counts, placement),) = coarse_counts(points, [angle], coarse)
        origin = placement(0, 0)  # a count's translations: placement(r, q) + [0, pool]
        checked = 0
        # the cells' lowest corner moved to around the reference's first cells
        low = RigidTransform(angle).apply(points).min(axis=0)
        for tx, ty in rng.uniform(-12.0, 10.0, (400, 2)) - low:
            r = int((ty - origin.ty) // coarse.pool)
            q = int((tx - origin.tx) // coarse.pool)
            t = RigidTransform(angle, tx, ty)
            fine = np.count_nonzero(index.occupied_agreement(t.apply(points), threshold))
            assert 0 <= r < counts.shape[0] and 0 <= q < counts.shape[1]
            assert fine <= counts[r, q] + 1e-3
            checked += int(fine > 0)
        assert checked > 100


def test_the_cell_search_lands_on_a_wall_between_two_equal_ones() -> None:
    # a line of cells midway between two parallel walls: shifted up or down it agrees alike,
    # and the middle of all the best shifts (their mean) would be where it started, on
    # neither wall
    states = np.full((100, 100), FREE, np.int8)
    states[40, 10:90] = OCCUPIED
    states[52, 10:90] = OCCUPIED
    index = ReferenceIndex.build(OccupancyMap(states, 0.05))
    line = np.column_stack([np.arange(30.0, 70.0), np.full(40, 46.0)])
    start = _best_shift(RigidTransform(), line, index, 2.0, np.arange(-8, 9))
    moved = start.apply(line)
    assert np.count_nonzero(index.occupied_agreement(moved, 2.0)) == line.shape[0]


def _cells_in(points: np.ndarray, left: int, top: int, side: int) -> np.ndarray:
    x, y = points[:, 0], points[:, 1]
    return points[(x >= left) & (x < left + side) & (y >= top) & (y < top + side)]


def test_a_part_mixed_with_other_borders_is_placed_at_its_walls_rotation() -> None:
    """A part's walls (a corner of a real building, turned by 40 degrees and shifted into the
    map's frame) mixed with half as many cells of another region turned its own way (the
    border of another part): at the rotations of the peaks of their Hough spectra against
    the reference's, the highest count over every translation is the part's place."""
    from pathlib import Path

    from brokenness import load_map
    from brokenness.measure.placement import placements
    from brokenness.registration.orientation import hough_spectrum, rotation_candidates

    reference = load_map(Path(__file__).parent / "data" / "building_31.yaml")
    index = ReferenceIndex.build(reference)
    walls = index.occupied_points
    truth = RigidTransform(np.radians(40.0), 250.0, -120.0)  # map cell -> reference cell
    part = np.rint(truth.inverse().apply(_cells_in(walls, 300, 300, 180)))
    other = RigidTransform(np.radians(-25.0), 30.0, 260.0).apply(_cells_in(walls, 80, 60, 120))
    other = np.rint(other)[: part.shape[0] // 2]
    cells = np.unique(np.vstack([part, other]), axis=0)
    angles = rotation_candidates(hough_spectrum(cells), hough_spectrum(walls), 4)
    coarse = CoarseAgreement.of(index, SETTINGS.threshold)
    first = next(placements(cells, angles, index, coarse, SETTINGS, SETTINGS.min_cells, 8))
    off = np.hypot(*(first.apply(part) - truth.apply(part)).T)
    assert float(np.median(off)) <= 1.0


@pytest.mark.parametrize("degrees", [0.0, 17.0, 45.0, 90.0, 203.5])
def test_a_rotation_skipped_for_its_spread_could_not_reach_the_floor(
    corner: OccupancyMap, corner_index: ReferenceIndex, degrees: float
) -> None:
    # the most cells one box of the agreement grid's extent holds bounds every coarse count
    # of the rotation, so a rotation skipped below the floor loses no placement
    coarse = CoarseAgreement.of(corner_index, SETTINGS.threshold)
    assert 0 < coarse.extent[0] <= coarse.grid.shape[0]
    assert 0 < coarse.extent[1] <= coarse.grid.shape[1]
    points = cell_points(corner.occupied[100:260, 120:300]) + [120.0, 100.0]
    angle = np.radians(degrees)
    ((counts, _),) = coarse_counts(points, [angle], coarse)
    ((_, _, template),) = _templates(points, [angle], coarse.pool)
    assert counts.max() <= _most_in_box(template, coarse.extent)


def test_only_rotations_that_cannot_reach_the_floor_are_skipped() -> None:
    # a long, thin reference: the cells of a long wall turned across it spread wider than
    # its walls, and no translation can count the floor of them there
    states = np.full((40, 400), FREE, np.int8)
    states[[5, 34], 10:390] = OCCUPIED
    index = ReferenceIndex.build(OccupancyMap(states, 0.05))
    coarse = CoarseAgreement.of(index, SETTINGS.threshold)
    wall = np.column_stack([np.arange(300.0), np.zeros(300)])  # 300 cells in a row
    along, across = 0.0, np.pi / 2
    floor = 250.0
    spread = [_most_in_box(t, coarse.extent) for _, _, t in _templates(wall, [along, across], 4)]
    assert spread[0] >= floor > spread[1]  # turned across, at most a box's height of cells
    peaks = _coarse_peaks(wall, [along, across], coarse, floor)
    assert peaks and all(abs(p.rotation - along) < 1e-9 for p in peaks)
    # counted anyway, the skipped rotation has no count at the floor to give
    (along_counts, _), (across_counts, _) = coarse_counts(wall, [along, across], coarse)
    assert along_counts.max() >= floor > across_counts.max()
