"""The benchmark's case lists and the regression fixtures are what they say (not the algorithm).

Checks the helpers of ``tests/_controls.py`` and ``benchmarks/cases.py``: controls pair
different places only, the broken real-log maps have the partitions and ground truth they
claim. What ``compute_brokenness`` returns on them is for the tests of the algorithm.
"""

from __future__ import annotations

import numpy as np
import pytest
from _controls import broken_real_log_maps, negative_controls
from cases import control_sources, negative_control_pairs, same_place_pairs

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
