"""Maps and references that cover different areas (``benchmarks/partial_reference.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brokenness import OccupancyMap, compute_brokenness, load_map

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _crop(m: OccupancyMap, rows: slice, cols: slice) -> OccupancyMap:
    return OccupancyMap(np.ascontiguousarray(m.states[rows, cols]), m.resolution)


@pytest.fixture(scope="module")
def building() -> OccupancyMap:
    return load_map(EXAMPLES / "building_31.yaml")


def test_map_within_its_reference_is_measured_on_what_it_shows(building):
    # a map of the left part of the building against the whole: unbroken
    part = _crop(building, slice(None), slice(0, round(0.6 * building.shape[1])))
    result = compute_brokenness(part, building)
    assert result.measured and result.degree == 0


def test_broken_map_keeps_the_parts_its_reference_sees(building):
    # the bundled example (degree 2) against the reference without its bottom tenth: every
    # part is still seen, and still found
    broken = load_map(EXAMPLES / "broken_building_31.yaml")
    reference = _crop(building, slice(0, round(0.9 * building.shape[0])), slice(None))
    result = compute_brokenness(broken, reference)
    assert result.measured and result.degree == 2


def test_map_past_its_reference_keeps_what_lies_beyond_unassigned(building):
    # the unbroken map of the whole building against a reference of its left 70 %: the
    # cells beyond the reference fit elsewhere on it only by chance, each such placement
    # explaining a part of its region only (0.63 of it here, session 30), so none is a
    # partition (measure/explained.py) and those cells stay unassigned (before: degree 2)
    reference = _crop(building, slice(None), slice(0, round(0.7 * building.shape[1])))
    result = compute_brokenness(building, reference)
    assert result.measured and result.degree == 0
    beyond = building.occupied[:, round(0.7 * building.shape[1]) + 5 :]
    assert result.unassigned_cells >= 0.8 * np.count_nonzero(beyond)


def test_map_past_its_reference_of_repeated_rooms_is_not_broken(building):
    # against a reference of its left 80 %: until session 45 degree 3, measured, three
    # placements of the cells beyond it at other rooms, each explaining 86-95 % of its
    # region (a strict expected failure). They are in doubt (their own free space does not
    # show their place), and since session 46 step 11 asks for the partitions in doubt to
    # be found again with the grid turned by a half turn: none of their cells is
    reference = _crop(building, slice(None), slice(0, round(0.8 * building.shape[1])))
    result = compute_brokenness(building, reference)
    assert not result.measured or result.degree == 0
