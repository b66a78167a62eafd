"""A small, vectorised reader and writer for greyscale Netpbm images (PGM ``P2`` and ``P5``).

Pillow is not used for PGM because the exact behaviour matters here: 16-bit samples
(``maxval`` > 255, big-endian per the Netpbm spec), arbitrary ``maxval``, comments anywhere in
the header, a size check *before* any pixel array is allocated, and precise messages for
truncated files. The pixel data are decoded by numpy in one call, never per pixel.

References
----------
.. [1] Netpbm PGM format specification, https://netpbm.sourceforge.net/doc/pgm.html
"""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import NDArray

from ..errors import MapFormatError, MapSizeError
from ..limits import check_cells

__all__ = ["PGM_MAGICS", "decode_pgm", "encode_pgm"]

#: Magic numbers handled by :func:`decode_pgm`.
PGM_MAGICS: tuple[bytes, bytes] = (b"P2", b"P5")

_SKIP = re.compile(rb"(?:[ \t\r\n\v\f]+|#[^\r\n]*(?:\r\n|\r|\n))*")
_NUMBER = re.compile(rb"[0-9]{1,12}")
_COMMENT = re.compile(rb"#[^\r\n]*")
_WHITESPACE = b" \t\r\n\v\f"
_MAX_REPEAT = 1 << 31  # below the regular expression engine's largest repeat count


def _header(data: bytes, name: str) -> tuple[int, int, int, int]:
    """Parse ``magic width height maxval`` and return them with the raster offset."""
    pos = 2
    values: list[int] = []
    for field in ("width", "height", "maxval"):
        pos = _SKIP.match(data, pos).end()  # type: ignore[union-attr]
        match = _NUMBER.match(data, pos)
        if match is None:
            if pos >= len(data) or data[pos : pos + 1] == b"#":
                raise MapFormatError(f"{name}: truncated PGM header (no {field})")
            raise MapFormatError(f"{name}: invalid PGM header (bad {field})")
        values.append(int(match.group()))
        pos = match.end()
    if pos >= len(data) or data[pos] not in _WHITESPACE:
        raise MapFormatError(f"{name}: invalid PGM header (no whitespace after maxval)")
    width, height, maxval = values
    if width == 0 or height == 0:
        raise MapSizeError(f"{name}: PGM image has a zero side ({width}x{height})")
    check_cells(height, width, f"{name}: PGM image")
    if not 1 <= maxval <= 65535:
        raise MapFormatError(f"{name}: invalid PGM maxval {maxval} (must be 1..65535)")
    return width, height, maxval, pos + 1


def _parse_plain(body: bytes, count: int, name: str) -> NDArray[np.int64]:
    """Decimal samples of a plain PGM body (comments removed): numpy's C parser first."""
    if len(body) > 8 * count + 4096 and count < _MAX_REPEAT:
        # far more text than ``count`` samples need (6 bytes each at most, "65535 "): only
        # the first ``count`` tokens are samples, so cut the rest off before numpy parses
        # (and allocates) them; a tiny header cannot make it parse a huge body. Possessive
        # quantifiers: the match never backtracks, it runs in linear time in C.
        match = re.match(rb"(?:[ \t\r\n\v\f]*+[^ \t\r\n\v\f]++){%d}" % count, body)
        if match is not None:
            body = body[: match.end()]
    try:
        return np.fromstring(body, dtype=np.int64, sep=" ")
    except ValueError:
        pass  # something after the samples, or a bad token: find out which, token by token
    tokens = body.split(maxsplit=count)[:count]
    try:
        return np.array([int(t) for t in tokens], dtype=np.int64)
    except (ValueError, OverflowError):
        raise MapFormatError(f"{name}: invalid sample in plain PGM data") from None


def decode_pgm(data: bytes, name: str) -> tuple[NDArray[np.unsignedinteger], int]:
    """Decode a PGM file held in memory.

    Parameters
    ----------
    data : bytes
        The whole file, starting with ``P2`` (plain/ASCII) or ``P5`` (binary).
    name : str
        File name used in error messages.

    Returns
    -------
    pixels : ndarray of uint8 or uint16, shape (height, width)
        Sample values, row 0 at the top. ``uint16`` when ``maxval`` > 255.
    maxval : int
        The maximum sample value of the file (white).

    Raises
    ------
    MapFormatError
        Bad magic or header, truncated pixel data, samples above ``maxval``.
    MapSizeError
        If the header announces a zero side or more than :func:`~brokenness.limits.max_cells`
        pixels (checked before decoding anything).
    """
    magic = data[:2]
    if magic not in PGM_MAGICS:
        raise MapFormatError(f"{name}: not a PGM P2/P5 file (magic {magic!r})")
    width, height, maxval, pos = _header(data, name)
    count = width * height
    dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(np.uint16)
    if magic == b"P5":
        need = count * (1 if maxval < 256 else 2)
        have = len(data) - pos
        if have < need:
            raise MapFormatError(
                f"{name}: truncated PGM data ({have} of {need} bytes for {width}x{height} pixels)"
            )
        raw = ">u2" if maxval >= 256 else "u1"
        pixels = np.frombuffer(data, dtype=raw, count=count, offset=pos).reshape(height, width)
        pixels = pixels.astype(dtype, copy=False)
    else:
        body = data[pos:]
        if b"#" in body:
            body = _COMMENT.sub(b" ", body)
        values = _parse_plain(body, count, name)
        if len(values) < count:
            raise MapFormatError(
                f"{name}: truncated PGM data ({len(values)} of {count} samples "
                f"for {width}x{height} pixels)"
            )
        values = values[:count]
        if values.min() < 0:
            raise MapFormatError(f"{name}: negative sample in plain PGM data")
        pixels = values.reshape(height, width)
    if maxval not in (255, 65535) or magic == b"P2":
        top = int(pixels.max())
        if top > maxval:
            raise MapFormatError(f"{name}: PGM sample {top} is larger than maxval {maxval}")
    return np.ascontiguousarray(pixels, dtype=dtype), maxval


def encode_pgm(pixels: NDArray[np.uint8], *, comment: str | None = None) -> bytes:
    """Encode an 8-bit greyscale image as binary PGM (``P5``, maxval 255).

    Parameters
    ----------
    pixels : ndarray of uint8, shape (height, width)
    comment : str, optional
        One line written as a ``#`` comment in the header.

    Returns
    -------
    bytes
    """
    height, width = pixels.shape
    head = b"P5\n"
    if comment:
        head += b"# " + " ".join(comment.split()).encode("utf-8", "replace") + b"\n"
    head += f"{width} {height}\n255\n".encode("ascii")
    return head + np.ascontiguousarray(pixels, dtype=np.uint8).tobytes()
