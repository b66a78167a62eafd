"""What the stages after Algorithm 1 read of a call: the map and the reference, fixed.

The recursion (:mod:`brokenness.measure.recursion`) finds partitions; the stages after it
(the recovery, the tests of what is real, the settle step, the relocation and the judge)
read the same things of the map and the reference on every pass: the map's occupied cells,
the map and the reference at the working resolution, the per-map settings, and two
quantities of the map alone, made once a call. :class:`MapContext` holds them: the
recovery (:func:`~brokenness.measure.recovery.recover`,
:func:`~brokenness.measure.recovery.relocation_rivals`,
:func:`~brokenness.measure.recovery.drop_incoherent`) and the recursion module's stages
take it instead of the same six arguments passed by hand. The lower-level steps that need
only some of them (:func:`~brokenness.measure.settle.settle`, the joins of
:mod:`~brokenness.measure.partitions`) take those, so that they can be used, and tested,
on their own.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from ..grid import OccupancyMap
from ..masking import ReferenceIndex
from ..registration.orientation import hough_spectrum
from .evidence import ClearFree
from .options import Settings
from .placement import CoarseAgreement

__all__ = ["MapContext"]


@dataclass(frozen=True, eq=False)
class MapContext:
    """The map and the reference of a call, as the stages after the recursion read them.

    Attributes
    ----------
    points : ndarray, shape (N, 2)
        The map's occupied cells ``(x, y)`` in the working grid, row-major (the members of
        every partition index them).
    working : OccupancyMap
        The map at the working resolution (that of ``index``'s reference).
    index : ReferenceIndex
        The reference at the working resolution.
    settings : Settings
        The per-map settings.
    around : ndarray, shape (N,)
        Per occupied cell, the occupied cells in the square window around it
        (:func:`~brokenness.measure.recovery.occupied_around`).
    clear : ClearFree
        The map's clear free cells (:class:`~brokenness.measure.evidence.ClearFree`, made
        when a contradiction first needs them).
    """

    points: NDArray[np.float64]
    working: OccupancyMap
    index: ReferenceIndex
    settings: Settings
    around: NDArray[np.float64]
    clear: ClearFree

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the working grid."""
        return self.working.shape

    @cached_property
    def coarse(self) -> CoarseAgreement:
        """The reference's coarse agreement grid at the settings' threshold, for placements
        at every translation (:class:`~brokenness.measure.placement.CoarseAgreement`;
        made when first needed)."""
        return CoarseAgreement.of(self.index, self.settings.threshold)

    @cached_property
    def reference_directions(self) -> NDArray[np.float64]:
        """The Hough spectrum of the reference's walls
        (:func:`~brokenness.registration.orientation.hough_spectrum`; made when first
        needed)."""
        return hough_spectrum(self.index.occupied_points)
