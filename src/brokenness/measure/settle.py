"""Settle: each partition's transform refitted where its own cells are, kept if the map agrees more.

A partition's transform is registered on a *remainder* of the recursion: the cells left
when the partitions found before it were masked out. Where two parts are only a little off
from each other (the bump happened close to where the robot then mapped), the remainder
holds cells of both, and the refined transform is a compromise between the two: it puts
most cells of one part and many of the other within a few cells of a wall, but neither
part where its own transform does. The greedy recursion cannot undo that (the cells it
masked are gone for the next step), and :func:`~brokenness.measure.partitions.reassign`
only moves cells between the transforms it is given.

Refitted on the cells of one part alone, such a transform converges to that part's own (on
a real-log map of the benchmark, Seattle at degree 6, two compromises 4-5 cells off, which
made 71 % and 46 % of their parts' cells agree, converged to the true transforms, 0.0 and
0.1 cells off, when refitted on their true parts' cells). The cells of one part are found
locally: a part is a contiguous stretch of the robot's run, so a small square of the map
mostly holds one. So :func:`settle`:

1. lays a grid of square *tiles* of side :data:`TILE_SIDE` cells over the map;
2. in every tile of at least :data:`MIN_TILE_CELLS` occupied cells, refits the transform
   of the partition that makes most of the tile's cells agree (a tile mostly holds one
   part), if it makes at least :data:`~brokenness.measure.recovery.SUPPORT_SHARE` (the
   coherence test's share) but less than :data:`EXPLAINED` of them agree, on the tile's
   cells, with the
   refinement of the recursion's hypotheses (rotation sweep, trimmed ICP, compass search,
   :mod:`~brokenness.measure.refine`; :data:`REFITS` times): each refit is a *candidate*
   transform of that partition;
   Isolated cells (specks of noise, hidden from the registration too) take no part in
   this stage. The refinement pulls only on cells within the loose threshold, so it cannot
   reach a part that a pure-shift bump moved farther against its neighbour (half a metre
   is 10 cells at 5 cm): every partition's transform is also shifted, by whole cells
   within :data:`MAX_SHIFT`, to where the most cells that no partition explains agree, and
   refitted there (on those cells and its own), a candidate of that partition too;
3. replaces, one at a time, the transform of a partition by one of its own candidates when
   that makes more cells of the map agree with the reference under some partition (the
   union of the cells explained, the count the recursion itself maximises), the largest
   gain first, until no replacement adds a cell. *Rivals* (transforms found elsewhere: the
   recovery's hypotheses of suspects too few for a new partition, and of the own cells of
   each partition whose free space does not show that it is in place, registered alone)
   are offered to every
   partition too: a part registered where a twin of its room is (turned by 90 or 180
   degrees, or far off) fits its own cells there, so no refit moves it, but its true place
   leaves a few of its cells unexplained, and the recovery finds the true transform among
   them. A rival is judged by the same count; a partition that had at least ``min_cells``
   cells no other explains and has fewer with the rival in is dropped (a part may be held
   by two wrong placements), its cells counted as lost; and the gain must exceed what chance
   could give on the cells the two contest (the shift search's margin, below), or come
   with a partition's free space that crosses the reference's walls significantly less
   often (:class:`_FreeSpaceTest`), which, when no replacement adds a cell, also breaks a
   tie of the count;
4. when no replacement adds a cell, *splits* a partition in two if its refits say it holds
   two parts: the compromise of two parts at one rotation, shifted against each other (a
   pure-shift bump), is refitted to one part on that part's tiles and to the other on the
   other's. Of the cells no other partition explains, the pair of transforms (the
   partition's own or one of its refits, and another of its refits) must explain more than
   the partition does alone; each must pass the recursion's stopping rule as the recursion
   would have taken it after the other (the cells it explains among those the other leaves,
   against the chance of a random placement); and the cells each explains alone must not be
   explained loosely by the other's transform (the recursion's merge test,
   :func:`~brokenness.measure.partitions.merge_target`: the two are off from each other,
   not one part with a residual error). The split that explains most is made, and steps
   3-4 are repeated; once a split is made, the whole step runs again with the new
   partitions' own tiles. Of refits that put a partition's cells within
   :data:`SAME_FIT` of each other only the first is paired, and at most
   :data:`MAX_SPLIT_REFITS` of them (those explaining the most cells);
5. gives every cell to its best partition again
   (:func:`~brokenness.measure.partitions.reassign`), and, given the map's clear free
   cells, drops each half split off whose free space (the free cells whose nearest wall is
   one of its cells) crosses the reference's walls significantly more often under its own
   transform than under that of the partition it was split from
   (:meth:`_FreeSpaceTest.worsened`, the rivals' comparison the other way round): a part
   that is truly off puts its free space on walls about as often as chance under the
   transform that held it, while a half that agrees by coincidence (a twin of a symmetric
   corridor, clutter on a floor) moves free space that transform kept clear onto walls.

A transform moves only where the cells of its own partition pull it and the whole map agrees
more; a partition is added only with the evidence a new partition of the recursion needs.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from .._points import point_norms, take_rows
from ..masking import ReferenceIndex
from ..masking.distance import within
from ..transform import RigidTransform
from .evidence import MIN_EXPECTED, ClearFree, FreeSpace, chance_rate, free_space
from .options import Settings
from .partitions import Found, merge_target, reassign
from .recovery import SUPPORT_SHARE
from .refine import refit_transform
from .views import not_isolated

__all__ = ["EXPLAINED", "MIN_TILE_CELLS", "TILE_SIDE", "settle"]

#: Side of the square tiles, in cells of the working grid: twice the window of the
#: coherence test (``2 SUPPORT_RADIUS + 1`` cells), small enough that most tiles hold one
#: part, large enough to hold walls of two directions.
TILE_SIDE = 50
#: A tile is refitted only if it holds at least this many occupied cells (the refinement
#: samples up to thousands; 60 cells are a few metres of wall).
MIN_TILE_CELLS = 60
#: Rounds of refinement per tile and partition.
REFITS = 2
#: A tile whose partition already makes this share of its cells agree is not refitted.
EXPLAINED = 0.95
#: Refits that put every cell of their partition within this many cells of each other are
#: one fit for a split (the first is kept).
SAME_FIT = 1.0
#: A tile's partition is also refitted from the best whole-cell shift of its transform
#: within this many cells (half a tile): parts shifted farther than the refinement reaches.
MAX_SHIFT = TILE_SIDE // 2
#: ... counted on at most this many cells (an even stride of them), in chunks of
#: ``_SHIFT_CHUNK`` cells (bounded temporaries; a chunk's counts fit in a byte).
SHIFT_SAMPLE = 1000
_SHIFT_CHUNK = 255
#: At most this many distinct refits of a partition are paired in the search for a split.
MAX_SPLIT_REFITS = 32


def settle(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
    rivals: Sequence[RigidTransform] = (),
    refits: bool = True,
    clear: ClearFree | None = None,
    owned: FreeSpace | None = None,
    by_count: bool = False,
) -> list[Found]:
    """Refit each partition's transform on tiles of its cells; keep what explains more, and
    split a partition whose refits are two parts (see the module docstring).

    Parameters
    ----------
    found : list of Found
        The partitions (members index ``points``).
    points : ndarray, shape (N, 2)
        The map's occupied cells, ``(x, y)``.
    index : ReferenceIndex
        The reference.
    settings : Settings
        The per-map settings (``threshold``, ``loose``, ``min_cells``).
    rivals : sequence of RigidTransform, optional
        Transforms found elsewhere (the recovery's hypotheses too weak for a new partition),
        offered to every partition as replacements; one is taken only if it makes more
        cells agree than chance could (see step 3).
    refits : bool, optional
        Refit the transforms on tiles and shifts (steps 2 and 4); ``False`` offers only the
        ``rivals``, to partitions already settled (whose refits added nothing).
    clear : ClearFree, optional
        The map's clear free cells (:class:`~brokenness.measure.evidence.ClearFree`, at the
        working resolution, as ``points``): a rival that explains more cells, though not
        more than chance could, is taken when the partition's free space then crosses the
        reference's walls significantly less often (step 3). Without them, only the count
        of agreeing cells judges a rival.
    owned : FreeSpace, optional
        :func:`~brokenness.measure.evidence.free_space` of ``found``, if already made (made
        here when a rival needs it).
    by_count : bool, optional
        Take a rival that empties no partition for any gain of the count (the measure's
        last pass, :mod:`~brokenness.measure.pool`: neither the degree nor the verdict is
        at stake there); a rival that empties one must still be significant.

    Returns
    -------
    list of Found
        The partitions, in the order given, with their settled transforms and cells; the
        halves split off after them.
    """
    if not found:
        return found
    threshold = settings.threshold
    transforms = [f.transform for f in found]
    # specks of noise are no part's walls: they neither pull a refit nor count as explained
    walls = points[not_isolated(points)]
    agree = np.stack([index.occupied_agreement(t.apply(walls), threshold) for t in transforms])
    seeds: list[int] = []
    candidates: list[RigidTransform] = []
    if refits:
        seeds, candidates = _candidates(transforms, agree, walls, index, settings)
        more_seeds, more = _shifted_copies(transforms, agree, walls, index, settings)
        seeds, candidates = seeds + more_seeds, candidates + more
    local = len(candidates)  # the refits; the rivals, offered to every partition, after them
    for t in rivals:
        seeds += list(range(len(transforms)))
        candidates += [t] * len(transforms)
    if not candidates:
        return found
    rows = [index.occupied_agreement(t.apply(walls), threshold) for t in candidates[:local]]
    for t in rivals:  # one lookup a rival, its row offered to every partition
        row = index.occupied_agreement(t.apply(walls), threshold)
        rows += [row] * len(transforms)
    offered = np.stack(rows)
    seeds_arr = np.asarray(seeds)
    p0 = index.chance_agreement(threshold)
    free = None if clear is None else _FreeSpaceTest(found, points, clear, index, settings, owned)
    added: list[Found] = []
    parents: list[int] = []  # the partition each of ``added`` was split from
    alive = np.ones(len(transforms), dtype=bool)  # partitions a rival left redundant drop out
    while True:
        covered = _column_counts(agree)
        explained = int(np.count_nonzero(covered))
        best_gain, best, emptied = 0, None, _NO_CELLS
        tie: tuple[tuple[int, int], NDArray[np.intp]] | None = None  # the first clearing tie
        alone = _row_counts(agree & (covered == 1))  # cells only each explains
        for j in range(len(transforms)):
            mine = np.flatnonzero(seeds_arr == j)
            if mine.size == 0:
                continue
            rest = covered - agree[j]  # the partitions but j that explain each cell
            others = rest > 0
            near = mine[mine < local]
            if near.size:
                gains = _row_counts(others | offered[near]) - explained
                k = int(np.argmax(gains))
                if int(gains[k]) > best_gain:
                    best_gain, best, emptied = int(gains[k]), (j, int(near[k])), _NO_CELLS
            for c in mine[mine >= local]:
                offer = _rival_gain(
                    j,
                    offered[c],
                    agree,
                    (rest, others, explained),
                    alone,
                    p0,
                    settings,
                    None if free is None else free.clears(j, transforms[j], candidates[c]),
                    ties=tie is None and best is None,
                    by_count=by_count,
                )
                if offer is None:
                    continue
                gain, redundant = offer
                if gain > best_gain:
                    best_gain, best, emptied = gain, (j, int(c)), redundant
                elif gain == 0 and tie is None:
                    tie = (j, int(c)), redundant
        if best is None and tie is not None:  # no rival adds a cell: a tie that clears
            best, emptied = tie
        if best is not None:
            j, c = best
            transforms[j], agree[j] = candidates[c], offered[c]
            seeds_arr[c] = -1  # used
            for dead in emptied.tolist():
                alive[dead], agree[dead] = False, False
                seeds_arr[seeds_arr == dead] = -1
            continue
        # no replacement adds a cell: a partition whose refits disagree may be two parts
        # (step 4)
        if len(transforms) >= settings.max_partitions:
            break
        own = np.where(np.arange(seeds_arr.size) < local, seeds_arr, -1)  # no rival halves
        split = _best_split(transforms, agree, candidates, offered, own, walls, index, settings)
        if split is None:
            break
        j, a, b, confidence = split
        if a >= 0:
            transforms[j], agree[j] = candidates[a], offered[a]
            seeds_arr[a] = -1
        transforms.append(candidates[b])
        agree = np.vstack([agree, offered[b][None]])
        added.append(Found(candidates[b], np.zeros(0, np.intp), confidence, 0.0))
        parents.append(j)
        alive = np.append(alive, True)
        seeds_arr[b] = -1
    if (
        not added
        and alive.all()
        and all(t is f.transform for t, f in zip(transforms, found, strict=True))
    ):
        return found
    moved = [
        Found(t, f.members, f.confidence, f.seconds)
        for t, f, kept in zip(transforms[: len(found)], found, alive[: len(found)], strict=True)
        if kept
    ]
    halves = [
        (a, transforms[j])
        for a, j, kept in zip(added, parents, alive[len(found) :], strict=True)
        if kept
    ]
    added = [a for a, _ in halves]
    settled = reassign([*moved, *added], points, index, threshold, settings.min_cells)
    if added and free is not None:
        settled = _without_worse_halves(settled, halves, points, index, settings, free)
    if added and len(settled) > len(found):  # the new partitions' own tiles: settle again
        return settle(settled, points, index, settings, rivals, refits, clear, by_count=by_count)
    return settled


def _without_worse_halves(
    settled: list[Found],
    halves: list[tuple[Found, RigidTransform]],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
    free: _FreeSpaceTest,
) -> list[Found]:
    """``settled`` without the halves split off (each given with the transform of the
    partition it was split from) whose free space is worse under their own transform (step 5
    of the module docstring, :meth:`_FreeSpaceTest.worsened`), the cells reassigned."""
    parents = [
        (q, parent)
        for q, g in enumerate(settled)
        for half, parent in halves
        if g.transform is half.transform
    ]
    worse = free.worsened(settled, parents)
    if not worse:
        return settled
    kept = [g for q, g in enumerate(settled) if q not in worse]
    return reassign(kept, points, index, settings.threshold, settings.min_cells)


def _rival_gain(
    j: int,
    offered: NDArray[np.bool_],
    agree: NDArray[np.bool_],
    without: tuple[NDArray[np.int64], NDArray[np.bool_], int],
    alone: NDArray[np.intp],
    p0: float,
    settings: Settings,
    clears: Callable[[], bool] | None = None,
    ties: bool = False,
    by_count: bool = False,
) -> tuple[int, NDArray[np.intp]] | None:
    """What replacing partition ``j``'s transform by a rival (its agreement ``offered``)
    gains, and the partitions it leaves redundant (step 3). ``without`` is what the
    partitions explain without ``j`` (the same for every rival of ``j``): per cell how many
    of the others explain it, whether any does, and how many cells all the partitions
    explain; ``alone`` is, per partition, its cells no other explains.

    The gain is the count the recursion maximises: cells explained by some partition. A
    partition that had at least ``min_cells`` cells no other explains, and has fewer once
    the rival is in, is left without evidence of its own and is dropped (a part at a wrong
    place may be held by two partitions, each explaining half of its cells there); the
    cells it still explained alone count as lost. A rival is not a refit of the partition's
    own cells, so the gain must be significant: exceed what chance could give on the cells
    the two contest (the shift search's margin), or, if it is positive but smaller, come
    with the other kind of evidence, ``clears()``: the partition's free space crosses the
    reference's walls significantly less often under the rival
    (:meth:`_FreeSpaceTest.clears`). With ``ties``, a rival that explains exactly as many
    cells (gain ``0``) is offered too when it clears the free space: the count cannot tell
    the two placements apart, the free space can (a small part at a twin of its room, whose
    true transform the recovery found: in a drawn office at degree 7, the true place of a
    part of 7 % explained as many cells, one more or less as other partitions moved, while
    its free space crossed the reference's walls significantly less often); :func:`settle`
    takes such a tie only when no rival adds a cell (and, as every replacement, uses each
    candidate once, so the step ends). With ``by_count``, a rival that empties no partition
    is taken for any gain. ``None``: the rival is not taken. (A version that
    also credited each dropped partition with the smallest partition's cells, a cost per
    partition, replaced two small partitions by one transform that explained fewer cells: a
    degree one short.)
    """
    rest, others, explained = without
    after = rest + offered
    alone_after = _row_counts(agree & (after == 1))
    emptied = (alone >= settings.min_cells) & (alone_after < settings.min_cells)
    emptied[j] = False
    redundant = np.flatnonzero(emptied)
    if redundant.size:
        after = after - _column_counts(agree[redundant])
    gain = int(np.count_nonzero(after)) - explained
    if by_count and gain > 0 and redundant.size == 0:
        return gain, redundant
    contested = int(np.count_nonzero((agree[j] | offered) & ~others))
    margin = settings.significance * np.sqrt(contested * p0 * (1.0 - p0))
    if gain > margin or (gain > 0 and clears is not None and clears()):
        return gain, redundant
    if ties and gain == 0 and clears is not None and clears():
        return 0, redundant  # a tie: taken if no rival adds a cell
    return None


class _FreeSpaceTest:
    """Whether a rival transform clears a partition's free space (step 3 of the module
    docstring): the partition's clear free cells (those whose nearest wall is its, as the
    contradiction test of :mod:`~brokenness.measure.evidence` charges them) cross reference
    walls at a significantly lower rate under the rival than under its transform.

    Under a right transform a part's free space lands on reference walls only where the two
    maps differ; under a wrong one (a twin of its room, turned by 90 or 180 degrees) about as
    often as free space dropped at random. A part held at such a twin fits its walls there
    about as well as in its true place, so the count of agreeing cells tells the two apart by
    a few cells only (on the realistic benchmark's failing maps, 6-14 cells against a chance
    margin of 21-31), while the rates of its free space differ by a factor of 5-10. The two
    rates, ``x / n`` of each transform (``n`` free cells landing on known reference cells,
    ``x`` of them on walls), are compared as Poisson counts: the fall must exceed ``z``
    (the stopping rule's significance) standard deviations of the difference,
    ``sqrt((x_old + 1) / n_old^2 + (x_new + 1) / n_new^2)``, and each rate must be
    measurable (chance would put at least
    :data:`~brokenness.measure.evidence.MIN_EXPECTED` of its cells on walls).

    The free space is assigned once, from the partitions' members as given to the settle
    step (the members do not change until its final reassignment), and only when a rival
    needs it.
    """

    def __init__(
        self,
        found: list[Found],
        points: NDArray[np.float64],
        clear: ClearFree,
        index: ReferenceIndex,
        settings: Settings,
        owned: FreeSpace | None = None,
    ) -> None:
        self._args = (found, points, clear)
        self._index = index
        self._z = settings.significance
        self._chance = chance_rate(index)
        self._owned = owned

    def worsened(self, found: list[Found], parents: list[tuple[int, RigidTransform]]) -> list[int]:
        """Of the partitions ``q`` of ``found`` given with a transform ``parent`` (that of the
        partition each was split from), those whose free space (the free cells whose nearest
        wall is one of its cells, among ``found``'s) crosses the reference's walls at a
        significantly *higher* rate under its own transform than under ``parent``: the
        comparison of :meth:`clears`, the other way round."""
        if not parents:
            return []
        _, points, clear = self._args
        owned = free_space(found, points, clear, self._index)
        return [
            q
            for q, parent in parents
            if self._falls(
                owned.counts(q, found[q].transform, self._index),
                owned.counts(q, parent, self._index),
            )
        ]

    def clears(self, j: int, old: RigidTransform, new: RigidTransform) -> Callable[[], bool]:
        """The test for partition ``j``, transform ``old`` replaced by ``new`` (a callable:
        it runs only when asked)."""
        return lambda: self._clears(j, old, new)

    def _clears(self, j: int, old: RigidTransform, new: RigidTransform) -> bool:
        if self._owned is None:
            self._owned = free_space(*self._args, self._index)
        return self._falls(
            self._owned.counts(j, old, self._index), self._owned.counts(j, new, self._index)
        )

    def _falls(self, old: tuple[int, int], new: tuple[int, int]) -> bool:
        """Whether the rate ``x / n`` of ``(n, x)`` falls significantly from ``old`` to
        ``new`` (see the class docstring; ``False`` when either cannot be told)."""
        (n_old, x_old), (n_new, x_new) = old, new
        if min(n_old, n_new) * self._chance < MIN_EXPECTED:
            return False  # too few free cells on the reference to tell a rate
        fall = x_old / n_old - x_new / n_new
        spread = math.sqrt((x_old + 1.0) / n_old**2 + (x_new + 1.0) / n_new**2)
        return fall > self._z * spread


def _best_split(
    transforms: list[RigidTransform],
    agree: NDArray[np.bool_],
    candidates: list[RigidTransform],
    offered: NDArray[np.bool_],
    seeds: NDArray[np.intp],
    walls: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
) -> tuple[int, int, int, float] | None:
    """The split of a partition in two that explains the most cells more than it does.

    Returns ``(j, a, b, confidence)``: partition ``j``'s transform is replaced by its refit
    ``a`` (``-1``: kept) and its refit ``b`` is added, if the two explain more of the cells
    that no other partition explains than ``j`` alone, each of them passes the stopping rule
    as the recursion would take it after the other (among those cells, less the ones the
    other explains), and the cells it explains alone are not explained loosely by the
    other's transform (the recursion's merge test,
    :func:`~brokenness.measure.partitions.merge_target`: the two are off from each other).
    """
    covered = _column_counts(agree)
    p0 = index.chance_agreement(settings.threshold)
    best, best_gain = None, 0
    for j in range(agree.shape[0]):
        others = (covered - agree[j]) > 0
        mine = _distinct(j, seeds, candidates, offered, take_rows(walls, agree[j]), ~others)
        if mine.size == 0:
            continue
        open_cells = int(np.count_nonzero(~others))
        names = np.concatenate([[-1], mine])
        open_at = np.flatnonzero(~others)
        halves = np.vstack([agree[j][None], offered[mine]])[:, open_at]  # (1 + M, open)
        some = halves.any(axis=0)  # open cells some half explains (the others count nowhere)
        halves, open_at = halves[:, some], open_at[some]
        # both[x, y]: the open cells halves x and y both explain
        both = np.stack([_row_counts(halves & row) for row in halves])
        counts = np.diagonal(both)
        only = counts[:, None] - both  # only[x, y]: cells x explains and y does not
        gain = counts[:, None] + counts[None, :] - both - counts[0]
        # each half as the recursion would take it after the other: the cells it explains
        # among those the other leaves pass the stopping rule
        needed = np.array([settings.needed(open_cells - int(c), p0)[2] for c in counts])
        ok = (only >= needed[None, :]) & (only.T >= needed[:, None]) & (gain > best_gain)
        ok[:, 0] = False  # the partition's own transform is kept (x = 0), never added
        np.fill_diagonal(ok, False)
        xs, ys = np.nonzero(ok)
        for q in np.lexsort((ys, xs, -gain[xs, ys])):  # the largest gain first
            x, y = int(xs[q]), int(ys[q])
            tx = transforms[j] if x == 0 else candidates[int(names[x])]
            ty = candidates[int(names[y])]
            only_x = open_at[halves[x] & ~halves[y]]
            only_y = open_at[halves[y] & ~halves[x]]
            rest = [t for q, t in enumerate(transforms) if q != j]
            if _explains([tx, *rest], take_rows(walls, only_y), index, settings) or _explains(
                [ty, *rest], take_rows(walls, only_x), index, settings
            ):
                continue
            chance = settings.needed(open_cells - int(counts[x]), p0)[0]
            ky = int(only[y, x])
            best, best_gain = (j, int(names[x]), int(names[y]), (ky - chance) / ky), int(gain[x, y])
            break
    return best


def _distinct(
    j: int,
    seeds: NDArray[np.intp],
    candidates: list[RigidTransform],
    offered: NDArray[np.bool_],
    cells: NDArray[np.float64],
    open_cells: NDArray[np.bool_],
) -> NDArray[np.intp]:
    """Partition ``j``'s unused refits that a split may use: of refits that put its cells
    within a cell of each other (:data:`SAME_FIT`) the first, and at most
    :data:`MAX_SPLIT_REFITS` of them, those explaining the most open cells first."""
    mine = np.flatnonzero(seeds == j)
    if mine.size == 0 or cells.shape[0] == 0:
        return mine
    sample = cells[:: max(1, cells.shape[0] // 256)]
    placed = np.stack([candidates[int(c)].apply(sample) for c in mine])  # (M, S, 2)
    kept: list[int] = []
    for q in range(mine.size):
        if all(float(point_norms(placed[q] - placed[k]).max()) > SAME_FIT for k in kept):
            kept.append(q)
    distinct = mine[kept]
    explained = _row_counts(offered[distinct] & open_cells)
    order = np.lexsort((distinct, -explained))[:MAX_SPLIT_REFITS]
    return np.sort(distinct[order])


def _explains(
    transforms: list[RigidTransform],
    cells: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
) -> bool:
    """One of ``transforms`` explains ``cells`` loosely (the merge test of the recursion)."""
    found = [Found(t, _NO_CELLS, 0.0, 0.0) for t in transforms]
    return merge_target(found, cells, index, settings.loose) is not None


_NO_CELLS = np.zeros(0, dtype=np.intp)


def _row_counts(mask: NDArray[np.bool_]) -> NDArray[np.intp]:
    """``numpy.count_nonzero(mask, axis=1)`` of a 2D mask: one count a row (numpy's count
    along an axis sums the cells as integers, several times the cost on rows of a map's
    cells)."""
    return np.array([np.count_nonzero(row) for row in mask], dtype=np.intp)


def _column_counts(mask: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``mask.sum(axis=0)`` of a 2D mask (how many rows hold each cell), summed as bytes
    while fewer than 256 rows cannot overflow them."""
    if mask.shape[0] >= 256:
        return np.asarray(mask.sum(axis=0), dtype=np.int64)
    return np.add.reduce(mask.view(np.uint8), axis=0, dtype=np.uint8).astype(np.int64)


def _candidates(
    transforms: list[RigidTransform],
    agree: NDArray[np.bool_],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
) -> tuple[list[int], list[RigidTransform]]:
    """Per tile, the refit of the partition that explains most of its cells (step 2)."""
    if points.shape[0] == 0:  # every cell isolated (a map of specks): no tile to refit
        return [], []
    tile = (points[:, 1] // TILE_SIDE).astype(np.int64) * (1 << 32) + (
        points[:, 0] // TILE_SIDE
    ).astype(np.int64)
    order = np.argsort(tile, kind="stable")
    _, starts = np.unique(tile[order], return_index=True)
    bounds = [*starts[1:], order.size]
    seeds: list[int] = []
    candidates: list[RigidTransform] = []
    for start, stop in zip(starts, bounds, strict=True):
        cells = order[start:stop]
        if cells.size < MIN_TILE_CELLS:
            continue
        share = agree[:, cells].mean(axis=1)
        j = int(np.argmax(share))  # the partition of the tile: a tile mostly holds one part
        if SUPPORT_SHARE <= share[j] < EXPLAINED:
            tile_points = take_rows(points, cells)
            origins = [transforms[j]]
            shifted = _shift_search(
                transforms[j],
                tile_points,
                index,
                settings.threshold,
                settings.loose,
                settings.significance,
            )
            if shifted is not None:
                origins.append(shifted)
            for refit in origins:
                for _ in range(REFITS):
                    refit = refit_transform(
                        refit, tile_points, index, settings.threshold, settings.loose
                    )
                if refit is not transforms[j]:
                    seeds.append(j)
                    candidates.append(refit)
    return seeds, candidates


def _shifted_copies(
    transforms: list[RigidTransform],
    agree: NDArray[np.bool_],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
) -> tuple[list[int], list[RigidTransform]]:
    """Per partition, its transform shifted to where most cells no partition explains agree."""
    left = np.asarray(~agree.any(axis=0))
    seeds: list[int] = []
    candidates: list[RigidTransform] = []
    if np.count_nonzero(left) < settings.min_cells:
        return seeds, candidates
    left_points = take_rows(points, left)
    for j, t in enumerate(transforms):
        shifted = _shift_search(
            t,
            left_points,
            index,
            settings.threshold,
            settings.loose,
            settings.significance,
        )
        if shifted is None:
            continue
        cells = take_rows(points, left | agree[j])
        refit = shifted
        for _ in range(REFITS):
            refit = refit_transform(refit, cells, index, settings.threshold, settings.loose)
        seeds.append(j)
        candidates.append(refit)
    return seeds, candidates


def _shift_search(
    transform: RigidTransform,
    cells: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    reach: float,
    significance: float,
) -> RigidTransform | None:
    """``transform`` followed by the whole-cell shift, within :data:`MAX_SHIFT` cells, that
    makes the most ``cells`` agree, if it makes more agree than no shift by more than chance
    could (``significance`` standard deviations of the count of cells agreeing by chance)
    and is longer than ``reach`` (the refinement's: it finds shorter ones itself); ``None``
    if not.

    The refinement's trimmed ICP only pulls on cells within the loose threshold, so it cannot
    reach a part shifted farther against a partition (a pure-shift bump of half a metre is
    10 cells at 5 cm). Every other shift is counted first, then the eight around the best
    of them, on at most :data:`SHIFT_SAMPLE` of the cells (an even stride of them), by
    lookups in the reference's agreement mask around them.
    """
    picked = cells[:: max(1, -(-cells.shape[0] // SHIFT_SAMPLE))]
    moved = np.rint(transform.apply(picked)).astype(np.int64)
    h, w = index.occupied_distance.shape
    x0, y0 = moved.min(axis=0) - MAX_SHIFT
    x1, y1 = moved.max(axis=0) + MAX_SHIFT + 1
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if cx0 >= cx1 or cy0 >= cy1:
        return None
    width = int(x1 - x0)
    window = np.zeros((int(y1 - y0), width), dtype=bool)  # the agreement mask, zero outside
    window[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0] = within(
        index.occupied_distance[cy0:cy1, cx0:cx1], threshold
    )
    flat = window.ravel().view(np.uint8)  # 0/1 bytes: a chunk's counts summed as bytes
    at = (moved[:, 1] - y0) * width + (moved[:, 0] - x0)

    def counted(shifts: NDArray[np.int64]) -> NDArray[np.int64]:
        offsets = shifts[:, 0] * width + shifts[:, 1]
        counts = np.zeros(offsets.size, dtype=np.int64)
        for start in range(0, at.size, _SHIFT_CHUNK):
            hits = flat.take(at[start : start + _SHIFT_CHUNK, None] + offsets[None, :])
            counts += np.add.reduce(hits, axis=0, dtype=np.uint8)
        return counts

    # every other shift first (a cell agrees within ``threshold``, so a part's peak is
    # several shifts wide), then the shifts around the best of them
    steps = np.arange(-MAX_SHIFT, MAX_SHIFT + 1, 2)
    coarse = np.stack(np.meshgrid(steps, steps, indexing="ij"), axis=-1).reshape(-1, 2)
    around = coarse[int(np.argmax(counted(coarse)))]  # (dy, dx); the first of ties
    near = np.arange(-1, 2)
    fine = np.stack(np.meshgrid(near, near, indexing="ij"), axis=-1).reshape(-1, 2) + around
    fine = fine[(np.abs(fine) <= MAX_SHIFT).all(axis=1)]
    fine = np.vstack([fine, np.zeros((1, 2), np.int64)])  # and no shift, last
    counts = counted(fine)
    best = int(np.argmax(counts))
    dy, dx = (int(v) for v in fine[best])
    # more cells than no shift, by more than chance could add (the stopping rule's z and
    # chance agreement, over the cells counted), and farther than the refinement reaches
    p0 = index.chance_agreement(threshold)
    margin = significance * np.sqrt(at.size * p0 * (1.0 - p0))
    if counts[best] - counts[-1] <= margin or np.hypot(dx, dy) <= reach:
        return None
    return RigidTransform(0.0, float(dx), float(dy)).compose(transform)
