"""Vectorised evaluation of Birk & Carpin's dissimilarity Delta for many transforms at once.

Private helper of :mod:`brokenness.registration.random_walk`. Everything that depends on one
map only (distance maps, cell coordinates) is computed once; evaluating a batch of ``W``
transforms is then a handful of numpy gathers and reductions over ``W x N`` sampled cells.

Lookup tables
-------------
For each map and each kind ``c`` (occupied, free) one uint16 table holds, per cell, the
Manhattan distance to the nearest cell of kind ``c`` if the cell itself is *known*, and
:data:`UNKNOWN_VALUE` if it is unknown; a point that falls off the map reads the same. One
gather then answers three questions about a transformed cell of kind ``c``: is its landing
cell known (``v != UNKNOWN_VALUE``), does it agree (``v == 0``: the landing cell is of kind
``c``) or disagree (known and ``v > 0``: the other kind), and how far is the nearest cell
of kind ``c`` (``v``). Integer tables halve the memory traffic of float32 ones and make
the sums exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..grid import FREE, OCCUPIED
from ..masking import manhattan_distance_map
from ..masking.distance import REMAP_SIDE, remap_points

__all__: list[str] = []

KINDS: tuple[int, int] = (OCCUPIED, FREE)
#: Table value of an unknown cell (and of every point off the map).
UNKNOWN_VALUE: int = 65535
#: Points gathered per ``cv2.remap`` call (OpenCV asserts fewer than 32767 columns).
_REMAP_COLUMNS: int = 32000


@dataclass(frozen=True, eq=False)
class MapTables:
    """Distance lookup tables and sampled cell coordinates of one map.

    Attributes
    ----------
    shape : (rows, cols)
    tables : tuple of two uint16 arrays, shape (rows, cols)
        Lookup tables for occupied and free cells (see the module docstring).
    points : tuple of two float32 arrays, shape (3, n_c)
        Homogeneous ``(x, y, 1)`` coordinates (as columns) of the (sampled) occupied and
        free cells.
    weights : tuple of two floats
        ``N_c / n_c``: how many cells of the map one sampled cell stands for.
    counts : tuple of two ints
        ``N_c``, the number of occupied and free cells before sampling.
    cap : float
        Distance used for a kind that is absent from the map (``rows + cols``, and the
        largest distance stored).
    """

    shape: tuple[int, int]
    tables: tuple[NDArray[np.uint16], NDArray[np.uint16]]
    points: tuple[NDArray[np.float32], NDArray[np.float32]]
    weights: tuple[float, float]
    counts: tuple[int, int]
    cap: float

    @property
    def n_known(self) -> int:
        """Number of known (occupied or free) cells."""
        return self.counts[0] + self.counts[1]

    @property
    def centroid(self) -> NDArray[np.float64]:
        """Mean ``(x, y)`` of the known cells (of the samples, weighted by kind)."""
        total = np.zeros(2)
        mass = 0.0
        for pts, w in zip(self.points, self.weights, strict=True):
            if pts.shape[1]:
                total += pts[:2].astype(np.float64).sum(axis=1) * w
                mass += pts.shape[1] * w
        return total / mass if mass else np.array([self.shape[1] / 2.0, self.shape[0] / 2.0])


def sample_indices(n: int, max_points: int) -> NDArray[np.intp]:
    """Deterministic subsample of ``range(n)``: all of it, or ``max_points`` evenly spaced.

    Evenly spaced in the row-major order of the cells, so the sample covers the whole map;
    it does not depend on the random walk's seed.
    """
    if n <= max_points:
        return np.arange(n, dtype=np.intp)
    return np.linspace(0, n - 1, max_points).round().astype(np.intp)


def build_tables(states: NDArray[np.int8], max_points: int) -> MapTables:
    """Lookup tables and sampled coordinates of one map (see :class:`MapTables`)."""
    rows, cols = states.shape
    cap = float(min(rows + cols, UNKNOWN_VALUE - 1))
    known = states >= 0
    tables = []
    points = []
    weights = []
    counts = []
    for kind in KINDS:
        mask = states == kind
        dist = manhattan_distance_map(mask)
        dist = np.where(np.isfinite(dist), np.minimum(dist, cap), cap).astype(np.uint16)
        tables.append(np.where(known, dist, UNKNOWN_VALUE).astype(np.uint16))
        r, c = np.nonzero(mask)
        n = r.size
        keep = sample_indices(n, max_points)
        points.append(np.vstack([c[keep], r[keep], np.ones(keep.size)]).astype(np.float32))
        weights.append(n / keep.size if keep.size else 0.0)
        counts.append(n)
    return MapTables(
        shape=(rows, cols),
        tables=(tables[0], tables[1]),
        points=(points[0], points[1]),
        weights=(weights[0], weights[1]),
        counts=(counts[0], counts[1]),
        cap=cap,
    )


def subsample_tables(tables: MapTables, max_points: int) -> MapTables:
    """The same tables with at most ``max_points`` cells of each kind (see
    :func:`sample_indices`); the distance maps are shared, not copied."""
    points = []
    weights = []
    for pts, w, n in zip(tables.points, tables.weights, tables.counts, strict=True):
        if pts.shape[1] <= max_points:
            points.append(pts)
            weights.append(w)
            continue
        keep = sample_indices(pts.shape[1], max_points)
        points.append(np.ascontiguousarray(pts[:, keep]))
        weights.append(n / keep.size)
    return MapTables(
        shape=tables.shape,
        tables=tables.tables,
        points=(points[0], points[1]),
        weights=(weights[0], weights[1]),
        counts=tables.counts,
        cap=tables.cap,
    )


def _lookup(
    tables: MapTables, kind_index: int, points: NDArray[np.float32], matrix: NDArray[np.float32]
) -> NDArray[np.uint16]:
    """Table values at the transformed points, shape (W, n); unknown off the map.

    ``points`` (3, n) homogeneous columns; ``matrix`` (2W, 3) holds the x rows of the ``W``
    affine transforms, then their y rows. Element-wise products give all coordinates, and
    ``cv2.remap`` with nearest-neighbour interpolation (round half to even, like
    ``numpy.rint``) gathers the table values, reading unknown outside the grid.
    """
    if points.shape[1] > _REMAP_COLUMNS:  # cv2.remap handles at most 32766 columns
        return np.concatenate(
            [
                _lookup(tables, kind_index, points[:, i : i + _REMAP_COLUMNS], matrix)
                for i in range(0, points.shape[1], _REMAP_COLUMNS)
            ],
            axis=1,
        )
    # Element-wise products, not a matrix product: BLAS would bring its own threads (which
    # spin for minutes on a loaded machine) and, with them, results that could depend on
    # the number of threads; these are exact float32 operations in a fixed order.
    coords = matrix[:, 0:1] * points[0] + matrix[:, 1:2] * points[1] + matrix[:, 2:3]
    w = matrix.shape[0] // 2
    table = tables.tables[kind_index]
    if max(table.shape) >= REMAP_SIDE:  # too large for one remap: read in windows
        xy = np.stack([coords[:w].reshape(-1), coords[w:].reshape(-1)], axis=1)
        found = remap_points(table, xy, cv2.INTER_NEAREST, UNKNOWN_VALUE)
        return np.asarray(found, dtype=np.uint16).reshape(coords[:w].shape)
    values = cv2.remap(
        tables.tables[kind_index],
        coords[:w],
        coords[w:],
        cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=UNKNOWN_VALUE,
    )
    return np.asarray(values, dtype=np.uint16)  # a no-op: remap keeps the table's type


def explained_cells(
    reference: MapTables,
    points: NDArray[np.float32],
    cos: NDArray[np.float64],
    sin: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    explain_cells: float,
) -> NDArray[np.bool_]:
    """Which of ``points`` (3, n) land within ``explain_cells`` of an occupied reference cell
    under each of the ``W`` transforms: a (W, n) boolean array."""
    w = cos.shape[0]
    forward = np.empty((2 * w, 3), dtype=np.float32)
    forward[:w, 0], forward[:w, 1], forward[:w, 2] = cos, -sin, tx
    forward[w:, 0], forward[w:, 1], forward[w:, 2] = sin, cos, ty
    v = _lookup(reference, 0, points, forward)
    return np.asarray(v <= min(explain_cells, UNKNOWN_VALUE - 1))


@dataclass(frozen=True)
class Scores:
    """Delta and its parts for a batch of ``W`` transforms (arrays of shape (W,)).

    ``explained`` is not part of Delta: the occupied moving cells (scaled back to cells when
    sampled) that land within ``explain_cells`` of an occupied reference cell, the masking's
    measure of how much of the map a transform explains.
    """

    delta: NDArray[np.float64]
    psi: NDArray[np.float64]
    agree: NDArray[np.float64]
    disagree: NDArray[np.float64]
    explained: NDArray[np.float64]

    @property
    def acceptance(self) -> NDArray[np.float64]:
        """Acceptance indicator agree / (agree + disagree), 0 without overlap."""
        total = self.agree + self.disagree
        return np.divide(self.agree, total, out=np.zeros_like(total), where=total > 0)


def score(
    reference: MapTables,
    moving: MapTables,
    cos: NDArray[np.float64],
    sin: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    c_lock: float,
    chunk_elements: int = 400_000,
    explain_cells: float = 2.0,
) -> Scores:
    """Delta = Psi (restricted to the overlap) + c_lock * (disagree - agree), per transform.

    Parameters
    ----------
    reference, moving : MapTables
    cos, sin, tx, ty : ndarray, shape (W,)
        The transforms ``x' = cos x - sin y + tx``, ``y' = sin x + cos y + ty`` (moving cells
        to reference cells).
    c_lock : float
        Weight of the agreement term, per cell.
    chunk_elements : int
        Transforms are evaluated in groups of about this many transformed points, so that
        the temporaries stay in the processor's cache (a speed setting only).
    explain_cells : float
        Distance (Manhattan, cells) within which an occupied moving cell counts as
        explained (``Scores.explained``).

    Notes
    -----
    Psi is summed over the two kinds and both directions. Moving -> reference: the mean
    distance from each moving cell of kind ``c`` whose landing cell is known in the
    reference to the nearest reference cell of kind ``c``. Reference -> moving: the same for
    reference cells mapped back by the inverse transform onto known moving cells. A
    direction in which a kind exists but no cell of it lands on known ground adds ``cap``
    (the largest distance); a kind absent from the source map adds nothing. Agreement is
    counted in the moving -> reference direction, scaled back to cells when sampled.
    """
    n_points = sum(p.shape[1] for p in (*moving.points, *reference.points))
    group = max(1, chunk_elements // max(n_points, 1))
    if cos.shape[0] > group:
        parts = [
            score(
                reference,
                moving,
                cos[i : i + group],
                sin[i : i + group],
                tx[i : i + group],
                ty[i : i + group],
                c_lock,
                chunk_elements,
                explain_cells,
            )
            for i in range(0, cos.shape[0], group)
        ]
        return Scores(
            *(
                np.concatenate([getattr(p, f) for p in parts])
                for f in ("delta", "psi", "agree", "disagree", "explained")
            )
        )
    w = cos.shape[0]
    # Rows 0..W-1: x' = cos x - sin y + tx; rows W..2W-1: y' = sin x + cos y + ty.
    forward = np.empty((2 * w, 3), dtype=np.float32)
    forward[:w, 0], forward[:w, 1], forward[:w, 2] = cos, -sin, tx
    forward[w:, 0], forward[w:, 1], forward[w:, 2] = sin, cos, ty
    # The inverse: x = cos (x' - tx) + sin (y' - ty), y = -sin (x' - tx) + cos (y' - ty).
    inverse = np.empty((2 * w, 3), dtype=np.float32)
    inverse[:w, 0], inverse[:w, 1], inverse[:w, 2] = cos, sin, -(cos * tx + sin * ty)
    inverse[w:, 0], inverse[w:, 1], inverse[w:, 2] = -sin, cos, sin * tx - cos * ty
    psi = np.zeros(w)
    agree = np.zeros(w)
    disagree = np.zeros(w)
    explained = np.zeros(w)
    for k in range(len(KINDS)):
        # Moving -> reference.
        if moving.points[k].shape[1]:
            v = _lookup(reference, k, moving.points[k], forward)
            mean, n_known, n_agree = _reduce(v, reference.cap)
            psi += mean
            weight = moving.weights[k]
            agree += n_agree * weight
            disagree += (n_known - n_agree) * weight
            if KINDS[k] == OCCUPIED:
                near = np.count_nonzero(v <= min(explain_cells, UNKNOWN_VALUE - 1), axis=1)
                explained += near * weight
        # Reference -> moving, through the inverse transform.
        if reference.points[k].shape[1]:
            psi += _reduce(_lookup(moving, k, reference.points[k], inverse), moving.cap)[0]
    delta = psi + c_lock * (disagree - agree)
    return Scores(delta=delta, psi=psi, agree=agree, disagree=disagree, explained=explained)


def _reduce(
    v: NDArray[np.uint16], cap: float
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Row-wise mean of the known entries, their count, and the zeros (agreements).

    Integer sums, so the result does not depend on the summation order. Rows without a
    known entry get the mean ``cap``.
    """
    n_unknown = np.count_nonzero(v == UNKNOWN_VALUE, axis=1)
    n_known = v.shape[1] - n_unknown
    # uint32 sums are twice as fast as int64 ones and cannot overflow below 65537 columns.
    acc = np.uint32 if v.shape[1] <= 65536 else np.int64
    total = (v.sum(axis=1, dtype=acc).astype(np.int64) - UNKNOWN_VALUE * n_unknown).astype(
        np.float64
    )
    mean = np.divide(total, n_known, out=np.full(v.shape[0], cap), where=n_known > 0)
    return mean, n_known, np.count_nonzero(v == 0, axis=1)
