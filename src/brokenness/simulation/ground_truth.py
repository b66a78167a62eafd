"""A broken map of a run and its ground truth: bumps, partitions, the honest expected degree.

:func:`break_run` maps a laser run (:mod:`.laser`, or a real log: :mod:`.carmen`) twice with
:func:`.mapper.scan_counts` -- with the true poses (the *reference*, :func:`reference_map`)
and with bumps (:mod:`.bumps`) composed onto the pose estimate (the *broken map*) -- and
derives the ground truth of every partition; :func:`draw_broken_map` draws the bumps of a
:class:`~.options.BumpOptions`, redrawing until a requested degree counts, and
:func:`broken_map_from_run` maps and judges given bumps.

Geometry
--------
Both maps have the same resolution. The reference covers the box of everything the laser can
see (a building, or a log's poses and hits) plus 0.5 m. Scans of segment ``j`` (between bump
``j`` and bump ``j + 1``; segment 0 before the first bump) were drawn with the estimated poses
``E_j o true pose``, so everything they see lies inside ``E_j(box)``: the broken map's canvas
is the bounding box of all ``E_j(box)`` plus 0.5 m (its lower-left corner on a multiple of
the resolution), so no scan falls off it. Without bumps the two canvases are identical.

Ground truth
------------
Partition ``j`` is the set of occupied broken-map cells that scans of segment ``j`` hit most
often (the ``labels`` image). Its true transform, in the convention of
:func:`brokenness.compute_brokenness` (broken-map cell -> reference cell), is
``W_ref^-1 o E_j^-1 o W_map`` with ``W`` each map's :meth:`~brokenness.OccupancyMap.
cell_to_world_matrix`; its ``world`` part is ``E_j^-1``.

The expected degree (the honest rule)
-------------------------------------
Partitions are examined largest first. A partition *counts* when

1. it holds at least ``max(min_partition_fraction * N, min_partition_cells)`` cells (N =
   occupied cells of the broken map; defaults 2 % and 30, those of ``compute_brokenness``);
2. at least half of its cells agree with the reference under its own transform (Manhattan
   distance to an occupied reference cell <= ``threshold`` = 2 cells);
3. for every partition counted before it, its transform differs: the mean displacement of
   its cells between the two transforms exceeds ``merge_threshold`` (4 cells = 2 x 2, the
   default merge threshold of ``compute_brokenness``), *and* it is not explained by that
   transform either: the chance-corrected share of its cells agreeing within
   ``merge_threshold`` under the other transform, ``(s - q) / (1 - q)`` with ``q`` the
   reference's chance agreement, is below 0.5 (``compute_brokenness``'s merge rule; catches
   e.g. a shift along a featureless corridor).

The four numbers are a :class:`~.options.HonestRule`. ``expected_degree`` = counted
partitions - 1. A bump whose partition does not count is reported with ``counted = False`` and
the reason. Partition 0 (before the first bump) is judged like the others: after an early bump
it may be too small, and then the degree is the number of counted bumps minus one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import MapSizeError, ParameterError
from ..grid import OccupancyMap
from ..masking import ReferenceIndex, cell_points
from ..transform import RigidTransform
from .building import Building
from .bumps import Bump, BumpedPoses, apply_bumps
from .laser import LaserRun
from .mapper import counts_to_map, grid_geometry, scan_counts, segment_labels
from .options import BumpOptions, HonestRule

__all__ = [
    "NOT_OCCUPIED",
    "SimulatedMap",
    "SimulatedPartition",
    "break_run",
    "broken_map_from_run",
    "draw_broken_map",
    "reference_map",
]

#: Label of cells that are not occupied in the broken map.
NOT_OCCUPIED = -1
_CANVAS_MARGIN = 0.5  # metres around the box the laser sees (and around every E_j(box))


@dataclass(frozen=True)
class SimulatedPartition:
    """Ground truth of one partition: the cells drawn by scans ``[first_scan, end_scan)``.

    Attributes
    ----------
    index : int
        Segment index (0 before the first bump, ``j`` after bump ``j - 1``).
    first_scan, end_scan : int
    transform : RigidTransform
        Broken-map cell -> reference cell (``world``: broken-map metres -> reference metres).
    cells : int
        Occupied broken-map cells labelled with this partition.
    share : float
        ``cells`` / occupied cells of the broken map.
    agreement : float
        Share of its cells within ``threshold`` of an occupied reference cell when moved by
        ``transform``.
    counted : bool
    reason : str
        Why it counts or not.
    """

    index: int
    first_scan: int
    end_scan: int
    transform: RigidTransform
    cells: int
    share: float
    agreement: float
    counted: bool
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "index": self.index,
            "scans": [self.first_scan, self.end_scan],
            "transform": self.transform.to_dict(),
            "cells": self.cells,
            "share": self.share,
            "agreement": self.agreement,
            "counted": self.counted,
            "reason": self.reason,
        }


@dataclass(frozen=True, eq=False)
class SimulatedMap:
    """A broken map, its reference and the ground truth (see the module docstring).

    Attributes
    ----------
    map : OccupancyMap
        The broken map (mapped with the bumped pose estimate).
    reference : OccupancyMap
        The same run mapped with the true poses.
    expected_degree : int
    partitions : tuple of SimulatedPartition
        One per segment of the run, in scan order.
    labels : ndarray of int16
        Per broken-map cell, the partition that drew it; -1 where not occupied.
    bumps : tuple of Bump
        With ``counted`` / ``reason`` set (bump ``j`` starts partition ``j + 1``).
    seed : int
    parameters : dict
        Every parameter of the run (JSON-ready).
    building : Building
    run : LaserRun
    estimated_poses : ndarray, shape (N, 3)
        The bumped pose estimate the broken map was drawn with.
    """

    map: OccupancyMap
    reference: OccupancyMap
    expected_degree: int
    partitions: tuple[SimulatedPartition, ...]
    labels: NDArray[np.int16]
    bumps: tuple[Bump, ...]
    seed: int
    parameters: dict[str, Any] = field(default_factory=dict)
    building: Building | None = None
    run: LaserRun | None = None
    estimated_poses: NDArray[np.float64] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready ground truth (no arrays)."""
        return {
            "seed": self.seed,
            "parameters": self.parameters,
            "expected_degree": self.expected_degree,
            "bumps": [b.to_dict() for b in self.bumps],
            "partitions": [p.to_dict() for p in self.partitions],
            "occupied_cells": self.map.n_occupied,
            "map": {
                "shape": list(self.map.shape),
                "resolution": self.map.resolution,
                "origin": list(self.map.origin or ()),
            },
            "reference": {
                "shape": list(self.reference.shape),
                "resolution": self.reference.resolution,
                "origin": list(self.reference.origin or ()),
            },
        }


