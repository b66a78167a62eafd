"""ROS ``map_server`` YAML map descriptions: reading (validated) and writing.

A map YAML looks like::

    image: map.pgm            # relative to the YAML file's folder, or absolute
    resolution: 0.05          # metres per pixel
    origin: [-10.0, -10.0, 0.0]   # pose (x, y, yaw) of the lower-left pixel's corner
    negate: 0                 # 1: black is free, white occupied
    occupied_thresh: 0.65     # p > occupied_thresh -> occupied
    free_thresh: 0.196        # p < free_thresh -> free
    mode: trinary             # trinary (default) | scale | raw

``image`` and ``resolution`` are required. ``map_server`` also requires ``origin``, ``negate``
and both thresholds; we are lenient and use ``origin`` unknown, ``negate`` 0 and the defaults
0.65 / 0.196 when they are missing. Numbers given as strings (``"1e-3"``, which YAML 1.1 does
not treat as a float, but ``map_server``'s yaml-cpp does) are accepted.

References
----------
.. [1] ROS map_server, http://wiki.ros.org/map_server#YAML_format
.. [2] Nav2 map_server, ``nav2_map_server/src/map_io.cpp``
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ..errors import MapFormatError
from ..limits import MAX_COORDINATE, MAX_RESOLUTION, MAX_TEXT_BYTES, MIN_RESOLUTION
from ._files import path_text, read_file_bytes, shown
from ._yaml import parse_yaml
from .pixels import DEFAULT_FREE_THRESH, DEFAULT_OCCUPIED_THRESH, MODES

__all__ = ["MapYaml", "dump_map_yaml", "is_rosbag2_metadata", "parse_map_yaml", "read_map_yaml"]


@dataclass(frozen=True)
class MapYaml:
    """The validated content of a ROS map YAML file.

    Attributes
    ----------
    image : Path
        Image file, already resolved against the YAML file's folder.
    resolution : float
        Metres per pixel, finite and > 0.
    origin : tuple of 3 floats or None
        ``(x, y, yaw)`` of the lower-left corner of the map; ``None`` if the YAML has none.
    negate : bool
    occupied_thresh, free_thresh : float
        In [0, 1], ``free_thresh < occupied_thresh``.
    mode : str
        ``"trinary"``, ``"scale"`` or ``"raw"``.
    """

    image: Path
    resolution: float
    origin: tuple[float, float, float] | None
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str


def _number(value: Any, key: str, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise MapFormatError(f"{name}: '{key}' must be a number, got {shown(value)}")
    try:
        number = float(value)
    except (ValueError, OverflowError):
        raise MapFormatError(f"{name}: '{key}' must be a number, got {shown(value)}") from None
    if not math.isfinite(number):
        raise MapFormatError(f"{name}: '{key}' must be finite, got {shown(value)}")
    return number


def is_rosbag2_metadata(doc: Any) -> bool:
    """True when a parsed YAML document is a rosbag2 ``metadata.yaml``."""
    return isinstance(doc, dict) and "rosbag2_bagfile_information" in doc


def load_yaml_document(path: Path) -> Any:
    """Parse a YAML file of at most :data:`~brokenness.limits.MAX_TEXT_BYTES` bytes.

    Uses :func:`brokenness.io._yaml.parse_yaml` (safe loader, duplicate keys and aliases
    refused); every failure is a one-line :class:`MapFormatError` (or :class:`MapError` for
    the file itself, :class:`~brokenness.errors.MapSizeError` for a file over the limit).
    """
    data = read_file_bytes(path, MAX_TEXT_BYTES, "map YAML")
    return parse_yaml(data, path_text(path))


def parse_map_yaml(doc: Any, path: Path) -> MapYaml:
    """Validate a parsed map YAML document.

    Parameters
    ----------
    doc : object
        What :func:`load_yaml_document` returned.
    path : Path
        The YAML file (to resolve ``image`` and for messages).

    Returns
    -------
    MapYaml

    Raises
    ------
    MapFormatError
        Not a mapping, a duplicate key, ``image`` or ``resolution`` missing, a value of the
        wrong type or out of range (resolution NaN or outside [1e-6, 1e4] m, origin not 3
        finite numbers within 1e9, thresholds outside [0, 1] or ``free_thresh >=
        occupied_thresh``, unknown ``mode``, ``negate`` not 0/1). A value the message echoes
        is shortened (:func:`~brokenness.io._files.shown`).
    """
    name = path_text(path)
    if not isinstance(doc, dict):
        kind = "empty" if doc is None else type(doc).__name__
        raise MapFormatError(f"{name}: not a ROS map YAML (expected a mapping, got {kind})")
    for key in ("image", "resolution"):
        if key not in doc:
            raise MapFormatError(f"{name}: not a ROS map YAML (no '{key}' field)")
    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise MapFormatError(f"{name}: 'image' must be a file name, got {shown(image)}")
    resolution = _number(doc["resolution"], "resolution", name)
    if resolution <= 0:
        raise MapFormatError(f"{name}: 'resolution' must be > 0, got {shown(doc['resolution'])}")
    if not MIN_RESOLUTION <= resolution <= MAX_RESOLUTION:
        raise MapFormatError(
            f"{name}: 'resolution' {resolution!r} is outside the supported range "
            f"[{MIN_RESOLUTION:g}, {MAX_RESOLUTION:g}] metres per cell"
        )

    origin: tuple[float, float, float] | None = None
    if doc.get("origin") is not None:
        raw = doc["origin"]
        if not isinstance(raw, list | tuple) or len(raw) != 3:
            raise MapFormatError(f"{name}: 'origin' must be [x, y, yaw], got {shown(raw)}")
        x, y, yaw = (_number(v, "origin", name) for v in raw)
        if max(abs(x), abs(y), abs(yaw)) > MAX_COORDINATE:
            raise MapFormatError(
                f"{name}: 'origin' {shown(raw)} is out of range (|value| <= {MAX_COORDINATE:g})"
            )
        origin = (x, y, yaw)

    negate_raw = doc.get("negate", 0)
    if isinstance(negate_raw, bool):
        negate = negate_raw
    elif isinstance(negate_raw, int) and negate_raw in (0, 1):
        negate = bool(negate_raw)
    else:
        raise MapFormatError(f"{name}: 'negate' must be 0 or 1, got {shown(negate_raw)}")

    occupied = DEFAULT_OCCUPIED_THRESH
    free = DEFAULT_FREE_THRESH
    if doc.get("occupied_thresh") is not None:
        occupied = _number(doc["occupied_thresh"], "occupied_thresh", name)
    if doc.get("free_thresh") is not None:
        free = _number(doc["free_thresh"], "free_thresh", name)
    for key, value in (("occupied_thresh", occupied), ("free_thresh", free)):
        if not 0.0 <= value <= 1.0:
            raise MapFormatError(f"{name}: '{key}' must be in [0, 1], got {value!r}")
    if free >= occupied:
        raise MapFormatError(
            f"{name}: free_thresh ({free}) must be smaller than occupied_thresh ({occupied})"
        )

    mode = doc.get("mode", "trinary")
    if mode is None:
        mode = "trinary"
    if not isinstance(mode, str) or mode.strip().lower() not in MODES:
        raise MapFormatError(f"{name}: unknown mode {shown(mode)} (expected trinary, scale or raw)")
    return MapYaml(
        image=path.parent / image.strip(),
        resolution=resolution,
        origin=origin,
        negate=negate,
        occupied_thresh=occupied,
        free_thresh=free,
        mode=mode.strip().lower(),
    )


def read_map_yaml(path: Path) -> MapYaml:
    """Read and validate a ROS map YAML file (see :func:`parse_map_yaml`)."""
    return parse_map_yaml(load_yaml_document(path), path)


def dump_map_yaml(
    image_name: str,
    resolution: float,
    origin: tuple[float, float, float],
    *,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
) -> str:
    """Text of a ``map_saver``-style YAML for a trinary image (floats written exactly).

    Returns
    -------
    str
    """
    doc = {
        "image": image_name,
        "mode": "trinary",
        "resolution": float(resolution),
        "origin": [float(v) for v in origin],
        "negate": 0,
        "occupied_thresh": float(occupied_thresh),
        "free_thresh": float(free_thresh),
    }
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
