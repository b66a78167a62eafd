"""Full-resolution refinement of a rigid transform on the reference's distance map.

The spectral stage of iFMI works on a reduced image for speed; its estimate is then polished
here at full resolution: the outline cells of the moving map's occupied cells (a
deterministic subsample) are moved by the transform and the sum of their Euclidean
distances to the nearest outline cell of the reference is minimised by Gauss-Newton (a
point-to-distance-field ICP, as in chamfer matching). Only points closer than a threshold
count, and the threshold shrinks over the iterations, so the part of the map that agrees
with the reference drives the fit and the rest (other partitions, clutter) is ignored --
what the recursion of Algorithm 1 needs.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from .._points import take_rows
from ..masking.distance import sample_at, sample_xy

__all__ = [
    "distance_field",
    "edge_distance_field",
    "edge_points",
    "edges",
    "inlier_count",
    "inlier_counts",
    "outline_distance_field",
    "refine_rigid",
    "refine_rigid_many",
]


def edges(occupied: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Occupied cells with a non-occupied 4-neighbour (the outline of walls and obstacles).

    A wall one or two cells thick is all outline; a thick obstacle keeps only its rim. The
    refinement fits outlines because the inside of a blob is at distance 0 from the blob at
    many poses and would make the fit indifferent to small turns and shifts.
    """
    return _edges_u8(occupied).view(np.bool_)


