"""One rigid piece held as several partitions: join them under the transform they share.

The degree counts the *fewest* rigid pieces that explain the map. Every other stage of the
measure judges partitions by the cells they explain, and that cannot tell one part from
pieces of it: in a building that looks alike under a turn (an atrium with corridors at equal
angles), a part can be held as several partitions, each piece at a *twin* of its place,
where it fits as well as at its own. Together the pieces explain the same cells as the part
would under its true transform, so no step that counts explained cells prefers the part.
What tells them apart is the count of partitions: if one transform explains what two
neighbouring partitions explain, they are not "off" relative to each other, whatever their
transforms say.

:func:`join_pieces` asks that of every partition: its cells are registered together with
those of its neighbours in the map (the cells around a piece are mostly the rest of its
part), the transform that explains the partition's own cells best among the hypotheses is
taken, and the partition joins a neighbour under it when both keep what they explain: each
loses fewer than ``min_cells`` (the stopping rule's smallest partition) of the cells that
agree under its own transform, and at most ``1 - JOIN_SHARE`` (20 %) of them (the share of
:func:`~brokenness.measure.partitions.consolidate`, which joins two partitions under one of
their own transforms; here the transform is new). A piece of a true part passes (it keeps
all its cells); two parts of a broken map do not (under one transform, one of them loses
most of its cells).

It is the measure's last step before the contradiction test, after the relocation of
doubtful partitions (:func:`~brokenness.measure.recursion.compute_brokenness`): the
relocation moves a partition at a wrong place to its own, and a join made first can leave
no partition doubtful while a part is still split.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from .._points import take_rows
from ..registration.base import Registrar
from ..transform import RigidTransform
from .context import MapContext
from .hypotheses import best_hypothesis
from .partitions import JOIN_SHARE, Found, reassign
from .views import cells_candidates, exhausted

__all__ = ["NEIGHBOUR_BLOCK", "join_pieces", "neighbours"]

#: Side (cells) of the blocks on which partitions are neighbours: two partitions are when
#: cells of both lie in one block or in two adjacent ones (16-32 cells apart at most; the
#: support test's window is 25 cells).
NEIGHBOUR_BLOCK = 16


def neighbours(found: list[Found], points: NDArray[np.float64]) -> list[list[int]]:
    """Per partition, the partitions with cells in its blocks or the blocks next to them
    (:data:`NEIGHBOUR_BLOCK`), in order.

    Parameters
    ----------
    found : list of Found
        The partitions (members index ``points``).
    points : ndarray, shape (N, 2)
        The map's occupied cells ``(x, y)``.

    Returns
    -------
    list of list of int
    """
    k = len(found)
    if k == 0:
        return []
    bx = (points[:, 0] // NEIGHBOUR_BLOCK).astype(np.intp) + 1  # a block of margin around
    by = (points[:, 1] // NEIGHBOUR_BLOCK).astype(np.intp) + 1
    shape = (int(by.max()) + 2, int(bx.max()) + 2)
    present = np.zeros((k, *shape), np.uint8)
    for j, f in enumerate(found):
        present[j, by[f.members], bx[f.members]] = 1
    square = np.ones((3, 3), np.uint8)
    near = [cv2.dilate(present[j], square) > 0 for j in range(k)]
    seen = present > 0
    return [[j for j in range(k) if j != i and np.any(near[i] & seen[j])] for i in range(k)]


def join_pieces(
    found: list[Found], context: MapContext, registrar: Registrar | None, whole: Any
) -> list[Found]:
    """Join neighbouring partitions that one transform explains (see the module docstring).

    Parameters
    ----------
    found : list of Found
        The partitions.
    context : MapContext
        The map and the reference of the call.
    registrar : Registrar or None
        The registration of a partition with its neighbours (the measure's wider search);
        ``None``: nothing is joined. Once it has spent its budget
        (:func:`~brokenness.measure.views.exhausted`), nothing more is registered.
    whole : object
        ``registrar``'s prepared reference.

    Returns
    -------
    list of Found
        ``found`` itself when nothing was joined, else the partitions with the joined ones
        replaced by one and every cell given to its best partition
        (:func:`~brokenness.measure.partitions.reassign`).
    """
    if registrar is None:
        return found
    points, index, settings = context.points, context.index, context.settings
    threshold, min_cells = settings.threshold, settings.min_cells
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    tried: set[bytes] = set()  # transforms whose partition was registered with its neighbours
    while len(found) > 1:
        near = neighbours(found, points)
        own = [_agreeing(f.transform, f, points, context) for f in found]
        joined: tuple[int, int, RigidTransform] | None = None
        for i in sorted(range(len(found)), key=lambda q: (found[q].members.size, q)):
            key = found[i].transform.matrix.tobytes()
            if not near[i] or key in tried:
                continue
            if exhausted(registrar):
                return found
            tried.add(key)
            cells = np.zeros(points.shape[0], dtype=bool)
            for q in (i, *near[i]):
                cells[found[q].members] = True
            hypotheses = cells_candidates(
                registrar, whole, context.working, rows, cols, cells, settings
            )
            own_points = take_rows(points, found[i].members)
            best = best_hypothesis(hypotheses, own_points, index, threshold)
            if best is None or not _keeps(best[0], found[i], own[i], points, context):
                continue
            partner = next(
                (j for j in near[i] if _keeps(best[0], found[j], own[j], points, context)), None
            )
            if partner is not None:
                joined = (i, partner, best[0])
                break
        if joined is None:
            return found
        i, j, transform = joined
        piece = Found(
            transform,
            np.concatenate([found[i].members, found[j].members]),
            max(found[i].confidence, found[j].confidence),
            found[i].seconds + found[j].seconds,
        )
        rest = [f for q, f in enumerate(found) if q not in (i, j)]
        found = reassign([*rest, piece], points, index, threshold, min_cells)
    return found


def _agreeing(
    transform: RigidTransform, f: Found, points: NDArray[np.float64], context: MapContext
) -> NDArray[np.bool_]:
    """Which cells of partition ``f`` agree with the reference under ``transform``."""
    moved = transform.apply(take_rows(points, f.members))
    return context.index.occupied_agreement(moved, context.settings.threshold)


def _keeps(
    transform: RigidTransform,
    f: Found,
    own: NDArray[np.bool_],
    points: NDArray[np.float64],
    context: MapContext,
) -> bool:
    """Whether ``transform`` keeps what partition ``f`` explains: of its cells that agree
    under its own transform (``own``), it loses fewer than ``min_cells`` and at most
    ``1 - JOIN_SHARE`` of them."""
    lost = np.count_nonzero(own & ~_agreeing(transform, f, points, context))
    return bool(
        lost < context.settings.min_cells and lost <= (1.0 - JOIN_SHARE) * np.count_nonzero(own)
    )
