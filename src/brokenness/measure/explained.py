"""Explained regions: a partition must explain the region of the map it lies in.

A true part of a broken map is one rigid piece of the robot's run: under its transform
nearly every occupied cell of its stretch of the map agrees with the reference, and the
cells around its own that no partition explains are specks, clutter the reference does not
hold, and the borders of other parts. A placement that agrees by chance is different: walls
being lines, a transform can put some wall segments of a region on reference walls, enough
to pass the stopping rule, but the rest of the region agrees under nothing. That is what
the map's cells beyond the reference give when the map extends past it (a floor plan of one
wing, a reference run that went less far): every such region is registered like a lost
part, and its best placement explains a share of it (with session 29's code, 186 of the
211 cases of ``benchmarks/partial_reference.py`` that were measured held such a partition).

So a partition is real only if it explains its *region*: of the occupied cells within the
coherence window (:data:`~brokenness.measure.support.SUPPORT_RADIUS` cells) of its own,
those that no partition explains, specks of noise left out
(:func:`~brokenness.measure.views.isolated_points`), must be few against its own cells: its
cells must be at least :data:`REGION_SHARE` of the two together. Once the partitions are
settled and relocated (the last stage before the judge, and the partitions the threshold
was chosen on: earlier, a true part's partition may still hold a twin's cells, or lack its
own), :func:`drop_unexplained` drops the partition with the smallest share while that is
under it, one at a time, the cells given to the partitions left
(:func:`~brokenness.measure.partitions.reassign`). (Run on the partitions of every round of
the recovery's tests instead, it dropped a true partition of a real-log map not yet
settled, 0.79 of its region, and its neighbours fell after it: 8 partitions to 2, found
again by the next round, at the cost of that round.) The cells of a region that nothing
explains then stay unassigned: the map is measured on what lies on the reference, if that
is most of it (:data:`MAP_SHARE`, tested by the judge of
:mod:`~brokenness.measure.recursion`, :func:`explained_share`). A map of another place
loses most of its partitions to this test (277 of the 392 negative controls of session 30
were left holding 3-34 % of the cells), and what is left of it is one placement chosen for
fitting well: its free space alone no longer shows the map to be of another place, but it
holds a minority of the map.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .context import MapContext
from .partitions import Found, owners, reassign
from .support import SUPPORT_RADIUS, in_box, window_box, window_counts
from .views import isolated_points

__all__ = ["MAP_SHARE", "REGION_SHARE", "drop_unexplained", "explained_share", "region_shares"]

#: A partition's cells must be at least this share of its cells and the unexplained cells
#: of its region. Chosen on the realistic benchmark (README, "How the thresholds were
#: chosen"): the 1886 true partitions of sets 0-2 hold 0.87 or more (1 % under 0.93), while
#: the partitions that a map's cells beyond a cropped reference gave hold 0.63 (median) and
#: 0.84 at most, and every such case holds one under 0.8.
REGION_SHARE = 0.8
#: A map is measured only if its partitions explain at least this share of its occupied
#: cells: the degree describes the map, not a minority of it.
MAP_SHARE = 0.5


def explained_share(found: list[Found], context: MapContext) -> float:
    """The share of the map's occupied cells (``context.points``) that its partitions hold."""
    n = context.points.shape[0]
    return sum(f.members.size for f in found) / n if n else 0.0


def region_shares(found: list[Found], context: MapContext) -> NDArray[np.float64]:
    """Per partition, its cells' share of its cells and the cells of its region that no
    partition explains (the occupied cells, specks left out, that belong to no partition and
    lie within :data:`~brokenness.measure.support.SUPPORT_RADIUS` cells of one of its own,
    in a square window). The cost follows the cells: one windowed count per partition, over
    the box of the windows around its own cells."""
    points = context.points
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    owner = owners(found, points.shape[0])
    left = (owner < 0) & ~isolated_points(rows, cols)
    shares = np.ones(len(found))
    if not left.any():
        return shares
    for j, f in enumerate(found):
        if f.members.size == 0:
            continue
        mine = owner == j
        # only the unexplained cells in the box of the windows around its own can count
        box = window_box(rows[mine], cols[mine], context.shape, SUPPORT_RADIUS)
        at = left & in_box(rows, cols, box)
        unexplained = 0
        if at.any():
            near = window_counts(rows, cols, mine, at, context.shape, SUPPORT_RADIUS)
            unexplained = int(np.count_nonzero(near))
        shares[j] = f.members.size / (f.members.size + unexplained)
    return shares


def drop_unexplained(found: list[Found], context: MapContext) -> list[Found]:
    """The partitions that explain their regions (see the module docstring), cells
    reassigned: the one with the smallest share (:func:`region_shares`) is dropped while it
    is under :data:`REGION_SHARE`, one at a time (the cells of a placement dropped count
    against the placements beside it in the next round: those beyond a reference fall
    together). Returns ``found`` itself when none is dropped."""
    settings = context.settings
    while len(found) > 1:
        shares = region_shares(found, context)
        worst = int(np.argmin(shares))  # the first of equal shares
        if shares[worst] >= REGION_SHARE:
            break
        kept = [f for j, f in enumerate(found) if j != worst]
        found = (
            reassign(kept, context.points, context.index, settings.threshold, settings.min_cells)
            if len(kept) > 1
            else kept
        )
    return found
