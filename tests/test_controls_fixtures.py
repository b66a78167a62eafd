"""The benchmark's case lists and the regression fixtures are what they say (not the algorithm).

Checks the helpers of ``tests/_controls.py`` and ``benchmarks/cases.py``: controls pair
different places only, the broken real-log maps have the partitions and ground truth they
claim. What ``compute_brokenness`` returns on them is for the tests of the algorithm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _controls import broken_real_log_maps, negative_controls
from cases import control_sources, negative_control_pairs, same_place_pairs, turned_map

from brokenness import load_map
from brokenness.grid import UNKNOWN
from brokenness.masking import ReferenceIndex, cell_points


def test_controls_pair_different_places_and_same_place_pairs_are_apart() -> None:
    sources = control_sources()
    full = negative_control_pairs(sources=sources)
    quick = negative_control_pairs(quick=True, sources=sources)
    assert len(set(full)) == len(full) and set(quick) <= set(full)
    assert all(sources[a].place != sources[b].place for a, b in full)
    same = same_place_pairs(sources)
    assert not set(same) & set(full)
    if "willow_stage" in sources:
        assert ("willow_slam", "willow_stage") in same


def test_a_turned_control_map_holds_the_whole_map_in_a_frame_of_its_own() -> None:
    """``negative_controls.py --turn``: no turn is the map shifted by whole cells; a turn
    keeps every wall on the canvas (nearest neighbour: about as many occupied cells)."""
    m = load_map(Path(__file__).parent / "data" / "tb3_sandbox.yaml")
    h, w = m.shape
    same = turned_map(m, 0.0)
    assert same.shape == (h + 20, w + 20) and same.resolution == m.resolution
    assert np.array_equal(same.states[13 : 13 + h, 17 : 17 + w], m.states)
    assert np.count_nonzero(same.states != UNKNOWN) == np.count_nonzero(m.states != UNKNOWN)
    turned = turned_map(m, 37.0)
    assert abs(turned.n_occupied - m.n_occupied) < 0.15 * m.n_occupied
    known = np.argwhere(turned.states != UNKNOWN)
    assert known.min() > 0 and (known.max(axis=0) < np.array(turned.shape) - 1).all()
    # turned: the map's walls are no longer along the grid (tb3's are)
    assert not np.array_equal(turned.states[13 : 13 + h, 17 : 17 + w], m.states)


def test_the_negative_control_fixtures_are_maps_with_walls() -> None:
    controls = negative_controls()
    assert len(controls) >= 3
    for c in controls:
        assert c.map.n_occupied > 100 and c.reference.n_occupied > 100, c.name


@pytest.fixture(scope="module")
def broken():  # noqa: ANN201
    return broken_real_log_maps()


def test_broken_real_log_maps_hold_their_partitions(broken) -> None:  # noqa: ANN001
    assert [b.expected_degree for b in broken] == [6, 8]
    for b in broken:
        assert len(b.truths) == b.expected_degree + 1 == len(b.shares)
        assert min(b.shares) >= 0.05
        assert np.array_equal(b.labels >= 0, b.map.occupied)
        index = ReferenceIndex.build(b.reference)
        for j, t in enumerate(b.truths):
            pts = cell_points(b.labels == j)
            assert index.occupied_agreement(t.apply(pts), 2.0).mean() > 0.8, (b.name, j)


def test_all_partitions_true_needs_a_one_to_one_match_within_3_cells(broken) -> None:  # noqa: ANN001
    from realistic import all_partitions_true

    from brokenness import RigidTransform

    b = broken[0]
    truths = b.truths
    assert all_partitions_true(list(reversed(truths)), truths, b.labels)  # order is free
    assert not all_partitions_true(truths[:-1], truths, b.labels)  # one short
    assert not all_partitions_true([*truths, truths[0]], truths, b.labels)  # one spurious
    assert not all_partitions_true([truths[0]] * len(truths), truths, b.labels)  # not 1:1
    near = RigidTransform(0.0, 2.0, 1.0).compose(truths[1])  # 2.2 cells off: still true
    far = RigidTransform(0.0, 4.0, 0.0).compose(truths[1])  # 4 cells off: not
    assert all_partitions_true([truths[0], near, *truths[2:]], truths, b.labels)
    assert not all_partitions_true([truths[0], far, *truths[2:]], truths, b.labels)
