"""Vectorised evaluation of Birk & Carpin's dissimilarity Delta for many transforms at once.

Private helper of :mod:`brokenness.registration.random_walk`. Everything that depends on one
map only (distance maps, cell coordinates) is computed once; evaluating a batch of ``W``
transforms is then a handful of numpy gathers and reductions over ``W x N`` sampled cells.

Lookup tables
-------------
For each map and each kind ``c`` (occupied, free) one float32 table holds, per cell, the
Manhattan distance to the nearest cell of kind ``c`` if the cell itself is *known*, and
``-1`` if it is unknown; a point that falls off the map also reads -1. One gather then
answers three questions about a transformed cell of kind ``c``: is its landing cell known
(``v >= 0``), does it agree (``v == 0``: the landing cell is of kind ``c``) or disagree
(``v > 0``: known but of the other kind), and how far is the nearest cell of kind ``c``
(``v``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..grid import FREE, OCCUPIED
from ..masking import manhattan_distance_map

__all__: list[str] = []

KINDS: tuple[int, int] = (OCCUPIED, FREE)


@dataclass(frozen=True, eq=False)
class MapTables:
    """Distance lookup tables and sampled cell coordinates of one map.

    Attributes
    ----------
    shape : (rows, cols)
    tables : tuple of two float32 arrays, shape (rows, cols)
        Lookup tables for occupied and free cells (see the module docstring).
    points : tuple of two float32 arrays, shape (n_c, 3)
        Homogeneous ``(x, y, 1)`` coordinates of the (sampled) occupied and free cells.
    weights : tuple of two floats
        ``N_c / n_c``: how many cells of the map one sampled cell stands for.
    counts : tuple of two ints
        ``N_c``, the number of occupied and free cells before sampling.
    cap : float
        Distance used for a kind that is absent from the map (``rows + cols``).
    """

    shape: tuple[int, int]
    tables: tuple[NDArray[np.float32], NDArray[np.float32]]
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
            if pts.shape[0]:
                total += pts[:, :2].astype(np.float64).sum(axis=0) * w
                mass += pts.shape[0] * w
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
    cap = float(rows + cols)
    known = states >= 0
    tables = []
    points = []
    weights = []
    counts = []
    for kind in KINDS:
        mask = states == kind
        dist = manhattan_distance_map(mask)
        dist = np.where(np.isfinite(dist), dist, np.float32(cap)).astype(np.float32)
        tables.append(np.where(known, dist, np.float32(-1.0)).astype(np.float32))
        r, c = np.nonzero(mask)
        n = r.size
        keep = sample_indices(n, max_points)
        points.append(np.column_stack([c[keep], r[keep], np.ones(keep.size)]).astype(np.float32))
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


def _lookup(
    tables: MapTables, kind_index: int, points: NDArray[np.float32], matrices: NDArray[np.float32]
) -> NDArray[np.float32]:
    """Table values at the transformed points, shape (W, n); -1 off the map.

    ``points`` (n, 3) homogeneous, ``matrices`` (W, 3, 2) transposed affine matrices: one
    matrix product gives all coordinates in OpenCV's two-channel map layout, and
    ``cv2.remap`` with nearest-neighbour interpolation (round half to even, like
    ``numpy.rint``) gathers the table values, reading -1 outside the grid.
    """
    coords = np.matmul(points, matrices)
    return cv2.remap(
        tables.tables[kind_index],
        coords,
        None,
        cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=-1.0,
    )


@dataclass(frozen=True)
class Scores:
    """Delta and its parts for a batch of ``W`` transforms (arrays of shape (W,))."""

    delta: NDArray[np.float64]
    psi: NDArray[np.float64]
    agree: NDArray[np.float64]
    disagree: NDArray[np.float64]

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
    chunk_elements: int = 160_000,
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
    n_points = sum(p.shape[0] for p in (*moving.points, *reference.points))
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
            )
            for i in range(0, cos.shape[0], group)
        ]
        return Scores(
            *(
                np.concatenate([getattr(p, f) for p in parts])
                for f in ("delta", "psi", "agree", "disagree")
            )
        )
    w = cos.shape[0]
    forward = np.empty((w, 3, 2), dtype=np.float32)  # rows: x, y, 1 -> columns x', y'
    forward[:, 0, 0], forward[:, 1, 0], forward[:, 2, 0] = cos, -sin, tx
    forward[:, 0, 1], forward[:, 1, 1], forward[:, 2, 1] = sin, cos, ty
    inverse = np.empty((w, 3, 2), dtype=np.float32)
    inverse[:, 0, 0], inverse[:, 1, 0] = cos, sin
    inverse[:, 2, 0] = -(cos * tx + sin * ty)
    inverse[:, 0, 1], inverse[:, 1, 1] = -sin, cos
    inverse[:, 2, 1] = sin * tx - cos * ty
    psi = np.zeros(w)
    agree = np.zeros(w)
    disagree = np.zeros(w)
    for k in range(len(KINDS)):
        # Moving -> reference.
        if moving.points[k].shape[0]:
            v = _lookup(reference, k, moving.points[k], forward)
            mean, n_known, n_agree = _reduce(v, reference.cap)
            psi += mean
            weight = moving.weights[k]
            agree += n_agree * weight
            disagree += (n_known - n_agree) * weight
        # Reference -> moving, through the inverse transform.
        if reference.points[k].shape[0]:
            psi += _reduce(_lookup(moving, k, reference.points[k], inverse), moving.cap)[0]
    delta = psi + c_lock * (disagree - agree)
    return Scores(delta=delta, psi=psi, agree=agree, disagree=disagree)


def _reduce(
    v: NDArray[np.float32], cap: float
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Row-wise mean of the known (non-negative) entries, their count, and the zeros.

    Unknown entries are exactly -1, so the sum of the known ones is ``sum(v) + n_unknown``.
    Rows without a known entry get the mean ``cap``.
    """
    n_unknown = np.count_nonzero(v < 0, axis=1)
    n_known = v.shape[1] - n_unknown
    total = v.sum(axis=1, dtype=np.float64) + n_unknown
    mean = np.divide(total, n_known, out=np.full(v.shape[0], cap), where=n_known > 0)
    return mean, n_known, np.count_nonzero(v == 0, axis=1)
