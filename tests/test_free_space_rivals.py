"""A rival judged by the free space as well as the walls (the settle step, step 3).

Two rooms of the same size side by side, A and B. A has a short wall stub that B lacks, B a
pillar in the middle that A lacks. The map holds both, room A moved by a bump; its partition
is placed where room B is (its walls fit there as well as at home, but for the stub), and
the true transform of A is offered as a rival. By the walls alone the rival gains only the
stub's cells, fewer than chance could (the margin of the stopping rule's ``z``); but under
the wrong placement A's free space covers B's pillar, and under the rival it lands on
nothing: the contradiction of the partition's free space falls from about one free cell in
twenty to none, far beyond ``z`` standard deviations.
"""

from __future__ import annotations

import numpy as np
import pytest
from _breaking import SETTINGS, break_map, median_error

from brokenness import OccupancyMap, RigidTransform
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.context import MapContext
from brokenness.measure.evidence import (
    MAP_RATIO,
    ClearFree,
    Contradiction,
    contradiction,
    free_space,
)
from brokenness.measure.partitions import Found
from brokenness.measure.recovery import relocation_rivals
from brokenness.measure.settle import settle
from brokenness.measure.support import occupied_around
from brokenness.measure.views import prepared_reference
from brokenness.registration.methods import make_registrar

#: Room A's bump in the map (cells, x and y).
BUMP = (0.0, 30.0)


def _rooms() -> tuple[OccupancyMap, np.ndarray, np.ndarray]:
    """The reference (rooms A and B) and the masks of the two rooms' regions."""
    states = np.full((170, 300), UNKNOWN, np.int8)
    regions = []
    for c0 in (20, 160):  # room A, room B: 100 x 100 cells, walls two cells thick
        states[30:132, c0 : c0 + 102] = OCCUPIED
        states[32:130, c0 + 2 : c0 + 100] = FREE
        region = np.zeros(states.shape, bool)
        region[25:137, c0 - 5 : c0 + 107] = True
        regions.append(region)
    states[32:46, 70:72] = OCCUPIED  # A's stub
    states[70:91, 200:221] = OCCUPIED  # B's pillar
    return OccupancyMap(states, 0.05), regions[0], regions[1]


@pytest.fixture(scope="module")
def case():
    """The map, its points, room A's cells, the partitions (A at B's place), A's true
    transform and the reference's index."""
    reference, room_a, room_b = _rooms()
    moved = RigidTransform(0.0, *BUMP)
    broken, truths = break_map(reference, [room_a, room_b], [moved, RigidTransform()], pad=10)
    points = cell_points(broken.occupied)
    in_a = truths[0].apply(points)[:, 0] < 140  # left of the gap between the rooms
    wrong = RigidTransform(0.0, 140.0, 0.0).compose(truths[0])  # A's walls onto B's
    found = [
        Found(truths[1], np.flatnonzero(~in_a), 1.0, 0.0),
        Found(wrong, np.flatnonzero(in_a), 1.0, 0.0),
    ]
    return broken, points, in_a, found, truths[0], ReferenceIndex.build(reference)


def test_free_space_counts_are_those_of_the_contradiction(case) -> None:
    broken, points, _, found, truth, index = case
    clear = ClearFree(broken, SETTINGS.threshold)
    owned = free_space(found, points, clear, index)
    whole = contradiction(found, points, clear, index)
    again = contradiction(found, points, clear, index, owned)
    assert np.array_equal(whole.counted, again.counted)
    assert np.array_equal(whole.contradicting, again.contradicting)
    for j, f in enumerate(found):
        assert owned.counts(j, f.transform, index) == (whole.counted[j], whole.contradicting[j])
    # A's free space on B's pillar under the wrong placement, on nothing under its own
    counted, crossing = owned.counts(1, found[1].transform, index)
    assert crossing > 0.03 * counted
    counted, crossing = owned.counts(1, truth, index)
    assert counted > 5000 and crossing == 0


def test_walls_alone_do_not_take_the_rival(case) -> None:
    _, points, in_a, found, truth, index = case
    settled = settle(found, points, index, SETTINGS, [truth])
    assert median_error(settled[1].transform, truth, points[in_a]) > 100.0


def test_the_free_space_takes_the_rival(case) -> None:
    broken, points, in_a, found, truth, index = case
    settled = settle(
        found, points, index, SETTINGS, [truth], clear=ClearFree(broken, SETTINGS.threshold)
    )
    assert len(settled) == 2
    assert median_error(settled[1].transform, truth, points[in_a]) < 0.5
    assert settled[0].transform is found[0].transform


