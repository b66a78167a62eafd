"""Linear-time Manhattan distance maps, the building block of Birk's similarity Psi.

A map's Manhattan distances are whole numbers: :func:`compact_distance_map` keeps them in
two bytes a cell (``uint16``), and :func:`sample_at` reads such a map exactly as it reads
the same values in ``float32`` (see :func:`_bilinear_whole`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import cast

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DistanceMap",
    "beyond",
    "compact_distance_map",
    "lookup_distance",
    "manhattan_distance_map",
    "remap_points",
    "sample_at",
    "sample_xy",
    "within",
]

#: A distance map as :func:`sample_at` reads it: ``float32``, or whole numbers in ``uint16``.
DistanceMap = NDArray[np.float32] | NDArray[np.uint16]

#: The value of a ``uint16`` map's cells off the grid in a nearest-cell lookup (no distance
#: of a map of fewer than 65535 rows plus columns reaches it).
_NO_CELL = 65535
#: Points per ``cv2.remap`` call are laid out in rows of this many (OpenCV asserts sides
#: under 32767).
_ROW_POINTS = 1024
#: ``cv2.remap`` asserts that the grid it reads has sides under this (``SHRT_MAX``).
REMAP_SIDE = 32767
#: A grid with a side of :data:`REMAP_SIDE` or more is read in windows of this side, plus
#: :data:`_WINDOW_MARGIN` cells (see :func:`remap_points`).
_WINDOW = 16384
#: Cells a point may read past the first of its cells: bilinear interpolation reads that
#: cell and the next, and OpenCV's fixed-point rounding of the coordinate (1/32 of a cell)
#: can move both one cell on.
_WINDOW_MARGIN = 2
#: Largest exponent of a coordinate's bucket (coordinates of 2**7 and more share one), and
#: so the patches a row or column of an atlas holds, at most (see :func:`_bilinear_whole`).
_TOP_BUCKET = 7


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


def compact_distance_map(mask: ArrayLike) -> DistanceMap:
    """:func:`manhattan_distance_map` in two bytes a cell where every distance fits.

    Parameters
    ----------
    mask : array_like of bool, 2D
        The cells of one kind, at least one of them ``True``.

    Returns
    -------
    ndarray of uint16, or of float32
        The same whole numbers as :func:`manhattan_distance_map`: ``uint16`` when the grid
        has fewer than 65535 rows plus columns (no distance reaches :data:`_NO_CELL`),
        ``float32`` otherwise (or if ``mask`` is empty).

    Notes
    -----
    The transform runs on the bounding box of the ``True`` cells (:func:`_box_distances`)
    in ``float32`` (OpenCV's exact type for it), which is then copied into the ``uint16``
    grid and freed: the grid-sized ``float32`` map is never held.
    """
    m = np.asarray(mask, dtype=bool)
    if sum(m.shape) >= _NO_CELL or not m.any():
        return manhattan_distance_map(m)
    c0, r0, bw, bh = cv2.boundingRect(np.ascontiguousarray(m).view(np.uint8))
    r1, c1 = r0 + bh, c0 + bw
    inner = np.logical_not(m[r0:r1, c0:c1]).view(np.uint8)  # a fresh box of bytes
    out = np.empty(m.shape, dtype=np.uint16)
    _box_distances(inner, out[r0:r1, c0:c1])
    del inner
    _extend_box(out, r0, r1, c0, c1)
    return out


def _box_distances(seeds_not: NDArray[np.uint8], out: NDArray[np.uint16]) -> None:
    """Write into ``out`` the Manhattan distances to the zero cells of ``seeds_not``, by
    OpenCV's exact ``float32`` transform of the box (freed when copied; its one-byte
    transform, saturated at 255, is no faster on maps whose distances pass 255)."""
    box = cv2.distanceTransform(seeds_not, cv2.DIST_L1, 3)
    np.copyto(out, box, casting="unsafe")  # whole numbers under 65535


def _extend_box(out: DistanceMap, r0: int, r1: int, c0: int, c1: int) -> None:
    """Fill ``out`` outside the box ``[r0, r1) x [c0, c1)``, which holds the Manhattan
    distances to cells all inside it: a cell outside is as far as its nearest box cell plus
    the distance to the box (whole numbers, exact in float32 and, for the grids
    :func:`compact_distance_map` keeps so, in uint16), written without temporaries."""
    h, w = out.shape
    kind = out.dtype
    band = out[r0:r1]
    if c0 > 0:  # left of the box, its rows
        np.add(band[:, c0 : c0 + 1], np.arange(c0, 0, -1, dtype=kind), out=band[:, :c0])
    if c1 < w:  # right of it
        np.add(band[:, c1 - 1 : c1], np.arange(1, w - c1 + 1, dtype=kind), out=band[:, c1:])
    if r0 > 0:  # above: the box's first row, now full width, plus the rows between
        steps = np.arange(r0, 0, -1, dtype=kind)[:, None]
        np.add(out[r0 : r0 + 1], steps, out=out[:r0])
    if r1 < h:  # below
        steps = np.arange(1, h - r1 + 1, dtype=kind)[:, None]
        np.add(out[r1 - 1 : r1], steps, out=out[r1:])


def within(distance: DistanceMap, threshold: float) -> NDArray[np.bool_]:
    """``distance <= threshold``; for a ``uint16`` map (whole numbers) by the whole bound
    ``floor(threshold)``, the same cells without a wider temporary."""
    if distance.dtype != np.uint16 or not math.isfinite(threshold):
        return np.asarray(distance <= threshold)
    bound = math.floor(threshold)
    if bound < 0:
        return np.zeros(distance.shape, dtype=bool)
    return np.asarray(distance <= np.uint16(min(bound, _NO_CELL)))


def beyond(distance: DistanceMap, limit: float) -> NDArray[np.bool_]:
    """``distance > limit``; for a ``uint16`` map by the whole bound ``floor(limit)``."""
    if distance.dtype != np.uint16 or not math.isfinite(limit):
        return np.asarray(distance > limit)
    bound = math.floor(limit)
    if bound < 0:
        return np.ones(distance.shape, dtype=bool)
    return np.asarray(distance > np.uint16(min(bound, _NO_CELL)))


def lookup_distance(distance_map: DistanceMap, points: ArrayLike) -> NDArray[np.float32]:
    """Sample a distance map at (sub-cell) points, ``inf`` outside the grid.

    Parameters
    ----------
    distance_map : ndarray, 2D
        As returned by :func:`manhattan_distance_map` or :func:`compact_distance_map`.
    points : array_like, shape (N, 2)
        ``(x, y) = (column, row)`` coordinates; rounded to the nearest cell.

    Returns
    -------
    ndarray of float32, shape (N,)
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return sample_at(distance_map, p, math.inf, nearest=True)


