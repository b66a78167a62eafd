"""What the registration sees in each step: the map's remainder and the unmatched reference.

Matched cells are withdrawn (set to unknown) from both; for methods that use free space, the
free cells nearer to withdrawn walls than to remaining ones go too. Isolated occupied cells
(salt-and-pepper noise) can be hidden from the registration when the reference shows that
walls are connected lines.
"""

from __future__ import annotations

from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from ..grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from ..masking import manhattan_distance_map
from ..registration.base import Candidate, CellsRegistrar, OccupiedCells, Registrar

__all__ = [
    "candidates_of",
    "exhausted",
    "prepared_reference",
    "isolated_cells",
    "isolated_points",
    "moving_remainder",
    "not_isolated",
    "occupied_count",
    "reference_states",
    "remainder_cells",
    "remainder_states",
    "walls_connected",
    "withdraw",
]

#: A reference with at most this share of isolated occupied cells has connected walls.
ISOLATED_SHARE = 0.05
#: Cells of a box per given cell up to which a grid-wide filter on the box costs less than
#: lookups at the cells (small maps; the answers are the same).
_DENSE_BOX = 64


def withdraw(
    states: NDArray[np.int8], withdrawn: NDArray[np.bool_], keep: NDArray[np.bool_]
) -> NDArray[np.int8]:
    """Cell states with ``withdrawn`` occupied cells, and the free cells nearer to them than
    to any ``keep`` occupied cell, set to unknown."""
    out = states.copy()
    out[withdrawn] = UNKNOWN
    if withdrawn.any():
        nearer = manhattan_distance_map(withdrawn) < manhattan_distance_map(keep)
        out[(states == FREE) & nearer] = UNKNOWN
    return out


def remainder_states(
    working: OccupancyMap,
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    remaining: NDArray[np.bool_],
    uses_free: bool,
    drop_isolated: bool,
) -> NDArray[np.int8]:
    """The map T of the recursion, as the registration sees it.

    Masked occupied cells (and, for methods that use it, their free space) are withdrawn.
    With ``drop_isolated``, so are *isolated* occupied cells (no other occupied cell within
    two cells): salt-and-pepper noise, whose flat spectrum would drown the walls of a small
    remainder. They are hidden from the registration only; the masking still counts them.
    """
    withdrawn = np.zeros(working.shape, dtype=bool)
    withdrawn[rows[~remaining], cols[~remaining]] = True
    left = working.occupied & ~withdrawn
    out = working.states.copy() if not uses_free else withdraw(working.states, withdrawn, left)
    out[withdrawn] = UNKNOWN
    if drop_isolated:
        out[left & isolated_cells(left)] = UNKNOWN
    return out


def remainder_cells(
    shape: tuple[int, int],
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    remaining: NDArray[np.bool_],
    drop_isolated: bool,
) -> OccupiedCells:
    """The occupied cells of :func:`remainder_states`, built from the cells left alone.

    The same cells as ``remainder_states(...) == OCCUPIED`` (for a method that does not use
    free space), as a crop of the box of the cells left: the cost follows those cells, not
    the grid. Isolated cells are found on that box (a cell outside it is never occupied).
    When the cells come row by row (as :func:`~brokenness.masking.cell_points` lists them),
    they are handed on as the crop's ``points`` too.
    """
    r, c = rows[remaining], cols[remaining]
    if r.size == 0:
        return OccupiedCells(np.zeros((0, 0), dtype=bool), (0, 0), shape)
    r0, c0 = int(r.min()), int(c.min())
    grid = np.zeros((int(r.max()) - r0 + 1, int(c.max()) - c0 + 1), dtype=bool)
    if drop_isolated:
        keep = ~isolated_points(r, c)
        r, c = r[keep], c[keep]
    grid[r - r0, c - c0] = True
    return OccupiedCells(grid, (c0, r0), shape, _row_major_points(r - r0, c - c0, grid.shape[1]))


def _row_major_points(
    rows: NDArray[np.intp], cols: NDArray[np.intp], width: int
) -> NDArray[np.int32] | None:
    """``(x, y)`` of distinct cells as int32, if they come row by row (else ``None``)."""
    flat = rows * width + cols
    if flat.size > 1 and not bool(np.all(flat[1:] > flat[:-1])):
        return None
    out = np.empty((rows.shape[0], 2), dtype=np.int32)
    out[:, 0] = cols
    out[:, 1] = rows
    return out


def moving_remainder(
    working: OccupancyMap,
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    remaining: NDArray[np.bool_],
    uses_free: bool,
    drop_isolated: bool,
    as_cells: bool,
) -> NDArray[np.int8] | OccupiedCells:
    """What the registration is given of the cells left: their occupied cells
    (:func:`remainder_cells`) when it takes them (``as_cells``) and does not use free space,
    else the grid of :func:`remainder_states`."""
    if as_cells and not uses_free:
        return remainder_cells(working.shape, rows, cols, remaining, drop_isolated)
    return remainder_states(working, rows, cols, remaining, uses_free, drop_isolated)


def candidates_of(
    registrar: Registrar,
    prepared: Any,
    moving: NDArray[np.int8] | OccupiedCells,
    max_candidates: int,
) -> list[Candidate]:
    """``registrar.candidates`` of what :func:`moving_remainder` returns."""
    if isinstance(moving, OccupiedCells):
        return cast(CellsRegistrar, registrar).candidates(prepared, moving, max_candidates)
    return registrar.candidates(prepared, moving, max_candidates)


