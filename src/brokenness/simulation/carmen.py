"""CARMEN laser logs: read them, map them, and break them with bump noise.

A CARMEN log is a text file (often gzip'd) with one message per line. This module reads the
laser messages with their (SLAM-corrected) poses:

``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp``
    The old front-laser message. ``x y theta`` is the pose of the laser (in the
    Radish ``*-corrected`` logs the corrected pose). The message carries no beam angles; they
    follow the CARMEN convention for a 180 degree scanner (see :func:`flaser_angles`).

``ROBOTLASER1 laser_type start_angle fov angular_resolution max_range accuracy remission_mode
n r_1 .. r_n m e_1 .. e_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv
forward_safety side_safety turn_axis ipc_timestamp host logger_timestamp``
    The newer laser message with its own geometry: beam ``i`` points at
    ``start_angle + i * angular_resolution`` from the laser's heading, and readings at or
    beyond ``max_range`` are no returns. The laser pose is used.

Rules (documented, tested):

- gzip is detected by the file's magic bytes (``1f 8b``), not by its name; a gzip file cut
  short is read up to where it ends (the cut line is then skipped as truncated).
- A log (the file, and its text once gunzipped) may have at most :data:`MAX_LOG_BYTES` bytes
  (256 MiB); the text is inflated in bounded steps and refused with a one-line
  :class:`~brokenness.errors.MapSizeError` as soon as it passes the limit, so a small "gzip
  bomb" cannot fill the memory. Only the laser lines are split into fields (reading takes up
  to about 20 bytes of memory per byte of laser text, so a log stays within about 5 GB).
- If a log holds valid ``ROBOTLASER1`` lines, those are used and ``FLASER`` lines are ignored
  (logs that have both carry the same scans twice); otherwise the ``FLASER`` lines are used.
- A laser line that is truncated or malformed (too few or too many fields, a field that is
  not a number, a non-finite number, a beam count < 1) is skipped and counted in
  :attr:`CarmenLog.skipped_lines`; a :class:`~brokenness.MapWarning` says how many.
  Lines may lack the fields after the poses (timestamps, host; not used).
- All scans of a :class:`CarmenLog` share one beam layout. The most common layout (beam count,
  and for ``ROBOTLASER1`` start angle and resolution) is kept; scans with another layout are
  skipped, counted in :attr:`CarmenLog.skipped_scans` and warned about.
- Max range: ``ROBOTLASER1`` logs its own (the largest over the kept scans); for ``FLASER`` it
  is the largest reading in the log (the Radish logs report a no-return as the sensor's maximum,
  e.g. 50, 51.1, 81.91 m; 32.767 m SICK codes in orebro). A reading at or above
  ``(1 - MAX_RANGE_MARGIN) * max_range`` (0.2 % below it: the Radish logs print several
  codes just under the maximum, e.g. 81.83..81.91 or 32.759..32.767) is a *no return*: never
  a hit, and by default it clears no free space either (``clear_no_returns``). Readings
  ``<= 0`` are invalid and ignored.

Mapping (:func:`map_log`) uses :mod:`brokenness.simulation.mapper`; :func:`wall_check` measures
whether a log maps to single walls; :func:`broken_log_map` makes broken maps of the real
building with the bump noise of :mod:`brokenness.simulation.bumps` and the ground truth of
:mod:`brokenness.simulation.ground_truth`.
"""

from __future__ import annotations

import math
import os
import re
import warnings
import zlib
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import MapError, MapFormatError, MapSizeError, ParameterError
from ..grid import OccupancyMap
from ..io import MapWarning
from ..io._files import path_text, read_file_bytes
from .bumps import Bump
from .ground_truth import SimulatedMap, break_run
from .laser import Laser, LaserRun
from .mapper import ScanCounts, counts_to_map, grid_geometry, scan_counts
from .options import BumpOptions, HonestRule

__all__ = [
    "MAX_LOG_BYTES",
    "MAX_RANGE_MARGIN",
    "CarmenLog",
    "WallCheck",
    "broken_log_map",
    "flaser_angles",
    "log_geometry",
    "log_run",
    "map_log",
    "read_carmen",
    "wall_check",
]

#: Relative margin below the max range at which a reading counts as a no return (0.2 %).
MAX_RANGE_MARGIN: float = 0.002

#: Largest CARMEN log read, in bytes: the file, and its text once gunzipped (256 MiB).
MAX_LOG_BYTES: int = 256 << 20