def _broken_canvas(
    errors: Sequence[NDArray[np.float64]],
    extent: tuple[float, float, float, float],
    poses: NDArray[np.float64],
    resolution: float,
) -> tuple[tuple[int, int], tuple[float, float, float]]:
    x0, y0, x1, y1 = extent
    corners = np.array([[x0, y0, 1.0], [x1, y0, 1.0], [x1, y1, 1.0], [x0, y1, 1.0]])
    pts = [(corners @ e.T)[:, :2] for e in errors] + [poses[:, :2]]
    try:
        return grid_geometry(np.concatenate(pts), resolution, margin=_CANVAS_MARGIN)
    except MapSizeError as exc:  # the shifts of many bumps add up
        raise MapSizeError(
            f"the broken map (its parts shifted apart by the bumps): {exc}; use a smaller bump "
            "radius or fewer bumps"
        ) from None


def _mapped(
    run: LaserRun,
    poses: NDArray[np.float64],
    resolution: float,
    shape: tuple[int, int],
    origin: tuple[float, float, float],
) -> OccupancyMap:
    """The run's scans drawn from ``poses`` on a grid (the mapper's default log-odds)."""
    counts = scan_counts(
        poses,
        run.ranges,
        run.angles,
        max_range=run.laser.max_range,
        resolution=resolution,
        shape=shape,
        origin=origin,
    )
    return counts_to_map(counts)


