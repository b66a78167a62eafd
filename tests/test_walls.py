"""The thickness at which a map draws its walls, and the agreement threshold that covers it."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from brokenness import (
    OccupancyMap,
    compute_brokenness,
    load_map,
    resample_to_resolution,
    save_map,
)
from brokenness.cli.main import main
from brokenness.errors import NothingFoundWarning
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.masking import cell_points
from brokenness.measure.walls import LARGEST_THICKNESS, wall_thickness

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
_BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
if str(_BENCH) not in sys.path:
    sys.path.insert(0, str(_BENCH))

from thick_walls import thickened  # noqa: E402  (the benchmark's own dilation)


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


def test_most_wall_cells_decide():
    # half the walls' cells in a 4-thick wall, the rest one cell thick: the majority's
    mixed = _room(1, side=200)
    mixed = np.vstack([mixed, np.zeros((20, mixed.shape[1]), bool)])
    mixed[-12:-8, 10:210] = True  # 800 cells, against the room's 796
    assert _thickness(mixed) == 4
    mixed[-12:-8, 10:14] = False  # 784 against 796
    assert _thickness(mixed) == 1


def test_solids_count_as_the_largest_thickness():
    # the outside of a building drawn occupied (a solid), thin walls inside it
    outside = np.ones((200, 200), dtype=bool)
    outside[40:160, 40:160] = False
    outside[100, 40:160] = True
    assert _thickness(outside) == LARGEST_THICKNESS
    assert _thickness(np.ones((60, 60), dtype=bool)) == LARGEST_THICKNESS
    assert _thickness(_room(LARGEST_THICKNESS + 2)) == LARGEST_THICKNESS


def test_a_large_box_is_looked_at_in_bands_spread_over_it():
    # a room of 3-cell walls in a box of 3000 x 3000 cells: more than the 4,000,000 cells
    # looked at in full, the same thickness from the bands
    big = np.zeros((3000, 3000), dtype=bool)
    big[100:2900, 100:2900] = _room(3, side=2800)[10:2810, 10:2810]
    for row in range(300, 2700, 300):
        big[row : row + 3, 100:2900] = True
    assert _thickness(big) == 3


def test_the_thickness_does_not_depend_on_the_grid_frame():
    walls = _room(3) | np.eye(100, dtype=bool)
    turned = np.rot90(walls)
    shifted = np.pad(walls, ((7, 0), (0, 13)))
    assert _thickness(walls) == _thickness(turned) == _thickness(shifted) == 3


def test_the_command_line_says_why_the_threshold_was_raised(tmp_path, capsys):
    broken = resample_to_resolution(load_map(EXAMPLES / "broken_building_31.yaml"), 0.1)
    save_map(thickened(broken, 3), tmp_path / "thick.yaml")
    reference = str(EXAMPLES / "building_31.yaml")
    assert main(["compute", str(tmp_path / "thick.yaml"), reference]) == 0
    out = capsys.readouterr().out
    assert "degree of brokenness: 2" in out
    assert (
        "threshold: 4.5 working cells, not 2: how far the map draws a wall beyond the "
        "reference's drawing of it; the map draws its walls 4 of its cells thick"
    ) in out
    assert main(["compute", str(EXAMPLES / "broken_building_31.yaml"), reference]) == 0
    assert "threshold:" not in capsys.readouterr().out  # not raised: no line


def test_a_coarse_map_with_thick_walls_is_measured_with_a_threshold_that_covers_them():
    # The bundled broken example (degree 2) at 0.1 m, its walls thickened to 4 map cells,
    # against the reference at 0.05 m (walls of 2 cells): upsampled, a wall is 8 working
    # cells across, and at c = 2 most of the map's cells could not agree under the true
    # transforms (45 % did: not measured). The threshold covers the band about the wall
    # beyond the reference's: 2 (4 + 1) / 2 - (2 - 1) / 2 working cells.
    broken = resample_to_resolution(load_map(EXAMPLES / "broken_building_31.yaml"), 0.1)
    reference = load_map(EXAMPLES / "building_31.yaml")
    thick = thickened(broken, 3)
    assert _thickness(thick.occupied) == 4
    assert _thickness(reference.occupied) == 2
    result = compute_brokenness(thick, reference)
    assert result.measured
    assert result.degree == 2
    assert result.parameters["threshold"] == 2.0  # as asked, for the record
    assert result.parameters["working_threshold"] == pytest.approx(4.5)
    # the same partitions as the map with its own walls, about the same cells each
    thin = compute_brokenness(broken, reference)
    assert thin.degree == 2
    cells = cell_points(broken.occupied)
    for p, q in zip(result.partitions, thin.partitions, strict=True):
        assert np.median(p.transform.displacement(q.transform, cells)) < 3.0


def test_walls_three_cells_thick_at_the_references_resolution_change_nothing():
    # the band about a wall reaches one cell to either side: c = 2 covers it, c stays as asked
    ref = load_map(EXAMPLES / "building_31.yaml")
    states = np.array(ref.states)
    states[states == UNKNOWN] = FREE
    two = thickened(OccupancyMap(states, ref.resolution, ref.origin), 2)
    assert _thickness(two.occupied) == 3
    result = compute_brokenness(two, ref)
    assert result.degree == 0
    assert result.parameters["working_threshold"] == 2.0


def test_a_reference_drawn_as_thick_as_the_map_needs_no_more():
    # both maps' walls thickened alike: the reference's band holds the map's
    broken = thickened(load_map(EXAMPLES / "broken_building_31.yaml"), 5)
    reference = thickened(load_map(EXAMPLES / "building_31.yaml"), 5)
    assert _thickness(broken.occupied) == _thickness(reference.occupied) >= 5
    result = compute_brokenness(broken, reference)
    assert result.degree == 2
    assert result.parameters["working_threshold"] == 2.0


def test_a_map_of_solids_keeps_the_threshold():
    # the outside of the building drawn occupied: no band about its walls to tell
    m = load_map(EXAMPLES / "building_31.yaml")
    states = np.pad(np.array(m.states), 120, constant_values=OCCUPIED)
    solid = OccupancyMap(states, m.resolution)
    assert _thickness(solid.occupied) == LARGEST_THICKNESS
    with pytest.warns(NothingFoundWarning):  # the solid is most of its occupied cells
        result = compute_brokenness(resample_to_resolution(solid, 0.1), m)
    assert result.parameters["working_threshold"] == 2.0


def test_an_upsampled_reference_holds_the_wall_anywhere_in_its_middle_cell():
    # a map at 0.05 m, walls 7 cells thick, against the reference at 0.1 m (walls 2 of its
    # cells): upsampled, each reference cell is 2 working cells and the wall anywhere in
    # the middle one, so the reference surely reaches 2 (2 - 1) / 2 working cells beyond
    # it: c = 1 + (7 - 1) / 2 - 1 (not the 1.5 of a band of 4 working cells drawn about it)
    broken = thickened(load_map(EXAMPLES / "broken_building_31.yaml"), 5)
    reference = resample_to_resolution(load_map(EXAMPLES / "building_31.yaml"), 0.1)
    assert _thickness(broken.occupied) == 7
    assert _thickness(reference.occupied) == 2
    result = compute_brokenness(broken, reference)
    assert result.degree == 2
    assert result.parameters["working_resolution"] == pytest.approx(0.05)
    assert result.parameters["working_threshold"] == pytest.approx(3.0)