_GZIP_MAGIC = b"\x1f\x8b"
_INFLATE_CHUNK = 16 << 20  # gzip text is inflated this many bytes at a time
#: A laser line: starts with the message name (the first field is checked after splitting).
_LASER_LINE = re.compile(rb"^(?:FLASER|ROBOTLASER1)[^\n]*", re.MULTILINE)


@dataclass(frozen=True, eq=False)
class CarmenLog:
    """The laser scans of a CARMEN log with their poses.

    Attributes
    ----------
    poses : ndarray, shape (N, 3)
        World ``x, y, theta`` of the laser per scan (metres, radians), in file order.
    ranges : ndarray, shape (N, B)
        Readings in metres, as logged.
    angles : ndarray, shape (B,)
        Beam directions relative to the laser's heading, radians.
    max_range : float
        The sensor's maximum range (metres); see :attr:`hit_range`.
    skipped_lines : int
        Laser lines skipped because they were truncated or malformed.
    skipped_scans : int
        Well-formed scans skipped because their beam layout differs from the kept one.
    message : str
        ``"FLASER"`` or ``"ROBOTLASER1"``: which message the scans come from.
    source : str, optional
        The file read.
    """

    poses: NDArray[np.float64]
    ranges: NDArray[np.float64]
    angles: NDArray[np.float64]
    max_range: float
    skipped_lines: int = 0
    skipped_scans: int = 0
    message: str = "FLASER"
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        poses = np.array(self.poses, dtype=np.float64)
        ranges = np.array(self.ranges, dtype=np.float64)
        angles = np.array(self.angles, dtype=np.float64)
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ParameterError(f"poses must have shape (N, 3), got {poses.shape}")
        if angles.ndim != 1 or ranges.shape != (poses.shape[0], angles.shape[0]):
            raise ParameterError(
                f"ranges {ranges.shape} must be (N, B) for {poses.shape[0]} poses and "
                f"{angles.shape[0]} angles"
            )
        if not (math.isfinite(self.max_range) and self.max_range > 0):
            raise ParameterError(f"max_range must be a positive number, got {self.max_range!r}")
        for name, arr in (("poses", poses), ("ranges", ranges), ("angles", angles)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "max_range", float(self.max_range))

    @property
    def n_scans(self) -> int:
        """Number of scans ``N``."""
        return int(self.poses.shape[0])

    @property
    def n_beams(self) -> int:
        """Beams per scan ``B``."""
        return int(self.angles.shape[0])

    @property
    def hit_range(self) -> float:
        """Readings at or above this many metres are no returns (not hits)."""
        return self.max_range * (1.0 - MAX_RANGE_MARGIN)

    @property
    def hits(self) -> NDArray[np.bool_]:
        """Boolean (N, B): readings that are real returns (``0 < r < hit_range``)."""
        return (self.ranges > 0) & (self.ranges < self.hit_range)

    def end_points(self, poses: ArrayLike | None = None) -> NDArray[np.float64]:
        """World ``(x, y)`` of every hit, shape (K, 2), scan by scan, beam by beam.

        Parameters
        ----------
        poses : array_like, shape (N, 3), optional
            Laser poses to use instead of :attr:`poses`.
        """
        p = self.poses if poses is None else _check_poses(poses, self.n_scans)
        hits = self.hits
        heading = p[:, 2:3] + self.angles[None, :]
        x = p[:, 0:1] + self.ranges * np.cos(heading)
        y = p[:, 1:2] + self.ranges * np.sin(heading)
        return np.column_stack([x[hits], y[hits]])

    def select(self, scans: ArrayLike) -> CarmenLog:
        """A log with only some scans (an index array, mask or slice result), same geometry.

        Examples
        --------
        >>> first_half = log.select(np.arange(log.n_scans // 2))  # doctest: +SKIP
        """
        idx = np.arange(self.n_scans)[np.asarray(scans)]
        return CarmenLog(
            self.poses[idx],
            self.ranges[idx],
            self.angles,
            self.max_range,
            self.skipped_lines,
            self.skipped_scans,
            self.message,
            self.source,
        )

    def __repr__(self) -> str:
        src = f", source={self.source!r}" if self.source else ""
        return (
            f"CarmenLog({self.message}, scans={self.n_scans}, beams={self.n_beams}, "
            f"max_range={self.max_range:g}, skipped_lines={self.skipped_lines}, "
            f"skipped_scans={self.skipped_scans}{src})"
        )


def _check_poses(poses: ArrayLike, n: int) -> NDArray[np.float64]:
    p = np.asarray(poses, dtype=np.float64)
    if p.shape != (n, 3):
        raise ParameterError(f"poses must have shape ({n}, 3), got {p.shape}")
    if not np.isfinite(p).all():
        raise ParameterError("poses must be finite")
    return p


