"""Recovery: partitions that the greedy recursion lost, found again among incoherent cells.

The recursion takes the largest part first, and every partition it finds also takes the
cells of parts not yet found that land within ``threshold`` of a reference wall under its
transform by coincidence. In a building of similar rooms and long straight walls that share
is large (10-15 % of a part's cells per wrong transform in MIT building 31), so a small
partition can lose most of its cells to the four or five partitions found before it; what
is left of it then falls below the smallest partition, or is too little to be registered,
and the recursion ends one partition short.

Once all the transforms are known, such cells are easy to tell apart: a partition is a
contiguous stretch of the robot's run, so around a cell that truly belongs to its partition
most occupied cells agree with the reference under that partition's transform too, while a
cell taken by coincidence lies among cells that do not. :func:`recover` therefore, after
the recursion:

1. gives every cell to the partition that aligns it best
   (:func:`~brokenness.measure.partitions.reassign`);
2. measures each cell's *support* (:func:`agreement_support`): the share of the occupied
   cells in the ``(2 r + 1)``-cell square around it (``r =`` :data:`SUPPORT_RADIUS`) that
   agree under its partition's transform. Cells of no partition, and cells with a support
   below :data:`SUPPORT_SHARE`, are *suspects* (a partition's own cells have a support near
   1, about 0.5 on its border);
3. registers the suspects with the whole reference -- first only those in regions of
   suspects (at least :data:`DENSE_SHARE` of the cells around them are suspects: a lost
   partition is a region of them, the borders of the partitions found are lines of them),
   then, if that finds nothing and the two differ, all of them; then, if that finds nothing
   either, each group of suspects that could hold a partition, and the region around it
   with all its cells (:func:`suspect_regions`: a small part that the partitions found
   before it took most of leaves half of the suspects or less, mixed with the borders of
   other parts, and its hypothesis is among neither set's, but the region around its
   suspects holds its taken cells too; neither a group of nearly all the suspects nor a
   region of nearly all the map, registered already, is registered again) -- and keeps
   the best hypothesis that is not a partition already found. If none of those searches
   finds a partition, the regions of suspects are *placed* instead of registered
   (:meth:`_Search.placed`): at the rotations that turn their walls onto the reference's
   (the peaks of their Hough spectra's correlation,
   :mod:`~brokenness.registration.orientation`), every translation counted
   (:mod:`~brokenness.measure.placement`). The registration takes its rotation from the
   whole spectrum of what it registers, and a few cells of a small part mixed with the
   borders of parts turned by other bumps have the wrong strongest directions; their walls,
   counted one by one, still point the part's way. Last, the region around each group of
   them is placed with all its cells (:func:`_regions_around`): a small part that the
   partitions found before it took most of can leave fewer suspects than a partition holds
   (sim d7 s25 of the realistic benchmark: 147 of its 626 cells), too few to count a
   placement on, while the region around them holds its taken cells too, and at the part's
   rotation its place explains them. Most of a region's cells are other partitions', so what
   a placement explains of them is no evidence of its own: its best placement goes straight
   to step 5's count of the cells it would take;
4. counts it as a new partition if the suspects it explains *coherently* (they agree under
   it, and so do at least :data:`SUPPORT_SHARE` of the cells around them: coincidences are
   scattered) pass the recursion's stopping rule on the suspects (``k >= n p0 + z sigma``
   and the smallest partition), it is not explained by a partition already found
   (:func:`~brokenness.measure.partitions.merge_target`), and it keeps at least the
   smallest partition's cells when every cell goes to its best partition again (if that
   leaves another partition too few cells of its own, that one is dropped, and the new one
   is kept only if the partitions then explain more cells: a part found at its place
   replaces its twin, :func:`_kept`);
5. if no hypothesis passes step 4's count (or, for the regions placed last, is counted
   on it), counts the best hypotheses of step 3 again over the whole map
   (:func:`_taken_partition`): the cells a new partition of the hypothesis would
   *take* (:func:`taken_cells`: they agree coherently under it, and belong to no partition
   or have more cells of their neighbourhood agreeing under it than under their
   partition's transform) must pass the stopping rule over all the map's cells, with
   chance what the rival hypotheses would take (upper quartile), and the same tests of
   merging and of keeping enough cells. A part shifted along a corridor against a partition
   found before it shares its walls along the shift with that partition, so few of its
   cells are suspects; its own region is what its true transform takes. Such a partition
   must also make the map's free space cross the reference's walls significantly less often
   (:func:`_clears_free_space`): coincidences do not;
6. repeats until nothing new is found (or ``max_partitions`` is reached).

A best hypothesis that fails only the count of step 4 is returned as a *rival*: when a
partition sits at a wrong place that fits its own cells (a twin of its room), the cells of
its part that the wrong place leaves are suspects, too few for a new partition, and their
hypothesis is the part's true transform; :func:`~brokenness.measure.settle.settle` offers it
to every partition as a replacement. In the first round (``relocate``) the own cells of each
partition whose free space does not show that it is in place
(:meth:`~brokenness.measure.evidence.Contradiction.doubtful`) are also registered alone, and
the best hypothesis that puts them elsewhere than every partition does is a rival too:
registered alone, a part's cells give their true place among their hypotheses, though the
place it was found at fits them too. Those cells are also placed at every translation, at
the hypotheses' rotations, and the placement that explains them about as well and whose
free space crosses the reference's walls least is a rival too
(:mod:`~brokenness.measure.placement`): the true place of a part held at a twin is often
not among the registration's translation peaks. Each of these rivals is offered as found
and refitted on the partition's cells (:func:`~brokenness.measure.refine.refit_transform`,
the settle step's refit of its own candidates): a hypothesis of a few cells' residual error
makes fewer cells agree than the twin it should replace, and the settle step judges a
rival as it is given. Of the partitions settled, those whose free space does not show that
they are in place are registered alone again, with their neighbourhood, and each of them
together with every partition that touches it in the map: the recursion can split a small
part into two pieces, each at a twin, and only their union carries enough of the part to
give its place. The cells of every other partition are registered alone too (a twin of a
room can show its free space in place as well as the room does). After the settle step,
the recovery runs again while it finds new partitions (the recursion's
``RECOVERY_ROUNDS``), if the tests after it changed the partitions: settled transforms
leave clearer suspects.

On the 160 simulated maps of degrees 2-5 of ``benchmarks/accuracy.py``, the recovery (with
:func:`~brokenness.measure.partitions.consolidate`) gives the exact degree in 145 maps
instead of 136, and on the 3 x 2 benchmark map of building 31 it finds the sixth partition
at every angle tried (10-25 degrees), where the recursion alone finds five.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from .._points import point_norms, take_rows
from ..masking import ReferenceIndex
from ..registration.base import Candidate, Registrar
from ..registration.orientation import hough_spectrum, rotation_candidates
from ..transform import RigidTransform
from .context import MapContext
from .evidence import Contradiction, FreeSpace, contradiction, free_space
from .hypotheses import RIVAL_QUANTILE, best_hypothesis, rival_chance, rivals
from .options import Settings
from .partitions import Found, merge_target, owners, reassign, with_fringe
from .placement import free_placement, placements
from .pool import counts, distinct_indices, recorded_transforms
from .refine import refit_transform
from .support import (
    SUPPORT_RADIUS,
    SUPPORT_SHARE,
    box_counts,
    in_box,
    occupied_around,
    window_box,
    window_counts,
)
from .views import candidates_of, exhausted, moving_remainder, occupied_count

__all__ = [
    "DENSE_SHARE",
    "NEIGHBOURHOOD_RADIUS",
    "REGION_REACH",
    "SUPPORT_RADIUS",
    "SUPPORT_SHARE",
    "agreement_support",
    "drop_incoherent",
    "neighbourhood_counts",
    "occupied_around",
    "recover",
    "relocation_rivals",
    "suspect_regions",
    "taken_cells",
]

#: Suspects with at least this share of suspects around them form the regions searched first.
DENSE_SHARE = 0.3
#: The neighbourhood of a settled partition registered alone for a rival
#: (:func:`relocation_rivals`): the occupied cells within this many cells of its own, half
#: the window of the support (0.3 m at 5 cm cells; see the README for how it was chosen).
NEIGHBOURHOOD_RADIUS = SUPPORT_RADIUS // 2
#: ... and all suspects are searched next, unless the regions hold this share of them already.
_SAME_SET = 0.8
#: Peaks of the Hough spectra's correlation whose rotations (each both ways round) the suspects
#: are placed at, in the last search for a lost partition: a building's walls run in a few
#: directions (two, 90 degrees apart, in most), so a part's rotation gives two peaks, and
#: four peaks hold it beside one other family of directions (on the three held-out maps
#: traced, the part's rotation was the first or second peak, within 0.6 degrees).
ROTATION_PEAKS = 4
#: Candidates (the best by plain agreement) whose coherent agreement is counted per search.
_COHERENT_RANKED = 4
#: Of those, the best (by coherent agreement) refined on the cells.
_REFINED = 2


def agreement_support(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    shape: tuple[int, int],
    radius: int = SUPPORT_RADIUS,
) -> NDArray[np.float64]:
    """Per occupied cell, the share of the occupied cells around it that agree with the
    reference under its partition's transform.

    Parameters
    ----------
    found : list of Found
        The partitions (members index ``points``).
    points : ndarray, shape (N, 2)
        The map's occupied cells, ``(x, y)``.
    index : ReferenceIndex
        The reference.
    threshold : float
        Agreement threshold (Manhattan distance in cells).
    shape : (int, int)
        Shape of the map grid.
    radius : int
        Half-width of the square window, in cells.

    Returns
    -------
    ndarray of float64
        In [0, 1]; 0 for cells of no partition.
    """
    around = occupied_around(points, shape, radius)
    return _support(found, points, index, threshold, shape, radius, around)


def drop_incoherent(found: list[Found], context: MapContext) -> list[Found]:
    """The partitions that are coherent regions of the map, cells reassigned.

    A partition must hold at least ``context.settings.min_cells`` cells with a support of at least
    :data:`SUPPORT_SHARE` (:func:`agreement_support`): the test a partition found by the
    recovery passes, applied to every partition. A set of scattered cells that one transform
    happens to put on reference walls (common where walls are long and straight) has little
    support; it is not a part of the map that is "off", and its cells go to the partitions
    that align them best. The least coherent partition is dropped first, one at a time.
    """
    points, index, around = context.points, context.index, context.around
    threshold, min_cells = context.settings.threshold, context.settings.min_cells
    while len(found) > 1:
        support = _support(found, points, index, threshold, context.shape, SUPPORT_RADIUS, around)
        coherent = [int(np.count_nonzero(support[f.members] >= SUPPORT_SHARE)) for f in found]
        worst = min(range(len(found)), key=lambda j: (coherent[j], j))
        if coherent[worst] >= min_cells:
            break
        kept = [f for j, f in enumerate(found) if j != worst]
        found = reassign(kept, points, index, threshold, min_cells) if len(kept) > 1 else kept
    return found


def _support(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    shape: tuple[int, int],
    radius: int,
    around: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`agreement_support`, with ``around`` (occupied cells around each) given."""
    support = np.zeros(points.shape[0])
    for f in found:
        if f.members.size == 0:
            continue
        at = np.zeros(points.shape[0], dtype=bool)
        at[f.members] = True
        support[at], _ = _share(f.transform, points, at, index, threshold, shape, radius, around)
    return support


