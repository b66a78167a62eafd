"""Seeded synthetic floor plans: rooms, corridors, doors, clutter, slanted walls.

The generator splits the building's interior recursively (binary space partitioning). The
first split of a large enough region is a *corridor* (two parallel walls with a passage
between them); the other splits are single walls. Every split wall gets at least one door,
so all rooms are connected; corridor walls get a door to every room along them that has
room for one. Some room corners are cut by a diagonal wall (walls that are not
axis-aligned) and rooms get clutter: boxes at random angles and round pillars, kept clear of
the robot's route.

Everything is in metres in a world frame with y up and the building's lower-left outer
corner at (0, 0). :attr:`Building.grid` rasterises it (True = solid) at
``truth_resolution`` with the same geometry conventions as :class:`~brokenness.OccupancyMap`
(row 0 = top, cell (col, row) covers ``x in [col*res, (col+1)*res)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import ParameterError

__all__ = [
    "MAX_BUILDING_SIDE",
    "Building",
    "Door",
    "Room",
    "check_building_size",
    "generate_building",
]

#: Longest side of a generated building, metres. The floor plan, its route and the scans
#: grow with the area: 500 m x 500 m takes about 20 s and 1.3 GB to simulate at 0.2 m/cell,
#: 1 km already more than 30 s and 1.6 GB before the maps are drawn.
MAX_BUILDING_SIDE: float = 500.0

Rect = tuple[float, float, float, float]  # x0, y0, x1, y1 (metres)


@dataclass(frozen=True)
class Room:
    """A room (or corridor): its free interior rectangle, metres."""

    index: int
    rect: Rect
    corridor: bool = False

    @property
    def centre(self) -> tuple[float, float]:
        x0, y0, x1, y1 = self.rect
        return (0.5 * (x0 + x1), 0.5 * (y0 + y1))


@dataclass(frozen=True)
class Door:
    """A gap in a wall between two rooms.

    ``gap`` is the rectangle carved out of the wall; ``approach`` are the points, one per
    room, just in front of the door on either side (the robot's route passes through them).
    """

    rooms: tuple[int, int]
    gap: Rect
    approach: tuple[tuple[float, float], tuple[float, float]]


@dataclass(frozen=True, eq=False)
class Building:
    """A synthetic floor plan and its rasterisation.

    Attributes
    ----------
    width, height : float
        Outer size in metres.
    rooms : tuple of Room
    doors : tuple of Door
    grid : ndarray of bool, shape (rows, cols)
        True where the plan is solid (walls, clutter), at ``truth_resolution``; row 0 = top.
    truth_resolution : float
        Metres per cell of ``grid``.
    route : ndarray, shape (K, 2)
        The robot's tour through the building (metres): a depth-first walk over the rooms
        through their doors, back to the start.
    spin_at : tuple of int
        Indices into ``route`` of room centres, where the robot turns on the spot.
    """

    width: float
    height: float
    rooms: tuple[Room, ...]
    doors: tuple[Door, ...]
    grid: NDArray[np.bool_]
    truth_resolution: float
    route: NDArray[np.float64]
    spin_at: tuple[int, ...]


@dataclass
class _Plan:
    rng: np.random.Generator
    wall: float
    corridor_width: float
    door_width: float
    min_room: float
    rooms: list[Room]
    walls: list[Rect]
    # (axis, coordinate of the wall's low side, of its high side, rooms low, rooms high)
    splits: list[tuple[int, float, float, list[int], list[int], bool]]


def _split(plan: _Plan, rect: Rect, depth: int) -> list[int]:
    """Split ``rect`` recursively; returns the indices of the leaf rooms inside it."""
    x0, y0, x1, y1 = rect
    w, h = x1 - x0, y1 - y0
    axis = 0 if w >= h else 1  # 0: vertical wall (split x), 1: horizontal wall (split y)
    length = w if axis == 0 else h
    lo = x0 if axis == 0 else y0
    corridor = depth == 0 and length >= 2 * plan.min_room + plan.corridor_width + 2 * plan.wall
    need = plan.corridor_width + 2 * plan.wall if corridor else plan.wall
    if length < 2 * plan.min_room + need or (depth >= 2 and plan.rng.random() < 0.25):
        idx = len(plan.rooms)
        plan.rooms.append(Room(idx, rect))
        return [idx]
    free = length - need - 2 * plan.min_room
    cut = lo + plan.min_room + plan.rng.uniform(0.2, 0.8) * free  # low side of the wall(s)
    if corridor:
        a, b = cut, cut + plan.wall  # first wall
        c, d = b + plan.corridor_width, b + plan.corridor_width + plan.wall  # second wall
        if axis == 0:
            plan.walls += [(a, y0, b, y1), (c, y0, d, y1)]
            low, mid, high = (x0, y0, a, y1), (b, y0, c, y1), (d, y0, x1, y1)
        else:
            plan.walls += [(x0, a, x1, b), (x0, c, x1, d)]
            low, mid, high = (x0, y0, x1, a), (x0, b, x1, c), (x0, d, x1, y1)
        rooms_low = _split(plan, low, depth + 1)
        cidx = len(plan.rooms)
        plan.rooms.append(Room(cidx, mid, corridor=True))
        rooms_high = _split(plan, high, depth + 1)
        plan.splits.append((axis, a, b, rooms_low, [cidx], True))
        plan.splits.append((axis, c, d, [cidx], rooms_high, True))
        return rooms_low + [cidx] + rooms_high
    a, b = cut, cut + plan.wall
    if axis == 0:
        plan.walls.append((a, y0, b, y1))
        low, high = (x0, y0, a, y1), (b, y0, x1, y1)
    else:
        plan.walls.append((x0, a, x1, b))
        low, high = (x0, y0, x1, a), (x0, b, x1, y1)
    rooms_low = _split(plan, low, depth + 1)
    rooms_high = _split(plan, high, depth + 1)
    plan.splits.append((axis, a, b, rooms_low, rooms_high, False))
    return rooms_low + rooms_high


def _doors(plan: _Plan) -> list[Door]:
    """At least one door per split wall; a door to every fitting room on corridor walls."""
    doors: list[Door] = []
    margin = 0.5 * plan.wall + 0.15
    for axis, a, b, low, high, corridor in plan.splits:
        along = 1 - axis  # coordinate running along the wall
        candidates = []
        for i in low:
            ri = plan.rooms[i].rect
            if not math.isclose(ri[2 + axis], a, abs_tol=1e-9):
                continue
            for j in high:
                rj = plan.rooms[j].rect
                if not math.isclose(rj[axis], b, abs_tol=1e-9):
                    continue
                s0 = max(ri[along], rj[along]) + margin
                s1 = min(ri[2 + along], rj[2 + along]) - margin
                if s1 - s0 >= plan.door_width:
                    candidates.append((i, j, s0, s1))
        if not candidates:
            continue
        if corridor:
            chosen = candidates
        else:
            chosen = [candidates[int(plan.rng.integers(len(candidates)))]]
        for i, j, s0, s1 in chosen:
            c = plan.rng.uniform(s0 + 0.5 * plan.door_width, s1 - 0.5 * plan.door_width)
            d0, d1 = c - 0.5 * plan.door_width, c + 0.5 * plan.door_width
            off = 0.45
            if axis == 0:
                gap = (a - 0.01, d0, b + 0.01, d1)
                approach = ((a - off, c), (b + off, c))
            else:
                gap = (d0, a - 0.01, d1, b + 0.01)
                approach = ((c, a - off), (c, b + off))
            doors.append(Door((i, j), gap, approach))
    return doors


def _tour(
    rooms: list[Room], doors: list[Door], start: int
) -> tuple[list[tuple[float, float]], list[int]]:
    """Depth-first walk over the rooms through their doors, returning to the start."""
    adj: dict[int, list[tuple[int, Door]]] = {r.index: [] for r in rooms}
    for d in doors:
        i, j = d.rooms
        adj[i].append((j, d))
        adj[j].append((i, d))
    route: list[tuple[float, float]] = []
    spins: list[int] = []
    seen = {start}

    def visit(r: int) -> None:
        centre = rooms[r].centre
        route.append(centre)
        if not rooms[r].corridor:
            spins.append(len(route) - 1)
        for nxt, d in adj[r]:
            if nxt in seen:
                continue
            seen.add(nxt)
            here, there = (
                (d.approach[0], d.approach[1])
                if d.rooms[0] == r
                else (d.approach[1], d.approach[0])
            )
            if rooms[r].corridor:  # walk along the corridor's centre line to the door
                route.append(_corridor_point(rooms[r], here))
            route.extend([here, there])
            visit(nxt)
            route.extend([there, here])
            if rooms[r].corridor:
                route.append(_corridor_point(rooms[r], here))
            route.append(centre)

    visit(start)
    return route, spins


def _corridor_point(room: Room, p: tuple[float, float]) -> tuple[float, float]:
    x0, y0, x1, y1 = room.rect
    if x1 - x0 < y1 - y0:  # vertical corridor
        return (0.5 * (x0 + x1), p[1])
    return (p[0], 0.5 * (y0 + y1))


def _segment_distance(
    p: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distance from point ``p`` to each segment ``a[i]-b[i]``."""
    ab = b - a
    t = np.clip(
        np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12),
        0.0,
        1.0,
    )
    return np.linalg.norm(a + t[:, None] * ab - p, axis=1)


