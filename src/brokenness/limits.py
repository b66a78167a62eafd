"""Limits on inputs and options, checked before anything is allocated.

Every size that a file or an option can make this package allocate is bounded here, so that a
hostile or mistaken input fails at once with a one-line typed error instead of exhausting the
memory:

* **cells per map**: :data:`MAX_CELLS` (100 million, e.g. 10000 x 10000: 500 m x 500 m at
  5 cm), overridable with the environment variable :data:`MAX_CELLS_ENV`
  (``BROKENNESS_MAX_CELLS``, a positive integer of at most :data:`MAX_CELLS_CEILING`, 2**53;
  read at each check, so it also reaches batch workers). It bounds decoded images and arrays
  (from their headers), ROS bag grids, a map or reference resampled to the other's
  resolution, and the neighbourhood that ``threshold`` implies;
* **file sizes**: :func:`max_file_bytes` for images, arrays and result files (8 bytes per
  allowed cell), :data:`MAX_TEXT_BYTES` for map YAML and error files, and
  :data:`MAX_MANIFEST_BYTES` for manifests;
* **resolution** within [:data:`MIN_RESOLUTION`, :data:`MAX_RESOLUTION`] metres per cell and
  origin coordinates within :data:`MAX_COORDINATE`;
* **measurable maps**: at least :data:`MIN_OCCUPIED_CELLS` occupied cells (the stopping
  rule's smallest partition, ``min_partition_cells`` of
  :func:`brokenness.compute_brokenness`);
* **registration hypotheses** asked for (``max_candidates``, ``--candidates``): at most
  :data:`MAX_CANDIDATES` (:func:`check_candidates`).

The functions take the values to check and return nothing or the checked value; they hold no
state.
"""

from __future__ import annotations

import math
import os
import reprlib
from collections.abc import Mapping
from numbers import Integral

from .errors import MapError, MapSizeError, ParameterError

__all__ = [
    "MAX_CANDIDATES",
    "MAX_CELLS",
    "MAX_CELLS_CEILING",
    "MAX_CELLS_ENV",
    "MAX_COORDINATE",
    "MAX_MANIFEST_BYTES",
    "MAX_RESOLUTION",
    "MAX_TEXT_BYTES",
    "MAX_WORKERS",
    "MIN_OCCUPIED_CELLS",
    "MIN_RESOLUTION",
    "check_candidates",
    "check_cells",
    "check_measurable",
    "check_threshold",
    "max_cells",
    "max_file_bytes",
    "resolution_in_range",
]

#: Default largest map, in cells. About 40 bytes per cell are needed by the brokenness
#: computation, so this keeps one map within about 4 GB of memory.
MAX_CELLS: int = 100_000_000
#: Environment variable that overrides :data:`MAX_CELLS` (a positive integer).
MAX_CELLS_ENV: str = "BROKENNESS_MAX_CELLS"
#: Largest value of :data:`MAX_CELLS_ENV`: 2**53, the largest integer up to which a float
#: holds every integer exactly (the value is read as a number, ``4e6`` allowed); 8 bytes per
#: cell (:func:`max_file_bytes`) then still fit a 64-bit file size. Far beyond any memory.
MAX_CELLS_CEILING: int = 2**53
#: Bytes per allowed cell that an image, array or result file may take on disk.
FILE_BYTES_PER_CELL: int = 8
#: Largest map YAML, batch error file or other small text file read, in bytes.
MAX_TEXT_BYTES: int = 1 << 20
#: Largest batch manifest, in bytes (some hundred thousand pairs).
MAX_MANIFEST_BYTES: int = 64 << 20
#: Smallest resolution accepted, metres per cell (one micrometre).
MIN_RESOLUTION: float = 1e-6
#: Largest resolution accepted, metres per cell (ten kilometres).
MAX_RESOLUTION: float = 1e4
#: Largest absolute origin coordinate accepted (metres, or radians for the yaw).
MAX_COORDINATE: float = 1e9
#: Fewest occupied cells a map needs to be measured: the smallest partition of the stopping
#: rule (``min_partition_cells`` of :func:`brokenness.compute_brokenness`).
MIN_OCCUPIED_CELLS: int = 30
#: Most worker processes (or Dask workers of a local cluster) a batch or a timeline starts.
MAX_WORKERS: int = 256
#: Most registration hypotheses a call asks for (``max_candidates`` of
#: :func:`brokenness.register` and :func:`brokenness.compute_brokenness`): all that iFMI can
#: give at the widest (64 rotation peaks, each with its 180-degree twin, 16 translations
#: each: the largest ``rotation_peaks`` and ``translation_peaks``). A larger search budget
#: examines nothing more, it only costs time.
MAX_CANDIDATES: int = 2048


def max_cells(environ: Mapping[str, str] | None = None) -> int:
    """The limit on cells per map: ``$BROKENNESS_MAX_CELLS`` if set, else :data:`MAX_CELLS`.

    Parameters
    ----------
    environ : mapping, optional
        Where to look the variable up (default :data:`os.environ`).

    Returns
    -------
    int

    Raises
    ------
    ParameterError
        If the variable is set but is not a positive integer of at most
        :data:`MAX_CELLS_CEILING`.

    Examples
    --------
    >>> max_cells({})
    100000000
    >>> max_cells({"BROKENNESS_MAX_CELLS": "4e6"})
    4000000
    """
    env = os.environ if environ is None else environ
    text = env.get(MAX_CELLS_ENV)
    if text is None or not text.strip():
        return MAX_CELLS
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 1 and value == int(value)):
        raise ParameterError(f"{MAX_CELLS_ENV} must be a positive integer, got {text!r}")
    if value > MAX_CELLS_CEILING:
        raise ParameterError(
            f"{MAX_CELLS_ENV} must be at most 2**53 = {MAX_CELLS_CEILING} cells (the largest "
            f"integer a float holds exactly; far beyond any memory), got {text!r}"
        )
    return int(value)


