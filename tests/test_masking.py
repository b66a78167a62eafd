"""Psi (picture distance), distance maps and the local agreement Psi_2."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage as ndi

from brokenness import MapError, OccupancyMap, picture_distance
from brokenness.masking import (
    ReferenceIndex,
    cell_points,
    lookup_distance,
    manhattan_distance_map,
    unmatched_reference,
)


def _room(shape=(60, 80)) -> np.ndarray:
    a = np.zeros(shape, bool)
    a[10, 10:70] = a[50, 10:70] = a[10:51, 10] = a[10:51, 70] = True
    a[10:35, 40] = True
    return a


def test_manhattan_distance_is_exact():
    rng = np.random.default_rng(1)
    mask = rng.random((40, 50)) < 0.03
    expected = ndi.distance_transform_cdt(~mask, metric="taxicab")
    np.testing.assert_array_equal(manhattan_distance_map(mask), expected)
    assert np.isinf(manhattan_distance_map(np.zeros((3, 3), bool))).all()


def test_manhattan_distance_outside_the_cells_box_is_exact():
    # the transform runs on the box of the cells; the margins around it are filled in
    rng = np.random.default_rng(7)
    for shape, box in [
        ((60, 80), (20, 31, 45, 52)),
        ((30, 30), (0, 5, 25, 30)),
        ((9, 70), (4, 5, 3, 4)),
    ]:
        mask = np.zeros(shape, bool)
        r0, r1, c0, c1 = box
        mask[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0)) < 0.2
        mask[r0, c0] = mask[r1 - 1, c1 - 1] = True
        expected = ndi.distance_transform_cdt(~mask, metric="taxicab")
        got = manhattan_distance_map(mask)
        assert got.dtype == np.float32 and got.flags.c_contiguous
        np.testing.assert_array_equal(got, expected)


def test_lookup_distance_rounds_and_is_inf_outside():
    d = manhattan_distance_map(np.eye(5, dtype=bool))
    out = lookup_distance(d, [[0.4, 0.4], [2.0, 0.0], [-1.0, 0.0], [4.6, 0.0]])
    assert out[0] == 0 and out[1] == 2 and np.isinf(out[2]) and np.isinf(out[3])


def test_compact_distance_map_holds_the_same_whole_numbers():
    from brokenness.masking.distance import compact_distance_map

    rng = np.random.default_rng(11)
    for shape, box in [
        ((60, 80), (20, 31, 45, 52)),
        ((30, 30), (0, 30, 0, 30)),
        ((1, 9), (0, 1, 4, 5)),
    ]:
        mask = np.zeros(shape, bool)
        r0, r1, c0, c1 = box
        mask[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0)) < 0.2
        mask[r0, c0] = True
        got = compact_distance_map(mask)
        assert got.dtype == np.uint16 and got.flags.c_contiguous
        np.testing.assert_array_equal(got, manhattan_distance_map(mask))
    # a grid of 65535 rows plus columns or more, or no cell, keeps float32
    assert compact_distance_map(np.zeros((3, 3), bool)).dtype == np.float32
    assert compact_distance_map(np.ones((1, 65534), bool)).dtype == np.float32


def test_compact_distance_map_beyond_one_byte_and_its_bounds():
    # distances of 255 and more (past one byte) are kept; the whole-number bounds of a
    # uint16 map select the same cells as the float comparisons
    from brokenness.masking.distance import beyond, compact_distance_map, within

    mask = np.zeros((700, 650), bool)
    mask[3, 5] = mask[690, 640] = mask[350, 20] = True
    got, exact = compact_distance_map(mask), manhattan_distance_map(mask)
    assert got.dtype == np.uint16 and got.max() > 255
    np.testing.assert_array_equal(got, exact)
    for t in (-1.0, -0.5, 0.0, 0.5, 2.0, 2.7, 300.0, 1e9, np.inf, -np.inf, np.nan):
        np.testing.assert_array_equal(within(got, t), exact <= t)
        np.testing.assert_array_equal(beyond(got, t), exact > t)


def _sample_points(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    """Points over the grid and its border, near the first rows and columns and on the
    powers of two and the cells' edges."""
    h, w = shape
    spread = np.column_stack([rng.uniform(-3, w + 3, 20000), rng.uniform(-3, h + 3, 20000)])
    corner = rng.uniform(-1.5, 3.0, (4000, 2))
    edges = np.array(
        [[0, 0], [-1, -1], [-0.5, 0.25], [0.25, -0.5], [w - 1, h - 1], [w - 0.5, h - 0.5],
         [w, h], [-1e-9, 0.5], [1e-30, 1e-30], [1e10, 2], [1, 1], [2, 2], [127.99999, 128.00001],
         [255.999, 3.5], [w - 1e-4, 0.5], [0.5, h - 1e-4]]
    )  # fmt: skip
    return np.vstack([spread, corner, edges, rng.uniform(100, 300, (4000, 2))])


