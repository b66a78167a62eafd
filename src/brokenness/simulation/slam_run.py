"""A simulated SLAM run that publishes its map as it explores: a bump, later a repair.

What :func:`brokenness.timeline` is for. A robot explores a synthetic building
(:func:`~brokenness.simulation.synthetic.simulate_broken_map`, one bump); the "SLAM node"
publishes the map of all scans so far every ``publish_every`` scans. Until the bump the map
is right; from the bump on, everything it maps is rigidly off (degree 1 once enough of it
is mapped); from ``repair_scan`` on (a loop closure), the node re-optimises the whole pose
chain and publishes the map of every scan so far with the corrected poses (degree 0 again).
The map of every message is on one canvas (the broken map's), so the bag's maps differ only
in what they show.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import ParameterError
from ..grid import OccupancyMap
from .bumps import Bump
from .mapper import map_prefixes
from .synthetic import SimulatedMap, simulate_broken_map

__all__ = ["SlamRun", "simulate_slam_run"]


@dataclass(frozen=True, eq=False)
class SlamRun:
    """A run that publishes its map every ``publish_every`` scans (see the module docstring).

    Attributes
    ----------
    simulation : SimulatedMap
        The run with its one bump (``simulation.map``: the final map without a repair).
    reference : OccupancyMap
    bump : Bump
        The bump (its ``scan`` is the first scan drawn off).
    repair_scan : int or None
        From this scan on the published maps use the corrected poses.
    ends : tuple of int
        Scans in each published map (``[0, end)``).
    scan_period : float
        Seconds between scans; message ``j`` is stamped ``ends[j] * scan_period``.
    """

    simulation: SimulatedMap
    bump: Bump
    repair_scan: int | None
    ends: tuple[int, ...]
    scan_period: float

    @property
    def reference(self) -> OccupancyMap:
        """The reference (all scans, true poses)."""
        return self.simulation.reference

    @property
    def stamps_ns(self) -> tuple[int, ...]:
        """Bag time of each message, nanoseconds."""
        return tuple(int(round(e * self.scan_period * 1e9)) for e in self.ends)

    @property
    def break_message(self) -> int:
        """Index of the first message that shows scans drawn after the bump."""
        return next(i for i, e in enumerate(self.ends) if e > self.bump.scan)

    @property
    def repair_message(self) -> int | None:
        """Index of the first message with the corrected poses."""
        if self.repair_scan is None:
            return None
        return next(i for i, e in enumerate(self.ends) if e >= self.repair_scan)

    def maps(self) -> Iterator[tuple[int, OccupancyMap]]:
        """``(stamp_ns, map)`` of each message, lazily (the counts are accumulated)."""
        sim = self.simulation
        assert sim.run is not None and sim.estimated_poses is not None
        run = sim.run
        geometry: dict[str, Any] = {
            "max_range": run.laser.max_range,
            "resolution": float(sim.map.resolution or 0.05),
            "shape": sim.map.shape,
            "origin": sim.map.origin or (0.0, 0.0, 0.0),
        }
        cut = len(self.ends) if self.repair_scan is None else self.repair_message
        assert cut is not None
        stamps = self.stamps_ns
        broken = map_prefixes(
            sim.estimated_poses, run.ranges, run.angles, self.ends[:cut], **geometry
        )
        for j, m in enumerate(broken):
            yield stamps[j], m
        if cut < len(self.ends):
            fixed = map_prefixes(
                run.noisy_poses, run.ranges, run.angles, self.ends[cut:], **geometry
            )
            for j, m in enumerate(fixed, start=cut):
                yield stamps[j], m


def simulate_slam_run(
    *,
    seed: int = 0,
    bump_at: float = 0.5,
    repair_at: float | None = 0.8,
    rotation_deg: float = 20.0,
    shift_m: float = 0.5,
    publish_every: int = 10,
    scan_period: float = 0.5,
    size: float | tuple[float, float] = 15.0,
    resolution: float = 0.05,
) -> SlamRun:
    """A simulated run with one bump and, optionally, a repair (see the module docstring).

    Parameters
    ----------
    seed : int
        Building, route, noise.
    bump_at, repair_at : float
        Where in the run (share of its scans) the bump happens and the loop closure repairs
        the map (``None``: never).
    rotation_deg, shift_m : float
        The bump: a rotation about the robot and a shift (direction from the seed).
    publish_every : int
        Scans between two published maps (the last scan is always published).
    scan_period : float
        Seconds between scans.
    size, resolution
        Of the building, as for :func:`simulate_broken_map`.

    Returns
    -------
    SlamRun
    """
    if not (0.0 < bump_at < 1.0) or (repair_at is not None and not (bump_at < repair_at <= 1.0)):
        raise ParameterError("need 0 < bump_at < repair_at <= 1")
    if publish_every < 1:
        raise ParameterError(f"publish_every must be >= 1, got {publish_every!r}")
    probe = simulate_broken_map(seed=seed, size=size, resolution=resolution)
    n = int(probe.parameters["scans"])
    rng = np.random.default_rng([seed, 15])
    bump = Bump(
        scan=max(1, int(n * bump_at)),
        theta=math.radians(rotation_deg),
        d=float(shift_m),
        direction=float(rng.uniform(-math.pi, math.pi)),
    )
    sim = simulate_broken_map(seed=seed, bumps=[bump], size=size, resolution=resolution)
    ends: NDArray[np.int64] = np.arange(publish_every, n + 1, publish_every)
    if len(ends) == 0 or ends[-1] != n:
        ends = np.append(ends, n)
    repair = None if repair_at is None else min(n, max(bump.scan + 1, int(n * repair_at)))
    return SlamRun(
        simulation=sim,
        bump=sim.bumps[0],
        repair_scan=repair,
        ends=tuple(int(e) for e in ends),
        scan_period=float(scan_period),
    )
