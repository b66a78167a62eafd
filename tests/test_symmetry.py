"""Step 10: pieces of one part held at twins that a symmetry of the reference relates are one
partition (``brokenness.measure.symmetry``)."""

from __future__ import annotations

import numpy as np
import pytest
from _controls import BrokenCase, split_part_drawn_maps

from brokenness import (
    BrokennessOptions,
    OccupancyMap,
    RigidTransform,
    compute_brokenness,
    simulate_broken_map,
)
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure import recursion
from brokenness.measure.options import Settings
from brokenness.measure.partitions import Found
from brokenness.measure.symmetry import merges, symmetries
from brokenness.registration.methods import make_registrar


@pytest.fixture(scope="module")
def case() -> BrokenCase:
    """The drawn atrium of degree 5 (``benchmarks/drawn_buildings.py``, seed 0) in its own
    frame: one part of 21 % was held as three pieces at twins 72 degrees round before step
    10 (``test_negative_controls.test_pieces_of_one_part_held_at_twins_are_one_partition``
    checks every part in place)."""
    return split_part_drawn_maps()[0]


@pytest.fixture(scope="module")
def atrium(case: BrokenCase) -> tuple[OccupancyMap, OccupancyMap]:
    return case.map, case.reference


def _reference_symmetries(ref: OccupancyMap) -> tuple[list[RigidTransform], ReferenceIndex]:
    index = ReferenceIndex.build(ref)
    registrar = make_registrar("ifmi", **recursion._IFMI_THOROUGH_OPTIONS)  # its wider search
    settings = Settings.of(BrokennessOptions(), 1000, True, True)
    prepared = registrar.prepare_reference(ref.states)
    return symmetries(registrar, prepared, index, settings), index


def test_the_reference_registered_with_itself_gives_its_turns_by_72_degrees(atrium):
    _, ref = atrium
    motions, index = _reference_symmetries(ref)
    turns = sorted(round(m.rotation_deg) % 360 for m in motions)
    for turn in (72, 144, 216, 288):  # the five corridors, 72 degrees apart
        assert turn in turns
    walls = index.occupied_points
    identity = RigidTransform.identity()
    # no identity among them, and the turns by 72 degrees map the walls onto walls
    assert all(np.median(m.displacement(identity, walls)) > 2.0 for m in motions)
    for turn in (72, 144, 216, 288):
        at_turn = [m for m in motions if round(m.rotation_deg) % 360 == turn]
        best = max(np.count_nonzero(index.occupied_agreement(m.apply(walls), 2.0)) for m in at_turn)
        assert best > 0.5 * walls.shape[0]


def test_two_halves_of_an_unbroken_map_at_twins_are_one_merge(atrium):
    _, ref = atrium
    motions, index = _reference_symmetries(ref)
    turn = next(m for m in motions if round(m.rotation_deg) % 360 == 72)
    points = cell_points(ref.occupied)  # the reference as its own, unbroken, map
    half = points[:, 0] < np.median(points[:, 0])
    a, b = np.flatnonzero(half), np.flatnonzero(~half)
    settings = Settings.of(BrokennessOptions(), points.shape[0], True, True)
    # one half in place, the other at its twin 72 degrees round: both consistent on their own
    found = [Found(RigidTransform.identity(), a, 1.0, 0.0), Found(turn, b, 1.0, 0.0)]
    best = merges(found, points, index, settings, motions)[0]
    assert best.partitions == (0, 1)
    assert best.lost < settings.min_cells
    # the transform that explains both puts the halves together: at one place or a twin of it
    moved = best.transform.apply(points)
    assert np.count_nonzero(index.occupied_agreement(moved, 2.0)) > 0.9 * points.shape[0]
    # turned by 30 degrees instead (no symmetry of the atrium): nothing merges them
    centre = points.mean(axis=0)
    turned = RigidTransform(np.radians(30.0), 0.0, 0.0)
    shift = centre - turned.apply(centre[None])[0]
    off = RigidTransform(np.radians(30.0), float(shift[0]), float(shift[1]))
    apart = [found[0], Found(off, b, 1.0, 0.0)]
    assert all(m.partitions != (0, 1) for m in merges(apart, points, index, settings, motions))


def test_without_the_symmetries_the_pieces_at_twins_stay(case, monkeypatch):
    """The drawn atrium gets its degree, 5, by step 10; without the reference's symmetries
    the three pieces of one part stay (degree 7)."""
    assert compute_brokenness(case.map, case.reference).degree == case.expected_degree == 5
    monkeypatch.setattr(recursion, "symmetries", lambda *args: [])
    assert compute_brokenness(case.map, case.reference).degree == 7


def test_a_small_true_part_that_a_twin_explains_only_in_part_is_kept():
    """A simulated map (seed 16, degree 5) whose 99-cell true part a twin of another
    partition explains only 46 cells of: fewer than the smallest partition's cells are lost,
    but the twin does not explain the part, so no merge (degree 4 with the allowance alone)."""
    sim = simulate_broken_map(seed=16, degree=5)
    result = compute_brokenness(sim.map, sim.reference)
    assert result.degree == sim.expected_degree == 5
