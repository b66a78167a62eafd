"""How thick a map draws its walls, in whole cells.

A mapper marks a wall across as many cells as its sensor model, its resolution and its
post-processing make it: the project's simulated maps and most SLAM maps at 5 cm draw a
wall one or two cells thick, other mappers (or a map cleaned by a dilation) three or four.
A wall is drawn about where it is, so the agreement threshold ``c`` must cover how far
the map's band reaches beyond the band in which the reference draws the same wall, as it
covers a coarse map's upsampled cells
(:func:`brokenness.measure.recursion._at_working_resolution`).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from .._points import sorted_lookup

__all__ = ["LARGEST_THICKNESS", "wall_thickness"]

#: The thickest walls told apart (cells): a map whose occupied cells lie mostly in squares
#: this wide draws solids (objects drawn filled, the outside of a building drawn occupied)
#: or walls too thick to tell a band about them (0.4 m at 5 cm, 0.8 m at 10 cm).
LARGEST_THICKNESS = 8

#: Cells of the box per occupied cell up to which the grid of the box is drawn at once
#: (it costs less than looking the cells up among themselves; as
#: :func:`~brokenness.measure.partitions.cell_components`).
_DENSE_BOX = 64
#: Cells of the box looked at, at most (bands of rows spread evenly over a larger box): a
#: share of the cells, not a count, is asked of them.
_MAX_BOX = 4_000_000
#: ... but in this many bands at least.
_MIN_BANDS = 16
#: Rows of the bands in which the occupied cells are drawn on a grid (bounded temporaries).
_BAND_ROWS = 128


def wall_thickness(points: NDArray[np.float64], largest: int = LARGEST_THICKNESS) -> int:
    """The thickness, in whole cells, at which a map draws most of its walls.

    The largest ``k`` (from 1 to ``largest``) such that at least half of the occupied cells
    lie in a ``k x k`` square of occupied cells: what a morphological opening by a
    ``k x k`` square keeps of the walls. A wall one cell thick keeps nothing at ``k = 2``;
    a wall ``t`` cells thick along the grid keeps all of its cells up to ``k = t``. A
    diagonal wall counts thinner than it is, and speckle noise counts for nothing: an
    estimate that errs on the thin side. ``largest`` means walls at least that thick, or
    solids (:data:`LARGEST_THICKNESS`).

    In a box mostly empty, the 2 x 2 squares are found on the cells alone (sorted keys), and
    a map of thin walls, where fewer than half of the cells lie in one, stops there, at a
    cost that follows its occupied cells. Otherwise the openings are made on the grid of the
    cells' box, in bands of rows (bounded temporaries; in a large box, bands spread evenly
    over it).

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        ``(x, y) = (column, row)`` of the distinct occupied cells (whole numbers).
    largest : int
        The largest thickness told apart (at least 2).

    Returns
    -------
    int
        From 1 (also for no cell) to ``largest``.

    Examples
    --------
    >>> import numpy as np
    >>> rows, cols = np.mgrid[10:13, 0:50]  # a wall 3 cells thick, 50 long
    >>> wall_thickness(np.column_stack([cols.ravel(), rows.ravel()]).astype(float))
    3
    """
    n = points.shape[0]
    if n == 0:
        return 1
    # whole cells (a side of a map within the cell limit fits int32), from 0
    cols = points[:, 0].astype(np.int32)
    rows = points[:, 1].astype(np.int32)
    cols -= cols.min()
    rows -= rows.min()
    box = (int(rows.max()) + 1) * (int(cols.max()) + 1)
    if box > _DENSE_BOX * n and 2 * _in_squares_of_two(rows, cols) < n:
        return 1  # fewer than half of the cells in a 2 x 2 square: walls of one cell
    held = _held(rows, cols, largest)  # held[k - 1]: the cells in full k x k squares
    thickness = 1
    for k in range(2, largest + 1):
        if 2 * held[k - 1] < held[0]:
            break
        thickness = k
    return thickness


def _in_squares_of_two(rows: NDArray[np.int32], cols: NDArray[np.int32]) -> int:
    """How many of the cells lie in a full 2 x 2 square of them (on the cells alone)."""
    width = int(cols.max()) + 2  # a margin: no square wraps into the next row
    keys = np.sort(rows.astype(np.int64) * width + cols)
    corners = keys
    for step in (1, width, width + 1):
        corners = corners[sorted_lookup(keys, corners + step)[1]]
    if corners.size == 0:
        return 0
    held = np.zeros(keys.size, dtype=bool)
    for step in (0, 1, width, width + 1):
        held |= sorted_lookup(corners, keys - step)[1]
    return int(np.count_nonzero(held))


def _held(rows: NDArray[np.int32], cols: NDArray[np.int32], largest: int) -> list[int]:
    """For each ``k`` from 1 to ``largest``, how many cells lie in a full ``k x k`` square:
    the cells an opening by that square keeps (an erosion that marks each full square by
    its top-left cell, then a dilation back over the square), counted band by band; in a
    box of more than :data:`_MAX_BOX` cells, in as many bands as fit in that (at least
    :data:`_MIN_BANDS`), spread evenly (``[0]``: the cells of those bands)."""
    halo = largest - 1  # the rows an opening of a band's rows reads beyond them
    width = int(cols.max()) + 1 + 2 * halo
    if rows.size > 1 and bool(np.any(rows[1:] < rows[:-1])):  # not row by row already
        order = np.argsort(rows, kind="stable")
        rows, cols = rows[order], cols[order]
    counts = [0] * largest
    height = int(rows[-1]) + 1
    tops = np.arange(0, height, _BAND_ROWS)
    most = max(_MIN_BANDS, _MAX_BOX // (_BAND_ROWS * width))
    if tops.size > most:  # a large box: bands spread evenly over it
        tops = tops[np.unique(np.linspace(0, tops.size - 1, most).round().astype(np.intp))]
    for top in tops.tolist():
        bottom = min(top + _BAND_ROWS, height)
        lo, hi = np.searchsorted(rows, [top - halo, bottom + halo])
        band = np.zeros((bottom - top + 2 * halo, width), dtype=np.uint8)
        band[rows[lo:hi] - top + halo, cols[lo:hi] + halo] = 1
        core = band[halo : halo + bottom - top]
        counts[0] += int(np.count_nonzero(core))
        for k in range(2, largest + 1):
            square = np.ones((k, k), dtype=np.uint8)
            corners = cv2.erode(
                band, square, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT, borderValue=0
            )
            held = cv2.dilate(
                corners,
                square,
                anchor=(k - 1, k - 1),
                borderType=cv2.BORDER_CONSTANT,
                borderValue=0,
            )
            kept = int(np.count_nonzero(held[halo : halo + bottom - top]))
            if kept == 0:
                break  # a full larger square holds only cells that a smaller one holds
            counts[k - 1] += kept
    return counts
