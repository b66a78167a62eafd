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
  nearest occupied cell (found on a grid of 2 x 2 blocks): the scan that saw a cell free
  is, most likely, the scan that saw the wall behind it (a broken map's free space is the
  union of its partitions'). An occupied cell is its partition's wall unless the
  partition does not explain its neighbourhood and another one does (:func:`wall_owners`);
* it is moved by that partition's transform; it *contradicts* when it lands on an occupied
  reference cell, and counts when it lands on a known reference cell at all;
* the *chance rate* ``q`` is the share of the known reference cells that are occupied: the
  contradiction rate of free space dropped at random on the reference.

:class:`ClearFree` finds the clear free cells (once a call: they do not depend on the
partitions), :func:`free_space` gives each to its partition, and :func:`contradiction`
returns, per partition and for the whole map, the contradicting and the counted cells. The
ratio of the observed rate to ``q`` over the whole map decides whether the map is of the
reference's place (:data:`MAP_RATIO`). Per partition it is reported, and it chooses the
partitions searched again (:meth:`Contradiction.doubtful`), but it does not judge them:
the free space around a small partition is mostly seen from the scans of other
partitions (a broken map's free space is one union), so a true 4 % partition of a simulated
map was measured at 1.19 times the chance rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._points import cells_at, take_rows
from ..grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from ..masking import ReferenceIndex
from ..masking.distance import beyond
from ..transform import RigidTransform
from .partitions import Found, owners
from .support import SUPPORT_RADIUS, SUPPORT_SHARE, window_counts
from .views import isolated_points, not_isolated

__all__ = [
    "MAP_RATIO",
    "Contradiction",
    "FreeSpace",
    "ClearFree",
    "WallContradiction",
    "chance_rate",
    "contradiction",
    "doubtful_bound",
    "free_space",
    "wall_contradiction",
    "wall_owners",
]

#: A map is measured only if its free space crosses reference walls at most this share of
#: the chance rate, at the significance of the stopping rule (:meth:`Contradiction.upper_ratio`;
#: see the module docstring and the README for how it was chosen).
MAP_RATIO = 0.5
#: A rate is judged only when chance alone would put at least this many of its cells on
#: walls (fewer cells cannot tell a rate from the chance rate).
MIN_EXPECTED = 10.0
#: About this many clear free cells at most (an even grid of them) are looked up: enough
#: that chance alone would put thousands on walls.
_MAX_FREE = 400_000
#: ... in chunks of this many, so that the temporaries do not grow with the map.
_CHUNK = 16_384


#: Rows of the bands in which whole-grid masks are built (bounded temporaries).
_BAND_ROWS = 512


def _free_box(states: NDArray[np.int8]) -> tuple[int, int, int, int] | None:
    """``(row0, row1, col0, col1)`` (half-open) of the free cells, or None if there are none;
    found in bands of rows (no mask of the whole grid)."""
    rows = np.zeros(states.shape[0], dtype=bool)
    cols = np.zeros(states.shape[1], dtype=bool)
    for a in range(0, states.shape[0], _BAND_ROWS):
        free = states[a : a + _BAND_ROWS] == FREE
        rows[a : a + _BAND_ROWS] = free.any(axis=1)
        cols |= free.any(axis=0)
    if not rows.any():
        return None
    r, c = np.flatnonzero(rows), np.flatnonzero(cols)
    return int(r[0]), int(r[-1]) + 1, int(c[0]), int(c[-1]) + 1


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
        The clear free cells of every ``stride``-th row and column were looked up (counts are
        of those).
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

    def upper_ratio(self, z: float, i: int | None = None) -> float:
        """Upper confidence bound, ``z`` standard deviations, of the whole map's ratio (or,
        given ``i``, of partition ``i``'s).

        The contradicting cells are counted as a Poisson count ``X``; its upper bound is
        ``X + z sqrt(X + 1) + z^2 / 3`` (a close one-sided bound also for small counts), over
        the count chance would give (``n q``). ``inf`` when nothing is counted: a map that
        shows no free space on the reference cannot show that it fits there.
        """
        n = int(self.counted.sum() if i is None else self.counted[i])
        x = int(self.contradicting.sum() if i is None else self.contradicting[i])
        expected = n * self.chance
        if expected <= 0.0:
            return math.inf
        return (x + z * math.sqrt(x + 1.0) + z * z / 3.0) / expected

    def doubtful(self, z: float) -> list[int]:
        """The partitions whose free space, on its own, would not pass the map's test: the
        upper bound of its ratio, at ``z`` standard deviations, is :func:`doubtful_bound`
        (a rate that crosses walls too often, or too few cells to show that it does not).
        """
        return [i for i in range(self.counted.size) if doubtful_bound(self.upper_ratio(z, i))]


def doubtful_bound(bound: float | None) -> bool:
    """Whether an upper bound of a free-space ratio leaves its placement in doubt: it is over
    :data:`MAP_RATIO`, or nothing bounds it (``inf``, or ``None`` as results report it).

    The one test of a partition's own free space, on the counts during the measure
    (:meth:`Contradiction.doubtful`) and on a result's
    :attr:`~brokenness.measure.result.Partition.contradiction_bound` after it
    (:func:`~brokenness.measure.frames.partitions_in_doubt`).
    """
    return bound is None or not bound <= MAP_RATIO


@dataclass(frozen=True)
class FreeSpace:
    """The map's clear free cells (an even grid of them) and the partition that owns each.

    A clear free cell is free and farther than ``2 c`` from the map's walls; it belongs to the
    partition of its nearest wall (see the module docstring). Made once by
    :func:`free_space` for a set of partitions (their members), it is counted under their
    transforms by :func:`contradiction`, and under other transforms of one partition by
    :meth:`counts` (the settle step's judgement of a rival transform).

    Attributes
    ----------
    x, y : ndarray of int32, shape (M,)
        The clear free cells looked up (columns and rows of the working grid).
    owner : ndarray of int16, shape (M,)
        The partition (index in the list given) that owns each.
    stride : int
        The clear free cells of every ``stride``-th row and column were taken.
    """

    x: NDArray[np.int32]
    y: NDArray[np.int32]
    owner: NDArray[np.int16]
    stride: int

    def points(self, which: NDArray[np.bool_] | NDArray[np.intp]) -> NDArray[np.float64]:
        """The cells ``which`` selects (a mask or indices), as points ``(x, y)`` (float64)."""
        return np.column_stack([self.x[which], self.y[which]]).astype(np.float64)

    def counts(self, j: int, transform: RigidTransform, index: ReferenceIndex) -> tuple[int, int]:
        """``(counted, contradicting)`` of partition ``j``'s free cells moved by
        ``transform``: those that land on known reference cells, and those of them that land
        on occupied ones."""
        return landing(self.points(self.owner == j), transform, index)


def chance_rate(index: ReferenceIndex) -> float:
    """``q``: the share of the reference's known cells that are occupied, the rate at which
    free space dropped at random lands on walls (``0`` for a reference that knows nothing)."""
    n_known = index.known_count  # the occupied cells are counted in its occupied_points
    return float(index.occupied_points.shape[0]) / n_known if n_known else 0.0


def landing(
    owned: NDArray[np.float64], transform: RigidTransform, index: ReferenceIndex
) -> tuple[int, int]:
    """``(counted, contradicting)`` of the free cells ``owned`` (points ``(x, y)``) moved by
    ``transform``: those that land on known reference cells, and those of them that land on
    occupied ones (:meth:`FreeSpace.counts` of a partition's cells)."""
    if owned.shape[0] == 0:
        return 0, 0
    h, w = index.reference.shape
    moved = np.rint(transform.apply(owned)).astype(np.intp)
    x, y = moved[:, 0], moved[:, 1]
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    x, y = x[inside], y[inside]
    # the reference's known cells are looked up in its states (a mask of them would add a
    # byte a cell to the peak)
    on_known = cells_at(index.reference.states, y, x) != UNKNOWN
    return (
        int(np.count_nonzero(on_known)),
        int(np.count_nonzero(on_known & cells_at(index.occupied, y, x))),
    )


def contradiction(
    found: list[Found],
    points: NDArray[np.float64],
    clear: ClearFree,
    index: ReferenceIndex,
    owned: FreeSpace | None = None,
) -> Contradiction:
    """How often the map's clear free space lands on reference walls, per partition.

    Parameters
    ----------
    found : list of Found
        The partitions (members index ``points``).
    points : ndarray, shape (N, 2)
        The map's occupied cells ``(x, y)`` in the working grid, row-major.
    clear : ClearFree
        The map's clear free cells (at the working resolution).
    index : ReferenceIndex
        The reference, at the working resolution.
    owned : FreeSpace, optional
        :func:`free_space` of ``found`` (their members; made here if not given).

    Returns
    -------
    Contradiction
    """
    k = len(found)
    if owned is None:
        owned = free_space(found, points, clear, index)
    counted = np.zeros(k, np.int64)
    contradicting = np.zeros(k, np.int64)
    for start in range(0, owned.owner.size, _CHUNK):  # bounded temporaries
        owner = owned.owner[start : start + _CHUNK]
        for j, f in enumerate(found):
            sel = np.flatnonzero(owner == j)
            if sel.size:
                n, hits = landing(owned.points(sel + start), f.transform, index)
                counted[j] += n
                contradicting[j] += hits
    return Contradiction(counted, contradicting, chance_rate(index), owned.stride)


@dataclass(frozen=True, eq=False)
class ClearFree:
    """The clear free cells of a map (an even grid of them): free, and farther than ``2 c``
    from every map wall.

    What :func:`free_space` needs of the map whatever its partitions, for every contradiction
    of a call. Made on first use, once: the passes over the grid run when a contradiction
    first needs them (for a map of one partition, only at the end, once the registration's
    memory is freed).

    Parameters
    ----------
    working : OccupancyMap
        The map at the working resolution.
    threshold : float
        Agreement threshold ``c`` (cells).

    Attributes
    ----------
    stride : int
        The clear free cells of every ``stride``-th row and column are taken.
    box : tuple of int
        ``(row0, row1, col0, col1)`` (half-open): the box of the map's free cells with the
        walls around them (a margin of ``2 c`` and a cell), in which their walls are looked
        for.
    """

    working: OccupancyMap
    threshold: float
    #: the last :func:`free_space` of these cells, with what it was made of (one entry: the
    #: steps of a call ask again for the free space of partitions they have not changed)
    _last: list[tuple[_Partitioning, FreeSpace]] = field(
        default_factory=list, init=False, repr=False, compare=False
    )

    @cached_property
    def _cells(self) -> _Cells:
        return _clear_cells(self.working.states, self.threshold)

    @property
    def stride(self) -> int:
        return self._cells.stride

    @property
    def box(self) -> tuple[int, int, int, int]:
        return self._cells.box

    def cells(self) -> tuple[NDArray[np.int32], NDArray[np.int32]]:
        """The clear free cells taken, ``(x, y)`` (columns and rows of the working grid,
        row-major): new arrays on every call (kept as a byte a cell of the strided box)."""
        mask, stride, (r0, _, c0, _) = self._cells
        clear = np.flatnonzero(mask)  # flat indices in the strided box
        x, y = np.empty(clear.size, np.int32), np.empty(clear.size, np.int32)
        for start in range(0, clear.size, _CHUNK):  # bounded temporaries
            rows, cols = np.divmod(clear[start : start + _CHUNK], mask.shape[1])
            x[start : start + rows.size] = cols * stride + c0
            y[start : start + rows.size] = rows * stride + r0
        return x, y


@dataclass(frozen=True, eq=False)
class _Partitioning:
    """What :func:`free_space` is made of besides the clear cells: the partitions' transforms
    and members (copies), in order, the map's occupied points and the reference's index (the
    last two the same objects: a call's own, which nothing changes)."""

    parts: tuple[tuple[RigidTransform, NDArray[np.intp]], ...]
    points: NDArray[np.float64]
    index: ReferenceIndex

    @classmethod
    def of(
        cls, found: list[Found], points: NDArray[np.float64], index: ReferenceIndex
    ) -> _Partitioning:
        return cls(tuple((f.transform, f.members.copy()) for f in found), points, index)

    def made_of(
        self, found: list[Found], points: NDArray[np.float64], index: ReferenceIndex
    ) -> bool:
        """Whether ``found`` makes the same free space: the same points and index objects,
        equal transforms and equal members, partition by partition."""
        return (
            self.points is points
            and self.index is index
            and len(self.parts) == len(found)
            and all(
                t == f.transform and np.array_equal(m, f.members)
                for (t, m), f in zip(self.parts, found, strict=True)
            )
        )


class _Cells(NamedTuple):
    """What :class:`ClearFree` keeps: the clear cells of the strided box, and the box."""

    mask: NDArray[np.bool_]
    stride: int
    box: tuple[int, int, int, int]


def _clear_cells(states: NDArray[np.int8], threshold: float) -> _Cells:
    """:class:`ClearFree`'s cells of the map of ``states``."""
    # the box of the map's free cells: free space outside it does not exist
    free_box = _free_box(states)
    if free_box is None:
        return _Cells(np.zeros((0, 0), bool), 1, (0, 0, 0, 0))
    # clear free cells: farther than 2c from every map wall (a disc of radius 2c around walls);
    # the box takes the walls around the free cells along (a margin of the disc's radius and
    # a cell: the walls that bound the free space, and that mark free cells as near a wall)
    radius = max(int(math.ceil(2.0 * threshold)), 1)
    margin = radius + 1
    r0, r1 = max(free_box[0] - margin, 0), min(free_box[1] + margin, states.shape[0])
    c0, c1 = max(free_box[2] - margin, 0), min(free_box[3] + margin, states.shape[1])
    box = states[r0:r1, c0:c1]
    occupied = box == OCCUPIED
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    near_wall = cv2.dilate(occupied.view(np.uint8), disc).view(bool)
    del occupied
    clear_mask = np.logical_not(near_wall, out=near_wall)  # in place: no fresh grids
    for a in range(0, clear_mask.shape[0], _BAND_ROWS):  # ... nor a temporary of the box
        clear_mask[a : a + _BAND_ROWS] &= box[a : a + _BAND_ROWS] == FREE
    n_clear = int(np.count_nonzero(clear_mask))
    # an even grid of at most about _MAX_FREE of them (every stride-th row and column)
    stride = max(1, math.ceil(math.sqrt(n_clear / _MAX_FREE)))
    strided = clear_mask[::stride, ::stride]  # copied when strided: the whole mask is freed
    return _Cells(strided if stride == 1 else strided.copy(), stride, (r0, r1, c0, c1))


def wall_owners(
    found: list[Found], points: NDArray[np.float64], index: ReferenceIndex, clear: ClearFree
) -> NDArray[np.int16]:
    """The partition whose wall each occupied cell is, for the free space it bounds.

    Each cell of a partition is its partition's wall, unless it is *incoherent* there and
    *coherent* under another partition that also explains it: under its own partition's
    transform fewer than :data:`~brokenness.measure.support.SUPPORT_SHARE` of the occupied
    cells around it agree with the reference, under the other's (the one under which most
    do) at least that share. The recovery's test of a partition's cells
    (:mod:`~brokenness.measure.support`), asked of a wall that several partitions explain:
    where two parts of a broken map meet or overlap, a wall the greedy recursion gave to one
    partition is often the other part's (it agrees under both transforms, by coincidence
    along a long wall), and the free space in front of it was seen by the scans that saw
    the walls around it. Cells of no partition are ``-1``.
    """
    owner = owners(found, points.shape[0]).astype(np.int16)
    if len(found) < 2:
        return owner
    threshold = clear.threshold
    agree = np.stack(
        [index.occupied_agreement(f.transform.apply(points), threshold) for f in found]
    )
    ambiguous = (owner >= 0) & (np.count_nonzero(agree, axis=0) >= 2)
    if not ambiguous.any():
        return owner
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    shape = clear.working.shape
    support = np.stack(
        [window_counts(rows, cols, a, ambiguous, shape, SUPPORT_RADIUS) for a in agree]
    )
    # the share of the occupied cells around each that agree under each partition
    everything = np.ones(points.shape[0], dtype=bool)
    around = window_counts(rows, cols, everything, ambiguous, shape, SUPPORT_RADIUS)
    share = support / np.maximum(around, 1.0)
    share[~agree[:, ambiguous]] = -1.0
    own = owner[ambiguous].astype(np.intp)
    m = np.arange(own.size)
    best = np.argmax(share, axis=0)  # the first of ties
    # incoherent under its own partition, coherent under another: that one's wall
    switch = (share[own, m] < SUPPORT_SHARE) & (share[best, m] >= SUPPORT_SHARE)
    owner[ambiguous] = np.where(switch, best, own)
    return owner


def free_space(
    found: list[Found], points: NDArray[np.float64], clear: ClearFree, index: ReferenceIndex
) -> FreeSpace:
    """The map's clear free cells and the partition of ``found`` that owns each (the one of
    the nearest wall, :func:`wall_owners`; arguments as for :func:`contradiction`).

    The last one made with ``clear`` is kept there and given again for the same partitions
    (equal transforms and members, the same ``points`` and ``index``): the recovery, the
    relocation and the tests of a call ask for the free space of partitions they did not
    change, and at 8000² cells each takes a third of a second (the labels of the nearest
    walls, below)."""
    for made, owned in clear._last:
        if made.made_of(found, points, index):
            return owned
    owned = _free_space(found, points, clear, index)
    clear._last[:] = [(_Partitioning.of(found, points, index), owned)]
    return owned


def _free_space(
    found: list[Found], points: NDArray[np.float64], clear: ClearFree, index: ReferenceIndex
) -> FreeSpace:
    """:func:`free_space`, made anew."""
    empty = FreeSpace(np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0, np.int16), 1)
    x, y = clear.cells()
    if not found or x.size == 0:
        return empty
    r0, r1, c0, c1 = clear.box
    # the walls that label free space: cells of a partition, not isolated (a speck of noise
    # that one partition's transform happens to explain must not claim the room around it)
    owner = wall_owners(found, points, index, clear)
    px, py = points[:, 0].astype(np.intp) - c0, points[:, 1].astype(np.intp) - r0
    in_box = (py >= 0) & (py < r1 - r0) & (px >= 0) & (px < c1 - c0)
    px, py, owner = px[in_box], py[in_box], owner[in_box]  # row-major, as the box's labels
    is_source = (owner >= 0) & ~isolated_points(py, px)  # the box's walls are these points
    if not is_source.any():
        return empty
    # the nearest source wall of every cell, on a grid of 2 x 2 blocks (a quarter of the
    # memory and time; a block belongs to the partition of a source wall in it)
    coarse_shape = (-(-(r1 - r0) // 2), -(-(c1 - c0) // 2))
    block_owner = np.full(coarse_shape, -1, dtype=np.int16)
    block_owner[py[is_source] // 2, px[is_source] // 2] = owner[is_source]
    is_block = block_owner >= 0
    nearest: NDArray[np.int32] = np.asarray(
        cv2.distanceTransformWithLabels(
            np.logical_not(is_block).view(np.uint8),
            cv2.DIST_L2,
            cv2.DIST_MASK_5,
            labelType=cv2.DIST_LABEL_PIXEL,
        )[1],
        dtype=np.int32,
    )  # labels number the source blocks 1.. row-major, as boolean indexing lists them
    owners_of_blocks = block_owner[is_block]
    del block_owner, is_block
    # the owners, looked up chunk by chunk (bounded temporaries, whatever the map)
    out = FreeSpace(x, y, np.empty(x.size, np.int16), clear.stride)
    for start in range(0, x.size, _CHUNK):
        rows = y[start : start + _CHUNK].astype(np.intp) - r0
        cols = x[start : start + _CHUNK].astype(np.intp) - c0
        out.owner[start : start + rows.size] = owners_of_blocks.take(
            cells_at(nearest, rows // 2, cols // 2) - 1
        )
    return out


@dataclass(frozen=True)
class WallContradiction:
    """Wall contradiction of a set of partitions: map walls in the reference's clear free space.

    Attributes
    ----------
    counted : int
        Occupied map cells (isolated ones left out) that land on known reference cells, each
        under the transform of its partition or, unassigned, of the partition of its nearest
        assigned cell.
    contradicting : int
        Those that land on a *clear* free reference cell: free, farther than ``2 c`` from
        every reference wall.
    chance : float
        The share of known reference cells that are clear free: the rate of walls dropped
        at random.
    """

    counted: int
    contradicting: int
    chance: float

    def ratio(self) -> float | None:
        """Observed rate over the chance rate; ``None`` when too few cells are counted."""
        if self.chance <= 0.0 or self.counted * self.chance < MIN_EXPECTED:
            return None
        return (self.contradicting / self.counted) / self.chance

    def upper_ratio(self, z: float) -> float:
        """Upper bound of the ratio, as :meth:`Contradiction.upper_ratio` bounds its own."""
        expected = self.counted * self.chance
        if expected <= 0.0:
            return math.inf
        x = self.contradicting
        return (x + z * math.sqrt(x + 1.0) + z * z / 3.0) / expected


def wall_contradiction(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
) -> WallContradiction:
    """How often the map's walls land in the reference's clear free space.

    The converse of :func:`contradiction` (the other half of Birk & Carpin's disagreement:
    occupied in the map where the reference is free). A partition's own cells agree, so
    they never land there; what can are the cells no partition explains. Of a map of the
    reference's place those are few (clutter, moved furniture, a part not found); of a map
    of another place that one small partition happens to fit, they are most of the map, and
    they land on the reference's free space about as often as walls dropped at random.

    Parameters
    ----------
    found : list of Found
        The partitions (members index ``points``).
    points : ndarray, shape (N, 2)
        The map's occupied cells ``(x, y)`` in the working grid.
    index : ReferenceIndex
        The reference, at the working resolution.
    threshold : float
        Agreement threshold ``c`` (cells); clear free space is farther than ``2 c`` from
        reference walls.

    Returns
    -------
    WallContradiction
    """
    states = index.reference.states
    distance = index.occupied_distance
    limit = 2.0 * threshold
    # the share of the known cells that are free and farther than ``limit`` from walls
    known = index.known_count
    chance = index.free_beyond_count(limit) / known if known else 0.0
    owner = owners(found, points.shape[0])
    assigned = owner >= 0
    if not assigned.any():
        return WallContradiction(0, 0, chance)
    # specks of noise are not walls (the registration hides them too)
    walls = not_isolated(points)
    lost = walls & ~assigned
    if lost.any():  # the partition of the nearest assigned cell
        _, nearest = cKDTree(take_rows(points, assigned)).query(take_rows(points, lost))
        owner[lost] = owner[assigned][nearest]
    counted = contradicting = 0
    h, w = states.shape
    for j, f in enumerate(found):
        sel = walls & (owner == j)
        moved = np.rint(f.transform.apply(take_rows(points, sel))).astype(np.intp)
        x, y = moved[:, 0], moved[:, 1]
        inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        x, y = x[inside], y[inside]
        landed = cells_at(states, y, x)
        counted += int(np.count_nonzero(landed != UNKNOWN))
        contradicting += int(np.count_nonzero((landed == FREE) & beyond(distance[y, x], limit)))
    return WallContradiction(counted, contradicting, chance)
