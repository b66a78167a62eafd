"""The result of :func:`brokenness.compute_brokenness`: degree, partitions, figures."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..transform import RigidTransform

__all__ = ["NOT_OCCUPIED", "UNASSIGNED", "BrokennessResult", "Partition"]

#: Label of a map cell that is not occupied (free or unknown) in ``BrokennessResult.labels``.
NOT_OCCUPIED: int = -1
#: Label of an occupied cell that belongs to no partition (noise, or too little to count).
UNASSIGNED: int = -2


@dataclass(frozen=True)
class Partition:
    """One part of the map that is consistent with the reference on its own (Birk's L^i).

    Attributes
    ----------
    index : int
        0 for the largest partition, then by decreasing size.
    cells : int
        Number of occupied map cells in the partition.
    fraction : float
        ``cells`` over the number of occupied cells of the map.
    transform : RigidTransform
        The whole transform from the original map to the reference for this partition
        (cells, and metres in ``.world`` when both maps have geometry).
    confidence : float
        Share of the partition's cells that chance does not explain, in [0, 1]:
        ``(k - n p0) / k`` for the ``k`` cells that agreed out of the ``n`` left, where ``p0``
        is the probability that a randomly placed cell agrees (see the stopping rule).
    rotation_offset_deg : float
        Rotation of this partition relative to the largest one, degrees (0 for the largest).
    displacement : float
        Mean distance, in reference cells, between where this partition's cells land under
        its own transform and under the largest partition's (0 for the largest): how far
        "off" it is.
    displacement_m : float or None
        The same in metres, when the reference resolution is known.
    step_seconds : float
        Time of the recursion step that found it (registration + masking).
    contradiction : float or None
        How often the map's free space of this partition lands on reference walls under its
        transform, over the rate of a random placement (0: never; 1: as often as chance;
        ``None``: too little free space to tell). See :mod:`brokenness.measure.evidence`.
    contradiction_bound : float or None
        Its upper bound at the stopping rule's significance (a Poisson bound on the
        contradicting cells over what chance would give; ``None``: no free space of this
        partition lands on the reference). Over
        :data:`~brokenness.measure.evidence.MAP_RATIO`, the partition's own free space does
        not show that it is in place (the whole map's must, for the degree to be measured),
        and the measure searches its place again (README, steps 8 and 9).
    acceptance : float or None
        Birk & Carpin's acceptance indicator ``agree / (agree + disagree)`` of the
        partition's cells under its transform (see
        :func:`brokenness.registration.random_walk.partition_acceptance`); reported for
        ``method="random-walk"``, ``None`` otherwise.
    """

    index: int
    cells: int
    fraction: float
    transform: RigidTransform
    confidence: float
    rotation_offset_deg: float
    displacement: float
    displacement_m: float | None
    step_seconds: float
    contradiction: float | None = None
    acceptance: float | None = None
    contradiction_bound: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "index": self.index,
            "cells": self.cells,
            "fraction": self.fraction,
            "transform": self.transform.to_dict(),
            "confidence": self.confidence,
            "rotation_offset_deg": self.rotation_offset_deg,
            "displacement_cells": self.displacement,
            "displacement_m": self.displacement_m,
            "step_seconds": self.step_seconds,
            "contradiction": self.contradiction,
            "contradiction_bound": self.contradiction_bound,
            "acceptance": self.acceptance,
        }


@dataclass(frozen=True, eq=False)
class BrokennessResult:
    """Degree of brokenness of a map with respect to a reference, and its partitions.

    Attributes
    ----------
    degree : int or None
        Number of partitions minus one (0 = not broken); ``None`` when the degree was not
        measured (see ``measured``).
    partitions : tuple of Partition
        Largest first.
    labels : ndarray of int16
        Same shape as the map: the partition index of each occupied cell,
        :data:`UNASSIGNED` (-2) for occupied cells in no partition and :data:`NOT_OCCUPIED`
        (-1) elsewhere.
    occupied_cells : int
        Occupied cells of the map.
    unassigned_cells : int
        Occupied cells that belong to no partition.
    method : str
        Registration method (``"ifmi"`` or ``"random-walk"``).
    parameters : dict
        Every option that shaped the result (threshold, stopping rule...), for the record.
    seconds : float
        Total wall-clock time.
    measured : bool
        False when the evidence does not show that the map is of the reference's place (no
        part of it agrees with the reference well enough to carry a partition): then
        ``degree`` is ``None`` and ``reason`` says why. Never a silent 0.
    reason : str or None
        Why the degree was not measured (``None`` when it was).
    contradiction : float or None
        The whole map's free-space contradiction over the chance rate, every clear free
        cell charged to the partition of its nearest wall (:mod:`brokenness.measure.evidence`);
        when its upper bound is above :data:`~brokenness.measure.evidence.MAP_RATIO` the map
        is not measured.
    contradiction_bound : float or None
        That upper bound (a Poisson bound on the contradicting cells at the stopping rule's
        significance, over what chance would give): the number the measured/not measured
        decision rests on. ``None`` when there are no partitions or too little free space
        to bound it.
    """

    degree: int | None
    partitions: tuple[Partition, ...]
    labels: NDArray[np.int16] = field(repr=False)
    occupied_cells: int
    unassigned_cells: int
    method: str
    parameters: dict[str, Any]
    seconds: float
    measured: bool = True
    reason: str | None = None
    contradiction: float | None = None
    contradiction_bound: float | None = None

    @property
    def unassigned_fraction(self) -> float:
        """Share of the occupied cells that belong to no partition."""
        return self.unassigned_cells / self.occupied_cells if self.occupied_cells else 0.0

    @property
    def largest_fraction(self) -> float:
        """Size of the largest partition as a share of the occupied cells (0 if none)."""
        return self.partitions[0].fraction if self.partitions else 0.0

    @property
    def step_seconds(self) -> tuple[float, ...]:
        """Time of each recursion step that produced a partition."""
        return tuple(p.step_seconds for p in self.partitions)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (without the label image)."""
        return {
            "measured": self.measured,
            "degree": self.degree,
            "reason": self.reason,
            "contradiction": self.contradiction,
            "contradiction_bound": self.contradiction_bound,
            "occupied_cells": self.occupied_cells,
            "unassigned_cells": self.unassigned_cells,
            "unassigned_fraction": self.unassigned_fraction,
            "largest_fraction": self.largest_fraction,
            "partitions": [p.to_dict() for p in self.partitions],
            "method": self.method,
            "parameters": dict(self.parameters),
            "seconds": self.seconds,
        }
