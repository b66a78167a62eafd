"""Hand-made maps and results for the reporting tests (no tests here, only builders).

The broken map is exact by construction: the reference's occupied cells right of column
``CUT`` are moved by ``SHIFT`` cells, so partition 1's transform back onto the reference is
the opposite shift.
"""

from __future__ import annotations

import numpy as np

from brokenness import OccupancyMap, RigidTransform
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.measure.result import NOT_OCCUPIED, UNASSIGNED, BrokennessResult, Partition

SIZE = 80
CUT = 42
SHIFT = (5, 3)  # (dx, dy) in cells of the right part of the broken map


def rooms(size: int = SIZE) -> OccupancyMap:
    """A small floor plan: outer walls, two inner walls, a pillar; unknown outside."""
    s = np.full((size, size), UNKNOWN, np.int8)
    s[6:74, 6:74] = FREE
    occ = np.zeros((size, size), bool)
    occ[6, 6:74] = occ[73, 6:74] = True
    occ[6:74, 6] = occ[6:74, 73] = True
    occ[6:50, 40] = True
    occ[30, 6:32] = True
    occ[55:60, 55:60] = True
    occ[20:45, 60] = True
    s[occ] = OCCUPIED
    return OccupancyMap(s, resolution=0.05, origin=(-2.0, -1.0, 0.0), source="rooms.pgm")


def broken_rooms() -> tuple[OccupancyMap, OccupancyMap, BrokennessResult]:
    """Reference, broken map (right part shifted) and the exact result for them."""
    ref = rooms()
    dx, dy = SHIFT
    right = np.zeros(ref.shape, bool)
    right[:, CUT:] = True
    states = ref.states.copy()
    moved = np.full(ref.shape, UNKNOWN, np.int8)
    moved[dy:, dx:] = ref.states[:-dy, :-dx]
    moved_right = np.zeros(ref.shape, bool)
    moved_right[dy:, dx:] = right[:-dy, :-dx]
    states[right] = UNKNOWN
    states[moved_right & (moved != UNKNOWN)] = moved[moved_right & (moved != UNKNOWN)]
    # keep the left part's walls on top
    left_occ = ref.occupied & ~right
    states[left_occ] = OCCUPIED
    m = OccupancyMap(states, ref.resolution, ref.origin, source="broken.pgm")
    labels = np.full(ref.shape, NOT_OCCUPIED, np.int16)
    part1 = m.occupied & moved_right & ~left_occ
    labels[m.occupied] = 0
    labels[part1] = 1
    # two stray occupied cells that belong to no partition
    noise = [(15, 20), (65, 25)]
    states2 = m.states.copy()
    for r, c in noise:
        states2[r, c] = OCCUPIED
        labels[r, c] = UNASSIGNED
    m = OccupancyMap(states2, ref.resolution, ref.origin, source="broken.pgm")
    n = m.n_occupied
    c0, c1 = int((labels == 0).sum()), int((labels == 1).sum())
    t1 = RigidTransform(0.0, -dx, -dy).with_world(m, ref)
    t0 = RigidTransform.identity().with_world(m, ref)
    parts = (
        Partition(0, c0, c0 / n, t0, 0.95, 0.0, 0.0, 0.0, 0.01),
        Partition(
            1,
            c1,
            c1 / n,
            t1,
            0.9,
            0.0,
            float(np.hypot(dx, dy)),
            float(np.hypot(dx, dy)) * 0.05,
            0.02,
        ),
    )
    result = BrokennessResult(
        degree=1,
        partitions=parts,
        labels=labels,
        occupied_cells=n,
        unassigned_cells=len(noise),
        method="ifmi",
        parameters={"threshold": 2.0, "seed": None},
        seconds=0.05,
    )
    return ref, m, result
