"""Break a real map on purpose: move regions of it by known rigid transforms.

Used by the end-to-end tests until (and beside) the simulator: the ground truth of each
partition is exact, because we made the motion ourselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from brokenness import OccupancyMap, RigidTransform, load_map
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.measure.options import Settings


def building_31_corner(side: int = 520) -> OccupancyMap:
    """The bundled MIT building 31 map's top-left ``side`` x ``side`` cells (unknown where the
    map is smaller), as a reference in its own frame."""
    m = load_map(Path(__file__).parent / "data" / "building_31.yaml")
    states = np.full((side, side), UNKNOWN, np.int8)
    crop = m.states[:side, :side]
    states[: crop.shape[0], : crop.shape[1]] = crop
    return OccupancyMap(states, m.resolution, (0.0, 0.0, 0.0))


def median_error(t: RigidTransform, truth: RigidTransform, pts: np.ndarray) -> float:
    """Median distance (cells) between where ``t`` and ``truth`` put ``pts``."""
    return float(np.median(t.displacement(truth, pts)))


def move_about(
    center: tuple[float, float], degrees: float, shift: tuple[float, float]
) -> RigidTransform:
    """Rotation by ``degrees`` about ``center`` (x, y), then a shift: ref cells -> map cells."""
    rot = RigidTransform(np.radians(degrees))
    c = np.asarray(center, float)
    t = c - rot.apply(c[None])[0] + np.asarray(shift, float)
    return RigidTransform(np.radians(degrees), t[0], t[1])


def break_map(
    reference: OccupancyMap,
    regions: Sequence[np.ndarray],
    motions: Sequence[RigidTransform],
    *,
    pad: int = 0,
) -> tuple[OccupancyMap, list[RigidTransform]]:
    """Move each region of ``reference`` by its motion and composite the pieces.

    Parameters
    ----------
    reference : OccupancyMap
    regions : sequence of bool arrays
        Disjoint masks over the reference grid.
    motions : sequence of RigidTransform
        Reference cells -> broken-map cells, one per region.
    pad : int
        Cells added on every side of the broken map, so that moved regions stay on it.

    Returns
    -------
    broken : OccupancyMap
        The reference's shape plus ``2 * pad`` (same resolution; origin moved by the pad).
    truth : list of RigidTransform
        Per region, the transform from broken-map cells back to reference cells (the
        convention of ``compute_brokenness``).
    """
    shift = RigidTransform(0.0, pad, pad)
    motions = [shift.compose(m) for m in motions]
    h, w = reference.shape[0] + 2 * pad, reference.shape[1] + 2 * pad
    occupied = np.zeros((h, w), bool)
    free = np.zeros((h, w), bool)
    for region, motion in zip(regions, motions, strict=True):
        src = np.where(region, reference.states + 1, 0).astype(np.uint8)  # 0 outside, 1..3 inside
        moved = cv2.warpAffine(
            src, motion.matrix[:2], (w, h), flags=cv2.INTER_NEAREST, borderValue=0
        )
        occupied |= moved == OCCUPIED + 1
        free |= moved == FREE + 1
    states = np.full((h, w), UNKNOWN, np.int8)
    states[free] = FREE
    states[occupied] = OCCUPIED
    origin = reference.origin
    if origin is not None and reference.resolution is not None:
        r = reference.resolution
        c, si = np.cos(origin[2]), np.sin(origin[2])
        origin = (origin[0] - r * pad * (c - si), origin[1] - r * pad * (si + c), origin[2])
    broken = OccupancyMap(states, reference.resolution, origin, source="broken")
    return broken, [m.inverse() for m in motions]


def strips(shape: tuple[int, int], cuts: Sequence[float], axis: int = 1) -> list[np.ndarray]:
    """Split a grid into strips at the given fractions of its width (axis=1) or height (0)."""
    h, w = shape
    n = w if axis == 1 else h
    edges = [0, *[int(round(c * n)) for c in cuts], n]
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        m = np.zeros(shape, bool)
        if axis == 1:
            m[:, a:b] = True
        else:
            m[a:b, :] = True
        out.append(m)
    return out


#: The per-map settings of the defaults for a map of a few thousand occupied cells, for tests
#: that call the measure's stages directly.
SETTINGS = Settings(
    threshold=2.0,
    loose=4.0,
    min_cells=30,
    significance=6.0,
    max_partitions=16,
    max_candidates=12,
    uses_free=True,
    drop_isolated=True,
)
