"""A partition must explain the region of the map it lies in (``measure/explained.py``)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from brokenness import RigidTransform, compute_brokenness, load_map
from brokenness.measure.explained import MAP_SHARE, REGION_SHARE, region_shares
from brokenness.measure.partitions import Found
from brokenness.measure.support import SUPPORT_RADIUS


def _wall(x0: int, y0: int, length: int) -> np.ndarray:
    """Cells ``(x, y)`` of a horizontal wall two cells thick."""
    xs = np.arange(x0, x0 + length)
    return np.vstack([np.column_stack([xs, np.full(length, y)]) for y in (y0, y0 + 1)])


def _context(points: np.ndarray) -> SimpleNamespace:
    shape = (int(points[:, 1].max()) + 1, int(points[:, 0].max()) + 1)
    return SimpleNamespace(points=points.astype(np.float64), shape=shape)


def test_the_unexplained_cells_around_a_partition_lower_its_share():
    reach = SUPPORT_RADIUS
    whole = _wall(10, 10, 100)  # explained entirely: share 1
    part = _wall(10, 10 + 10 * reach, 100)  # its left 30 cells explained, the rest not
    far = _wall(10, 10 + 20 * reach, 100)  # explained by nothing, far from every partition
    speck = np.array([[120, 14]])  # a lone cell beside the first wall: noise, not counted
    points = np.vstack([whole, part, far, speck])
    n_whole = whole.shape[0]
    left = n_whole + np.flatnonzero(part[:, 0] < 40)
    found = [
        Found(RigidTransform(), np.arange(n_whole), 1.0, 0.0),
        Found(RigidTransform(), left, 1.0, 0.0),
    ]
    shares = region_shares(found, _context(points))
    assert shares[0] == 1.0
    # the other cells of its wall within the window of its own count against it
    right = part[part[:, 0] >= 40]
    within = np.count_nonzero(right[:, 0] <= 39 + reach)
    assert within < right.shape[0]  # the window does not reach the whole wall
    assert shares[1] == left.size / (left.size + within)
    assert shares[1] < REGION_SHARE < shares[0]


def test_every_cell_explained_gives_every_partition_a_full_share():
    points = np.vstack([_wall(0, 0, 50), _wall(0, 40, 50)])
    found = [
        Found(RigidTransform(), np.arange(100), 1.0, 0.0),
        Found(RigidTransform(), np.arange(100, 200), 1.0, 0.0),
    ]
    assert region_shares(found, _context(points)).tolist() == [1.0, 1.0]


def test_a_map_whose_partitions_hold_a_minority_of_it_is_not_measured():
    """Building 31 against the Willow Garage SLAM map: every placement but one explains a
    part of its region only, and the one left holds 5 % of the map's cells; its free space
    alone would not show the map to be of another place, so the judge first asks that the
    partitions hold most of the map (issue 16: before, degree 10)."""
    data = Path(__file__).parent / "data"
    result = compute_brokenness(
        load_map(data / "building_31.yaml"), load_map(data / "willow-2010-02-18-0.10.yaml")
    )
    assert not result.measured and result.degree is None
    share = 1.0 - result.unassigned_fraction
    assert share < MAP_SHARE
    assert result.reason is not None and result.reason.startswith(
        f"only {100 * share:.0f} % of the map's occupied cells agree"
    )
