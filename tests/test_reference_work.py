"""A call makes its reference's share once, for every grid frame it measures the map in.

:class:`~brokenness.measure.reference.ReferenceWork`: the reference at the working resolution
and its index, made once a call and the same, bit for bit, as when each frame made its own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import brokenness.measure.recursion as recursion
from brokenness import OccupancyMap, RigidTransform, compute_brokenness, load_map
from brokenness.grid import FREE, OCCUPIED
from brokenness.masking import ReferenceIndex
from brokenness.measure.reference import ReferenceWork


def test_the_reference_is_prepared_once_for_every_frame(monkeypatch: pytest.MonkeyPatch):
    """A map measured in two grid frames (README step 11, asked of every map here) indexes
    its reference once, and gets the same result, bit for bit, as with a share made for each
    frame."""
    builds: list[int] = []
    build = ReferenceIndex.build.__func__  # type: ignore[attr-defined]

    def counted(cls, reference):
        builds.append(reference.shape[0])
        return build(cls, reference)

    examples = Path(__file__).parents[1] / "examples"
    m = load_map(examples / "broken_building_31.yaml")
    r = load_map(examples / "building_31.yaml")
    monkeypatch.setattr(ReferenceIndex, "build", classmethod(counted))
    monkeypatch.setattr(recursion, "to_replicate", lambda result: True)
    shared = compute_brokenness(m, r)
    assert shared.parameters["replication_frame"] == "turned 180"  # measured in two frames
    assert len(builds) == 1

    # each frame with a share of its own
    compute = recursion._compute

    def apart(original, work, opts):
        return compute(original, ReferenceWork(work.reference), opts)

    monkeypatch.setattr(recursion, "_compute", apart)
    builds.clear()
    alone = compute_brokenness(m, r)
    assert len(builds) == 2
    assert alone.degree == shared.degree and alone.parameters == shared.parameters
    assert np.array_equal(alone.labels, shared.labels)
    assert [p.transform for p in alone.partitions] == [p.transform for p in shared.partitions]


def test_a_working_reference_is_made_once_per_resolution():
    states = np.full((40, 60), FREE, np.int8)
    states[10, 5:50] = OCCUPIED
    reference = OccupancyMap(states, 0.1)
    work = ReferenceWork(reference)
    same = work.at(None)
    assert work.at(0.1) is same and same.reference is reference
    assert same.to_reference == RigidTransform.identity()
    finer = work.at(0.05)
    assert work.at(0.05) is finer and finer.reference.shape == (80, 120)
    assert finer.index is finer.index  # indexed once
    # a cell of the finer grid maps to the reference's cell that holds it
    assert np.allclose(finer.to_reference.apply([[1.0, 1.0]]), [[0.25, 0.25]])
