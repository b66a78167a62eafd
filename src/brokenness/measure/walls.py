"""How thick a map draws its walls, in whole cells.

A mapper marks a wall across as many cells as its sensor model, its resolution and its
post-processing make it: the project's simulated maps and most SLAM maps at 5 cm draw a
wall one or two cells thick, other mappers (or a map cleaned by a dilation) three or four.
The agreement threshold ``c`` must cover that band, as it covers the band of a coarse map's
upsampled cells (:func:`brokenness.measure.recursion._at_working_resolution`): the wall
the reference draws lies anywhere within it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["LARGEST_THICKNESS", "wall_thickness"]

#: The largest thickness told apart (cells): walls this thick or thicker give this.
LARGEST_THICKNESS = 8


def wall_thickness(points: NDArray[np.float64], largest: int = LARGEST_THICKNESS) -> int:
    """The thickness, in whole cells, at which a map draws most of its walls.

    The largest ``k`` (from 1 to ``largest``) such that at least half of the occupied cells
    lie in a ``k x k`` square of occupied cells: what a morphological opening by a
    ``k x k`` square keeps of the walls. A wall one cell thick keeps nothing at ``k = 2``;
    a wall ``t`` cells thick along the grid keeps all of its cells up to ``k = t``. A
    diagonal wall counts thinner than it is, and speckle noise counts for nothing: an
    estimate that errs on the thin side.

    Computed on the cells alone (sorted keys, no grid of the map's size): the cost follows
    the occupied cells.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        ``(x, y) = (column, row)`` of the distinct occupied cells (whole numbers).
    largest : int
        The largest thickness looked for.

    Returns
    -------
    int
        At least 1 (also for no cell).

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
    cols = points[:, 0].astype(np.int64)
    rows = points[:, 1].astype(np.int64)
    cols -= cols.min()
    rows -= rows.min()
    width = int(cols.max()) + largest + 1  # a margin: no square wraps into the next row
    keys = np.sort(rows * width + cols)
    thickness = 1
    for k in range(2, largest + 1):
        offsets = [dr * width + dc for dr in range(k) for dc in range(k)]
        # the full squares, by their top-left cell
        full = np.ones(n, dtype=bool)
        for step in offsets[1:]:
            full &= _present(keys, keys + step)
        corners = keys[full]
        if 2 * corners.size * k * k < n:
            break  # the squares cannot hold half of the cells
        kept = np.zeros(n, dtype=bool)
        for step in offsets:
            kept |= _present(corners, keys - step)
        if 2 * int(np.count_nonzero(kept)) < n:
            break
        thickness = k
    return thickness


def _present(keys: NDArray[np.int64], probe: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Whether each of ``probe`` is among the sorted ``keys``."""
    at = np.searchsorted(keys, probe)
    at[at == keys.size] = 0
    return np.asarray(keys[at] == probe)
