"""numpy ``.npy`` maps: reading (no pickles) and writing ``nav_msgs/OccupancyGrid`` values."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import MapError, MapFormatError, MapSizeError
from ..grid import OCCUPIED, UNKNOWN, OccupancyMap
from ..limits import max_cells
from ._files import one_line, read_file_bytes

__all__ = ["ROW_ORDERS", "check_npy_header", "decode_npy", "encode_npy", "is_occupancy_grid_values"]

#: Row orders of a ``.npy`` array: ``"ros"`` (row 0 is the origin row, at the bottom of the
#: map: what ``np.array(msg.data).reshape(h, w)`` gives for a ``nav_msgs/OccupancyGrid``)
#: or ``"image"`` (row 0 is the top row, as in a PGM/PNG and in :class:`OccupancyMap`).
ROW_ORDERS: tuple[str, ...] = ("ros", "image")


def is_occupancy_grid_values(arr: NDArray[np.generic]) -> bool:
    """True for an integer array read as ``nav_msgs/OccupancyGrid`` values (-1, 0..100).

    Integers holding -1, 0 and 1 with at least one 1 are the three states of
    :class:`OccupancyMap` instead; every other integer array is OccupancyGrid values.
    """
    if not np.issubdtype(arr.dtype, np.integer) or not arr.size:
        return False
    low, high = int(arr.min()), int(arr.max())
    return not (low >= -1 and high == 1)


def decode_npy(
    path: Path,
    *,
    resolution: float | None = None,
    origin: tuple[float, float, float] | None = None,
    row_order: str | None = None,
) -> OccupancyMap:
    """Load a 2D ``.npy`` array as a map.

    Accepted contents:

    * ``bool``: True occupied, False free;
    * integers holding only -1, 0 and 1: the three states of :class:`OccupancyMap`
      (1 is occupied). A ``nav_msgs/OccupancyGrid`` holding nothing but 1 % occupancy is
      implausible, so this reading is unambiguous in practice;
    * other integers: ``nav_msgs/OccupancyGrid`` values, -1 unknown and 0..100 percent,
      thresholded by :meth:`OccupancyMap.from_array` (>= 65 occupied, <= 19 free);
    * floats: occupancy probabilities in [0, 1] (NaN or inf is an error).

    Row order (``row_order``): ``nav_msgs/OccupancyGrid`` values are taken in ROS order by
    default, as the rosbag reader takes them: row 0 of the array is the origin row, the
    *bottom* of the map (``np.array(msg.data).reshape(h, w)``), so the rows are flipped into
    the image order of :class:`OccupancyMap`. Boolean, three-state and float arrays are
    taken in image order (row 0 at the top) by default. ``row_order="ros"`` or ``"image"``
    says it for any array.

    Raises
    ------
    MapFormatError
        Not a valid ``.npy`` file, or an object/pickled array.
    MapError
        Not 2D, NaN values, values out of range.
    MapSizeError
        Larger than :func:`~brokenness.limits.max_cells`, whatever the number of dimensions
        (checked from the header, before any allocation).
    """
    name = str(path)
    data = read_file_bytes(path, what=".npy array")
    check_npy_header(data, name)  # every check on the header, before numpy allocates anything
    try:
        arr = np.load(io.BytesIO(data), allow_pickle=False)
    except ValueError as exc:
        raise MapFormatError(f"{name}: unreadable .npy array ({one_line(exc)})") from None
    except Exception as exc:  # OSError, EOFError, struct errors on a damaged file
        raise MapFormatError(f"{name}: corrupt or truncated .npy file ({one_line(exc)})") from None
    if not isinstance(arr, np.ndarray):
        raise MapFormatError(f"{name}: not a single numpy array")
    try:
        if arr.ndim != 2:
            raise MapError(f"a map must be a 2D array, got shape {arr.shape}")
        ros = is_occupancy_grid_values(arr) if row_order is None else row_order == "ros"
        if ros:
            arr = arr[::-1]
        if np.issubdtype(arr.dtype, np.integer) and arr.size:
            low, high = int(arr.min()), int(arr.max())
            if low >= -1 and high == 1:
                return OccupancyMap(
                    arr.astype(np.int8), resolution=resolution, origin=origin, source=name
                )
        return OccupancyMap.from_array(arr, resolution=resolution, origin=origin, source=name)
    except MapError as exc:
        raise type(exc)(f"{name}: {exc}") from None
    except (TypeError, ValueError) as exc:  # complex, structured, string arrays...
        raise MapFormatError(f"{name}: unsupported array ({one_line(exc)})") from None


def check_npy_header(data: bytes, name: str) -> tuple[tuple[int, ...], np.dtype[Any]]:
    """Validate the header of ``.npy`` bytes before numpy allocates the array.

    Parameters
    ----------
    data : bytes
        The whole ``.npy`` file.
    name : str
        The file, for messages.

    Returns
    -------
    shape : tuple of int
    dtype : numpy.dtype

    Raises
    ------
    MapFormatError
        A bad header, an object (pickled) array, or fewer data bytes than the header claims.
    MapSizeError
        More cells than :func:`~brokenness.limits.max_cells`, whatever the number of
        dimensions.
    MapError
        Not a 2D array.
    """
    stream = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(stream)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(stream)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(stream)
    except Exception as exc:  # numpy raises ValueError or others on a bad header
        raise MapFormatError(f"{name}: not a valid .npy file ({one_line(exc)})") from None
    cells = math.prod(shape)
    if cells > max_cells():
        raise MapSizeError(
            f"{name}: array of shape {shape} ({cells} cells) is larger than the limit of "
            f"{max_cells()} cells"
        )
    if len(shape) != 2:
        raise MapError(f"{name}: a map must be a 2D array, got shape {shape}")
    if dtype.hasobject:
        raise MapFormatError(f"{name}: unreadable .npy array (object arrays are refused)")
    need = cells * dtype.itemsize
    have = len(data) - stream.tell()
    if need > have:
        raise MapFormatError(
            f"{name}: truncated .npy file ({have} of {need} bytes of data for shape {shape})"
        )
    return shape, dtype


def encode_npy(states: NDArray[np.int8]) -> bytes:
    """``.npy`` bytes of ``nav_msgs/OccupancyGrid`` values: -1 unknown, 0 free, 100 occupied.

    In ROS row order (row 0 = the bottom row of the map, as ``OccupancyGrid.data``), the
    order :func:`decode_npy` reads such values in by default.
    """
    states = states[::-1]
    nav = np.zeros(states.shape, dtype=np.int8)
    nav[states == OCCUPIED] = 100
    nav[states == UNKNOWN] = -1
    buf = io.BytesIO()
    np.save(buf, nav, allow_pickle=False)
    return buf.getvalue()