def flaser_angles(n: int) -> NDArray[np.float64]:
    """Beam angles of an ``FLASER`` scan of ``n`` beams (radians, from the laser's heading).

    The CARMEN convention for 180 degree SICK scanners: an odd ``n`` spans -90..+90 degrees
    inclusive (181 beams: 1 degree, 361: 0.5 degree); an even ``n`` starts at -90 degrees with a
    step of ``180 / n`` degrees (180 beams: 1 degree, 360: 0.5 degree, ending one step short of
    +90). Other beam counts follow the same two rules (an assumption: FLASER does not record
    its field of view); ``n = 1`` is a single beam straight ahead.

    Examples
    --------
    >>> import numpy as np
    >>> np.degrees(flaser_angles(181)[[0, 1, -1]]).round(6).tolist()
    [-90.0, -89.0, 90.0]
    >>> np.degrees(flaser_angles(360)[[0, 1, -1]]).round(6).tolist()
    [-90.0, -89.5, 89.5]
    """
    if n < 1:
        raise ParameterError(f"a scan needs at least one beam, got {n}")
    if n == 1:
        return np.zeros(1)
    step = math.pi / (n - 1) if n % 2 else math.pi / n
    return -0.5 * math.pi + step * np.arange(n, dtype=np.float64)


# -- reading ------------------------------------------------------------------------------------
def _read_bytes(path: Path, limit: int | None = None) -> bytes:
    """The file's bytes, gunzipped when it starts with the gzip magic (partial if cut short).

    The file must be a regular file of at most ``limit`` bytes (default
    :data:`MAX_LOG_BYTES`), and so must its text.

    Raises
    ------
    MapError
        Missing, not a regular file (a FIFO, a device, a directory), unreadable.
    MapSizeError
        The file, or its gunzipped text, larger than ``limit`` bytes.
    MapFormatError
        An empty file, or a file that starts like gzip but is not.
    """
    cap = MAX_LOG_BYTES if limit is None else limit
    name = path_text(path)
    if not os.path.lexists(path):
        raise MapError(f"no such CARMEN log: {name}")
    data = read_file_bytes(path, cap, "CARMEN log")  # a regular file within the limit
    if not data.startswith(_GZIP_MAGIC):
        return data
    return _gunzip(data, name, cap)


def _gunzip(data: bytes, name: str, limit: int) -> bytes:
    """Every gzip member of ``data`` inflated, in steps of :data:`_INFLATE_CHUNK` bytes.

    Stops with a MapSizeError as soon as the text passes ``limit`` bytes (so a few hundred
    kilobytes that inflate to gigabytes cost at most ``limit``); a stream cut short is read up
    to where it ends, with a warning.
    """
    parts: list[bytes] = []
    total = 0
    rest = data
    first = True
    while rest.startswith(_GZIP_MAGIC):  # gzip files may hold several members
        inflater = zlib.decompressobj(wbits=31)
        pending = rest
        try:
            while True:
                part = inflater.decompress(pending, _INFLATE_CHUNK)
                total += len(part)
                if total > limit:
                    raise MapSizeError(
                        f"{name}: the gunzipped CARMEN log is larger than the limit of "
                        f"{limit} bytes"
                    )
                parts.append(part)
                pending = inflater.unconsumed_tail
                if inflater.eof or (not pending and len(part) < _INFLATE_CHUNK):
                    break  # the member's end, or all input used with more wanted: cut short
        except zlib.error as exc:
            if first:
                raise MapFormatError(f"{name} is not a valid gzip file ({exc})") from None
            break
        if not inflater.eof:
            warnings.warn(
                f"{name}: gzip data ends early; reading what is there", MapWarning, stacklevel=4
            )
            break
        rest = inflater.unused_data
        first = False
    return b"".join(parts)


