"""The hypotheses of a call, remembered and offered once more (``measure/pool.py``)."""

from __future__ import annotations

import numpy as np
import pytest
from _breaking import move_about

from brokenness import OccupancyMap, RigidTransform
from brokenness.masking import cell_points
from brokenness.measure.pool import Recorded, distinct_indices, offered, recorded_transforms
from brokenness.registration.base import Candidate

THRESHOLD = 2.0


class _Fixed:
    """A registrar that returns the same two hypotheses every time."""

    name = "fixed"
    uses_free_space = False
    accepts_cells = True

    def __init__(self) -> None:
        self.calls = 0

    def prepare_reference(self, reference_states):
        return "prepared"

    def candidates(self, prepared_reference, moving_states, max_candidates):
        self.calls += 1
        return [
            Candidate(RigidTransform(0.0, float(self.calls), 0.0), 0.9),
            Candidate(RigidTransform(0.5, 0.0, float(self.calls)), 0.5),
        ]


def test_recorded_remembers_every_hypothesis_in_order() -> None:
    pool: list[tuple[Candidate, ...]] = []
    inner = _Fixed()
    recorded = Recorded(inner, pool)
    assert recorded.prepare_reference(None) == "prepared"
    first = recorded.candidates("prepared", None, 2)
    second = recorded.candidates("prepared", None, 2)
    assert pool == [tuple(first), tuple(second)]  # one group a registration
    assert recorded_transforms(pool) == [c.transform for c in first + second]
    assert inner.calls == 2 and recorded.registrar is inner
    # the registrar's own attributes, the optional ones too
    assert (recorded.name, recorded.uses_free_space, recorded.accepts_cells) == (
        "fixed",
        False,
        True,
    )
    with pytest.raises(AttributeError):
        recorded.exhausted  # noqa: B018 - absent from the registrar: absent here


@pytest.fixture(scope="module")
def halves(corner: OccupancyMap):
    """The corner's cells with the right half turned by 90 degrees: the cells, the right
    half's mask and its true transform (map -> reference)."""
    ref_points = cell_points(corner.occupied)
    right = ref_points[:, 0] >= 260
    motion = move_about(tuple(ref_points[right].mean(axis=0)), 90.0, (15.0, -10.0))
    points = ref_points.copy()
    points[right] = motion.apply(ref_points[right])
    return points, right, motion.inverse()


def test_offered_are_the_hypotheses_that_could_explain_more(corner_index, halves) -> None:
    points, right, truth = halves
    wrong = RigidTransform(0.0, 0.0, 120.0).compose(truth)
    transforms = [RigidTransform(), wrong]
    again = RigidTransform(truth.rotation, truth.tx, truth.ty)  # found twice: offered once
    pool = [RigidTransform(), wrong, truth, again, RigidTransform(0.0, 300.0, 300.0)]
    rivals = offered(pool, transforms, points, corner_index, THRESHOLD)
    # the partitions' own transforms and a placement off the reference add nothing
    assert rivals == [truth]


def test_offered_puts_the_most_promising_first(corner_index, halves) -> None:
    points, _, truth = halves
    transforms = [RigidTransform(), RigidTransform(0.0, 0.0, 120.0).compose(truth)]
    # a placement 4 cells off the truth explains fewer of the half's cells: offered after
    off = RigidTransform(0.0, 0.0, 4.0).compose(truth)
    rivals = offered([off, truth], transforms, points, corner_index, THRESHOLD)
    assert rivals[0] == truth


def test_offered_of_nothing(corner_index) -> None:
    assert offered([], [RigidTransform()], np.zeros((3, 2)), corner_index, THRESHOLD) == []
    assert offered([RigidTransform()], [RigidTransform()], np.zeros((0, 2)), corner_index, 2) == []


def _brute_force(pool, transforms, walls, index, threshold):
    """:func:`offered` by its definition: every distinct hypothesis looked up at every cell."""
    agree = np.stack([index.occupied_agreement(t.apply(walls), threshold) for t in transforms])
    covered = agree.sum(axis=0)
    alone = agree & (covered == 1)
    bounds = []
    for h in [pool[k] for k in distinct_indices(pool, walls.mean(axis=0))]:
        row = index.occupied_agreement(h.apply(walls), threshold)
        new = np.count_nonzero(row & (covered == 0))
        gains = [new - np.count_nonzero(only & ~row) for only in alone]
        bounds.append((max(gains), h))
    ranked = sorted(enumerate(bounds), key=lambda item: (-item[1][0], item[0]))
    return [h for _, (bound, h) in ranked if bound > 0]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_offered_passes_over_only_what_cannot_gain(corner_index, halves, seed) -> None:
    # the samples and the unexplained cells only pass over hypotheses that the whole map
    # would rule out too: the same hypotheses, in the same order, as looking up every one
    # at every cell
    points, _, truth = halves
    rng = np.random.default_rng(seed)
    wrong = RigidTransform(0.0, 0.0, 120.0).compose(truth)
    transforms = [RigidTransform(), wrong, RigidTransform(0.0, 2.5, 0.0).compose(truth)]
    pool = [
        RigidTransform(np.radians(rng.normal(0.0, 1.0)), *rng.normal(0.0, 3.0, 2)).compose(base)
        for base in (RigidTransform(), wrong, truth)
        for _ in range(20)
    ]
    rivals = offered(pool, transforms, points, corner_index, THRESHOLD)
    assert rivals == _brute_force(pool, transforms, points, corner_index, THRESHOLD)
    assert len(rivals) > 0