def _judge(
    transforms: list[RigidTransform],
    points: list[NDArray[np.float64]],
    n_occupied: int,
    index: ReferenceIndex,
    rule: HonestRule,
) -> tuple[list[float], list[bool], list[str]]:
    """The honest rule of the module docstring: agreement, counted, reason per partition."""
    threshold, merge_threshold = rule.threshold, rule.merge_threshold
    n = len(points)
    need = max(rule.min_partition_fraction * n_occupied, float(rule.min_partition_cells))
    q = index.chance_agreement(merge_threshold)
    agreement = [
        float(index.occupied_agreement(transforms[j].apply(points[j]), threshold).mean())
        if len(points[j])
        else 0.0
        for j in range(n)
    ]
    counted = [False] * n
    reason = [""] * n
    chosen: list[int] = []
    for j in sorted(range(n), key=lambda j: (-len(points[j]), j)):
        p = points[j]
        if len(p) < need:
            reason[j] = (
                f"too small: {len(p)} cells = {100 * len(p) / max(n_occupied, 1):.2f} % "
                f"of the occupied cells (< {need:.0f})"
            )
            continue
        if agreement[j] < 0.5:
            reason[j] = (
                f"only {100 * agreement[j]:.0f} % of its cells agree with the reference "
                "under its own transform"
            )
            continue
        why = ""
        for i in chosen:
            disp = float(transforms[j].displacement(transforms[i], p).mean())
            if disp <= merge_threshold:
                why = (
                    f"same transform as partition {i}: mean displacement {disp:.2f} cells "
                    f"(<= {merge_threshold:g})"
                )
                break
            s = float(index.occupied_agreement(transforms[i].apply(p), merge_threshold).mean())
            if q < 1.0 and (s - q) / (1.0 - q) >= 0.5:
                why = (
                    f"explained by partition {i}'s transform: {100 * s:.0f} % of its cells "
                    f"agree within {merge_threshold:g} cells under it (chance {100 * q:.0f} %)"
                )
                break
        if why:
            reason[j] = why
            continue
        counted[j] = True
        reason[j] = "largest partition" if not chosen else "distinct"
        chosen.append(j)
    return agreement, counted, reason


_Outcome = tuple[
    OccupancyMap,
    int,
    tuple[SimulatedPartition, ...],
    NDArray[np.int16],
    tuple[Bump, ...],
    BumpedPoses,
]


def broken_map_from_run(
    run: LaserRun,
    reference: OccupancyMap,
    bumps: Sequence[Bump],
    *,
    extent: tuple[float, float, float, float],
    index: ReferenceIndex | None = None,
    threshold: float = 2.0,
    merge_threshold: float = 4.0,
    min_partition_fraction: float = 0.02,
    min_partition_cells: int = 30,
) -> _Outcome:
    """Map a run with bumps composed onto its pose estimate; judge the partitions.

    Parameters
    ----------
    run : LaserRun
    reference : OccupancyMap
        The run mapped with the true poses.
    bumps : sequence of Bump
    extent : (x0, y0, x1, y1)
        World box (metres) that holds everything the laser can see.
    index : ReferenceIndex, optional
        Of ``reference`` (built if not given).
    threshold, merge_threshold, min_partition_fraction, min_partition_cells
        The honest rule (module docstring; :class:`~brokenness.simulation.options.HonestRule`).

    Returns
    -------
    tuple
        ``(map, expected_degree, partitions, labels, bumps with verdicts, bumped poses)``.
    """
    rule = HonestRule(threshold, merge_threshold, min_partition_fraction, min_partition_cells)
    return _map_with_bumps(run, reference, bumps, extent, index, rule)


