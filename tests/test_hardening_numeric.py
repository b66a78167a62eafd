"""Extreme but accepted inputs: typed errors or results, never a crash, a blow-up or a wrong
answer (resolution ratios, grids past OpenCV's sides, maps of isolated cells, search budgets,
integer arrays, raw exceptions of the library's entry points)."""

from __future__ import annotations

import math
import warnings

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from brokenness import (
    BrokennessOptions,
    BrokennessResult,
    MapError,
    OccupancyMap,
    ParameterError,
    RigidTransform,
    compute_brokenness,
    register,
    resample_to_resolution,
    simulate_broken_map,
)
from brokenness.io.resample import _overlap_matrix
from brokenness.limits import MAX_CANDIDATES, check_candidates
from brokenness.masking.distance import (
    REMAP_SIDE,
    _remap,
    lookup_distance,
    remap_points,
    sample_xy,
)
from brokenness.measure.options import Settings
from brokenness.measure.settle import _candidates
from brokenness.registration import make_registrar
from brokenness.registration._rw_scoring import UNKNOWN_VALUE, _lookup, build_tables


def _room() -> NDArray[np.bool_]:
    room = np.zeros((120, 160), bool)
    room[20, 20:140] = room[100, 20:140] = room[20:101, 20] = room[20:101, 140] = True
    room[20:60, 80] = room[60, 50:80] = True
    return room


