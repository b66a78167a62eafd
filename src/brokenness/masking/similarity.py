"""Birk's picture-distance function Psi between two maps."""

from __future__ import annotations

from collections.abc import Iterator

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import MapError
from ..grid import FREE, OCCUPIED, OccupancyMap, count_state

__all__ = ["picture_distance"]

#: Rows of the grid a band of the sums covers (no temporary of the grid's size).
_BAND_ROWS = 512
#: Largest exact distance of one saturated one-byte Manhattan pass (255 means "farther").
_LEVEL = 254


def _count(states: NDArray[np.int8], kind: int) -> int:
    """Cells of ``states`` equal to ``kind``, counted in bands of rows."""
    return count_state(states, kind)


def _level_pass(seeds_not: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Manhattan distance to the zero cells of ``seeds_not``, saturated at 255 (one byte a
    cell: OpenCV's L1 transform writes bytes directly, with no wider temporary)."""
    return np.asarray(
        cv2.distanceTransform(seeds_not, cv2.DIST_L1, 3, dstType=cv2.CV_8U), dtype=np.uint8
    )


def _distance_sum(
    of_states: NDArray[np.int8], of_kind: int, to_states: NDArray[np.int8], to_kind: int
) -> int:
    """Sum over the ``of_kind`` cells of ``of_states`` of the exact Manhattan distance to the
    nearest ``to_kind`` cell of ``to_states`` (there must be one).

    By saturated one-byte passes: the first gives every distance under 255. A cell at 255
    or more is exactly 254 farther than the nearest cell at exactly 254 (its shortest lattice
    path to the nearest ``to_kind`` cell crosses that level, and no cell of the level is
    nearer the target than 254), so the next pass, seeded with the cells at 254, gives the
    distances under 254 + 255, and so on until every ``of_kind`` cell has its distance. Maps
    of one place need one pass; a pass holds two bytes a cell, and a mask of the cells still
    without a distance is kept only when there are some.
    """
    rows, bands = of_states.shape[0], range(0, of_states.shape[0], _BAND_ROWS)
    level = _level_pass(np.not_equal(to_states, to_kind).view(np.uint8))
    total, offset = 0, 0
    pending: NDArray[np.bool_] | None = None  # the of_kind cells still without a distance
    while True:
        left = 0
        for r in bands:
            band = slice(r, min(r + _BAND_ROWS, rows))
            cells = of_states[band] == of_kind if pending is None else pending[band]
            values = level[band][cells]
            near = values < 255
            n_near = int(np.count_nonzero(near))
            total += int(values[near].sum(dtype=np.int64)) + offset * n_near
            left += values.size - n_near
        if not left:
            return total
        if pending is None:
            pending = np.empty(of_states.shape, dtype=bool)
            for r in bands:
                band = slice(r, min(r + _BAND_ROWS, rows))
                np.logical_and(of_states[band] == of_kind, level[band] == 255, out=pending[band])
        else:
            for r in bands:
                band = slice(r, min(r + _BAND_ROWS, rows))
                pending[band] &= level[band] == 255
        offset += _LEVEL
        np.not_equal(level, _LEVEL, out=level.view(np.bool_))  # zero at the seeds: the 254s
        level = _level_pass(level)


#: A box of cells ``(r0, r1, c0, c1)``: rows ``r0 .. r1 - 1``, columns ``c0 .. c1 - 1``.
_Box = tuple[int, int, int, int]


def _union(a: _Box | None, b: _Box | None) -> _Box | None:
    """The smallest box holding both boxes (``None`` is the empty box)."""
    if a is None or b is None:
        return a if b is None else b
    return (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3]))


def _mask_box(masks: Iterator[tuple[int, NDArray[np.bool_]]]) -> _Box | None:
    """Bounding box of the True cells of a mask given band by band as ``(first row, band)``,
    or ``None`` when there is none."""
    box: _Box | None = None
    for r, band in masks:
        x, y, w, h = cv2.boundingRect(np.ascontiguousarray(band).view(np.uint8))
        if w:
            box = _union(box, (r + y, r + y + h, x, x + w))
    return box


def _row_bands(rows: int) -> range:
    return range(0, rows, _BAND_ROWS)


def _differ_box(a: NDArray[np.int8], b: NDArray[np.int8]) -> _Box | None:
    """Bounding box of the cells whose states differ in ``a`` and ``b`` (``None``: none)."""
    return _mask_box(
        (r, a[r : r + _BAND_ROWS] != b[r : r + _BAND_ROWS]) for r in _row_bands(a.shape[0])
    )


def _kind_box(states: NDArray[np.int8], kind: int) -> _Box | None:
    """Bounding box of the ``kind`` cells of ``states`` (``None`` when there is none)."""
    return _mask_box((r, states[r : r + _BAND_ROWS] == kind) for r in _row_bands(states.shape[0]))


def _off_box(
    of_states: NDArray[np.int8], to_states: NDArray[np.int8], kind: int, differ: _Box
) -> _Box | None:
    """Bounding box of the cells of ``kind`` in ``of_states`` and not in ``to_states``: all
    within ``differ``, the box of the cells where the two maps differ."""
    r0, r1, c0, c1 = differ
    of, to = of_states[r0:r1, c0:c1], to_states[r0:r1, c0:c1]
    box = _mask_box(
        (r, (of[r : r + _BAND_ROWS] == kind) & (to[r : r + _BAND_ROWS] != kind))
        for r in _row_bands(r1 - r0)
    )
    return None if box is None else (box[0] + r0, box[1] + r0, box[2] + c0, box[3] + c0)