def _map_with_bumps(
    run: LaserRun,
    reference: OccupancyMap,
    bumps: Sequence[Bump],
    extent: tuple[float, float, float, float],
    index: ReferenceIndex | None,
    rule: HonestRule,
) -> _Outcome:
    """:func:`broken_map_from_run` with the honest rule as one object."""
    res = reference.resolution
    if res is None:
        raise ParameterError("the reference needs a resolution")
    index = ReferenceIndex.build(reference) if index is None else index
    bp = apply_bumps(run.noisy_poses, bumps)
    shape, origin = _broken_canvas(bp.errors, extent, bp.poses, res)
    broken = _mapped(run, bp.poses, res, shape, origin)
    # label = the segment with the most hits in the cell (first one on ties)
    labels = segment_labels(
        bp.poses, run.ranges, run.angles, bp.segment, broken, max_range=run.laser.max_range
    )
    n_seg = len(bp.errors)
    w_map = broken.cell_to_world_matrix()
    w_ref_inv = np.linalg.inv(reference.cell_to_world_matrix())
    transforms = [
        RigidTransform.from_matrix(w_ref_inv @ np.linalg.inv(e) @ w_map).with_world(
            broken, reference
        )
        for e in bp.errors
    ]
    points = [cell_points(labels == j) for j in range(n_seg)]
    n_occ = broken.n_occupied
    agreement, counted, reason = _judge(transforms, points, n_occ, index, rule)
    firsts = [0] + [b.scan for b in bp.bumps]
    ends = firsts[1:] + [len(bp.poses)]
    parts = tuple(
        SimulatedPartition(
            j,
            firsts[j],
            ends[j],
            transforms[j],
            len(points[j]),
            len(points[j]) / max(n_occ, 1),
            agreement[j],
            counted[j],
            reason[j],
        )
        for j in range(n_seg)
    )
    judged = tuple(
        b.with_verdict(counted[j + 1], "" if counted[j + 1] else reason[j + 1])
        for j, b in enumerate(bp.bumps)
    )
    return broken, sum(counted) - 1, parts, labels, judged, bp


def draw_broken_map(
    run: LaserRun,
    reference: OccupancyMap,
    index: ReferenceIndex,
    extent: tuple[float, float, float, float],
    options: BumpOptions,
    *,
    hint: str,
) -> tuple[_Outcome, int]:
    """Draw bumps for a run and map it with them; with a ``degree``, redraw until it counts.

    Shared by synthetic runs and real logs. Draw ``k`` is :meth:`BumpOptions.draw
    <brokenness.simulation.options.BumpOptions.draw>` ``(n_scans, k)``, mapped and judged by
    :func:`broken_map_from_run` with ``options.rule``; in ``degree`` mode up to
    ``options.max_attempts`` draws are made until the honest expected degree equals it.

    Parameters
    ----------
    run : LaserRun
    reference : OccupancyMap
        The run mapped with the true poses (:func:`reference_map`).
    index : ReferenceIndex
        Of ``reference``.
    extent : (x0, y0, x1, y1)
        World box (metres) that holds everything the laser can see.
    options : BumpOptions
    hint : str
        What to try when the degree is not reached (the end of the error message).

    Returns
    -------
    (tuple, int)
        The outcome of :func:`broken_map_from_run` for the last draw, and the number of draws.

    Raises
    ------
    ParameterError
        If the bump radius exceeds the world's diagonal
        (:meth:`~brokenness.simulation.options.BumpOptions.check_radius`), no draw gives the
        requested degree (``hint`` says what to try), or no partition counts at all (too many
        bumps, or too coarse a map: the expected degree would be -1).
    """
    options.check_radius(extent)
    n_scans = len(run.true_poses)
    degree = options.degree
    seen: list[int] = []
    outcome = None
    for k in range(options.attempts):
        outcome = _map_with_bumps(
            run, reference, options.draw(n_scans, k), extent, index, options.rule
        )
        seen.append(outcome[1])
        if degree is None or outcome[1] == degree:
            break
    if outcome is not None and max(seen) < 0:
        _no_partition_counts(outcome, options.rule, len(seen))
    if outcome is None or (degree is not None and outcome[1] != degree):
        raise ParameterError(
            f"could not make a map of degree {degree} in {options.max_attempts} draws (got "
            f"degrees {sorted(set(seen))}); {hint}"
        )
    return outcome, len(seen)


