"""The options of :func:`brokenness.compute_brokenness`, and the settings every stage reads.

:class:`BrokennessOptions` is what a user chooses (one frozen object, validated once);
:class:`Settings` is what the stages of the measure (recursion, recovery, the tests of the
partitions) read, derived once per map from the options, the map and the registration.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

from ..errors import ParameterError
from ..limits import check_candidates
from ..registration.methods import METHODS

__all__ = ["MAX_FRAMES", "BrokennessOptions", "Settings"]

#: The most grid frames a map can be measured in (:mod:`brokenness.measure.frames`).
MAX_FRAMES = 5


@dataclass(frozen=True)
class BrokennessOptions:
    """Options of :func:`brokenness.compute_brokenness` (all validated on construction).

    Attributes
    ----------
    method : {"ifmi", "random-walk"}
        Registration of each step: the deterministic improved Fourier-Mellin method of the
        paper, or the stochastic map-merging baseline (Birk & Carpin 2006).
    threshold : float
        ``c`` of Psi_2, in reference cells: a moved map cell agrees with the reference when
        the Manhattan distance to the nearest occupied reference cell is at most ``c``.
        Default 2 (10 cm at 5 cm per cell), enough for wall thickness and jitter. (With
        maps of two resolutions, in cells of the finer one. A map works with at least how
        far it draws a wall from where it is, beyond the reference's drawing of it: the
        side of one of its cells when it is coarser than the reference, more for walls
        drawn thicker than the reference's; the result's
        ``parameters["working_threshold"]``.)
    min_partition_fraction : float
        Smallest partition, as a share of the map's occupied cells (default 2 %).
    min_partition_cells : int
        Smallest partition, in cells (default 30).
    significance : float
        ``z`` of the chance test of the stopping rule (default 6).
    merge_threshold : float or None
        Loose agreement (cells) used to merge a new set into an earlier partition, and the
        fringe of a partition; ``None`` (default): ``2 * threshold``.
    max_partitions : int
        Upper bound on the number of partitions (default 16): the recursion always ends.
    max_candidates : int
        Registration hypotheses examined per step (default 12, at most
        :data:`~brokenness.limits.MAX_CANDIDATES`; the recovery's searches among suspect
        cells ask for twice as many). A search budget, not a test: the tests
        a hypothesis must pass do not depend on it. See the README ("The search breadth",
        under "How it is computed") for how it was chosen.
    seed : int or None
        Seed of the random-walk registration (iFMI uses no randomness).
    registration_options : mapping
        Keyword options of the registration method (see :func:`brokenness.register`); kept
        as a sorted tuple of ``(name, value)`` pairs, so that the options stay frozen.
    frames : int
        Grid frames of the map the measure may run in (default 1: the map's own): with
        ``k`` of them, a map measured in its own frame with a partition *in doubt* (its own
        free space does not show that it is in place: ``Partition.contradiction_bound``
        over :data:`~brokenness.measure.evidence.MAP_RATIO`) is also measured turned by a
        half turn, then a quarter turn each way, then shifted (the first ``k``; at most 5),
        and of the results measured at the own frame's degree, the one that leaves the
        fewest cells to no partition is kept (see :mod:`brokenness.measure.frames` and the
        README, "Frames"; the other frames never change the degree). Up to ``k`` times the
        time for such a map, and twice with ``k`` of 1 (README step 11: such a map is
        measured only if it is measured turned by a half turn too); a map whose partitions
        all show their place, or that is not measured in its own frame, costs one frame.
    """

    method: str = "ifmi"
    threshold: float = 2.0
    min_partition_fraction: float = 0.02
    min_partition_cells: int = 30
    significance: float = 6.0
    merge_threshold: float | None = None
    max_partitions: int = 16
    max_candidates: int = 12
    seed: int | None = None
    registration_options: Mapping[str, Any] | tuple[tuple[str, Any], ...] = ()
    frames: int = 1

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ParameterError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if not (_number(self.threshold) and self.threshold > 0):
            raise ParameterError(
                f"threshold must be a positive number of cells, got {self.threshold!r}"
            )
        if not (_number(self.min_partition_fraction) and 0.0 <= self.min_partition_fraction < 1):
            raise ParameterError(
                f"min_partition_fraction must be in [0, 1), got {self.min_partition_fraction!r}"
            )
        if not (_whole(self.min_partition_cells) and self.min_partition_cells >= 1):
            raise ParameterError(
                f"min_partition_cells must be an integer >= 1, got {self.min_partition_cells!r}"
            )
        if not (_number(self.significance) and self.significance >= 0):
            raise ParameterError(f"significance must be >= 0, got {self.significance!r}")
        loose = self.loose
        if not (_number(loose) and loose >= self.threshold):
            raise ParameterError("merge_threshold must be a number at least threshold")
        if not (_whole(self.max_partitions) and self.max_partitions >= 1):
            raise ParameterError(
                f"max_partitions must be an integer >= 1, got {self.max_partitions!r}"
            )
        check_candidates(self.max_candidates)  # in [1, MAX_CANDIDATES]
        if not (_whole(self.frames) and 1 <= self.frames <= MAX_FRAMES):
            raise ParameterError(
                f"frames must be an integer from 1 to {MAX_FRAMES}, got {self.frames!r}"
            )
        if self.seed is not None and not _whole(self.seed):
            raise ParameterError(f"seed must be an integer, got {self.seed!r}")
        given = self.registration_options
        try:
            items = dict(given.items() if isinstance(given, Mapping) else given)
        except (TypeError, ValueError):
            raise ParameterError(
                "registration_options must be a mapping of keyword options"
            ) from None
        if not all(isinstance(k, str) for k in items):
            raise ParameterError("registration_options must be keyed by option names")
        # frozen, as the options object is: a sorted tuple of pairs
        object.__setattr__(self, "registration_options", tuple(sorted(items.items())))

    @property
    def loose(self) -> float:
        """The merge threshold in effect (``2 * threshold`` unless given)."""
        return 2.0 * self.threshold if self.merge_threshold is None else self.merge_threshold

    def min_cells(self, n_occupied: int) -> int:
        """The smallest partition of a map of ``n_occupied`` occupied cells, in cells:
        ``max(min_partition_cells, ceil(min_partition_fraction * n_occupied))``."""
        return max(self.min_partition_cells, math.ceil(self.min_partition_fraction * n_occupied))

    @property
    def registration_kwargs(self) -> dict[str, Any]:
        """``registration_options`` as keyword arguments."""
        return dict(self.registration_options)

    def to_dict(self) -> dict[str, Any]:
        """The options as plain values (the merge threshold in effect), for the record."""
        record = {f.name: getattr(self, f.name) for f in fields(self)}
        record["merge_threshold"] = self.loose
        record["registration_options"] = self.registration_kwargs
        return record


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _whole(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


@dataclass(frozen=True)
class Settings:
    """What the stages of the measure read, fixed for one map.

    Attributes
    ----------
    threshold : float
        Agreement threshold ``c`` (cells).
    loose : float
        Loose agreement of the merge test and the fringe (cells).
    min_cells : int
        Smallest partition, in cells of this map:
        ``max(min_partition_cells, ceil(min_partition_fraction * N))``.
    significance : float
        ``z`` of the chance test.
    max_partitions, max_candidates : int
        Bounds of the recursion, and hypotheses examined per step.
    uses_free : bool
        The registration uses free space (then withdrawn walls take their free space along).
    drop_isolated : bool
        Isolated occupied cells are hidden from the registration (the reference's walls are
        connected lines).
    as_cells : bool
        The registration takes the cells left as
        :class:`~brokenness.registration.base.OccupiedCells` (built from those cells alone)
        instead of a grid of the map's size.
    """

    threshold: float
    loose: float
    min_cells: int
    significance: float
    max_partitions: int
    max_candidates: int
    uses_free: bool
    drop_isolated: bool
    as_cells: bool = False

    @classmethod
    def of(
        cls,
        options: BrokennessOptions,
        n_occupied: int,
        uses_free: bool,
        drop_isolated: bool,
        as_cells: bool = False,
    ) -> Settings:
        """The settings for a map of ``n_occupied`` occupied cells."""
        return cls(
            threshold=options.threshold,
            loose=options.loose,
            min_cells=options.min_cells(n_occupied),
            significance=options.significance,
            max_partitions=options.max_partitions,
            max_candidates=options.max_candidates,
            uses_free=uses_free,
            drop_isolated=drop_isolated,
            as_cells=as_cells,
        )

    def needed(self, n: int, p0: float) -> tuple[float, float, float]:
        """The stopping rule for ``n`` cells left and chance agreement ``p0``: the cells
        chance explains, their spread, and the agreeing cells a partition needs
        (``max(min_cells, n p0 + z sqrt(n p0 (1 - p0)))``)."""
        chance = n * p0
        spread = math.sqrt(chance * (1.0 - p0))
        return chance, spread, max(self.min_cells, chance + self.significance * spread)

    def for_tests(self, tests: int) -> Settings:
        """These settings for ``tests`` tests made at once, of which the best is kept: the
        significance whose one-sided normal tail is the stopping rule's divided among them
        (Bonferroni), so that chance passes any of them no more often than it passes one
        test at ``significance`` (for 1,000 tests at ``z = 6``, ``z = 7.04``)."""
        if tests <= 1:
            return self
        from statistics import NormalDist  # not at import: only the measure's last pass asks

        tail = 0.5 * math.erfc(self.significance / math.sqrt(2.0))  # 1 - Phi(z)
        return replace(self, significance=-NormalDist().inv_cdf(tail / tests))

    def beyond_chance(self, n: int, p0: float) -> int:
        """The fewest of ``n`` cells that must agree for chance (each cell agreeing with
        probability ``p0``) to make that many agree no more often than a normal variable
        exceeds ``z`` standard deviations: the smallest ``k`` with ``P(X >= k) <= 1 - Phi(z)``,
        ``X ~ Binomial(n, p0)`` (``n + 1`` if no ``k`` is that rare).

        The exact tail of :meth:`needed`'s ``n p0 + z sqrt(n p0 (1 - p0))`` without its
        smallest partition: the two agree within a few cells when ``n p0`` is large, but
        the binomial's tail is much heavier than the normal one when ``n p0`` is small (at
        ``z = 6``, 7 of 7 cells agreeing at ``p0 = 0.1`` happen 10^-7 of the time, 100 times
        the normal tail, though ``7 > n p0 + z sqrt(n p0 (1 - p0)) = 5.5``)."""
        if n <= 0:
            return 1
        from scipy import special  # not at import: the batch process loads no SciPy

        tail = 0.5 * math.erfc(self.significance / math.sqrt(2.0))  # 1 - Phi(z)
        low, high = 0, n + 1  # P(X >= low) > tail (low = 0: certain), high: rare enough
        while high - low > 1:
            k = (low + high) // 2
            if float(special.bdtrc(k - 1, n, p0)) <= tail:  # bdtrc(j) = P(X > j)
                high = k
            else:
                low = k
        return high
