"""Maps as users have them: a run drawn in its own frame, cropped; a floor-plan reference.

:func:`map_in_frame` draws a run's scans (with any pose estimate, e.g. bumped) in another
world frame -- the SLAM run "started anywhere": the whole map turned and shifted by a rigid
``frame`` -- on a grid cropped to what the scans saw, three-state (free by ray casting,
unknown elsewhere), and labels each occupied cell with the segment of the run whose scans hit
it most often (the partitions of :mod:`brokenness.simulation.ground_truth`).

:func:`plan_map` rasterises a synthetic building's plan (:attr:`Building.grid`) as a
reference: every wall and clutter object occupied, including walls the robot never saw, the
rest of the building free, the margin around it unknown.

The ground truth of a partition drawn with world error ``E_j`` in frame ``F`` is, from a cell
of the map of :func:`map_in_frame` to a cell of a reference ``R``:
``W_R^-1 o E_j^-1 o F^-1 o W_map`` (``W`` = :meth:`~brokenness.OccupancyMap.
cell_to_world_matrix`); :func:`frame_truth` computes it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ParameterError
from ..grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from ..transform import RigidTransform
from .building import Building
from .mapper import counts_to_map, grid_geometry, scan_counts, segment_labels

__all__ = ["frame_truth", "map_in_frame", "plan_map"]


def _moved(poses: NDArray[np.float64], frame: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.empty_like(poses)
    out[:, :2] = poses[:, :2] @ frame[:2, :2].T + frame[:2, 2]
    out[:, 2] = poses[:, 2] + math.atan2(frame[1, 0], frame[0, 0])
    out[:, 2] = np.remainder(out[:, 2] + math.pi, 2 * math.pi) - math.pi
    return out


def map_in_frame(
    poses: ArrayLike,
    ranges: ArrayLike,
    angles: ArrayLike,
    *,
    max_range: float,
    resolution: float,
    frame: ArrayLike | None = None,
    segment: ArrayLike | None = None,
    margin: float = 0.5,
) -> tuple[OccupancyMap, NDArray[np.int16]]:
    """Map scans drawn from ``frame`` o ``poses`` on a grid cropped to what they saw.

    Parameters
    ----------
    poses : array_like, shape (N, 3)
        Laser poses (world ``x, y, theta``) the scans are drawn with.
    ranges : array_like, shape (N, B)
        Readings; ``0 < r < max_range`` are hits, ``r <= 0`` ignored (the mapper's rules).
    angles : array_like, shape (B,)
        Beam directions relative to the laser's heading, radians.
    max_range : float
        Metres.
    resolution : float
        Metres per cell of the map.
    frame : array_like 3x3, optional
        Rigid world matrix applied to every pose (default identity).
    segment : array_like of int, shape (N,), optional
        Segment of each scan (default all 0); labels follow the most hits per cell.
    margin : float
        Metres around the bounding box of the hits and the poses.

    Returns
    -------
    (OccupancyMap, ndarray of int16)
        The map (origin on a multiple of ``resolution``, yaw 0) and, per cell, the segment
        whose scans hit it most often (first on ties) where occupied, -1 elsewhere.
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(ranges, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64)
    if r.shape != (len(p), len(a)):
        raise ParameterError(f"ranges must have shape {(len(p), len(a))}, got {r.shape}")
    f = np.eye(3) if frame is None else np.asarray(frame, dtype=np.float64)
    seg = np.zeros(len(p), np.int64) if segment is None else np.asarray(segment, np.int64)
    moved = _moved(p, f)
    hit = np.isfinite(r) & (r > 0) & (r < max_range)
    heading = moved[:, 2:3] + a[None, :]
    ends = np.stack(
        [moved[:, 0:1] + r * np.cos(heading), moved[:, 1:2] + r * np.sin(heading)], axis=-1
    )[hit]
    shape, origin = grid_geometry(np.concatenate([ends, moved[:, :2]]), resolution, margin)
    counts = scan_counts(
        moved, r, a, max_range=max_range, resolution=resolution, shape=shape, origin=origin
    )
    m = counts_to_map(counts)
    return m, segment_labels(moved, r, a, seg, m, max_range=max_range)


def frame_truth(
    map_: OccupancyMap,
    reference: OccupancyMap,
    error: ArrayLike,
    frame: ArrayLike | None = None,
) -> RigidTransform:
    """True transform (map cell -> reference cell) of a partition drawn with world error.

    ``W_ref^-1 o error^-1 o frame^-1 o W_map``, with its world part ``error^-1 o frame^-1``
    (map metres -> reference metres). Both maps need a resolution and an origin.
    """
    e = np.asarray(error, dtype=np.float64)
    f = np.eye(3) if frame is None else np.asarray(frame, dtype=np.float64)
    m = (
        np.linalg.inv(reference.cell_to_world_matrix())
        @ np.linalg.inv(e)
        @ np.linalg.inv(f)
        @ map_.cell_to_world_matrix()
    )
    return RigidTransform.from_matrix(m).with_world(map_, reference)


def plan_map(building: Building, resolution: float, *, margin: float = 0.5) -> OccupancyMap:
    """The building's plan as a reference map: walls and clutter occupied, inside free.

    A cell is occupied when the centre of any cell of :attr:`Building.grid` that is solid lies
    in it, free when it lies inside the building's outer box and holds nothing solid, unknown
    in the ``margin`` around the box. The grid is that of :func:`simulate_broken_map`'s
    reference at this resolution (the box ``[0, width] x [0, height]`` plus ``margin``, corner
    on a multiple of the resolution), so a plan and a true-pose reference share cells.
    """
    if not (math.isfinite(resolution) and resolution > 0):
        raise ParameterError(f"resolution must be a positive number, got {resolution!r}")
    shape, origin = grid_geometry(
        [[0.0, 0.0], [building.width, building.height]], resolution, margin=margin
    )
    rows, cols = shape
    tr = building.truth_resolution
    g_rows = building.grid.shape[0]
    rr, cc = np.nonzero(building.grid)
    x = (cc + 0.5) * tr
    y = (g_rows - rr - 0.5) * tr
    col = np.floor((x - origin[0]) / resolution).astype(np.int64)
    row = rows - 1 - np.floor((y - origin[1]) / resolution).astype(np.int64)
    ok = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
    states = np.full(shape, UNKNOWN, dtype=np.int8)
    # cell centres inside the building's box are free, then the solid ones occupied
    cx = origin[0] + (np.arange(cols) + 0.5) * resolution
    cy = origin[1] + (rows - np.arange(rows) - 0.5) * resolution
    inside = ((cy >= 0) & (cy <= building.height))[:, None] & ((cx >= 0) & (cx <= building.width))[
        None, :
    ]
    states[inside] = FREE
    states[row[ok], col[ok]] = OCCUPIED
    return OccupancyMap(states, resolution, origin, "plan")
