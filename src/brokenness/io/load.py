"""``load_map``: one entry point for every map file format."""

from __future__ import annotations

import importlib
import os
from pathlib import Path

from ..errors import MapError, MapFormatError, ParameterError
from ..grid import OccupancyMap
from ..limits import MAX_COORDINATE, MAX_RESOLUTION, MIN_RESOLUTION, resolution_in_range
from ._files import as_path, check_regular, path_text, shown
from .arrays import ROW_ORDERS, decode_npy
from .pixels import (
    DEFAULT_FREE_THRESH,
    DEFAULT_OCCUPIED_THRESH,
    MODES,
    pixels_to_states,
    read_pixels,
)
from .ros_yaml import is_rosbag2_metadata, load_yaml_document, parse_map_yaml

__all__ = ["BAG_SUFFIXES", "IMAGE_SUFFIXES", "YAML_SUFFIXES", "is_rosbag", "load_map"]

#: Suffixes read as ROS map YAML.
YAML_SUFFIXES: frozenset[str] = frozenset({".yaml", ".yml"})
#: Suffixes handed to the rosbag reader.
BAG_SUFFIXES: frozenset[str] = frozenset({".bag", ".db3", ".mcap"})
#: Raster image suffixes (PGM by our reader, the rest by Pillow).
IMAGE_SUFFIXES: frozenset[str] = frozenset(
    {
        ".pgm",
        ".pnm",
        ".ppm",
        ".pbm",
        ".png",
        ".bmp",
        ".tif",
        ".tiff",
        ".gif",
        ".jpg",
        ".jpeg",
        ".webp",
        ".tga",
    }
)

PathLike = str | os.PathLike[str]


def is_rosbag(path: Path) -> bool:
    """True for a ROS 1 bag, a rosbag2 storage file, or a rosbag2 folder (has metadata.yaml).

    Never raises: a path that cannot be examined (a folder on the way that cannot be entered,
    an invalid name) is not a bag folder, and the reader then says what is wrong with it.
    """
    if path.suffix.lower() in BAG_SUFFIXES:
        return True
    # os.path (not Path.is_dir, which re-raises PermissionError): False on any OS error
    return os.path.isdir(path) and os.path.isfile(path / "metadata.yaml")


def _load_bag(path: Path, topic: str | None) -> OccupancyMap:
    try:
        module = importlib.import_module("brokenness.io.rosbag")
        loader = module.load_bag_map
    except (ImportError, AttributeError) as exc:
        raise MapError(f"{path_text(path)}: rosbag support is unavailable ({exc})") from None
    return loader(path, topic=topic or "/map")  # type: ignore[no-any-return]


def _geometry(
    resolution: float | None, origin: tuple[float, float, float] | None
) -> tuple[float | None, tuple[float, float, float] | None]:
    """Validate the keyword geometry arguments (they override the file's)."""
    if resolution is not None:
        try:
            res = float(resolution)
        except (TypeError, ValueError, OverflowError):
            raise ParameterError(f"resolution must be a number, got {shown(resolution)}") from None
        if not resolution_in_range(res):
            raise ParameterError(
                f"resolution must be a number of metres in [{MIN_RESOLUTION:g}, "
                f"{MAX_RESOLUTION:g}], got {shown(res)}"
            )
        resolution = res
    if origin is not None:
        try:
            x, y, yaw = (float(v) for v in origin)
        except (TypeError, ValueError, OverflowError):
            raise ParameterError(f"origin must be (x, y, yaw), got {shown(origin)}") from None
        if not all(abs(v) <= MAX_COORDINATE for v in (x, y, yaw)):
            raise ParameterError(
                f"origin must be three finite numbers within {MAX_COORDINATE:g}, "
                f"got {shown(origin)}"
            )
        origin = (x, y, yaw)
    return resolution, origin