def max_file_bytes() -> int:
    """Largest image, array or result file read: 8 bytes per allowed cell plus 1 MiB."""
    return FILE_BYTES_PER_CELL * max_cells() + (1 << 20)


def check_cells(rows: float, cols: float, what: str) -> None:
    """Raise :class:`MapSizeError` if a grid of ``rows`` x ``cols`` exceeds the cell limit.

    ``rows`` and ``cols`` may be floats (a size before rounding) and as large as one likes:
    the product is formed without overflow.

    Parameters
    ----------
    rows, cols : int or float
    what : str
        Start of the message (``"map.png: image"``).

    Raises
    ------
    MapSizeError
    """
    limit = max_cells()
    cells = float(rows) * float(cols)
    if not math.isfinite(cells) or cells > limit:
        shown = f"{cols:.0f}x{rows:.0f}" if math.isfinite(cells) else "an unbounded size"
        raise MapSizeError(
            f"{what} of {shown} cells is larger than the limit of {limit} cells "
            f"(set {MAX_CELLS_ENV} to change it)"
        )


def resolution_in_range(value: float) -> bool:
    """True when ``value`` is a resolution this package accepts (finite, in range)."""
    return math.isfinite(value) and MIN_RESOLUTION <= value <= MAX_RESOLUTION


def check_resolution(value: object, error: type[ValueError] = ParameterError) -> float:
    """A resolution (metres per cell) as a float in [:data:`MIN_RESOLUTION`,
    :data:`MAX_RESOLUTION`]; ``error`` (a :class:`ParameterError` by default, a
    :class:`MapError` for a map's own) for anything else, a value that is no number
    included."""
    try:
        res = float(value)  # type: ignore[arg-type]  # anything: refused below if not a number
    except (TypeError, ValueError, OverflowError):
        res = math.nan
    if not resolution_in_range(res):
        raise error(
            f"resolution must be a number of metres per cell in [{MIN_RESOLUTION:g}, "
            f"{MAX_RESOLUTION:g}], got {reprlib.repr(value)}"
        )
    return res


def check_threshold(threshold: float, reference_shape: tuple[int, int] | None = None) -> float:
    """Validate the masking threshold ``c`` and the neighbourhood it implies.

    The masking dilates the reference by the Manhattan ball of radius ``2 c`` (the default
    merge threshold), which has ``(4 c + 1)^2`` cells: it must fit the cell limit. Beyond the
    reference's Manhattan diameter (rows + cols) every cell agrees anyway, so a larger
    threshold is refused as meaningless.

    Parameters
    ----------
    threshold : float
    reference_shape : (rows, cols), optional

    Returns
    -------
    float

    Raises
    ------
    ParameterError
    """
    try:
        c = float(threshold)
    except (TypeError, ValueError):
        raise ParameterError(f"threshold must be a number of cells, got {threshold!r}") from None
    if not (math.isfinite(c) and c > 0):
        raise ParameterError(f"threshold must be a positive number of cells, got {threshold!r}")
    side = 4.0 * math.floor(c) + 1.0
    limit = max_cells()
    if side * side > limit:
        largest = (math.isqrt(limit) - 1) // 4
        raise ParameterError(
            f"threshold {threshold!r} implies a neighbourhood of {side:.6g}x{side:.6g} cells, "
            f"more than the limit of {limit} cells (at most {largest})"
        )
    if reference_shape is not None:
        diameter = reference_shape[0] + reference_shape[1]
        if c > diameter:
            raise ParameterError(
                f"threshold {threshold!r} is larger than the reference itself ({diameter} "
                "cells corner to corner): every cell would agree"
            )
    return c


def check_candidates(value: object, name: str = "max_candidates") -> int:
    """Validate a number of registration hypotheses: an integer in [1, :data:`MAX_CANDIDATES`].

    Parameters
    ----------
    value : object
    name : str
        The option, for the message.

    Returns
    -------
    int

    Raises
    ------
    ParameterError
    """
    # numbers.Integral: Python's and numpy's integers (without importing numpy)
    count = int(value) if isinstance(value, Integral) and not isinstance(value, bool) else 0
    if not 1 <= count <= MAX_CANDIDATES:
        raise ParameterError(f"{name} must be an integer in [1, {MAX_CANDIDATES}], got {value!r}")
    return count


def check_measurable(occupied_cells: int, name: str, minimum: int = MIN_OCCUPIED_CELLS) -> None:
    """Raise :class:`MapError` when a map has too few occupied cells to be measured.

    A partition needs at least ``minimum`` cells (the stopping rule's ``min_partition_cells``),
    so a map with fewer occupied cells has no partition that could be significant, and its
    degree would be a "0" that was never measured.

    Parameters
    ----------
    occupied_cells : int
    name : str
        The map, for the message.
    minimum : int

    Raises
    ------
    MapError
    """
    if occupied_cells == 0:
        raise MapError(f"{name}: the map has no occupied cell: nothing to measure")
    if occupied_cells < minimum:
        raise MapError(
            f"{name}: too few occupied cells to measure ({occupied_cells}; a partition needs "
            f"at least {minimum}, min_partition_cells)"
        )
