"""Brokenness by recursive registration and masking (Birk 2010, Algorithm 1).

The recursion, for a map M and a reference R::

    T = occupied cells of M
    repeat:
        register T with R                      -> ranked candidate transforms
        refine each candidate (ICP), keep the one under which most cells of T agree
        L = cells of T that agree with R       (Psi_2: Manhattan distance to an occupied
                                                 reference cell <= threshold)
        stop if L is not significant           (see "Stopping rule" below)
        if L agrees with an earlier partition's transform (loosely), add it there;
        else count L as a new partition
        T = T \\ L;  R = R \\ (reference cells matched by L)

Stopping rule ("nothing significant is left")
---------------------------------------------
A candidate set L of ``k`` agreeing cells, out of the ``n`` cells left in T, becomes a
partition only if all of these hold:

1. ``k >= min_partition_cells`` and ``k >= min_partition_fraction * N`` (N = occupied
   cells of the map): too small a part is noise, not a structural error;
2. ``k`` is far above chance: a cell dropped at random on the known reference area agrees
   with probability ``p0`` (the share of known reference cells within ``threshold`` of a
   wall), so noise alone gives ``k ~ Binomial(n, p0)``; we ask
   ``k >= n p0 + z sqrt(n p0 (1 - p0))`` with ``z = significance`` (default 6, which also
   covers the maximisation over transforms done by the registration).

Otherwise the recursion stops and the cells left in T are *unassigned* (reported as such,
label :data:`~brokenness.measure.result.UNASSIGNED`). A set that passes but whose cells
agree, within ``merge_threshold``, with the transform of a partition already found is not
"off" relative to it (thickened walls, jitter): it is merged into that partition and not
counted.

We register the untransformed remainder of the map in each step, so the transform found is
already the whole transform from the original map to the reference (the composition of the
paper's per-step transforms), without resampling T again and again.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import MapError, ParameterError
from ..grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from ..masking import ReferenceIndex, cell_points, manhattan_distance_map, unmatched_reference
from ..masking.distance import lookup_distance
from ..registration.base import Candidate, Registrar
from ..registration.methods import make_registrar
from ..transform import RigidTransform
from .refine import polish_transform, refine_transform, soft_agreement, sweep_rotation
from .result import NOT_OCCUPIED, UNASSIGNED, BrokennessResult, Partition

__all__ = ["compute_brokenness"]

MapLike = OccupancyMap | ArrayLike | str | os.PathLike[str]

#: Candidates (by raw agreement) that get the full refinement in each step.
_REFINED_CANDIDATES = 2
#: At most this many cells (an even stride of them) score the hypotheses of a step.
_SAMPLE_CELLS = 4000
#: A reference with at most this share of isolated occupied cells has connected walls.
_ISOLATED_SHARE = 0.05
#: iFMI options of the recursion, under the user's: a remainder mixes partitions, so more
#: rotation peaks are worth examining than for a single registration.
_IFMI_RECURSION_OPTIONS = {"rotation_peaks": 3, "peak_ratio": 0.3}


@dataclass(frozen=True)
class _Found:
    """A partition as the recursion finds it (before sorting by size)."""

    transform: RigidTransform
    members: NDArray[np.intp]  # indices into the map's occupied points
    confidence: float
    seconds: float


def _as_map(value: MapLike, role: str) -> OccupancyMap:
    if isinstance(value, OccupancyMap):
        return value
    if isinstance(value, str | os.PathLike):
        from ..io import load_map

        return load_map(value)
    try:
        return OccupancyMap.from_array(value)
    except MapError as exc:
        raise MapError(f"{role}: {exc}") from None


def _withdraw(
    states: NDArray[np.int8], withdrawn: NDArray[np.bool_], keep: NDArray[np.bool_]
) -> NDArray[np.int8]:
    """Cell states with ``withdrawn`` occupied cells, and the free cells nearer to them than
    to any ``keep`` occupied cell, set to unknown."""
    out = states.copy()
    out[withdrawn] = UNKNOWN
    if withdrawn.any():
        nearer = manhattan_distance_map(withdrawn) < manhattan_distance_map(keep)
        out[(states == FREE) & nearer] = UNKNOWN
    return out


def _check_options(
    threshold: float,
    min_partition_fraction: float,
    min_partition_cells: int,
    significance: float,
    merge_threshold: float,
    max_partitions: int,
) -> None:
    if not (math.isfinite(threshold) and threshold > 0):
        raise ParameterError(f"threshold must be a positive number of cells, got {threshold!r}")
    if not (0.0 <= min_partition_fraction < 1.0):
        raise ParameterError(
            f"min_partition_fraction must be in [0, 1), got {min_partition_fraction!r}"
        )
    if min_partition_cells < 1:
        raise ParameterError(f"min_partition_cells must be >= 1, got {min_partition_cells!r}")
    if not (math.isfinite(significance) and significance >= 0):
        raise ParameterError(f"significance must be >= 0, got {significance!r}")
    if not (math.isfinite(merge_threshold) and merge_threshold >= threshold):
        raise ParameterError("merge_threshold must be at least threshold")
    if max_partitions < 1:
        raise ParameterError(f"max_partitions must be >= 1, got {max_partitions!r}")


def compute_brokenness(
    map: MapLike,  # noqa: A002 - the paper's name
    reference: MapLike,
    *,
    method: str = "ifmi",
    threshold: float = 2.0,
    min_partition_fraction: float = 0.02,
    min_partition_cells: int = 30,
    significance: float = 6.0,
    merge_threshold: float | None = None,
    max_partitions: int = 16,
    max_candidates: int = 6,
    seed: int | None = None,
    registration_options: dict[str, Any] | None = None,
) -> BrokennessResult:
    """Degree of brokenness of ``map`` with respect to ``reference`` (Birk 2010, Algorithm 1).

    The map is split, greedily and largest first, into partitions that each agree with the
    reference under their own rigid transform; the degree is the number of partitions minus
    one. Each step registers what is left of the map with the reference, masks out the cells
    that then agree with it (Manhattan distance to an occupied reference cell at most
    ``threshold``), and repeats until nothing significant is left (see the module docstring
    for the stopping rule).

    Parameters
    ----------
    map : OccupancyMap, array_like or path
        The map under test. Arrays go through :meth:`OccupancyMap.from_array`, paths through
        :func:`brokenness.load_map`.
    reference : OccupancyMap, array_like or path
        The reference (ground truth). If both maps know their resolution and the two differ,
        the map is resampled to the reference's resolution first.
    method : {"ifmi", "random-walk"}
        Registration used in each step: the deterministic improved Fourier-Mellin method of the
        paper, or the stochastic map-merging baseline (Birk & Carpin 2006).
    threshold : float
        ``c`` of Psi_2, in reference cells: a moved map cell agrees with the reference when
        the Manhattan distance to the nearest occupied reference cell is at most ``c``.
        Default 2 (e.g. 10 cm at 5 cm per cell), enough for wall thickness and jitter.
    min_partition_fraction : float
        Smallest partition, as a share of the map's occupied cells (default 2 %).
    min_partition_cells : int
        Smallest partition, in cells (default 30).
    significance : float
        ``z`` of the chance test of the stopping rule (default 6).
    merge_threshold : float, optional
        Loose agreement used to merge a new set into an earlier partition (default
        ``2 * threshold``): if at least half of the new set agrees within this distance under
        an earlier partition's transform, it belongs to that partition.
    max_partitions : int
        Upper bound on the number of partitions (default 16): the recursion always ends.
    max_candidates : int
        Registration hypotheses examined per step (default 6).
    seed : int, optional
        Seed of the random-walk registration (iFMI uses no randomness).
    registration_options : dict, optional
        Keyword options of the registration method (see :func:`brokenness.register`). For
        iFMI the recursion defaults to ``rotation_peaks=3, peak_ratio=0.3`` (a remainder mixes
        partitions, so its angle spectrum has more than one peak worth trying).

    Returns
    -------
    BrokennessResult
        ``degree``, ``partitions`` (largest first, each with the whole transform from the
        original map to the reference), ``labels`` image, unassigned cells, timings.

    Raises
    ------
    MapError
        If either map has no occupied cell or cannot be read.
    ParameterError
        For options out of range.

    References
    ----------
    .. [1] A. Birk, "Using Recursive Spectral Registrations to Determine Brokenness as
       Measure of Structural Map Errors", ICRA 2010.

    Examples
    --------
    >>> import numpy as np
    >>> from brokenness import compute_brokenness
    >>> room = np.zeros((120, 160), bool)
    >>> room[20, 20:140] = room[100, 20:140] = room[20:101, 20] = room[20:101, 140] = True
    >>> room[20:60, 80] = room[60, 50:80] = True
    >>> compute_brokenness(room, room).degree
    0
    """
    started = time.perf_counter()
    if merge_threshold is None:
        merge_threshold = 2.0 * threshold
    _check_options(
        threshold,
        min_partition_fraction,
        min_partition_cells,
        significance,
        merge_threshold,
        max_partitions,
    )
    original = _as_map(map, "map")
    ref = _as_map(reference, "reference")
    if original.n_occupied == 0:
        raise MapError("the map has no occupied cell: nothing to measure")
    index = ReferenceIndex.build(ref)  # raises for an empty reference

    working, to_working = _common_resolution(original, ref)
    options = dict(_IFMI_RECURSION_OPTIONS) if method == "ifmi" else {}
    options.update(registration_options or {})
    registrar = make_registrar(method, seed=seed, **options)

    points = cell_points(working.occupied)  # (N, 2), row-major order
    n_total = points.shape[0]
    min_cells = max(min_partition_cells, math.ceil(min_partition_fraction * n_total))
    found = _recurse(
        working,
        points,
        index,
        registrar,
        threshold=threshold,
        min_cells=min_cells,
        significance=significance,
        merge_threshold=merge_threshold,
        max_partitions=max_partitions,
        max_candidates=max_candidates,
    )
    found = _reassign(found, points, index, threshold, min_cells)
    partitions, labels_working = _assemble(found, points, working, to_working, original, ref, index)
    labels = _labels_in_original_grid(labels_working, working, to_working, original)
    n_occupied = original.n_occupied
    assigned = int(np.count_nonzero(labels >= 0))
    # Partition sizes and fractions are counted in the original map's cells.
    partitions = tuple(
        Partition(
            index=p.index,
            cells=int(np.count_nonzero(labels == p.index)),
            fraction=float(np.count_nonzero(labels == p.index)) / n_occupied,
            transform=p.transform,
            confidence=p.confidence,
            rotation_offset_deg=p.rotation_offset_deg,
            displacement=p.displacement,
            displacement_m=p.displacement_m,
            step_seconds=p.step_seconds,
        )
        for p in partitions
    )
    parameters = {
        "threshold": threshold,
        "min_partition_fraction": min_partition_fraction,
        "min_partition_cells": min_partition_cells,
        "significance": significance,
        "merge_threshold": merge_threshold,
        "max_partitions": max_partitions,
        "max_candidates": max_candidates,
        "seed": seed,
        "registration_options": dict(registration_options or {}),
        "working_resolution": working.resolution,
    }
    return BrokennessResult(
        degree=max(len(partitions) - 1, 0),
        partitions=partitions,
        labels=labels,
        occupied_cells=n_occupied,
        unassigned_cells=n_occupied - assigned,
        method=method,
        parameters=parameters,
        seconds=time.perf_counter() - started,
    )


def _common_resolution(m: OccupancyMap, ref: OccupancyMap) -> tuple[OccupancyMap, RigidTransform]:
    """The map at the reference's resolution, and the transform original -> working cells."""
    if (
        m.resolution is None
        or ref.resolution is None
        or math.isclose(m.resolution, ref.resolution, rel_tol=1e-9)
    ):
        return m, RigidTransform.identity()
    from ..io.resample import cell_scale_offset, resample_to_resolution

    working = resample_to_resolution(m, ref.resolution)
    s, tx, ty = cell_scale_offset(m, working)
    return working, RigidTransform(0.0, tx, ty, s)


