"""Broken maps of known degree: a synthetic building, a laser run, bump noise, ground truth.

:func:`simulate_broken_map` generates a building (:mod:`.building`), drives a laser robot
through it (:mod:`.laser`) and breaks the run with bump noise: :func:`.ground_truth.break_run`
maps it with the true poses (the *reference*, the building plus 0.5 m) and with the bumped
estimate (the *broken map*) and derives the ground truth of every partition and the honest
expected degree (see :mod:`.ground_truth` for the geometry and the rule).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Real

import numpy as np

from ..errors import ParameterError
from ..limits import (
    check_cells,
    check_resolution,
)
from .building import check_building_size, generate_building
from .bumps import Bump
from .ground_truth import NOT_OCCUPIED as NOT_OCCUPIED  # defined here before ground_truth
from .ground_truth import SimulatedMap, SimulatedPartition, break_run, broken_map_from_run
from .laser import Laser, simulate_run
from .options import BumpOptions, HonestRule

__all__ = ["SimulatedMap", "SimulatedPartition", "broken_map_from_run", "simulate_broken_map"]


def _check_world(width: float, height: float, resolution: float, options: BumpOptions) -> None:
    """The building's size, its cells and the bump radius, before anything is generated."""
    check_building_size(width, height)
    check_cells(height / resolution, width / resolution, f"a {width:g} m x {height:g} m map")
    options.check_radius((0.0, 0.0, width, height))


def _sides(size: object) -> tuple[float, float]:
    """The building's width and height from ``size``: one number, or a pair of numbers."""
    values = (size, size) if isinstance(size, Real) else size
    try:
        width, height = (float(v) for v in values)  # type: ignore[attr-defined]  # checked
    except (TypeError, ValueError):  # not a number or a pair of numbers
        raise ParameterError(
            f"size must be a number of metres or a pair (width, height), got {size!r}"
        ) from None
    return width, height


def _check_run(laser: object, spacing: object, pose_sigma: object) -> None:
    """The types of the run's keywords (their ranges are checked where the run is made)."""
    if not isinstance(laser, Laser):
        raise ParameterError(f"laser must be a Laser, got {laser!r}")
    pair = tuple(pose_sigma) if isinstance(pose_sigma, tuple | list) else ()
    numbers = (spacing, *pair)
    if len(pair) != 2 or not all(isinstance(v, Real) and not isinstance(v, bool) for v in numbers):
        raise ParameterError(
            f"spacing must be a number of metres and pose_sigma a pair of numbers (metres, "
            f"radians), got {spacing!r} and {pose_sigma!r}"
        )


