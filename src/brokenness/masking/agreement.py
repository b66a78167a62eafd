"""Local agreement with the reference (Birk's Psi_2) and masking of matched cells.

A cell of the map, moved by a transform onto the reference, *agrees* when the Manhattan
distance from where it lands to the nearest reference cell of the same kind is at most
``threshold`` cells. The reference's distance maps are computed once and reused by every
step of the recursion (:class:`ReferenceIndex`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .._points import squared_norms
from ..errors import MapError
from ..grid import FREE, UNKNOWN, OccupancyMap
from .distance import (
    DistanceMap,
    beyond,
    compact_distance_map,
    lookup_distance,
    manhattan_distance_map,
    sample_at,
    within,
)

__all__ = [
    "ReferenceIndex",
    "ball_offsets",
    "cell_points",
    "free_distance_histogram",
    "manhattan_ball",
    "unmatched_reference",
    "within_manhattan",
]

#: References of up to this many cells use a nearest-cell lookup table, larger ones a KD-tree.
_LOOKUP_TABLE_CELLS = 4_000_000
#: References of more than this many cells (about 5657², whose float32 map is 128 MB) keep
#: their Manhattan distance map in two bytes a cell
#: (:func:`~brokenness.masking.distance.compact_distance_map`: the same samples, bit for bit,
#: but its bilinear ones cost about five times a float32 lookup, 20 % of the call at 3500²
#: and 1-5 % at 8000² and 10000²), smaller ones in float32.
COMPACT_CELLS = 32_000_000
#: Rows of a band of the grid-wide counts and masks (no temporary of the grid's size).
_BAND_ROWS = 512
#: Distances below this are told apart by :func:`free_distance_histogram` (its last bin holds
#: every distance from it on).
_HISTOGRAM_TOP = 255
#: Manhattan balls of up to this many cells are cleared cell by cell (radius 3: 25 cells).
_SCATTER_BALL = 25


def cell_points(mask: ArrayLike) -> NDArray[np.float64]:
    """``(x, y) = (column, row)`` coordinates of the ``True`` cells, shape (N, 2), row-major."""
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2 or m.size == 0:
        rows, cols = np.nonzero(m)
        return np.column_stack([cols, rows]).astype(np.float64)
    # OpenCV's scan lists the cells row by row, as numpy's nonzero does, in one fast pass
    found = cv2.findNonZero(np.ascontiguousarray(m).view(np.uint8))
    if found is None:
        return np.zeros((0, 2), dtype=np.float64)
    return found.reshape(-1, 2).astype(np.float64)


@dataclass(frozen=True, eq=False)
class ReferenceIndex:
    """What the recursion needs to know about the reference, computed once.

    Attributes
    ----------
    reference : OccupancyMap
    occupied_distance : ndarray of float32 or uint16
        Manhattan distance map to the nearest occupied reference cell (whole numbers; in
        ``uint16`` for references of more than :data:`COMPACT_CELLS` cells).
    occupied_points : ndarray, shape (N, 2)
        Coordinates of the occupied reference cells.
    """

    reference: OccupancyMap
    occupied_distance: DistanceMap
    occupied_points: NDArray[np.float64]

    @classmethod
    def build(cls, reference: OccupancyMap) -> ReferenceIndex:
        """Index a reference map.

        Raises
        ------
        MapError
            If the reference has no occupied cell.
        """
        occupied = reference.occupied
        if not occupied.any():
            raise MapError("the reference map has no occupied cell")
        points = cell_points(occupied)
        compact = occupied.size > COMPACT_CELLS
        index = cls(
            reference=reference,
            occupied_distance=(
                compact_distance_map(occupied) if compact else manhattan_distance_map(occupied)
            ),
            occupied_points=points,
        )
        index.__dict__["occupied"] = occupied  # the cached property, already at hand
        return index

    @cached_property
    def occupied(self) -> NDArray[np.bool_]:
        """The reference's occupied cells (computed once; do not modify)."""
        return self.reference.occupied

    @property
    def known(self) -> NDArray[np.bool_]:
        """The reference's known (occupied or free) cells (computed on each use: it is needed
        by the chance agreement, once per threshold, and the contradiction test only, and
        holding it would add a byte a cell to the peak of the call)."""
        return self.reference.known

    @cached_property
    def _chance(self) -> dict[float, float]:
        return {}

    @cached_property
    def tree(self) -> cKDTree:
        """Nearest-neighbour index of ``occupied_points`` (Euclidean)."""
        return cKDTree(self.occupied_points)

    @cached_property
    def nearest_occupied(self) -> NDArray[np.float32]:
        """Per cell, the row of ``occupied_points`` nearest to it (Euclidean, exact).

        One linear-time pass (OpenCV's labelled distance transform), so that nearest-point
        queries are array lookups instead of tree searches. Stored as float32 (exact for the
        up to 4 million cells it is built for) so that ``cv2.remap`` can look it up.
        """
        _, labels = cv2.distanceTransformWithLabels(
            np.logical_not(self.occupied).view(np.uint8),
            cv2.DIST_L2,
            cv2.DIST_MASK_PRECISE,
            labelType=cv2.DIST_LABEL_PIXEL,
        )
        # labels number the zero pixels 1..N in row-major order, as cell_points lists them
        return (labels - 1).astype(np.float32)

    def nearest_points(self, points: ArrayLike, max_distance: float) -> NDArray[np.float64]:
        """The occupied reference cell nearest to each point (``inf`` rows beyond reach).

        Small references answer from a per-cell lookup table (:attr:`nearest_occupied`, one
        labelled distance transform); large ones, where that table costs more to build than
        the queries of a whole computation, from a KD-tree (:attr:`tree`).

        Parameters
        ----------
        points : array_like, shape (N, 2)
            Query points ``(x, y)``, rounded to the nearest cell for the lookup table.
        max_distance : float
            Points farther than this from every occupied cell get ``inf`` coordinates.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        nearest, found = self._nearest(p, max_distance)
        nearest[~found] = np.inf
        return nearest

    def correspondences(
        self, points: ArrayLike, max_distance: float
    ) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        """The points within reach of an occupied reference cell, and those cells.

        :meth:`nearest_points` as an ICP step uses it: ``(rows, cells)`` with ``rows`` the
        indices (ascending) of the points whose :meth:`nearest_points` row is finite, and
        ``cells`` those rows, shape ``(len(rows), 2)``.

        Parameters
        ----------
        points : array_like, shape (N, 2)
            Query points ``(x, y)``, as for :meth:`nearest_points`.
        max_distance : float
            As for :meth:`nearest_points`.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        nearest, found = self._nearest(p, max_distance)
        rows = np.flatnonzero(found)
        return rows, nearest.take(rows, axis=0)

    def _nearest(
        self, p: NDArray[np.float64], max_distance: float
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """For each point of ``p`` (shape (N, 2)), an occupied reference cell (its nearest
        one where the second array is ``True``: found within ``max_distance``; any
        finite cell or ``inf`` elsewhere), see :meth:`nearest_points`."""
        if self.reference.states.size > _LOOKUP_TABLE_CELLS:
            out = np.full(p.shape, np.inf)
            dist, idx = self.tree.query(p, k=1, distance_upper_bound=max_distance)
            found = np.isfinite(dist)
            out[found] = self.occupied_points[np.asarray(idx)[found]]
            return out, found
        # nearest-cell lookup in one remap (cells off the grid read -1: no neighbour)
        label = sample_at(self.nearest_occupied, p, -1.0, nearest=True)
        idx = label.astype(np.intp)
        out = self.occupied_points.take(np.maximum(idx, 0), axis=0)
        far = squared_norms(out - p) > max_distance * max_distance
        return out, ~(far | (idx < 0))

    def occupied_agreement(self, points: ArrayLike, threshold: float) -> NDArray[np.bool_]:
        """Which (transformed) occupied map cells agree with the reference (Psi_2 <= c)."""
        return lookup_distance(self.occupied_distance, points) <= threshold

    def chance_agreement(self, threshold: float) -> float:
        """Probability that a cell dropped at random on the known reference area agrees.

        The fraction of known reference cells within ``threshold`` (Manhattan) of an occupied
        reference cell: the agreement that noise gets by luck. Used by the stopping rule.
        Computed once per threshold.
        """
        cached = self._chance.get(threshold)
        if cached is not None:
            return cached
        bound = _whole_bound(threshold)
        if bound is None:  # beyond what the histogram tells apart
            states, distance = self.reference.states, self.occupied_distance
            n_known, n_near = _known_and_near(states, distance, threshold)
        elif bound < 0:
            n_known, n_near = self.known_count, 0
        else:  # the occupied cells (at distance 0) and the free cells within the bound
            n_known = self.known_count
            n_near = self.occupied_points.shape[0] + int(self._free_histogram[: bound + 1].sum())
        value = 1.0 if n_known == 0 else float(n_near) / n_known
        self._chance[threshold] = value
        return value

    @cached_property
    def _free_histogram(self) -> NDArray[np.int64]:
        """:func:`free_distance_histogram` of the reference (one pass, on first use)."""
        return free_distance_histogram(self.reference.states, self.occupied_distance)

    @property
    def known_count(self) -> int:
        """Number of known (occupied or free) reference cells."""
        return self.occupied_points.shape[0] + int(self._free_histogram.sum())

    def free_beyond_count(self, limit: float) -> int:
        """Number of free reference cells farther than ``limit`` (Manhattan) from every
        occupied one (``distance > limit``, as :func:`~brokenness.masking.distance.beyond`
        counts them)."""
        bound = _whole_bound(limit)
        if bound is None:  # beyond what the histogram tells apart
            return _free_beyond(self.reference.states, self.occupied_distance, limit)
        return int(self._free_histogram[max(bound + 1, 0) :].sum())


def free_distance_histogram(states: NDArray[np.int8], distance: DistanceMap) -> NDArray[np.int64]:
    """How many free cells lie at each distance.

    Parameters
    ----------
    states : ndarray of int8
        A grid of cell states.
    distance : ndarray of float32 or uint16
        Finite whole-number distances of its cells (a Manhattan distance map), same shape.

    Returns
    -------
    ndarray of int64, shape (256,)
        Bin ``k`` counts the free cells at distance ``k``, the last bin those at 255 or more.
        Counted in bands of rows (no temporary of the grid's size).
    """
    out = np.zeros(_HISTOGRAM_TOP + 1, dtype=np.int64)
    bins, span = [_HISTOGRAM_TOP + 1], [0, _HISTOGRAM_TOP + 1]
    # OpenCV counts in float32: whole numbers, exact for bands of fewer than 2**24 cells
    rows = max(1, min(_BAND_ROWS, ((1 << 24) - 1) // max(states.shape[1], 1)))
    for r in range(0, states.shape[0], rows):
        free = states[r : r + rows] == FREE
        # the distances saturated to one byte (whole numbers: exact below 255)
        capped = cv2.convertScaleAbs(distance[r : r + rows])
        hist = cv2.calcHist([capped], [0], free.view(np.uint8), bins, span)
        out += hist.reshape(-1).astype(np.int64)
    return out


def _whole_bound(threshold: float) -> int | None:
    """The largest whole distance within ``threshold`` (``floor``), when the histogram of
    :func:`free_distance_histogram` tells it apart (``None`` otherwise, or if not finite)."""
    if not math.isfinite(threshold):
        return None
    bound = math.floor(threshold)
    return bound if bound < _HISTOGRAM_TOP else None


def _free_beyond(states: NDArray[np.int8], distance: DistanceMap, limit: float) -> int:
    """The free cells of ``states`` farther than ``limit`` in ``distance``, counted in bands
    of rows."""
    return sum(
        int(
            np.count_nonzero(
                (states[r : r + _BAND_ROWS] == FREE) & beyond(distance[r : r + _BAND_ROWS], limit)
            )
        )
        for r in range(0, states.shape[0], _BAND_ROWS)
    )


def _known_and_near(
    states: NDArray[np.int8], distance: DistanceMap, threshold: float
) -> tuple[int, int]:
    """The known cells of ``states`` and those of them within ``threshold`` of ``distance``,
    counted in bands of rows (no temporary of the grid's size)."""
    n_known = n_near = 0
    for r in range(0, states.shape[0], _BAND_ROWS):
        known = states[r : r + _BAND_ROWS] != UNKNOWN
        n_known += int(np.count_nonzero(known))
        known &= within(distance[r : r + _BAND_ROWS], threshold)
        n_near += int(np.count_nonzero(known))
    return n_known, n_near


def unmatched_reference(
    reference_occupied: NDArray[np.bool_],
    matched_points: ArrayLike,
    threshold: float,
    *,
    in_place: bool = False,
) -> NDArray[np.bool_]:
    """Remove from ``reference_occupied`` the cells explained by a matched partition.

    Parameters
    ----------
    reference_occupied : ndarray of bool
        The occupied reference cells still available for registration.
    matched_points : array_like, shape (N, 2)
        The partition's cells, already moved into the reference frame.
    threshold : float
        Reference cells within this Manhattan distance of a matched point are removed.
    in_place : bool
        Remove them from ``reference_occupied`` itself (C-contiguous) instead of a copy.

    Returns
    -------
    ndarray of bool
        A new mask (``reference_occupied`` itself if ``in_place``).

    Notes
    -----
    The cost follows the matched cells: for a small radius each cell of the Manhattan ball
    around the hits is cleared directly (one scatter a cell of the ball); a larger radius
    dilates the hits' box in bands of rows.
    """
    p = np.asarray(matched_points, dtype=float).reshape(-1, 2)
    h, w = reference_occupied.shape
    cols = np.rint(p[:, 0]).astype(np.intp)
    rows = np.rint(p[:, 1]).astype(np.intp)
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    if in_place and not reference_occupied.flags.c_contiguous:
        raise ValueError("in_place needs a C-contiguous mask")
    out = reference_occupied if in_place else reference_occupied.copy()
    radius = int(np.floor(threshold))
    if not inside.any() or radius < 0:
        return out
    rows, cols = rows[inside], cols[inside]
    if 2 * radius * (radius + 1) + 1 <= _SCATTER_BALL:
        _clear_ball(out, rows, cols, radius)
    else:
        _clear_dilated(out, rows, cols, threshold)
    return out


def _clear_ball(
    out: NDArray[np.bool_], rows: NDArray[np.intp], cols: NDArray[np.intp], radius: int
) -> None:
    """Clear the cells of ``out`` within Manhattan ``radius`` of the cells ``(rows, cols)``
    (inside the grid), one offset of the ball at a time."""
    h, w = out.shape
    flat = out.reshape(-1)  # a view: ``out`` is C-contiguous
    base = rows * w + cols
    for dr, dc in ball_offsets(radius):
        r, c = rows + dr, cols + dc
        ok = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        flat[base[ok] + (dr * w + dc)] = False


def _clear_dilated(
    out: NDArray[np.bool_], rows: NDArray[np.intp], cols: NDArray[np.intp], threshold: float
) -> None:
    """:func:`_clear_ball` for a large radius: the hits' box, widened by the radius, dilated
    in bands of rows (each with the hits within the radius above and below it)."""
    h, w = out.shape
    radius = int(np.floor(threshold))
    r0, r1 = max(int(rows.min()) - radius, 0), min(int(rows.max()) + radius + 1, h)
    c0, c1 = max(int(cols.min()) - radius, 0), min(int(cols.max()) + radius + 1, w)
    order = np.argsort(rows, kind="stable")
    rows, cols = rows[order], cols[order]
    for b0 in range(r0, r1, _BAND_ROWS):
        b1 = min(b0 + _BAND_ROWS, r1)
        lo, hi = max(b0 - radius, r0), min(b1 + radius, r1)
        i, j = np.searchsorted(rows, (lo, hi))
        hit = np.zeros((hi - lo, c1 - c0), dtype=bool)
        hit[rows[i:j] - lo, cols[i:j] - c0] = True
        near = within_manhattan(hit, threshold)[b0 - lo : b1 - lo]
        out[b0:b1, c0:c1] &= ~near


def within_manhattan(mask: NDArray[np.bool_], threshold: float) -> NDArray[np.bool_]:
    """Cells within Manhattan distance ``threshold`` of a True cell of ``mask``.

    ``manhattan_distance_map(mask) <= threshold``, by one dilation (distances between cells
    are whole numbers).
    """
    radius = int(np.floor(threshold))
    if radius < 0:
        return np.zeros(mask.shape, dtype=bool)
    src = np.ascontiguousarray(mask, dtype=bool).view(np.uint8)
    near = cv2.dilate(src, manhattan_ball(radius)) if radius > 0 else src
    return np.asarray(near, dtype=bool)


def manhattan_ball(radius: int) -> NDArray[np.uint8]:
    """Structuring element of the cells within Manhattan distance ``radius`` of the centre."""
    r = np.arange(-radius, radius + 1)
    return (np.abs(r)[:, None] + np.abs(r)[None, :] <= radius).astype(np.uint8)


def ball_offsets(radius: int) -> list[tuple[int, int]]:
    """The offsets ``(dr, dc)`` of the cells of :func:`manhattan_ball`, row by row."""
    return [(int(dr) - radius, int(dc) - radius) for dr, dc in np.argwhere(manhattan_ball(radius))]
