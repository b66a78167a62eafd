"""The thickness at which a map draws its walls, and the agreement threshold that covers it."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from brokenness import OccupancyMap, compute_brokenness, load_map, resample_to_resolution
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.masking import cell_points
from brokenness.measure.walls import LARGEST_THICKNESS, wall_thickness

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _thickness(mask: np.ndarray) -> int:
    return wall_thickness(cell_points(mask))


def _room(thickness: int, side: int = 80) -> np.ndarray:
    """The outline of a square room, its walls ``thickness`` cells thick."""
    mask = np.zeros((side + 20, side + 20), dtype=bool)
    mask[10 : 10 + side, 10 : 10 + side] = True
    mask[10 + thickness : 10 + side - thickness, 10 + thickness : 10 + side - thickness] = False
    return mask


@pytest.mark.parametrize("thickness", [1, 2, 3, 5])
def test_a_room_drawn_with_walls_of_each_thickness(thickness):
    assert _thickness(_room(thickness)) == thickness


def test_thin_diagonal_walls_and_speckle_count_as_one_cell():
    diagonal = np.eye(200, dtype=bool) | np.eye(200, k=1, dtype=bool)  # an 8-connected stair
    assert _thickness(diagonal) == 1
    speckle = np.random.default_rng(0).random((300, 300)) < 0.05
    assert _thickness(speckle) == 1
    assert wall_thickness(np.zeros((0, 2))) == 1


def test_most_cells_decide_and_solid_areas_stop_at_the_largest():
    # half the walls' cells in a 4-thick wall, the rest one cell thick: the majority's
    mixed = _room(1, side=200)
    mixed[300:, :] = False
    mixed = np.vstack([mixed, np.zeros((20, mixed.shape[1]), bool)])
    mixed[-12:-8, 10:210] = True  # 800 cells, against the room's 796
    assert _thickness(mixed) == 4
    block = np.ones((60, 60), dtype=bool)
    assert _thickness(block) == LARGEST_THICKNESS


def test_the_thickness_does_not_depend_on_the_grid_frame():
    walls = _room(3) | np.eye(100, dtype=bool)
    turned = np.rot90(walls)
    shifted = np.pad(walls, ((7, 0), (0, 13)))
    assert _thickness(walls) == _thickness(turned) == _thickness(shifted) == 3


def _thickened(m: OccupancyMap, side: int) -> OccupancyMap:
    """``m`` with its walls dilated by a ``side`` x ``side`` square (free cells included)."""
    states = np.array(m.states)
    occupied = (states == OCCUPIED).astype(np.uint8)
    states[cv2.dilate(occupied, np.ones((side, side), np.uint8)) > 0] = OCCUPIED
    return OccupancyMap(states, m.resolution, m.origin)


def test_a_coarse_map_with_thick_walls_is_measured_with_a_threshold_that_covers_them():
    # The bundled broken example (degree 2) at 0.1 m, its walls thickened to 4 map cells,
    # against the reference at 0.05 m: upsampled, a wall is 8 working cells across, and at
    # c = 2 most of the map's cells could not agree under the true transforms (45 % did:
    # not measured). The threshold covers the band about the wall, (4 + 1) / 2 map cells.
    broken = resample_to_resolution(load_map(EXAMPLES / "broken_building_31.yaml"), 0.1)
    reference = load_map(EXAMPLES / "building_31.yaml")
    thick = _thickened(broken, 3)
    assert _thickness(thick.occupied) == 4
    result = compute_brokenness(thick, reference)
    assert result.measured
    assert result.degree == 2
    assert result.parameters["threshold"] == 2.0  # as asked, for the record
    assert result.parameters["working_threshold"] == pytest.approx(5.0)
    # the same partitions as the map with its own walls, about the same cells each
    thin = compute_brokenness(broken, reference)
    assert thin.degree == 2
    for p, q in zip(result.partitions, thin.partitions, strict=True):
        cells = cell_points(broken.occupied)
        assert np.median(p.transform.displacement(q.transform, cells)) < 3.0


def test_walls_three_cells_thick_at_the_references_resolution_change_nothing():
    # the band about a wall reaches one cell to either side: c = 2 covers it, c stays as asked
    ref = load_map(EXAMPLES / "building_31.yaml")
    states = np.array(ref.states)
    states[states == UNKNOWN] = FREE
    two = OccupancyMap(states, ref.resolution, ref.origin)
    two = _thickened(two, 2)
    assert _thickness(two.occupied) == 3
    result = compute_brokenness(two, ref)
    assert result.degree == 0
    assert result.parameters["working_threshold"] == 2.0