def test_the_free_space_does_not_move_a_right_placement(case) -> None:
    # the other way round: A at home, B's placement offered as a rival gains no cell
    broken, points, in_a, found, truth, index = case
    right = [found[0], Found(truth, found[1].members, 1.0, 0.0)]
    settled = settle(
        right,
        points,
        index,
        SETTINGS,
        [found[1].transform],
        clear=ClearFree(broken, SETTINGS.threshold),
    )
    assert median_error(settled[1].transform, truth, points[in_a]) < 0.5


def test_only_a_partition_whose_free_space_fails_is_searched_again(case) -> None:
    # the relocation's choice (``Contradiction.doubtful``): A at B's place crosses B's pillar
    broken, points, _, found, truth, index = case
    z = SETTINGS.significance
    clear = ClearFree(broken, SETTINGS.threshold)
    wrong = contradiction(found, points, clear, index)
    assert wrong.doubtful(z) == [1]
    assert wrong.upper_ratio(z, 1) > MAP_RATIO >= wrong.upper_ratio(z, 0)
    right = [found[0], Found(truth, found[1].members, 1.0, 0.0)]
    assert contradiction(right, points, clear, index).doubtful(z) == []


def test_a_partition_bound_is_the_map_bound_of_its_counts() -> None:
    counts = Contradiction(np.array([4000, 50, 0]), np.array([40, 0, 0]), 0.1, 1)
    for i in range(3):
        alone = Contradiction(counts.counted[i : i + 1], counts.contradicting[i : i + 1], 0.1, 1)
        assert counts.upper_ratio(6.0, i) == alone.upper_ratio(6.0)
    # 4000 cells at a tenth of chance: in place; 50 cells (5 on walls by chance) cannot show
    # it, even with none on walls; no cell at all cannot either
    assert counts.doubtful(6.0) == [1, 2]


def _relocation_search(broken, points, index):  # noqa: ANN001, ANN202
    """The relocation's context, registrar and prepared reference for the two rooms' map."""
    registrar = make_registrar("ifmi", rotation_peaks=6, peak_ratio=0.05, translation_peaks=3)
    whole = prepared_reference(registrar, index.reference, index.occupied, True, False)
    clear = ClearFree(broken, SETTINGS.threshold)
    around = occupied_around(points, broken.shape)
    return MapContext(points, broken, index, SETTINGS, around, clear), registrar, whole


def test_the_relocation_offers_the_placement_whose_free_space_fits(case) -> None:
    # step 8: A's cells placed at every translation fit at B's place and at home alike, and
    # the free space picks home: offered after the best hypothesis of A's cells registered
    # alone (and before that of their neighbourhood), each rival as found and refitted on
    # A's cells. B's partition, not searched, has its own cells registered alone first
    # (their best place elsewhere; no neighbourhood, no pair), its half turn placing nothing
    broken, points, in_a, found, truth, index = case
    context, registrar, whole = _relocation_search(broken, points, index)
    owned = free_space(found, points, context.clear, index)

    registered = relocation_rivals(found, context, registrar, whole, [1])
    offered = relocation_rivals(found, context, registrar, whole, [1], owned)
    assert len(registered) == 6 and len(offered) == len(registered) + 2
    assert offered[:4] + offered[6:] == registered
    assert all(median_error(t, found[0].transform, points[~in_a]) > 3.0 for t in registered[:2])
    assert all(median_error(t, truth, points[in_a]) < 1.0 for t in registered[2:])
    assert median_error(offered[4], truth, points[in_a]) < 1.0
    assert median_error(offered[5], truth, points[in_a]) < 1.0


def test_every_partition_is_registered_alone_and_placed_at_the_opposite_rotation(case) -> None:
    # after settling (``relocation_rivals``): a partition whose free space does not make it
    # doubtful has its own cells registered alone (no neighbourhood, no pair: session 41, a
    # twin of a room can show its free space in place), and, given the free space, its cells
    # placed at every translation at the opposite of its rotation. Room A held at home
    # turned half a turn about its centre fits its square walls but for the stub: its cells
    # registered alone give its home, and so does its half turn
    broken, points, in_a, found, truth, index = case
    centre = truth.apply(points[in_a]).mean(axis=0)
    half_turn = RigidTransform(np.pi, *(2.0 * centre)).compose(truth)  # about the centre
    turned = [found[0], Found(half_turn, found[1].members, 1.0, 0.0)]
    context, registrar, whole = _relocation_search(broken, points, index)
    owned = free_space(turned, points, context.clear, index)
    registered = relocation_rivals(turned, context, registrar, whole, [])
    assert len(registered) == 4  # each partition's best place elsewhere, found and refitted
    assert all(median_error(t, truth, points[in_a]) < 1.0 for t in registered[2:])
    offered = relocation_rivals(turned, context, registrar, whole, [], owned)
    assert len(offered) == 6 and offered[:4] == registered
    assert all(median_error(t, truth, points[in_a]) < 1.0 for t in offered[4:])
