"""Bring a map to another resolution while keeping its world geometry.

Cell relation
-------------
With ``s = old_resolution / new_resolution`` the centre of old cell ``x`` (column) lies at
new coordinate ``x' = (x + 0.5) * s - 0.5``. Rows are handled the same way but counted from
the **bottom** row, ``y_b = rows - 1 - y``, because the map's ``origin`` is its lower-left
corner: ``y_b' = (y_b + 0.5) * s - 0.5``. In top-row coordinates (the library's convention)
this is ``y' = (y + 0.5) * s - 0.5 + (rows' - rows * s)``; the last term is zero whenever
``rows * s`` is an integer (for instance 2x or 0.5x of an even-sized map).

Size and origin
---------------
``rows' = ceil(rows * s)`` and ``cols' = ceil(cols * s)`` (at least 1; a 1e-9 tolerance absorbs
floating-point noise), so the new grid covers the whole old rectangle and overhangs it by
less than one new cell at the top and right. ``origin`` is kept unchanged: the lower-left
corner stays where it is in the world, and every point keeps its world position
(:meth:`~brokenness.grid.OccupancyMap.cell_to_world_matrix` of both maps agree).

States
------
Downsampling (``s < 1``) is area-weighted, with exact overlap lengths of old and new cells
(separable sparse matrices, no per-cell loop). ``cv2.resize(INTER_AREA)`` is not used because
it scales by ``new_size / old_size`` per axis, which differs from ``s`` once sizes are rounded,
and anchors the top-left corner instead of the origin. With areas in units of one old cell:

* **occupied** if the occupied area inside the new cell is at least 1/4 of an old cell. Every
  occupied old cell has at least a quarter of its area inside some new cell, so no wall or
  single obstacle cell can vanish; for integer factors this is exactly max-pooling of the
  occupied cells;
* else **free** if free cells cover more than half of the new cell;
* else **unknown** (area outside the old map counts as unknown).

Upsampling (``s > 1``) is nearest-neighbour: each new cell takes the state of the old cell
containing its centre (clamped at the overhanging edge). Upsampling by an integer factor and
downsampling back gives the original map exactly.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..errors import MapError
from ..grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from ..limits import check_cells, check_resolution

__all__ = ["cell_scale_offset", "common_resolution", "resample_to_resolution", "resampled_size"]

_EPS = 1e-9
#: Occupied area (in old cells) that makes a new cell occupied.
OCCUPIED_AREA: float = 0.25
#: Fraction of a new cell that free cells must exceed to make it free.
FREE_FRACTION: float = 0.5


def resampled_size(n: int, scale: float) -> int:
    """Number of cells ``ceil(n * scale)`` (at least 1) along an axis of ``n`` cells."""
    return max(1, math.ceil(n * scale - _EPS))


def _overlap_matrix(n_new: int, n_old: int, scale: float) -> sp.csr_matrix:
    """Sparse ``(n_new, n_old)`` matrix of overlap lengths (in old cells), for ``scale < 1``.

    A new cell overlaps ``ceil(1 / scale) + 1`` old cells at most, and never more than the
    ``n_old`` there are: the entries tried are bounded by the old cells, not by the ratio.
    """
    width = 1.0 / scale
    k = min(math.ceil(width) + 1, n_old + 1)
    i = np.repeat(np.arange(n_new), k)
    lo = i * width
    j = np.floor(lo).astype(np.int64) + np.tile(np.arange(k), n_new)
    overlap = np.minimum(lo + width, j + 1) - np.maximum(lo, j)
    keep = (overlap > _EPS) & (j < n_old)
    return sp.csr_matrix((overlap[keep], (i[keep], j[keep])), shape=(n_new, n_old))


def _downsample(states: NDArray[np.int8], scale: float, shape: tuple[int, int]) -> NDArray[np.int8]:
    rows, cols = states.shape
    wy = _overlap_matrix(shape[0], rows, scale)
    wx = _overlap_matrix(shape[1], cols, scale)

    def area(mask: NDArray[np.bool_]) -> NDArray[np.float64]:
        return np.asarray((wx @ (wy @ mask.astype(np.float64)).T).T)

    occupied = area(states == OCCUPIED) >= OCCUPIED_AREA - _EPS
    free = area(states == FREE) > FREE_FRACTION / (scale * scale) + _EPS
    out = np.full(shape, UNKNOWN, dtype=np.int8)
    out[free] = FREE
    out[occupied] = OCCUPIED
    return out


def _upsample(states: NDArray[np.int8], scale: float, shape: tuple[int, int]) -> NDArray[np.int8]:
    rows, cols = states.shape
    iy = np.minimum(np.floor((np.arange(shape[0]) + 0.5) / scale).astype(np.int64), rows - 1)
    ix = np.minimum(np.floor((np.arange(shape[1]) + 0.5) / scale).astype(np.int64), cols - 1)
    return states[np.ix_(iy, ix)]


def resample_to_resolution(m: OccupancyMap, resolution: float) -> OccupancyMap:
    """Resample a map to another resolution, keeping its world geometry.

    See the module docstring for the exact cell relation, size rounding and state rules.

    Parameters
    ----------
    m : OccupancyMap
        A map with a known ``resolution``.
    resolution : float
        The new resolution in metres per cell.

    Returns
    -------
    OccupancyMap
        Same ``origin`` and ``source``; ``m`` itself when the resolution is unchanged.

    Raises
    ------
    MapError
        If ``m`` is not an :class:`OccupancyMap` or has no resolution.
    MapSizeError
        If the resampled map would have more than :func:`~brokenness.limits.max_cells`
        cells (checked before anything is allocated).
    ParameterError
        If ``resolution`` is not a number of metres in
        [:data:`~brokenness.limits.MIN_RESOLUTION`, :data:`~brokenness.limits.MAX_RESOLUTION`]
        (the range of a map's own).

    Examples
    --------
    >>> import numpy as np
    >>> m = OccupancyMap(np.zeros((4, 4), np.int8), resolution=0.05)
    >>> resample_to_resolution(m, 0.1).shape
    (2, 2)
    """
    if not isinstance(m, OccupancyMap):
        raise MapError(f"only an OccupancyMap can be resampled, got {type(m).__name__}")
    new_res = check_resolution(resolution)  # a ParameterError out of range
    if m.resolution is None:
        raise MapError(f"{m.source or 'map'}: has no resolution, so it cannot be resampled")
    if new_res == m.resolution:
        return m
    scale = m.resolution / new_res
    rows, cols = m.shape
    # the size after resampling, checked before anything is allocated
    check_cells(rows * scale, cols * scale, f"{m.source or 'map'}: resampled to {new_res:g} m")
    shape = (resampled_size(rows, scale), resampled_size(cols, scale))
    flipped = m.states[::-1]  # bottom row first: the origin corner is the anchor
    if scale < 1:
        out = _downsample(flipped, scale, shape)
    else:
        out = _upsample(flipped, scale, shape)
    return OccupancyMap(np.ascontiguousarray(out[::-1]), new_res, m.origin, m.source)


def cell_scale_offset(old: OccupancyMap, new: OccupancyMap) -> tuple[float, float, float]:
    """Affine relation between the cells of a map and of its resampled copy.

    For ``new = resample_to_resolution(old, r)`` the centre of old cell ``(x, y)`` (column,
    row from the top) is at new cell ``(s * x + tx, s * y + ty)``, with
    ``s = old.resolution / new.resolution``, ``tx = 0.5 * s - 0.5`` and
    ``ty = 0.5 * s - 0.5 + (rows' - rows * s)`` (rows are anchored at the bottom).

    Returns
    -------
    (s, tx, ty) : tuple of float

    Raises
    ------
    MapError
        If either map has no resolution.
    """
    if old.resolution is None or new.resolution is None:
        raise MapError("both maps need a resolution to relate their cells")
    s = old.resolution / new.resolution
    t = 0.5 * s - 0.5
    return s, t, t + (new.shape[0] - old.shape[0] * s)


def common_resolution(a: OccupancyMap, b: OccupancyMap) -> float | None:
    """The resolution to bring two maps to before comparing them: the coarser of the two.

    Downsampling the finer map invents no detail, and walls survive it (see
    :func:`resample_to_resolution`).

    Returns
    -------
    float or None
        ``max(a.resolution, b.resolution)``, or ``None`` if either map has no resolution.
    """
    if a.resolution is None or b.resolution is None:
        return None
    return max(a.resolution, b.resolution)
