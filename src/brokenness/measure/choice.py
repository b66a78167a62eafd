"""Which hypothesis a step of the recursion keeps.

A step has hypotheses registered with the whole reference R and, at times, with R' (the
reference less the walls earlier partitions matched); the best of each pool is
:func:`~brokenness.measure.hypotheses.best_hypothesis`'s, :func:`mostly_claimed` tells
whether the best of R lies mostly on walls earlier partitions matched (then R' is asked
too), and :func:`prefer_unexplained` decides between the best of R and of R'. The reasons
are in the docstring of :mod:`brokenness.measure.recursion` ("Two references").
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..transform import RigidTransform

__all__ = ["mostly_claimed", "prefer_unexplained"]


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
    moved = transform.apply(points[agree]).astype(np.float32)
    cols = np.rint(moved[:, 0]).astype(np.intp) - offset[0]
    rows = np.rint(moved[:, 1]).astype(np.intp) - offset[1]
    h, w = near_claimed.shape
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    on_claimed = near_claimed[rows[inside], cols[inside]]
    return bool(np.count_nonzero(on_claimed) * 2 >= np.count_nonzero(agree))
