"""Does a map fit its reference far better mirrored? (A row-order slip, usually.)

A map read with its rows in the wrong order (a ``nav_msgs/OccupancyGrid`` array taken in
image order, an image flipped by a converter) is the mirror image of the place: no rigid
transform aligns it, and the brokenness computation reports a large degree or nothing at
all, either of which looks like an answer. :func:`mirror_check` registers the map as it is
and with its rows reversed with the reference, and compares the share of the map's occupied
cells that land near a reference wall (Birk's agreement, within ``threshold`` cells,
Manhattan) under the best hypothesis of each. It is cheap (two registrations), so the
command line runs it only when a result looks suspicious (not measured, or a large degree).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grid import OccupancyMap
from ..masking.agreement import cell_points
from ..masking.distance import lookup_distance, manhattan_distance_map
from ..registration.api import register

__all__ = ["MIN_GAIN", "MIN_RATIO", "MirrorCheck", "mirror_check", "mirrored"]

#: The mirrored map must explain at least this many times the share of the map as it is...
MIN_RATIO: float = 1.5
#: ...and at least this much more of it (a share of the occupied cells), to be "far better".
MIN_GAIN: float = 0.2


@dataclass(frozen=True)
class MirrorCheck:
    """Agreement of a map with its reference as it is and with its rows reversed.

    Attributes
    ----------
    share : float
        Share of the map's occupied cells within ``threshold`` of a reference wall under the
        best registration of the map as it is.
    mirrored_share : float
        The same for the map with its rows in the other order.
    """

    share: float
    mirrored_share: float

    @property
    def far_better_mirrored(self) -> bool:
        """True when the mirrored map fits far better (:data:`MIN_RATIO`, :data:`MIN_GAIN`)."""
        return (
            self.mirrored_share >= MIN_RATIO * self.share
            and self.mirrored_share - self.share >= MIN_GAIN
        )

    def message(self) -> str:
        """One line for the user."""
        return (
            "the map fits the reference far better mirrored: rows in the wrong order? "
            f"({100 * self.mirrored_share:.0f}% of its cells agree mirrored, "
            f"{100 * self.share:.0f}% as it is; for a .npy see --row-order)"
        )


def mirrored(m: OccupancyMap) -> OccupancyMap:
    """The map with its rows in the other order (same resolution and origin)."""
    return OccupancyMap(m.states[::-1], m.resolution, m.origin, m.source)


def _agreement(
    m: OccupancyMap, ref: OccupancyMap, distance: np.ndarray, threshold: float, method: str
) -> float:
    points = cell_points(m.occupied)
    if not len(points):
        return 0.0
    reg = register(ref, m, method=method, seed=0, max_candidates=3)
    best = 0.0
    for c in reg.candidates:
        near = lookup_distance(distance, c.transform.apply(points)) <= threshold
        best = max(best, float(np.count_nonzero(near)) / len(points))
    return best


def mirror_check(
    m: OccupancyMap,
    reference: OccupancyMap,
    *,
    threshold: float = 2.0,
    method: str = "ifmi",
) -> MirrorCheck:
    """Register ``m`` as it is and mirrored with ``reference``; compare their agreement.

    Raises
    ------
    MapError
        If a map has no occupied cell (from :func:`brokenness.register`).
    """
    distance = manhattan_distance_map(reference.occupied)
    return MirrorCheck(
        share=_agreement(m, reference, distance, threshold, method),
        mirrored_share=_agreement(mirrored(m), reference, distance, threshold, method),
    )
