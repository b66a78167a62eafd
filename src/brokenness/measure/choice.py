"""Which hypothesis a step of the recursion keeps.

A step has hypotheses registered with the whole reference R and, at times, with R' (the
reference less the walls earlier partitions matched); the best of each pool is
:func:`~brokenness.measure.hypotheses.best_hypothesis`'s, :func:`mostly_claimed` tells
whether the best of R lies mostly on walls earlier partitions matched (then R' is asked
too), and :func:`prefer_unexplained` decides between the best of R and of R'. The reasons
are in the docstring of :mod:`brokenness.measure.recursion` ("Two references").
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from .._points import cells_at, take_rows
from ..masking import within_manhattan
from ..masking.agreement import ball_offsets
from ..transform import RigidTransform

__all__ = ["mostly_claimed", "mostly_on_claimed", "prefer_unexplained"]

#: Manhattan balls of up to this many cells are looked up cell by cell around the moved
#: cells (radius 4: 41 cells); a larger one dilates the matched walls' box instead.
_LOOKUP_BALL = 41
#: Rows of a band of the grid-wide scan of the matched walls' box.
_BAND_ROWS = 512


def prefer_unexplained(
    best: tuple[RigidTransform, NDArray[np.bool_]],
    best_rest: tuple[RigidTransform, NDArray[np.bool_]] | None,
    margin: float,
) -> tuple[RigidTransform, NDArray[np.bool_]]:
    """The hypothesis a step keeps: the best of all, or the best registered with R'.

    Parameters
    ----------
    best : (RigidTransform, ndarray of bool)
        The best hypothesis among those registered with the whole reference R and with R'
        (the reference less the walls earlier partitions matched), with the cells of the
        remainder that agree under it.
    best_rest : (RigidTransform, ndarray of bool) or None
        The best among those registered with R' only.
    margin : float
        Agreeing cells that chance alone could account for (``z sigma`` of the stopping rule).

    Returns
    -------
    (RigidTransform, ndarray of bool)
        ``best_rest`` if it explains at least as many cells as ``best`` less ``margin`` (the
        two explain the remainder equally well, and ``best_rest`` puts it where no partition
        is yet), else ``best``.
    """
    if best_rest is None:
        return best
    if np.count_nonzero(best_rest[1]) >= np.count_nonzero(best[1]) - margin:
        return best_rest
    return best


def mostly_claimed(
    best: tuple[RigidTransform, NDArray[np.bool_]],
    points: NDArray[np.float64],
    near_claimed: NDArray[np.bool_],
    threshold: float,
    offset: tuple[int, int] = (0, 0),
) -> bool:
    """Whether most agreeing cells of ``best`` land on walls earlier partitions matched.

    ``near_claimed`` marks the reference cells within ``threshold`` of such walls
    (:func:`~brokenness.masking.within_manhattan`), or those of a box of the reference
    whose first cell is ``offset`` ``(col0, row0)`` (no such cell lies outside it); the
    moved cells are rounded to the nearest cell (in single precision, half to even, as
    :func:`~brokenness.masking.sample_at` rounds), cells off it are not on them.
    """
    transform, agree = best
    if not agree.any():
        return False
    moved = transform.apply(take_rows(points, agree)).astype(np.float32)
    cols = np.rint(moved[:, 0]).astype(np.intp) - offset[0]
    rows = np.rint(moved[:, 1]).astype(np.intp) - offset[1]
    h, w = near_claimed.shape
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    on_claimed = cells_at(near_claimed, rows[inside], cols[inside])
    return bool(np.count_nonzero(on_claimed) * 2 >= np.count_nonzero(agree))


def mostly_on_claimed(
    best: tuple[RigidTransform, NDArray[np.bool_]],
    points: NDArray[np.float64],
    occupied: NDArray[np.bool_],
    available: NDArray[np.bool_],
    threshold: float,
) -> bool:
    """:func:`mostly_claimed` with the walls earlier partitions matched given as the
    reference's ``occupied`` cells no longer ``available``.

    For a small ``threshold`` the Manhattan ball around each moved cell is looked up in
    the two masks (the cost follows the agreeing cells); a larger one dilates the box of the
    matched walls (:func:`near_claimed`). The same answer either way.

    Parameters
    ----------
    best : (RigidTransform, ndarray of bool)
        A transform and which of ``points`` agree under it.
    points : ndarray, shape (N, 2)
        Map cells ``(x, y)``.
    occupied, available : ndarray of bool
        The reference's occupied cells, and those still available (not matched).
    threshold : float
        Manhattan radius (cells) around the matched walls.

    Returns
    -------
    bool
    """
    transform, agree = best
    if not agree.any():
        return False
    radius = int(math.floor(threshold))
    if 2 * radius * (radius + 1) + 1 > _LOOKUP_BALL:
        claimed, offset = near_claimed(occupied, available, threshold)
        return mostly_claimed(best, points, claimed, threshold, offset)
    moved = transform.apply(take_rows(points, agree)).astype(np.float32)
    cols = np.rint(moved[:, 0]).astype(np.intp)
    rows = np.rint(moved[:, 1]).astype(np.intp)
    h, w = occupied.shape
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    rows, cols = rows[inside], cols[inside]
    on = np.zeros(rows.shape[0], dtype=bool)
    for dr, dc in ball_offsets(radius):
        r, c = rows + dr, cols + dc
        k = np.flatnonzero((r >= 0) & (r < h) & (c >= 0) & (c < w) & ~on)
        rk, ck = r[k], c[k]
        on[k] = cells_at(occupied, rk, ck) & ~cells_at(available, rk, ck)
    return bool(np.count_nonzero(on) * 2 >= np.count_nonzero(agree))


def near_claimed(
    occupied: NDArray[np.bool_], available: NDArray[np.bool_], threshold: float
) -> tuple[NDArray[np.bool_], tuple[int, int]]:
    """The reference cells within ``threshold`` of walls earlier partitions matched.

    Parameters
    ----------
    occupied, available : ndarray of bool
        The reference's occupied cells, and those still available (not matched).
    threshold : float
        Manhattan radius (cells).

    Returns
    -------
    (ndarray of bool, (int, int))
        The cells within ``threshold`` of an occupied cell no longer available, as a box of
        the grid, and the box's first cell ``(col0, row0)`` (no such cell lies outside it);
        an empty box at ``(0, 0)`` when no wall was matched.
    """
    box = _claimed_box(occupied, available)
    if box is None:
        return np.zeros((0, 0), dtype=bool), (0, 0)
    radius = max(int(math.floor(threshold)), 0)
    h, w = occupied.shape
    r0, r1 = max(box[0] - radius, 0), min(box[1] + radius, h)
    c0, c1 = max(box[2] - radius, 0), min(box[3] + radius, w)
    claimed = occupied[r0:r1, c0:c1] & ~available[r0:r1, c0:c1]
    return within_manhattan(claimed, threshold), (c0, r0)


def _claimed_box(
    occupied: NDArray[np.bool_], available: NDArray[np.bool_]
) -> tuple[int, int, int, int] | None:
    """``(row0, row1, col0, col1)`` of ``occupied & ~available``, scanned in bands of rows
    (no temporary of the grid's size); None if there is no such cell."""
    rows = np.zeros(occupied.shape[0], dtype=bool)
    cols = np.zeros(occupied.shape[1], dtype=bool)
    for a in range(0, occupied.shape[0], _BAND_ROWS):
        band = occupied[a : a + _BAND_ROWS] & ~available[a : a + _BAND_ROWS]
        rows[a : a + _BAND_ROWS] = band.any(axis=1)
        cols |= band.any(axis=0)
    r, c = np.flatnonzero(rows), np.flatnonzero(cols)
    if r.size == 0:
        return None
    return int(r[0]), int(r[-1]) + 1, int(c[0]), int(c[-1]) + 1