def exhausted(registrar: Registrar) -> bool:
    """Whether ``registrar`` has spent its budget for this measure (its optional attribute
    ``exhausted``; absent: never), so that its optional searches are skipped."""
    return bool(getattr(registrar, "exhausted", False))


def prepared_reference(
    registrar: Registrar,
    reference: OccupancyMap,
    available: NDArray[np.bool_],
    uses_free: bool,
    as_cells: bool,
) -> Any:
    """``registrar.prepare_reference`` of the reference less the walls no longer
    ``available`` (:func:`reference_states`): given as its occupied cells (``available``
    itself, no copy) when the registration takes them (``as_cells``) and does not use free
    space."""
    if as_cells and not uses_free:
        cells = OccupiedCells(available, (0, 0), reference.shape)
        return cast(CellsRegistrar, registrar).prepare_reference(cells)
    return registrar.prepare_reference(reference_states(reference, available, uses_free))


def occupied_count(moving: NDArray[np.int8] | OccupiedCells) -> int:
    """Occupied cells of what :func:`moving_remainder` returns."""
    if isinstance(moving, OccupiedCells):
        return moving.count
    return int(np.count_nonzero(moving == OCCUPIED))


def isolated_cells(occupied: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Occupied cells with no other occupied cell in their 5x5 neighbourhood."""
    count = cv2.boxFilter(
        occupied.astype(np.uint8),
        cv2.CV_16U,
        (5, 5),
        normalize=False,
        borderType=cv2.BORDER_CONSTANT,
    )
    return occupied & (count == 1)


def not_isolated(points: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Which of the map's occupied cells ``points`` (``(x, y)``, whole cells) are walls, not
    specks of noise: the complement of :func:`isolated_points` at them."""
    return ~isolated_points(points[:, 1].astype(np.intp), points[:, 0].astype(np.intp))


def isolated_points(rows: NDArray[np.intp], cols: NDArray[np.intp]) -> NDArray[np.bool_]:
    """:func:`isolated_cells` at the given (distinct) occupied cells, counting only those.

    A small box of the cells is filtered as a grid; otherwise the cells are looked up among
    themselves, sorted by row and column (:func:`_isolated_sorted`): the cost follows the
    cells, not their box, and there is no temporary of the box's size.
    """
    if rows.size == 0:
        return np.zeros(0, dtype=bool)
    r0, c0 = int(rows.min()) - 2, int(cols.min()) - 2
    width = int(cols.max()) - c0 + 3
    height = int(rows.max()) - r0 + 3
    if height * width <= _DENSE_BOX * rows.size:  # a small box: one box filter is cheaper
        box = np.zeros((height, width), dtype=bool)
        box[rows - r0, cols - c0] = True
        return isolated_cells(box)[rows - r0, cols - c0]
    # row-major keys with two free columns on either side: cells of a row within two
    # columns of each other differ by at most 2, cells of different rows by at least 5
    keys = (rows - r0).astype(np.int64) * width + (cols - c0)
    if keys.size > 1 and not bool(np.all(keys[1:] > keys[:-1])):  # not row by row: sort
        order = np.argsort(keys, kind="stable")
        isolated = np.empty(keys.size, dtype=bool)
        isolated[order] = _isolated_sorted(keys[order], width)
        return isolated
    return _isolated_sorted(keys, width)


def _isolated_sorted(keys: NDArray[np.int64], width: int) -> NDArray[np.bool_]:
    """Per key, whether no other key lies within two rows and two columns of it.

    ``keys`` are ``row * width + col`` of distinct cells, ascending, every ``col`` at least 2
    and at most ``width - 3``: within a row the nearest other cells are the keys beside it
    in the order; in each of the four other rows, the first key at or after that row's
    ``col - 2`` is looked up (one binary search a cell and a row).
    """
    n = keys.size
    near = np.zeros(n, dtype=bool)
    beside = (keys[1:] - keys[:-1]) <= 2  # the same row, within two columns
    near[1:] = beside
    near[:-1] |= beside
    for dy in (-2, -1, 1, 2):
        low = keys + (dy * width - 2)  # that row, two columns to the left
        at = np.searchsorted(keys, low)
        np.minimum(at, n - 1, out=at)  # past the end: a key below ``low``, which fails
        gap = keys[at] - low
        near |= (gap >= 0) & (gap <= 4)
    return ~near


def reference_states(
    reference: OccupancyMap, available: NDArray[np.bool_], uses_free: bool
) -> NDArray[np.int8]:
    """The reference with the cells matched by earlier partitions withdrawn."""
    withdrawn = reference.occupied & ~available
    if not uses_free:
        out = reference.states.copy()
        out[withdrawn] = UNKNOWN
        return out
    return withdraw(reference.states, withdrawn, available)


def walls_connected(reference: OccupancyMap, points: NDArray[np.float64] | None = None) -> bool:
    """True when at most :data:`ISOLATED_SHARE` of the reference's occupied cells are isolated.

    Then isolated cells of the map are noise and are hidden from the registration; if the
    reference itself is dotted (a sparse probabilistic map), they are structure and stay.
    ``points``: the reference's occupied cells ``(x, y)``, if already at hand.
    """
    if points is None:
        rows, cols = np.nonzero(reference.occupied)
    else:
        rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    return bool(np.count_nonzero(isolated_points(rows, cols)) <= ISOLATED_SHARE * rows.size)
