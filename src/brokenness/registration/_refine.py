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

__all__ = ["distance_field", "edges", "inlier_count", "refine_rigid", "sample"]

_BLOCK = 1024  # cv2.remap maps are laid out as rows of this many points


def edges(occupied: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Occupied cells with a non-occupied 4-neighbour (the outline of walls and obstacles).

    A wall one or two cells thick is all outline; a thick obstacle keeps only its rim. The
    refinement fits outlines because the inside of a blob is at distance 0 from the blob at
    many poses and would make the fit indifferent to small turns and shifts.
    """
    occ = occupied.view(np.uint8) if occupied.dtype == np.bool_ else occupied.astype(np.uint8)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    inner = cv2.erode(occ, cross, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return occupied & (inner == 0)


def distance_field(cells: NDArray[np.bool_]) -> NDArray[np.float32]:
    """Euclidean distance (cells) from every cell to the nearest True cell."""
    other = np.ascontiguousarray(~cells).view(np.uint8)  # non-zero: not one of the cells
    out = cv2.distanceTransform(other, cv2.DIST_L2, cv2.DIST_MASK_5)
    return np.asarray(out, dtype=np.float32)


def sample(
    field: NDArray[np.float32], xy: NDArray[np.float64], outside: float
) -> NDArray[np.float32]:
    """Bilinear samples of ``field`` at points ``xy`` (N, 2) = (col, row); ``outside`` off-map."""
    n = xy.shape[0]
    rows = -(-n // _BLOCK)
    maps = np.zeros((2, rows * _BLOCK), dtype=np.float32)
    maps[:, :n] = xy.T
    out = cv2.remap(
        field,
        maps[0].reshape(rows, _BLOCK),
        maps[1].reshape(rows, _BLOCK),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=outside,
    )
    return np.asarray(out, dtype=np.float32).reshape(-1)[:n]


def inlier_count(
    field: NDArray[np.float32],
    points: NDArray[np.float64],
    matrix: NDArray[np.float64],
    radius: float,
) -> int:
    """Number of ``points`` that ``matrix`` (3x3) puts within ``radius`` of an occupied cell."""
    q = points @ matrix[:2, :2].T + matrix[:2, 2]
    return int(np.count_nonzero(sample(field, q, radius + 1e3) <= radius))


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
    centre = points.mean(axis=0)
    cx = points[:, 0] - centre[0]
    cy = points[:, 1] - centre[1]
    theta = math.atan2(matrix[1, 0], matrix[0, 0])
    m = matrix[:2, :2] @ centre + matrix[:2, 2]
    params = np.array([theta, m[0], m[1]], dtype=np.float64)
    iterations = max(1, iterations)
    shrink = max(1, iterations // 2)
    radii = np.concatenate(
        [np.geomspace(start_radius, end_radius, shrink), np.full(iterations - shrink, end_radius)]
    )
    far = float(start_radius) + 1e3
    n = points.shape[0]
    rows = -(-n // _BLOCK)
    maps = np.zeros((2, 5, rows * _BLOCK), dtype=np.float32)
    for k, radius in enumerate(radii):
        c, s = math.cos(params[0]), math.sin(params[0])
        rx = c * cx - s * cy  # rotated, centred points
        ry = s * cx + c * cy
        qx = rx + params[1]
        qy = ry + params[2]
        # the point and its four neighbours (central differences) in one remap
        maps[0, :, :n] = qx
        maps[1, :, :n] = qy
        maps[0, 1, :n] += 1.0
        maps[0, 2, :n] -= 1.0
        maps[1, 3, :n] += 1.0
        maps[1, 4, :n] -= 1.0
        vals = cv2.remap(
            field,
            maps[0].reshape(-1, _BLOCK),
            maps[1].reshape(-1, _BLOCK),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=far,
        ).reshape(5, -1)[:, :n]
        keep = vals[0] < radius
        if np.count_nonzero(keep) < 3:
            break
        v = vals[:, keep].astype(np.float64)
        r = v[0]
        gx = 0.5 * (v[1] - v[2])
        gy = 0.5 * (v[3] - v[4])
        # d q / d theta is the rotated, centred point turned by 90 degrees
        jac = np.stack([gy * rx[keep] - gx * ry[keep], gx, gy])
        a = jac @ jac.T
        b = jac @ r
        if not np.any(b):
            break
        a += np.diag(np.maximum(np.diag(a), 1e-9) * 1e-6)
        try:
            step = np.linalg.solve(a, -b)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)):
            break
        params = params + step
        # converged: the last step moved every point by about 0.01 cell or less
        if k >= shrink and abs(step[0]) < 1e-5 and abs(step[1]) < 1e-2 and abs(step[2]) < 1e-2:
            break
    theta, mx, my = params
    c, s = math.cos(theta), math.sin(theta)
    rot = np.array([[c, -s], [s, c]])
    t = np.array([mx, my]) - rot @ centre
    out = np.eye(3)
    out[:2, :2] = rot
    out[:2, 2] = t
    return out
