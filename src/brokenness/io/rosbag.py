"""Read an occupancy map straight from a ROS 1 or ROS 2 bag, without a ROS install.

The map is the **last** ``nav_msgs/OccupancyGrid`` message on a topic (``/map`` by default),
read with the pure-Python ``rosbags`` package:

* ROS 1: a ``.bag`` file.
* ROS 2: a bag folder with ``metadata.yaml`` (SQLite3 ``.db3`` or MCAP storage), or one
  ``.db3`` / ``.mcap`` storage file. A storage file inside a bag folder is read through the
  folder; a lone storage file (``metadata.yaml`` lost) is read directly.

Message types are taken from the definitions stored in the bag; a bag without them
(old ROS 2 SQLite bags) falls back to the ROS 2 Humble type store, whose
``nav_msgs/msg/OccupancyGrid`` is the same in every ROS 1 and ROS 2 release.

Conversion (``nav_msgs/MapMetaData`` semantics):

* ``data`` is row-major starting at the cell ``(0, 0)`` of the grid, which lies at
  ``info.origin`` -- the **bottom-left** corner when the origin's yaw is 0. Rows are flipped
  so that row 0 is the top row, as everywhere in this package.
* Values ``-1`` (unknown) and ``0..100`` (occupancy in percent) are thresholded by
  :meth:`brokenness.OccupancyMap.from_array` (>= 65 occupied, <= 19 free, ``map_saver``'s
  thresholds).
* ``info.resolution`` is the resolution; ``info.origin`` gives ``(x, y, yaw)`` of the
  lower-left corner, yaw from the quaternion (the same meaning as a ``map_server`` YAML),
  with the same range as a YAML origin (finite, ``|x|, |y| <=``
  :data:`~brokenness.limits.MAX_COORDINATE`).

Before the bag reader opens anything, every file it could open must be a regular file (no
FIFO, device or socket: opening one would block or never end): a ``.bag`` or storage file
itself, and for a rosbag2 folder *every* file in the folder, whatever ``metadata.yaml`` lists.
A rosbag2 ``metadata.yaml`` must be at most :data:`~brokenness.limits.MAX_TEXT_BYTES` and is
parsed first by the package's strict YAML reader (:func:`brokenness.io._yaml.parse_yaml`: no
aliases, no duplicate keys), so the bag reader never parses a huge or hostile one.

References
----------
.. [1] ``nav_msgs/OccupancyGrid`` and ``nav_msgs/MapMetaData``,
   https://docs.ros.org/en/rolling/p/nav_msgs/
.. [2] ``rosbags``, https://ternaris.gitlab.io/rosbags/
"""

from __future__ import annotations

import math
import os
import stat
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any

import numpy as np

from .._optional import require
from ..errors import BrokennessError, MapError, MapFormatError, ParameterError
from ..grid import OccupancyMap
from ..limits import MAX_COORDINATE, MAX_TEXT_BYTES, check_cells, resolution_in_range
from ._files import (
    REASON_CHARS,
    as_path,
    check_regular,
    one_line,
    path_text,
    read_file_bytes,
    shown,
    stat_path,
)
from ._yaml import parse_yaml

__all__ = [
    "MAX_PERIOD",
    "OCCUPANCY_GRID",
    "BagMap",
    "check_bag",
    "count_bag_maps",
    "iter_bag_maps",
    "load_bag_map",
    "quaternion_yaw",
    "thinning",
]

#: Message type of an occupancy grid, as ``rosbags`` names it for ROS 1 and ROS 2 alike.
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
_STORAGE_SUFFIXES = (".db3", ".mcap")
_MAX_NS = 2**63 - 1  # bag time stamps: signed 64-bit nanoseconds
#: Longest thinning period, seconds: the span of a bag's 64-bit nanosecond time stamps.
MAX_PERIOD: float = _MAX_NS / 1e9