def _needed_box(
    of_states: NDArray[np.int8], to_states: NDArray[np.int8], kind: int, differ: _Box | None
) -> _Box | None:
    """The part of the grid that the distances from the ``kind`` cells of ``of_states`` to the
    nearest ``kind`` cell of ``to_states`` need, or ``None`` when every one of them is 0.

    Only the cells of ``kind`` in ``of_states`` and not in ``to_states`` are at a distance
    other than 0 (and they lie where the maps differ, in ``differ``). The box of those and
    of all the ``kind`` cells of ``to_states`` holds every ``kind`` cell of ``of_states``
    (each is one or the other) and every target, so every nearest target is inside it; and
    a shortest Manhattan lattice path between two cells of a box stays in the box (it can go
    monotonically). The distances computed in the box are therefore those of the whole
    grid, cell for cell.
    """
    if differ is None:
        return None
    off = _off_box(of_states, to_states, kind, differ)
    if off is None:
        return None
    return _union(off, _kind_box(to_states, kind))


def _mean_distance(
    of_states: NDArray[np.int8],
    to_states: NDArray[np.int8],
    kind: int,
    cap: float,
    counts: tuple[int, int],
    differ: _Box | None,
) -> float:
    """Mean Manhattan distance from each ``kind`` cell of ``of_states`` to the nearest
    ``kind`` cell of ``to_states`` (``cap`` a cell when ``to_states`` has none).

    ``counts`` are the numbers of ``kind`` cells of the two, ``differ`` the box of the cells
    where they differ. Distances are whole numbers, so their sum is exact in integers (and
    equal to the float64 sum of the float32 distances, which is exact below 2**53). The
    distance maps cover only :func:`_needed_box` (none at all when the two maps have the
    same ``kind`` cells), which gives the same distances as the whole grid."""
    count, targets = counts
    if count == 0:
        return 0.0
    if targets == 0:
        return float(np.float64(cap) * count) / count
    box = _needed_box(of_states, to_states, kind, differ)
    if box is None:
        return 0.0
    r0, r1, c0, c1 = box
    of_box, to_box = of_states[r0:r1, c0:c1], to_states[r0:r1, c0:c1]
    return float(_distance_sum(of_box, kind, to_box, kind)) / count


def picture_distance(a: OccupancyMap | ArrayLike, b: OccupancyMap | ArrayLike) -> float:
    r"""Picture distance Psi between two maps of the same shape (Birk & Carpin 2006).

    .. math::

        \Psi(a, b) = \sum_{c \in \{\text{occ}, \text{free}\}} d(a, b, c) + d(b, a, c),
        \qquad d(a, b, c) = \frac{1}{\#_c(a)} \sum_{a[p] = c} \min_{b[p'] = c} |p - p'|_1

    i.e. for each kind of cell, the average Manhattan distance from every cell of that kind
    in one map to the nearest cell of the same kind in the other map, both ways. Unknown cells
    take no part. 0 means identical occupied and free sets; the value grows with noise,
    shifts and rotations. Distance maps make it linear in the number of cells; they are
    one byte a cell (saturated passes, exact), cover only the box of the cells that are
    at a distance other than 0 and of their targets (nothing when both maps have the same
    cells of a kind), and every sum is taken in bands of rows.

    Parameters
    ----------
    a, b : OccupancyMap or array_like
        Two maps on the same grid (same shape); an array is read as
        :meth:`OccupancyMap.from_array` reads it.

    Returns
    -------
    float
        Psi in cells. A kind that is absent from the other map contributes the largest
        possible distance, ``rows + cols``, per cell.

    Raises
    ------
    MapError
        If the shapes differ, or an array is not a map.

    References
    ----------
    .. [1] A. Birk and S. Carpin, "Merging occupancy grid maps from multiple robots",
       Proceedings of the IEEE 94(7), 2006.

    Examples
    --------
    >>> import numpy as np
    >>> from brokenness import OccupancyMap, picture_distance
    >>> walls = np.zeros((20, 20), bool); walls[5, 2:18] = True
    >>> m = OccupancyMap.from_array(walls)
    >>> picture_distance(m, m)
    0.0
    """
    a = a if isinstance(a, OccupancyMap) else OccupancyMap.from_array(a)
    b = b if isinstance(b, OccupancyMap) else OccupancyMap.from_array(b)
    if a.shape != b.shape:
        raise MapError(f"picture distance needs maps of one shape, got {a.shape} and {b.shape}")
    cap = float(sum(a.shape))
    differ = _differ_box(a.states, b.states)
    total = 0.0
    for kind in (OCCUPIED, FREE):
        n_a, n_b = _count(a.states, kind), _count(b.states, kind)
        total += _mean_distance(a.states, b.states, kind, cap, (n_a, n_b), differ) + (
            _mean_distance(b.states, a.states, kind, cap, (n_b, n_a), differ)
        )
    return total