def simulate_broken_map(
    *,
    seed: int = 0,
    degree: int | None = None,
    bumps: int | Sequence[Bump] | None = None,
    bump_probability: float | None = None,
    bump_radius: float = 1.0,
    max_rotation: float = 180.0,
    min_rotation: float = 10.0,
    size: float | tuple[float, float] = 15.0,
    resolution: float = 0.05,
    laser: Laser | None = None,
    spacing: float = 0.4,
    pose_sigma: tuple[float, float] = (0.01, math.radians(0.25)),
    threshold: float = 2.0,
    merge_threshold: float = 4.0,
    min_partition_fraction: float = 0.02,
    min_partition_cells: int = 30,
    max_attempts: int = 30,
) -> SimulatedMap:
    """A synthetic broken map of known (honest) degree, its reference and ground truth.

    Give at most one of ``degree``, ``bumps`` and ``bump_probability`` (none: no bumps, a
    degree-0 map whose only error is the small pose noise). The bump keywords and those of
    the honest rule are checked once, as a :class:`~brokenness.simulation.options.BumpOptions`,
    before any building is generated.

    Parameters
    ----------
    seed : int
        Everything (building, noise, bumps) follows from it: same seed and parameters, same
        maps bit for bit.
    degree : int, optional
        Make the honest expected degree exactly this: ``degree`` bumps at evenly spread
        fractions of the run (jittered), ``|theta|`` in ``[min_rotation, max_rotation]``;
        redrawn (deterministically from the seed) until the rule of the module docstring
        counts every one, at most ``max_attempts`` times.
    bumps : int or sequence of Bump, optional
        Exactly this many bumps (drawn once, the "k bumps" mode; the expected degree may be
        lower if some do not count), or these bumps.
    bump_probability : float, optional
        The paper's model: each scan bumps with this probability, ``theta ~ U[0, 2 pi)``
        (or ``U[-max_rotation, max_rotation]`` for ``max_rotation < 180``).
    bump_radius : float
        ``r``: shifts ``d ~ U[0, r]`` metres.
    max_rotation, min_rotation : float
        Degrees; ``min_rotation`` applies to ``degree`` and integer ``bumps`` only.
    size : float or (float, float)
        Building width and height, metres (15 m at 0.05 m/cell: about 300 x 300 cells).
    resolution : float
        Metres per cell of both maps (the building is rasterised at half of it), in
        [:data:`~brokenness.limits.MIN_RESOLUTION`, :data:`~brokenness.limits.MAX_RESOLUTION`].
    laser : Laser, optional
        Default :class:`~brokenness.simulation.laser.Laser` (181 beams over 270 deg, 8 m).
    spacing : float
        Metres driven between scans.
    pose_sigma : (float, float)
        Small Gaussian noise of the pose estimate per scan (metres, radians).
    threshold, merge_threshold, min_partition_fraction, min_partition_cells
        The honest rule (module docstring); defaults match ``compute_brokenness``.
    max_attempts : int
        Bound on redraws in ``degree`` mode.

    Returns
    -------
    SimulatedMap

    Raises
    ------
    ParameterError
        For invalid or conflicting options (a building side over
        :data:`~brokenness.simulation.building.MAX_BUILDING_SIDE`, a bump radius over the
        building's diagonal), when ``degree`` cannot be reached within ``max_attempts`` draws
        (try a larger building or fewer bumps), or when no partition counts (too many bumps
        or too coarse a map: the expected degree would be -1).
    MapSizeError
        If the maps would have more than :func:`brokenness.limits.max_cells` cells.

    Examples
    --------
    >>> sim = simulate_broken_map(seed=1, degree=2)
    >>> sim.expected_degree, sim.map.resolution == sim.reference.resolution
    (2, True)
    """
    options = BumpOptions(
        seed=seed,
        degree=degree,
        bumps=bumps,
        bump_probability=bump_probability,
        bump_radius=bump_radius,
        max_rotation=max_rotation,
        min_rotation=min_rotation,
        max_attempts=max_attempts,
        rule=HonestRule(threshold, merge_threshold, min_partition_fraction, min_partition_cells),
    )
    resolution = check_resolution(resolution)
    width, height = _sides(size)
    _check_world(width, height, resolution, options)
    laser = Laser() if laser is None else laser
    _check_run(laser, spacing, pose_sigma)
    building = generate_building(
        options.seed, width=float(width), height=float(height), truth_resolution=resolution / 2
    )
    run = simulate_run(
        building,
        laser=laser,
        spacing=spacing,
        pose_sigma=pose_sigma,
        rng=np.random.default_rng([options.seed, 1]),
    )
    setting = {
        "size_m": [float(width), float(height)],
        "resolution": resolution,
        "laser": {
            "beams": laser.beams,
            "fov_deg": laser.fov_deg,
            "max_range": laser.max_range,
            "range_sigma": laser.range_sigma,
        },
        "spacing": spacing,
        "pose_sigma": [pose_sigma[0], math.degrees(pose_sigma[1])],
    }
    return break_run(
        run,
        (0.0, 0.0, building.width, building.height),
        options,
        resolution=resolution,
        hint="use a larger building or a lower degree",
        setting=setting,
        extra={"scans": len(run.true_poses)},
        building=building,
    )