def _recurse(
    working: OccupancyMap,
    points: NDArray[np.float64],
    index: ReferenceIndex,
    registrar: Registrar,
    *,
    threshold: float,
    min_cells: int,
    significance: float,
    merge_threshold: float,
    max_partitions: int,
    max_candidates: int,
) -> list[_Found]:
    """Algorithm 1: the partitions in the order found (members index ``points``)."""
    n_total = points.shape[0]
    remaining = np.ones(n_total, dtype=bool)
    reference_occupied = index.reference.occupied
    p0 = index.chance_agreement(threshold)
    uses_free = bool(getattr(registrar, "uses_free_space", True))
    # If the reference's walls are connected lines (few isolated occupied cells), isolated
    # cells of the map are noise and are hidden from the registration; if the reference
    # itself is dotted (a sparse probabilistic map), they are structure and stay.
    ref_occ = index.reference.occupied
    walls_connected = np.count_nonzero(_isolated(ref_occ)) <= _ISOLATED_SHARE * np.count_nonzero(
        ref_occ
    )
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    found: list[_Found] = []
    carried: list[Candidate] = []
    steps = 0
    while np.count_nonzero(remaining) >= min_cells and len(found) < max_partitions:
        steps += 1
        if steps > 2 * max_partitions:  # merges do not count; bound them too
            break
        t0 = time.perf_counter()
        moving_states = _remainder_states(
            working, rows, cols, remaining, uses_free, walls_connected
        )
        if np.count_nonzero(moving_states == OCCUPIED) < min_cells:
            break  # what is left is scattered noise: nothing to register
        reference_states = _reference_states(index.reference, reference_occupied, uses_free)
        prepared = registrar.prepare_reference(reference_states)
        fresh = registrar.candidates(prepared, moving_states, max_candidates)
        # The hypotheses of the previous step stay in the running: a part seen there, beside
        # the larger one that won, is often registered better than from what is left alone.
        left = np.flatnonzero(remaining)
        best = _best_candidate([*fresh, *carried], points[left], index, threshold)
        carried = fresh
        if best is None:
            break
        transform, agree, _confidence = best
        k, n = int(np.count_nonzero(agree)), left.size
        chance = n * p0
        if k < min_cells or k < chance + significance * math.sqrt(chance * (1.0 - p0)):
            break
        members = left[_with_fringe(transform, points[left], agree, index, merge_threshold)]
        moved = transform.apply(points[members])
        # Merge into an earlier partition whose transform explains this set as well.
        target = _merge_target(found, points[members], index, merge_threshold)
        remaining[members] = False
        reference_occupied = unmatched_reference(reference_occupied, moved, threshold)
        elapsed = time.perf_counter() - t0
        excess = (k - chance) / k
        if target is not None:
            f = found[target]
            found[target] = _Found(
                f.transform, np.concatenate([f.members, members]), f.confidence, f.seconds + elapsed
            )
        else:
            found.append(_Found(transform, members, float(excess), elapsed))
        if not reference_occupied.any():
            break
    return found