def _floats(rows: list[list[bytes]]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Rows of equal length -> float array and a mask of rows that parsed and are finite."""
    try:
        arr = np.array(rows, dtype=np.float64)
    except ValueError:  # some field is not a number: parse row by row
        arr = np.full((len(rows), len(rows[0])), np.nan)
        for i, row in enumerate(rows):
            try:
                arr[i] = np.array(row, dtype=np.float64)
            except ValueError:
                pass
    return arr, np.asarray(np.isfinite(arr).all(axis=1))


@dataclass
class _Scans:
    """Well-formed scans of one message type, before the layout is chosen."""

    order: list[NDArray[np.int64]] = field(default_factory=list)  # positions in the file
    key: list[tuple[float, ...]] = field(default_factory=list)  # layout per group
    poses: list[NDArray[np.float64]] = field(default_factory=list)
    ranges: list[NDArray[np.float64]] = field(default_factory=list)
    max_range: list[NDArray[np.float64]] = field(default_factory=list)
    angles: list[NDArray[np.float64]] = field(default_factory=list)
    bad: int = 0


def _parse_flaser(lines: list[tuple[int, list[bytes]]]) -> _Scans:
    out = _Scans()
    groups: dict[int, list[tuple[int, list[bytes]]]] = {}
    for number, tok in lines:
        try:
            n = int(tok[1])
        except (IndexError, ValueError):
            out.bad += 1
            continue
        # n ranges + x y theta + odom x y theta, then optionally ts host logger_ts
        if n < 1 or not (n + 8 <= len(tok) <= n + 11):
            out.bad += 1
            continue
        groups.setdefault(n, []).append((number, tok))
    for n, group in groups.items():
        arr, ok = _floats([tok[2 : n + 5] for _, tok in group])
        out.bad += int(np.count_nonzero(~ok))
        if not ok.any():
            continue
        arr = arr[ok]
        out.order.append(np.array([number for number, _ in group])[ok])
        out.key.append((float(n),))
        out.ranges.append(arr[:, :n])
        out.poses.append(arr[:, n : n + 3])
        out.max_range.append(np.full(len(arr), np.nan))
        out.angles.append(flaser_angles(n))
    return out


def _parse_robotlaser(lines: list[tuple[int, list[bytes]]]) -> _Scans:
    out = _Scans()
    groups: dict[tuple[int, int], list[tuple[int, list[bytes]]]] = {}
    for number, tok in lines:
        try:
            n = int(tok[8])
            m = int(tok[9 + n])
        except (IndexError, ValueError):
            out.bad += 1
            continue
        # ... m remissions, laser pose (3), robot pose (3), tv rv fwd side turn, ts host ts
        if n < 1 or m < 0 or not (16 + n + m <= len(tok) <= 24 + n + m):
            out.bad += 1
            continue
        groups.setdefault((n, m), []).append((number, tok))
    for (n, m), group in groups.items():
        rows = [tok[2:6] + tok[9 : 9 + n] + tok[10 + n + m : 13 + n + m] for _, tok in group]
        arr, ok = _floats(rows)
        arr_ok = arr[ok]
        ok[ok] = arr_ok[:, 3] > 0  # a max range must be positive
        out.bad += int(np.count_nonzero(~ok))
        if not ok.any():
            continue
        arr = arr[ok]
        numbers = np.array([number for number, _ in group])[ok]
        # one layout per distinct (start angle, resolution) pair, rounded to micro-radians
        layout = np.round(arr[:, [0, 2]], 6)
        keys, inverse = np.unique(layout, axis=0, return_inverse=True)
        for k, (start, res) in enumerate(keys):
            sel = inverse.ravel() == k
            out.order.append(numbers[sel])
            out.key.append((float(n), float(start), float(res)))
            out.ranges.append(arr[sel, 4 : 4 + n])
            out.poses.append(arr[sel, 4 + n : 7 + n])
            out.max_range.append(arr[sel, 3])
            first = arr[np.flatnonzero(sel)[0]]  # the logged values, not the rounded key
            out.angles.append(first[0] + first[2] * np.arange(n, dtype=np.float64))
    return out


def read_carmen(path: str | PathLike[str]) -> CarmenLog:
    """Read the laser scans and their poses from a CARMEN log (plain or gzip'd).

    Parameters
    ----------
    path : str or path-like
        A CARMEN log file. gzip compression is detected from the content.

    Returns
    -------
    CarmenLog
        Scans in file order, one beam layout; see the module docstring for the rules
        (message choice, skipped lines and scans, max range and no returns).

    Raises
    ------
    MapError
        If the file is missing, unreadable or not a regular file (a FIFO, a device...).
    MapSizeError
        If the file, or its text once gunzipped, is larger than :data:`MAX_LOG_BYTES`.
    MapFormatError
        If the file holds no valid ``FLASER`` or ``ROBOTLASER1`` line (not a CARMEN laser
        log), or is a corrupt gzip file.

    Warns
    -----
    MapWarning
        When laser lines were skipped (malformed or truncated, or another beam layout), or a
        gzip file ends early.

    Examples
    --------
    >>> log = read_carmen("tests/data/carmen/orebro-corrected.log.gz")  # doctest: +SKIP
    >>> log.n_scans, log.n_beams  # doctest: +SKIP
    (237, 181)
    """
    p = Path(path)
    name = path_text(p)
    data = _read_bytes(p)
    flaser: list[tuple[int, list[bytes]]] = []
    robot: list[tuple[int, list[bytes]]] = []
    for line in _LASER_LINE.finditer(data):  # other lines are never split (nor copied)
        tok = line.group().split()
        if tok[0] == b"FLASER":
            flaser.append((line.start(), tok))
        elif tok[0] == b"ROBOTLASER1":
            robot.append((line.start(), tok))
    scans = _parse_robotlaser(robot) if robot else _Scans()
    message = "ROBOTLASER1"
    if not scans.order:
        scans, message = _parse_flaser(flaser), "FLASER"
        scans.bad += len(robot)
    if not scans.order:
        what = (
            "no FLASER or ROBOTLASER1 line"
            if not (flaser or robot)
            else (f"no valid laser line ({scans.bad} malformed)")
        )
        raise MapFormatError(f"{name} is not a CARMEN laser log: {what}")

    # keep the most common beam layout (ties: the one seen first)
    sizes: Counter[tuple[float, ...]] = Counter()
    first_line: dict[tuple[float, ...], int] = {}
    for key, order in zip(scans.key, scans.order, strict=True):
        sizes[key] += len(order)
        first_line[key] = min(first_line.get(key, len(data)), int(order.min()))
    keep = max(sizes, key=lambda k: (sizes[k], -first_line[k]))
    chosen = [i for i, k in enumerate(scans.key) if k == keep]
    order = np.concatenate([scans.order[i] for i in chosen])
    sort = np.argsort(order, kind="stable")
    poses = np.concatenate([scans.poses[i] for i in chosen])[sort]
    ranges = np.concatenate([scans.ranges[i] for i in chosen])[sort]
    skipped_scans = sum(sizes.values()) - sizes[keep]
    n = int(keep[0])
    angles = scans.angles[chosen[0]]
    if message == "FLASER":
        max_range = float(ranges.max())
    else:
        max_range = float(np.concatenate([scans.max_range[i] for i in chosen]).max())
    if not max_range > 0:
        raise MapFormatError(f"{name}: every laser reading is zero or negative")
    if scans.bad:
        warnings.warn(
            f"{name}: skipped {scans.bad} malformed or truncated {message} line(s)",
            MapWarning,
            stacklevel=2,
        )
    if skipped_scans:
        warnings.warn(
            f"{name}: skipped {skipped_scans} {message} scan(s) whose beam layout differs from "
            f"the {sizes[keep]} kept scans of {n} beams",
            MapWarning,
            stacklevel=2,
        )
    return CarmenLog(poses, ranges, angles, max_range, scans.bad, skipped_scans, message, str(p))


# -- mapping ------------------------------------------------------------------------------------
def _mapping_range(log: CarmenLog, max_range: float | None) -> float:
    if max_range is None:
        return log.hit_range
    if not (math.isfinite(max_range) and max_range > 0):
        raise ParameterError(f"max_range must be a positive number of metres, got {max_range!r}")
    return min(float(max_range), log.hit_range)


def log_geometry(
    log: CarmenLog,
    *,
    resolution: float = 0.05,
    poses: ArrayLike | Sequence[ArrayLike] | None = None,
    margin: float = 1.0,
    max_range: float | None = None,
) -> tuple[tuple[int, int], tuple[float, float, float]]:
    """Grid ``(shape, origin)`` covering a log's poses and hits (with one or more pose sets).

    Parameters
    ----------
    log : CarmenLog
    resolution : float
        Metres per cell.
    poses : array_like (N, 3), or a sequence of them, optional
        Pose sets to cover (default: the log's poses). Give the true and the bumped poses to
        put a broken map and its reference on one grid.
    margin : float
        Metres around the outermost hit or pose.
    max_range : float, optional
        Mapping range; hits beyond it are left out (see :func:`map_log`).
    """
    limit = _mapping_range(log, max_range)
    if poses is None:
        sets = [log.poses]
    else:
        arr = np.asarray(poses, dtype=np.float64)
        sets = [arr] if arr.ndim == 2 else list(arr)
    near = log.ranges[log.hits] < limit
    corners = []
    for p in sets:
        p = _check_poses(p, log.n_scans)
        pts = np.concatenate([log.end_points(p)[near], p[:, :2]])
        corners += [pts.min(axis=0), pts.max(axis=0)]  # the bounding box is all that matters
    return grid_geometry(np.array(corners), resolution, margin)


def map_log(
    log: CarmenLog,
    *,
    resolution: float = 0.05,
    poses: ArrayLike | None = None,
    margin: float = 1.0,
    max_range: float | None = None,
    shape: tuple[int, int] | None = None,
    origin: tuple[float, float, float] | None = None,
    clear_no_returns: bool = False,
) -> OccupancyMap:
    """Occupancy map of a CARMEN log (hits occupied, beams' free space free, rest unknown).

    Parameters
    ----------
    log : CarmenLog
        The scans (e.g. from :func:`read_carmen`).
    resolution : float
        Metres per cell.
    poses : array_like, shape (N, 3), optional
        Laser poses to map with instead of the log's (e.g. bumped poses).
    margin : float
        Metres of grid around the outermost hit or pose (when the grid is sized here).
    max_range : float, optional
        Mapping range in metres (like GMapping's ``maxUrange``): readings at or beyond it are
        not hits and clear free space up to it. Default and upper bound: the log's
        :attr:`CarmenLog.hit_range` (no returns are never hits).
    shape, origin : optional
        A fixed grid ``(rows, cols)`` and lower-left pose; both or neither. Default: sized by
        :func:`log_geometry` around the hits and poses mapped here.
    clear_no_returns : bool
        If True, a no return (a reading at or beyond :attr:`CarmenLog.hit_range`) clears free
        space up to the mapping range. Default False: no returns are ignored, because a beam
        that came back from nowhere (glass, black surfaces, sensor error codes) says little
        about the space it crossed, and clearing 80 m rays strews free cells far outside a
        building.

    Returns
    -------
    OccupancyMap
        With resolution and origin; ``source`` is the log's.

    Examples
    --------
    >>> log = read_carmen("tests/data/carmen/orebro-corrected.log.gz")  # doctest: +SKIP
    >>> m = map_log(log, resolution=0.1)  # doctest: +SKIP
    """
    p = log.poses if poses is None else _check_poses(poses, log.n_scans)
    if (shape is None) != (origin is None):
        raise ParameterError("give both shape and origin, or neither")
    if shape is None or origin is None:
        shape, origin = log_geometry(
            log, resolution=resolution, poses=p, margin=margin, max_range=max_range
        )
    counts = _counts(log, p, resolution, shape, origin, max_range, clear_no_returns)
    m = counts_to_map(counts)
    return OccupancyMap(m.states, m.resolution, m.origin, log.source)


def _counts(
    log: CarmenLog,
    poses: NDArray[np.float64],
    resolution: float,
    shape: tuple[int, int],
    origin: tuple[float, float, float],
    max_range: float | None,
    clear_no_returns: bool,
) -> ScanCounts:
    """Hit and miss counts of the log's scans drawn from ``poses``."""
    ranges = log.ranges
    if not clear_no_returns:
        ranges = np.where(ranges >= log.hit_range, 0.0, ranges)  # <= 0: ignored by the mapper
    return scan_counts(
        poses,
        ranges,
        log.angles,
        max_range=_mapping_range(log, max_range),
        resolution=resolution,
        shape=shape,
        origin=origin,
    )


# -- are the walls single? ----------------------------------------------------------------------
@dataclass(frozen=True)
class WallCheck:
    """How well the two halves of a log agree on where the walls are.

    Attributes
    ----------
    cross_half : float
        Of the occupied cells of the second half's map that the first half observed (known
        there), the fraction within ``tolerance`` cells (Manhattan) of an occupied cell of the
        first half's map. Near 1 for single walls; a doubled wall lands in space the first half
        saw free and lowers it.
    half_in_full : float
        Fraction of the first half's occupied cells within ``tolerance`` cells of an occupied
        cell of the whole log's map.
    psi_half_full : float
        :func:`~brokenness.picture_distance` (cells) between the first half's map and the whole
        log's map restricted to the cells the first half observed.
    compared_cells : int
        Occupied cells of the second half that entered ``cross_half``.
    resolution : float
    tolerance : int
    """

    cross_half: float
    half_in_full: float
    psi_half_full: float
    compared_cells: int
    resolution: float
    tolerance: int


def wall_check(
    log: CarmenLog,
    *,
    resolution: float = 0.1,
    tolerance: int = 2,
    poses: ArrayLike | None = None,
    max_range: float | None = 10.0,
) -> WallCheck:
    """Measure whether a log maps to single walls: its first half against its second half.

    The scans are split in file order into two halves; each half and the whole log are mapped
    on one grid (see :func:`map_log`). With consistent poses the second half's walls lie on the
    first half's where both saw the same place; with a pose error between the halves they are
    doubled and fall into space the first half saw free.

    Parameters
    ----------
    log : CarmenLog
    resolution : float
        Metres per cell of the maps compared.
    tolerance : int
        Cells (Manhattan) within which two walls count as one.
    poses : array_like, shape (N, 3), optional
        Poses to map with instead of the log's.
    max_range : float, optional
        Mapping range, as in :func:`map_log`. Default 10 m: far returns are few and noisy
        (a 0.5 degree error moves a 30 m return by 26 cm), and people and clutter seen from
        afar lower the agreement without saying anything about the poses. ``None``: the
        whole range of the log.

    Returns
    -------
    WallCheck
    """
    from ..masking import picture_distance
    from ..masking.distance import manhattan_distance_map

    if log.n_scans < 2:
        raise ParameterError("a wall check needs a log of at least two scans")
    if tolerance < 0:
        raise ParameterError(f"tolerance must be >= 0 cells, got {tolerance}")
    p = log.poses if poses is None else _check_poses(poses, log.n_scans)
    shape, origin = log_geometry(log, resolution=resolution, poses=p, max_range=max_range)
    half = log.n_scans // 2
    parts = [
        _counts(log.select(sel), p[sel], resolution, shape, origin, max_range, False)
        for sel in (np.arange(half), np.arange(half, log.n_scans))
    ]
    first, second = (counts_to_map(c) for c in parts)
    # counts add up beam by beam, so the whole log's map is the map of the summed counts
    full = counts_to_map(
        ScanCounts(
            parts[0].hits + parts[1].hits,
            parts[0].misses + parts[1].misses,
            parts[0].resolution,
            parts[0].origin,
            parts[0].dropped_hits + parts[1].dropped_hits,
        )
    )
    near_first = manhattan_distance_map(first.occupied) <= tolerance
    compared = second.occupied & first.known
    n_compared = int(np.count_nonzero(compared))
    cross = float(np.count_nonzero(compared & near_first)) / max(n_compared, 1)
    near_full = manhattan_distance_map(full.occupied) <= tolerance
    n_first = max(first.n_occupied, 1)
    half_in_full = float(np.count_nonzero(first.occupied & near_full)) / n_first
    restricted = full.with_states(np.where(first.known, full.states, -1).astype(np.int8))
    psi = picture_distance(first, restricted)
    return WallCheck(cross, half_in_full, psi, n_compared, float(resolution), int(tolerance))


# -- broken maps of a real building -------------------------------------------------------------
def log_run(
    log: CarmenLog, *, max_range: float | None = None, clear_no_returns: bool = False
) -> tuple[LaserRun, tuple[float, float, float, float]]:
    """A log as a :class:`~brokenness.simulation.laser.LaserRun`, and the box of what it saw.

    The run's true and noisy poses are both the log's (corrected) poses; its ranges are the
    log's with no returns set to 0 (ignored by the mapper) unless ``clear_no_returns``; its
    laser has the log's beams and the mapping range (``max_range`` as in :func:`map_log`).
    The box ``(x0, y0, x1, y1)`` (metres) holds the poses and the hits within the mapping
    range. :func:`broken_log_map` breaks this run; give it to
    :func:`~brokenness.simulation.ground_truth.broken_map_from_run` to draw other bumps
    without re-reading the log.
    """
    limit = _mapping_range(log, max_range)
    ranges = log.ranges
    if not clear_no_returns:
        ranges = np.where(ranges >= log.hit_range, 0.0, ranges)
    fov = float(np.degrees(log.angles[-1] - log.angles[0])) if log.n_beams > 1 else 1.0
    laser = Laser(
        beams=log.n_beams, fov_deg=min(max(fov, 1e-6), 360.0), max_range=limit, range_sigma=0.0
    )
    run = LaserRun(
        true_poses=log.poses, noisy_poses=log.poses, ranges=ranges, angles=log.angles, laser=laser
    )
    # the box of everything the reference holds: poses and hits within the mapping range
    near = log.ranges[log.hits] < limit
    pts = np.concatenate([log.end_points()[near], log.poses[:, :2]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return run, (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def broken_log_map(
    log: CarmenLog,
    *,
    seed: int = 0,
    degree: int | None = None,
    bumps: int | Sequence[Bump] | None = None,
    bump_probability: float | None = None,
    bump_radius: float = 1.0,
    max_rotation: float = 180.0,
    min_rotation: float = 10.0,
    resolution: float = 0.05,
    max_range: float | None = None,
    clear_no_returns: bool = False,
    threshold: float = 2.0,
    merge_threshold: float = 4.0,
    min_partition_fraction: float = 0.02,
    min_partition_cells: int = 30,
    max_attempts: int = 30,
) -> SimulatedMap:
    """A broken map of a real building: bump noise on a log's corrected pose chain.

    The reference is the log mapped with its (corrected) poses; the broken map is the same
    scans mapped with bumps composed onto the pose chain
    (:func:`~brokenness.simulation.bumps.apply_bumps`: after bump ``j`` every pose carries the
    world error ``E_j``). The ground truth and the honest expected degree are those of
    :func:`~brokenness.simulation.ground_truth.broken_map_from_run` (see
    :mod:`brokenness.simulation.ground_truth`): each partition's transform maps a broken-map cell
    onto the reference grid in the convention of :func:`brokenness.compute_brokenness`
    (``W_ref^-1 o E_j^-1 o W_map``), its ``world`` part is ``E_j^-1``.

    Geometry: the reference covers the log's poses and hits (within the mapping range) plus
    0.5 m; the broken map covers the images of that box under every ``E_j``. Without bumps the
    two grids are identical (same shape and origin); with bumps the broken map's grid is the
    larger box (same resolution, origin on the same lattice of cells).

    Give at most one of ``degree``, ``bumps`` and ``bump_probability``. The bump keywords and
    those of the honest rule are checked once, as a
    :class:`~brokenness.simulation.options.BumpOptions`.

    Parameters
    ----------
    log : CarmenLog
    seed : int
        The bumps follow from it (same seed and parameters: same maps, bit for bit).
    degree : int, optional
        Make the honest expected degree exactly this (redrawn up to ``max_attempts`` times).
    bumps : int or sequence of Bump, optional
        Exactly this many bumps (drawn once; the degree may come out lower), or these bumps.
    bump_probability : float, optional
        The paper's model: each scan bumps with this probability.
    bump_radius : float
        ``r``: shifts ``d ~ U[0, r]`` metres.
    max_rotation, min_rotation : float
        Degrees, as in :func:`~brokenness.simulation.synthetic.simulate_broken_map`.
    resolution : float
        Metres per cell of both maps.
    max_range, clear_no_returns
        As in :func:`map_log`.
    threshold, merge_threshold, min_partition_fraction, min_partition_cells
        The honest rule of :mod:`brokenness.simulation.ground_truth`.
    max_attempts : int
        Bound on redraws in ``degree`` mode.

    Returns
    -------
    SimulatedMap
        ``.map``, ``.reference``, ``.expected_degree``, ``.partitions`` (transforms, shares),
        ``.labels``, ``.bumps``, ``.parameters``; ``.building`` is None and ``.run`` holds the
        log's scans as mapped. Write it with :func:`~brokenness.simulation.save_simulation`.

    Raises
    ------
    ParameterError
        For invalid or conflicting options, or when ``degree`` is not reached.

    Examples
    --------
    >>> log = read_carmen("tests/data/carmen/orebro-corrected.log.gz")  # doctest: +SKIP
    >>> sim = broken_log_map(log, degree=1, seed=3, resolution=0.1,
    ...                      max_range=10.0)  # doctest: +SKIP
    >>> sim.expected_degree, len(sim.partitions)  # doctest: +SKIP
    (1, 2)
    """
    options = BumpOptions(
        seed=seed,
        degree=degree,
        bumps=bumps,
        bump_probability=bump_probability,
        bump_radius=bump_radius,
        max_rotation=max_rotation,
        min_rotation=min_rotation,
        max_attempts=max_attempts,
        rule=HonestRule(threshold, merge_threshold, min_partition_fraction, min_partition_cells),
    )
    if not (math.isfinite(resolution) and resolution > 0):
        raise ParameterError(f"resolution must be a positive number, got {resolution!r}")
    run, extent = log_run(log, max_range=max_range, clear_no_returns=clear_no_returns)
    setting = {
        "resolution": resolution,
        "log": log.source,
        "message": log.message,
        "scans": log.n_scans,
        "beams": log.n_beams,
        "max_range": run.laser.max_range,
        "clear_no_returns": clear_no_returns,
    }
    return break_run(
        run,
        extent,
        options,
        resolution=resolution,
        hint=f"{log.source or 'the log'}: try a lower degree",
        setting=setting,
        source=log.source,
    )
