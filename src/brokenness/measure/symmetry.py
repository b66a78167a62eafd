"""Fewest partitions: pieces of one part held at twins that a symmetry of the reference relates.

The degree of brokenness is the *least* number of partitions, less one, into which the map
splits with each partition consistent with the reference (Birk 2010, Definition 1). In a
building whose plan repeats itself under a rigid motion, a *symmetry* of the reference (the
drawn atrium of five corridors 72 degrees apart, a hexagonal arena), a part of the map fits
at each of its twins, and the greedy search can split one part into pieces, each held at a
different twin. Every piece is consistent with the reference on its own, so no test of a
partition tells it is wrong; but one transform explains all of them: the part's place, which
is one of the twins of each piece, the piece's transform followed by a symmetry. The
partitioning is then not the least one.

A symmetry of the reference is found as any registration is: the reference registered with
itself (:func:`symmetries`: its hypotheses other than the identity). For every partition's
transform followed by every symmetry, :func:`merges` finds the partitions that it explains
(most of each one's agreeing cells agree under it too) as well as their own transforms do,
all but fewer than the smallest partition's cells (``min_cells``) in total: the partitions
it would replace would not hold, between them, the cells that a partition must explain on
its own. The measure (:func:`brokenness.compute_brokenness`) replaces them by one partition
of that transform if the map is still measured and no other partition is dropped (README
step 10). A symmetry is a rigid motion: the mirror image of a wing is not one.

Two parts of a broken map whose transforms differ by a symmetry of the reference are one
partition by the definition (one transform makes both consistent); for parts bumped at
random, that takes a bump equal to a symmetry. Without the test that the transform
explains each partition it replaces, a small true part of a simulated map (99 cells, of
which the merged transform explained 46) was absorbed with the fewer-than-``min_cells``
allowance alone (``benchmarks/accuracy.py``, seed 16 at degree 5).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from .._points import take_rows
from ..masking import ReferenceIndex
from ..registration.base import Registrar
from ..transform import RigidTransform
from .options import Settings
from .partitions import EXPLAINED_EXCESS, Found

__all__ = ["Merge", "merges", "symmetries"]

#: The reference's walls looked at to tell a hypothesis of the reference against itself from
#: the identity: at most about this many (an even subsample).
_MAX_WALLS = 20_000


class Merge(NamedTuple):
    """One transform that explains several partitions as well as their own transforms.

    Attributes
    ----------
    transform : RigidTransform
        A partition's transform followed by a symmetry of the reference.
    partitions : tuple of int
        The partitions it explains (indices into the list given to :func:`merges`),
        ascending.
    lost : int
        Cells of those partitions that agree under their own transform and not under it.
    """

    transform: RigidTransform
    partitions: tuple[int, ...]
    lost: int


def symmetries(
    registrar: Registrar, prepared: Any, index: ReferenceIndex, settings: Settings
) -> list[RigidTransform]:
    """The rigid motions of the reference onto itself: the hypotheses of the reference
    registered with itself, other than the identity.

    Parameters
    ----------
    registrar : Registrar
        The registration (its wider search); ``prepared`` its prepared reference.
    index : ReferenceIndex
        The reference at the working resolution.
    settings : Settings
        The per-map settings: ``max_candidates`` hypotheses are asked for, and one that
        moves the reference's walls by at most ``threshold`` cells (median) is the identity.

    Returns
    -------
    list of RigidTransform
        Reference cells to reference cells, in the registration's order. Whether one is a
        symmetry of a part of the reference is for :func:`merges` to find: it is used only
        where it makes the cells of several partitions agree.
    """
    walls = index.occupied_points
    if walls.shape[0] == 0:
        return []
    walls = walls[:: max(1, walls.shape[0] // _MAX_WALLS)]
    hypotheses = registrar.candidates(prepared, index.reference.states, settings.max_candidates)
    identity = RigidTransform.identity()
    return [
        h.transform
        for h in hypotheses
        if float(np.median(h.transform.displacement(identity, walls))) > settings.threshold
    ]


def merges(
    found: list[Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    settings: Settings,
    motions: list[RigidTransform],
) -> list[Merge]:
    """The transforms that explain several partitions, best first.

    Each partition's transform is followed by each of ``motions`` (:func:`symmetries`). It
    *explains* a partition when most of the partition's agreeing cells agree under it too,
    beyond chance (``(kept / agreeing - p0) / (1 - p0) >= 0.5``, ``p0`` the chance agreement:
    the test of :func:`~brokenness.measure.partitions.merge_target`); the partitions it
    explains are taken in order of the cells they would lose (the cells that agree under
    their own transform and not under it), fewest first, while the total lost stays under
    ``settings.min_cells``. A transform that explains two partitions or more is a merge;
    merges are ranked by the partitions they replace (most first), then the cells lost
    (fewest first), then the order of the partition and of the motion.

    Parameters
    ----------
    found : list of Found
        The partitions (members index ``points``).
    points : ndarray, shape (N, 2)
        The map's occupied cells ``(x, y)`` in the working grid.
    index : ReferenceIndex
        The reference at the working resolution.
    settings : Settings
        The per-map settings (``threshold``, ``min_cells``).
    motions : list of RigidTransform
        The symmetries of the reference.

    Returns
    -------
    list of Merge
    """
    if len(found) < 2 or not motions:
        return []
    threshold = settings.threshold
    p0 = index.chance_agreement(threshold)
    own = np.zeros(points.shape[0], dtype=bool)  # each cell agrees under its partition's
    for f in found:
        own[f.members] = index.occupied_agreement(
            f.transform.apply(take_rows(points, f.members)), threshold
        )
    agreeing = [int(np.count_nonzero(own[f.members])) for f in found]
    ranked: list[tuple[int, int, int, int, Merge]] = []
    for j, f in enumerate(found):
        for s, motion in enumerate(motions):
            transform = motion.compose(f.transform)
            agree = index.occupied_agreement(transform.apply(points), threshold)
            lost = [int(np.count_nonzero(own[g.members] & ~agree[g.members])) for g in found]
            # the partitions it explains: most of their agreeing cells agree under it too,
            # beyond chance (the measure's test of cells explained by another transform,
            # :func:`~brokenness.measure.partitions.merge_target`, at the threshold)
            explained = [
                q
                for q in range(len(found))
                if agreeing[q] > 0
                and ((agreeing[q] - lost[q]) / agreeing[q] - p0) >= EXPLAINED_EXCESS * (1.0 - p0)
            ]
            taken: list[int] = []
            total = 0
            for q in sorted(explained, key=lambda q: (lost[q], q)):
                if total + lost[q] >= settings.min_cells:
                    break
                total += lost[q]
                taken.append(q)
            if len(taken) >= 2:
                merge = Merge(transform, tuple(sorted(taken)), total)
                ranked.append((-len(taken), total, j, s, merge))
    ranked.sort(key=lambda r: r[:4])
    return [r[4] for r in ranked]