def quaternion_yaw(x: float, y: float, z: float, w: float) -> float:
    """Yaw (rotation about z, radians in (-pi, pi]) of a quaternion.

    The quaternion need not be normalised. For a pure yaw rotation
    ``(0, 0, sin(t/2), cos(t/2))`` the result is ``t``.
    """
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def require_rosbags(what: str) -> None:
    """Raise :class:`~brokenness.errors.MissingDependencyError` unless the optional package
    ``rosbags`` (the extra ``brokenness[rosbags]``) can be imported; ``what`` names the
    feature in the message ("reading ROS bags")."""
    require("rosbags", what, "package rosbags", "rosbags")


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _grid_to_map(msg: Any, source: str) -> OccupancyMap:
    """An :class:`OccupancyMap` from a deserialised ``nav_msgs/OccupancyGrid``.

    ``source`` becomes the map's source; messages show it through
    :func:`~brokenness.io._files.path_text`.
    """
    name = path_text(source)
    info = msg.info
    width, height = int(info.width), int(info.height)
    if width <= 0 or height <= 0:
        raise MapFormatError(f"{name}: the OccupancyGrid is empty ({width}x{height} cells)")
    check_cells(height, width, f"{name}: OccupancyGrid")
    if not resolution_in_range(float(info.resolution)):
        raise MapFormatError(
            f"{name}: the OccupancyGrid's resolution {float(info.resolution)!r} is out of range"
        )
    data = np.asarray(msg.data)
    if data.size != width * height:
        raise MapFormatError(
            f"{name}: the OccupancyGrid has {data.size} values for {width}x{height} cells"
        )
    grid = data.astype(np.int8, copy=False).reshape(height, width)[::-1]  # row 0 = top
    q = info.origin.orientation
    origin = (
        float(info.origin.position.x),
        float(info.origin.position.y),
        quaternion_yaw(float(q.x), float(q.y), float(q.z), float(q.w)),
    )
    if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in origin):
        raise MapFormatError(
            f"{name}: the OccupancyGrid's origin {shown(origin)} is out of range (finite, "
            f"|value| <= {MAX_COORDINATE:g}, as for a map YAML)"
        )
    try:
        return OccupancyMap.from_array(  # percent values, whatever they hold
            grid,
            resolution=float(info.resolution),
            origin=origin,
            source=source,
            occupancy_grid=True,
        )
    except MapError as exc:
        raise MapFormatError(f"{name}: bad OccupancyGrid: {exc}") from None


def _pick(connections: Iterable[Any], topic: str, source: str) -> list[Any]:
    """The connections of ``topic``; one-line errors when it is missing or of another type.

    Topic and type names come from the bag: the message shows them shortened.
    """
    name = path_text(source)
    conns = list(connections)
    on_topic = [c for c in conns if c.topic == topic]
    if not on_topic:
        grids = sorted({str(c.topic) for c in conns if c.msgtype == OCCUPANCY_GRID})
        hint = (
            f"; OccupancyGrid topics: {_names(grids)}"
            if grids
            else "; the bag has no OccupancyGrid topic"
        )
        raise MapError(f"{name}: no topic {shown(topic)} in the bag{hint}")
    wrong = sorted({str(c.msgtype) for c in on_topic if c.msgtype != OCCUPANCY_GRID})
    if wrong:
        raise MapFormatError(
            f"{name}: topic {shown(topic)} carries {_names(wrong)}, not nav_msgs/OccupancyGrid"
        )
    return on_topic


def _names(names: list[str], most: int = 8) -> str:
    """``a, b, c`` of names read from a bag, each shortened, at most ``most`` of them."""
    parts = [n if n.isprintable() and len(n) <= 80 else shown(n) for n in names[:most]]
    more = len(names) - most
    return ", ".join(parts) + (f" and {more} more" if more > 0 else "")


