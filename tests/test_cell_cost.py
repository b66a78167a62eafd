"""Steps whose cost follows the cells (issue 14) give what the grid-wide versions gave."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from brokenness import OccupancyMap, load_map
from brokenness.grid import OCCUPIED
from brokenness.masking import (
    ReferenceIndex,
    cell_points,
    unmatched_reference,
    within_manhattan,
)
from brokenness.masking.distance import beyond, compact_distance_map, within
from brokenness.measure.partitions import cell_components
from brokenness.measure.views import (
    isolated_cells,
    isolated_points,
    remainder_cells,
    remainder_states,
)
from brokenness.registration import IFMIRegistrar, _refine
from brokenness.registration._spectral import coarse_indicator
from brokenness.registration.base import OccupiedCells

DATA = Path(__file__).parent / "data"


def _speckled(seed: int, shape: tuple[int, int] = (70, 90)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    occ = rng.random(shape) < 0.02  # isolated specks
    occ[10, 5:80] = occ[10:60, 30] = occ[55, 20:70] = True  # walls
    return occ


@pytest.mark.parametrize("seed", range(5))
def test_isolated_points_match_the_box_filter(seed: int) -> None:
    occ = _speckled(seed)
    rows, cols = np.nonzero(occ)
    expected = isolated_cells(occ)[rows, cols]
    got = isolated_points(rows, cols)
    assert got.any() and not got.all()
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("seed", range(6))
def test_isolated_points_of_sparse_cells_in_any_order(seed: int) -> None:
    # a box far larger than the cells (the sorted lookups, not the box filter), with cells
    # on the box's edges, in clusters across rows and alone; row-major and shuffled
    rng = np.random.default_rng(seed)
    grid = np.zeros((300, 400), dtype=bool)
    grid.flat[rng.choice(grid.size, 60, replace=False)] = True
    grid[0, :3] = grid[-1, -3:] = grid[:2, -1] = True
    for r, c in rng.integers(2, 290, size=(12, 2)):
        grid[r : r + rng.integers(1, 4), c : c + rng.integers(1, 4)] = True
    rows, cols = np.nonzero(grid)
    assert grid.size > 64 * rows.size
    expected = isolated_cells(grid)[rows, cols]
    assert expected.any() and not expected.all()
    np.testing.assert_array_equal(isolated_points(rows, cols), expected)
    shuffle = rng.permutation(rows.size)
    np.testing.assert_array_equal(isolated_points(rows[shuffle], cols[shuffle]), expected[shuffle])


@pytest.mark.parametrize("drop_isolated", [False, True])
def test_remainder_cells_are_the_occupied_cells_of_the_remainder(drop_isolated: bool) -> None:
    occ = _speckled(7)
    states = np.where(occ, 1, 0).astype(np.int8)
    states[:5] = -1
    working = OccupancyMap(states)
    points = cell_points(working.occupied)
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    remaining = np.random.default_rng(0).random(points.shape[0]) < 0.6
    grid = remainder_states(working, rows, cols, remaining, False, drop_isolated)
    cells = remainder_cells(working.shape, rows, cols, remaining, drop_isolated)
    np.testing.assert_array_equal(cells.states() == OCCUPIED, grid == OCCUPIED)
    assert cells.count == np.count_nonzero(grid == OCCUPIED) > 0


def test_cell_components_are_the_8_connected_components() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        grid = (rng.random((30, 40)) < 0.3).astype(np.uint8)
        _, comp = cv2.connectedComponents(grid, connectivity=8)
        rows, cols = np.nonzero(grid)
        order = rng.permutation(rows.size)
        rows, cols = rows[order], cols[order]
        got = cell_components(rows + 3, cols + 11)
        expected = comp[rows, cols]
        # the same partition of the cells, whatever the numbering
        pairs = set(zip(got.tolist(), expected.tolist(), strict=True))
        assert len(pairs) == len(set(got.tolist())) == len(set(expected.tolist()))


def test_matched_walls_are_withdrawn_on_the_box_of_the_hits() -> None:
    ref = _speckled(2)
    hits = np.array([[30.0, 10.0], [31.4, 12.6], [60.0, 55.0]])
    h, w = ref.shape
    grid = np.zeros((h, w), bool)
    c, r = np.rint(hits[:, 0]).astype(int), np.rint(hits[:, 1]).astype(int)
    grid[r, c] = True
    expected = ref & ~within_manhattan(grid, 2.0)
    out = unmatched_reference(ref, hits, 2.0)
    assert np.count_nonzero(out) < np.count_nonzero(ref)
    np.testing.assert_array_equal(out, expected)


@pytest.mark.parametrize("factor", [1, 2, 3, 5, 8])
def test_pooling_without_padding(factor: int) -> None:
    occ = _speckled(4, (67, 83))
    rows, cols = occ.shape
    padded = np.zeros((rows + (-rows % factor), cols + (-cols % factor)), np.uint8)
    padded[:rows, :cols] = occ
    pr, pc = padded.shape
    expected = padded.reshape(pr // factor, factor, pc // factor, factor).max(axis=(1, 3))
    np.testing.assert_array_equal(coarse_indicator(occ, factor), expected.astype(np.float32))


def test_ifmi_gives_the_same_hypotheses_from_cells_as_from_the_grid() -> None:
    m = load_map(DATA / "building_31.yaml")
    states = m.states.copy()
    states[:, : states.shape[1] // 2][states[:, : states.shape[1] // 2] == OCCUPIED] = -1
    reg = IFMIRegistrar(rotation_peaks=3, translation_peaks=3)
    from_grid = reg.candidates(reg.prepare_reference(m.states), states, 4)
    occ = states == OCCUPIED
    rows, cols = np.nonzero(occ)
    r0, c0 = int(rows.min()) - 3, int(cols.min()) - 2  # a crop with a margin
    crop = occ[r0:, c0:]
    cells = OccupiedCells(np.ascontiguousarray(crop), (c0, r0), m.shape)
    ref_cells = OccupiedCells(m.occupied, (0, 0), m.shape)
    from_cells = reg.candidates(reg.prepare_reference(ref_cells), cells, 4)
    assert [c.transform for c in from_cells] == [c.transform for c in from_grid]
    assert [c.confidence for c in from_cells] == [c.confidence for c in from_grid]


def test_sparse_cells_take_the_lookup_paths_with_the_same_answers() -> None:
    # few cells in a large box: lookups at the cells and the graph of the cells, not the box
    rng = np.random.default_rng(5)
    grid = np.zeros((400, 500), np.uint8)
    grid.flat[rng.choice(grid.size, 800, replace=False)] = 1
    grid[100, 10:200] = grid[150:300, 250] = 1
    rows, cols = np.nonzero(grid)
    assert grid.size > 64 * rows.size  # the sparse case
    np.testing.assert_array_equal(
        isolated_points(rows, cols), isolated_cells(grid.astype(bool))[rows, cols]
    )
    _, comp = cv2.connectedComponents(grid, connectivity=8)
    got = cell_components(rows, cols)
    pairs = set(zip(got.tolist(), comp[rows, cols].tolist(), strict=True))
    assert len(pairs) == len(set(got.tolist())) == len(set(comp[rows, cols].tolist())) > 100


def test_prepared_reference_pools_its_packed_cells_at_any_factor() -> None:
    m = load_map(DATA / "building_31.yaml")
    reg = IFMIRegistrar()
    prepared = reg.prepare_reference(m.states)
    rows, cols = np.nonzero(m.occupied)
    crop = m.occupied[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
    for factor in (prepared.factor + 1, prepared.factor + 3):
        np.testing.assert_array_equal(
            IFMIRegistrar._level(prepared, factor), coarse_indicator(crop, factor)
        )


@pytest.mark.parametrize("compact", [False, True])
def test_reference_counts_from_the_histogram_match_the_grid_wide_counts(compact: bool) -> None:
    # known cells near walls and free cells beyond a limit, from one histogram of the free
    # cells' distances, against the counts of the whole grid (both kinds of distance map)
    rng = np.random.default_rng(3)
    states = rng.choice(np.array([-1, 0, 1], np.int8), size=(700, 600), p=[0.3, 0.69, 0.01])
    states[:, :400][states[:, :400] == 1] = 0  # distances past the histogram's last bin
    states[:300, :40] = -1
    ref = OccupancyMap(states)
    index = ReferenceIndex.build(ref)
    if compact:
        index = ReferenceIndex(ref, compact_distance_map(ref.occupied), index.occupied_points)
    distance = index.occupied_distance
    assert distance.dtype == (np.uint16 if compact else np.float32)
    assert float(distance.max()) > 300
    known = states != -1
    assert index.known_count == np.count_nonzero(known)
    for t in (-1.0, 0.0, 0.5, 1.0, 2.0, 3.7, 120.0, 254.0, 254.5, 255.0, 300.0, math.inf):
        near = np.count_nonzero(known & within(distance, t))
        assert index.chance_agreement(t) == near / np.count_nonzero(known), t
        clear = np.count_nonzero((states == 0) & beyond(distance, t))
        assert index.free_beyond_count(t) == clear, t


@pytest.mark.parametrize("with_points", [False, True])
def test_reference_prepared_from_a_crop_of_cells_is_the_same(with_points: bool) -> None:
    # a tight crop with an offset (its cells listed or not): the same distance map, pooled
    # images and packed cells as from the grid of states
    occ = np.zeros((300, 260), dtype=bool)
    occ[40:200, 30:200] = _speckled(4, (160, 170))
    states = np.where(occ, 1, 0).astype(np.int8)
    rows, cols = np.nonzero(occ)
    r0, c0 = int(rows.min()), int(cols.min())
    crop = occ[r0 : rows.max() + 1, c0 : cols.max() + 1].copy()
    points = cell_points(crop).astype(np.int32) if with_points else None
    reg = IFMIRegistrar()
    a = reg.prepare_reference(states)
    b = reg.prepare_reference(OccupiedCells(crop, (c0, r0), occ.shape, points))
    assert a.distance is not None and b.distance is not None
    assert (a.offset, a.distance_offset, a.factor) == (b.offset, b.distance_offset, b.factor)
    np.testing.assert_array_equal(a.distance, b.distance)
    np.testing.assert_array_equal(a.crop, b.crop)
    assert a.levels.keys() == b.levels.keys()
    # ... and those of the grid-wide kernels: the erosion's outline, the pooled box
    dc0, dr0 = a.distance_offset
    window = occ[dr0 : dr0 + a.distance.shape[0], dc0 : dc0 + a.distance.shape[1]]
    np.testing.assert_array_equal(b.distance, _refine.edge_distance_field(window))
    box = occ[r0 : rows.max() + 1, c0 : cols.max() + 1]
    for f in a.levels:
        np.testing.assert_array_equal(a.levels[f], b.levels[f])
        np.testing.assert_array_equal(b.levels[f], coarse_indicator(box, f))
