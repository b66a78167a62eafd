"""Which partition's wall bounds a free cell (:func:`~brokenness.measure.evidence.wall_owners`).

Building 31's corner with its right part turned by 5 degrees: the greedy recursion gives the
left partition every cell its transform explains, among them walls of the right part that
land on reference walls by coincidence. Where those are incoherent under the left transform
(few of the walls around them agree) and coherent under the right one, they are the right
part's walls, and the free space in front of them is counted under its transform: the map's
free space of a right partition crosses fewer reference walls than when each wall bounds
the free space of the partition that holds it.
"""

from __future__ import annotations

import numpy as np
import pytest
from _breaking import SETTINGS, break_map, move_about

import brokenness.measure.evidence as evidence
from brokenness import OccupancyMap, RigidTransform
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.evidence import ClearFree, contradiction, free_space, wall_owners
from brokenness.measure.partitions import Found


def _members(found, points, index, clear):  # noqa: ARG001 - wall_owners' signature
    """Each wall its partition's (the attribution before coherence was asked)."""
    owner = np.full(points.shape[0], -1, np.int16)
    for j, f in enumerate(found):
        owner[f.members] = j
    return owner


def test_walls_taken_by_coincidence_bound_their_own_parts_free_space(
    corner: OccupancyMap, corner_index: ReferenceIndex, monkeypatch: pytest.MonkeyPatch
) -> None:
    right = np.zeros(corner.shape, bool)
    right[:, 360:] = True
    turned = move_about((440.0, 260.0), 5.0, (0.0, 0.0))
    broken, (left_t, right_t) = break_map(corner, [~right, right], [RigidTransform(), turned])
    points = cell_points(broken.occupied)
    threshold = SETTINGS.threshold
    under_left = corner_index.occupied_agreement(left_t.apply(points), threshold)
    under_right = corner_index.occupied_agreement(right_t.apply(points), threshold)
    # the greedy recursion's partitions: the left one first, with every cell it explains
    left, rest = np.flatnonzero(under_left), np.flatnonzero(under_right & ~under_left)
    found = [Found(left_t, left, 1.0, 0.0), Found(right_t, rest, 1.0, 0.0)]
    clear = ClearFree(broken, threshold)

    owner = wall_owners(found, points, corner_index, clear)
    x = left_t.apply(points)[:, 0]
    assert np.all(owner[under_left & (x < 330)] == 0)  # the left part's walls stay its
    assert np.all(owner[~(under_left | under_right)] == -1)  # cells of no partition
    moved = under_left & (owner == 1)
    assert np.count_nonzero(moved) > 50 and np.all(x[moved] >= 350)  # right-part walls only

    coherent = contradiction(found, points, clear, corner_index)
    monkeypatch.setattr(evidence, "wall_owners", _members)
    # new clear cells: the free space of these partitions made anew, not the one kept
    held = contradiction(found, points, ClearFree(broken, threshold), corner_index)
    # the left partition's free space lands on reference walls far less often
    assert coherent.contradicting[0] < 0.6 * held.contradicting[0]
    assert coherent.ratio() < held.ratio()


def test_the_free_space_of_unchanged_partitions_is_made_once(
    corner: OccupancyMap, corner_index: ReferenceIndex, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The recovery, the relocation and the tests of a call ask for the free space of the
    same partitions: it is made once per clear cells, and anew when a partition changes."""
    right = np.zeros(corner.shape, bool)
    right[:, 360:] = True
    turned = move_about((440.0, 260.0), 5.0, (0.0, 0.0))
    broken, (left_t, right_t) = break_map(corner, [~right, right], [RigidTransform(), turned])
    points = cell_points(broken.occupied)
    x = points[:, 0]
    found = [
        Found(left_t, np.flatnonzero(x < 360), 1.0, 0.0),
        Found(right_t, np.flatnonzero(x >= 360), 1.0, 0.0),
    ]
    clear = ClearFree(broken, SETTINGS.threshold)
    made = []
    real = evidence.wall_owners

    def counted(*args):
        made.append(1)
        return real(*args)

    monkeypatch.setattr(evidence, "wall_owners", counted)
    first = free_space(found, points, clear, corner_index)
    # equal partitions (new objects, copied members, other confidences): the one kept
    alike = [Found(f.transform, f.members.copy(), 0.5, 2.0) for f in found]
    assert free_space(alike, points, clear, corner_index) is first
    assert len(made) == 1
    # a partition with another transform, or other points: made anew, as new clear cells
    # make it
    moved = [found[0], Found(left_t, found[1].members, 1.0, 0.0)]
    for args in ((moved, points), (found, points.copy())):
        again = free_space(*args, clear, corner_index)
        fresh = free_space(*args, ClearFree(broken, SETTINGS.threshold), corner_index)
        assert again is not first
        for a, b in ((again.x, fresh.x), (again.y, fresh.y), (again.owner, fresh.owner)):
            np.testing.assert_array_equal(a, b)
    assert len(made) == 5
    # the same partitions in the other order: made anew, each cell owned by the other index
    swapped = free_space(found[::-1], points, clear, corner_index)
    assert len(made) == 6 and set(np.unique(first.owner)) == {0, 1}
    np.testing.assert_array_equal(swapped.owner, 1 - first.owner)
    # members changed in place after a call: no longer the partitions it was made for
    edited = [Found(f.transform, f.members.copy(), 1.0, 0.0) for f in found]
    free_space(edited, points, clear, corner_index)
    edited[1].members[: edited[1].members.size // 2] = edited[0].members[0]
    free_space(edited, points, clear, corner_index)
    assert len(made) == 8