def load_map(
    path: PathLike,
    *,
    mode: str | None = None,
    resolution: float | None = None,
    origin: tuple[float, float, float] | None = None,
    topic: str | None = None,
    row_order: str | None = None,
) -> OccupancyMap:
    """Load an occupancy map from a file, with ROS ``map_server`` semantics.

    The format is chosen from the path:

    * ``.yaml`` / ``.yml``: a ROS ``map_server`` map description. ``image`` is resolved
      against the YAML file's folder (or absolute); ``resolution``, ``origin`` (pose of the
      lower-left corner), ``negate``, ``occupied_thresh`` / ``free_thresh`` (strict: ``p >
      occupied_thresh`` occupied, ``p < free_thresh`` free, else unknown, with
      ``p = (maxval - v) / maxval``, or ``v / maxval`` when negated) and ``mode``
      (trinary / scale / raw) are applied exactly as :mod:`brokenness.io.pixels` documents.
      A :class:`~brokenness.io.MapWarning` flags the Nav2 trap (205-grey pixels read as free
      because ``free_thresh`` > 0.19608); the YAML is still followed, as ROS does.
    * ``.pgm`` (P2 / P5, 8 or 16 bit), ``.png`` and other Pillow formats: the image alone,
      thresholded with the ``map_server`` defaults (0.65 / 0.196, trinary unless ``mode``
      says otherwise); no geometry unless given as arguments.
    * ``.npy``: a 2D array, see :func:`brokenness.io.arrays.decode_npy`.
      ``nav_msgs/OccupancyGrid`` values (integers -1, 0..100) are in ROS row order by
      default (row 0 at the bottom, as in the message and as the rosbag reader reads it);
      other arrays in image order. ``row_order`` says which.
    * ``.bag`` / ``.db3`` / ``.mcap`` or a rosbag2 folder: the ``nav_msgs/OccupancyGrid``
      on ``topic`` (default ``/map``), read by :mod:`brokenness.io.rosbag`.

    A map without any occupied cell loads fine: it is an error for the brokenness
    computation, not for input/output.

    Parameters
    ----------
    path : str or path-like
    mode : {"trinary", "scale", "raw"}, optional
        Overrides the YAML ``mode`` (or sets it for a plain image).
    resolution : float, optional
        Metres per cell; overrides the file's.
    origin : (x, y, yaw), optional
        Pose of the lower-left corner; overrides the file's.
    topic : str, optional
        Topic of the map in a rosbag (default ``/map``).
    row_order : {"ros", "image"}, optional
        ``.npy`` only: ``"ros"`` when row 0 of the array is the bottom row of the map (the
        origin row of a ``nav_msgs/OccupancyGrid``), ``"image"`` when it is the top row.
        Default: ``"ros"`` for OccupancyGrid values, ``"image"`` for other arrays. Other
        formats fix their own row order (a ParameterError if given for them).

    Returns
    -------
    OccupancyMap
        ``source`` is the path as given.

    Raises
    ------
    MapError
        Missing file, directory, FIFO, device, socket or symbolic link loop (refused before
        anything is opened), unreadable file, image named by the YAML missing.
    MapFormatError
        Empty, corrupt or truncated file; YAML that is not a map; invalid field; unsupported
        extension.
    MapSizeError
        More than :func:`~brokenness.limits.max_cells` cells (checked before decoding), or a
        file larger than :func:`~brokenness.limits.max_file_bytes`.
    ParameterError
        Invalid ``mode``, ``resolution`` or ``origin`` argument, or a ``path`` that is not a
        path (``None``...).

    Examples
    --------
    >>> m = load_map("tests/data/tb3_sandbox.yaml")  # doctest: +SKIP
    >>> m.shape, m.resolution, m.origin  # doctest: +SKIP
    ((384, 384), 0.05, (-10.0, -10.0, 0.0))
    """
    if mode is not None and (not isinstance(mode, str) or mode.lower() not in MODES):
        raise ParameterError(f"mode must be one of {', '.join(MODES)}, got {shown(mode)}")
    mode = mode.lower() if mode is not None else None
    resolution, origin = _geometry(resolution, origin)
    p = as_path(path, "map path")
    source = str(p)  # the map's source: the path as given
    name = path_text(p)  # the path as messages show it (one line, bounded)
    if row_order is not None:
        if row_order not in ROW_ORDERS:
            raise ParameterError(f"row_order must be 'ros' or 'image', got {shown(row_order)}")
        if p.suffix.lower() != ".npy":
            raise ParameterError(f"{name}: row_order applies to .npy arrays only")

    if is_rosbag(p):
        bag = _load_bag(p, topic)  # checks that every file it reads is a regular file
        if resolution is None and origin is None:
            return bag
        return OccupancyMap(
            bag.states,
            resolution if resolution is not None else bag.resolution,
            origin if origin is not None else bag.origin,
            bag.source,
        )
    check_regular(p)  # before anything is opened: no FIFO, device, socket or directory
    suffix = p.suffix.lower()

    if suffix in YAML_SUFFIXES:
        doc = load_yaml_document(p)
        if is_rosbag2_metadata(doc):
            return load_map(p.parent, resolution=resolution, origin=origin, topic=topic)
        meta = parse_map_yaml(doc, p)
        image = path_text(meta.image)
        if meta.image.suffix.lower() in YAML_SUFFIXES | {".npy"} | BAG_SUFFIXES:
            raise MapFormatError(
                f"{name}: 'image' must be a raster image, got {path_text(meta.image.name)}"
            )
        if not os.path.lexists(meta.image):
            raise MapError(f"{name}: image file {image} does not exist")
        try:
            check_regular(meta.image, "map image")
        except MapError as exc:
            raise MapError(f"{name}: 'image': {exc}") from None
        states = pixels_to_states(
            read_pixels(meta.image),
            mode=mode or meta.mode,
            negate=meta.negate,
            occupied_thresh=meta.occupied_thresh,
            free_thresh=meta.free_thresh,
            name=name,
        )
        states.setflags(write=False)  # a fresh grid nobody else holds: taken without a copy
        return OccupancyMap(
            states,
            resolution if resolution is not None else meta.resolution,
            origin if origin is not None else meta.origin,
            source=source,
        )
    if suffix == ".npy":
        return decode_npy(p, resolution=resolution, origin=origin, row_order=row_order)
    if suffix in IMAGE_SUFFIXES:
        states = pixels_to_states(
            read_pixels(p),
            mode=mode or "trinary",
            occupied_thresh=DEFAULT_OCCUPIED_THRESH,
            free_thresh=DEFAULT_FREE_THRESH,
            name=name,
        )
        states.setflags(write=False)  # a fresh grid nobody else holds: taken without a copy
        return OccupancyMap(states, resolution, origin, source=source)
    raise MapFormatError(
        f"{name}: unsupported map file extension {shown(p.suffix or '(none)')} "
        "(use .yaml, .pgm, .png or another image, .npy, or a rosbag)"
    )
