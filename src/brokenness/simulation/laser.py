"""A robot with a 2D laser range finder in a synthetic building.

:func:`route_poses` turns a building's tour into scan poses (a scan every ``spacing``
metres, extra scans while turning on the spot at corners, a full spin in every room);
:func:`cast_rays` simulates the laser on the building's ground-truth grid by sphere tracing
on its Euclidean distance transform, all beams of all scans at once; :func:`simulate_run`
does both and adds Gaussian range noise and the small Gaussian noise of the pose estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ParameterError
from .building import Building

__all__ = [
    "MAX_READINGS",
    "MAX_SCANS",
    "Laser",
    "LaserRun",
    "cast_rays",
    "route_poses",
    "simulate_run",
]

# sphere-tracing iterations before the remaining beams march in fixed steps
_SPHERE_STEPS = 48
#: Most scans of a route (a 500 m building at the default 0.4 m spacing has some 20000).
MAX_SCANS: int = 1_000_000
#: Most readings (scans x beams) of a simulated run: 50 million ranges take 400 MB, and ray
#: casting needs about five times that.
MAX_READINGS: int = 50_000_000


@dataclass(frozen=True)
class Laser:
    """A 2D laser range finder.

    Attributes
    ----------
    beams : int
        Number of beams, evenly spread over the field of view (both ends included, unless
        the field of view is a full turn).
    fov_deg : float
        Field of view, degrees (at most 360), centred on the heading.
    max_range : float
        Metres; beams that hit nothing within it return exactly ``max_range``.
    range_sigma : float
        Standard deviation of the Gaussian range noise, metres.
    """

    beams: int = 181
    fov_deg: float = 270.0
    max_range: float = 8.0
    range_sigma: float = 0.01

    def __post_init__(self) -> None:
        if not (isinstance(self.beams, int | np.integer) and self.beams >= 1):
            raise ParameterError(f"beams must be a positive integer, got {self.beams!r}")
        if not (0 < self.fov_deg <= 360):
            raise ParameterError(f"fov_deg must be in (0, 360], got {self.fov_deg!r}")
        if not (math.isfinite(self.max_range) and self.max_range > 0):
            raise ParameterError(f"max_range must be a positive number, got {self.max_range!r}")
        if not (math.isfinite(self.range_sigma) and self.range_sigma >= 0):
            raise ParameterError(f"range_sigma must be >= 0, got {self.range_sigma!r}")

    @property
    def angles(self) -> NDArray[np.float64]:
        """Beam angles relative to the heading, radians, shape (beams,)."""
        fov = math.radians(self.fov_deg)
        if self.beams == 1:
            return np.zeros(1)
        if self.fov_deg >= 360:
            return -math.pi + fov * np.arange(self.beams) / self.beams
        return np.linspace(-0.5 * fov, 0.5 * fov, self.beams)


@dataclass(frozen=True, eq=False)
class LaserRun:
    """One simulated run: true poses, the noisy pose estimate and the scans.

    Attributes
    ----------
    true_poses : ndarray, shape (N, 3)
        World ``x, y, theta`` of the laser.
    noisy_poses : ndarray, shape (N, 3)
        The pose estimate without bumps: true poses plus small independent Gaussian noise.
    ranges : ndarray, shape (N, B)
        Metres, ``max_range`` where nothing was hit.
    angles : ndarray, shape (B,)
    laser : Laser
    """

    true_poses: NDArray[np.float64]
    noisy_poses: NDArray[np.float64]
    ranges: NDArray[np.float64]
    angles: NDArray[np.float64]
    laser: Laser


def route_poses(
    route: ArrayLike,
    *,
    spacing: float = 0.4,
    turn_step_deg: float = 45.0,
    spin_at: tuple[int, ...] = (),
) -> NDArray[np.float64]:
    """Scan poses along a polyline route.

    The robot drives along each segment facing forward, with a scan every ``spacing``
    metres (at least one per segment end); at each waypoint it turns on the spot toward the
    next segment with a scan every ``turn_step_deg``, and at the waypoints in ``spin_at`` it
    first turns once all the way round.

    Parameters
    ----------
    route : array_like, shape (K, 2)
        Waypoints, metres. Repeated consecutive waypoints are skipped.
    spacing : float
        Metres between scans while driving.
    turn_step_deg : float
        Degrees between scans while turning.
    spin_at : tuple of int
        Indices of waypoints where the robot spins a full turn.

    Returns
    -------
    ndarray, shape (N, 3)
        ``x, y, theta`` per scan.

    Raises
    ------
    ParameterError
        For fewer than two distinct waypoints, a non-finite or non-positive ``spacing`` or
        ``turn_step_deg``, or a route of more than :data:`MAX_SCANS` scans.
    """
    pts = np.asarray(route, dtype=float).reshape(-1, 2)
    if len(pts) < 2:
        raise ParameterError("a route needs at least two waypoints")
    if not (math.isfinite(spacing) and spacing > 0):
        raise ParameterError(f"spacing must be a positive number of metres, got {spacing!r}")
    if not (math.isfinite(turn_step_deg) and turn_step_deg > 0):
        raise ParameterError(f"turn_step_deg must be a positive number, got {turn_step_deg!r}")
    _check_scans(pts, spacing, turn_step_deg)
    step = math.radians(turn_step_deg)
    spins = set(spin_at)
    out: list[NDArray[np.float64]] = []
    heading: float | None = None
    for i in range(len(pts) - 1):
        a, b = pts[i], pts[i + 1]
        seg = b - a
        length = float(np.hypot(*seg))
        if length < 1e-9:
            continue
        new = math.atan2(seg[1], seg[0])
        if heading is None:
            heading = new
        turn = math.remainder(new - heading, 2 * math.pi)
        if i in spins:
            turn += math.copysign(2 * math.pi, turn if turn != 0 else 1.0)
        n_turn = int(math.ceil(abs(turn) / step))
        if n_turn > 0:
            th = heading + turn * np.arange(1, n_turn) / n_turn
            out.append(np.column_stack([np.full(len(th), a[0]), np.full(len(th), a[1]), th]))
        n = max(int(math.ceil(length / spacing)), 1)
        t = np.arange(n) / n
        out.append(np.column_stack([a[0] + t * seg[0], a[1] + t * seg[1], np.full(n, new)]))
        heading = new
    if heading is None:
        raise ParameterError("a route needs two distinct waypoints")
    out.append(np.array([[pts[-1, 0], pts[-1, 1], heading]]))
    poses = np.concatenate(out)
    poses[:, 2] = np.remainder(poses[:, 2] + math.pi, 2 * math.pi) - math.pi
    return poses


def _check_scans(pts: NDArray[np.float64], spacing: float, turn_step_deg: float) -> None:
    """Refuse a route of more than :data:`MAX_SCANS` scans before any pose is made."""
    length = float(np.sum(np.hypot(*np.diff(pts, axis=0).T)))
    turns = (len(pts) - 1) * math.ceil(720.0 / turn_step_deg)  # at most two turns a waypoint
    scans = length / spacing + len(pts) + turns
    if not scans <= MAX_SCANS:
        raise ParameterError(
            f"a route of {length:.4g} m scanned every {spacing!r} m (and every {turn_step_deg!r}"
            f" deg of a turn) has more than {MAX_SCANS} scans (MAX_SCANS)"
        )


def cast_rays(
    solid: NDArray[np.bool_],
    resolution: float,
    poses: ArrayLike,
    angles: ArrayLike,
    max_range: float,
) -> NDArray[np.float64]:
    """Ranges of laser beams on a ground-truth grid, by sphere tracing.

    Each beam advances by the distance to the nearest solid cell (Euclidean distance
    transform of the free space, minus a cell's half diagonal, at least half a cell) until it
    enters a solid cell; all beams march together.

    Parameters
    ----------
    solid : ndarray of bool, shape (rows, cols)
        True where solid; row 0 is the top row; the grid's lower-left corner is the world
        origin (as :attr:`Building.grid`).
    resolution : float
        Metres per cell of ``solid``.
    poses : array_like, shape (N, 3)
        World ``x, y, theta`` of the laser.
    angles : array_like, shape (B,)
        Beam angles relative to the heading.
    max_range : float
        Metres; beams that reach it (or leave the grid) return ``max_range``.

    Returns
    -------
    ndarray, shape (N, B)
        Distance to the entry point of the first solid cell, metres (within half a cell).
    """
    p = np.asarray(poses, dtype=float).reshape(-1, 3)
    a = np.asarray(angles, dtype=float).ravel()
    rows, cols = solid.shape
    # distance (cells) from each free cell's centre to the nearest solid cell's centre (exact)
    dist = cv2.distanceTransform((~solid).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    safe = np.maximum(dist - 1.0, 0.5).astype(np.float32)  # cells a beam may advance
    # a solid frame around the grid stops beams that would leave it
    safe[0, :] = safe[-1, :] = safe[:, 0] = safe[:, -1] = 0.0
    heading = (p[:, 2:3] + a[None, :]).ravel()
    x = (np.repeat(p[:, 0], len(a)) / resolution).astype(np.float32)
    y = (rows - np.repeat(p[:, 1], len(a)) / resolution).astype(np.float32)  # row axis, down
    dx, dy = np.cos(heading).astype(np.float32), (-np.sin(heading)).astype(np.float32)
    limit = max_range / resolution
    n = len(heading)
    t = np.zeros(n, dtype=np.float32)
    out = np.full(n, limit)
    active = np.arange(n)
    for _ in range(_SPHERE_STEPS):  # all beams march together, the arrays shrink as they stop
        if len(active) == 0:
            break
        c = np.clip((x + t * dx).astype(np.int32), 0, cols - 1)  # x, y >= 0 inside the frame
        r = np.clip((y + t * dy).astype(np.int32), 0, rows - 1)
        step = safe[r, c]
        hit = solid[r, c]
        done = hit | (step == 0.0) | (t >= limit)
        out[active[hit]] = t[hit]
        keep = ~done
        active, x, y, dx, dy, t = (v[keep] for v in (active, x, y, dx, dy, t))
        t += step[keep]
    # the few beams still marching (grazing along a wall): fixed half-cell steps, all at once;
    # the solid frame stops each within the grid's diagonal, however long the range
    reach = min(limit, math.hypot(rows, cols))
    for part in np.array_split(np.arange(len(active)), max(1, len(active) // 256)):
        if len(part) == 0:
            continue
        ts = t[part, None] + 0.5 * np.arange(int(2 * reach) + 2, dtype=np.float32)[None, :]
        c = np.clip((x[part, None] + ts * dx[part, None]).astype(np.int32), 0, cols - 1)
        r = np.clip((y[part, None] + ts * dy[part, None]).astype(np.int32), 0, rows - 1)
        stop = solid[r, c] | (safe[r, c] == 0.0) | (ts >= limit)
        first = np.argmax(stop, axis=1)
        rows_ = np.arange(len(part))
        ok = solid[r[rows_, first], c[rows_, first]] & (ts[rows_, first] < limit)
        out[active[part[ok]]] = ts[rows_, first][ok]
    ranges = np.minimum(out, limit) * resolution
    return ranges.reshape(len(p), len(a))


def simulate_run(
    building: Building,
    *,
    laser: Laser | None = None,
    spacing: float = 0.4,
    turn_step_deg: float = 45.0,
    pose_sigma: tuple[float, float] = (0.01, math.radians(0.25)),
    rng: np.random.Generator | None = None,
) -> LaserRun:
    """Drive the robot along the building's route and scan.

    Parameters
    ----------
    building : Building
    laser : Laser, optional
        Default :class:`Laser`.
    spacing, turn_step_deg : float
        See :func:`route_poses`.
    pose_sigma : (float, float)
        Standard deviation of the pose estimate's independent Gaussian noise per scan:
        metres (per axis) and radians.
    rng : numpy.random.Generator, optional
        Source of the range and pose noise (default: ``default_rng(0)``).

    Returns
    -------
    LaserRun

    Raises
    ------
    ParameterError
        For bad ``pose_sigma``, ``spacing`` or ``turn_step_deg`` (:func:`route_poses`), or a
        run of more than :data:`MAX_READINGS` readings (scans x beams).
    """
    laser = Laser() if laser is None else laser
    rng = np.random.default_rng(0) if rng is None else rng
    check_pose_sigma(pose_sigma)
    poses = route_poses(
        building.route, spacing=spacing, turn_step_deg=turn_step_deg, spin_at=building.spin_at
    )
    return scan_poses(building.grid, building.truth_resolution, poses, laser, pose_sigma, rng)


def check_pose_sigma(pose_sigma: tuple[float, float]) -> None:
    """Raise a :class:`ParameterError` unless ``pose_sigma`` is two non-negative numbers."""
    if not all(math.isfinite(s) and s >= 0 for s in pose_sigma):
        raise ParameterError(f"pose_sigma must be non-negative numbers, got {pose_sigma!r}")


def scan_poses(
    solid: NDArray[np.bool_],
    resolution: float,
    poses: NDArray[np.float64],
    laser: Laser,
    pose_sigma: tuple[float, float],
    rng: np.random.Generator,
) -> LaserRun:
    """Scan a ground-truth grid from ``poses``: the ranges of :func:`cast_rays` with Gaussian
    range noise (hits only, kept inside the range), and the pose estimate, the poses with
    Gaussian noise of ``pose_sigma`` (metres per axis, radians) drawn after it from ``rng``.

    Raises
    ------
    ParameterError
        For a run of more than :data:`MAX_READINGS` readings (scans x beams).
    """
    if len(poses) * laser.beams > MAX_READINGS:
        raise ParameterError(
            f"{len(poses)} scans of {laser.beams} beams are more than {MAX_READINGS} readings "
            "(MAX_READINGS): use a larger spacing or fewer beams"
        )
    angles = laser.angles
    ranges = cast_rays(solid, resolution, poses, angles, laser.max_range)
    noise = rng.normal(0.0, 1.0, ranges.shape) * laser.range_sigma
    hit = ranges < laser.max_range
    ranges = np.where(
        hit, np.clip(ranges + noise, 1e-3, laser.max_range * (1 - 1e-9)), laser.max_range
    )
    pn = rng.normal(0.0, 1.0, poses.shape) * np.array([pose_sigma[0], pose_sigma[0], pose_sigma[1]])
    return LaserRun(
        true_poses=poses, noisy_poses=poses + pn, ranges=ranges, angles=angles, laser=laser
    )
