"""``save_map``: write a map as ROS YAML + image, a plain image, or ``.npy`` (atomically)."""

from __future__ import annotations

import io
import os
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from ..errors import MapError, ParameterError
from ..grid import FREE, OCCUPIED, OccupancyMap
from ._files import MapWarning, as_path, atomic_write_bytes
from .arrays import encode_npy
from .pnm import encode_pgm
from .ros_yaml import dump_map_yaml

__all__ = [
    "DEFAULT_SAVE_ORIGIN",
    "DEFAULT_SAVE_RESOLUTION",
    "SAVER_FREE",
    "SAVER_OCCUPIED",
    "SAVER_UNKNOWN",
    "save_map",
    "states_to_image",
]

#: Grey value written for occupied cells (as ROS ``map_saver``).
SAVER_OCCUPIED: int = 0
#: Grey value written for unknown cells (as ROS ``map_saver``).
SAVER_UNKNOWN: int = 205
#: Grey value written for free cells (as ROS ``map_saver``).
SAVER_FREE: int = 254
#: Resolution written to a YAML for a map without one (the common ROS value, metres/cell).
DEFAULT_SAVE_RESOLUTION: float = 0.05
#: Origin written to a YAML for a map without one.
DEFAULT_SAVE_ORIGIN: tuple[float, float, float] = (0.0, 0.0, 0.0)

_IMAGE_FORMATS = ("pgm", "png")


def states_to_image(states: NDArray[np.int8]) -> NDArray[np.uint8]:
    """Trinary ``map_saver`` grey image: 0 occupied, 205 unknown, 254 free."""
    image = np.full(states.shape, SAVER_UNKNOWN, dtype=np.uint8)
    image[states == OCCUPIED] = SAVER_OCCUPIED
    image[states == FREE] = SAVER_FREE
    return image


def _encode_image(states: NDArray[np.int8], fmt: str) -> bytes:
    image = states_to_image(states)
    if fmt == "pgm":
        return encode_pgm(
            image, comment="brokenness trinary map: 0 occupied, 205 unknown, 254 free"
        )
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    return buf.getvalue()


def save_map(map: OccupancyMap, path: str | os.PathLike[str], *, image_format: str = "pgm") -> Path:
    """Write a map to a file; the format follows the extension of ``path``.

    * ``x.yaml`` / ``x.yml``: a ROS ``map_server`` YAML plus the image ``x.pgm`` (or ``x.png``
      with ``image_format="png"``) next to it, named relatively in the YAML. The image is
      trinary, as ``map_saver`` writes it: 0 occupied, 205 unknown, 254 free, with
      ``mode: trinary``, ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196``.
      Resolution and origin are the map's; a map without them gets
      :data:`DEFAULT_SAVE_RESOLUTION` (0.05 m) and :data:`DEFAULT_SAVE_ORIGIN` (0, 0, 0) and
      a :class:`MapWarning`, since ROS requires both.
    * ``.pgm`` / ``.png``: only that trinary image (no geometry).
    * ``.npy``: ``int8`` ``nav_msgs/OccupancyGrid`` values, -1 unknown, 0 free, 100 occupied,
      in ROS row order (row 0 = the bottom row, as ``OccupancyGrid.data``).

    Every file is written atomically (a temporary file in the same folder, then
    :func:`os.replace`); for a YAML the image is written first. ``load_map(save_map(m, p))``
    gives back exactly ``m``'s states, and for a YAML its resolution and origin.

    Parameters
    ----------
    map : OccupancyMap
    path : str or path-like
    image_format : {"pgm", "png"}
        Image written next to a YAML.

    Returns
    -------
    Path
        The path written (the YAML for a YAML).

    Raises
    ------
    ParameterError
        Unknown ``image_format``.
    MapError
        Unsupported extension, or the folder cannot be written.
    """
    if image_format not in _IMAGE_FORMATS:
        raise ParameterError(f"image_format must be 'pgm' or 'png', got {image_format!r}")
    if not isinstance(map, OccupancyMap):
        raise MapError(f"save_map needs an OccupancyMap, got {type(map).__name__}")
    p = as_path(path, "save_map's path")
    suffix = p.suffix.lower()
    if suffix in (".yaml", ".yml"):
        resolution, origin = map.resolution, map.origin
        if resolution is None or origin is None:
            warnings.warn(
                f"{p}: map has no {'resolution' if resolution is None else 'origin'}; writing "
                f"resolution {resolution or DEFAULT_SAVE_RESOLUTION} and origin "
                f"{list(origin or DEFAULT_SAVE_ORIGIN)}",
                MapWarning,
                stacklevel=2,
            )
        image_path = p.with_suffix("." + image_format)
        atomic_write_bytes(image_path, _encode_image(map.states, image_format))
        text = dump_map_yaml(
            image_path.name,
            resolution if resolution is not None else DEFAULT_SAVE_RESOLUTION,
            origin if origin is not None else DEFAULT_SAVE_ORIGIN,
        )
        atomic_write_bytes(p, text.encode("utf-8"))
        return p
    if suffix in (".pgm", ".png"):
        atomic_write_bytes(p, _encode_image(map.states, suffix[1:]))
        return p
    if suffix == ".npy":
        atomic_write_bytes(p, encode_npy(map.states))
        return p
    raise MapError(
        f"{p}: unsupported extension {p.suffix or '(none)'!r} for save_map "
        "(use .yaml, .pgm, .png or .npy)"
    )
