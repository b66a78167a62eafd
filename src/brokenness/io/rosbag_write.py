"""Write occupancy maps into a ROS 1 or ROS 2 bag as ``nav_msgs/OccupancyGrid`` messages.

The inverse of :func:`brokenness.io.rosbag.iter_bag_maps`, without a ROS install (the
pure-Python ``rosbags`` writers): what a SLAM node would have recorded on ``/map``. Used to
make bags of simulated runs (tests, examples, benchmarks). States become the message values
``100`` (occupied), ``0`` (free) and ``-1`` (unknown); rows are flipped so that the data
starts at the bottom-left cell; ``info.origin`` is the map's ``origin`` (x, y, yaw).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..grid import FREE, OCCUPIED, OccupancyMap
from .rosbag import OCCUPANCY_GRID, require_rosbags

__all__ = ["grid_message", "write_bag_maps"]


def grid_message(
    typestore: Any, m: OccupancyMap, stamp_ns: int, *, ros1: bool, seq: int = 0
) -> Any:
    """A ``nav_msgs/OccupancyGrid`` of ``m`` for a ``rosbags`` type store."""
    types = typestore.types
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    t = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
    header_t = types["std_msgs/msg/Header"]
    header = (
        header_t(seq=seq, stamp=t, frame_id="map") if ros1 else header_t(stamp=t, frame_id="map")
    )
    x, y, yaw = m.origin if m.origin is not None else (0.0, 0.0, 0.0)
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
        ),
    )
    rows, cols = m.shape
    info = types["nav_msgs/msg/MapMetaData"](
        map_load_time=t,
        resolution=float(m.resolution or 1.0),
        width=cols,
        height=rows,
        origin=pose,
    )
    values = np.full(m.shape, -1, np.int8)
    values[m.states == FREE] = 0
    values[m.states == OCCUPIED] = 100
    data = np.ascontiguousarray(values[::-1]).ravel()  # ROS: bottom row first
    return types[OCCUPANCY_GRID](header=header, info=info, data=data)


def write_bag_maps(
    path: str | os.PathLike[str],
    maps: Iterable[tuple[int, OccupancyMap]],
    *,
    topic: str = "/map",
    ros: int = 1,
) -> Path:
    """Write ``(stamp_ns, map)`` pairs (lazily, one at a time) as a bag.

    Parameters
    ----------
    path : path-like
        ROS 1: the ``.bag`` file; ROS 2: the bag folder (SQLite3 storage). Must not exist.
    maps : iterable of (int, OccupancyMap)
        Bag time (nanoseconds, increasing) and map of each message.
    topic : str
    ros : {1, 2}

    Returns
    -------
    Path

    Raises
    ------
    MissingDependencyError
        If the optional package ``rosbags`` is not installed.
    """
    require_rosbags("writing ROS bags")
    from rosbags.typesys import Stores, get_typestore

    p = Path(os.fspath(path))
    if ros == 1:
        from rosbags.rosbag1 import Writer as Writer1

        ts = get_typestore(Stores.ROS1_NOETIC)
        with Writer1(p) as w1:
            conn = w1.add_connection(topic, OCCUPANCY_GRID, typestore=ts)
            for seq, (stamp, m) in enumerate(maps):
                msg = grid_message(ts, m, stamp, ros1=True, seq=seq)
                w1.write(conn, int(stamp), ts.serialize_ros1(msg, OCCUPANCY_GRID))
        return p
    if ros == 2:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        ts = get_typestore(Stores.ROS2_HUMBLE)
        with Writer2(p, version=9, storage_plugin=StoragePlugin.SQLITE3) as w2:
            conn2 = w2.add_connection(topic, OCCUPANCY_GRID, typestore=ts)
            for stamp, m in maps:
                msg = grid_message(ts, m, stamp, ros1=False)
                w2.write(conn2, int(stamp), ts.serialize_cdr(msg, OCCUPANCY_GRID))
        return p
    raise ParameterError(f"ros must be 1 or 2, got {ros!r}")
