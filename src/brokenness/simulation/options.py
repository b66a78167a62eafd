"""The options of a broken map: its bump model and the honest rule that judges its partitions.

:class:`BumpOptions` says how the bumps of a run are drawn (:mod:`.bumps`) and, through its
:class:`HonestRule`, when the partition a bump starts counts towards the expected degree (the
rule of :mod:`brokenness.simulation.ground_truth`). One object, checked once, is what
:func:`~brokenness.simulation.synthetic.simulate_broken_map` and
:func:`~brokenness.simulation.carmen.broken_log_map` build from their keywords and hand on.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from numbers import Real
from typing import Any

import numpy as np

from ..errors import ParameterError
from .bumps import Bump, draw_bumps, draw_k_bumps

__all__ = ["BumpOptions", "HonestRule"]


def _check_number(name: str, value: object) -> None:
    """Raise :class:`ParameterError` unless ``value`` is a real number (its range, NaN
    outside every one, is checked where it is used)."""
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ParameterError(f"{name} must be a number, got {value!r}")


def _bumps(bumps: Iterable[Any]) -> tuple[Bump, ...]:
    """The explicit bumps given (:class:`ParameterError` unless a sequence of :class:`Bump`)."""
    try:
        items = tuple(bumps)
    except TypeError:  # not a sequence at all
        items = (None,)
    if not all(isinstance(b, Bump) for b in items):
        raise ParameterError(
            f"bumps must be a number of bumps or a sequence of Bump, got {bumps!r}"
        )
    return items


@dataclass(frozen=True)
class HonestRule:
    """When a partition counts towards the expected degree (the honest rule).

    Defaults are those of :func:`brokenness.compute_brokenness`; see
    :mod:`brokenness.simulation.ground_truth` for the rule itself.

    Attributes
    ----------
    threshold : float
        Cells (Manhattan): a partition's cell agrees with the reference when moved by the
        partition's transform it lies this close to an occupied reference cell.
    merge_threshold : float
        Cells: two partitions whose transforms move a partition's cells by at most this much
        on average, or that explain each other within it, are one.
    min_partition_fraction : float
        A partition counts only with at least this share of the occupied cells ...
    min_partition_cells : int
        ... and at least this many cells.
    """

    threshold: float = 2.0
    merge_threshold: float = 4.0
    min_partition_fraction: float = 0.02
    min_partition_cells: int = 30

    def __post_init__(self) -> None:
        for name in ("threshold", "merge_threshold", "min_partition_fraction"):
            _check_number(name, getattr(self, name))
        cells = self.min_partition_cells
        if isinstance(cells, bool) or not isinstance(cells, int | np.integer) or cells < 1:
            raise ParameterError(f"min_partition_cells must be an integer >= 1, got {cells!r}")

    def parameters(self) -> dict[str, Any]:
        """JSON-ready entries of a simulation's ``parameters``."""
        return {
            "threshold": self.threshold,
            "merge_threshold": self.merge_threshold,
            "min_partition_fraction": self.min_partition_fraction,
            "min_partition_cells": self.min_partition_cells,
        }