def sample_at(
    field: DistanceMap,
    points: ArrayLike,
    outside: float,
    *,
    nearest: bool = False,
) -> NDArray[np.float32]:
    """Samples of a float32 grid at (sub-cell) points, ``outside`` off the grid.

    One ``cv2.remap`` over the points laid out as a two-channel map: as given when that fits
    (OpenCV wants sides under 32767), in rows of 1024 points otherwise (a grid with a side
    of 32767 cells or more: in windows, :func:`remap_points`, the same samples). A
    ``uint16`` grid of whole numbers (:func:`compact_distance_map`) gives the samples of the
    same values in ``float32``, bit for bit.

    Parameters
    ----------
    field : ndarray of float32 or uint16, 2D
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
    if field.dtype == np.uint16:
        whole = cast("NDArray[np.uint16]", field)
        flat = _whole_samples(whole, grid.reshape(-1, 2), outside, nearest=nearest)
        return flat.reshape(shape)
    out = _remap(field, grid, cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR, outside)
    return np.asarray(out, dtype=np.float32).reshape(shape)


def sample_xy(
    field: DistanceMap,
    x: NDArray[np.float32],
    y: NDArray[np.float32],
    outside: float,
    *,
    nearest: bool = False,
) -> NDArray[np.float32]:
    """:func:`sample_at` of the points whose coordinates are given as two arrays.

    ``sample_xy(field, x, y, outside)`` is ``sample_at(field, np.stack([x, y], axis=-1),
    outside)``, bit for bit: OpenCV rounds each coordinate in the same way whether its map
    is one two-channel array or two one-channel planes. The planes spare a caller that
    computes the coordinates one axis at a time the interleaving (strided stores) of the
    points.

    Parameters
    ----------
    field : ndarray of float32 or uint16, 2D
        As for :func:`sample_at`.
    x, y : ndarray of float32
        The column and row coordinates of the points, of one shape.
    outside : float
        The value of points off the grid.
    nearest : bool
        As for :func:`sample_at`.

    Returns
    -------
    ndarray of float32
        The shape of ``x``.

    Raises
    ------
    ValueError
        If ``x`` and ``y`` differ in shape.
    """
    if x.shape != y.shape:
        raise ValueError(f"x and y differ in shape: {x.shape} and {y.shape}")
    shape = x.shape
    if x.size == 0:
        return np.zeros(shape, dtype=np.float32)
    cols = shape[-1] if x.ndim else 1
    rows = x.size // cols
    # sample_at's own layouts (and windows of a grid too large for one remap)
    if field.dtype == np.uint16 or max(rows, cols) >= 32_000 or max(field.shape) >= REMAP_SIDE:
        return sample_at(field, np.stack([x, y], axis=-1), outside, nearest=nearest)
    out = cv2.remap(
        field,
        np.ascontiguousarray(x, dtype=np.float32).reshape(rows, cols),
        np.ascontiguousarray(y, dtype=np.float32).reshape(rows, cols),
        cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float(outside),
    )
    return np.asarray(out, dtype=np.float32).reshape(shape)


def _remap(
    field: NDArray[np.float32] | NDArray[np.uint16],
    grid: NDArray[np.float32],
    interpolation: int,
    outside: float,
) -> NDArray[np.float32] | NDArray[np.uint16]:
    """``cv2.remap`` of ``field`` at the points ``grid`` (shape (..., 2), float32), flat, in
    the field's type: the points as given when they fit OpenCV's sides, else in rows (a
    field too large for OpenCV: in windows, :func:`remap_points`)."""
    if max(field.shape) >= REMAP_SIDE:
        return remap_points(field, grid.reshape(-1, 2), interpolation, outside)
    count = math.prod(grid.shape[:-1])
    if grid.ndim == 2:
        grid = grid.reshape(1, -1, 2)
    if grid.ndim != 3 or max(grid.shape[:2]) >= 32_000:
        flat = grid.reshape(-1, 2)
        n, width = flat.shape[0], _ROW_POINTS
        grid = np.full((-(-n // width) * width, 2), -1e6, dtype=np.float32)
        grid[:n] = flat
        grid = grid.reshape(-1, width, 2)
    out = cv2.remap(  # type: ignore[call-overload]  # map2=None: map1 has both
        field,
        grid,
        None,
        interpolation,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float(outside),
    )
    samples = cast("NDArray[np.float32] | NDArray[np.uint16]", np.asarray(out).reshape(-1))
    return samples[:count]


def remap_points(
    field: NDArray[np.float32] | NDArray[np.uint16],
    xy: NDArray[np.float32],
    interpolation: int,
    outside: float,
    window: int = _WINDOW,
) -> NDArray[np.float32] | NDArray[np.uint16]:
    """``cv2.remap`` of a grid of any size at the points ``xy``, in the grid's type.

    OpenCV reads grids with sides under :data:`REMAP_SIDE` only. A sample reads the cells
    around its point alone, so a larger grid is read in windows: each point goes to the
    window of the first cell it reads (the floor of its coordinates; off the grid, the
    window at the nearest edge; NaN, the first), whose cells reach :data:`_WINDOW_MARGIN`
    past it, and is moved by the window's corner. The move is a multiple of ``window``, a
    power of two: exact in float32 (for coordinates under ``2**24``), and OpenCV splits the
    moved coordinate into the same fraction and the same whole part less the corner (it
    rounds half to even, which an even move keeps). So every sample is the one of the whole
    grid, bit for bit; a window's edges are the grid's wherever a point reads past them.
    (Where OpenCV makes NaN, for a coordinate or an ``outside`` that is not finite, it does
    so depending on the points beside it in its vectors; no caller of this package asks for
    such samples.)

    Parameters
    ----------
    field : ndarray of float32 or uint16, 2D
    xy : ndarray of float32, shape (N, 2)
        ``(x, y) = (column, row)`` coordinates.
    interpolation : int
        ``cv2.INTER_NEAREST`` or ``cv2.INTER_LINEAR``.
    outside : float
        The value of cells off the grid.
    window : int, optional
        Side of the windows: a power of two below ``REMAP_SIDE - _WINDOW_MARGIN``.

    Returns
    -------
    ndarray, shape (N,)
    """
    out = np.empty(xy.shape[0], dtype=field.dtype)
    if out.size == 0:
        return out
    h, w = field.shape
    across = -(-w // window)
    # each point's window, row by row; in 16 bits when they fit (numpy's stable sort of
    # them is then a radix sort)
    kind = np.dtype(np.uint16 if -(-h // window) * across < 1 << 16 else np.intp)
    key = _window_of(xy[:, 1], h, window).astype(kind)
    key *= across
    key += _window_of(xy[:, 0], w, window).astype(kind)
    groups: Sequence[NDArray[np.intp] | slice] = (slice(None),)  # one window: every point
    if int(key.min()) != int(key.max()):
        order = np.argsort(key, kind="stable")
        groups = np.split(order, np.flatnonzero(np.diff(key[order])) + 1)
    for idx in groups:
        wy, wx = divmod(int(key[idx][0]), across)
        r0, c0 = wy * window, wx * window
        rows = slice(r0, min(r0 + window + _WINDOW_MARGIN, h))
        cols = slice(c0, min(c0 + window + _WINDOW_MARGIN, w))
        moved = xy[idx] - np.array([c0, r0], dtype=np.float32)  # whole cells: exact
        out[idx] = _remap(field[rows, cols], moved, interpolation, outside)
    return out


def _window_of(v: NDArray[np.float32], side: int, window: int) -> NDArray[np.float32]:
    """The window (of ``window`` cells, a power of two, along an axis of ``side``) of the
    first cell each coordinate reads, as whole float32 numbers: off the axis, the window at
    the nearest end; NaN, the first."""
    k = np.multiply(v, np.float32(1.0 / window))  # exact: ``window`` is a power of two
    np.floor(k, out=k)
    np.clip(k, 0, (side - 1) // window, out=k)
    k[np.isnan(k)] = 0
    return k


def _whole_samples(
    field: NDArray[np.uint16], xy: NDArray[np.float32], outside: float, *, nearest: bool
) -> NDArray[np.float32]:
    """:func:`sample_at` of a ``uint16`` grid at the points ``xy`` (shape (N, 2)).

    A bilinear sample with a value off the grid that is not finite is taken from the whole
    grid in ``float32`` (OpenCV interpolates ``inf`` into NaN at points of the border, by an
    order of its own; no caller of this package asks for it)."""
    if not nearest:
        if not math.isfinite(outside):
            whole = field.astype(np.float32)
            return np.asarray(_remap(whole, xy, cv2.INTER_LINEAR, outside), dtype=np.float32)
        return _bilinear_whole(field, xy, np.float32(outside))
    cells = _remap(field, xy, cv2.INTER_NEAREST, _NO_CELL)  # the same cells, as uint16
    out = cells.astype(np.float32)
    out[cells == _NO_CELL] = outside
    return out


def _bilinear_whole(
    field: NDArray[np.uint16], xy: NDArray[np.float32], outside: np.float32
) -> NDArray[np.float32]:
    """OpenCV's bilinear samples of ``field`` as ``float32``, from small ``float32`` atlases.

    Each point's four cells are copied, as ``float32`` (``outside`` off the grid), into a
    patch of its own in a small atlas, and the point is moved onto its patch; one
    ``cv2.remap`` of the atlas gives the sample. OpenCV splits each coordinate into its
    whole part (``floor``) and its fraction (``x - floor(x)``) and interpolates the four
    values by the fractions; so the sample is the same if the moved point has the same
    fractions, and the same four values, bit for bit, as the original. For ``2**e <= x``,
    the moved coordinate ``p + (x - floor(x))`` (``p`` the patch's whole column) is exact in
    float32 when it stays under ``2**(e+1)``, where float32 is no coarser than at ``x``
    (``x - floor(x)`` is exact for ``x >= 1``): each point's bucket (:func:`_buckets`) caps
    its patch's column at ``2**(e+1) - 2``, and the same for rows. A coordinate below 1 (the
    first row or column, or the border just before it) is not moved at all, and its patch
    holds the first two rows or columns of the grid where they are. Points whose four cells
    are all off the grid take ``outside`` (OpenCV interpolates four ``outside`` values there,
    which gives ``outside`` for a finite one), and so do points with a coordinate that is
    not finite (OpenCV gives ``outside`` or NaN for them, depending on the points beside
    them in its vectors; no transform of this package gives such points).
    """
    h, w = field.shape
    x, y = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
    fx, fy = np.floor(x), np.floor(y)
    low = 1 << _TOP_BUCKET
    # most often every point is in the top bucket and its four cells on the grid (NaN fails)
    if min(fx.min(), fy.min()) >= low and fx.max() <= w - 1 and fy.max() <= h - 1:
        return _bucket_samples(field, (x, y, fx, fy), _TOP_BUCKET, _TOP_BUCKET, outside)
    out = np.full(x.shape, outside, dtype=np.float32)
    # OpenCV's test (NaN fails it): a cell of the four is on the grid
    near = (fx >= -1) & (fx <= w - 1) & (fy >= -1) & (fy <= h - 1)
    top = near & (fx >= low) & (fy >= low)
    if top.any():
        part = (x[top], y[top], fx[top], fy[top])
        out[top] = _bucket_samples(field, part, _TOP_BUCKET, _TOP_BUCKET, outside)
    rest = np.flatnonzero(near & ~top)
    if rest.size == 0:
        return out
    keys = _buckets(x[rest]) * (_TOP_BUCKET + 2) + _buckets(y[rest])
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    starts = np.flatnonzero(np.diff(sorted_keys, prepend=np.int16(-1)))
    ends = np.append(starts[1:], sorted_keys.size)
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        bx, by = divmod(int(sorted_keys[a]), _TOP_BUCKET + 2)
        idx = rest[order[a:b]]
        part = (x[idx], y[idx], fx[idx], fy[idx])
        out[idx] = _bucket_samples(field, part, bx - 1, by - 1, outside)
    return out


def _buckets(v: NDArray[np.float32]) -> NDArray[np.int16]:
    """Per coordinate, 0 below 1, else ``1 + min(e, _TOP_BUCKET)`` for ``2**e <= v < 2**(e+1)``."""
    _, e = np.frexp(np.maximum(v, np.float32(0.5)))  # v = m 2**e, 0.5 <= m < 1: e - 1 above 1
    return np.minimum(e, _TOP_BUCKET + 1).astype(np.int16)


#: Points as :func:`_bilinear_whole` passes them on: ``x``, ``y`` and their floors.
_Points = tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]


def _bucket_samples(
    field: NDArray[np.uint16], points: _Points, ex: int, ey: int, outside: np.float32
) -> NDArray[np.float32]:
    """:func:`_bilinear_whole` of the ``points`` of one bucket (``ex``, ``ey``: the
    exponents of their coordinates' powers of two, capped at :data:`_TOP_BUCKET`; -1 below
    1), in atlases of at most ``2**ex`` by ``2**ey`` patches (one patch, the grid's own
    first cells, in a direction below 1)."""
    x, y = points[0], points[1]
    cols = 1 if ex < 0 else 1 << ex
    rows = 1 if ey < 0 else 1 << ey
    if ex < 0 and ey < 0:  # every point reads the same patch: the grid's corner
        corner = np.empty((2, 2), dtype=np.float32)
        zero = np.zeros((1, 1), dtype=np.intp)
        _fill_patches(corner, field, zero, zero, outside)
        return np.asarray(_remap(corner, np.column_stack([x, y]), cv2.INTER_LINEAR, float(outside)))
    if x.size <= cols * rows:
        return _atlas_samples(field, points, (cols, rows), (ex < 0, ey < 0), outside)
    out = np.empty(x.shape, dtype=np.float32)
    for a in range(0, x.size, cols * rows):
        part = slice(a, a + cols * rows)
        chunk = (x[part], y[part], points[2][part], points[3][part])
        out[part] = _atlas_samples(field, chunk, (cols, rows), (ex < 0, ey < 0), outside)
    return out


def _atlas_samples(
    field: NDArray[np.uint16],
    points: _Points,
    capacity: tuple[int, int],
    keep: tuple[bool, bool],
    outside: np.float32,
) -> NDArray[np.float32]:
    """One atlas of :func:`_bilinear_whole`, of at most ``capacity`` (columns, rows)
    patches of two by two cells: point ``k`` reads the patch ``k`` (row ``k // cols``,
    column ``k % cols``); a direction ``keep`` (x, y) is not moved (one patch across, the
    grid's first two cells of it)."""
    x, y, fx, fy = points
    keep_x, keep_y = keep
    n = x.size
    cols = min(capacity[0], n)
    rows = -(-n // cols)
    # each patch's first cell in the grid; the last row of patches filled up with copies
    # of the last one (read by no point)
    ox = np.zeros(rows * cols, np.intp)
    oy = np.zeros(rows * cols, np.intp)
    if not keep_x:
        ox[:n] = fx
        ox[n:] = ox[n - 1]
    if not keep_y:
        oy[:n] = fy
        oy[n:] = oy[n - 1]
    atlas = np.empty((2 * rows, 2 * cols), dtype=np.float32)
    _fill_patches(atlas, field, oy.reshape(rows, cols), ox.reshape(rows, cols), outside)
    px, py = _slot_positions(cols, capacity[0] * capacity[1])
    grid = np.empty((n, 2), dtype=np.float32)
    # x - floor(x) is exact for x >= 1; the patch's column added is exact (see above)
    grid[:, 0] = x if keep_x else (x - fx) + px[:n]
    grid[:, 1] = y if keep_y else (y - fy) + py[:n]
    return np.asarray(_remap(atlas, grid, cv2.INTER_LINEAR, float(outside)), dtype=np.float32)


@lru_cache(maxsize=32)
def _slot_positions(cols: int, count: int) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """The first column and row, in an atlas, of each of ``count`` patches ``cols`` across
    (float32, read-only)."""
    slot = np.arange(count)
    px = (2 * (slot % cols)).astype(np.float32)
    py = (2 * (slot // cols)).astype(np.float32)
    px.flags.writeable = py.flags.writeable = False
    return px, py


def _fill_patches(
    atlas: NDArray[np.float32],
    field: NDArray[np.uint16],
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    outside: np.float32,
) -> None:
    """Fill the ``atlas`` of ``rows.shape`` patches: patch ``(i, j)`` holds the cells
    ``(rows[i, j] + dy, cols[i, j] + dx)`` of ``field``, ``dy, dx`` in ``(0, 1)``, as float32
    (``outside`` off the grid), at ``(2 i + dy, 2 j + dx)``."""
    h, w = field.shape
    flat = field.reshape(-1)  # a view: the maps of compact_distance_map are C-contiguous
    view = atlas.reshape(rows.shape[0], 2, rows.shape[1], 2)  # [i, dy, j, dx]
    base = rows * w + cols
    inside = rows.min() >= 0 and rows.max() < h - 1 and cols.min() >= 0 and cols.max() < w - 1
    for dy in (0, 1):
        for dx in (0, 1):
            if inside:  # one gather a corner, written in place
                view[:, dy, :, dx] = flat.take(base + (dy * w + dx))
                continue
            on = (rows + dy >= 0) & (rows + dy < h) & (cols + dx >= 0) & (cols + dx < w)
            corner = np.full(rows.shape, outside, dtype=np.float32)
            corner[on] = flat.take(base[on] + (dy * w + dx))
            view[:, dy, :, dx] = corner