def _edges_u8(occupied: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """:func:`edges` as 0/1 bytes (a fresh array; the input may be a view of a larger grid)."""
    occ = occupied.view(np.uint8) if occupied.dtype == np.bool_ else (occupied != 0).view(np.uint8)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    inner = cv2.erode(occ, cross, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    # the erosion lies inside the cells (the cross holds its centre): cells less it, in place
    return np.asarray(cv2.subtract(occ, inner, dst=inner), dtype=np.uint8)


def edge_points(
    occupied: NDArray[np.bool_], cells: NDArray[np.int32] | None = None
) -> NDArray[np.int32]:
    """``(x, y)`` of the cells of :func:`edges`, row by row, shape (N, 2).

    The occupied cells are listed once (one fast scan; or given as ``cells``, their
    ``(x, y)`` row by row, as the scan lists them) and each is tested by looking up its four
    neighbours (cells off the grid are not occupied, as for :func:`edges`): the cost beyond
    the scan follows the cells, and there is no temporary of the grid's size.
    """
    occ = np.ascontiguousarray(occupied, dtype=np.bool_)
    h, w = occ.shape
    if cells is None:
        found = cv2.findNonZero(occ.view(np.uint8))
        if found is None:
            return np.zeros((0, 2), dtype=np.int32)
        xy = np.asarray(found, dtype=np.int32).reshape(-1, 2)
    elif cells.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.int32)
    else:
        xy = np.ascontiguousarray(cells, dtype=np.int32)
    x, y = xy[:, 0], xy[:, 1]
    flat = occ.reshape(-1)
    at = y.astype(np.intp) * w + x
    last = flat.size - 1
    # a cell on the grid's edge has a neighbour off it; the clipped look-ups of such cells
    # are not used
    inner = (x > 0) & (x < w - 1) & (y > 0) & (y < h - 1)
    inner &= flat[np.maximum(at - 1, 0)] & flat[np.minimum(at + 1, last)]
    inner &= flat[np.maximum(at - w, 0)] & flat[np.minimum(at + w, last)]
    return take_rows(xy, ~inner)


def edge_distance_field(occupied: NDArray[np.bool_]) -> NDArray[np.float32]:
    """``distance_field(edges(occupied))``, with one temporary grid of bytes, not three."""
    outline = _edges_u8(occupied)
    np.bitwise_xor(outline, 1, out=outline)  # non-zero: not an outline cell
    out = cv2.distanceTransform(outline, cv2.DIST_L2, cv2.DIST_MASK_5)
    return np.asarray(out, dtype=np.float32)


def outline_distance_field(
    outline: NDArray[np.int32], shape: tuple[int, int]
) -> NDArray[np.float32]:
    """:func:`distance_field` of a ``shape`` grid whose True cells are ``outline``.

    Parameters
    ----------
    outline : ndarray of int32, shape (N, 2)
        ``(x, y)`` of the cells (inside the grid), as :func:`edge_points` lists them.
    shape : (int, int)
        ``(rows, cols)`` of the grid.

    Returns
    -------
    ndarray of float32
        ``shape``: the same values as :func:`edge_distance_field` of occupied cells whose
        :func:`edges` are ``outline``, from one grid of bytes marked at the cells.
    """
    rows, cols = shape
    other = np.ones(rows * cols, dtype=np.uint8)  # non-zero: not an outline cell
    other[outline[:, 1].astype(np.intp) * cols + outline[:, 0]] = 0
    out = cv2.distanceTransform(other.reshape(rows, cols), cv2.DIST_L2, cv2.DIST_MASK_5)
    return np.asarray(out, dtype=np.float32)


def distance_field(cells: NDArray[np.bool_]) -> NDArray[np.float32]:
    """Euclidean distance (cells) from every cell to the nearest True cell."""
    other = np.ascontiguousarray(~cells).view(np.uint8)  # non-zero: not one of the cells
    out = cv2.distanceTransform(other, cv2.DIST_L2, cv2.DIST_MASK_5)
    return np.asarray(out, dtype=np.float32)


def inlier_count(
    field: NDArray[np.float32],
    points: NDArray[np.float64],
    matrix: NDArray[np.float64],
    radius: float,
) -> int:
    """Number of ``points`` that ``matrix`` (3x3) puts within ``radius`` of an occupied cell."""
    q = points @ matrix[:2, :2].T + matrix[:2, 2]
    return int(np.count_nonzero(sample_at(field, q, radius + 1e3) <= radius))


def inlier_counts(
    field: NDArray[np.float32],
    points: NDArray[np.float64],
    matrices: list[NDArray[np.float64]],
    radius: float,
) -> list[int]:
    """:func:`inlier_count` of ``points`` under each of ``matrices``, in one lookup."""
    if not matrices:
        return []
    stack = np.asarray(matrices, dtype=np.float64)
    q = np.matmul(points, stack[:, :2, :2].transpose(0, 2, 1)) + stack[:, None, :2, 2]
    near = sample_at(field, q, radius + 1e3) <= radius  # (len(matrices), N)
    return [int(c) for c in np.count_nonzero(near, axis=1)]


def refine_rigid(
    field: NDArray[np.float32],
    points: NDArray[np.float64],
    matrix: NDArray[np.float64],
    *,
    start_radius: float,
    end_radius: float,
    iterations: int,
) -> NDArray[np.float64]:
    """Gauss-Newton refinement of the rigid ``matrix`` (3x3) mapping ``points`` into ``field``.

    Parameters
    ----------
    field : ndarray of float32
        :func:`distance_field` of the reference.
    points : ndarray, shape (N, 2)
        Occupied cells of the moving map, ``(x, y)``.
    matrix : ndarray, shape (3, 3)
        Initial rigid transform.
    start_radius, end_radius : float
        Inlier threshold (cells) of the first and last iteration (geometric schedule).
    iterations : int
        Number of Gauss-Newton steps.

    Returns
    -------
    ndarray, shape (3, 3)
        The refined rigid transform (the initial one if no point is an inlier).
    """
    out = refine_rigid_many(
        field,
        points,
        [matrix],
        start_radius=start_radius,
        end_radius=end_radius,
        iterations=iterations,
    )
    return out[0]


def refine_rigid_many(
    field: NDArray[np.float32],
    points: NDArray[np.float64],
    matrices: list[NDArray[np.float64]],
    *,
    start_radius: float,
    end_radius: float,
    iterations: int,
) -> list[NDArray[np.float64]]:
    """:func:`refine_rigid` of several starting transforms of the same points at once.

    Each iteration samples the field for every transform still moving in one lookup; a
    transform stops, as in :func:`refine_rigid`, when it has fewer than 3 inliers, its
    system is singular or its step has converged.
    """
    k_all = len(matrices)
    if k_all == 0:
        return []
    n = points.shape[0]
    centre = points.mean(axis=0)
    cx = points[:, 0] - centre[0]
    cy = points[:, 1] - centre[1]
    # each transform's angle and where it puts the centre, as Python floats (updated one
    # transform at a time below: numpy's scalar indexing would cost more than the algebra)
    c0, c1 = float(centre[0]), float(centre[1])
    theta = [math.atan2(m[1, 0], m[0, 0]) for m in matrices]
    mx = [float(m[0, 0]) * c0 + float(m[0, 1]) * c1 + float(m[0, 2]) for m in matrices]
    my = [float(m[1, 0]) * c0 + float(m[1, 1]) * c1 + float(m[1, 2]) for m in matrices]
    iterations = max(1, iterations)
    shrink = max(1, iterations // 2)
    # inlier radius: geometric from start to end over the first half, then constant
    ratio = end_radius / start_radius
    radii = [
        start_radius * ratio ** (k / max(shrink - 1, 1)) if k < shrink else end_radius
        for k in range(iterations)
    ]
    far = float(start_radius) + 1e3
    active = list(range(k_all))  # the transforms still moving
    # per transform, each point and its four neighbours (central differences), all sampled
    # in one lookup: their columns and rows as two planes (no interleaving of the points)
    plane_x = np.empty((k_all, 5, n), dtype=np.float32)
    plane_y = np.empty((k_all, 5, n), dtype=np.float32)
    normal = np.empty((k_all, 4, n))  # per transform, the rows of its normal equations
    for k, radius in enumerate(radii):
        if not active:
            break
        a = len(active)
        angles = np.array([theta[h] for h in active])
        c = np.cos(angles)[:, None]
        s = np.sin(angles)[:, None]
        rx = c * cx - s * cy  # (a, n) rotated, centred points
        ry = s * cx + c * cy
        _neighbours(rx + np.array([mx[h] for h in active])[:, None], plane_x[:a], (1, 2))
        _neighbours(ry + np.array([my[h] for h in active])[:, None], plane_y[:a], (3, 4))
        vals = sample_xy(field, plane_x[:a], plane_y[:a], far)  # (a, 5, n)
        keep = vals[:, 0] < radius  # (a, n)
        counts = np.count_nonzero(keep, axis=1)
        w = keep.astype(np.float64)
        rows = normal[:a]  # (a, 4, n): d/d theta, d/dx, d/dy and the residual
        # in float64 from the float32 samples (each converted exactly, as by astype)
        np.multiply(vals[:, 0], w, out=rows[:, 3])
        gx = np.multiply(0.5 * _difference(vals[:, 1], vals[:, 2]), w, out=rows[:, 1])
        gy = np.multiply(0.5 * _difference(vals[:, 3], vals[:, 4]), w, out=rows[:, 2])
        # d q / d theta is the rotated, centred point turned by 90 deg
        np.subtract(gy * rx, gx * ry, out=rows[:, 0])
        # per transform, the 3x3 normal matrix and the right-hand side, as one batched product
        sums = np.matmul(rows[:, :3], rows.transpose(0, 2, 1)).tolist()  # (a, 3, 4)
        still = []
        for h, inliers, system in zip(active, counts.tolist(), sums, strict=True):
            if inliers < 3:
                continue
            (a00, a01, a02, b0), (_, a11, a12, b1), (_, _, a22, b2) = system
            if b0 == 0.0 and b1 == 0.0 and b2 == 0.0:
                continue
            # Levenberg-style damping of the diagonal, then Cramer's rule for the 3x3 system
            # (small-matrix algebra on Python floats: numpy's per-call overhead would dominate)
            a00 += max(a00, 1e-9) * 1e-6
            a11 += max(a11, 1e-9) * 1e-6
            a22 += max(a22, 1e-9) * 1e-6
            step = _solve3(a00, a01, a02, a11, a12, a22, -b0, -b1, -b2)
            if step is None:
                continue
            d_theta, d_x, d_y = step
            theta[h] += d_theta
            mx[h] += d_x
            my[h] += d_y
            # converged: the last step moved every point by about 0.01 cell or less
            if k >= shrink and abs(d_theta) < 1e-5 and abs(d_x) < 1e-2 and abs(d_y) < 1e-2:
                continue
            still.append(h)
        active = still
    out = []
    for h in range(k_all):
        c, s = math.cos(theta[h]), math.sin(theta[h])
        rot = np.array([[c, -s], [s, c]])
        t = np.array([mx[h], my[h]]) - rot @ centre
        m = np.eye(3)
        m[:2, :2] = rot
        m[:2, 2] = t
        out.append(m)
    return out


def _difference(a: NDArray[np.float32], b: NDArray[np.float32]) -> NDArray[np.float64]:
    """``a - b`` in float64 (both converted exactly first, without a float64 copy)."""
    return np.subtract(a, b, dtype=np.float64)


def _neighbours(
    centre: NDArray[np.float64], out: NDArray[np.float32], along: tuple[int, int]
) -> None:
    """One coordinate of the points of :func:`refine_rigid_many` and of their four
    neighbours: ``out[:, q]`` (shape (a, n)) is ``centre`` in float32, one cell more for
    ``q = along[0]`` and one less for ``q = along[1]`` (each added in float32 to the
    rounded centre), for the neighbours of the other axis ``centre`` itself."""
    base = out[:, 0]
    base[...] = centre
    for q in range(1, 5):
        if q == along[0]:
            np.add(base, np.float32(1.0), out=out[:, q])
        elif q == along[1]:
            np.subtract(base, np.float32(1.0), out=out[:, q])
        else:
            out[:, q] = base


def _solve3(
    a00: float,
    a01: float,
    a02: float,
    a11: float,
    a12: float,
    a22: float,
    b0: float,
    b1: float,
    b2: float,
) -> tuple[float, float, float] | None:
    """Solve the symmetric 3x3 system ``A x = b`` by Cramer's rule (None if singular)."""
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    if not math.isfinite(det) or abs(det) < 1e-300:
        return None
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    x0 = (c00 * b0 + c01 * b1 + c02 * b2) / det
    x1 = (c01 * b0 + c11 * b1 + c12 * b2) / det
    x2 = (c02 * b0 + c12 * b1 + c22 * b2) / det
    if not (math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2)):
        return None
    return x0, x1, x2
