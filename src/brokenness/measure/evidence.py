"""Contradiction: does the map's observed free space cross the reference's walls?

Agreement alone cannot tell a right alignment from a wrong one in a building of straight
walls: a wall segment lies along *some* reference wall under many transforms, and the
registration picks the transform under which most of them do. What a wrong alignment
cannot avoid is contradiction: where the robot saw free space, the reference has a wall.
Under the right transform a map's free space lands on a reference wall only where the two
maps really differ (a door open in one and closed in the other, glass, a moved object);
under a wrong one it lands on walls about as often as free space dropped at random would.

This module measures that, once the partitions are known:

* every *clear* free cell of the map (free, and farther than ``2 c`` from the map's own walls,
  so that wall thickness and a residual error do not count) belongs to the partition of its
  nearest occupied cell: the scan that saw a cell free is, most likely, the scan that saw the
  wall behind it (a broken map's free space is the union of its partitions');
* it is moved by that partition's transform; it *contradicts* when it lands on an occupied
  reference cell, and counts when it lands on a known reference cell at all;
* the *chance rate* ``q`` is the share of the known reference cells that are occupied: the
  contradiction rate of free space dropped at random on the reference.

:func:`contradiction` returns, per partition and for the whole map, the contradicting and the
counted cells. The ratio of the observed rate to ``q`` over the whole map decides whether the
map is of the reference's place (:data:`MAP_RATIO`). Per partition it is reported, not
judged: the free space around a small partition is mostly seen from the scans of other
partitions (a broken map's free space is one union), so a true 4 % partition of a simulated
map was measured at 1.19 times the chance rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..grid import FREE, OccupancyMap
from ..masking import ReferenceIndex
from ..masking.distance import sample_at
from .partitions import Found
from .views import isolated_cells

__all__ = ["MAP_RATIO", "Contradiction", "contradiction", "distance_to"]

#: A map is measured only if its free space crosses reference walls at most this share of
#: the chance rate (see the module docstring and the README for how it was chosen).
MAP_RATIO = 0.5
#: A rate is judged only when chance alone would put at least this many of its cells on
#: walls (fewer cells cannot tell a rate from the chance rate).
MIN_EXPECTED = 10.0
#: At most this many clear free cells (an even stride of them) are looked up.
_MAX_FREE = 400_000


@dataclass(frozen=True)
class Contradiction:
    """Free-space contradiction of a set of partitions.

    Attributes
    ----------
    counted : ndarray of int64
        Per partition (in the order given), clear free cells that land on known reference
        cells under its transform.
    contradicting : ndarray of int64
        Per partition, those that land on an occupied reference cell.
    chance : float
        ``q``: the share of known reference cells that are occupied.
    stride : int
        One clear free cell in ``stride`` was looked up (counts are of those).
    """

    counted: NDArray[np.int64]
    contradicting: NDArray[np.int64]
    chance: float
    stride: int

    def ratio(self, i: int | None = None) -> float | None:
        """Observed rate over the chance rate, for partition ``i`` or (``None``) the whole
        map; ``None`` when too few cells are counted to tell (:data:`MIN_EXPECTED`)."""
        n = int(self.counted.sum() if i is None else self.counted[i])
        x = int(self.contradicting.sum() if i is None else self.contradicting[i])
        if self.chance <= 0.0 or n * self.chance < MIN_EXPECTED:
            return None
        return (x / n) / self.chance


def distance_to(mask: NDArray[np.bool_]) -> NDArray[np.float32]:
    """Euclidean distance (OpenCV's 5x5 approximation) of every cell to the nearest True one."""
    grid = np.where(mask, 0, 1).astype(np.uint8)
    return np.asarray(cv2.distanceTransform(grid, cv2.DIST_L2, 5), dtype=np.float32)


def contradiction(
    found: list[Found],
    points: NDArray[np.float64],
    working: OccupancyMap,
    index: ReferenceIndex,
    threshold: float,
) -> Contradiction:
    """How often the map's clear free space lands on reference walls, per partition.

    Parameters
    ----------
    found : list of Found
        The partitions (members index ``points``).
    points : ndarray, shape (N, 2)
        The map's occupied cells ``(x, y)`` in ``working``'s grid, row-major.
    working : OccupancyMap
        The map at the reference's resolution.
    index : ReferenceIndex
        The reference.
    threshold : float
        Agreement threshold ``c`` (cells); free cells within ``2 c`` of a map wall are not
        counted.

    Returns
    -------
    Contradiction
    """
    reference = index.reference
    known = reference.known
    n_known = int(np.count_nonzero(known))
    chance = float(np.count_nonzero(reference.occupied & known)) / n_known if n_known else 0.0
    k = len(found)
    empty = Contradiction(np.zeros(k, np.int64), np.zeros(k, np.int64), chance, 1)
    free = working.states == FREE
    if k == 0 or not free.any():
        return empty
    # the box of the map's known cells: free space outside it does not exist
    rows_known = np.flatnonzero(free.any(axis=1))
    cols_known = np.flatnonzero(free.any(axis=0))
    r0, r1 = int(rows_known[0]), int(rows_known[-1]) + 1
    c0, c1 = int(cols_known[0]), int(cols_known[-1]) + 1
    occupied = working.occupied[r0:r1, c0:c1]
    # the walls that label free space: cells of a partition, not isolated (a speck of noise
    # that one partition's transform happens to explain must not claim the room around it)
    owner = np.full(points.shape[0], -1, dtype=np.intp)
    for j, f in enumerate(found):
        owner[f.members] = j
    px, py = points[:, 0].astype(np.intp) - c0, points[:, 1].astype(np.intp) - r0
    in_box = (py >= 0) & (py < r1 - r0) & (px >= 0) & (px < c1 - c0)
    source = np.zeros(occupied.shape, dtype=bool)
    source[py[in_box], px[in_box]] = owner[in_box] >= 0
    source &= ~isolated_cells(occupied)
    if not source.any():
        return empty
    clear = free[r0:r1, c0:c1] & (distance_to(occupied) > 2.0 * threshold)
    # which source wall is nearest (labels number the sources row-major)
    _, nearest = cv2.distanceTransformWithLabels(
        np.where(source, 0, 1).astype(np.uint8),
        cv2.DIST_L2,
        cv2.DIST_MASK_5,
        labelType=cv2.DIST_LABEL_PIXEL,
    )
    fr, fc = np.nonzero(clear)
    stride = max(1, -(-fr.size // _MAX_FREE))
    fr, fc = fr[::stride], fc[::stride]
    if fr.size == 0:
        return empty
    sr, sc = np.nonzero(source)
    source_owner = np.full(occupied.shape, -1, dtype=np.intp)
    source_owner[py[in_box], px[in_box]] = owner[in_box]
    free_owner = source_owner[sr, sc][nearest[fr, fc] - 1]
    free_pts = np.column_stack([fc + c0, fr + r0]).astype(np.float64)
    occupied_ref = reference.occupied.view(np.uint8).astype(np.float32)
    known_ref = known.view(np.uint8).astype(np.float32)
    counted = np.zeros(k, np.int64)
    contradicting = np.zeros(k, np.int64)
    for j, f in enumerate(found):
        sel = free_owner == j
        if not sel.any():
            continue
        moved = f.transform.apply(free_pts[sel])
        on_known = sample_at(known_ref, moved, 0.0, nearest=True) > 0.5
        on_wall = sample_at(occupied_ref, moved, 0.0, nearest=True) > 0.5
        counted[j] = int(np.count_nonzero(on_known))
        contradicting[j] = int(np.count_nonzero(on_wall & on_known))
    return Contradiction(counted, contradicting, chance, stride)
