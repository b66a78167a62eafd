"""Two parts at one rotation, shifted against each other (a pure-shift bump).

Building 31 (a real map, 520 x 520 cells), the part right of column 360 (a fifth of its
walls) shifted by 12 cells (0.6 m at 5 cm) along the rows: under the other part's transform
the walls along the shift still lie near reference walls, so one transform explains 90 % of
the cells of both. They are two
partitions all the same: the walls across the shift agree under one transform only.

- :func:`consolidate` must not join them (they were joined while one transform made 80 %
  of the cells of both agree), but must still join one piece found twice;
- :func:`settle` must split a compromise between them (one partition holding both parts,
  its transform halfway) into the two parts, and must not split a map whose right part is
  only 3 cells off (within the loose threshold of the merge test: a residual, not a bump).
"""

from __future__ import annotations

import numpy as np
from _breaking import SETTINGS, median_error

from brokenness import OccupancyMap, RigidTransform
from brokenness.masking import cell_points
from brokenness.measure.partitions import Found, consolidate
from brokenness.measure.settle import settle

SHIFT = (0.0, 12.0)
CUT = 360


def _shifted(reference: OccupancyMap, shift: tuple[float, float]):
    """The reference's walls with the right part shifted; the right part; both truths."""
    points = cell_points(reference.occupied)
    right = points[:, 0] >= CUT
    moved = points.copy()
    moved[right] += shift
    truths = [RigidTransform(), RigidTransform(0.0, -shift[0], -shift[1])]
    return moved, right, truths


def test_consolidate_keeps_shifted_parts_apart(corner, corner_index) -> None:
    points, right, truths = _shifted(corner, SHIFT)
    found = [
        Found(truths[0], np.flatnonzero(~right), 1.0, 0.0),
        Found(truths[1], np.flatnonzero(right), 1.0, 0.0),
    ]
    # one transform explains most cells of both, as the old join test asked
    both = corner_index.occupied_agreement(truths[0].apply(points), SETTINGS.threshold)
    assert both.mean() > 0.85
    kept = consolidate(found, points, corner_index, SETTINGS)
    assert len(kept) == 2
    for f, t, part in zip(kept, truths, (~right, right), strict=True):
        assert median_error(f.transform, t, points[part]) < 0.5


def test_consolidate_joins_one_piece_found_twice(corner, corner_index) -> None:
    points = cell_points(corner.occupied)
    right = points[:, 0] >= CUT
    found = [
        Found(RigidTransform(), np.flatnonzero(~right), 1.0, 0.0),
        Found(RigidTransform(0.0, 0.4, -0.3), np.flatnonzero(right), 1.0, 0.0),
    ]
    assert len(consolidate(found, points, corner_index, SETTINGS)) == 1


def test_settle_splits_a_compromise_of_shifted_parts(corner, corner_index) -> None:
    points, right, truths = _shifted(corner, SHIFT)
    halfway = RigidTransform(0.0, -SHIFT[0] / 2, -SHIFT[1] / 2)
    found = [Found(halfway, np.arange(points.shape[0]), 1.0, 0.0)]
    settled = settle(found, points, corner_index, SETTINGS)
    assert len(settled) == 2
    for t, part in zip(truths, (~right, right), strict=True):
        errors = [median_error(f.transform, t, points[part]) for f in settled]
        assert min(errors) < 1.0, errors


def test_settle_does_not_split_parts_within_the_loose_threshold(corner, corner_index) -> None:
    # 3 cells: beyond the agreement threshold (2), within the merge test's (4): a residual
    # error of an unbroken map, not a bump
    points, _, _ = _shifted(corner, (0.0, 3.0))
    found = [Found(RigidTransform(), np.arange(points.shape[0]), 1.0, 0.0)]
    assert len(settle(found, points, corner_index, SETTINGS)) == 1


def test_settle_finds_a_part_shifted_beyond_the_refinement(corner, corner_index) -> None:
    # one partition with the other part's exact transform: the shifted part is 12 cells
    # off, beyond the trimmed ICP's reach (the loose threshold, 4), so only the shift
    # search of its unexplained cells can place it
    points, right, truths = _shifted(corner, SHIFT)
    found = [Found(truths[0], np.arange(points.shape[0]), 1.0, 0.0)]
    settled = settle(found, points, corner_index, SETTINGS)
    assert len(settled) == 2
    errors = [median_error(f.transform, truths[1], points[right]) for f in settled]
    assert min(errors) < 1.0, errors