@pytest.mark.parametrize("shape", [(300, 300), (40, 700), (1, 50), (2, 2), (3, 1), (500, 900)])
def test_sample_at_reads_a_uint16_map_as_its_float32_values(shape):
    # bilinear and nearest samples, bit for bit, on and off the grid (cv2.remap's own border)
    from brokenness.masking import sample_at
    from brokenness.masking.distance import compact_distance_map

    rng = np.random.default_rng(sum(shape))
    mask = np.zeros(shape, bool)
    mask[rng.integers(0, shape[0], 30), rng.integers(0, shape[1], 30)] = True
    exact, compact = manhattan_distance_map(mask), compact_distance_map(mask)
    assert compact.dtype == np.uint16
    points = _sample_points(rng, shape)
    for pts in (points, points[:5], points[-4000:].reshape(2, 2000, 2)):
        for outside in (3.0, 1002.5, np.inf):
            for nearest in (False, True):
                a = sample_at(exact, pts, outside, nearest=nearest)
                b = sample_at(compact, pts, outside, nearest=nearest)
                assert a.shape == b.shape and b.dtype == np.float32
                np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("shape", [(300, 300), (40, 700), (1, 50), (500, 900)])
def test_sample_xy_equals_sample_at_of_the_stacked_points(shape):
    # the coordinates as two planes: the same samples as the two-channel points, bit for bit
    # (float32 and uint16 maps, bilinear and nearest, on and off the grid, every layout)
    from brokenness.masking.distance import compact_distance_map, sample_at, sample_xy

    rng = np.random.default_rng(len(shape) + shape[0])
    mask = np.zeros(shape, bool)
    mask[rng.integers(0, shape[0], 30), rng.integers(0, shape[1], 30)] = True
    fields = (
        manhattan_distance_map(mask),
        compact_distance_map(mask),
        rng.uniform(0, 40, shape).astype(np.float32),  # not whole numbers
    )
    points = _sample_points(rng, shape).astype(np.float32)
    wide = rng.uniform(-50, max(shape) + 50, (33_000, 2)).astype(np.float32)  # > OpenCV's side
    layouts = (points, points[:5], points[-4000:].reshape(2, 2000, 2), wide, points[:0])
    for field in fields:
        for pts in layouts:
            x, y = pts[..., 0].copy(), pts[..., 1].copy()
            for outside in (3.0, 1002.5):
                for nearest in (False, True):
                    a = sample_at(field, pts, outside, nearest=nearest)
                    b = sample_xy(field, x, y, outside, nearest=nearest)
                    assert a.shape == b.shape == x.shape and b.dtype == np.float32
                    assert a.tobytes() == b.tobytes()
    with pytest.raises(ValueError):
        sample_xy(fields[0], points[:3, 0].copy(), points[:2, 1].copy(), 0.0)


