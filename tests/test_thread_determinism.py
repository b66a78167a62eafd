"""Results do not depend on how many threads OpenCV runs.

A batch worker runs OpenCV on one thread (``brokenness._threads``), ``brokenness compute``
on one per core, and machines differ in cores: the same pair must give the same bits in
all of them. ``cv2.warpAffine``'s bilinear warp of a float image does not (it gave other
bits on one thread than on two or more, from canvases of about 200 cells), so iFMI draws
its turned images with ``cv2.remap`` of a map computed in numpy (``_draw_turned``).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from brokenness import compute_brokenness, load_map
from brokenness.registration.ifmi import _draw_turned


@contextlib.contextmanager
def opencv_threads(n: int) -> Iterator[None]:
    before = cv2.getNumThreads()
    cv2.setNumThreads(n)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def _walls(shape: tuple[int, int], seed: int) -> np.ndarray:
    """A float32 image of a few hundred straight wall segments (what iFMI turns)."""
    rng = np.random.default_rng(seed)
    img = np.zeros(shape, np.uint8)
    for _ in range(300):
        x0, y0 = rng.integers(0, shape[1]), rng.integers(0, shape[0])
        length, angle = rng.integers(5, 60), rng.choice([0.0, math.pi / 2, rng.uniform(0, math.pi)])
        x1, y1 = int(x0 + length * math.cos(angle)), int(y0 + length * math.sin(angle))
        cv2.line(img, (int(x0), int(y0)), (x1, y1), 1, 1)
    return img.astype(np.float32)


def _forward(image: np.ndarray, theta: float, side: int) -> np.ndarray:
    """The 2x3 matrix of iFMI's drawing: ``image`` turned by ``theta`` about its centre into
    the centre of a ``side`` x ``side`` canvas, the shift rounded to whole cells."""
    h, w = image.shape
    c, s = math.cos(theta), math.sin(theta)
    turn = np.array([[c, -s], [s, c]])
    centre_m = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    shift = np.round(np.full(2, (side - 1) / 2.0) - turn @ centre_m)
    return np.column_stack([turn, shift])


def _drawn(image: np.ndarray, theta: float, side: int) -> np.ndarray:
    canvas = np.zeros((side + 7, side + 5), np.float32)[:side, :side]  # a view, as iFMI's
    _draw_turned(image, theta, _forward(image, theta, side)[:, 2], canvas)
    return canvas.copy()


@pytest.mark.parametrize("degrees", [0.3, 17.0, 93.7, 180.0, -61.2])
def test_turned_image_has_the_same_bits_on_any_number_of_threads(degrees: float) -> None:
    image = _walls((380, 420), seed=int(degrees * 10) % 97)
    side = math.ceil(math.hypot(*image.shape)) + 2
    theta = math.radians(degrees)
    with opencv_threads(1):
        one = _drawn(image, theta, side)
    for n in (2, 4, 8):
        with opencv_threads(n):
            assert _drawn(image, theta, side).tobytes() == one.tobytes(), n
    assert one.sum() > 0.9 * image.sum()  # the image is on the canvas, not cut off


def test_turned_image_is_the_warp_of_the_image() -> None:
    """The same geometry as ``cv2.warpAffine`` of the forward matrix (bilinear, 1/32 cell):
    at most one sub-cell step of interpolation apart, cell by cell."""
    image = _walls((300, 260), seed=3)
    side = math.ceil(math.hypot(*image.shape)) + 2
    for degrees in (0.0, 12.5, 90.0, 147.0):
        theta = math.radians(degrees)
        forward = _forward(image, theta, side)
        with opencv_threads(1):
            warped = cv2.warpAffine(image, forward, (side, side), flags=cv2.INTER_LINEAR)
        drawn = _drawn(image, theta, side)
        assert np.abs(drawn - warped).max() <= 1.0 / 16.0, degrees
        if degrees == 0.0:  # a whole-cell shift: an exact copy
            assert np.array_equal(drawn, warped)


def test_a_broken_map_gives_the_same_bits_on_one_thread_as_on_two() -> None:
    """A realistic heavily broken map (8 bumps, map at 0.1 m in its own frame, reference at
    0.05 m): before iFMI drew with ``cv2.remap``, its transforms differed in their last
    digits between one OpenCV thread and two."""
    folder = Path(__file__).parent / "data" / "realistic_sim_d8_s14"
    m, ref = load_map(folder / "map.yaml"), load_map(folder / "reference.yaml")
    results = []
    for n in (1, 2):
        with opencv_threads(n):
            results.append(compute_brokenness(m, ref))
    one, two = results
    assert one.measured and one.degree == two.degree
    bits = [
        np.array([(p.transform.rotation, p.transform.tx, p.transform.ty) for p in r.partitions])
        for r in results
    ]
    assert bits[0].tobytes() == bits[1].tobytes()
    assert np.array_equal(one.labels, two.labels)
