"""Image pixels -> three cell states, with the exact semantics of ROS ``map_server``.

The conversion of :func:`pixels_to_states` follows ``map_server`` (ROS 1 ``image_loader.cpp``
and Nav2 ``map_io.cpp``):

* the colour channels of a pixel are averaged (alpha is not a colour channel);
* ``p = (maxval - avg) / maxval`` is the occupancy probability, or ``p = avg / maxval`` when
  ``negate`` is set (black means free);
* ``trinary`` and ``scale``: ``p > occupied_thresh`` -> occupied, ``p < free_thresh`` -> free,
  anything else (including ``p`` equal to a threshold: the comparisons are strict) ->
  unknown. In ``scale`` mode ``map_server`` writes the in-between values as 1..99; with only
  three states they are unknown, so ``scale`` and ``trinary`` give the same states;
* ``raw``: the averaged pixel value ``v`` (rounded half up) *is* the occupancy value of a
  ``nav_msgs/OccupancyGrid``: ``0..100`` percent, anything else (255 = -1 in ``int8``) unknown,
  as in Nav2. To get three states it is thresholded like the other modes:
  ``v / 100 > occupied_thresh`` -> occupied, ``v / 100 < free_thresh`` -> free, else unknown.
  ``negate`` is ignored in ``raw`` mode (as Nav2 does);
* a pixel whose alpha is not fully opaque is **unknown**, in every mode. This is Nav2's rule
  for ``scale`` mode and the intent of a transparent pixel; ``map_server``'s ``trinary`` mode
  instead averages alpha in as a fourth channel, which turns transparent *black* pixels (the
  usual encoding of "nothing here" in a PNG) into walls. We deliberately do not copy that.

The conversion is a lookup table indexed by the channel sum, so it is exact (no rounding
differences between pixels of equal value) and costs one vectorised gather.
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray
from PIL import Image, UnidentifiedImageError

from ..errors import MapFormatError, MapSizeError
from ..grid import FREE, OCCUPIED, UNKNOWN
from ..limits import check_cells
from ._files import REASON_CHARS, MapWarning, one_line, path_text, read_file_bytes, shown
from .pnm import PGM_MAGICS, decode_pgm

__all__ = [
    "DEFAULT_FREE_THRESH",
    "DEFAULT_OCCUPIED_THRESH",
    "MODES",
    "Pixels",
    "pixels_to_states",
    "read_pixels",
]

#: ``map_server`` default threshold above which a pixel is occupied.
DEFAULT_OCCUPIED_THRESH: float = 0.65
#: ``map_server`` default threshold below which a pixel is free.
DEFAULT_FREE_THRESH: float = 0.196
#: The ``mode`` values of a ROS map YAML.
MODES: tuple[str, ...] = ("trinary", "scale", "raw")

#: Grey value ``map_saver`` writes for unknown cells.
_SAVER_UNKNOWN_GREY = 205
#: Formats whose images Pillow opens in the 32-bit integer mode ``I`` only to hold 16-bit
#: samples: a 16-bit grey PNG (Pillow before 10.3 opens it as ``I``, later as ``I;16``).
_SIXTEEN_BIT_I_FORMATS = frozenset({"PNG"})


@dataclass(frozen=True)
class Pixels:
    """Decoded image samples, reduced to what the map conversion needs.

    Attributes
    ----------
    sums : ndarray of unsigned int, shape (rows, cols)
        Sum of the colour channels of each pixel (the sample itself for grey images).
    channels : int
        Number of colour channels summed (1 for grey, 3 for colour).
    maxval : int
        Value of white in one channel (255 for 8-bit images, 65535 for 16-bit...).
    opaque : ndarray of bool or None
        Per pixel, True when fully opaque; ``None`` when the image has no alpha channel.
    """

    sums: NDArray[np.unsignedinteger]
    channels: int
    maxval: int
    opaque: NDArray[np.bool_] | None = None


def _from_pillow(img: Image.Image, name: str) -> Pixels:
    """Convert an opened (and loaded) Pillow image to :class:`Pixels`."""
    mode = img.mode
    if mode == "1":
        img, mode = img.convert("L"), "L"
    elif mode in ("P", "PA"):
        transparent = mode == "PA" or "transparency" in img.info
        mode = "RGBA" if transparent else "RGB"
        img = img.convert(mode)
    elif mode == "La":
        img, mode = img.convert("LA"), "LA"
    elif mode in ("RGBa",):
        img, mode = img.convert("RGBA"), "RGBA"
    elif mode in ("RGBX", "CMYK", "YCbCr", "LAB", "HSV"):
        img, mode = img.convert("RGB"), "RGB"

    arr = np.asarray(img)
    if mode == "L":
        return Pixels(arr.astype(np.uint8, copy=False), 1, 255)
    if mode == "LA":
        return Pixels(np.ascontiguousarray(arr[..., 0]), 1, 255, arr[..., 1] == 255)
    if mode == "RGB":
        return Pixels(arr.sum(axis=2, dtype=np.uint16), 3, 255)
    if mode == "RGBA":
        return Pixels(arr[..., :3].sum(axis=2, dtype=np.uint16), 3, 255, arr[..., 3] == 255)
    if mode.startswith("I;16"):
        return Pixels(arr.astype(np.uint16), 1, 65535)
    if mode == "I" and img.format in _SIXTEEN_BIT_I_FORMATS:
        if arr.size and (arr.min() < 0 or arr.max() > 65535):
            raise MapFormatError(f"{name}: 16-bit image with values outside 0..65535")
        return Pixels(arr.astype(np.uint16), 1, 65535)
    if mode == "I":
        # 32-bit (or signed) integer samples have no agreed white: 255, 65535, 2**31 - 1 and
        # 2**32 - 1 all occur, and a guess would silently turn walls into free space or back
        kind = f"{img.format} image" if img.format else "image"
        raise MapFormatError(
            f"{name}: {kind} of 32-bit or signed integer samples (mode 'I'): its white level "
            "is ambiguous; save the map as an 8-bit or 16-bit grey image"
        )
    raise MapFormatError(
        f"{name}: unsupported image mode {shown(mode)} (use a grey or colour image)"
    )


def _read_pillow(data: bytes, name: str) -> Pixels:
    try:
        # Pillow warns of a possible "decompression bomb" above its own pixel count
        # (Image.MAX_IMAGE_PIXELS, about 89 million), below this package's limit; the limit
        # that governs is this package's (check_cells, from the header, before decoding), so
        # Pillow's warning is silenced here, for this image only. Pillow's error (twice its
        # count) still stands and is reported as a MapSizeError below.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as img:
                width, height = img.size
                if width == 0 or height == 0:
                    raise MapSizeError(f"{name}: image has a zero side ({width}x{height})")
                check_cells(height, width, f"{name}: image")
                img.load()
                return _from_pillow(img, name)
    except Image.DecompressionBombError as exc:
        reason = one_line(exc, REASON_CHARS)
        raise MapSizeError(f"{name}: image refused as too large ({reason})") from None
    except UnidentifiedImageError:
        raise MapFormatError(f"{name}: not an image file Pillow can read") from None
    except MemoryError:
        raise MapSizeError(f"{name}: image too large to decode in memory") from None
    except (MapFormatError, MapSizeError):
        raise
    except Exception as exc:  # Pillow's plugins raise OSError, SyntaxError, struct.error...
        reason = one_line(exc, REASON_CHARS) or type(exc).__name__
        raise MapFormatError(f"{name}: corrupt or truncated image ({reason})") from None


def read_pixels(path: Path) -> Pixels:
    """Read any supported raster image file into :class:`Pixels`.

    PGM ``P2``/``P5`` (8 or 16 bit) is decoded by :func:`brokenness.io.pnm.decode_pgm`;
    everything else (PNG, BMP, TIFF, PPM...) by Pillow, whose modes are mapped as follows:
    ``1``/``L`` grey, ``LA`` grey + alpha, ``RGB`` (and ``CMYK``, ``YCbCr``... converted to
    RGB), ``RGBA``, palette images through RGB or RGBA (palette transparency becomes alpha),
    ``I;16*`` as 16-bit grey, and ``I`` as 16-bit grey for a 16-bit PNG (which Pillow before
    10.3 opens as ``I``). Float images and other 32-bit integer images (a TIFF of
    ``int32``...) are refused: their white level is ambiguous, and guessing it would
    silently misread the map.

    Raises
    ------
    MapError
        Missing, not a regular file (directory, FIFO, device...) or unreadable file.
    MapFormatError
        Empty, corrupt or truncated file; unsupported image mode (float, 32-bit integer).
    MapSizeError
        Image larger than :func:`~brokenness.limits.max_cells` (checked from the header,
        before decoding), a file larger than :func:`~brokenness.limits.max_file_bytes`, or
        an image refused by Pillow's decompression-bomb guard.
    """
    name = path_text(path)
    data = read_file_bytes(path, what="map image")  # a regular file within the size limit
    if data[:2] in PGM_MAGICS:
        pixels, maxval = decode_pgm(data, name)
        return Pixels(pixels, 1, maxval)
    return _read_pillow(data, name)


def _lut(
    channels: int, maxval: int, mode: str, negate: bool, occupied: float, free: float
) -> NDArray[np.int8]:
    """State of every possible channel sum ``0 .. channels * maxval``."""
    sums = np.arange(channels * maxval + 1, dtype=np.float64)
    avg = sums / channels
    if mode == "raw":
        value = np.floor(avg + 0.5)
        valid = value <= 100
        p = value / 100.0
    else:
        valid = np.ones(sums.shape, dtype=bool)
        p = avg / maxval if negate else (maxval - avg) / maxval
    lut = np.full(sums.shape, UNKNOWN, dtype=np.int8)
    lut[valid & (p > occupied)] = OCCUPIED
    lut[valid & (p < free)] = FREE
    return lut


def _lookup(lut: NDArray[np.int8], sums: NDArray[np.unsignedinteger]) -> NDArray[np.int8]:
    """``lut[sums]`` as a new array: OpenCV's table lookup for 8-bit sums and a table of
    all 256 bytes (a few times faster than numpy's gather on a large image), numpy's
    indexing otherwise."""
    if sums.dtype == np.uint8 and lut.shape == (256,):
        table = np.ascontiguousarray(lut).view(np.uint8)
        return np.asarray(cv2.LUT(np.ascontiguousarray(sums), table)).view(np.int8)
    return lut[sums]


def pixels_to_states(
    pixels: Pixels,
    *,
    mode: str = "trinary",
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
    name: str = "map",
) -> NDArray[np.int8]:
    """Threshold decoded pixels into :data:`OCCUPIED` / :data:`FREE` / :data:`UNKNOWN`.

    See the module docstring for the exact rule. Emits a :class:`MapWarning` on the Nav2
    trap: in ``trinary`` or ``scale`` mode without ``negate``, pixels of the 8-bit grey 205
    that ``map_saver`` writes for unknown cells read as free when ``free_thresh`` > 50/255
    (about 0.19608; Nav2's default 0.25 does this). The YAML is still followed, as
    ``map_server`` would.

    Parameters
    ----------
    pixels : Pixels
    mode : {"trinary", "scale", "raw"}
    negate : bool
    occupied_thresh, free_thresh : float
        Thresholds in [0, 1] on the occupancy probability (strict comparisons).
    name : str
        File name for the warning.

    Returns
    -------
    ndarray of int8
    """
    lut = _lut(pixels.channels, pixels.maxval, mode, negate, occupied_thresh, free_thresh)
    states = _lookup(lut, pixels.sums)
    if pixels.opaque is not None:
        states[~pixels.opaque] = UNKNOWN
    if mode != "raw" and not negate and pixels.maxval == 255:
        grey = _SAVER_UNKNOWN_GREY * pixels.channels
        if lut[grey] == FREE:
            hits = pixels.sums == grey
            if pixels.opaque is not None:
                hits &= pixels.opaque
            count = int(np.count_nonzero(hits))
            if count:
                warnings.warn(
                    f"{name}: {count} pixels of grey 205 (map_saver's 'unknown') read as FREE "
                    f"because free_thresh={free_thresh} > 50/255 (0.19608); following the YAML "
                    "as map_server does - set free_thresh: 0.196 if they mean unknown",
                    MapWarning,
                    stacklevel=3,
                )
    return states
