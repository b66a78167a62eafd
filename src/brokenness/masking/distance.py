"""Linear-time Manhattan distance maps, the building block of Birk's similarity Psi."""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["lookup_distance", "manhattan_distance_map", "sample_at"]


def manhattan_distance_map(mask: ArrayLike) -> NDArray[np.float32]:
    """Manhattan (L1) distance from every cell to the nearest ``True`` cell of ``mask``.

    Parameters
    ----------
    mask : array_like of bool, 2D
        The cells of one kind (for example the occupied cells of the reference).

    Returns
    -------
    ndarray of float32
        Same shape as ``mask``; 0 on ``True`` cells, ``inf`` everywhere if ``mask`` is empty.

    Notes
    -----
    OpenCV's two-pass ``distanceTransform`` with the 3x3 L1 mask is exact for the Manhattan
    metric and runs in linear time (Borgefors 1986), like the two-pass algorithm of Birk &
    Carpin (2006). It runs on the bounding box of the ``True`` cells only: outside it, the
    distance is the distance to the box plus that of the nearest box cell (every L1 path
    into the box passes through it), filled in directly (:func:`_extend_box`), so that the
    cost follows the cells of that box, not the empty margins of the grid.
    """
    m = np.asarray(mask, dtype=bool)
    if not m.any():
        return np.full(m.shape, np.inf, dtype=np.float32)
    # OpenCV measures the distance to the nearest zero pixel (one byte a cell, no wider
    # temporary); its bounding box of the non-zero pixels is one fast pass
    c0, r0, bw, bh = cv2.boundingRect(np.ascontiguousarray(m).view(np.uint8))
    r1, c1 = r0 + bh, c0 + bw
    if (r0, c0, r1, c1) == (0, 0, *m.shape):
        distance = cv2.distanceTransform(np.logical_not(m).view(np.uint8), cv2.DIST_L1, 3)
        return np.asarray(distance, dtype=np.float32)
    out = np.empty(m.shape, dtype=np.float32)
    inner = np.logical_not(m[r0:r1, c0:c1]).view(np.uint8)  # a fresh box of bytes
    cv2.distanceTransform(inner, cv2.DIST_L1, 3, dst=out[r0:r1, c0:c1])  # written in place
    _extend_box(out, r0, r1, c0, c1)
    return out


def _extend_box(out: NDArray[np.float32], r0: int, r1: int, c0: int, c1: int) -> None:
    """Fill ``out`` outside the box ``[r0, r1) x [c0, c1)``, which holds the Manhattan
    distances to cells all inside it: a cell outside is as far as its nearest box cell plus
    the distance to the box (whole numbers, exact in float32), written without temporaries."""
    h, w = out.shape
    band = out[r0:r1]
    if c0 > 0:  # left of the box, its rows
        np.add(band[:, c0 : c0 + 1], np.arange(c0, 0, -1, dtype=np.float32), out=band[:, :c0])
    if c1 < w:  # right of it
        np.add(band[:, c1 - 1 : c1], np.arange(1, w - c1 + 1, dtype=np.float32), out=band[:, c1:])
    if r0 > 0:  # above: the box's first row, now full width, plus the rows between
        steps = np.arange(r0, 0, -1, dtype=np.float32)[:, None]
        np.add(out[r0 : r0 + 1], steps, out=out[:r0])
    if r1 < h:  # below
        steps = np.arange(1, h - r1 + 1, dtype=np.float32)[:, None]
        np.add(out[r1 - 1 : r1], steps, out=out[r1:])


def lookup_distance(distance_map: NDArray[np.float32], points: ArrayLike) -> NDArray[np.float32]:
    """Sample a distance map at (sub-cell) points, ``inf`` outside the grid.

    Parameters
    ----------
    distance_map : ndarray, 2D
        As returned by :func:`manhattan_distance_map`.
    points : array_like, shape (N, 2)
        ``(x, y) = (column, row)`` coordinates; rounded to the nearest cell.

    Returns
    -------
    ndarray of float32, shape (N,)
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return sample_at(distance_map, p, math.inf, nearest=True)


def sample_at(
    field: NDArray[np.float32],
    points: ArrayLike,
    outside: float,
    *,
    nearest: bool = False,
) -> NDArray[np.float32]:
    """Samples of a float32 grid at (sub-cell) points, ``outside`` off the grid.

    One ``cv2.remap`` over the points laid out as a two-channel map: as given when that fits
    (OpenCV wants sides under 32767), in rows of 1024 points otherwise.

    Parameters
    ----------
    field : ndarray of float32, 2D
        A distance map, or any per-cell float32 table.
    points : array_like, shape (..., 2)
        ``(x, y) = (column, row)`` coordinates.
    outside : float
        The value of points off the grid.
    nearest : bool
        The value of the nearest cell (rounded half to even, like :func:`numpy.rint`)
        instead of the bilinear interpolation of the four around.

    Returns
    -------
    ndarray of float32
        The shape of ``points`` without its last axis.
    """
    grid = np.asarray(points, dtype=np.float32)
    shape = grid.shape[:-1]
    if grid.size == 0:
        return np.zeros(shape, dtype=np.float32)
    if grid.ndim == 2:
        grid = grid.reshape(1, -1, 2)
    if grid.ndim != 3 or max(grid.shape[:2]) >= 32_000:
        flat = grid.reshape(-1, 2)
        n, width = flat.shape[0], 1024
        grid = np.full((-(-n // width) * width, 2), -1e6, dtype=np.float32)
        grid[:n] = flat
        grid = grid.reshape(-1, width, 2)
    out = cv2.remap(  # type: ignore[call-overload]  # map2=None: map1 has both
        field,
        grid,
        None,
        cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float(outside),
    )
    count = math.prod(shape)
    return np.asarray(out, dtype=np.float32).reshape(-1)[:count].reshape(shape)
