"""A simulated run through any floor plan: a route through its free space, scanned.

The synthetic buildings of :mod:`.building` come with their own tour; a map or floor plan
that a user has (a ROS map, a Stage world, a CAD export as an occupancy grid) does not.
:func:`plan_route` plans one, and :func:`simulate_plan_run` drives the simulated laser
along it, so that broken maps of *any* building can be drawn
(:func:`~brokenness.simulation.ground_truth.broken_map_from_run`).

The route, on a grid of :data:`ROUTE_CELL` metres:

1. **Where the robot fits.** Free cells (known free in the plan: occupied and unknown cells
   are solid) at least ``clearance`` metres from every solid cell, pooled onto the route
   grid (a route cell is open if any plan cell in it is), the largest 8-connected piece of
   them. A route cell's centre is within ``ROUTE_CELL / sqrt 2`` of a plan cell that keeps
   the clearance, so the robot stays at least ``clearance - ROUTE_CELL`` from every wall,
   and two rooms behind a wall thinner than twice the clearance are not joined.
2. **Waypoints.** In every block of ``waypoint_spacing`` metres, the open cell farthest
   from the walls (the first in row-major order of ties); blocks twice as large, as often
   as needed, where the tour's distances would be more than :data:`MAX_TOUR_ENTRIES`.
3. **Tour.** From a waypoint drawn by ``rng``, always on to the nearest waypoint not yet
   visited, nearest along the open cells (Dijkstra on the 8-connected route grid).
4. **Polyline.** The shortest paths between consecutive waypoints, joined and simplified
   (Douglas-Peucker, :func:`cv2.approxPolyDP`, to within half a route cell).

:func:`simulate_plan_run` then scans along the route as
:func:`~brokenness.simulation.laser.simulate_run` does for a synthetic building (a scan every
``spacing`` metres and every ``turn_step_deg`` of a turn, ray cast on the plan's solid
cells, with range and pose noise), and :func:`broken_plan_map` breaks that run as
:func:`~brokenness.simulation.carmen.broken_log_map` breaks a real log's: a broken map of the
building, its reference (the run mapped with its true poses) and the ground truth.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import MapError, ParameterError
from ..grid import FREE, OccupancyMap
from .ground_truth import SimulatedMap, break_run
from .laser import Laser, LaserRun, check_pose_sigma, route_poses, scan_poses
from .options import BumpOptions

__all__ = ["MAX_TOUR_ENTRIES", "ROUTE_CELL", "broken_plan_map", "plan_route", "simulate_plan_run"]

#: Side of a cell of the route grid, metres.
ROUTE_CELL = 0.2
#: At most this many (waypoint, route cell) distances are held at once (the tour's
#: shortest paths from every waypoint: 8 + 4 bytes each, 200 MB): for a plan so large, or
#: waypoints so close, that there would be more, the blocks that give one waypoint each are
#: doubled in side until they fit (the six buildings of ``realistic.py --plans`` need 5 % of
#: it at the default spacing).
MAX_TOUR_ENTRIES = 2**24


def plan_route(
    plan: OccupancyMap,
    *,
    clearance: float = 0.4,
    waypoint_spacing: float = 3.0,
    rng: np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """A tour through the free space of ``plan``, as a polyline in metres.

    See the module docstring for the steps.

    Parameters
    ----------
    plan : OccupancyMap
        The building: known free cells are where the robot may go; occupied and unknown
        cells are solid.
    clearance : float
        Metres the route keeps from every solid cell (at least ``clearance - ROUTE_CELL``,
        see the module docstring).
    waypoint_spacing : float
        Metres between the centres of the blocks that each give one waypoint.
    rng : numpy.random.Generator, optional
        Draws the starting waypoint (default: ``default_rng(0)``).

    Returns
    -------
    ndarray of float64, shape (K, 2)
        World ``x, y`` in metres, the plan's lower-left corner at the origin (as
        :attr:`~brokenness.simulation.building.Building.grid` and
        :func:`~brokenness.simulation.laser.cast_rays` take it).

    Raises
    ------
    ParameterError
        For a clearance or waypoint spacing that is not a positive number.
    MapError
        If the robot fits nowhere in the plan (no free cell keeps the clearance).
    """
    for name, value in (("clearance", clearance), ("waypoint_spacing", waypoint_spacing)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive number, got {value!r}")
    rng = np.random.default_rng(0) if rng is None else rng
    res = _resolution(plan)
    free = np.asarray(plan.states == FREE, dtype=np.uint8)
    room = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res  # metres
    factor = max(1, round(ROUTE_CELL / res))
    room_pooled = _max_pool(room, factor)
    open_cells = room_pooled >= clearance
    count, labels, stats, _ = cv2.connectedComponentsWithStats(
        open_cells.astype(np.uint8), connectivity=8
    )
    if count < 2:
        raise MapError(f"no free cell of the plan is {clearance} m from every wall")
    piece = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))  # the first of the largest
    inside = labels == piece
    nodes = np.full(inside.shape, -1, dtype=np.int64)
    rows, cols = np.nonzero(inside)
    nodes[rows, cols] = np.arange(rows.size)
    room_open = room_pooled[rows, cols]
    block = max(1, round(waypoint_spacing / (factor * res)))
    waypoints = _waypoints(rows, cols, room_open, inside.shape[1], block)
    while waypoints.size * rows.size > MAX_TOUR_ENTRIES and waypoints.size > 1:
        block *= 2
        waypoints = _waypoints(rows, cols, room_open, inside.shape[1], block)
    path = _tour(inside, nodes, rows, cols, waypoints, int(rng.integers(waypoints.size)))
    curve = np.stack([cols[path], rows[path]], axis=1).astype(np.int32).reshape(-1, 1, 2)
    simple = cv2.approxPolyDP(curve, 0.5, closed=False).reshape(-1, 2).astype(np.float64)
    cell = factor * res  # route cell centre (col, row) -> world (x, y), row 0 at the top
    x = (simple[:, 0] + 0.5) * cell
    y = plan.shape[0] * res - (simple[:, 1] + 0.5) * cell
    return np.stack([x, y], axis=1)


def simulate_plan_run(
    plan: OccupancyMap,
    *,
    laser: Laser | None = None,
    clearance: float = 0.4,
    waypoint_spacing: float = 3.0,
    spacing: float = 0.4,
    turn_step_deg: float = 45.0,
    pose_sigma: tuple[float, float] = (0.01, math.radians(0.25)),
    rng: np.random.Generator | None = None,
) -> tuple[LaserRun, tuple[float, float, float, float]]:
    """Drive the simulated laser along :func:`plan_route` through ``plan`` and scan.

    Parameters
    ----------
    plan : OccupancyMap
        The building (occupied and unknown cells are solid).
    laser : Laser, optional
        Default :class:`~brokenness.simulation.laser.Laser`.
    clearance, waypoint_spacing : float
        See :func:`plan_route`.
    spacing, turn_step_deg : float
        See :func:`~brokenness.simulation.laser.route_poses`.
    pose_sigma : (float, float)
        Standard deviation of the pose estimate's noise per scan: metres and radians.
    rng : numpy.random.Generator, optional
        The start of the tour, then the range and pose noise (default: ``default_rng(0)``).

    Returns
    -------
    run : LaserRun
    extent : (float, float, float, float)
        The plan's box ``(0, 0, width, height)`` in metres, the frame of the run's poses.

    Raises
    ------
    ParameterError
        For bad options, or a run of more than ``MAX_READINGS`` readings.
    MapError
        If the robot fits nowhere in the plan.
    """
    laser = Laser() if laser is None else laser
    rng = np.random.default_rng(0) if rng is None else rng
    check_pose_sigma(pose_sigma)
    route = plan_route(plan, clearance=clearance, waypoint_spacing=waypoint_spacing, rng=rng)
    poses = route_poses(route, spacing=spacing, turn_step_deg=turn_step_deg)
    res = _resolution(plan)
    run = scan_poses(np.asarray(plan.states != FREE), res, poses, laser, pose_sigma, rng)
    height, width = (side * res for side in plan.shape)
    return run, (0.0, 0.0, float(width), float(height))


def broken_plan_map(
    plan: OccupancyMap,
    options: BumpOptions | None = None,
    *,
    resolution: float = 0.05,
    laser: Laser | None = None,
    clearance: float = 0.4,
    waypoint_spacing: float = 3.0,
) -> SimulatedMap:
    """A broken map of the building of ``plan``: a simulated run through it, bumped.

    The run is :func:`simulate_plan_run`'s (its tour's start and its noise drawn from
    ``numpy.random.default_rng([options.seed, 7])``); the reference, the broken map, the
    ground truth and the honest expected degree are those of
    :func:`~brokenness.simulation.carmen.broken_log_map` for a real log's run.

    Parameters
    ----------
    plan : OccupancyMap
        The building: a map or floor plan with a resolution (occupied and unknown cells are
        solid).
    options : BumpOptions, optional
        The bumps and the honest rule (default: ``BumpOptions()``, no bumps).
    resolution : float
        Metres per cell of the broken map and the reference.
    laser : Laser, optional
        Default :class:`~brokenness.simulation.laser.Laser`.
    clearance, waypoint_spacing : float
        The tour, as for :func:`plan_route`.

    Returns
    -------
    SimulatedMap
        As :func:`~brokenness.simulation.synthetic.simulate_broken_map`'s; ``.building`` is
        None, ``.run`` the simulated run.

    Raises
    ------
    ParameterError
        For bad options, or when ``options.degree`` is not reached.
    MapError
        For a plan without a resolution, or one in which the robot fits nowhere.

    Examples
    --------
    >>> from brokenness import load_map
    >>> plan = load_map("tests/data/depot.yaml")  # doctest: +SKIP
    >>> sim = broken_plan_map(plan, BumpOptions(seed=2, degree=2))  # doctest: +SKIP
    >>> sim.expected_degree, len(sim.partitions)  # doctest: +SKIP
    (2, 3)
    """
    options = BumpOptions() if options is None else options
    if not (isinstance(resolution, int | float) and math.isfinite(resolution) and resolution > 0):
        raise ParameterError(f"resolution must be a positive number, got {resolution!r}")
    run, extent = simulate_plan_run(
        plan,
        laser=laser,
        clearance=clearance,
        waypoint_spacing=waypoint_spacing,
        rng=np.random.default_rng([options.seed, 7]),
    )
    setting = {
        "resolution": resolution,
        "plan": plan.source,
        "plan_resolution": plan.resolution,
        "scans": len(run.true_poses),
        "beams": run.laser.beams,
        "max_range": run.laser.max_range,
        "clearance": clearance,
        "waypoint_spacing": waypoint_spacing,
    }
    return break_run(
        run,
        extent,
        options,
        resolution=resolution,
        hint=f"{plan.source or 'the plan'}: try a lower degree",
        setting=setting,
        source=plan.source,
    )


def _resolution(plan: OccupancyMap) -> float:
    """The plan's metres per cell (a plan without one cannot be scanned in metres)."""
    if plan.resolution is None:
        raise MapError("the plan has no resolution: its metres per cell are needed")
    return float(plan.resolution)