def _measure(m: object, ref: object) -> BrokennessResult:
    """``compute_brokenness`` with its "not measured" warning silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return compute_brokenness(m, ref)


# -- 6: resolution ratios --
def test_overlap_matrix_is_bounded_by_the_old_cells():
    """A new cell 1e10 old cells wide overlaps the 5 there are: no 1e10 entries tried."""
    w = _overlap_matrix(1, 5, 1e-10)
    assert w.shape == (1, 5) and w.toarray().tolist() == [[1.0] * 5]
    # where the bound does not bite, the usual overlaps (half cells at scale 2/3)
    np.testing.assert_array_equal(
        _overlap_matrix(2, 3, 2 / 3).toarray(), [[1.0, 0.5, 0.0], [0.0, 0.5, 1.0]]
    )


def test_extreme_resolution_ratio_resamples_at_once():
    m = OccupancyMap(_room().astype(np.int8), resolution=1e-6)
    coarse = resample_to_resolution(m, 1e4)  # 1e-10: was 74.5 GiB
    assert coarse.shape == (1, 1) and coarse.states[0, 0] == 1
    result = _measure(m, OccupancyMap(_room().astype(np.int8), resolution=1e4))
    assert result.occupied_cells == int(_room().sum())


@pytest.mark.parametrize("res", [1e-300, 1e-7, 2e4, "abc", None, [1.0]])
def test_resolution_out_of_the_accepted_range_is_refused(res):
    if res is not None:
        with pytest.raises(MapError, match="resolution"):
            OccupancyMap(np.zeros((2, 2), np.int8), resolution=res)
    with pytest.raises(ParameterError, match="resolution"):
        resample_to_resolution(OccupancyMap(np.zeros((2, 2), np.int8), resolution=0.05), res)


def test_resample_needs_a_map():
    with pytest.raises(MapError, match="OccupancyMap"):
        resample_to_resolution(_room().astype(np.int8), 0.1)


# -- 7: grids with a side of 32767 cells or more --
@pytest.mark.parametrize("dtype", [np.float32, np.uint16])
@pytest.mark.parametrize("interpolation", [cv2.INTER_NEAREST, cv2.INTER_LINEAR])
@pytest.mark.parametrize("window", [2, 4, 16])
def test_windows_sample_as_the_whole_grid(dtype, interpolation, window):
    """In windows, every sample is the one of a single remap of the grid, bit for bit:
    halves (rounded to even), points a 64th of a cell before a cell, points off the grid."""
    rng = np.random.default_rng(7)
    field = (rng.random((23, 37)) * 1000).astype(dtype)
    xy = np.column_stack([rng.uniform(-3, 40, 600), rng.uniform(-3, 26, 600)]).astype(np.float32)
    xy[:100] = np.round(xy[:100]) - np.float32(0.5)
    xy[100:200] = np.round(xy[100:200]) - np.float32(1 / 64)
    xy[200:210] = 1e9
    outside = 65535.0 if dtype == np.uint16 else -1.0
    whole = _remap(field, xy, interpolation, outside)
    windowed = remap_points(field, xy, interpolation, outside, window=window)
    assert windowed.dtype == whole.dtype
    np.testing.assert_array_equal(windowed.view(np.uint8), whole.view(np.uint8))


def test_lookup_in_a_grid_past_opencv_sides():
    field = (np.arange(2 * (REMAP_SIDE + 100)) % 1000).astype(np.float32).reshape(2, -1)
    xy = np.array([[REMAP_SIDE + 50, 1], [3, 0], [REMAP_SIDE + 200, 0]], np.float64)
    got = lookup_distance(field, xy)
    assert got.tolist() == [field[1, REMAP_SIDE + 50], field[0, 3], math.inf]
    compact = field.astype(np.uint16)  # the nearest-cell path of uint16 maps
    assert lookup_distance(compact, xy[:2]).tolist() == got[:2].tolist()
    x, y = np.float32([REMAP_SIDE + 50.5, 3.25]), np.float32([1.0, 0.0])  # bilinear, planes
    expected = [(field[1, REMAP_SIDE + 50] + field[1, REMAP_SIDE + 51]) / 2, field[0, 3] + 0.25]
    np.testing.assert_allclose(sample_xy(field, x, y, -1.0), expected, rtol=1e-6)


def test_random_walk_lookup_past_opencv_sides():
    states = np.zeros((3, REMAP_SIDE + 300), np.int8)
    states[1, ::7] = 1
    tables = build_tables(states, 1000)
    points = np.array(
        [[0.0, 40000.0, 32800.4, 5.0], [1.0, 1.0, 2.0, 7.0], [1, 1, 1, 1]], np.float32
    )
    matrix = np.array([[1, 0, 0], [1, 0, 3.0], [0, 1, 0], [0, 1, 0.0]], np.float32)  # 2 shifts
    got = _lookup(tables, 0, points, matrix)
    table = tables.tables[0]
    for w, dx in enumerate((0, 3)):
        for k in range(points.shape[1]):
            x, y = int(np.rint(points[0, k] + dx)), int(points[1, k])
            inside = 0 <= x < table.shape[1] and 0 <= y < table.shape[0]
            assert got[w, k] == (table[y, x] if inside else UNKNOWN_VALUE)


def test_wide_map_is_measured_and_registered():
    wide = np.zeros((40, REMAP_SIDE + 33), bool)
    wide[5, 100:32790] = wide[35, 100:32790] = True
    wide[5:36, 32000] = wide[5:36, 32789] = wide[5:20, 32400] = True
    wide[20, 32300:32400] = True
    assert compute_brokenness(wide, wide).degree == 0
    assert register(wide, wide).transform.translation == pytest.approx((0.0, 0.0), abs=1e-3)


# -- 8, 12: maps of isolated cells --
def test_settle_tiles_of_no_cells():
    settings = Settings(2.0, 4.0, 30, 6.0, 16, 12, True, True)
    t = RigidTransform()
    assert _candidates([t], np.zeros((1, 0), bool), np.zeros((0, 2)), None, settings) == ([], [])


def _dots() -> NDArray[np.bool_]:
    dots = np.zeros((100, 100), bool)
    dots[::9, ::9] = True
    return dots


def _two_rows() -> NDArray[np.int8]:
    """Two rows of cells 5 apart, each beside one of the other row: every tile of one row is
    made of isolated cells (the reviewer's odd/tworow map)."""
    rows = np.zeros((2, 300), np.int8)
    rows[0, ::5] = rows[1, 2::5] = 1
    return rows


def _one_row() -> NDArray[np.bool_]:
    row = np.zeros((1, 1000), bool)
    row[0, ::3] = True
    return row


@pytest.mark.parametrize("make", [_dots, _two_rows, _one_row])
def test_maps_of_isolated_cells_give_a_result(make):
    m = make()
    result = _measure(m, m)
    assert result.occupied_cells == int(np.count_nonzero(m == 1))
    assert result.degree in (0, None) and (result.degree is None) == (not result.measured)


# -- 10: search budgets --
@pytest.mark.parametrize("count", [10**20, 10**9, MAX_CANDIDATES + 1, 0, True, 2.0])
def test_candidates_out_of_range_are_refused(count):
    with pytest.raises(ParameterError, match=rf"\[1, {MAX_CANDIDATES}\]"):
        BrokennessOptions(max_candidates=count)
    with pytest.raises(ParameterError, match=rf"\[1, {MAX_CANDIDATES}\]"):
        register(_room(), _room(), max_candidates=count)
    with pytest.raises(ParameterError, match="max_candidates"):
        compute_brokenness(_room(), _room(), max_candidates=count)


def test_candidates_in_range():
    assert BrokennessOptions(max_candidates=MAX_CANDIDATES).max_candidates == MAX_CANDIDATES
    assert check_candidates(np.int64(5)) == 5


def test_ifmi_allocates_per_hypothesis_found_not_asked():
    registrar = make_registrar("ifmi")
    room = _room().astype(np.int8)
    found = registrar.candidates(registrar.prepare_reference(room), room, 10**12)
    assert 1 <= len(found) <= 64


# -- 13, 14: integer arrays --
def test_integer_states_read_alike_everywhere():
    states = _room().astype(np.int8)
    states[0] = -1
    for dtype in (np.int8, np.int64, np.uint8):
        arr = np.maximum(states, 0).astype(dtype) if dtype == np.uint8 else states.astype(dtype)
        assert OccupancyMap.from_array(arr).states.tolist() == arr.tolist()
    assert compute_brokenness(states, states).degree == 0
    assert register(states, states).transform.translation == pytest.approx((0, 0), abs=1e-3)
    # a reader that knows it holds OccupancyGrid values: 1 is 1 % occupied, i.e. free
    nav = OccupancyMap.from_array(np.array([[1, 0, -1]]), occupancy_grid=True)
    assert nav.states.tolist() == [[0, 0, -1]]


@pytest.mark.parametrize("values", [[[255, 256, 257]], [[2, 0]], [[-129, 0]], [[1 << 40, 0]]])
def test_states_are_checked_before_the_cast(values):
    with pytest.raises(MapError, match="-1 .unknown., 0 .free. or 1 .occupied."):
        OccupancyMap(np.array(values))


# -- 17: raw exceptions of the entry points --
@pytest.mark.parametrize("origin", [5, "abc", (1.0, 2.0), (0.0, float("nan"), 0.0), ("a", 1, 2)])
def test_bad_origin(origin):
    with pytest.raises(MapError, match="origin"):
        OccupancyMap(np.zeros((2, 2), np.int8), origin=origin)


def test_ragged_lists_are_map_errors():
    with pytest.raises(MapError, match="2D grid"):
        OccupancyMap([[1, 0], [0]])
    with pytest.raises(MapError, match="2D grid"):
        compute_brokenness([[1, 0], [0]], _room())
    with pytest.raises(MapError, match="2D grid"):
        register(_room(), [[1, 0], [0]])


@pytest.mark.parametrize("size", [[1], [10, 10, 10], "ab", None, (10, "x")])
def test_simulation_size_is_checked(size):
    with pytest.raises(ParameterError, match="size"):
        simulate_broken_map(seed=0, size=size)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"max_rotation": "x"},
        {"bump_radius": "x", "degree": 1},
        {"threshold": "x"},
        {"min_partition_cells": 0},
        {"bumps": ["x"]},
        {"spacing": "x"},
        {"pose_sigma": (0.1,)},
        {"laser": "x"},
        {"resolution": "x"},
    ],
)
def test_simulation_keywords_are_checked(kwargs):
    with pytest.raises(ParameterError):
        simulate_broken_map(seed=0, **kwargs)


@pytest.mark.parametrize(
    "args",
    [
        (float("nan"), 0.0, 0.0),
        (float("inf"), 0.0, 0.0),
        (0.0, float("inf"), 0.0),
        (0.0, 0.0, float("nan")),
        (0.0, 0.0, 0.0, 0.0),
        (0.0, 0.0, 0.0, -1.0),
        (0.0, 0.0, 0.0, float("nan")),
        ("x", 0.0, 0.0),
        (0.0, None, 0.0),
    ],
)
def test_transforms_need_finite_numbers_and_a_positive_scale(args):
    with pytest.raises(ParameterError, match="transform"):
        RigidTransform(*args)


def test_transform_matrix_is_checked():
    with pytest.raises(ParameterError):
        RigidTransform.from_matrix([[1.0, 0.0]])
    with pytest.raises(ValueError):  # a ParameterError is a ValueError, as before
        RigidTransform.from_matrix(np.full((3, 3), np.nan))
    t = RigidTransform(0.5, 1.0, 2.0, 0.25)
    np.testing.assert_allclose(t.inverse().compose(t).matrix, np.eye(3), atol=1e-12)
