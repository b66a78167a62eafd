"""A vectorised log-odds occupancy-grid mapper for 2D laser scans.

Every beam of every scan is handled at once (in memory-bounded chunks): the cell of each
beam's end point collects a *hit*, and the cells the beam crosses before it collect a
*miss* (free space). Each beam counts at most once per cell. The log-odds of a cell is
``hits * hit_logodds + misses * miss_logodds`` (the log-odds prior 0, no clamping), and
its state is :data:`~brokenness.OCCUPIED` at or above ``occupied_logodds``,
:data:`~brokenness.FREE` at or below ``free_logodds``, else :data:`~brokenness.UNKNOWN`.

Geometry is the one of :class:`~brokenness.OccupancyMap`: ``origin = (x, y, yaw)`` is the
world pose of the lower-left corner of the grid, row 0 is the top row, and cell
``(col, row)`` covers ``x in [col*res, (col+1)*res)`` and
``y in [(rows-1-row)*res, (rows-row)*res)`` of the map frame.

Input conventions (shared with :mod:`brokenness.simulation.carmen`):

- ``poses``: shape (N, 3), world ``x, y, theta`` (metres, radians) of the *laser*;
- ``ranges``: shape (N, B), metres. A value ``>= max_range`` or non-finite is *no hit*:
  the beam still clears free space up to ``max_range``. A value ``<= 0`` is an invalid
  reading and is ignored entirely;
- ``angles``: shape (B,), radians, beam directions relative to the laser's heading.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ParameterError
from ..grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from ..limits import check_cells

__all__ = [
    "DEFAULT_FREE_LOGODDS",
    "DEFAULT_HIT_LOGODDS",
    "DEFAULT_MISS_LOGODDS",
    "DEFAULT_OCCUPIED_LOGODDS",
    "ScanCounts",
    "counts_to_map",
    "grid_geometry",
    "map_prefixes",
    "map_scans",
    "scan_counts",
    "segment_labels",
]

#: Log-odds added to a cell by each beam ending in it (p = 0.7).
DEFAULT_HIT_LOGODDS: float = 0.85
#: Log-odds added to a cell by each beam crossing it (p = 0.4).
DEFAULT_MISS_LOGODDS: float = -0.4
#: A cell is occupied at or above this log-odds (p = 0.65, ROS ``map_saver``'s threshold).
DEFAULT_OCCUPIED_LOGODDS: float = 0.619
#: A cell is free at or below this log-odds (p = 0.4: one clean miss is enough).
DEFAULT_FREE_LOGODDS: float = -0.4

# samples per chunk of the free-space pass (small enough to stay in cache)
_CHUNK_SAMPLES = 1 << 18
# free cells gathered before one np.bincount over the whole grid
_FLUSH_CELLS = 1 << 22
# samples of one beam before the grid clips it: far beyond any grid, within an int64
_MAX_SAMPLES = float(2**53)


@dataclass(frozen=True, eq=False)
class ScanCounts:
    """Per-cell counts of beam end points (``hits``) and beams crossing (``misses``).

    Both are int32 arrays of the grid's shape (rows, cols); ``dropped_hits`` counts beam end
    points that fell outside the grid.
    """

    hits: NDArray[np.int32]
    misses: NDArray[np.int32]
    resolution: float
    origin: tuple[float, float, float]
    dropped_hits: int


def _check_inputs(
    poses: ArrayLike,
    ranges: ArrayLike,
    angles: ArrayLike,
    max_range: float,
    resolution: float,
    shape: tuple[int, int],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    p = np.asarray(poses, dtype=float)
    r = np.asarray(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ParameterError(f"poses must have shape (N, 3), got {p.shape}")
    if a.ndim != 1:
        raise ParameterError(f"angles must have shape (B,), got {a.shape}")
    if r.shape != (p.shape[0], a.shape[0]):
        raise ParameterError(
            f"ranges must have shape (N, B) = ({p.shape[0]}, {a.shape[0]}), got {r.shape}"
        )
    if not np.isfinite(p).all() or not np.isfinite(a).all():
        raise ParameterError("poses and angles must be finite")
    if not (math.isfinite(max_range) and max_range > 0):
        raise ParameterError(f"max_range must be a positive number, got {max_range!r}")
    if not (math.isfinite(resolution) and resolution > 0):
        raise ParameterError(f"resolution must be a positive number, got {resolution!r}")
    if len(shape) != 2 or min(shape) < 1:
        raise ParameterError(f"shape must be (rows, cols) with positive sides, got {shape!r}")
    return p, r, a


def grid_geometry(
    points_xy: ArrayLike, resolution: float, margin: float = 1.0
) -> tuple[tuple[int, int], tuple[float, float, float]]:
    """Size a grid around world points (a trajectory, beam end points).

    The grid covers the bounding box of ``points_xy`` plus ``margin`` metres on every side;
    its lower-left corner lies on a multiple of ``resolution`` (so that grids of the same
    resolution made this way share cell boundaries).

    Parameters
    ----------
    points_xy : array_like, shape (N, 2)
        World points, metres; non-finite rows are ignored.
    resolution : float
        Metres per cell.
    margin : float
        Metres added on every side.

    Returns
    -------
    shape : tuple of int
        ``(rows, cols)``.
    origin : tuple of float
        ``(x, y, 0.0)``: world position of the lower-left corner.

    Raises
    ------
    ParameterError
        Without a finite point, or for a non-positive resolution / negative margin.
    MapSizeError
        If the grid would have more than :func:`brokenness.limits.max_cells` cells (points
        spread too far for the resolution).

    Examples
    --------
    >>> grid_geometry([[0.0, 0.0], [1.0, 2.0]], 0.1, margin=0.5)
    ((30, 20), (-0.5, -0.5, 0.0))
    """
    if not (math.isfinite(resolution) and resolution > 0):
        raise ParameterError(f"resolution must be a positive number, got {resolution!r}")
    if not (math.isfinite(margin) and margin >= 0):
        raise ParameterError(f"margin must be a non-negative number, got {margin!r}")
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        raise ParameterError("grid_geometry needs at least one finite point")
    with np.errstate(over="ignore", invalid="ignore"):  # far points: refused just below
        lo = np.floor((pts.min(axis=0) - margin) / resolution + 1e-9)
        hi = np.ceil((pts.max(axis=0) + margin) / resolution - 1e-9)
        span = np.maximum(hi - lo, 1)
    check_cells(float(span[1]), float(span[0]), f"a grid at {resolution:g} m per cell")
    cols, rows = (int(v) for v in span)
    # rounded to nanometres, so that e.g. -117 * 0.05 is written as -5.85
    x0, y0 = (round(float(v * resolution), 9) for v in lo)
    return (rows, cols), (x0, y0, 0.0)


def _to_cells(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    resolution: float,
    origin: tuple[float, float, float],
    shape: tuple[int, int],
) -> NDArray[np.int64]:
    """Flat cell index of world points; -1 outside the grid."""
    ox, oy, yaw = origin
    dx, dy = x - ox, y - oy
    if yaw != 0.0:
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = c * dx + s * dy, -s * dx + c * dy
    rows, cols = shape
    col = np.floor(dx / resolution).astype(np.int64)
    row = rows - 1 - np.floor(dy / resolution).astype(np.int64)
    inside = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
    return np.where(inside, row * cols + col, -1)


def scan_counts(
    poses: ArrayLike,
    ranges: ArrayLike,
    angles: ArrayLike,
    *,
    max_range: float,
    resolution: float,
    shape: tuple[int, int],
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    step: float = 0.5,
    free_space: bool = True,
) -> ScanCounts:
    """Count beam end points and beam crossings per cell, all beams vectorised.

    Parameters
    ----------
    poses, ranges, angles
        The scans; see the module docstring for the conventions.
    max_range : float
        Metres; readings at or beyond it (or non-finite) are no hits and clear free space up
        to ``max_range``.
    resolution : float
        Metres per cell.
    shape : tuple of int
        ``(rows, cols)`` of the grid.
    origin : tuple of float
        World pose ``(x, y, yaw)`` of the grid's lower-left corner.
    step : float
        Sampling step along each beam, in cells (at most 0.5 is sensible).
    free_space : bool
        If False, only hits are counted (``misses`` stays zero); much faster.

    Returns
    -------
    ScanCounts
        Points outside the grid are not counted (``dropped_hits`` says how many end points).
    """
    p, r, a = _check_inputs(poses, ranges, angles, max_range, resolution, shape)
    if not (math.isfinite(step) and 0 < step <= 1):
        raise ParameterError(f"step must be in (0, 1] cells, got {step!r}")
    origin = (float(origin[0]), float(origin[1]), float(origin[2]))
    rows, cols = int(shape[0]), int(shape[1])
    n_cells = rows * cols
    heading = (p[:, 2:3] + a[None, :]).ravel()
    cos, sin = np.cos(heading), np.sin(heading)
    bx = np.repeat(p[:, 0], a.shape[0])
    by = np.repeat(p[:, 1], a.shape[0])
    rr = r.ravel()
    with np.errstate(invalid="ignore"):
        valid = ~(rr <= 0)  # NaN stays valid (no hit, free up to max_range)
        is_hit = valid & np.isfinite(rr) & (rr < max_range)
    hit_cell = np.full(rr.shape, -1, dtype=np.int64)
    hit_cell[is_hit] = _to_cells(
        bx[is_hit] + rr[is_hit] * cos[is_hit],
        by[is_hit] + rr[is_hit] * sin[is_hit],
        resolution,
        origin,
        (rows, cols),
    )
    inside = hit_cell >= 0
    hits = np.bincount(hit_cell[inside], minlength=n_cells).astype(np.int32)
    dropped = int(np.count_nonzero(is_hit & ~inside))
    misses = np.zeros(n_cells, dtype=np.int64)
    if free_space:
        # march in cell units of the map frame, float32: fx = column, fy = rows - row
        ox, oy, yaw = origin
        c, s = math.cos(yaw), math.sin(yaw)
        fx0 = ((c * (bx - ox) + s * (by - oy)) / resolution).astype(np.float32)
        fy0 = ((-s * (bx - ox) + c * (by - oy)) / resolution).astype(np.float32)
        dfx = (np.cos(heading - yaw) * step).astype(np.float32)
        dfy = (np.sin(heading - yaw) * step).astype(np.float32)
        length = np.where(is_hit, rr, max_range)
        length = np.where(valid, length, 0.0)
        # capped (any huge max_range): the grid clips every beam below just after
        n_samples = np.ceil(np.minimum(length / (step * resolution), _MAX_SAMPLES))
        n_samples = n_samples.astype(np.int64)
        # clip every beam to the grid (sample k lies at fx0 + k * dfx, fy0 + k * dfy), so
        # that no sample needs a bounds check: k_lo <= k <= k_hi, a hundredth of a cell inside
        k_lo = np.zeros(len(rr))
        k_hi = (n_samples - 1).astype(float)
        for f0, df, size in ((fx0, dfx, cols), (fy0, dfy, rows)):
            f0d, dfd = f0.astype(float), df.astype(float)
            with np.errstate(divide="ignore", invalid="ignore"):
                ka = (0.01 - f0d) / dfd
                kb = (size - 0.01 - f0d) / dfd
            moving = dfd != 0
            k_lo = np.where(moving, np.maximum(k_lo, np.minimum(ka, kb)), k_lo)
            k_hi = np.where(moving, np.minimum(k_hi, np.maximum(ka, kb)), k_hi)
            still_out = ~moving & ((f0d < 0.01) | (f0d > size - 0.01))
            k_hi = np.where(still_out, -1.0, k_hi)
        k_lo = np.ceil(k_lo).astype(np.int64)
        k_hi = np.floor(k_hi).astype(np.int64)
        n_samples = np.maximum(k_hi - k_lo + 1, 0)
        # beams sorted by length and marched in blocks of similar length: a 2D (beam, step)
        # block wastes little padding and needs no per-sample index arithmetic
        beams = np.flatnonzero(n_samples > 0)
        beams = beams[np.argsort(n_samples[beams], kind="stable")]
        lengths = n_samples[beams]
        hit32 = hit_cell.astype(np.int32)
        pending: list[NDArray[np.int32]] = []
        n_pending = 0
        start = 0
        while start < len(beams):
            stop = min(start + max(_CHUNK_SAMPLES // int(lengths[start]), 1), len(beams))
            while stop - start > 1 and (stop - start) * int(lengths[stop - 1]) > _CHUNK_SAMPLES:
                stop = start + max((stop - start) // 2, 1)
            sel = beams[start:stop]
            width = int(lengths[stop - 1])
            steps = np.arange(width, dtype=np.float32)[None, :]
            k = k_lo[sel].astype(np.float32)[:, None] + steps
            col = np.floor(fx0[sel, None] + k * dfx[sel, None]).astype(np.int32)
            row = np.floor(fy0[sel, None] + k * dfy[sel, None]).astype(np.int32)
            cell = (rows - 1 - row) * np.int32(cols) + col
            keep = steps < n_samples[sel, None].astype(np.float32)  # padding of short beams
            keep[:, 1:] &= cell[:, 1:] != cell[:, :-1]  # each beam counts once per cell
            keep &= cell != hit32[sel, None]  # the end point's cell is a hit, not a miss
            pending.append(cell[keep])
            n_pending += len(pending[-1])
            if n_pending > _FLUSH_CELLS or stop >= len(beams):
                misses += np.bincount(np.concatenate(pending), minlength=n_cells)
                pending, n_pending = [], 0
            start = stop
    return ScanCounts(
        hits=hits.reshape(rows, cols),
        misses=misses.astype(np.int32).reshape(rows, cols),
        resolution=float(resolution),
        origin=origin,
        dropped_hits=dropped,
    )


def segment_labels(
    poses: NDArray[np.float64],
    ranges: NDArray[np.float64],
    angles: NDArray[np.float64],
    segment: NDArray[np.int64],
    drawn: OccupancyMap,
    *,
    max_range: float,
) -> NDArray[np.int16]:
    """Per occupied cell of a map, the segment of the run whose scans hit it most often.

    Ties go to the first segment; cells that are not occupied get -1. The hits are counted
    one segment at a time on the map's grid (only hits, as :func:`scan_counts` with
    ``free_space=False``).

    Parameters
    ----------
    poses, ranges, angles
        The scans, as for :func:`scan_counts`.
    segment : ndarray of int, shape (N,)
        Segment (partition) of each scan.
    drawn : OccupancyMap
        The map the scans drew (with its resolution and origin).
    max_range : float
        As for :func:`scan_counts`.

    Returns
    -------
    ndarray of int16
        Of the map's shape.
    """
    if drawn.resolution is None or drawn.origin is None:
        raise ParameterError("segment labels need a map with a resolution and an origin")
    best = np.zeros(drawn.shape, dtype=np.int32)
    owner = np.zeros(drawn.shape, dtype=np.int16)
    for j in np.unique(segment):
        sel = segment == j
        hits = scan_counts(
            poses[sel],
            ranges[sel],
            angles,
            max_range=max_range,
            resolution=drawn.resolution,
            shape=drawn.shape,
            origin=drawn.origin,
            free_space=False,
        ).hits
        more = hits > best
        owner[more] = j
        best[more] = hits[more]
    return np.where(drawn.occupied, owner, -1).astype(np.int16)


def counts_to_map(
    counts: ScanCounts,
    *,
    hit_logodds: float = DEFAULT_HIT_LOGODDS,
    miss_logodds: float = DEFAULT_MISS_LOGODDS,
    occupied_logodds: float = DEFAULT_OCCUPIED_LOGODDS,
    free_logodds: float = DEFAULT_FREE_LOGODDS,
) -> OccupancyMap:
    """Threshold the log-odds of :class:`ScanCounts` into a three-state map.

    See :func:`map_scans` for the parameters.
    """
    if not (hit_logodds > 0 and miss_logodds < 0 and free_logodds < occupied_logodds):
        raise ParameterError(
            "need hit_logodds > 0, miss_logodds < 0 and free_logodds < occupied_logodds"
        )
    logodds = counts.hits * float(hit_logodds) + counts.misses * float(miss_logodds)
    states = np.full(logodds.shape, UNKNOWN, dtype=np.int8)
    states[logodds <= free_logodds] = FREE
    states[logodds >= occupied_logodds] = OCCUPIED
    return OccupancyMap(states, resolution=counts.resolution, origin=counts.origin)


def map_scans(
    poses: ArrayLike,
    ranges: ArrayLike,
    angles: ArrayLike,
    *,
    max_range: float,
    resolution: float,
    shape: tuple[int, int],
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    hit_logodds: float = DEFAULT_HIT_LOGODDS,
    miss_logodds: float = DEFAULT_MISS_LOGODDS,
    occupied_logodds: float = DEFAULT_OCCUPIED_LOGODDS,
    free_logodds: float = DEFAULT_FREE_LOGODDS,
    step: float = 0.5,
) -> OccupancyMap:
    """Map 2D laser scans into a three-state occupancy grid (log-odds, all beams at once).

    Parameters
    ----------
    poses : array_like, shape (N, 3)
        World ``x, y, theta`` of the laser per scan (metres, radians).
    ranges : array_like, shape (N, B)
        Metres. ``>= max_range`` or non-finite: no hit, free space up to ``max_range``;
        ``<= 0``: invalid reading, ignored.
    angles : array_like, shape (B,)
        Beam angles relative to the laser's heading, radians.
    max_range : float
        The laser's maximum range, metres.
    resolution : float
        Metres per cell.
    shape : tuple of int
        ``(rows, cols)``; use :func:`grid_geometry` to size it around the data.
    origin : tuple of float
        World pose ``(x, y, yaw)`` of the lower-left corner (ROS ``map_server`` convention).
    hit_logodds, miss_logodds : float
        Log-odds added per beam ending in / crossing a cell (positive / negative).
    occupied_logodds, free_logodds : float
        Thresholds on the summed log-odds: occupied at or above, free at or below, unknown
        in between (and where no beam came).
    step : float
        Sampling step along beams, in cells.

    Returns
    -------
    OccupancyMap
        With ``resolution`` and ``origin`` set. Beams leaving the grid are clipped to it.

    Raises
    ------
    ParameterError
        For inconsistent shapes, non-finite poses or angles, or invalid parameters.

    Examples
    --------
    >>> import numpy as np
    >>> m = map_scans([[0.5, 0.5, 0.0]], [[0.3]], [0.0], max_range=4.0, resolution=0.1,
    ...               shape=(10, 10))
    >>> int(m.states[4, 8]), int(m.states[4, 6])
    (1, 0)
    """
    counts = scan_counts(
        poses,
        ranges,
        angles,
        max_range=max_range,
        resolution=resolution,
        shape=shape,
        origin=origin,
        step=step,
    )
    return counts_to_map(
        counts,
        hit_logodds=hit_logodds,
        miss_logodds=miss_logodds,
        occupied_logodds=occupied_logodds,
        free_logodds=free_logodds,
    )


def map_prefixes(
    poses: ArrayLike,
    ranges: ArrayLike,
    angles: ArrayLike,
    ends: Iterable[int],
    *,
    max_range: float,
    resolution: float,
    shape: tuple[int, int],
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    step: float = 0.5,
) -> Iterator[OccupancyMap]:
    """Maps of growing prefixes of a run: scans ``[0, end)`` for each ``end``, lazily.

    What a SLAM node publishes while it explores: the map so far. The counts are
    accumulated (each map costs only the scans added since the previous one), so mapping
    every prefix of a run costs about as much as mapping the whole run once; each map equals
    :func:`map_scans` of the same scans (default log-odds).

    Parameters
    ----------
    poses, ranges, angles
        The whole run (see :func:`map_scans`).
    ends : iterable of int
        Increasing prefix lengths, each in ``[1, N]``.
    max_range, resolution, shape, origin, step
        As for :func:`map_scans`.

    Yields
    ------
    OccupancyMap
        One per ``end``.

    Raises
    ------
    ParameterError
        For ends that do not increase or fall outside ``[1, N]``.

    Examples
    --------
    >>> maps = map_prefixes([[0.5, 0.5, 0.0], [0.5, 0.5, 1.6]], [[0.3], [0.3]], [0.0], [1, 2],
    ...                     max_range=4.0, resolution=0.1, shape=(10, 10))
    >>> [int(m.n_occupied) for m in maps]
    [1, 2]
    """
    p = np.asarray(poses, dtype=float)
    r = np.asarray(ranges, dtype=float)
    hits = misses = None
    start = dropped = 0
    for end in ends:
        end = int(end)
        if not (start < end <= len(p)):
            raise ParameterError(
                f"prefix ends must increase within [1, {len(p)}], got {end} after {start}"
            )
        c = scan_counts(
            p[start:end],
            r[start:end],
            angles,
            max_range=max_range,
            resolution=resolution,
            shape=shape,
            origin=origin,
            step=step,
        )
        hits = c.hits if hits is None else hits + c.hits
        misses = c.misses if misses is None else misses + c.misses
        start, dropped = end, dropped + c.dropped_hits
        yield counts_to_map(ScanCounts(hits, misses, c.resolution, c.origin, dropped))
