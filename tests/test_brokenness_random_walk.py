"""Algorithm 1 driven by the random-walk baseline (issue 4): known degrees 0..2, repeatable.

The random walk costs seconds per step, so these use the depot map at 0.1 m (154x302).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _breaking import break_map, move_about, strips

from brokenness import RigidTransform, compute_brokenness, load_map, resample_to_resolution
from brokenness.masking import cell_points

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def depot():
    with pytest.warns():  # the Nav2 free_thresh trap of depot.yaml
        return resample_to_resolution(load_map(DATA / "depot.yaml"), 0.1)


def _case(ref, degree):
    h, w = ref.shape
    if degree == 0:
        return break_map(ref, strips(ref.shape, []), [RigidTransform()], pad=10)
    if degree == 1:
        motions = [RigidTransform(), move_about((0.8 * w, h / 2), -10.0, (2.0, 1.0))]
        return break_map(ref, strips(ref.shape, [0.6]), motions, pad=10)
    motions = [
        RigidTransform(),
        move_about((0.6 * w, h / 2), 8.0, (2.0, -2.0)),
        move_about((0.87 * w, h / 2), -15.0, (-2.0, 2.0)),
    ]
    return break_map(ref, strips(ref.shape, [0.45, 0.75]), motions, pad=10)


@pytest.mark.parametrize("degree", [0, 1, 2])
def test_random_walk_finds_the_degree_and_transforms(depot, degree):
    broken, truths = _case(depot, degree)
    result = compute_brokenness(broken, depot, method="random-walk", seed=1)
    assert result.method == "random-walk"
    assert result.degree == degree
    found = []
    for p in result.partitions:
        pts = cell_points(result.labels == p.index)
        errors = [float(p.transform.displacement(t, pts).mean()) for t in truths]
        found.append(int(np.argmin(errors)))
        assert min(errors) < 1.5
    assert sorted(found) == list(range(degree + 1))


def test_random_walk_same_seed_same_answer(depot):
    broken, _ = _case(depot, 1)
    options = {"registration_options": {"rotations": 8, "walkers_per_angle": 1, "patience": 60}}
    a = compute_brokenness(broken, depot, method="random-walk", seed=7, **options)
    b = compute_brokenness(broken, depot, method="random-walk", seed=7, **options)
    assert np.array_equal(a.labels, b.labels)
    assert [p.transform for p in a.partitions] == [p.transform for p in b.partitions]
