"""Rotation hypotheses from wall directions: the Hough spectra of cells and of the reference.

The spectral registration (:mod:`~brokenness.registration.ifmi`) finds the rotation of a
moving image from the angular profile of its whole magnitude spectrum. A few cells of a
small part, mixed with borders of other parts (each turned by its own bump), give a
spectrum whose strongest directions are not the part's: on the realistic benchmark's
held-out maps that came out a partition short or with a part at a twin, registering the
region of suspects where the part lay gave no hypothesis within 20 degrees of its rotation,
though its walls point the way the reference's do.

The *Hough spectrum* of Censi, Iocchi and Grisetti [1]_, used by Carpin for map merging
[2]_, counts the walls' directions instead: the Hough transform of the cells (for every
direction ``theta`` of a line's normal, the cells on each line ``x cos theta + y sin theta =
rho``, one cell wide) and, per direction, the sum of the squares of its counts. A straight
wall of ``L`` cells adds about ``L**2`` at its direction and little elsewhere, however it
was drawn on the grid; the spectrum does not depend on where the cells are, and turning
them shifts it. The rotations that turn the moving cells' walls onto the reference's are
the peaks of the two spectra's circular cross-correlation; a wall from another part adds
its own direction, but moves no peak. The peaks are rotations modulo a half turn (a wall
has no front), so each gives two hypotheses, ``theta`` and ``theta + pi``; their
translations are for :mod:`~brokenness.measure.placement` to find.

References
----------
.. [1] A. Censi, L. Iocchi, G. Grisetti, "Scan matching in the Hough domain", ICRA 2005.
.. [2] S. Carpin, "Fast and accurate map merging for multi-robot systems", Autonomous
   Robots 25(3), 2008.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._spectral import circular_peaks, parabolic_offset

__all__ = ["BINS", "SAMPLE_CELLS", "hough_spectrum", "rotation_candidates"]

#: Directions of the spectrum over half a turn (one degree each).
BINS = 180
#: At most this many cells (an even stride of them) make a spectrum (a long wall keeps
#: hundreds of them, and the cost of a spectrum follows them: ``BINS`` lines a cell).
SAMPLE_CELLS = 16_384
#: Directions transformed at once (bounded temporaries: the counts of this many directions
#: over every line of the cells' extent).
_CHUNK = 30
#: Cells whose lines are counted at once (the integer lines of a chunk's directions are
#: made for this many cells at a time, not for all: a bounded temporary beside ``rho``).
_ROWS = 2048
#: Peaks of the correlation closer than this many bins to a higher one are that one.
_PEAK_SEPARATION = 3


def hough_spectrum(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """The Hough spectrum of cells ``(x, y)``: per direction of a line's normal over half a
    turn (:data:`BINS` of them, ``theta = pi b / BINS``), the sum over the lines of that
    direction, one cell apart, of the square of the cells each holds; normalised to sum 1
    (all zeros for no cell).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        The cells (an even stride of at most :data:`SAMPLE_CELLS` of them is counted).

    Returns
    -------
    ndarray of float64, shape (BINS,)
    """
    spectrum = np.zeros(BINS, dtype=np.float64)
    if points.shape[0] == 0:
        return spectrum
    sample = points[:: max(1, -(-points.shape[0] // SAMPLE_CELLS))].astype(np.float64)
    sample = sample - sample.mean(axis=0)  # the spectrum does not depend on where they are
    reach = float(np.sqrt((sample * sample).sum(axis=1).max()))
    lines = 2 * math.ceil(reach) + 2  # rho from -reach to reach, a cell a line
    theta = np.arange(BINS) * (math.pi / BINS)
    normals = np.vstack([np.cos(theta), np.sin(theta)])  # (2, BINS)
    for start in range(0, BINS, _CHUNK):
        chunk = normals[:, start : start + _CHUNK]
        first = np.arange(chunk.shape[1]) * lines  # each direction's first line
        rho = sample @ chunk  # (N, chunk): x cos theta + y sin theta
        rho += reach + 0.5  # at least a half: truncation rounds to the nearest line
        counts = np.zeros(chunk.shape[1] * lines, dtype=np.intp)
        for top in range(0, rho.shape[0], _ROWS):  # lines of a few rows at a time
            line = rho[top : top + _ROWS].astype(np.intp)
            line += first
            counts += np.bincount(line.ravel(), minlength=counts.size)
        del rho  # before the next chunk's
        per_line = counts.astype(np.float64).reshape(chunk.shape[1], lines)
        spectrum[start : start + chunk.shape[1]] = np.einsum("ij,ij->i", per_line, per_line)
    total = spectrum.sum()
    return spectrum / total if total > 0 else spectrum


def rotation_candidates(
    moving: NDArray[np.float64], reference: NDArray[np.float64], count: int
) -> list[float]:
    """The rotations (radians, in ``[0, 2 pi)``) that turn the walls of the moving cells
    onto the reference's best: the ``count`` highest peaks of the circular cross-correlation
    of their Hough spectra, each to a fraction of a degree and as ``theta`` and
    ``theta + pi``, highest peak first.

    Parameters
    ----------
    moving, reference : ndarray, shape (BINS,)
        :func:`hough_spectrum` of the moving cells and of the reference's.
    count : int
        Peaks taken (at most ``2 count`` rotations returned).

    Returns
    -------
    list of float

    Examples
    --------
    A straight wall of 100 cells, and the same wall turned by 30 degrees and drawn on the
    grid again:

    >>> import numpy as np
    >>> wall = np.column_stack([np.arange(100.0), np.zeros(100)])
    >>> c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    >>> turned = np.rint(wall @ np.array([[c, s], [-s, c]]))
    >>> first, flipped = rotation_candidates(hough_spectrum(wall), hough_spectrum(turned), 1)
    >>> round(float(np.degrees(first))), round(float(np.degrees(flipped)))
    (30, 210)
    """
    if count < 1 or not moving.any() or not reference.any():
        return []
    # score[s]: the moving cells' direction b turned onto the reference's b + s
    score = np.real(np.fft.ifft(np.conj(np.fft.fft(moving)) * np.fft.fft(reference)))
    # maxima of every value within the separation (not on the flank of a higher peak), and
    # farther than it from a higher one
    sep = _PEAK_SEPARATION
    peaks = circular_peaks(score, count, sep + 1, window=sep)
    step = math.pi / BINS
    # each peak to a fraction of a bin (the vertex of the parabola through it and its two
    # neighbours), both ways round (a wall has no front)
    angles = [
        (s + parabolic_offset(score[(s - 1) % BINS], score[s], score[(s + 1) % BINS])) * step
        for s in peaks
    ]
    return [a for t in angles for a in (t % math.pi, t % math.pi + math.pi)]