def _no_partition_counts(outcome: _Outcome, rule: HonestRule, draws: int) -> None:
    """Raise: no partition of the broken map counts, so it has no expected degree."""
    broken, _expected, parts, *_ = outcome
    n = broken.n_occupied
    need = max(rule.min_partition_fraction * n, rule.min_partition_cells)
    largest = max((p.cells for p in parts), default=0)
    tries = "" if draws == 1 else f" in any of {draws} draws"
    raise ParameterError(
        f"no partition of the broken map counts{tries}, so it has no expected degree: one "
        f"counts with at least {need:.0f} cells, half of them agreeing with the reference, "
        f"and the largest has {largest} of the map's {n} occupied cells; use fewer bumps (a "
        "lower bump probability) or a finer resolution"
    )


def reference_map(
    run: LaserRun, extent: tuple[float, float, float, float], resolution: float
) -> OccupancyMap:
    """A run mapped with its true poses on the box ``extent`` plus 0.5 m (the reference).

    Parameters
    ----------
    run : LaserRun
    extent : (x0, y0, x1, y1)
        World box (metres) that holds everything the laser can see.
    resolution : float
        Metres per cell; the grid's lower-left corner lies on a multiple of it.

    Returns
    -------
    OccupancyMap
    """
    shape, origin = grid_geometry([extent[:2], extent[2:]], resolution, margin=_CANVAS_MARGIN)
    return _mapped(run, run.true_poses, resolution, shape, origin)


def break_run(
    run: LaserRun,
    extent: tuple[float, float, float, float],
    options: BumpOptions,
    *,
    resolution: float,
    hint: str,
    setting: Mapping[str, Any],
    extra: Mapping[str, Any] | None = None,
    building: Building | None = None,
    source: str | None = None,
) -> SimulatedMap:
    """The reference of a run, a broken map of it drawn with bumps, and the ground truth.

    The common part of :func:`~brokenness.simulation.synthetic.simulate_broken_map` and
    :func:`~brokenness.simulation.carmen.broken_log_map`: :func:`reference_map`, then
    :func:`draw_broken_map`.

    Parameters
    ----------
    run, extent, options, hint
        As for :func:`draw_broken_map`.
    resolution : float
        Metres per cell of both maps.
    setting : mapping
        The ``parameters`` entries that describe the run (building and laser, or log), put
        between the bump model's and the honest rule's.
    extra : mapping, optional
        Entries put last, after ``attempts``.
    building : Building, optional
    source : str, optional
        The ``source`` of both maps.

    Returns
    -------
    SimulatedMap
    """
    reference = replace(reference_map(run, extent, resolution), source=source)
    index = ReferenceIndex.build(reference)
    outcome, attempts = draw_broken_map(run, reference, index, extent, options, hint=hint)
    broken, expected, parts, labels, judged, bumped = outcome
    parameters: dict[str, Any] = {
        **options.parameters(),
        **setting,
        **options.rule.parameters(),
        "attempts": attempts,
        **(extra or {}),
    }
    return SimulatedMap(
        map=replace(broken, source=source),
        reference=reference,
        expected_degree=expected,
        partitions=parts,
        labels=labels,
        bumps=judged,
        seed=options.seed,
        parameters=parameters,
        building=building,
        run=run,
        estimated_poses=bumped.poses,
    )
