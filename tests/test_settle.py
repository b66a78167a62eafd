"""Settle: a compromise transform refitted where its partition's cells are.

Building 31 (a real map, 520 x 520 cells) cut in two halves, the right half turned by 1.5
degrees about its centre and shifted by 3 cells: two parts only a little off from each
other, as a bump close to where the robot then mapped makes them. Given the two partitions
with their cells but with transforms halfway between the two parts' (what a registration of
a remainder holding cells of both gives), :func:`settle` must move each transform back to
its own part's and give the cells back to their parts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _breaking import SETTINGS

from brokenness import OccupancyMap, RigidTransform, load_map
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.partitions import Found
from brokenness.measure.settle import settle

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def reference() -> OccupancyMap:
    m = load_map(DATA / "building_31.yaml")
    states = np.full((520, 520), -1, np.int8)
    h, w = m.shape
    r0, c0 = max((h - 520) // 2, 0), max((w - 520) // 2, 0)
    crop = m.states[r0 : r0 + 520, c0 : c0 + 520]
    states[: crop.shape[0], : crop.shape[1]] = crop
    return OccupancyMap(states, m.resolution, (0.0, 0.0, 0.0))


def _turn(deg: float, about: tuple[float, float], shift: tuple[float, float]) -> RigidTransform:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    x, y = about
    return RigidTransform(a, x - c * x + s * y + shift[0], y - s * x - c * y + shift[1])


def _two_parts(reference: OccupancyMap):
    """The reference's occupied cells, the right half moved by ``off``; both truths."""
    points = cell_points(reference.occupied)
    right = points[:, 0] >= 260
    off = _turn(1.5, (390.0, 260.0), (3.0, -2.0))
    moved = points.copy()
    moved[right] = off.apply(points[right])
    truths = [RigidTransform(0.0, 0.0, 0.0), off.inverse()]
    return moved, right, truths


def test_compromise_transforms_settle_on_their_parts(reference: OccupancyMap) -> None:
    points, right, truths = _two_parts(reference)
    index = ReferenceIndex.build(reference)
    halfway = _turn(-0.75, (390.0, 260.0), (-1.5, 1.0))  # between the two parts
    # each partition holds most of its part's cells and a share of the other's
    members = [np.flatnonzero(~right | (np.arange(right.size) % 5 == 0)), np.flatnonzero(right)]
    found = [
        Found(RigidTransform(0.0, 0.0, 0.0), members[0], 1.0, 0.0),
        Found(halfway, members[1], 1.0, 0.0),
    ]
    before = np.median(halfway.displacement(truths[1], points[right]))
    settled = settle(found, points, index, SETTINGS)
    assert len(settled) == 2
    after = np.median(settled[1].transform.displacement(truths[1], points[right]))
    assert before > 2.0, before
    assert after < 1.0, after
    # the cells went back to their parts
    owner = np.full(points.shape[0], -1)
    for j, f in enumerate(settled):
        owner[f.members] = j
    assert np.mean(owner[right] == 1) > 0.9 and np.mean(owner[~right] == 0) > 0.9


def test_right_transforms_stay(reference: OccupancyMap) -> None:
    points, right, truths = _two_parts(reference)
    index = ReferenceIndex.build(reference)
    found = [
        Found(truths[0], np.flatnonzero(~right), 1.0, 0.0),
        Found(truths[1], np.flatnonzero(right), 1.0, 0.0),
    ]
    settled = settle(found, points, index, SETTINGS)
    for f, t, part in zip(settled, truths, (~right, right), strict=True):
        assert np.median(f.transform.displacement(t, points[part])) < 0.5


@pytest.mark.parametrize("rows", [0, 1, 6, 255, 256, 300])
def test_row_and_column_counts_are_numpys(rows: int) -> None:
    from brokenness.measure.settle import _column_counts, _row_counts

    rng = np.random.default_rng(rows)
    mask = rng.random((rows, 777)) < 0.3
    for m in (mask, mask[:, ::3], mask[::-1]):
        counts = _row_counts(m)
        assert counts.dtype == np.intp and np.array_equal(counts, np.count_nonzero(m, axis=1))
        column = _column_counts(m)
        assert column.dtype == np.int64 and np.array_equal(column, m.sum(axis=0))


def test_a_half_whose_free_space_lands_on_walls_is_worse(reference: OccupancyMap) -> None:
    # The map is the reference itself; its right half held by a placement turned 180 degrees
    # about the half's centre (a twin of a symmetric building's wing). Split off from the
    # identity, that half's free space lands on the reference's walls far more often under
    # its own transform than under the identity's, which keeps it clear.
    from brokenness.measure.evidence import ClearFree
    from brokenness.measure.settle import _FreeSpaceTest

    points = cell_points(reference.occupied)
    right = points[:, 0] >= 260
    index = ReferenceIndex.build(reference)
    clear = ClearFree(reference, SETTINGS.threshold)
    twin = _turn(180.0, tuple(points[right].mean(axis=0)), (0.0, 0.0))
    found = [
        Found(RigidTransform(), np.flatnonzero(~right), 1.0, 0.0),
        Found(twin, np.flatnonzero(right), 1.0, 0.0),
    ]
    test = _FreeSpaceTest(found, points, clear, index, SETTINGS)
    assert test.worsened(found, [(1, RigidTransform())]) == [1]
    # the same half at its true place (the identity) is no worse than under a partition
    # whose transform is the twin
    found[1] = Found(RigidTransform(), np.flatnonzero(right), 1.0, 0.0)
    assert test.worsened(found, [(1, twin)]) == []