def check_building_size(width: float, height: float) -> None:
    """Raise :class:`ParameterError` unless both sides are in [6 m, :data:`MAX_BUILDING_SIDE`]."""
    if not (width >= 6.0 and height >= 6.0):
        raise ParameterError(f"a building must be at least 6 m x 6 m, got {width} x {height}")
    if not (width <= MAX_BUILDING_SIDE and height <= MAX_BUILDING_SIDE):
        side = f"{MAX_BUILDING_SIDE:g} m"
        raise ParameterError(
            f"a building must be at most {side} x {side} (MAX_BUILDING_SIDE), got {width} x "
            f"{height}"
        )


def generate_building(
    seed: int | None = 0,
    *,
    width: float = 15.0,
    height: float = 15.0,
    truth_resolution: float = 0.025,
    wall_thickness: float = 0.15,
    corridor_width: float = 1.8,
    door_width: float = 0.9,
    min_room: float = 2.8,
    chamfer_probability: float = 0.35,
    clutter_density: float = 0.06,
) -> Building:
    """Generate a seeded floor plan.

    Parameters
    ----------
    seed : int, optional
        Seed of :func:`numpy.random.default_rng`; the same seed gives the same building.
    width, height : float
        Outer size, metres (at least 6 m each).
    truth_resolution : float
        Metres per cell of the rasterised plan (use at most half the map resolution).
    wall_thickness, corridor_width, door_width, min_room : float
        Metres. ``min_room`` is the smallest side of a room.
    chamfer_probability : float
        Chance that a room gets one corner cut by a diagonal wall.
    clutter_density : float
        Expected clutter objects per square metre of room floor.

    Returns
    -------
    Building

    Raises
    ------
    ParameterError
        For a building too small (under 6 m) or too large (over :data:`MAX_BUILDING_SIDE`),
        or non-positive sizes.

    Examples
    --------
    >>> b = generate_building(3, width=12, height=10)
    >>> b.grid.dtype, len(b.rooms) > 1
    (dtype('bool'), True)
    """
    check_building_size(width, height)
    for name, v in [
        ("truth_resolution", truth_resolution),
        ("wall_thickness", wall_thickness),
        ("door_width", door_width),
        ("corridor_width", corridor_width),
        ("min_room", min_room),
    ]:
        if not (math.isfinite(v) and v > 0):
            raise ParameterError(f"{name} must be a positive number, got {v!r}")
    rng = np.random.default_rng(seed)
    t = wall_thickness
    plan = _Plan(rng, t, corridor_width, door_width, min_room, [], [], [])
    _split(plan, (t, t, width - t, height - t), 0)
    doors = _doors(plan)
    rooms = plan.rooms
    start = next((r.index for r in rooms if r.corridor), 0)
    # the tour visits every room a door reaches (all of them in 50 of 50 seeds checked; a split
    # wall without room for a door would leave rooms unvisited, which are then never mapped)
    route, spins = _tour(rooms, doors, start)

    cols, rows = int(math.ceil(width / truth_resolution)), int(math.ceil(height / truth_resolution))
    grid = np.zeros((rows, cols), dtype=np.uint8)

    def to_px(
        x: NDArray[np.float64] | float, y: NDArray[np.float64] | float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return (np.asarray(x) / truth_resolution, rows - np.asarray(y) / truth_resolution)

    def fill_rect(r: Rect, value: int) -> None:
        c0, r1 = to_px(r[0], r[1])
        c1, r0 = to_px(r[2], r[3])
        grid[
            max(int(np.floor(r0)), 0) : int(np.ceil(r1)),
            max(int(np.floor(c0)), 0) : int(np.ceil(c1)),
        ] = value

    def fill_poly(pts: NDArray[np.float64]) -> None:
        px, py = to_px(pts[:, 0], pts[:, 1])
        poly = np.rint(np.column_stack([px, py]) * 16).astype(np.int32)
        cv2.fillPoly(grid, [poly], 1, lineType=cv2.LINE_8, shift=4)

    # outer walls and split walls
    for r in [
        (0, 0, width, t),
        (0, height - t, width, height),
        (0, 0, t, height),
        (width - t, 0, width, height),
    ] + plan.walls:
        fill_rect(r, 1)
    for d in doors:
        fill_rect(d.gap, 0)

    route_arr = np.asarray(route, dtype=float)
    seg_a, seg_b = route_arr[:-1], route_arr[1:]
    for room in rooms:
        if room.corridor:
            continue
        x0, y0, x1, y1 = room.rect
        w, h = x1 - x0, y1 - y0
        # a diagonal wall across one corner, clear of this room's doors and the route
        if rng.random() < chamfer_probability:
            corner = int(rng.integers(4))
            cx, cy = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)][corner]
            sx, sy = (1 if cx == x0 else -1), (1 if cy == y0 else -1)
            lx, ly = rng.uniform(0.2, 0.4) * w, rng.uniform(0.2, 0.4) * h
            tri = np.array([[cx, cy], [cx + sx * lx, cy], [cx, cy + sy * ly]])
            clear = True
            for d in doors:
                if room.index not in d.rooms:
                    continue
                gx0, gy0, gx1, gy1 = d.gap
                dx, dy = 0.5 * (gx0 + gx1), 0.5 * (gy0 + gy1)
                if (abs(dx - cx) < lx + door_width) and (abs(dy - cy) < ly + door_width):
                    clear = False
            if clear:
                fill_poly(tri)
        # clutter: rotated boxes and round pillars, away from the walls and the route
        n = int(rng.poisson(clutter_density * w * h))
        for _ in range(n):
            size = rng.uniform(0.25, 0.8, size=2)
            radius = 0.5 * float(np.hypot(*size))
            if w < 2 * radius + 0.8 or h < 2 * radius + 0.8:
                continue
            p = np.array(
                [
                    rng.uniform(x0 + radius + 0.3, x1 - radius - 0.3),
                    rng.uniform(y0 + radius + 0.3, y1 - radius - 0.3),
                ]
            )
            if seg_a.size and _segment_distance(p, seg_a, seg_b).min() < radius + 0.45:
                continue
            if rng.random() < 0.3:
                cx_, cy_ = to_px(p[0], p[1])
                cv2.circle(
                    grid,
                    (int(round(float(cx_))), int(round(float(cy_)))),
                    max(1, int(round(0.5 * size[0] / truth_resolution))),
                    1,
                    -1,
                )
            else:
                ang = rng.uniform(0, math.pi)
                c, s = math.cos(ang), math.sin(ang)
                half = 0.5 * size
                corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
                pts = corners @ np.array([[c, s], [-s, c]]) + p
                fill_poly(pts)
    return Building(
        width=float(width),
        height=float(height),
        rooms=tuple(rooms),
        doors=tuple(doors),
        grid=grid.astype(bool),
        truth_resolution=float(truth_resolution),
        route=route_arr,
        spin_at=tuple(spins),
    )