def _last_message(reader: Any, connections: list[Any]) -> bytes | None:
    """Raw bytes of the last message (latest time stamp; ties: the last one read)."""
    last: tuple[int, bytes] | None = None
    for _conn, stamp, raw in reader.messages(connections=connections):
        if last is None or stamp >= last[0]:
            last = (stamp, bytes(raw))
    return None if last is None else last[1]


def _read_any(paths: list[Path], topic: str, source: str) -> OccupancyMap:
    from rosbags.highlevel import AnyReader

    with AnyReader(paths, default_typestore=_typestore()) as reader:
        conns = _pick(reader.connections, topic, source)
        raw = _last_message(reader, conns)
        if raw is None:
            raise MapError(f"{path_text(source)}: no message on topic {shown(topic)}")
        msg = reader.deserialize(raw, OCCUPANCY_GRID)
    return _grid_to_map(msg, source)


def _read_storage_file(path: Path, topic: str, source: str) -> OccupancyMap:
    """A lone rosbag2 storage file (no ``metadata.yaml``): read with its storage plugin."""
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    storage: McapReader | Sqlite3Reader = (
        McapReader(path) if path.suffix.lower() == ".mcap" else Sqlite3Reader(path)
    )
    storage.open()
    try:
        conns = _pick(storage.connections, topic, source)
        raw = _last_message(storage, conns)
    finally:
        storage.close()
    if raw is None:
        raise MapError(f"{path_text(source)}: no message on topic {shown(topic)}")
    msg = _typestore().deserialize_cdr(raw, OCCUPANCY_GRID)
    return _grid_to_map(msg, source)


def _metadata(meta: Path) -> Any:
    """A rosbag2 ``metadata.yaml``, parsed: a regular file of at most
    :data:`~brokenness.limits.MAX_TEXT_BYTES` bytes, by the package's strict YAML reader.

    Raises
    ------
    MapError
        Not a regular file, unreadable; :class:`~brokenness.errors.MapSizeError` if larger
        than the limit; :class:`MapFormatError` if not valid YAML (aliases, duplicate keys...).
    """
    data = read_file_bytes(meta, MAX_TEXT_BYTES, "rosbag2 metadata file")
    return parse_yaml(data, path_text(meta))


def _listed_names(doc: Any) -> list[str]:
    """File names in a parsed ``metadata.yaml``'s ``relative_file_paths`` (none if it has none).

    The bag reader opens ``folder / PurePath(entry).name`` for each entry.
    """
    try:
        names = doc["rosbag2_bagfile_information"]["relative_file_paths"]
    except (LookupError, TypeError):
        return []
    if not isinstance(names, list):
        return []
    return [PurePath(n).name for n in names if isinstance(n, str)]


def _check_bag_folder(folder: Path) -> None:
    """Every file of a rosbag2 folder must be a regular file, and its metadata.yaml valid.

    The bag reader opens every file ``metadata.yaml`` lists, whatever its name, so every file
    in the folder is checked (sub-folders, which it never reads, are skipped) before anything
    is opened. Then ``metadata.yaml`` is read and parsed, bounded (:func:`_metadata`). A
    folder without ``metadata.yaml`` is never read (the readers say it needs one).
    """
    meta = folder / "metadata.yaml"
    if not os.path.lexists(meta):
        return
    try:
        entries = sorted(os.listdir(folder))
    except OSError as exc:
        reason = one_line(exc.strerror or exc, REASON_CHARS)
        raise MapError(f"{path_text(folder)}: cannot list the bag folder ({reason})") from None
    for entry in entries:
        item = folder / entry
        if not os.path.isdir(item):
            check_regular(item, "rosbag2 file")
    _metadata(meta)