def test_reference_index_keeps_large_maps_compact(monkeypatch):
    import brokenness.masking.agreement as agreement

    ref = OccupancyMap.from_array(_room())
    assert ReferenceIndex.build(ref).occupied_distance.dtype == np.float32
    monkeypatch.setattr(agreement, "COMPACT_CELLS", 0)
    index = ReferenceIndex.build(ref)
    assert index.occupied_distance.dtype == np.uint16
    np.testing.assert_array_equal(index.occupied_distance, manhattan_distance_map(ref.occupied))


def test_picture_distance_zero_on_itself_and_grows_with_shift():
    room = OccupancyMap.from_array(_room())
    assert picture_distance(room, room) == 0.0
    shifted = [OccupancyMap.from_array(np.roll(_room(), k, axis=1)) for k in (1, 2, 4)]
    values = [picture_distance(room, s) for s in shifted]
    assert 0 < values[0] < values[1] < values[2]
    assert picture_distance(room, shifted[0]) == pytest.approx(picture_distance(shifted[0], room))


def test_picture_distance_matches_brute_force():
    rng = np.random.default_rng(7)
    a = OccupancyMap(rng.choice(np.array([-1, 0, 1], np.int8), size=(12, 9)))
    b = OccupancyMap(rng.choice(np.array([-1, 0, 1], np.int8), size=(12, 9)))

    def d(x, y, kind):
        px = np.argwhere(x.states == kind)
        py = np.argwhere(y.states == kind)
        if len(px) == 0:
            return 0.0
        dist = np.abs(px[:, None, :] - py[None, :, :]).sum(-1).min(1)
        return dist.mean()

    brute = sum(d(a, b, k) + d(b, a, k) for k in (1, 0))
    assert picture_distance(a, b) == pytest.approx(brute)


def test_picture_distance_shape_mismatch():
    with pytest.raises(MapError):
        picture_distance(OccupancyMap.from_array(_room()), OccupancyMap.from_array(_room((61, 80))))


def test_reference_index_agreement_and_chance():
    ref = OccupancyMap.from_array(_room())
    index = ReferenceIndex.build(ref)
    pts = cell_points(ref.occupied)
    assert index.occupied_agreement(pts, 2).all()
    top = (pts[:, 1] == 10) & (pts[:, 0] > 13) & (pts[:, 0] < 37)
    assert not index.occupied_agreement(pts + [0, 3], 2)[top].any()
    p0 = index.chance_agreement(2)
    near = (manhattan_distance_map(ref.occupied) <= 2).mean()
    assert p0 == pytest.approx(near)
    with pytest.raises(MapError):
        ReferenceIndex.build(OccupancyMap(np.zeros((4, 4), np.int8)))


def test_unmatched_reference_removes_the_manhattan_neighbourhood():
    ref = np.zeros((20, 20), bool)
    ref[10, :] = True
    out = unmatched_reference(ref, [[10.0, 8.0]], 2)
    removed = ref & ~out
    # (10, 10) is at distance 2 of (x=10, y=8): removed; (11, 10) at 3: kept
    assert removed[10, 10] and not removed[10, 11] and not removed[10, 9]
    assert np.array_equal(unmatched_reference(ref, np.empty((0, 2)), 2), ref)


def test_nearest_points_matches_a_kd_tree():
    """The lookup-table answer (one remap) is the KD-tree's on rounded queries, with points
    beyond reach or off the grid reported as inf."""
    rng = np.random.default_rng(3)
    states = np.where(rng.random((90, 120)) < 0.03, 1, 0).astype(np.int8)
    index = ReferenceIndex.build(OccupancyMap(states))
    pts = rng.random((3000, 2)) * [160, 130] - 20  # some off the grid
    got = index.nearest_points(pts, 4.0)
    rounded = np.rint(pts)
    dist, idx = index.tree.query(rounded)
    inside = (rounded[:, 0] >= 0) & (rounded[:, 0] < 120) & (rounded[:, 1] >= 0)
    inside &= rounded[:, 1] < 90
    reach = np.linalg.norm(index.occupied_points[idx] - pts, axis=1) <= 4.0
    found = np.isfinite(got[:, 0])
    # ties between equally near cells may pick either: compare distances, not cells
    near_got = np.linalg.norm(got[found] - rounded[found], axis=1)
    assert np.allclose(near_got, dist[found])
    assert np.all(np.linalg.norm(got[found] - pts[found], axis=1) <= 4.0)
    assert np.count_nonzero(found != (inside & reach)) <= 0.01 * len(pts)  # ties only
    assert not found[~inside].any()