def _max_pool(values: NDArray[np.float32], factor: int) -> NDArray[np.float32]:
    """The largest of each ``factor`` x ``factor`` block (those at the far edges smaller)."""
    if factor == 1:
        return values
    h, w = values.shape
    rows = np.maximum.reduceat(values, np.arange(0, h, factor), axis=0)
    return np.asarray(np.maximum.reduceat(rows, np.arange(0, w, factor), axis=1))


def _waypoints(
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    room: NDArray[np.float32],
    width: int,
    side: int,
) -> NDArray[np.intp]:
    """Of the open cells ``rows, cols`` (row-major, their nodes numbered in that order; ``room``
    their distance to the walls, on a grid ``width`` cells wide), the node of the one farthest
    from the walls in each block of ``side`` cells (the first of ties), blocks row-major."""
    key = (rows // side) * (width // side + 1) + cols // side
    order = np.lexsort((-room, key))  # by block, then farthest first (stable: row-major)
    first = np.ones(order.size, dtype=bool)
    first[1:] = key[order][1:] != key[order][:-1]
    return np.asarray(order[first])


def _tour(
    inside: NDArray[np.bool_],
    nodes: NDArray[np.int64],
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    waypoints: NDArray[np.intp],
    start: int,
) -> NDArray[np.int64]:
    """The nodes along the greedy tour of ``waypoints`` from ``waypoints[start]``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    h, w = inside.shape
    src: list[NDArray[np.int64]] = []
    dst: list[NDArray[np.int64]] = []
    length: list[NDArray[np.float64]] = []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):  # each undirected edge once
        r2, c2 = rows + dr, cols + dc
        ok = (r2 < h) & (c2 >= 0) & (c2 < w)
        ok[ok] = inside[r2[ok], c2[ok]]
        src.append(nodes[rows[ok], cols[ok]])
        dst.append(nodes[r2[ok], c2[ok]])
        length.append(np.full(int(ok.sum()), math.hypot(dr, dc)))
    n = rows.size
    graph = coo_matrix(
        (np.concatenate(length), (np.concatenate(src), np.concatenate(dst))), shape=(n, n)
    ).tocsr()
    distances, previous = dijkstra(
        graph, directed=False, indices=waypoints, return_predecessors=True
    )
    at = start
    left = np.ones(waypoints.size, dtype=bool)
    left[at] = False
    path = [np.array([waypoints[at]])]
    while left.any():
        reach = np.where(left, distances[at, waypoints], np.inf)
        nxt = int(np.argmin(reach))  # all reachable: the waypoints are in one piece
        steps = [int(waypoints[nxt])]
        while steps[-1] != waypoints[at]:
            steps.append(int(previous[at, steps[-1]]))
        path.append(np.array(steps[-2::-1]))  # from the node after ``at`` to ``nxt``
        left[nxt] = False
        at = nxt
    return np.concatenate(path)