def _check_bag_files(p: Path) -> Path | None:
    """Check every file the bag reader would open; the rosbag2 folder it would read, if any.

    Returns
    -------
    Path or None
        ``p`` for a rosbag2 folder; the folder of a storage file that its folder's
        ``metadata.yaml`` lists (it is read through the folder); None for a ``.bag`` file or
        a lone storage file.
    """
    if stat.S_ISDIR(stat_path(p).st_mode):
        _check_bag_folder(p)
        return p
    check_regular(p, "rosbag")
    meta = p.parent / "metadata.yaml"
    if p.suffix.lower() not in _STORAGE_SUFFIXES or not os.path.lexists(meta):
        return None
    if p.name not in _listed_names(_metadata(meta)):
        return None
    _check_bag_folder(p.parent)
    return p.parent


def _checked_bag(path: str | os.PathLike[str]) -> tuple[Path, Path | None]:
    """:func:`check_bag`, with the rosbag2 folder to read through (see _check_bag_files)."""
    p = as_path(path, "bag")
    return p, _check_bag_files(p)


def check_bag(path: str | os.PathLike[str]) -> Path:
    """Refuse a bag that is missing or whose files are not all regular files.

    Nothing is opened but a rosbag2 ``metadata.yaml`` (itself checked first, read within
    :data:`~brokenness.limits.MAX_TEXT_BYTES` bytes and parsed without aliases), so a FIFO or
    a device (``/dev/zero`` through a symbolic link...) fails at once instead of blocking or
    being read forever. In a rosbag2 folder every file is checked, listed or not.

    Parameters
    ----------
    path : path-like
        A ROS 1 ``.bag``, a rosbag2 folder or a rosbag2 ``.db3`` / ``.mcap`` file.

    Returns
    -------
    Path

    Raises
    ------
    MapError
        Missing path, or a FIFO, device, socket or directory where a bag file should be.
    MapSizeError
        A ``metadata.yaml`` larger than :data:`~brokenness.limits.MAX_TEXT_BYTES`.
    MapFormatError
        A ``metadata.yaml`` that is not valid YAML (aliases and duplicate keys refused).
    ParameterError
        If ``path`` is not a path at all (``None``...).
    """
    return _checked_bag(path)[0]


def thinning(
    every: int, period: float | None, error: type[BrokennessError] = ParameterError
) -> int | None:
    """Check ``every`` and ``period`` (seconds); the period in nanoseconds (None without).

    A period is kept as 64-bit nanoseconds, as bag time stamps are, so it must be finite,
    non-negative and at most :data:`MAX_PERIOD` seconds (about 292 years).

    Raises
    ------
    BrokennessError
        Of class ``error``, for a bad ``every`` or ``period``.
    """
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise error(f"every must be a positive integer, got {shown(every)}")
    if period is None:
        return None
    try:
        seconds = float(period)
    except (TypeError, ValueError):
        seconds = math.nan
    if not (math.isfinite(seconds) and 0 <= seconds <= MAX_PERIOD):
        raise error(
            f"period must be a number of seconds in [0, {MAX_PERIOD:.4g}] (bag time stamps "
            f"are 64-bit nanoseconds), got {shown(period)}"
        )
    return min(round(seconds * 1e9), _MAX_NS)


