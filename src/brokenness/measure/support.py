"""Support: how much of a cell's neighbourhood agrees with the reference under a transform.

A part of a broken map is a contiguous stretch of the robot's run, so around a cell that
truly belongs to a partition most occupied cells agree with the reference under that
partition's transform too, while a cell that a transform puts on a reference wall by
coincidence lies among cells that do not. The *support* of a cell under a transform is the
share of the occupied cells in the ``(2 r + 1)``-cell square around it (``r =``
:data:`SUPPORT_RADIUS`) that agree under it; at least :data:`SUPPORT_SHARE` is *coherent*.

The recovery (:mod:`~brokenness.measure.recovery`) finds suspects and lost partitions with
it, and the free-space evidence (:mod:`~brokenness.measure.evidence`) gives a wall that
several partitions explain to the one that explains its neighbourhood. This module counts
cells in square windows (:func:`window_counts`: integral images over the box of the
windows, in bands of rows, so that the temporaries stay bounded).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "SUPPORT_RADIUS",
    "SUPPORT_SHARE",
    "box_counts",
    "in_box",
    "occupied_around",
    "window_box",
    "window_counts",
]

#: Half-width (cells) of the square window in which a cell's support is counted
#: (0.6 m at 5 cm cells).
SUPPORT_RADIUS = 12
#: A cell whose partition's transform makes fewer than this share of the occupied cells
#: around it agree is a suspect; a hypothesis explains a cell coherently when it makes at
#: least this share agree.
SUPPORT_SHARE = 0.4


def occupied_around(
    points: NDArray[np.float64], shape: tuple[int, int], radius: int = SUPPORT_RADIUS
) -> NDArray[np.float64]:
    """Per occupied cell, the occupied cells in the square window around it (a quantity of
    the map alone, computed once a call: :attr:`~brokenness.measure.context.MapContext.around`)."""
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    everything = np.ones(points.shape[0], dtype=bool)
    return window_counts(rows, cols, everything, everything, shape, radius)


def window_counts(
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    which: NDArray[np.bool_],
    at: NDArray[np.bool_],
    shape: tuple[int, int],
    radius: int,
) -> NDArray[np.float64]:
    """At the cells ``at``, how many ``which`` cells lie in the square window around them.

    Only the box around ``at`` is counted (one integral image a band of rows)."""
    ar, ac = rows[at], cols[at]
    box = window_box(ar, ac, shape, radius)
    inside = which & in_box(rows, cols, box)
    return box_counts(rows[inside], cols[inside], ar, ac, box, radius)


def box_counts(
    wr: NDArray[np.intp],
    wc: NDArray[np.intp],
    ar: NDArray[np.intp],
    ac: NDArray[np.intp],
    box: tuple[int, int, int, int],
    radius: int,
) -> NDArray[np.float64]:
    """:func:`window_counts` of the cells ``(wr, wc)``, all inside ``box`` (that of the
    windows around the cells ``(ar, ac)``), at the cells ``(ar, ac)``."""
    r0, r1, c0, c1 = box
    width = c1 - c0 + 2 * radius  # the box's columns and the margins its windows reach
    # in bands of rows (each with the rows its windows reach): bounded temporaries
    band = max(2 * radius + 1, -(-_BAND_CELLS // width))
    if r1 - r0 <= band:  # the usual case: one band holds the box
        return _band_counts(wr, wc, ar, ac, (r0, r1 - r0), (c0, width), radius)
    out = np.zeros(ar.shape[0], dtype=np.float64)
    for b0 in range(r0, r1, band):
        b1 = min(b0 + band, r1)
        here = (ar >= b0) & (ar < b1)
        if not here.any():
            continue
        near = (wr >= b0 - radius) & (wr < b1 + radius)
        out[here] = _band_counts(
            wr[near], wc[near], ar[here], ac[here], (b0, b1 - b0), (c0, width), radius
        )
    return out


def _band_counts(
    wr: NDArray[np.intp],
    wc: NDArray[np.intp],
    ar: NDArray[np.intp],
    ac: NDArray[np.intp],
    band: tuple[int, int],
    columns: tuple[int, int],
    radius: int,
) -> NDArray[np.float64]:
    """At the cells ``(ar, ac)`` of the rows ``band = (b0, rows)``, how many of the cells
    ``(wr, wc)`` lie in the square window around them, from one integral image.

    The grid holds the band's rows and the ``radius`` rows above and below it, and the
    ``columns = (c0, width)`` from ``c0 - radius`` on (every window inside it, the cells off
    the map zero as in a box filter with a constant border); each window's count is four
    lookups of the integral image (whole numbers: exactly what a box filter counts).
    """
    b0, rows = band
    c0, width = columns
    side = 2 * radius + 1
    grid = np.zeros((rows + 2 * radius, width), np.uint8)
    # marked by flat index (a fresh C-contiguous grid: its flat view), a third of the cost
    # of indexing it by rows and columns
    grid.reshape(-1)[(wr - (b0 - radius)) * width + (wc - (c0 - radius))] = 1
    sums = np.asarray(cv2.integral(grid, sdepth=cv2.CV_32S)).reshape(-1)
    step = width + 1  # the integral image has a leading row and column of zeros
    corner = (ar - b0) * step + (ac - c0)  # each window's first row and column in the grid
    far = side * step
    counts = (
        sums.take(corner + (far + side)) - sums.take(corner + far) - sums.take(corner + side)
    ) + sums.take(corner)
    return counts.astype(np.float64)


#: Cells of a band of rows of :func:`window_counts` (about 2 million: its integral image,
#: four bytes a cell, takes what the box filter's two-byte counts of twice as many took).
_BAND_CELLS = 1 << 21


def window_box(
    rows: NDArray[np.intp], cols: NDArray[np.intp], shape: tuple[int, int], radius: int
) -> tuple[int, int, int, int]:
    """Rows ``[r0, r1)`` and columns ``[c0, c1)`` of the windows around the cells
    ``(rows, cols)``."""
    r0, r1 = max(int(rows.min()) - radius, 0), min(int(rows.max()) + radius + 1, shape[0])
    c0, c1 = max(int(cols.min()) - radius, 0), min(int(cols.max()) + radius + 1, shape[1])
    return r0, r1, c0, c1


def in_box(
    rows: NDArray[np.intp], cols: NDArray[np.intp], box: tuple[int, int, int, int]
) -> NDArray[np.bool_]:
    r0, r1, c0, c1 = box
    return (rows >= r0) & (rows < r1) & (cols >= c0) & (cols < c1)
