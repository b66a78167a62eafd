"""The choice, in a step of the recursion, between the hypotheses of R and of R'."""

from __future__ import annotations

import numpy as np

from brokenness.measure.recursion import _prefer_unexplained
from brokenness.transform import RigidTransform


def _hyp(rotation: float, agreeing: int, n: int = 1000):
    agree = np.zeros(n, dtype=bool)
    agree[:agreeing] = True
    return RigidTransform(rotation, 0.0, 0.0), agree


def test_the_hypothesis_of_the_reduced_reference_wins_a_near_tie():
    best, rest = _hyp(0.1, 500), _hyp(0.2, 460)
    assert _prefer_unexplained(best, rest, margin=50.0) is rest
    assert _prefer_unexplained(best, _hyp(0.2, 450), margin=50.0)[0].rotation == 0.2


def test_the_better_hypothesis_wins_beyond_the_margin():
    best, rest = _hyp(0.1, 500), _hyp(0.2, 449)
    assert _prefer_unexplained(best, rest, margin=50.0) is best
    assert _prefer_unexplained(best, rest, margin=0.0) is best


def test_without_a_reduced_hypothesis_the_best_is_kept():
    best = _hyp(0.1, 500)
    assert _prefer_unexplained(best, None, margin=50.0) is best
