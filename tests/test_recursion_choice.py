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


def test_mostly_on_claimed_is_mostly_claimed_of_the_dilated_matched_walls():
    import brokenness.measure.choice as choice
    from brokenness.measure.choice import mostly_claimed, mostly_on_claimed, near_claimed

    rng = np.random.default_rng(2)
    for trial in range(60):
        occupied = rng.random((30, 40)) < 0.3
        available = occupied & (rng.random((30, 40)) < 0.5)
        points = rng.uniform(-2, 42, (50, 2))
        agree = rng.random(50) < 0.8
        transform = RigidTransform(float(rng.uniform(-0.2, 0.2)), 1.0, -1.0)
        threshold = (0.0, 1.0, 2.0, 3.5, 6.0)[trial % 5]  # 6: the dilation path
        claimed, offset = near_claimed(occupied, available, threshold)
        expected = mostly_claimed((transform, agree), points, claimed, threshold, offset)
        got = mostly_on_claimed((transform, agree), points, occupied, available, threshold)
        assert got == expected
    assert choice._LOOKUP_BALL < 2 * 6 * 7 + 1
