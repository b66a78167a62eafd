"""Wall contradiction: the map's walls in the reference's clear free space.

A map of another place in which one small piece happens to fit the reference is explained
by one small partition; its other walls, moved with that partition, land in the reference's
free space about as often as walls dropped at random. A map of the reference's place has
almost none there.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from brokenness import OccupancyMap, RigidTransform, load_map
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.evidence import MAP_RATIO, wall_contradiction
from brokenness.measure.partitions import Found

DATA = Path(__file__).parent / "data"
IDENTITY = RigidTransform(0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def reference() -> OccupancyMap:
    m = load_map(DATA / "building_31.yaml")
    return OccupancyMap(m.states[:520, :520].copy(), m.resolution, (0.0, 0.0, 0.0))


def _random_walls(shape: tuple[int, int], n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    canvas = np.zeros(shape, np.uint8)
    for _ in range(n):
        x0, y0 = rng.integers(0, shape[1]), rng.integers(0, shape[0])
        angle, length = rng.uniform(0, np.pi), rng.uniform(20, 120)
        x1, y1 = int(x0 + length * np.cos(angle)), int(y0 + length * np.sin(angle))
        cv2.line(canvas, (int(x0), int(y0)), (x1, y1), 1, 1)
    return canvas.astype(bool)


def test_the_reference_itself_has_no_wall_in_free_space(reference: OccupancyMap) -> None:
    points = cell_points(reference.occupied)
    index = ReferenceIndex.build(reference)
    found = [Found(IDENTITY, np.arange(points.shape[0]), 1.0, 0.0)]
    walls = wall_contradiction(found, points, index, 2.0)
    assert walls.counted > 1000
    assert walls.contradicting == 0
    assert walls.upper_ratio(6.0) < 0.1


def test_a_piece_that_fits_does_not_carry_another_place(reference: OccupancyMap) -> None:
    piece = np.zeros(reference.shape, bool)
    piece[150:280, 150:280] = reference.occupied[150:280, 150:280]
    walls_elsewhere = _random_walls(reference.shape, 120, seed=3) & ~piece
    occupied = piece | walls_elsewhere
    points = cell_points(occupied)
    in_piece = piece[points[:, 1].astype(int), points[:, 0].astype(int)]
    index = ReferenceIndex.build(reference)
    found = [Found(IDENTITY, np.flatnonzero(in_piece), 1.0, 0.0)]
    walls = wall_contradiction(found, points, index, 2.0)
    ratio = walls.ratio()
    assert ratio is not None and ratio > 0.6
    assert walls.upper_ratio(6.0) > MAP_RATIO
    # the piece alone is a partial map of the reference's place: nothing contradicts
    alone = cell_points(piece)
    found_alone = [Found(IDENTITY, np.arange(alone.shape[0]), 1.0, 0.0)]
    assert wall_contradiction(found_alone, alone, index, 2.0).contradicting == 0