def load_bag_map(path: str | os.PathLike[str], topic: str = "/map") -> OccupancyMap:
    """Load the last ``nav_msgs/OccupancyGrid`` on ``topic`` from a ROS 1 or ROS 2 bag.

    Parameters
    ----------
    path : path-like
        A ROS 1 ``.bag`` file, a rosbag2 folder (with ``metadata.yaml``), or a rosbag2
        ``.db3`` / ``.mcap`` storage file.
    topic : str
        The map topic (default ``/map``).

    Returns
    -------
    OccupancyMap
        Row 0 at the top; ``resolution`` and ``origin`` (x, y, yaw of the lower-left
        corner) from the message's ``info``; ``source`` is the path as given.

    Raises
    ------
    MapError
        Missing path, a FIFO, device or socket among the bag's files (refused before
        anything is opened), no such topic, no message on the topic.
    MapFormatError
        Corrupt or unreadable bag, a topic of another message type, an inconsistent grid.
    MissingDependencyError
        If the optional package ``rosbags`` is not installed.

    Examples
    --------
    >>> m = load_bag_map("run_2026-11-20.bag", topic="/map")  # doctest: +SKIP
    >>> m.shape, m.resolution, m.origin  # doctest: +SKIP
    ((384, 384), 0.05, (-10.0, -10.0, 0.0))
    """
    p, folder = _checked_bag(path)
    source = str(path)
    name = path_text(source)
    if not isinstance(topic, str) or not topic:
        raise MapError(f"{name}: the topic must be a non-empty string, got {shown(topic)}")
    suffix = p.suffix.lower()
    require_rosbags("reading ROS bags")
    try:
        if folder is not None:
            if not os.path.isfile(folder / "metadata.yaml"):
                raise MapFormatError(f"{name}: a rosbag2 folder needs a metadata.yaml")
            return _read_any([folder], topic, source)
        if suffix == ".bag":
            return _read_any([p], topic, source)
        if suffix in _STORAGE_SUFFIXES:
            return _read_storage_file(p, topic, source)
        raise MapFormatError(f"{name}: not a rosbag (.bag, .db3, .mcap or a rosbag2 folder)")
    except MapError:
        raise
    except MemoryError:
        raise MapFormatError(f"{name}: the bag is too large to read") from None
    except Exception as exc:  # rosbags raises many kinds on damaged files
        text = one_line(exc, REASON_CHARS) or type(exc).__name__
        raise MapFormatError(f"{name}: cannot read the bag ({text})") from None


# -- every message ----------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class BagMap:
    """One map message of a bag, as :func:`iter_bag_maps` yields it.

    Attributes
    ----------
    index : int
        Position of the message on its topic (0-based, counting every message, also those
        thinned out).
    stamp_ns : int
        Time the bag recorded the message, nanoseconds.
    header_stamp : float or None
        ``header.stamp`` of the message, seconds (``None`` when it is zero).
    map : OccupancyMap
        The map (as :func:`load_bag_map` reads it).
    """

    index: int
    stamp_ns: int
    header_stamp: float | None
    map: OccupancyMap


@contextmanager
def _open_raw(
    p: Path, folder: Path | None, topic: str, source: str
) -> Iterator[tuple[Iterator[tuple[int, bytes]], Callable[[bytes], Any], int | None]]:
    """(stamp, raw) of every message on ``topic``, a deserialiser, and the message count.

    ``p`` and ``folder`` are what :func:`_checked_bag` returned: every file is checked.
    """
    if folder is not None:
        if not os.path.isfile(folder / "metadata.yaml"):
            raise MapFormatError(f"{path_text(source)}: a rosbag2 folder needs a metadata.yaml")
        paths = [folder]
    elif p.suffix.lower() == ".bag":
        paths = [p]
    elif p.suffix.lower() in _STORAGE_SUFFIXES:
        from rosbags.rosbag2.storage_mcap import McapReader
        from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

        storage: McapReader | Sqlite3Reader = (
            McapReader(p) if p.suffix.lower() == ".mcap" else Sqlite3Reader(p)
        )
        storage.open()
        try:
            conns = _pick(storage.connections, topic, source)
            store = _typestore()
            raw = ((stamp, bytes(data)) for _c, stamp, data in storage.messages(connections=conns))
            yield raw, lambda b: store.deserialize_cdr(b, OCCUPANCY_GRID), None
        finally:
            storage.close()
        return
    else:
        raise MapFormatError(
            f"{path_text(source)}: not a rosbag (.bag, .db3, .mcap or a rosbag2 folder)"
        )
    from rosbags.highlevel import AnyReader

    with AnyReader(paths, default_typestore=_typestore()) as reader:
        conns = _pick(reader.connections, topic, source)
        counts = [getattr(c, "msgcount", None) for c in conns]
        total: int | None = sum(int(n) for n in counts if isinstance(n, int))
        if not all(isinstance(n, int) for n in counts):
            total = None
        raw = ((stamp, bytes(data)) for _c, stamp, data in reader.messages(connections=conns))
        yield raw, lambda b: reader.deserialize(b, OCCUPANCY_GRID), total