def _remainder_states(
    working: OccupancyMap,
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    remaining: NDArray[np.bool_],
    uses_free: bool,
    drop_isolated: bool,
) -> NDArray[np.int8]:
    """The map T of the recursion, as the registration sees it.

    Masked occupied cells (and, for methods that use it, their free space) are withdrawn.
    With ``drop_isolated``, so are *isolated* occupied cells (no other occupied cell within
    two cells): salt-and-pepper noise, whose flat spectrum would drown the walls of a small
    remainder. They are hidden from the registration only; the masking still counts them.
    """
    withdrawn = np.zeros(working.shape, dtype=bool)
    withdrawn[rows[~remaining], cols[~remaining]] = True
    left = working.occupied & ~withdrawn
    out = working.states.copy() if not uses_free else _withdraw(working.states, withdrawn, left)
    out[withdrawn] = UNKNOWN
    if drop_isolated:
        out[left & _isolated(left)] = UNKNOWN
    return out


def _isolated(occupied: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Occupied cells with no other occupied cell in their 5x5 neighbourhood."""
    count = cv2.boxFilter(
        occupied.astype(np.uint8),
        cv2.CV_16U,
        (5, 5),
        normalize=False,
        borderType=cv2.BORDER_CONSTANT,
    )
    return occupied & (count == 1)


def _reference_states(
    reference: OccupancyMap, available: NDArray[np.bool_], uses_free: bool
) -> NDArray[np.int8]:
    """The reference with the cells matched by earlier partitions withdrawn."""
    withdrawn = reference.occupied & ~available
    if not uses_free:
        out = reference.states.copy()
        out[withdrawn] = UNKNOWN
        return out
    return _withdraw(reference.states, withdrawn, available)


def _best_candidate(
    candidates: list[Any],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
) -> tuple[RigidTransform, NDArray[np.bool_], float] | None:
    """Refine the most promising candidates; keep the one that aligns the most cells best.

    Candidates are ranked by the smooth agreement score (:func:`soft_agreement`), which
    rewards exact alignment over loose agreement: a transform that gains a few cells of
    another partition by tilting the main one a little must not win.
    """

    def soft(moved: NDArray[np.float64]) -> float:
        return soft_agreement(index.occupied_distance, moved, threshold)

    def hard(moved: NDArray[np.float64]) -> NDArray[np.bool_]:
        return index.occupied_agreement(moved, threshold)

    # Hypotheses are scored on an evenly strided sample of the cells (deterministic).
    sample = points[:: max(1, -(-points.shape[0] // _SAMPLE_CELLS))]
    # Rigid hypotheses only (a registration's matrix algebra may leave the scale at 1 +- 1e-15).
    rigid = [
        Candidate(
            RigidTransform(c.transform.rotation, c.transform.tx, c.transform.ty), c.confidence
        )
        for c in candidates
        if abs(c.transform.scale - 1.0) < 1e-6
    ]
    raw = [(soft(c.transform.apply(sample)), i, c) for i, c in enumerate(rigid)]
    raw.sort(key=lambda item: (-item[0], item[1]))
    best: tuple[RigidTransform, float] | None = None
    best_score = -1.0
    # Refine the best hypothesis, and the runner-up only when it scored comparably.
    contenders = [c for value, _, c in raw[:_REFINED_CANDIDATES] if value >= 0.5 * raw[0][0]]
    for cand in contenders:
        moved = cand.transform.apply(sample)
        agree = hard(moved)
        if not agree.any():
            continue
        swept = sweep_rotation(cand.transform, sample, soft, moved[agree].mean(axis=0))
        fitted = refine_transform(swept, sample, index.nearest_points, gate=threshold + 1.0)
        polished = polish_transform(
            fitted, sample[hard(fitted.apply(sample))], index.occupied_distance, threshold
        )
        for option in (polished, fitted, swept, cand.transform):
            value = soft(option.apply(sample))
            if value > best_score:
                best_score = value
                best = (option, float(cand.confidence))
    if best is None:
        return None
    return best[0], hard(best[0].apply(points)), best[1]


def _with_fringe(
    transform: RigidTransform,
    pts: NDArray[np.float64],
    agree: NDArray[np.bool_],
    index: ReferenceIndex,
    loose: float,
) -> NDArray[np.bool_]:
    """``agree`` plus the cells that agree loosely and touch it in the map (8-connected).

    Thick walls, clutter and a residual error of a fraction of a cell leave a fringe of
    cells just beyond the threshold around a partition. Left behind, such a fringe could later
    pass for a partition of its own; it belongs to the partition it touches.
    """
    near = lookup_distance(index.occupied_distance, transform.apply(pts)) <= loose
    if np.array_equal(near, agree):
        return agree
    cols = pts[:, 0].astype(np.intp)
    rows = pts[:, 1].astype(np.intp)
    c0, r0 = cols.min(), rows.min()
    grid = np.zeros((rows.max() - r0 + 1, cols.max() - c0 + 1), np.uint8)
    grid[rows[near] - r0, cols[near] - c0] = 1
    _, comp = cv2.connectedComponents(grid, connectivity=8)
    seeds = np.unique(comp[rows[agree] - r0, cols[agree] - c0])
    touched = np.isin(comp[rows - r0, cols - c0], seeds[seeds > 0])
    return agree | (near & touched)


def _merge_target(
    found: list[_Found], pts: NDArray[np.float64], index: ReferenceIndex, merge_threshold: float
) -> int | None:
    """Index of the earlier partition whose transform loosely explains ``pts``, if any.

    Under that transform, at least half of the cells that chance would not put within
    ``merge_threshold`` of a reference wall must land there: ``(share - q) / (1 - q) >= 0.5``
    with ``q`` the chance agreement at ``merge_threshold`` (in a dense map a loose threshold
    is met by many cells of a part that is really off).
    """
    q = index.chance_agreement(merge_threshold)
    best, best_excess = None, 0.5
    for i, f in enumerate(found):
        d = lookup_distance(index.occupied_distance, f.transform.apply(pts))
        share = float(np.count_nonzero(d <= merge_threshold)) / max(pts.shape[0], 1)
        excess = (share - q) / (1.0 - q) if q < 1.0 else 0.0
        if excess >= best_excess:
            best, best_excess = i, excess
    return best


def _reassign(
    found: list[_Found],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    min_cells: int,
) -> list[_Found]:
    """Give each cell to the partition under whose transform it agrees *best*.

    The recursion is greedy: the first partition takes every cell that agrees with the
    reference under its transform, including cells of other parts that land near a wall by
    coincidence (common in maps of many similar rooms). Once all transforms are known, each
    agreeing cell goes to the partition that puts it closest to a reference wall; ties keep
    the greedy choice when it is among them, else the larger partition. Cells that agree under
    no transform stay unassigned. A partition left with fewer than ``min_cells`` cells is
    dropped and the assignment repeated without it.
    """
    if len(found) < 2:
        return found
    owner = np.full(points.shape[0], -1, dtype=np.intp)
    for j, f in enumerate(found):
        owner[f.members] = j
    kept = list(range(len(found)))
    while True:
        distances = np.stack(
            [
                lookup_distance(index.occupied_distance, found[j].transform.apply(points))
                for j in kept
            ]
        )
        best = distances.min(axis=0)
        tied = distances == best
        greedy = np.array([owner == j for j in kept])
        # the greedy owner if it is among the best, else the first (largest-found) best
        choice = np.where(
            (tied & greedy).any(axis=0), np.argmax(tied & greedy, axis=0), np.argmax(tied, axis=0)
        )
        assigned = np.where(best <= threshold, np.asarray(kept)[choice], -1)
        sizes = {j: int(np.count_nonzero(assigned == j)) for j in kept}
        small = [j for j in kept if sizes[j] < min_cells]
        if not small or len(kept) == 1:
            break
        kept = [j for j in kept if j not in small]
    return [
        _Found(
            found[j].transform, np.flatnonzero(assigned == j), found[j].confidence, found[j].seconds
        )
        for j in kept
        if sizes[j] > 0
    ]


def _assemble(
    found: list[_Found],
    points: NDArray[np.float64],
    working: OccupancyMap,
    to_working: RigidTransform,
    original: OccupancyMap,
    ref: OccupancyMap,
    index: ReferenceIndex,
) -> tuple[list[Partition], NDArray[np.int16]]:
    """Sort partitions by size, relate them to the largest, and draw the label image."""
    order = sorted(range(len(found)), key=lambda i: (-found[i].members.size, i))
    labels = np.full(working.shape, NOT_OCCUPIED, dtype=np.int16)
    labels[working.occupied] = UNASSIGNED
    partitions: list[Partition] = []
    if not found:
        return partitions, labels
    largest = found[order[0]].transform
    for new_index, i in enumerate(order):
        f = found[i]
        pts = points[f.members]
        labels[pts[:, 1].astype(np.intp), pts[:, 0].astype(np.intp)] = new_index
        offset = math.degrees(math.remainder(f.transform.rotation - largest.rotation, 2 * math.pi))
        displacement = float(f.transform.displacement(largest, pts).mean()) if new_index else 0.0
        whole = f.transform.compose(to_working).with_world(original, ref)
        partitions.append(
            Partition(
                index=new_index,
                cells=int(f.members.size),
                fraction=0.0,  # filled in by the caller, in original cells
                transform=whole,
                confidence=f.confidence,
                rotation_offset_deg=0.0 if new_index == 0 else offset,
                displacement=displacement,
                displacement_m=None if ref.resolution is None else displacement * ref.resolution,
                step_seconds=f.seconds,
            )
        )
    return partitions, labels


def _labels_in_original_grid(
    labels: NDArray[np.int16],
    working: OccupancyMap,
    to_working: RigidTransform,
    original: OccupancyMap,
) -> NDArray[np.int16]:
    """Carry the working-grid labels back to the original map's grid (nearest cell)."""
    if working is original:
        return labels
    out = np.full(original.shape, NOT_OCCUPIED, dtype=np.int16)
    occ = original.occupied
    pts = to_working.apply(cell_points(occ))
    h, w = labels.shape
    c = np.clip(np.rint(pts[:, 0]).astype(np.intp), 0, w - 1)
    r = np.clip(np.rint(pts[:, 1]).astype(np.intp), 0, h - 1)
    lab = labels[r, c]
    out[occ] = np.where(lab >= 0, lab, UNASSIGNED)
    return out
