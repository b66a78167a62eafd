"""What the registration sees in each step: the map's remainder and the unmatched reference.

Matched cells are withdrawn (set to unknown) from both; for methods that use free space, the
free cells nearer to withdrawn walls than to remaining ones go too. Isolated occupied cells
(salt-and-pepper noise) can be hidden from the registration when the reference shows that
walls are connected lines.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from ..grid import FREE, UNKNOWN, OccupancyMap
from ..masking import manhattan_distance_map

__all__ = [
    "isolated_cells",
    "reference_states",
    "remainder_states",
    "walls_connected",
    "withdraw",
]

#: A reference with at most this share of isolated occupied cells has connected walls.
ISOLATED_SHARE = 0.05


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


def walls_connected(reference: OccupancyMap) -> bool:
    """True when at most :data:`ISOLATED_SHARE` of the reference's occupied cells are isolated.

    Then isolated cells of the map are noise and are hidden from the registration; if the
    reference itself is dotted (a sparse probabilistic map), they are structure and stay.
    """
    occupied = reference.occupied
    return bool(
        np.count_nonzero(isolated_cells(occupied)) <= ISOLATED_SHARE * np.count_nonzero(occupied)
    )