@pytest.mark.parametrize("table", [True, False])
def test_correspondences_are_the_finite_rows_of_nearest_points(table, monkeypatch):
    # the lookup table's answer and the KD-tree's (a reference above the table's size)
    import brokenness.masking.agreement as agreement

    if not table:
        monkeypatch.setattr(agreement, "_LOOKUP_TABLE_CELLS", 10)
    rng = np.random.default_rng(5)
    states = np.where(rng.random((90, 120)) < 0.03, 1, 0).astype(np.int8)
    index = ReferenceIndex.build(OccupancyMap(states))
    pts = rng.random((3000, 2)) * [160, 130] - 20  # some off the grid
    for reach in (0.5, 4.0):
        every = index.nearest_points(pts, reach)
        rows, cells = index.correspondences(pts, reach)
        finite = np.flatnonzero(np.isfinite(every[:, 0]))
        assert rows.dtype == np.intp and 0 < rows.size < len(pts)
        np.testing.assert_array_equal(rows, finite)
        assert cells.tobytes() == every[finite].tobytes()


def test_picture_distance_far_apart_kinds_need_several_saturated_passes():
    # the only free cell of b is about 600 cells from most free cells of a: distances of
    # 255 and more come from the later one-byte passes, and must still be exact
    a = OccupancyMap(np.zeros((400, 420), np.int8))
    states = np.full((400, 420), -1, np.int8)
    states[3, 5] = 0
    states[390, 410] = 1
    b = OccupancyMap(states)
    free = np.argwhere(a.states == 0)
    exact = float(np.abs(free - np.array([3, 5])).sum(axis=1).sum()) / len(free)
    assert picture_distance(a, b) == exact + 0.0 + 0.0 + sum(a.shape)  # free a->b, b->a; occ
    assert picture_distance(b, a) == picture_distance(a, b)


def test_unmatched_reference_in_place_and_large_radius_agree_with_the_copy():
    rng = np.random.default_rng(11)
    ref = rng.random((60, 70)) < 0.3
    hits = rng.uniform(-3, 72, (40, 2))
    for threshold in (0.0, 2.0, 3.0, 7.5):
        expected = ref & ~(manhattan_distance_map_of_hits(hits, ref.shape) <= threshold)
        assert np.array_equal(unmatched_reference(ref, hits, threshold), expected)
        inplace = ref.copy()
        assert unmatched_reference(inplace, hits, threshold, in_place=True) is inplace
        assert np.array_equal(inplace, expected)


def manhattan_distance_map_of_hits(hits: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    from brokenness.masking import manhattan_distance_map

    mask = np.zeros(shape, dtype=bool)
    cells = np.rint(hits).astype(int)
    ok = (
        (cells[:, 0] >= 0)
        & (cells[:, 0] < shape[1])
        & (cells[:, 1] >= 0)
        & (cells[:, 1] < shape[0])
    )
    mask[cells[ok, 1], cells[ok, 0]] = True
    return manhattan_distance_map(mask)


def test_picture_distance_takes_arrays_and_refuses_what_is_no_map():
    """Arrays are read as OccupancyMap.from_array reads them; a ragged list is a MapError,
    not an AttributeError."""
    walls = np.zeros((20, 20), bool)
    walls[5, 2:18] = True
    shifted = np.roll(walls, 1, axis=0)
    assert picture_distance(walls, walls) == 0.0
    assert picture_distance(walls, shifted) == picture_distance(
        OccupancyMap.from_array(walls), OccupancyMap.from_array(shifted)
    )
    with pytest.raises(MapError):
        picture_distance(np.array([[1, 2], [3]], dtype=object), walls)
