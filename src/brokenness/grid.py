"""The occupancy grid every part of :mod:`brokenness` works on.

A map has three cell states, as a ROS ``nav_msgs/OccupancyGrid`` after thresholding:
:data:`OCCUPIED`, :data:`FREE` and :data:`UNKNOWN`. Cell coordinates are
``(x, y) = (column, row)`` of the array as loaded: row 0 is the top row of the image.

Geometry (optional): ``resolution`` in metres per cell and ``origin = (x, y, yaw)``, the
pose in the world frame of the lower-left corner of the lower-left cell, exactly as in a
ROS ``map_server`` YAML file. The world frame has its y axis pointing up, so image rows
run against it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import MapError, MapSizeError
from .limits import (
    MAX_CELLS,
    check_cells,
    check_resolution,
)

__all__ = [
    "FREE",
    "MAX_CELLS",
    "OCCUPIED",
    "UNKNOWN",
    "OccupancyMap",
    "count_state",
    "holds_states",
]

#: Cell state of an occupied cell.
OCCUPIED: int = 1
#: Cell state of a free cell.
FREE: int = 0
#: Cell state of a cell that was never observed.
UNKNOWN: int = -1

# MAX_CELLS (re-exported here): the default largest map, in cells (e.g. 10000 x 10000:
# 500 m x 500 m at 5 cm); the limit in force is brokenness.limits.max_cells(), which the
# environment variable BROKENNESS_MAX_CELLS overrides. Larger inputs raise MapSizeError
# before anything is decoded.


#: Rows of a grid compared at once by :func:`count_state`: a band's comparison stays in the
#: processor's cache, where one of the whole grid would be a fresh temporary of its size.
_COUNT_ROWS = 512


def count_state(states: NDArray[np.int8], state: int) -> int:
    """Number of cells of ``states`` equal to ``state``, counted in bands of rows.

    Parameters
    ----------
    states : ndarray of int8, 2D
    state : int
        :data:`OCCUPIED`, :data:`FREE` or :data:`UNKNOWN`.

    Returns
    -------
    int
    """
    return sum(
        int(np.count_nonzero(states[r : r + _COUNT_ROWS] == state))
        for r in range(0, states.shape[0], _COUNT_ROWS)
    )


def holds_states(array: NDArray[np.integer]) -> bool:
    """True when an integer array holds only the three cell states -1, 0 and 1.

    The rule by which :meth:`OccupancyMap.from_array` (and so every function that takes an
    array as a map) tells cell states from ``nav_msgs/OccupancyGrid`` percent values.
    """
    return bool(array.size) and int(array.min()) >= UNKNOWN and int(array.max()) <= OCCUPIED


def _grid(value: ArrayLike) -> NDArray[Any]:
    """``value`` as a 2D array (a :class:`MapError` for anything else, ragged lists too)."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nested lists, objects numpy cannot take
        raise MapError("a map must be a 2D grid of numbers, rows of one length") from None
    if arr.ndim != 2:
        raise MapError(f"a map must be a 2D grid, got an array of shape {arr.shape}")
    return arr


