"""The point selections and window counts of the measure's hot paths, against their plain
numpy definitions (they must give the same values, bit for bit)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from brokenness._points import cells_at, point_norms, sorted_lookup, squared_norms, take_rows
from brokenness.measure import support


@pytest.mark.parametrize("seed", range(10))
def test_point_norms_are_numpy_norms(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (*rng.integers(0, 30, size=int(rng.integers(1, 4))).tolist(), 2)
    offsets = rng.normal(size=shape) * float(rng.choice([1e-3, 1.0, 1e3]))
    offsets.reshape(-1)[:: max(1, offsets.size // 7)] = 0.0  # zeros among them
    got = point_norms(offsets)
    assert got.shape == shape[:-1]
    assert got.tobytes() == np.linalg.norm(offsets, axis=-1).tobytes()
    squares = squared_norms(offsets)
    assert squares.tobytes() == np.einsum("...i,...i->...", offsets, offsets).tobytes()


@pytest.mark.parametrize("seed", range(10))
def test_sorted_lookup_finds_exactly_the_keys_present(seed: int) -> None:
    rng = np.random.default_rng(seed)
    keys = np.unique(rng.integers(0, 500, size=int(rng.integers(1, 200)))).astype(np.int64)
    probe = rng.integers(-50, 600, size=300).astype(np.int64)  # before, among, past the keys
    at, found = sorted_lookup(keys, probe)
    assert found.tolist() == np.isin(probe, keys).tolist()
    assert np.array_equal(keys[at[found]], probe[found])  # where each found probe is
    assert np.all((at >= 0) & (at < keys.size))  # a valid index everywhere


@pytest.mark.parametrize("seed", range(20))
def test_take_rows_is_advanced_indexing(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 400))
    points = rng.normal(size=(n, 2)) * 100.0
    mask = rng.random(n) < rng.random()
    index = rng.integers(0, max(n, 1), size=int(rng.integers(0, 50))) if n else np.zeros(0, int)
    for which in (mask, np.flatnonzero(mask), index):
        got = take_rows(points, which)
        assert got.dtype == points.dtype and got.shape == points[which].shape
        np.testing.assert_array_equal(got, points[which])


@pytest.mark.parametrize("seed", range(20))
def test_cells_at_reads_what_row_and_column_indexing_reads(seed: int) -> None:
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 60, size=2))
    grid = rng.integers(-1, 2, size=(h, w)).astype(np.int8)
    rows = rng.integers(0, h, size=300)
    cols = rng.integers(0, w, size=300)
    np.testing.assert_array_equal(cells_at(grid, rows, cols), grid[rows, cols])
    view = np.asarray(grid.T)  # not C-contiguous: read by rows and columns
    np.testing.assert_array_equal(cells_at(view, cols, rows), view[cols, rows])


def _box_filter_counts(
    rows: np.ndarray, cols: np.ndarray, which: np.ndarray, at: np.ndarray, shape, radius: int
) -> np.ndarray:
    """The definition: a whole-grid integer box filter of the ``which`` cells, read at ``at``."""
    grid = np.zeros(shape, np.uint8)
    grid[rows[which], cols[which]] = 1
    side = 2 * radius + 1
    counts = cv2.boxFilter(
        grid, cv2.CV_16U, (side, side), normalize=False, borderType=cv2.BORDER_CONSTANT
    )
    return counts[rows[at], cols[at]].astype(np.float64)


@pytest.mark.parametrize("band_cells", [1 << 21, 64])  # one band; many bands of a few rows
@pytest.mark.parametrize("seed", range(12))
def test_window_counts_are_the_box_filter_counts(
    seed: int, band_cells: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(support, "_BAND_CELLS", band_cells)
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(5, 120)), int(rng.integers(5, 120)))
    n = int(rng.integers(1, shape[0] * shape[1] // 3 + 2))
    flat = rng.choice(shape[0] * shape[1], size=n, replace=False)
    rows, cols = (flat // shape[1]).astype(np.intp), (flat % shape[1]).astype(np.intp)
    which = rng.random(n) < 0.6
    at = rng.random(n) < 0.5
    at[int(rng.integers(0, n))] = True
    radius = int(rng.integers(1, 8))
    got = support.window_counts(rows, cols, which, at, shape, radius)
    np.testing.assert_array_equal(got, _box_filter_counts(rows, cols, which, at, shape, radius))
