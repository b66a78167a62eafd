"""Partitions: growing, merging and reassigning their cells, and the final result objects."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .._points import sorted_lookup, take_rows
from ..grid import OccupancyMap
from ..masking import ReferenceIndex, cell_points
from ..masking.distance import lookup_distance
from ..transform import RigidTransform
from .options import Settings
from .result import NOT_OCCUPIED, UNASSIGNED, Partition

__all__ = [
    "EXPLAINED_EXCESS",
    "JOIN_SHARE",
    "Found",
    "assemble",
    "cell_components",
    "consolidate",
    "drop_redundant",
    "labels_in_original_grid",
    "merge_target",
    "owners",
    "reassign",
    "with_fringe",
]


@dataclass(frozen=True)
class Found:
    """A partition as the recursion finds it (before sorting by size)."""

    transform: RigidTransform
    members: NDArray[np.intp]  # indices into the map's occupied points
    confidence: float
    seconds: float


def with_fringe(
    transform: RigidTransform,
    pts: NDArray[np.float64],
    agree: NDArray[np.bool_],
    index: ReferenceIndex,
    loose: float,
) -> NDArray[np.bool_]:
    """``agree`` plus the cells that agree loosely and touch it in the map (8-connected).

    Thick walls, clutter and a residual error of a fraction of a cell leave a fringe of
    cells just beyond the threshold around a partition. Left behind, such a fringe could later
    pass for a partition of its own; it belongs to the partition it touches.
    """
    near = lookup_distance(index.occupied_distance, transform.apply(pts)) <= loose
    if np.array_equal(near, agree) or not near.any():
        return agree
    comp = cell_components(pts[near, 1].astype(np.intp), pts[near, 0].astype(np.intp))
    seeds = np.unique(comp[agree[near]])
    touched = np.zeros(pts.shape[0], dtype=bool)
    touched[near] = np.isin(comp, seeds)
    return agree | (near & touched)


#: Cells of a box per given cell up to which labelling the box costs less than the graph of
#: the cells (small maps; the components are the same).
_DENSE_BOX = 64


def cell_components(rows: NDArray[np.intp], cols: NDArray[np.intp]) -> NDArray[np.int32]:
    """The 8-connected component of each of the given distinct cells (numbered from 0).

    The components of the cells alone, as a graph of neighbouring cells (found by sorted
    lookups of each cell's four forward neighbours): the cost follows the cells, not the
    grid of their box.
    """
    n = rows.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int32)
    r0, c0 = int(rows.min()), int(cols.min())
    height = int(rows.max()) - r0 + 1
    if height * (int(cols.max()) - c0 + 1) <= _DENSE_BOX * n:  # small box: label it directly
        grid = np.zeros((height, int(cols.max()) - c0 + 1), np.uint8)
        grid[rows - r0, cols - c0] = 1
        _, comp = cv2.connectedComponents(grid, connectivity=8)
        return np.asarray(comp[rows - r0, cols - c0], dtype=np.int32)
    # a column of margin on each side, so that no neighbour wraps into the next row
    width = int(cols.max()) - int(cols.min()) + 3
    keys = (rows - int(rows.min())) * width + (cols - int(cols.min()) + 1)
    order = np.argsort(keys, kind="stable")
    ordered = keys[order]
    heads, tails = [], []
    for step in (1, width - 1, width, width + 1):  # right, and the three below
        at, hit = sorted_lookup(ordered, keys + step)
        heads.append(np.flatnonzero(hit))
        tails.append(order[at[hit]])
    head, tail = np.concatenate(heads), np.concatenate(tails)
    graph = coo_matrix((np.ones(head.size, dtype=np.int8), (head, tail)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return np.asarray(labels, dtype=np.int32)


#: A transform *explains* a set of cells when at least this share of those that chance would
#: not put near a wall land near one under it: ``(share - q) / (1 - q) >= EXPLAINED_EXCESS``
#: (:func:`merge_target`; the pieces of step 10, :mod:`~brokenness.measure.symmetry`).
EXPLAINED_EXCESS = 0.5


def merge_target(
    found: list[Found], pts: NDArray[np.float64], index: ReferenceIndex, merge_threshold: float
) -> int | None:
    """Index of the earlier partition whose transform loosely explains ``pts``, if any.

    Under that transform, at least half of the cells that chance would not put within
    ``merge_threshold`` of a reference wall must land there: ``(share - q) / (1 - q) >= 0.5``
    with ``q`` the chance agreement at ``merge_threshold`` (in a dense map a loose threshold
    is met by many cells of a part that is really off).
    """
    q = index.chance_agreement(merge_threshold)
    best, best_excess = None, EXPLAINED_EXCESS
    for i, f in enumerate(found):
        d = lookup_distance(index.occupied_distance, f.transform.apply(pts))
        share = float(np.count_nonzero(d <= merge_threshold)) / max(pts.shape[0], 1)
        excess = (share - q) / (1.0 - q) if q < 1.0 else 0.0
        if excess >= best_excess:
            best, best_excess = i, excess
    return best


def owners(found: list[Found], n_points: int) -> NDArray[np.intp]:
    """Partition (index into ``found``) of each of ``n_points`` cells, ``-1`` for none."""
    owner = np.full(n_points, -1, dtype=np.intp)
    for j, f in enumerate(found):
        owner[f.members] = j
    return owner


def reassign(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    min_cells: int,
) -> list[Found]:
    """Give each cell to the partition under whose transform it agrees *best*.

    The recursion is greedy: the first partition takes every cell that agrees with the
    reference under its transform, including cells of other parts that land near a wall by
    coincidence (common in maps of many similar rooms). Once all transforms are known, each
    agreeing cell goes to the partition that puts it closest to a reference wall; ties keep
    the greedy choice when it is among them, else the larger partition. Cells that agree under
    no transform stay unassigned. A partition left with fewer than ``min_cells`` cells is
    dropped and the assignment repeated without it.
    """
    if len(found) < 2:
        return found
    owner = owners(found, points.shape[0])
    kept = list(range(len(found)))
    while True:
        distances = np.stack(
            [
                lookup_distance(index.occupied_distance, found[j].transform.apply(points))
                for j in kept
            ]
        )
        best = distances.min(axis=0)
        tied = distances == best
        greedy = np.array([owner == j for j in kept])
        # the greedy owner if it is among the best, else the first (largest-found) best
        choice = np.where(
            (tied & greedy).any(axis=0), np.argmax(tied & greedy, axis=0), np.argmax(tied, axis=0)
        )
        assigned = np.where(best <= threshold, np.asarray(kept)[choice], -1)
        sizes = {j: int(np.count_nonzero(assigned == j)) for j in kept}
        small = [j for j in kept if sizes[j] < min_cells]
        if not small or len(kept) == 1:
            break
        kept = [j for j in kept if j not in small]
    return [
        Found(
            found[j].transform, np.flatnonzero(assigned == j), found[j].confidence, found[j].seconds
        )
        for j in kept
        if sizes[j] > 0
    ]


def assemble(
    found: list[Found],
    points: NDArray[np.float64],
    working: OccupancyMap,
    frames: tuple[RigidTransform, RigidTransform],
    original: OccupancyMap,
    ref: OccupancyMap,
    index: ReferenceIndex,
) -> tuple[list[Partition], NDArray[np.int16]]:
    """Sort partitions by size, relate them to the largest, and draw the label image.

    ``frames`` are the transforms original map cells -> working map cells and working
    reference cells -> reference cells: the partitions' transforms are reported from the
    original map's cells to the reference's, and their displacements in reference cells.
    """
    to_working, to_reference = frames
    cell = to_reference.scale  # a working reference cell, in reference cells
    order = sorted(range(len(found)), key=lambda i: (-found[i].members.size, i))
    labels = np.full(working.shape, NOT_OCCUPIED, dtype=np.int16)
    labels[points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)] = UNASSIGNED
    partitions: list[Partition] = []
    if not found:
        return partitions, labels
    largest = found[order[0]].transform
    for new_index, i in enumerate(order):
        f = found[i]
        pts = take_rows(points, f.members)
        labels[pts[:, 1].astype(np.intp), pts[:, 0].astype(np.intp)] = new_index
        offset = math.degrees(math.remainder(f.transform.rotation - largest.rotation, 2 * math.pi))
        displacement = (
            cell * float(f.transform.displacement(largest, pts).mean()) if new_index else 0.0
        )
        whole = to_reference.compose(f.transform.compose(to_working)).with_world(original, ref)
        partitions.append(
            Partition(
                index=new_index,
                cells=int(f.members.size),
                fraction=0.0,  # filled in by the caller, in original cells
                transform=whole,
                confidence=f.confidence,
                rotation_offset_deg=0.0 if new_index == 0 else offset,
                displacement=displacement,
                displacement_m=None if ref.resolution is None else displacement * ref.resolution,
                step_seconds=f.seconds,
            )
        )
    return partitions, labels


def labels_in_original_grid(
    labels: NDArray[np.int16],
    working: OccupancyMap,
    to_working: RigidTransform,
    original: OccupancyMap,
) -> NDArray[np.int16]:
    """Carry the working-grid labels back to the original map's grid (nearest cell)."""
    if working is original:
        return labels
    out = np.full(original.shape, NOT_OCCUPIED, dtype=np.int16)
    occ = original.occupied
    pts = to_working.apply(cell_points(occ))
    h, w = labels.shape
    c = np.clip(np.rint(pts[:, 0]).astype(np.intp), 0, w - 1)
    r = np.clip(np.rint(pts[:, 1]).astype(np.intp), 0, h - 1)
    lab = labels[r, c]
    out[occ] = np.where(lab >= 0, lab, UNASSIGNED)
    return out


#: Share of the cells of two partitions that one transform must align to join them.
JOIN_SHARE = 0.8


def consolidate(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
) -> list[Found]:
    """Join partitions that are one rigid piece under one of their two transforms.

    The recursion merges a new set into an *earlier* partition whose transform explains it
    (:func:`merge_target`); a partition found later (by :mod:`~brokenness.measure.recovery`)
    can explain an earlier one just as well. That happens in symmetric buildings: a part
    first placed at a symmetric twin of its true place (turned by 90 or 180 degrees) agrees
    with the reference there, and the piece of it found again later agrees in its true
    place. Such partitions are not "off" relative to each other. Smallest first, a partition
    explained by another's transform (the test of :func:`merge_target`) joins it when one
    of the two transforms makes at least :data:`JOIN_SHARE` of the cells of both agree
    (within ``threshold``; neighbouring parts of a regular building can pass the loose test
    alone). Two partitions at one rotation (within :data:`SAME_ROTATION_DEG`) are joined
    only if the transform given up has no evidence of its own, the test of
    :func:`drop_redundant` (fewer than ``min_cells`` cells agree under it and not under the
    one kept): the two parts of a pure-shift bump pass the 80 % when one is much larger than
    the other, but the walls across the shift agree under one of them only. The joined
    partition keeps that transform (the one that makes more cells agree), and the cells are
    reassigned.
    """
    threshold, merge_threshold, min_cells = settings.threshold, settings.loose, settings.min_cells
    while len(found) > 1:
        for j in sorted(range(len(found)), key=lambda q: (found[q].members.size, q)):
            joined = _joined(found, j, points, index, threshold, merge_threshold, min_cells)
            if joined is not None:
                break
        else:
            return found
        i, partition = joined
        rest = [f for q, f in enumerate(found) if q not in (i, j)]
        found = reassign([*rest, partition], points, index, threshold, min_cells)
    return found


def _joined(
    found: list[Found],
    j: int,
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    merge_threshold: float,
    min_cells: int,
) -> tuple[int, Found] | None:
    """The partition ``j`` joins (its index) and the joined partition, if any."""
    others = [q for q in range(len(found)) if q != j]
    target = merge_target(
        [found[q] for q in others], take_rows(points, found[j].members), index, merge_threshold
    )
    if target is None:
        return None
    i = others[target]
    union = np.concatenate([found[i].members, found[j].members])
    pts = take_rows(points, union)
    agree = [index.occupied_agreement(found[q].transform.apply(pts), threshold) for q in (i, j)]
    agreeing = [int(np.count_nonzero(a)) for a in agree]
    kept = 0 if agreeing[0] >= agreeing[1] else 1
    keep = (found[i], found[j])[kept]
    if max(agreeing) < JOIN_SHARE * union.size:
        return None
    # at one rotation, the transform given up must have no evidence of its own (the test of
    # drop_redundant: the parts of a pure-shift bump agree along the shift under either)
    given_up, keeper = (found[i], found[j])[1 - kept], keep
    if (
        abs(_turn_deg(given_up.transform, keeper.transform)) <= SAME_ROTATION_DEG
        and np.count_nonzero(agree[1 - kept] & ~agree[kept]) >= min_cells
    ):
        return None
    return i, Found(keep.transform, union, keep.confidence, found[i].seconds + found[j].seconds)


def drop_redundant(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
) -> list[Found]:
    """Drop shifted copies: partitions at the rotation of another that explain fewer than
    ``min_cells`` cells it does not.

    A piece at the rotation of a partition already found (within
    :data:`SAME_ROTATION_DEG`), merely shifted, is what a long straight corridor gives by
    coincidence: under the shift its walls along the corridor still lie on reference walls.
    Its evidence of its own is the cells that agree under its transform and under none of
    the partitions at its rotation: the walls across the shift. Each round drops the
    partition with the fewest such cells if they are fewer than ``min_cells`` (the smallest
    partition of the stopping rule), and reassigns the cells. A partition turned against
    every other is evidence of its own by its transform, but not without cells: of its cells
    that no other partition explains, more must agree under it than chance would make agree
    (the stopping rule without its smallest partition, by the binomial's exact tail,
    :meth:`~brokenness.measure.options.Settings.beyond_chance`: these are often a handful of
    cells, where the normal approximation ``n p0 + z sqrt(n p0 (1 - p0))`` passes 7 of 7);
    a placement of a part at a twin of its room, once the part is found in its true place,
    explains nothing the true one does not. The partition with the least evidence (relative
    to what its test asks) is dropped first.
    """
    threshold, min_cells = settings.threshold, settings.min_cells
    p0 = index.chance_agreement(threshold)
    while len(found) > 1:
        shortfall: list[float] = []  # evidence over what is asked: below 1 fails
        for j, f in enumerate(found):
            pts = take_rows(points, f.members)
            own = index.occupied_agreement(f.transform.apply(pts), threshold)
            twins = [
                g
                for q, g in enumerate(found)
                if q != j and abs(_turn_deg(f.transform, g.transform)) <= SAME_ROTATION_DEG
            ]
            if twins:
                for g in twins:
                    own &= ~index.occupied_agreement(g.transform.apply(pts), threshold)
                shortfall.append(np.count_nonzero(own) / min_cells)
                continue
            unexplained = np.ones(pts.shape[0], dtype=bool)
            for q, g in enumerate(found):
                if q != j:
                    unexplained &= ~index.occupied_agreement(g.transform.apply(pts), threshold)
            asked = settings.beyond_chance(int(np.count_nonzero(unexplained)), p0)
            k = int(np.count_nonzero(own & unexplained))
            shortfall.append(k / asked)
        worst = min(range(len(found)), key=lambda j: (shortfall[j], j))
        if shortfall[worst] >= 1.0:
            break
        kept = [f for j, f in enumerate(found) if j != worst]
        found = reassign(kept, points, index, threshold, min_cells) if len(kept) > 1 else kept
    return found


#: Partitions turned by at most this much against each other are at "the same rotation".
SAME_ROTATION_DEG = 2.0


def _turn_deg(a: RigidTransform, b: RigidTransform) -> float:
    """Rotation of ``a`` relative to ``b``, degrees in (-180, 180]."""
    return math.degrees(math.remainder(a.rotation - b.rotation, 2 * math.pi))
