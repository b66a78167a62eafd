"""Rotation hypotheses from wall directions (brokenness.registration.orientation)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brokenness.grid import FREE, OCCUPIED
from brokenness.masking import cell_points
from brokenness.registration.orientation import BINS, hough_spectrum, rotation_candidates

SIZE = 400


def _walls(segments: list[tuple[float, float, float, float]], turn: float = 0.0) -> np.ndarray:
    """A grid of states whose walls are ``segments`` (x0, y0, x1, y1; around the middle of
    the grid), turned by ``turn`` radians about the middle before they are drawn."""
    c, s = math.cos(turn), math.sin(turn)
    mid = SIZE / 2.0
    image = np.zeros((SIZE, SIZE), np.uint8)
    for x0, y0, x1, y1 in segments:
        ends = [(mid + c * x - s * y, mid + s * x + c * y) for x, y in ((x0, y0), (x1, y1))]
        (a, b), (d, e) = ends
        cv2.line(image, (round(a), round(b)), (round(d), round(e)), 1, 1)
    return np.where(image > 0, OCCUPIED, FREE).astype(np.int8)


#: A wall of 150 cells along x and one of 60 at 30 degrees to it: one direction dominates,
#: so the first peak is the rotation itself (modulo a half turn).
_FLOOR = [(-75.0, 0.0, 75.0, 0.0), (-40.0, 40.0, -40.0 + 52.0, 40.0 + 30.0)]


def _histogram(states: np.ndarray) -> np.ndarray:
    return hough_spectrum(cell_points(states == OCCUPIED))


def _off(a: float, b: float, period: float = math.pi) -> float:
    """|a - b| modulo ``period``, in degrees."""
    return abs(math.degrees(math.remainder(a - b, period)))


@pytest.mark.parametrize("turn_deg", [0.0, 17.0, 90.0, 133.0, 200.0, 301.5])
def test_the_first_peak_is_the_rotation_both_ways_round(turn_deg):
    turn = math.radians(turn_deg)
    reference = _histogram(_walls(_FLOOR, turn))
    moving = _histogram(_walls(_FLOOR))
    first, flipped = rotation_candidates(moving, reference, 1)
    assert _off(first, turn) <= 1.0
    assert math.isclose(flipped - first, math.pi)


def test_walls_of_another_rotation_move_no_peak():
    """Half as many wall cells at another rotation (the border of another part) add their
    own direction; the part's rotation stays among the first two peaks."""
    turn = math.radians(40.0)
    reference = _histogram(_walls(_FLOOR, turn))
    part = _walls(_FLOOR)
    other = _walls([(-30.0, -60.0, 45.0, -60.0)], math.radians(-25.0))
    mixed = np.where((part == OCCUPIED) | (other == OCCUPIED), OCCUPIED, FREE).astype(np.int8)
    candidates = rotation_candidates(_histogram(mixed), reference, 2)
    assert len(candidates) == 4
    assert min(_off(a, turn) for a in candidates) <= 1.0


def test_the_spectrum_peaks_at_the_long_wall_s_normal():
    h = _histogram(_walls(_FLOOR))
    assert h.shape == (BINS,)
    assert math.isclose(h.sum(), 1.0)
    # the long wall runs along x: its lines' normal is at 90 degrees
    assert abs(int(np.argmax(h)) - 90) <= 1
    # the spectrum does not depend on where the cells are
    shifted = cell_points(_walls(_FLOOR) == OCCUPIED) + [37.0, -12.0]
    assert np.allclose(hough_spectrum(shifted), h)


def test_no_cells_no_directions_no_rotation():
    assert not hough_spectrum(np.zeros((0, 2))).any()
    assert rotation_candidates(np.zeros(BINS), _histogram(_walls(_FLOOR)), 3) == []
    assert rotation_candidates(_histogram(_walls(_FLOOR)), _histogram(_walls(_FLOOR)), 0) == []


def test_a_sample_of_many_cells_keeps_the_peaks():
    """A third of the cells, an even stride of them (as a spectrum takes of more than
    :data:`~brokenness.registration.orientation.SAMPLE_CELLS`), give the same rotation."""
    turn = math.radians(23.0)
    reference_cells = cell_points(_walls(_FLOOR, turn) == OCCUPIED)
    moving = _histogram(_walls(_FLOOR))
    whole = rotation_candidates(moving, hough_spectrum(reference_cells), 1)[0]
    assert reference_cells.shape[0] > 100
    sampled = hough_spectrum(reference_cells[::3])
    assert _off(rotation_candidates(moving, sampled, 1)[0], whole) <= 1.0


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 2.0 * math.pi))
def test_any_rotation_is_found_modulo_a_half_turn(turn):
    reference = _histogram(_walls(_FLOOR, turn))
    first = rotation_candidates(_histogram(_walls(_FLOOR)), reference, 1)[0]
    assert _off(first, turn) <= 1.0


@pytest.mark.parametrize("n", [1, 2047, 2048, 2049, 9000, 16_384])
def test_the_spectrum_counts_every_line_as_one_count_over_all_cells_would(n: int) -> None:
    # the lines are counted a block of cells at a time (bounded temporaries); the
    # spectrum is the one of a single count over all the cells, bit for bit
    from brokenness.registration import orientation

    rng = np.random.default_rng(n)
    cells = np.round(rng.normal(size=(n, 2)) * 120.0) + [300.0, -40.0]
    sample = cells - cells.mean(axis=0)
    reach = float(np.sqrt((sample * sample).sum(axis=1).max()))
    lines = 2 * math.ceil(reach) + 2
    theta = np.arange(BINS) * (math.pi / BINS)
    normals = np.vstack([np.cos(theta), np.sin(theta)])
    expected = np.zeros(BINS)
    for start in range(0, BINS, orientation._CHUNK):
        chunk = normals[:, start : start + orientation._CHUNK]
        rho = sample @ chunk
        rho += reach + 0.5
        line = rho.astype(np.intp) + np.arange(chunk.shape[1]) * lines
        per_line = np.bincount(line.ravel(), minlength=chunk.shape[1] * lines).astype(float)
        per_line = per_line.reshape(chunk.shape[1], lines)
        expected[start : start + chunk.shape[1]] = np.einsum("ij,ij->i", per_line, per_line)
    expected /= expected.sum()
    assert hough_spectrum(cells).tobytes() == expected.tobytes()
