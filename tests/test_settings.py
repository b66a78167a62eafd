"""The chance tests of :class:`brokenness.measure.options.Settings`."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from _breaking import SETTINGS
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import binom, norm

TAIL = norm.sf(SETTINGS.significance)  # z = 6: about 1e-9


@given(st.integers(0, 5000), st.floats(0.001, 0.999))
@settings(max_examples=200, deadline=None)
def test_beyond_chance_is_the_exact_binomial_count(n: int, p0: float) -> None:
    k = SETTINGS.beyond_chance(n, p0)
    assert 1 <= k <= n + 1
    if k <= n:
        assert binom.sf(k - 1, n, p0) <= TAIL * (1 + 1e-9)  # P(X >= k): rare enough
    if k >= 2:
        assert binom.sf(k - 2, n, p0) > TAIL * (1 - 1e-9)  # one fewer is not


@pytest.mark.parametrize(("n", "p0"), [(1000, 0.1), (20000, 0.2), (5000, 0.05)])
def test_beyond_chance_is_near_the_normal_rule_when_chance_is_large(n: int, p0: float) -> None:
    chance, spread, _ = SETTINGS.needed(n, p0)
    normal = chance + SETTINGS.significance * spread
    # the binomial's tail is heavier (skewed right for p0 < 1/2), by a few cells
    assert normal < SETTINGS.beyond_chance(n, p0) <= normal + 0.12 * SETTINGS.significance * spread


def test_beyond_chance_when_chance_is_small() -> None:
    # 7 of 7 at p0 = 0.096 pass the normal rule (5.3) but happen 7.5e-8 of the time
    chance, spread, _ = SETTINGS.needed(7, 0.096)
    assert 7 > chance + SETTINGS.significance * spread
    assert SETTINGS.beyond_chance(7, 0.096) == 8  # more than all of them: never
    assert SETTINGS.beyond_chance(9, 0.096) == 9
    assert SETTINGS.beyond_chance(0, 0.1) == 1
    assert SETTINGS.beyond_chance(50, 0.0) == 1  # no chance: one cell is evidence
    assert SETTINGS.beyond_chance(50, 1.0) == 51
    assert math.isclose(0.096**9, binom.sf(8, 9, 0.096))


@pytest.mark.parametrize("tests", [2, 10, 1000, 50_000])
def test_for_tests_divides_the_tail_among_the_tests(tests: int) -> None:
    # Bonferroni: the one-sided normal tail of the corrected significance, times the tests,
    # is the tail of the stopping rule's own
    def tail(z: float) -> float:
        return 0.5 * math.erfc(z / math.sqrt(2.0))

    strict = SETTINGS.for_tests(tests)
    assert strict.significance > SETTINGS.significance
    assert tail(strict.significance) * tests == pytest.approx(tail(SETTINGS.significance), rel=1e-9)
    assert replace(strict, significance=SETTINGS.significance) == SETTINGS  # nothing else
    assert SETTINGS.for_tests(1) is SETTINGS and SETTINGS.for_tests(0) is SETTINGS
