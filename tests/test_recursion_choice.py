"""The choice, in a step of the recursion, between the hypotheses of R and of R'."""

from __future__ import annotations

import numpy as np

from brokenness.measure.choice import prefer_unexplained
from brokenness.transform import RigidTransform


def _hyp(rotation: float, agreeing: int, n: int = 1000):
    agree = np.zeros(n, dtype=bool)
    agree[:agreeing] = True
    return RigidTransform(rotation, 0.0, 0.0), agree


def test_the_hypothesis_of_the_reduced_reference_wins_a_near_tie():
    best, rest = _hyp(0.1, 500), _hyp(0.2, 460)
    assert prefer_unexplained(best, rest, margin=50.0) is rest
    assert prefer_unexplained(best, _hyp(0.2, 450), margin=50.0)[0].rotation == 0.2


def test_the_better_hypothesis_wins_beyond_the_margin():
    best, rest = _hyp(0.1, 500), _hyp(0.2, 449)
    assert prefer_unexplained(best, rest, margin=50.0) is best
    assert prefer_unexplained(best, rest, margin=0.0) is best


def test_without_a_reduced_hypothesis_the_best_is_kept():
    best = _hyp(0.1, 500)
    assert prefer_unexplained(best, None, margin=50.0) is best


def test_within_manhattan_is_the_thresholded_distance_map():
    from brokenness.masking import manhattan_distance_map, within_manhattan

    rng = np.random.default_rng(5)
    mask = rng.random((40, 50)) > 0.97
    for threshold in (0.0, 1.0, 2.0, 2.5, 3.0):
        expected = manhattan_distance_map(mask) <= threshold
        assert np.array_equal(within_manhattan(mask, threshold), expected)


def test_mostly_claimed_counts_agreeing_cells_on_matched_walls():
    from brokenness.masking import within_manhattan
    from brokenness.measure.choice import mostly_claimed

    claimed = np.zeros((20, 20), dtype=bool)
    claimed[5, :] = True  # a wall an earlier partition matched
    distance = within_manhattan(claimed, 2.0)
    points = np.array([[x, 5.0] for x in range(6)] + [[x, 15.0] for x in range(4)])
    agree = np.ones(len(points), dtype=bool)
    identity = RigidTransform(0.0, 0.0, 0.0)
    assert mostly_claimed((identity, agree), points, distance, 2.0)  # 6 of 10 on it
    shifted = RigidTransform(0.0, 0.0, 10.0)  # none on it now
    assert not mostly_claimed((shifted, agree), points, distance, 2.0)
    assert not mostly_claimed((identity, np.zeros(len(points), bool)), points, distance, 2.0)