@dataclass(frozen=True)
class BumpOptions:
    """How the bumps of a broken map are drawn, and how its partitions are judged.

    Give at most one of ``degree``, ``bumps`` and ``bump_probability`` (none: no bumps).

    Attributes
    ----------
    seed : int
        The bumps follow from it (attempt ``k`` draws with ``numpy.random.default_rng([seed,
        2, k])``).
    degree : int, optional
        Exactly this many bumps at evenly spread fractions of the run (jittered), ``|theta|``
        in ``[min_rotation, max_rotation]``, redrawn up to ``max_attempts`` times until the
        honest expected degree equals it.
    bumps : int or sequence of Bump, optional
        Exactly this many bumps (drawn once; the degree may come out lower), or these bumps
        (kept as a tuple).
    bump_probability : float, optional
        The paper's model: each scan bumps with this probability.
    bump_radius : float
        ``r``: shifts ``d ~ U[0, r]`` metres.
    max_rotation, min_rotation : float
        Degrees; ``min_rotation`` applies to ``degree`` and integer ``bumps`` only.
    max_attempts : int
        Bound on redraws in ``degree`` mode.
    rule : HonestRule
        When a partition counts.

    Raises
    ------
    ParameterError
        For conflicting modes, a negative or non-integer seed or degree, rotations outside
        ``0 <= min_rotation <= max_rotation <= 180``, or a non-positive ``max_attempts``. The
        bump radius and probability are checked when bumps are drawn (:mod:`.bumps`; the
        radius also against the world's size, :meth:`check_radius`).

    Examples
    --------
    >>> options = BumpOptions(seed=3, degree=2)
    >>> options.attempts, options.rule.threshold
    (30, 2.0)
    >>> len(options.draw(100, 0))
    2
    """

    seed: int = 0
    degree: int | None = None
    bumps: int | Sequence[Bump] | None = None
    bump_probability: float | None = None
    bump_radius: float = 1.0
    max_rotation: float = 180.0
    min_rotation: float = 10.0
    max_attempts: int = 30
    rule: HonestRule = field(default_factory=HonestRule)

    def __post_init__(self) -> None:
        for name in ("bump_radius", "max_rotation", "min_rotation"):
            _check_number(name, getattr(self, name))
        if self.bump_probability is not None:
            _check_number("bump_probability", self.bump_probability)
        if not isinstance(self.rule, HonestRule):
            raise ParameterError(f"rule must be a HonestRule, got {self.rule!r}")
        modes = sum(v is not None for v in (self.degree, self.bumps, self.bump_probability))
        if modes > 1:
            raise ParameterError("give at most one of degree, bumps and bump_probability")
        seed = self.seed
        if not isinstance(seed, int | np.integer) or isinstance(seed, bool) or seed < 0:
            raise ParameterError(f"seed must be a non-negative integer, got {seed!r}")
        degree = self.degree
        if degree is not None and not (isinstance(degree, int | np.integer) and degree >= 0):
            raise ParameterError(f"degree must be a non-negative integer, got {degree!r}")
        if not (0.0 <= self.min_rotation <= self.max_rotation <= 180.0):
            raise ParameterError("need 0 <= min_rotation <= max_rotation <= 180 degrees")
        if not (isinstance(self.max_attempts, int) and self.max_attempts >= 1):
            raise ParameterError("max_attempts must be a positive integer")
        # plain Python numbers from here on: numpy integers would reach ``parameters`` (and
        # make a simulation's JSON fail)
        object.__setattr__(self, "seed", int(seed))
        if degree is not None:
            object.__setattr__(self, "degree", int(degree))
        if isinstance(self.bumps, int | np.integer):
            object.__setattr__(self, "bumps", int(self.bumps))
        elif self.bumps is not None:
            object.__setattr__(self, "bumps", _bumps(self.bumps))

    @property
    def drawn(self) -> bool:
        """True when bumps are drawn (``degree``, a number of ``bumps`` or a probability)."""
        counted = isinstance(self.bumps, int)
        return counted or self.degree is not None or self.bump_probability is not None

    def check_radius(self, extent: tuple[float, float, float, float]) -> None:
        """Refuse a bump radius beyond the diagonal of the world box ``extent`` (metres).

        A longer shift moves a partition off the world it was mapped in entirely, and the
        broken map's canvas grows with it (up to the number of bumps times the radius).
        Checked only when bumps are drawn (:attr:`drawn`).

        Raises
        ------
        ParameterError
        """
        if not self.drawn:
            return
        x0, y0, x1, y1 = extent
        width, height = x1 - x0, y1 - y0
        diagonal = math.hypot(width, height)
        if not (0.0 <= self.bump_radius <= diagonal):
            raise ParameterError(
                f"bump radius must be in [0, {diagonal:.4g}] m, the diagonal of the simulated "
                f"world ({width:.4g} m x {height:.4g} m; a longer shift moves a partition off "
                f"it), got {self.bump_radius!r}"
            )

    @property
    def attempts(self) -> int:
        """How many draws at most: ``max_attempts`` in ``degree`` mode, else one."""
        return self.max_attempts if self.degree is not None else 1

    def draw(self, n_scans: int, attempt: int) -> list[Bump]:
        """The bumps of draw number ``attempt`` for a run of ``n_scans`` scans, sorted by scan.

        Parameters
        ----------
        n_scans : int
        attempt : int
            0 for the first draw; each number gives other bumps (deterministically).

        Returns
        -------
        list of Bump
        """
        rng = np.random.default_rng([self.seed, 2, attempt])
        max_rotation = math.radians(self.max_rotation)
        if self.bump_probability is not None:
            return draw_bumps(
                n_scans,
                float(self.bump_probability),
                radius=self.bump_radius,
                max_rotation=max_rotation,
                rng=rng,
            )
        count = self.degree if self.degree is not None else self.bumps
        if isinstance(count, int | np.integer):  # evenly spread for a degree, else anywhere
            return draw_k_bumps(
                n_scans,
                int(count),
                radius=self.bump_radius,
                max_rotation=max_rotation,
                min_rotation=math.radians(self.min_rotation),
                rng=rng,
                spread=self.degree is not None,
            )
        return list(self.bumps) if isinstance(self.bumps, Sequence) else []  # explicit, or none

    def parameters(self) -> dict[str, Any]:
        """JSON-ready entries of a simulation's ``parameters`` (without the rule's)."""
        bumps = self.bumps
        return {
            "seed": self.seed,
            "degree": self.degree,
            "bumps": bumps if bumps is None or isinstance(bumps, int | np.integer) else "explicit",
            "bump_probability": self.bump_probability,
            "bump_radius": self.bump_radius,
            "max_rotation_deg": self.max_rotation,
            "min_rotation_deg": self.min_rotation,
        }
