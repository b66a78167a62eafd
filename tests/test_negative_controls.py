"""Negative controls: pairs that must not get a degree (the map is not of the reference's
place), and the contradiction measure that tells them apart."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

import brokenness
from brokenness import OccupancyMap, RigidTransform, compute_brokenness, load_map
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.evidence import MAP_RATIO, contradiction
from brokenness.measure.partitions import Found

DATA = Path(__file__).parent / "data"


def _load(name: str) -> OccupancyMap:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # depot's Nav2 grey warning
        return load_map(DATA / name)


def _random_walls(shape: tuple[int, int], n: int, seed: int) -> OccupancyMap:
    """Seeded random wall segments (0.5-6 m at 5 cm), free around them."""
    rng = np.random.default_rng(seed)
    img = np.zeros(shape, np.uint8)
    for _ in range(n):
        x0, y0 = int(rng.integers(0, shape[1])), int(rng.integers(0, shape[0]))
        angle, length = rng.uniform(0, np.pi), rng.uniform(10, 120)
        x1, y1 = int(x0 + length * np.cos(angle)), int(y0 + length * np.sin(angle))
        cv2.line(img, (x0, y0), (x1, y1), 1, 1)
    return OccupancyMap.from_array(img.astype(bool), resolution=0.05)


def _not_measured(m: OccupancyMap, ref: OccupancyMap) -> brokenness.BrokennessResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", brokenness.NothingFoundWarning)
        return compute_brokenness(m, ref)


@pytest.mark.parametrize(
    ("map_name", "reference_name"),
    [
        ("building_31.yaml", "willow-2010-02-18-0.10.yaml"),
        ("willow-2010-02-18-0.10.yaml", "building_31.yaml"),
        ("depot.yaml", "building_31.yaml"),
        ("building_31.yaml", "depot.yaml"),
        ("tb3_sandbox.yaml", "building_31.yaml"),
    ],
)
def test_a_map_of_another_building_gets_no_degree(map_name, reference_name):
    """Before the contradiction test these got degrees 10, 2, 11, 1 and 3."""
    result = _not_measured(_load(map_name), _load(reference_name))
    assert not result.measured and result.degree is None, result.partitions
    assert result.contradiction is not None and result.contradiction > MAP_RATIO


def test_random_walls_get_no_degree():
    """Random wall segments against a real building (degree 7 before)."""
    ref = _load("building_31.yaml")
    result = _not_measured(_random_walls(ref.shape, 60, 1), ref)
    assert not result.measured and result.degree is None


def test_another_simulated_building_gets_no_degree():
    """Two buildings of the same generator (rooms of the same sizes): degree 4 before."""
    one = brokenness.simulate_broken_map(seed=1, degree=0)
    other = brokenness.simulate_broken_map(seed=2, degree=0)
    result = _not_measured(one.map, other.reference)
    assert not result.measured and result.degree is None


def test_positive_pairs_stay_measured():
    """The bundled broken example and a map against itself keep their degree."""
    example = Path(__file__).parents[1] / "examples"
    result = compute_brokenness(
        load_map(example / "broken_building_31.yaml"), load_map(example / "building_31.yaml")
    )
    assert result.measured and result.degree == 2
    assert result.contradiction is not None and result.contradiction < 0.2
    b31 = _load("building_31.yaml")
    assert compute_brokenness(b31, b31).degree == 0


def _room_states() -> np.ndarray:
    states = np.full((100, 140), UNKNOWN, np.int8)
    states[10:90, 10:130] = FREE
    states[10, 10:130] = states[89, 10:130] = OCCUPIED
    states[10:90, 10] = states[10:90, 129] = OCCUPIED
    states[10:60, 70] = OCCUPIED  # an inner wall
    return states


def test_contradiction_is_zero_aligned_and_high_when_misplaced():
    """Free space moved onto the reference's walls contradicts; aligned, it never does."""
    room = OccupancyMap(_room_states())
    index = ReferenceIndex.build(room)
    points = cell_points(room.occupied)
    every = np.arange(points.shape[0])
    aligned = contradiction([Found(RigidTransform(), every, 1.0, 0.0)], points, room, index, 2.0)
    assert aligned.contradicting.sum() == 0 and aligned.counted.sum() > 1000
    assert aligned.ratio() == 0.0
    # shifted by 30 cells, the inner wall of the reference crosses the map's free space
    shifted = contradiction(
        [Found(RigidTransform(0.0, 30.0, 0.0), every, 1.0, 0.0)], points, room, index, 2.0
    )
    assert shifted.contradicting.sum() > 100
    assert shifted.ratio() is not None and shifted.ratio() > 0.25
    # chance rate: the occupied share of the known reference cells
    assert aligned.chance == pytest.approx(
        np.count_nonzero(room.occupied) / np.count_nonzero(room.known)
    )