def _origin(value: object) -> tuple[float, float, float]:
    """An origin as three finite floats ``(x, y, yaw)`` (:class:`MapError` otherwise)."""
    try:
        origin = tuple(float(v) for v in value)  # type: ignore[attr-defined]  # checked here
    except (TypeError, ValueError):
        origin = ()
    if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
        raise MapError(f"origin must be three finite numbers (x, y, yaw), got {value!r}")
    return origin[0], origin[1], origin[2]


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """A 2D occupancy grid with three states and optional world geometry.

    Parameters
    ----------
    states : ndarray of int8, shape (rows, cols)
        :data:`OCCUPIED` (1), :data:`FREE` (0) or :data:`UNKNOWN` (-1) per cell. The array is
        copied if needed and made read-only.
    resolution : float, optional
        Metres per cell, in [:data:`~brokenness.limits.MIN_RESOLUTION`,
        :data:`~brokenness.limits.MAX_RESOLUTION`] (as for a map file). ``None`` when unknown
        (plain images, arrays).
    origin : tuple of 3 floats, optional
        ``(x, y, yaw)`` of the lower-left corner of the map in the world frame (ROS
        ``map_server`` convention), metres and radians. ``None`` when unknown.
    source : str, optional
        Where the map came from (a path), for messages and result files.

    Raises
    ------
    MapError
        If ``states`` is not a 2D grid, holds values other than -1, 0, 1, or the geometry is
        invalid.
    MapSizeError
        If the map has a zero side or more than :func:`brokenness.limits.max_cells` cells.
    """

    states: NDArray[np.int8]
    resolution: float | None = None
    origin: tuple[float, float, float] | None = None
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        states = _grid(self.states)
        rows, cols = states.shape
        if rows == 0 or cols == 0:
            raise MapSizeError(f"a map must have at least one row and column, got {rows}x{cols}")
        check_cells(rows, cols, "map")
        if states.dtype != np.int8 and not np.issubdtype(states.dtype, np.integer):
            raise MapError(f"map states must be integers -1/0/1, got dtype {states.dtype}")
        # the three states are the consecutive integers -1, 0, 1: a grid holds nothing else
        # exactly when its smallest and largest values are within them (two reductions, no
        # temporary grid), checked before the cast to int8, which would wrap 255 to -1
        if int(states.min()) < UNKNOWN or int(states.max()) > OCCUPIED:
            raise MapError("map states must be -1 (unknown), 0 (free) or 1 (occupied)")
        if states.dtype != np.int8:
            states = states.astype(np.int8)
        if states is self.states and states.flags.writeable:
            states = states.copy()
        states.setflags(write=False)
        object.__setattr__(self, "states", states)
        if self.resolution is not None:
            object.__setattr__(self, "resolution", check_resolution(self.resolution, MapError))
        if self.origin is not None:
            object.__setattr__(self, "origin", _origin(self.origin))

    # -- constructors -------------------------------------------------------------------------
    @classmethod
    def from_array(
        cls,
        array: ArrayLike,
        *,
        resolution: float | None = None,
        origin: tuple[float, float, float] | None = None,
        source: str | None = None,
        occupancy_grid: bool = False,
    ) -> OccupancyMap:
        """Build a map from a boolean, cell-state or ``nav_msgs/OccupancyGrid``-style array.

        The one rule by which every function of the package that takes an array as a map
        reads it (:func:`brokenness.compute_brokenness`, :func:`brokenness.register`,
        ``.npy`` files).

        Parameters
        ----------
        array : array_like, 2D
            ``bool``: True is occupied, False is free. Integers holding only -1, 0 and 1
            (:func:`holds_states`): the three cell states (:data:`UNKNOWN`, :data:`FREE`,
            :data:`OCCUPIED`, as :attr:`states`). Other integers: ``nav_msgs/OccupancyGrid``
            values, -1 is unknown, 0..100 an occupancy probability in percent (>= 65
            occupied, <= 19 free, the ROS ``map_saver`` thresholds, else unknown); the two
            readings agree on -1 and 0, and a grid holding nothing but 1 % occupancy is
            implausible. Floats in [0, 1]: probability of occupancy with the same
            thresholds; NaN is rejected.
        resolution, origin, source
            See :class:`OccupancyMap`.
        occupancy_grid : bool, optional
            Integers are ``nav_msgs/OccupancyGrid`` values whatever they hold (for a reader
            that knows where they come from, a ROS bag's grid).

        Returns
        -------
        OccupancyMap

        Raises
        ------
        MapError
            If ``array`` is not a 2D grid of numbers, or holds values out of range.
        """
        arr = _grid(array)
        if arr.dtype == bool:
            states = np.where(arr, OCCUPIED, FREE).astype(np.int8)
        elif np.issubdtype(arr.dtype, np.integer) and not occupancy_grid and holds_states(arr):
            states = arr.astype(np.int8)
        elif np.issubdtype(arr.dtype, np.integer):
            if arr.size and (arr.min() < -1 or arr.max() > 100):
                raise MapError("integer maps must hold -1 (unknown) or 0..100 (occupancy %)")
            states = np.full(arr.shape, UNKNOWN, dtype=np.int8)
            states[(arr >= 0) & (arr <= 19)] = FREE
            states[arr >= 65] = OCCUPIED
        elif np.issubdtype(arr.dtype, np.floating):
            if not np.isfinite(arr).all():
                raise MapError("map array holds NaN or infinite values")
            if arr.size and (arr.min() < 0.0 or arr.max() > 1.0):
                raise MapError("float maps must hold occupancy probabilities in [0, 1]")
            states = np.full(arr.shape, UNKNOWN, dtype=np.int8)
            states[arr <= 0.196] = FREE
            states[arr >= 0.65] = OCCUPIED
        else:
            raise MapError(f"cannot read a map from an array of dtype {arr.dtype}")
        return cls(states, resolution=resolution, origin=origin, source=source)

    # -- views --------------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the grid."""
        return (int(self.states.shape[0]), int(self.states.shape[1]))

    @property
    def occupied(self) -> NDArray[np.bool_]:
        """Boolean mask of occupied cells."""
        return self.states == OCCUPIED

    @property
    def free(self) -> NDArray[np.bool_]:
        """Boolean mask of free cells."""
        return self.states == FREE

    @property
    def known(self) -> NDArray[np.bool_]:
        """Boolean mask of cells that are occupied or free."""
        return self.states != UNKNOWN

    @property
    def n_occupied(self) -> int:
        """Number of occupied cells."""
        return count_state(self.states, OCCUPIED)

    @property
    def has_geometry(self) -> bool:
        """True when both resolution and origin are known."""
        return self.resolution is not None and self.origin is not None

    def cell_to_world_matrix(self) -> NDArray[np.float64]:
        """3x3 homogeneous matrix taking cell coordinates ``(x, y)`` to world metres.

        The centre of cell ``(x, y)`` (column, row) lies at
        ``origin + R(yaw) @ (res * (x + 0.5), res * (rows - y - 0.5))``.

        Raises
        ------
        MapError
            If the map has no resolution or origin.
        """
        if self.resolution is None or self.origin is None:
            raise MapError("this map has no resolution/origin, so it has no world frame")
        res = self.resolution
        ox, oy, yaw = self.origin
        c, s = math.cos(yaw), math.sin(yaw)
        rows = self.shape[0]
        # cell -> map-aligned metres (y flipped), then rotate by yaw and shift by origin
        flip = np.array([[res, 0.0, 0.5 * res], [0.0, -res, (rows - 0.5) * res], [0, 0, 1]])
        rot = np.array([[c, -s, ox], [s, c, oy], [0, 0, 1.0]])
        return rot @ flip

    def with_states(self, states: NDArray[np.int8]) -> OccupancyMap:
        """A copy of this map with other states of the same shape and the same geometry."""
        if states.shape != self.states.shape:
            raise MapError(f"shape {states.shape} differs from the map's {self.states.shape}")
        return OccupancyMap(states, self.resolution, self.origin, self.source)

    def __repr__(self) -> str:
        rows, cols = self.shape
        geo = f", resolution={self.resolution}" if self.resolution is not None else ""
        src = f", source={self.source!r}" if self.source else ""
        return f"OccupancyMap({cols}x{rows}, occupied={self.n_occupied}{geo}{src})"