def _thinned(
    raw: Iterator[tuple[int, bytes]], every: int, period_ns: int | None
) -> Iterator[tuple[int, int, bytes]]:
    """(index, stamp, raw) of the messages kept; the last message is always kept."""
    kept_stamp: int | None = None
    held: tuple[int, int, bytes] | None = None  # latest not kept: kept if it is the last
    for i, (stamp, data) in enumerate(raw):
        if period_ns is not None:
            keep = kept_stamp is None or stamp - kept_stamp >= period_ns
        else:
            keep = i % every == 0
        if keep:
            held, kept_stamp = None, stamp
            yield i, stamp, data
        else:
            held = (i, stamp, data)
    if held is not None:
        yield held


def iter_bag_maps(
    path: str | os.PathLike[str],
    topic: str = "/map",
    *,
    every: int = 1,
    period: float | None = None,
) -> Iterator[BagMap]:
    """Every ``nav_msgs/OccupancyGrid`` on ``topic`` of a ROS 1 or ROS 2 bag, lazily.

    One message is deserialised at a time (and only the messages kept), so memory stays at
    one map however long the bag is. Messages come in the order of their bag time stamps.

    Parameters
    ----------
    path : path-like
        As for :func:`load_bag_map`.
    topic : str
        The map topic (default ``/map``).
    every : int
        Keep every ``every``-th message (the first, then every ``every``-th after it).
    period : float, optional
        Instead: keep a message when at least ``period`` seconds (bag time) have passed since
        the last one kept. With either, the last message of the topic is always kept.

    Yields
    ------
    BagMap

    Raises
    ------
    MapError
        Missing path, a FIFO, device or socket among the bag's files, no such topic, bad
        ``every`` / ``period`` (see :func:`thinning`; :func:`brokenness.timeline` raises a
        ParameterError for these).
    MapFormatError
        Corrupt bag, a topic of another message type, an inconsistent grid.
    MissingDependencyError
        If the optional package ``rosbags`` is not installed.
    """
    p, folder = _checked_bag(path)
    source = str(path)
    name = path_text(source)
    if not isinstance(topic, str) or not topic:
        raise MapError(f"{name}: the topic must be a non-empty string, got {shown(topic)}")
    period_ns = thinning(every, period, MapError)
    require_rosbags("reading ROS bags")
    try:
        with _open_raw(p, folder, topic, source) as (raw, deserialize, _total):
            for i, stamp, data in _thinned(raw, every, period_ns):
                msg = deserialize(data)
                del data
                st = msg.header.stamp
                header = float(st.sec) + 1e-9 * float(st.nanosec)
                m = _grid_to_map(msg, f"{source}#{topic}[{i}]")
                del msg
                yield BagMap(i, int(stamp), header if header > 0 else None, m)
    except MapError:
        raise
    except MemoryError:
        raise MapFormatError(f"{name}: a message is too large to read") from None
    except GeneratorExit:
        raise
    except Exception as exc:  # rosbags raises many kinds on damaged files
        text = one_line(exc, REASON_CHARS) or type(exc).__name__
        raise MapFormatError(f"{name}: cannot read the bag ({text})") from None


def count_bag_maps(path: str | os.PathLike[str], topic: str = "/map") -> int | None:
    """Messages on ``topic`` as the bag's index says (``None`` when it does not say)."""
    try:
        p, folder = _checked_bag(path)
        with _open_raw(p, folder, topic, str(path)) as (_raw, _deserialize, total):
            return total
    except Exception:  # the reading itself reports the errors
        return None