def _share(
    transform: RigidTransform,
    points: NDArray[np.float64],
    at: NDArray[np.bool_],
    index: ReferenceIndex,
    threshold: float,
    shape: tuple[int, int],
    radius: int,
    around: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """At the cells ``at``, the share of the occupied cells around that agree under
    ``transform`` (``around``: how many occupied cells there are around each cell), and the
    cells (indices of ``points``, ascending) that agree under ``transform`` in the box of the
    windows around the cells ``at`` (``at`` among them)."""
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    ar, ac = rows[at], cols[at]
    box = window_box(ar, ac, shape, radius)
    near = np.flatnonzero(in_box(rows, cols, box))  # only those can count
    near = near[index.occupied_agreement(transform.apply(take_rows(points, near)), threshold)]
    counts = box_counts(rows.take(near), cols.take(near), ar, ac, box, radius)
    return counts / around[at], near


#: Side of the blocks in which :func:`taken_cells` counts a neighbourhood's agreeing cells,
#: and the side of the neighbourhood in blocks: 25 x 25 cells, the coherence window
#: (``2 SUPPORT_RADIUS + 1``), counted on blocks so that the cost follows the cells.
BLOCK = 5
NEIGHBOURHOOD_BLOCKS = 5


def neighbourhood_counts(
    agree: NDArray[np.bool_], points: NDArray[np.float64]
) -> NDArray[np.int64]:
    """Per cell of ``points``, how many ``agree`` cells lie in its neighbourhood (the
    :data:`NEIGHBOURHOOD_BLOCKS` x :data:`NEIGHBOURHOOD_BLOCKS` blocks of :data:`BLOCK`
    cells around its block)."""
    cols = points[:, 0].astype(np.intp) // BLOCK
    rows = points[:, 1].astype(np.intp) // BLOCK
    if not agree.any():
        return np.zeros(points.shape[0], dtype=np.int64)
    reach = NEIGHBOURHOOD_BLOCKS // 2
    r0, c0 = int(rows.min()), int(cols.min())
    shape = (int(rows.max()) - r0 + 1, int(cols.max()) - c0 + 1)
    flat = (rows - r0) * shape[1] + (cols - c0)
    counts = np.bincount(flat[agree], minlength=shape[0] * shape[1]).reshape(shape)
    summed = cv2.boxFilter(
        counts.astype(np.float64),  # exact: integer counts far below 2^53
        cv2.CV_64F,
        (2 * reach + 1, 2 * reach + 1),
        normalize=False,
        borderType=cv2.BORDER_CONSTANT,
    )
    return np.rint(summed.reshape(-1).take(flat)).astype(np.int64)  # flat: each cell's block


#: Suspects within twice this many cells of each other form one group, and a group's region
#: holds the occupied cells within this many cells of its suspects: the width of the support
#: window (``2 SUPPORT_RADIUS``), counted on blocks of :data:`BLOCK` cells (see
#: :func:`suspect_regions`).
REGION_REACH = 2 * SUPPORT_RADIUS


def suspect_regions(
    points: NDArray[np.float64], suspect: NDArray[np.bool_], min_cells: int
) -> list[NDArray[np.bool_]]:
    """The regions of the map around groups of suspects, largest group first.

    On blocks of :data:`BLOCK` cells, the blocks that hold a suspect are grown by
    :data:`REGION_REACH` cells (rounded up to whole blocks); each 8-connected piece of what
    they cover is a region, and the suspects in it a group. Every group of at least
    ``min_cells`` suspects gives its region: all the occupied cells in it, not only the
    suspects (the cells of a lost part that other partitions took by coincidence are not
    suspects, but they tell its transform). The cost follows the cells and the pooled grid.

    Returns
    -------
    list of ndarray of bool
        One mask over ``points`` per region, in order of decreasing suspects (then of the
        region's first block, row-major: deterministic).
    """
    if np.count_nonzero(suspect) < min_cells:
        return []
    region, held, _ = _regions(points, suspect)
    return [region == g for g in range(1, held.size) if held[g] >= min_cells]


def _regions(
    points: NDArray[np.float64], cells: NDArray[np.bool_]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """The regions around ``cells`` (a mask over ``points``, at least one set): per point,
    its region (0 for none; the blocks of :data:`BLOCK` cells that hold one of ``cells``,
    grown by :data:`REGION_REACH` cells, 8-connected), numbered in order of decreasing
    ``cells`` held (then of the first block, row-major); and per region, the ``cells`` it
    holds and all the points it holds (index 0: outside every region, none held)."""
    reach = -(-REGION_REACH // BLOCK)
    cols = points[:, 0].astype(np.intp) // BLOCK
    rows = points[:, 1].astype(np.intp) // BLOCK
    r0, c0 = int(rows.min()) - reach, int(cols.min()) - reach
    rows, cols = rows - r0, cols - c0
    shape = (int(rows.max()) + reach + 1, int(cols.max()) + reach + 1)
    held = np.zeros(shape, np.uint8)
    held[rows[cells], cols[cells]] = 1
    grown = cv2.dilate(held, np.ones((2 * reach + 1, 2 * reach + 1), np.uint8))
    count, piece = cv2.connectedComponents(grown, connectivity=8)
    of_cell = piece[rows, cols]
    inside = np.bincount(of_cell[cells], minlength=count)
    inside[0] = 0  # outside every region
    order = np.array([0, *sorted(range(1, count), key=lambda g: (-inside[g], g))], np.intp)
    renumber = np.empty(count, np.intp)
    renumber[order] = np.arange(count)
    region = renumber[of_cell]
    size = np.bincount(region, minlength=count)
    size[0] = 0
    return region, inside[order], size


class _SearchStep(NamedTuple):
    """One search for a lost partition (step 3 of the module docstring)."""

    cells: NDArray[np.bool_]  # the cells its hypotheses are counted on (a mask)
    sources: list[NDArray[np.bool_]]  # the cells registered (none: ``cells``)
    placed: bool  # placed at the rotations of their walls instead of registered
    counted: bool = True  # counted on ``cells``; if not, only over the whole map (step 5)


def _searches(
    points: NDArray[np.float64],
    dense: NDArray[np.bool_],
    suspect: NDArray[np.bool_],
    min_cells: int,
) -> Iterator[_SearchStep]:
    """The searches for a lost partition, in turn (step 3 of the module docstring). First the
    regions of suspects (``dense``: a lost partition is a region of them; the borders of the
    partitions found are lines of them), then every suspect unless the regions hold
    :data:`_SAME_SET` of them, then the groups of suspects and the regions around them
    (:func:`_groups`, made only if the searches before found nothing), then the regions of
    suspects placed at the rotations of their walls, and last the region around each group
    of them placed with all its cells, its best placement counted only by the cells it would
    take over the whole map (step 5; a region's cells are mostly other partitions', and what
    a placement explains of those is no evidence of its own)."""
    yield _SearchStep(dense, [], placed=False)
    if np.count_nonzero(dense) < _SAME_SET * np.count_nonzero(suspect):
        yield _SearchStep(suspect, [], placed=False)
    groups = _groups(points, suspect, min_cells)
    if groups:
        yield _SearchStep(suspect, groups, placed=False)
    yield _SearchStep(dense, [], placed=True)
    for region in _regions_around(points, dense, min_cells):
        if np.count_nonzero(region) < _SAME_SET * points.shape[0]:  # else: registered whole
            yield _SearchStep(region, [], placed=True, counted=False)


def _regions_around(
    points: NDArray[np.float64], cells: NDArray[np.bool_], min_cells: int
) -> list[NDArray[np.bool_]]:
    """The regions around groups of ``cells`` (:func:`_regions`) that hold at least
    ``min_cells`` occupied cells, however few of ``cells`` (every region holds one), in
    order of decreasing ``cells`` held."""
    if not cells.any():
        return []
    region, _, size = _regions(points, cells)
    return [region == g for g in range(1, size.size) if size[g] >= min_cells]


def _groups(
    points: NDArray[np.float64], suspect: NDArray[np.bool_], min_cells: int
) -> list[NDArray[np.bool_]]:
    """The cells registered for a lost partition after the suspects: per region of
    :func:`suspect_regions`, its suspects and all its cells, but not a group that holds
    :data:`_SAME_SET` of the suspects (they were registered) nor a region that holds that
    share of the map (the recursion registered it)."""
    n_suspects, n = np.count_nonzero(suspect), points.shape[0]
    groups = []
    for region in suspect_regions(points, suspect, min_cells):
        mine = suspect & region
        if np.count_nonzero(mine) < _SAME_SET * n_suspects:
            groups.append(mine)
        if np.count_nonzero(region) < _SAME_SET * n:
            groups.append(region)
    return groups


def _owner_counts(
    found: list[Found],
    owner: NDArray[np.intp],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
) -> NDArray[np.int64]:
    """Per cell, the :func:`neighbourhood_counts` of its partition's transform (0 for cells
    of no partition)."""
    out = np.zeros(points.shape[0], dtype=np.int64)
    for j, f in enumerate(found):
        mine = owner == j
        if mine.any():
            agree = index.occupied_agreement(f.transform.apply(points), threshold)
            out[mine] = neighbourhood_counts(agree, points)[mine]
    return out


def taken_cells(
    transform: RigidTransform,
    owner: NDArray[np.intp],
    owner_count: NDArray[np.int64],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    around: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """The cells a new partition of ``transform`` would take: they agree under it, coherently
    (at least :data:`SUPPORT_SHARE` of the occupied cells in the window around them agree
    too), and either belong to no partition or have more cells of their neighbourhood agree
    under ``transform`` than under their partition's (``owner_count``)."""
    agree = index.occupied_agreement(transform.apply(points), threshold)
    if not agree.any():
        return agree
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    shape = (int(rows.max()) + 1, int(cols.max()) + 1)
    coherent = agree.copy()
    coherent[agree] = (
        window_counts(rows, cols, agree, agree, shape, SUPPORT_RADIUS)
        >= SUPPORT_SHARE * around[agree]
    )
    better = (owner < 0) | (neighbourhood_counts(agree, points) > owner_count)
    return coherent & better


def _new_ones(
    candidates: list[Candidate], found: list[Found], pts: NDArray[np.float64], tolerance: float
) -> list[Candidate]:
    """The candidates that put ``pts`` (on average) more than ``tolerance`` cells away from
    where every partition's transform puts them: the others are partitions already found,
    whose border cells are among the suspects."""
    if not candidates or not found:
        return candidates
    far = _far_from([c.transform for c in candidates], found, pts, tolerance)
    return [c for c, keep in zip(candidates, far, strict=True) if keep]


def _far_from(
    transforms: Sequence[RigidTransform],
    found: list[Found],
    pts: NDArray[np.float64],
    tolerance: float,
) -> NDArray[np.bool_]:
    """Per transform, whether it puts ``pts`` (on average, over an even sample of about 200
    of them) more than ``tolerance`` cells away from where every partition's transform
    puts them (:func:`_new_ones`)."""
    if not transforms or not found:
        return np.ones(len(transforms), dtype=bool)
    picked = pts[:: max(1, pts.shape[0] // 200)]
    sample = np.column_stack([picked, np.ones(picked.shape[0])])

    def moved(ts: Sequence[RigidTransform]) -> NDArray[np.float64]:
        return np.stack([t.matrix[:2] for t in ts]) @ sample.T  # (T, 2, M)

    a = moved(transforms)
    b = moved([f.transform for f in found])
    apart = point_norms(np.moveaxis(a[:, None] - b[None], 2, -1)).mean(axis=2)  # (T, F)
    return (apart > tolerance).all(axis=1)


def recover(
    found: list[Found],
    context: MapContext,
    registrar: Registrar,
    reference: Any,
    relocate: bool = False,
) -> tuple[list[Found], list[RigidTransform]]:
    """The partitions of the recursion, reassigned, plus those found again among suspects.

    See the module docstring for the steps and the tests a new partition must pass.

    Parameters
    ----------
    found : list of Found
        The recursion's partitions (members index ``context.points``).
    context : MapContext
        The map and the reference (:class:`~brokenness.measure.context.MapContext`); each
        round asks for twice its settings' ``max_candidates`` hypotheses.
    registrar : Registrar
        The registration (the recursion's wider search), and ``reference`` its prepared whole
        reference.
    relocate : bool, optional
        Also register the own cells of each partition whose free space does not show that
        it is in place (:meth:`~brokenness.measure.evidence.Contradiction.doubtful`) alone,
        once the new partitions are found, and return the best hypothesis that puts them
        elsewhere than every partition does as a rival (a part at a twin of its room: its
        own cells give its true place among their hypotheses).

    Returns
    -------
    found : list of Found
        Every cell given to the partition that aligns it best
        (:func:`~brokenness.measure.partitions.reassign`).
    rivals : list of RigidTransform
        The best hypotheses of the suspects that were too few cells for a new partition
        (step 4's count): where a partition sits at a wrong place that fits its cells
        about as well (a symmetric twin of a room), its true place leaves a few of its cells
        unexplained, and its true transform is found from them; :func:`~brokenness.measure.
        settle.settle` offers these to every partition as replacements.
    """
    points, index, settings, around = (
        context.points,
        context.index,
        context.settings,
        context.around,
    )
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    threshold, min_cells = settings.threshold, settings.min_cells
    search = _Search.of(context, registrar, reference)
    found = reassign(found, points, index, threshold, min_cells)
    rivals: list[RigidTransform] = []
    while found and len(found) < settings.max_partitions and not exhausted(registrar):
        t0 = time.perf_counter()
        support = _support(found, points, index, threshold, context.shape, SUPPORT_RADIUS, around)
        suspect = support < SUPPORT_SHARE
        if np.count_nonzero(suspect) < min_cells:
            break
        dense = suspect.copy()
        dense[suspect] = (
            window_counts(rows, cols, suspect, suspect, context.shape, SUPPORT_RADIUS)
            >= DENSE_SHARE * around[suspect]
        )
        new = None
        short: list[_Shortfall] = []
        for step in _searches(points, dense, suspect, min_cells):
            new, shortfall = search.lost_partition(found, step)
            if shortfall is not None:
                short.append(shortfall)
            if new is not None:
                break
        rivals += [shortfall.transform for shortfall in short if shortfall.rival]
        if new is None:  # counted over the whole map instead
            grown = _taken_over_map(context, found, short)
            if grown is None:
                break
            found = grown
            continue
        new = Found(new.transform, new.members, new.confidence, time.perf_counter() - t0)
        grown = reassign([*found, new], points, index, threshold, min_cells)
        if not _kept(found, grown, new):
            break  # it kept too few cells once every cell went to its best partition
        found = grown
    if relocate and len(found) > 1:
        owned = free_space(found, points, context.clear, index)
        evidence = contradiction(found, points, context.clear, index, owned)
        doubtful = evidence.doubtful(settings.significance)
        rivals += _relocations(search, found, None, doubtful, owned, place_every=False)
    return found, rivals


class _Taking:
    """What a new partition would take from the partitions ``found`` (:func:`taken_cells`),
    each transform's count made once."""

    def __init__(self, context: MapContext, found: list[Found]) -> None:
        self.context = context
        points, threshold = context.points, context.settings.threshold
        self.owner = owners(found, points.shape[0])
        self.owner_count = _owner_counts(found, self.owner, points, context.index, threshold)
        self._counts: dict[RigidTransform, int] = {}

    def cells(self, transform: RigidTransform) -> NDArray[np.bool_]:
        """The cells a new partition of ``transform`` would take."""
        context = self.context
        return taken_cells(
            transform,
            self.owner,
            self.owner_count,
            context.points,
            context.index,
            context.settings.threshold,
            context.around,
        )

    def count(self, transform: RigidTransform) -> int:
        """How many cells a new partition of ``transform`` would take."""
        if transform not in self._counts:
            self._counts[transform] = int(np.count_nonzero(self.cells(transform)))
        return self._counts[transform]

    def takeable(self) -> NDArray[np.bool_]:
        """The cells some transform could take: of no partition, or with fewer cells of
        their neighbourhood agreeing under their partition's transform than it holds (a
        cell is taken only where more agree under the new one)."""
        everywhere = neighbourhood_counts(np.ones_like(self.owner, bool), self.context.points)
        return (self.owner < 0) | (self.owner_count < everywhere)


def _taken_partition(
    context: MapContext, found: list[Found], shortfall: _Shortfall, taking: _Taking
) -> Found | None:
    """The partition of the cells the shortfall's transform would *take* from ``found``
    (``taking``'s :func:`taken_cells`), if they pass the stopping rule against what the
    other hypotheses of the shortfall would take.

    A part shifted along a corridor against a partition already found (a pure-shift
    bump) shares its walls parallel to the shift with that partition: they agree under
    both transforms and stay with the partition, so few of the part's cells are
    suspects, and their count fails although the hypothesis is the part's true
    transform. Counted over the whole map instead, the part's own region is what the
    hypothesis takes: there the cells around agree under it more than under their
    partition's transform. Chance is what the rival hypotheses of the same suspects
    (those that put them elsewhere) would take, at the upper quartile
    (:data:`~brokenness.measure.hypotheses.RIVAL_QUANTILE`), over all the map's cells.
    """
    settings, pts, index = context.settings, context.points, context.index
    p0 = index.chance_agreement(settings.threshold)
    transform, candidates = shortfall.transform, shortfall.candidates
    loose = settings.loose
    taken = taking.cells(transform)
    k = int(np.count_nonzero(taken))
    if k < settings.min_cells:
        return None
    n = pts.shape[0]
    shares = [
        taking.count(c.transform) / n
        for c, _ in rivals(candidates, pts[:: max(1, n // 200)], transform, loose)
    ]
    p_take = float(np.quantile(shares, RIVAL_QUANTILE)) if shares else p0
    chance, _, needed = settings.needed(n, min(p_take, p0))
    if k < needed:
        return None
    left = np.flatnonzero(taken)
    members = left[
        with_fringe(transform, take_rows(pts, left), np.ones(left.size, bool), index, loose)
    ]
    if merge_target(found, take_rows(pts, members), index, loose) is not None:
        return None
    return Found(transform, members, (k - chance) / k, 0.0)


def _taken_over_map(
    context: MapContext,
    found: list[Found],
    shortfalls: Sequence[_Shortfall],
    taking: _Taking | None = None,
    own_evidence: bool = False,
) -> list[Found] | None:
    """``found`` grown by the partition of the first of ``shortfalls`` that passes step 5
    (:func:`_taken_partition`, then :func:`_kept` and :func:`_clears_free_space`; with
    ``own_evidence``, its own free space must also cross the reference's walls significantly
    less often than chance), every cell given to its best partition; ``None`` if none
    passes. ``taking`` is what a new partition would take from ``found``, if made."""
    if not shortfalls:
        return None
    points, index, settings = context.points, context.index, context.settings
    taking = _Taking(context, found) if taking is None else taking
    before = None
    for shortfall in shortfalls:
        taken = _taken_partition(context, found, shortfall, taking)
        if taken is None:
            continue
        grown = reassign([*found, taken], points, index, settings.threshold, settings.min_cells)
        if not _kept(found, grown, taken):
            continue
        if before is None:
            before = contradiction(found, points, context.clear, index)
        after = contradiction(grown, points, context.clear, index)
        if not _clears_free_space(before, after, settings.significance):
            continue
        # the new partition is the last (``reassign`` keeps the order; ``_kept`` kept it)
        if own_evidence and not after.upper_ratio(settings.significance, len(grown) - 1) < 1.0:
            continue
        return grown
    return None


def pooled_partitions(
    found: list[Found], context: MapContext, pool: Sequence[Sequence[Candidate]]
) -> list[Found]:
    """``found`` grown by the partitions that the call's hypotheses hold (``pool``, one group
    a registration, :class:`~brokenness.measure.pool.Recorded`): step 5's count over the
    whole map (:func:`_taken_over_map`), each hypothesis with the other hypotheses of its
    registration as the rivals of its chance, as the recovery counts its searches' best.

    A part shifted a few cells along its neighbour's walls (a pure-shift bump), or whose
    cells the partitions found before it split among them, leaves few suspects, too few to
    register; its true transform is often among the hypotheses of an earlier registration
    of cells that were not yet its own. Since many hypotheses are tried here, and the best
    kept, each test is made at the significance of all the call's distinct hypotheses at
    once (:meth:`~brokenness.measure.options.Settings.for_tests`), and a partition is added
    only if its own free space crosses the reference's walls significantly less often than
    chance (at that significance: a placement of cells that fit by coincidence puts their
    free space on walls about as often as chance).

    The hypotheses tried in a round are the ``max_candidates`` that would take the most
    cells (:func:`taken_cells`), of the ``4 max_candidates`` that make the most of an even
    sample of the cells they could take agree (:func:`_pooled_shortfalls`).
    """
    settings = context.settings
    hypotheses = _Hypotheses.of(pool, context.points)
    context = replace(context, settings=settings.for_tests(len(hypotheses.distinct)))
    while found and len(found) < settings.max_partitions:
        taking = _Taking(context, found)
        shortfalls = _pooled_shortfalls(taking, hypotheses, found)
        grown = _taken_over_map(context, found, shortfalls, taking, own_evidence=True)
        if grown is None:
            break
        found = grown
    return found


#: Cells that a new partition could take looked up at most (an even sample of them), to
#: rank the call's hypotheses before their cells taken are counted: enough that a part's
#: true transform, which makes hundreds of its part's cells agree, stands out of chance.
_PROBE_TAKEABLE = 4096
#: The hypotheses ranked first on that sample whose cells taken are counted, as a multiple
#: of the ``max_candidates`` tried (the count is a millisecond each on the largest maps).
_COUNTED_PER_TRIED = 4


class _Hypotheses(NamedTuple):
    """The call's hypotheses as :func:`pooled_partitions` reads them, made once a call."""

    transforms: list[RigidTransform]  # every hypothesis, in the pool's order
    groups: list[tuple[Candidate, ...]]  # each one's registration (its rivals)
    distinct: list[int]  # the first of each group of the same placement (pool.distinct_indices)

    @classmethod
    def of(cls, pool: Sequence[Sequence[Candidate]], points: NDArray[np.float64]) -> _Hypotheses:
        transforms = recorded_transforms(pool)
        groups = [g for g in map(tuple, pool) for _ in g]  # one tuple a registration
        return cls(transforms, groups, distinct_indices(transforms, points.mean(axis=0)))


def _pooled_shortfalls(
    taking: _Taking, hypotheses: _Hypotheses, found: list[Found]
) -> list[_Shortfall]:
    """The distinct hypotheses of the call to try as new partitions (:func:`pooled_partitions`),
    the most cells taken first (ties in the pool's order), each with its registration's
    group as its rivals. A hypothesis that puts the map where a partition does is that
    partition (:func:`_new_ones`); the others are ranked by how many of an even sample of
    the cells some hypothesis could take (:meth:`_Taking.takeable`) they make agree, and of
    the first ``_COUNTED_PER_TRIED max_candidates``, the ``max_candidates`` that take the
    most cells, at least the smallest partition's, are returned."""
    context = taking.context
    points, index, settings = context.points, context.index, context.settings
    takeable = taking.takeable()
    if np.count_nonzero(takeable) < settings.min_cells:
        return []
    flat = hypotheses.transforms
    distinct = hypotheses.distinct
    far = _far_from([flat[k] for k in distinct], found, points, settings.loose)
    fresh = [k for k, keep in zip(distinct, far, strict=True) if keep]
    probe = points[takeable]
    probe = probe[:: max(1, -(-probe.shape[0] // _PROBE_TAKEABLE))]
    agreeing = counts([flat[k] for k in fresh], probe, index, settings.threshold)
    ranked = sorted(range(len(fresh)), key=lambda q: (-agreeing[q], q))
    cells = [
        (taking.count(flat[fresh[q]]), fresh[q])
        for q in ranked[: _COUNTED_PER_TRIED * settings.max_candidates]
    ]
    kept = sorted((-k, at) for k, at in cells if k >= settings.min_cells)
    return [
        _Shortfall(flat[at], hypotheses.groups[at]) for _, at in kept[: settings.max_candidates]
    ]


def _kept(found: list[Found], grown: list[Found], new: Found) -> bool:
    """Whether ``grown``, every cell of ``found`` and of the new partition ``new`` given to
    its best partition (:func:`~brokenness.measure.partitions.reassign`), keeps ``new``: it is
    one partition more, or ``new`` is in it and it assigns more cells than ``found`` did.

    The second is a replacement: a part held at a twin of its room, its true place found
    among the suspects, takes its cells from the twin (they agree better at the true place)
    and leaves the twin fewer than the smallest partition's cells, so the twin is dropped;
    the map then has as many partitions as before, more of its cells explained, and the
    part at its place. (Each replacement explains more cells, so replacements cannot cycle.)
    """
    if len(grown) > len(found):
        return True
    assigned = sum(f.members.size for f in found)
    return any(g.transform is new.transform for g in grown) and (
        sum(g.members.size for g in grown) > assigned
    )


def relocation_rivals(
    found: list[Found],
    context: MapContext,
    registrar: Registrar,
    reference: Any,
    which: Sequence[int] | None = None,
    free: FreeSpace | None = None,
) -> list[RigidTransform]:
    """Each partition's own cells, and its neighbourhood, registered alone: of each, the best
    hypothesis that puts them elsewhere than every partition's transform does (the rivals of
    ``recover``'s ``relocate``, for partitions already settled, or for those ``which``
    gives; the other arguments as for :func:`recover`).

    A part placed at a wrong place that fits its cells (the 180-degree twin of its stretch of
    corridor, a room like its own) holds, after the settle step, mostly its own cells, and
    registered alone they may give its true place among their hypotheses. Often they do not:
    the cells a twin explains are those that fit it, and the part's cells that tell its true
    place from the twin are the ones the wrong placement left to other partitions or to none.
    Those lie beside the partition's cells (a part is a contiguous stretch of the run), so its
    *neighbourhood* is registered too: the occupied cells within :data:`NEIGHBOURHOOD_RADIUS`
    of its cells. Given the map's free space ``free``
    (:func:`~brokenness.measure.evidence.free_space` of ``found``), its cells are also placed
    at every translation at the rotations of their hypotheses, and the placement that
    explains them about as well and whose free space crosses the reference's walls least is
    a rival too (:func:`~brokenness.measure.placement.free_placement`). The cells of every
    partition that ``which`` leaves out are registered alone too (no neighbourhood), and
    placed at the opposite of their own rotation only (the twin of a stretch of corridor or
    of a symmetric room is most often half a turn away): a partition whose free space
    passes on its own may still stand at a twin, a room like its own whose free space
    looks the same (session 41: a drawn atrium of degree 6, a part of 4.5 % held 144 cells
    off at the half-turned twin of its room, its free space at 0.46 of the chance rate, its
    own cells registered alone gave its place second among their hypotheses). A searched
    partition and one whose cells touch its own may be two pieces of one part,
    each at a twin: their union is registered too (:func:`_piece_rivals`). Each rival is given
    as found and refitted on the partition's cells
    (:func:`~brokenness.measure.refine.refit_transform`).
    :func:`~brokenness.measure.settle.settle` then judges every rival by the usual count, and
    by the free space.
    """
    search = _Search.of(context, registrar, reference)
    return _relocations(search, found, NEIGHBOURHOOD_RADIUS, which, free)


def _relocations(
    search: _Search,
    found: list[Found],
    radius: int | None = None,
    which: Sequence[int] | None = None,
    free: FreeSpace | None = None,
    place_every: bool = True,
) -> list[RigidTransform]:
    """:func:`relocation_rivals` with its search made, with the neighbourhood of ``radius``
    cells of each partition too, and the union of every searched partition with each
    partition that touches it within that radius (``None``: each partition's own cells
    alone), and, given the map's free
    space ``free`` (:func:`~brokenness.measure.evidence.free_space` of ``found``), the
    placement of each partition's cells that explains them about as well and whose free
    space crosses the reference's walls least
    (:func:`~brokenness.measure.placement.free_placement`): of the partitions ``which``
    gives, at their own rotation and those of their hypotheses; if ``place_every``, of the
    others too, at the opposite of their own rotation, with the best hypothesis of their own
    cells registered alone. None for a lone partition: its cells are what the first step
    registered."""
    if len(found) < 2:
        return []
    out: list[RigidTransform] = []
    settings, index = search.settings, search.index
    searched = set(range(len(found)) if which is None else which)
    for j in range(len(found)) if place_every else sorted(searched):
        members = found[j].members
        cells = take_rows(search.points, members)
        mine: list[RigidTransform | None] = []
        registered = j in searched and not exhausted(search.registrar)
        if registered:
            candidates = search.hypotheses(found, members)
            mine.append(search.best_of(candidates, members))
            angles = [found[j].transform.rotation, *(c.transform.rotation for c in candidates)]
        else:  # placed at the opposite of its own rotation only (a half-turn twin)
            angles = [found[j].transform.rotation + math.pi]
            if not exhausted(search.registrar):  # and its own cells registered alone
                mine.append(search.elsewhere(found, members))
        if free is not None and members.size >= settings.min_cells:
            mine.append(
                free_placement(
                    cells,
                    found[j].transform,
                    angles,
                    free.points(free.owner == j),
                    index,
                    search.context.coarse,
                    settings,
                )
            )
        if registered and radius is not None and not exhausted(search.registrar):
            mine.append(search.elsewhere(found, _neighbourhood(members, search, radius)))
        # each as found and refitted on the partition's cells, as the settle step refits its
        # own candidates (it judges a rival as it is given)
        out += _as_found_and_refitted(mine, cells, search)
    if radius is not None:
        out += _piece_rivals(search, found, sorted(searched), radius)
    return out


def _as_found_and_refitted(
    transforms: Sequence[RigidTransform | None], cells: NDArray[np.float64], search: _Search
) -> list[RigidTransform]:
    """Each of ``transforms`` (``None`` skipped) as found and refitted on ``cells``, as the
    settle step refits its own candidates (it judges a rival as it is given)."""
    settings, out = search.settings, []
    for t in transforms:
        if t is not None:
            refit = refit_transform(t, cells, search.index, settings.threshold, settings.loose)
            out += [t] if refit is t else [t, refit]  # (no refit: none of the cells agree)
    return out


def _piece_rivals(
    search: _Search, found: list[Found], searched: Sequence[int], radius: int
) -> list[RigidTransform]:
    """Rivals from two pieces of one part: of every partition ``searched`` and each other
    partition whose cells touch its own (one within ``radius`` cells of the other's), their
    union registered alone, its best hypothesis that puts the cells elsewhere than every
    partition does, as found and refitted on each of the two (the pairs of two searched
    partitions first, then those of a searched partition and one that is not).

    The greedy recursion can split a small part in two, each piece at a twin of its own
    stretch of the building, where the two fit their own cells; neither piece's cells, nor
    its neighbourhood, carry enough of the part to give its place registered alone. The
    part is one contiguous stretch of the run, so its pieces touch in the map, and their
    union gives the part's transform: offered to each, it explains the part's cells at one
    place, and the settle step judges it as every rival (the other piece, its cells then
    explained, is dropped as redundant). One of the two pieces may pass the free-space
    test on its own (the free space near a small piece is mostly other partitions'), so a
    searched partition is paired with every partition it touches.
    """
    out: list[RigidTransform] = []
    chosen = set(searched)
    others = [j for j in range(len(found)) if j not in chosen]
    pairs = [(i, j) for a, i in enumerate(searched) for j in searched[a + 1 :]]
    pairs += [(i, j) for i in searched for j in others]
    near: dict[int, NDArray[np.bool_]] = {}
    for i, j in pairs:
        if exhausted(search.registrar):
            return out
        if i not in near:
            near[i] = np.zeros(search.points.shape[0], dtype=bool)
            near[i][_neighbourhood(found[i].members, search, radius)] = True
        if not near[i][found[j].members].any():
            continue
        union = np.concatenate([found[i].members, found[j].members])
        union_place = search.elsewhere(found, union)
        for k in (i, j):
            out += _as_found_and_refitted(
                [union_place], take_rows(search.points, found[k].members), search
            )
    return out


def _neighbourhood(members: NDArray[np.intp], search: _Search, radius: int) -> NDArray[np.intp]:
    """The map's occupied cells within ``radius`` cells (a square window) of ``members``."""
    pts = search.context.points
    rows, cols = pts[:, 1].astype(np.intp), pts[:, 0].astype(np.intp)
    mine = np.zeros(pts.shape[0], dtype=bool)
    mine[members] = True
    everything = np.ones(pts.shape[0], dtype=bool)
    near = window_counts(rows, cols, mine, everything, search.context.shape, radius)
    return np.flatnonzero(near > 0)


def _clears_free_space(before: Contradiction, after: Contradiction, z: float) -> bool:
    """Whether the partitions of ``after`` (their
    :func:`~brokenness.measure.evidence.contradiction`: those found and, last, a partition
    taken over the whole map) make the map's free space cross the reference's walls
    significantly less often (``z`` standard deviations) than those found did (``before``).

    The test of a partition counted by the cells it takes (step 5 of the module docstring):
    the free space in front of the walls of a part that is truly off lands on reference walls
    at about the chance rate under the transform of the partition that held its walls, and
    rarely under its own, so the count of contradicting cells falls; a partition that took
    cells by coincidence moves their free space from one wrong placement to another. Only the
    free cells that change partition change the count: they are (nearly all) the new
    partition's, which contradict ``x_new`` times, and ``fall + x_new`` times before. The fall
    must exceed ``z`` standard deviations of the difference of those two Poisson counts,
    ``z sqrt(fall + 2 x_new)``.
    """
    fall = int(before.contradicting.sum()) - int(after.contradicting.sum())
    x_new = int(after.contradicting[-1])
    return fall > 0 and fall > z * math.sqrt(fall + 2 * x_new)


@dataclass(frozen=True)
class _Shortfall:
    """The best hypothesis of a search whose suspects were too few for a new partition, and
    the hypotheses it was chosen from (the rivals of its chance)."""

    transform: RigidTransform
    candidates: tuple[Candidate, ...]
    rival: bool = True  # offered to the settle step as a rival (not a placement's)


@dataclass(frozen=True)
class _Search:
    """What a search for a lost partition among suspect cells needs (fixed for a map):
    one registration of the suspects, and the tests its best hypothesis must pass."""

    context: MapContext
    registrar: Registrar
    reference: Any
    p0: float  # chance agreement of a random placement (bounds the rivals' chance)

    @classmethod
    def of(cls, context: MapContext, registrar: Registrar, reference: Any) -> _Search:
        """The search for a map (arguments as for :func:`recover`)."""
        p0 = context.index.chance_agreement(context.settings.threshold)
        return cls(context, registrar, reference, p0)

    @property
    def points(self) -> NDArray[np.float64]:
        return self.context.points

    @property
    def index(self) -> ReferenceIndex:
        return self.context.index

    @property
    def settings(self) -> Settings:
        return self.context.settings

    def lost_partition(
        self, found: list[Found], step: _SearchStep
    ) -> tuple[Found | None, _Shortfall | None]:
        """The partition that the cells of ``step`` hide, if its hypothesis passes every
        test; else ``None`` and, if the hypothesis failed only the count (too few of the
        cells agree coherently for a new partition) and the step is not placed, the
        hypothesis and its rivals (a rival for the settle step too).

        The hypotheses are those of the cells registered alone or, if the step has
        ``sources`` (masks over the map's cells), those of each source registered alone, or,
        if it is ``placed``, the placements of its cells (:meth:`placed`); they are counted
        on its cells either way. A step that is not ``counted`` returns its best hypothesis
        as a shortfall at once: it is counted over the whole map (:func:`_taken_partition`)."""
        cells, sources, placed = step.cells, step.sources, step.placed
        settings = self.settings
        n = int(np.count_nonzero(cells))
        if n < settings.min_cells or exhausted(self.registrar):
            return None, None  # too few cells, or the registration's budget is spent
        pts = self.points
        left = np.flatnonzero(cells)
        left_points = take_rows(pts, left)
        candidates: list[Candidate] = self.placed(found, left_points) if placed else []
        for source in () if placed else sources or (cells,):
            if exhausted(self.registrar):
                break  # no registration once the budget is spent
            candidates += self._new_hypotheses(found, cells, source)
        if not candidates:
            return None, None
        # the cells a hypothesis explains count only where the cells around agree under it
        # too (a partition is a contiguous region; coincidences are scattered); that is
        # counted for the best few candidates by plain agreement
        plain = [
            np.count_nonzero(
                self.index.occupied_agreement(c.transform.apply(left_points), settings.threshold)
            )
            for c in candidates
        ]
        ranked = sorted(range(len(candidates)), key=lambda q: (-plain[q], q))[:_COHERENT_RANKED]
        counts = {
            q: np.count_nonzero(self._coherent(candidates[q].transform, cells)) for q in ranked
        }
        ranked.sort(key=lambda q: (-counts[q], q))
        best = best_hypothesis(
            [candidates[q] for q in ranked[:_REFINED]], left_points, self.index, settings.threshold
        )
        if best is None:
            return None, None
        transform = best[0]
        if not step.counted:
            return None, _Shortfall(transform, tuple(candidates), rival=False)
        agree = self._coherent(transform, cells)
        k = int(np.count_nonzero(agree))
        # chance: what the other candidates make of the suspects (rival_chance)
        p_step = rival_chance(
            candidates,
            left_points,
            self.index,
            settings.threshold,
            transform,
            settings.loose,
            self.p0,
        )
        chance, _, needed = settings.needed(n, p_step)
        if k < needed:  # a placement is a last try, not a rival (see ``placed``)
            return None, None if placed else _Shortfall(transform, tuple(candidates))
        members = left[with_fringe(transform, left_points, agree, self.index, settings.loose)]
        if merge_target(found, take_rows(pts, members), self.index, settings.loose) is not None:
            return None, None  # an existing partition's transform, not a lost one
        return Found(transform, members, (k - chance) / k, 0.0), None

    def elsewhere(self, found: list[Found], members: NDArray[np.intp]) -> RigidTransform | None:
        """The best hypothesis of ``members`` registered alone that puts them elsewhere than
        every partition's transform does (``None`` if there is none)."""
        return self.best_of(self.hypotheses(found, members), members)

    def hypotheses(self, found: list[Found], members: NDArray[np.intp]) -> list[Candidate]:
        """The hypotheses of ``members`` registered alone that put them elsewhere than every
        partition's transform does (none for fewer than ``min_cells`` cells)."""
        if members.size < self.settings.min_cells:
            return []
        cells = np.zeros(self.points.shape[0], dtype=bool)
        cells[members] = True
        return self._new_hypotheses(found, cells)

    def best_of(
        self, candidates: list[Candidate], members: NDArray[np.intp]
    ) -> RigidTransform | None:
        """Of ``candidates`` (hypotheses of ``members``), the one that aligns the most of
        ``members`` best, refined (``None`` if there is none)."""
        if not candidates:
            return None
        best = best_hypothesis(
            candidates, take_rows(self.points, members), self.index, self.settings.threshold
        )
        return None if best is None else best[0]

    def _new_hypotheses(
        self,
        found: list[Found],
        cells: NDArray[np.bool_],
        source: NDArray[np.bool_] | None = None,
    ) -> list[Candidate]:
        """The hypotheses of ``source`` (default ``cells``) registered alone (twice
        ``max_candidates``) that do not put ``cells`` where a partition already found does;
        none if too few cells are left to register."""
        settings, pts = self.settings, self.points
        states = moving_remainder(
            self.context.working,
            pts[:, 1].astype(np.intp),
            pts[:, 0].astype(np.intp),
            cells if source is None else source,
            settings.uses_free,
            settings.drop_isolated,
            settings.as_cells,
        )
        if occupied_count(states) < settings.min_cells:
            return []
        return _new_ones(
            candidates_of(self.registrar, self.reference, states, 2 * settings.max_candidates),
            found,
            take_rows(pts, cells),
            settings.loose,
        )

    def placed(self, found: list[Found], cells: NDArray[np.float64]) -> list[Candidate]:
        """The placements of ``cells`` (points ``(x, y)``: the suspects' rows that
        :meth:`lost_partition` counts on) at the rotations that turn their wall directions
        onto the reference's (:func:`~brokenness.registration.orientation.rotation_candidates`,
        :data:`ROTATION_PEAKS` peaks, each both ways round), every translation counted
        (:func:`~brokenness.measure.placement.placements`: of those whose coarse count
        reaches the smallest partition, as many as there are rotations, the highest), that
        do not put ``cells`` where a partition already found does. The best of them that
        fails the count is not returned as a rival: step 5's count over the whole map and the
        settle step's offers are for the registration's hypotheses, and a placement that
        explains too few suspects is the search's last try.

        The registration's rotation comes from the whole spectrum of the cells registered:
        a small part's few cells, mixed with the borders of parts turned by other bumps,
        give a spectrum whose strongest directions are not the part's. The directions of
        their walls (their Hough spectrum) still show the part's rotation among the few
        highest peaks against the reference's, and at that rotation the part's place is the
        highest count over all translations."""
        settings, context = self.settings, self.context
        spectrum = hough_spectrum(cells)
        angles = rotation_candidates(spectrum, context.reference_directions, ROTATION_PEAKS)
        found_here = [
            Candidate(t, 1.0)
            for t in placements(
                cells, angles, self.index, context.coarse, settings, settings.min_cells, len(angles)
            )
        ]
        return _new_ones(found_here, found, cells, settings.loose)

    def _coherent(self, transform: RigidTransform, cells: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Of ``cells``, those that agree under ``transform`` with at least
        :data:`SUPPORT_SHARE` of the occupied cells around them agreeing too."""
        share, agreeing = _share(
            transform,
            self.points,
            cells,
            self.index,
            self.settings.threshold,
            self.context.shape,
            SUPPORT_RADIUS,
            self.context.around,
        )
        # the cells' own agreement, as the share's lookup found it (each cell's lookup is
        # its own: the same as looking the cells up alone)
        agree = np.zeros(self.points.shape[0], dtype=bool)
        agree[agreeing] = True
        return (share >= SUPPORT_SHARE) & agree[cells]
