"""The reference's share of a call: what the measure makes of the reference alone, made once.

:func:`brokenness.compute_brokenness` measures a map in its own grid frame and, where a
partition is in doubt, again in other grid frames (README step 11; ``frames``). The map
changes from frame to frame; the reference does not, nor do the call's options (one
options object for every frame). :class:`ReferenceWork` holds what is made of the
reference alone, so that every frame of a call uses it instead of making it again:

* the reference at the working resolution (upsampled to a finer map's cells), with the
  transform of its cells to the reference's (:meth:`ReferenceWork.at`);
* its :class:`~brokenness.masking.ReferenceIndex` (the distance map of its walls, the
  nearest-wall table, the chance agreement per threshold): on a reference of 8700 x 8700
  cells about half a second a frame;
* its symmetries, the registration of the reference with itself (README step 10;
  :meth:`WorkingReference.symmetries`).

Each is a function of the reference and of the call's options only, so a frame gets the
same values, bit for bit, as when it made its own. The registration's preparation of the
reference (its outline's distance map) is not kept between frames: a frame frees it before
its last stages, and keeping it for a frame that may not come would raise the peak memory
of every call for the few maps measured twice.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

from ..grid import OccupancyMap
from ..masking import ReferenceIndex, cell_points
from ..transform import RigidTransform
from .walls import wall_thickness

__all__ = ["ReferenceWork", "WorkingReference"]


@dataclass(frozen=True, eq=False)
class WorkingReference:
    """The reference at one working resolution, and what a call makes of it.

    Attributes
    ----------
    reference : OccupancyMap
        The reference at the working resolution.
    to_reference : RigidTransform
        Its cells -> the cells of the reference as given.
    """

    reference: OccupancyMap
    to_reference: RigidTransform
    _symmetries: dict[tuple[int, float], list[RigidTransform]] = field(
        default_factory=dict, repr=False
    )

    @cached_property
    def index(self) -> ReferenceIndex:
        """:attr:`reference`, indexed (made when first asked for)."""
        return ReferenceIndex.build(self.reference)

    @property
    def upsampling(self) -> float:
        """Working cells per cell of the reference as given (1 unless it was upsampled)."""
        return 1.0 / self.to_reference.scale

    def symmetries(
        self, key: tuple[int, float], make: Callable[[], list[RigidTransform]]
    ) -> list[RigidTransform]:
        """The reference's symmetries for the settings ``key`` (``(max_candidates,
        threshold)``, what :func:`~brokenness.measure.symmetry.symmetries` reads of them):
        ``make()`` the first time, the same list after."""
        if key not in self._symmetries:
            self._symmetries[key] = make()
        return self._symmetries[key]


@dataclass(eq=False)
class ReferenceWork:
    """What one call makes of its reference alone, for every frame it measures the map in.

    Parameters
    ----------
    reference : OccupancyMap
        The reference as given.
    """

    reference: OccupancyMap
    _at: dict[float | None, WorkingReference] = field(default_factory=dict, repr=False)

    @cached_property
    def wall_thickness(self) -> int:
        """The thickness, in its own cells, at which :attr:`reference` draws its walls
        (:func:`~brokenness.measure.walls.wall_thickness`; made when first asked for)."""
        return wall_thickness(cell_points(self.reference.occupied))

    def at(self, resolution: float | None) -> WorkingReference:
        """The reference at ``resolution`` (metres per cell; ``None``: as given).

        A finer resolution than the reference's upsamples it
        (:func:`~brokenness.io.resample.resample_to_resolution`); the same resolution, or
        ``None``, keeps it as it is. Made once per resolution.
        """
        key = None if resolution is None or self._own(resolution) else resolution
        if key not in self._at:
            if key is None:
                working, to_reference = self.reference, RigidTransform.identity()
            else:
                from ..io.resample import cell_scale_offset, resample_to_resolution

                working = resample_to_resolution(self.reference, key)
                s, tx, ty = cell_scale_offset(self.reference, working)
                to_reference = RigidTransform(0.0, tx, ty, s).inverse()
            self._at[key] = WorkingReference(working, to_reference)
        return self._at[key]

    def _own(self, resolution: float) -> bool:
        own = self.reference.resolution
        return own is None or math.isclose(resolution, own, rel_tol=1e-9)
