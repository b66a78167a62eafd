"""Pieces of one part held as several partitions (:mod:`brokenness.measure.pieces`).

A building that looks the same under a quarter turn (a hall with four identical arms): an
unbroken map of it held as two partitions, its left half in place and its right half at
the quarter-turn twin of its place, where every cell of it agrees too. Every stage that
counts explained cells is content with that; the degree is 1 where it is 0. Registered
together, the two halves give a transform that explains both, and they are joined. Two
parts that really are off relative to each other are not.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _breaking import SETTINGS, break_map, move_about

from brokenness import OccupancyMap, RigidTransform, compute_brokenness
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.context import MapContext
from brokenness.measure.evidence import ClearFree
from brokenness.measure.partitions import Found, reassign
from brokenness.measure.pieces import join_pieces, neighbours
from brokenness.measure.recursion import _IFMI_RECURSION_OPTIONS, _IFMI_THOROUGH_OPTIONS
from brokenness.measure.support import occupied_around
from brokenness.measure.views import prepared_reference
from brokenness.registration.methods import make_registrar

SIDE = 400
CENTRE = (SIDE - 1) / 2  # np.rot90 turns about the middle of the grid


@pytest.fixture(scope="module")
def building() -> OccupancyMap:
    """A hall with four identical arms (a corridor to a room with an L-shaped wall and a
    pillar), exactly the same under a quarter turn, at 5 cm."""
    c = SIDE // 2
    inside = np.zeros((SIDE, SIDE), np.uint8)
    cv2.rectangle(inside, (c - 50, c - 50), (c + 50, c + 50), 1, -1)
    cv2.rectangle(inside, (c + 50, c - 12), (c + 110, c + 12), 1, -1)
    cv2.rectangle(inside, (c + 110, c - 60), (c + 185, c + 40), 1, -1)
    inner = np.zeros((SIDE, SIDE), np.uint8)
    cv2.line(inner, (c + 130, c - 40), (c + 165, c - 40), 1, 3)
    cv2.line(inner, (c + 165, c - 40), (c + 165, c - 5), 1, 3)
    cv2.circle(inner, (c + 140, c + 20), 5, 1, -1)
    walls = (cv2.dilate(inside, np.ones((7, 7), np.uint8)) > 0) & (inside == 0) | (inner > 0)
    free = (inside > 0) & ~walls
    occupied = np.any([np.rot90(walls, k) for k in range(4)], axis=0)
    free = np.any([np.rot90(free, k) for k in range(4)], axis=0) & ~occupied
    states = np.full((SIDE, SIDE), UNKNOWN, np.int8)
    states[free] = FREE
    states[occupied] = OCCUPIED
    return OccupancyMap(states, 0.05, (0.0, 0.0, 0.0))


def _context(m: OccupancyMap, index: ReferenceIndex) -> MapContext:
    points = cell_points(m.occupied)
    return MapContext(
        points,
        m,
        index,
        SETTINGS,
        occupied_around(points, m.shape),
        ClearFree(m, SETTINGS.threshold),
    )


def _join(found: list[Found], context: MapContext) -> list[Found]:
    thorough = make_registrar("ifmi", **{**_IFMI_RECURSION_OPTIONS, **_IFMI_THOROUGH_OPTIONS})
    index = context.index
    whole = prepared_reference(thorough, index.reference, index.occupied, True, False)
    return join_pieces(found, context, thorough, whole)


def test_the_building_is_the_same_under_a_quarter_turn(building: OccupancyMap) -> None:
    assert all(np.array_equal(building.states, np.rot90(building.states, k)) for k in range(4))


def test_two_halves_of_an_unbroken_map_held_at_twins_are_joined(building: OccupancyMap) -> None:
    index = ReferenceIndex.build(building)
    context = _context(building, index)
    points = context.points
    quarter = move_about((CENTRE, CENTRE), 90.0, (0.0, 0.0))
    left = np.flatnonzero(points[:, 0] < CENTRE)
    right = np.flatnonzero(points[:, 0] >= CENTRE)
    found = [Found(RigidTransform(), left, 1.0, 0.0), Found(quarter, right, 1.0, 0.0)]
    for f in found:  # each half, at its place or at its twin, agrees everywhere
        moved = f.transform.apply(points[f.members])
        assert index.occupied_agreement(moved, SETTINGS.threshold).all()
    assert neighbours(found, points) == [[1], [0]]

    joined = _join(found, context)
    assert len(joined) == 1
    one = joined[0]
    assert one.members.size == points.shape[0]
    assert index.occupied_agreement(one.transform.apply(points), SETTINGS.threshold).mean() > 0.99


def test_two_parts_that_are_off_relative_to_each_other_are_not_joined(
    building: OccupancyMap,
) -> None:
    right = np.zeros(building.shape, bool)
    right[:, int(CENTRE) + 1 :] = True
    turned = move_about((300.0, CENTRE), 25.0, (6.0, -4.0))
    broken, truths = break_map(building, [~right, right], [RigidTransform(), turned], pad=40)
    index = ReferenceIndex.build(building)
    context = _context(broken, index)
    everything = np.arange(context.points.shape[0])
    found = reassign(
        [Found(t, everything, 1.0, 0.0) for t in truths],
        context.points,
        index,
        SETTINGS.threshold,
        SETTINGS.min_cells,
    )
    assert len(found) == 2
    assert _join(found, context) is found


def test_the_measure_counts_the_unbroken_map_once(building: OccupancyMap) -> None:
    result = compute_brokenness(building, building)
    assert result.measured and result.degree == 0
