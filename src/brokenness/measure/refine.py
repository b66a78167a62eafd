"""Local refinement of a registration: iterative closest points on the occupied cells.

Spectral registration is accurate to a fraction of a degree; far from the rotation centre
that can still be more than the masking threshold. A few ICP iterations against the
reference's occupied cells, with a shrinking correspondence gate, remove that residual
before the map is masked. Each iteration is a KD-tree query and a closed-form 2D Procrustes
fit (no Python loop over cells).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..transform import RigidTransform

__all__ = ["fit_rigid", "refine_transform"]


def fit_rigid(source: NDArray[np.float64], target: NDArray[np.float64]) -> RigidTransform:
    """Least-squares rigid transform taking ``source`` points onto ``target`` (2D Kabsch).

    Parameters
    ----------
    source, target : ndarray, shape (N, 2)
        Corresponding points, ``N >= 2``.

    Returns
    -------
    RigidTransform
        ``t`` minimising ``sum |t(source) - target|^2``.
    """
    cs = source.mean(axis=0)
    ct = target.mean(axis=0)
    s = source - cs
    t = target - ct
    cross = float(np.sum(s[:, 0] * t[:, 1] - s[:, 1] * t[:, 0]))
    dot = float(np.sum(s[:, 0] * t[:, 0] + s[:, 1] * t[:, 1]))
    angle = math.atan2(cross, dot)
    c, si = math.cos(angle), math.sin(angle)
    tx = ct[0] - (c * cs[0] - si * cs[1])
    ty = ct[1] - (si * cs[0] + c * cs[1])
    return RigidTransform(angle, tx, ty)


def refine_transform(
    transform: RigidTransform,
    points: NDArray[np.float64],
    tree: cKDTree,
    *,
    gate: float,
    final_gate: float,
    iterations: int = 8,
    max_points: int = 4000,
) -> RigidTransform:
    """Refine ``transform`` so that ``points`` land closer to the reference cells in ``tree``.

    Parameters
    ----------
    transform : RigidTransform
        Starting estimate, map cells -> reference cells (scale 1).
    points : ndarray, shape (N, 2)
        Occupied map cells to align (others' cells may be among them: the gate rejects them).
    tree : cKDTree
        Index of the occupied reference cells.
    gate : float
        Correspondences farther than this (cells) are ignored in the first iteration...
    final_gate : float
        ...shrinking linearly to this one in the last.
    iterations : int
        Number of ICP iterations.
    max_points : int
        At most this many points take part, picked by a fixed stride (deterministic).

    Returns
    -------
    RigidTransform
        The refined transform, or ``transform`` itself if too few correspondences were found.
    """
    if points.shape[0] > max_points:
        stride = int(math.ceil(points.shape[0] / max_points))
        points = points[::stride]
    current = transform
    for i in range(iterations):
        g = gate + (final_gate - gate) * (i / max(iterations - 1, 1))
        moved = current.apply(points)
        dist, idx = tree.query(moved, k=1, distance_upper_bound=g)
        inliers = np.isfinite(dist)
        if np.count_nonzero(inliers) < 3:
            break
        step = fit_rigid(moved[inliers], tree.data[idx[inliers]])
        current = step.compose(current)
        if abs(step.rotation) < 1e-7 and math.hypot(step.tx, step.ty) < 1e-5:
            break
    return current
