"""Brokenness by recursive registration and masking (Birk 2010, Algorithm 1).

The recursion, for a map M and a reference R::

    T = occupied cells of M
    repeat:
        register T with R, and with R'         -> ranked hypotheses (plus the previous
          (R less the walls already matched)      step's, which may fit what is left better)
        refine the best ones on the cells      (rotation sweep, trimmed ICP, compass search
                                                  on the agreement itself: measure.refine)
        L = cells of T that agree with R       (Psi_2: Manhattan distance to an occupied
                                                 reference cell <= threshold), plus the
                                                 fringe that agrees loosely and touches L
        stop if L is not significant           (see "Stopping rule" below)
        if L is explained by an earlier partition's transform, add it there;
        else count L as a new partition
        T = T \\ L;  R' = R' \\ (reference cells matched by L)
    give every cell to the partition whose transform aligns it best (measure.partitions)
    repeat:                                    (measure.recovery)
        S = cells of no partition, or whose partition's transform makes few cells around
            them agree (cells a partition took by coincidence)
        register S with R; count its best hypothesis as a new partition if the cells of
        S it explains coherently pass the stopping rule; reassign every cell
        (hypotheses too weak for a new partition are kept as rivals)
    join partitions that one of their transforms aligns as one piece (measure.partitions)
    drop partitions that are not real: too few coherent cells (measure.recovery), or a
        shifted copy at the rotation of another (measure.partitions)
    settle each transform: refits on tiles of its cells, shifts, splits, rivals
        (measure.settle), and drop again
    recover again (and the steps after it) while new partitions are found
    relocate: each partition whose free space does not show that it is in place (it
        crosses the reference's walls too often, or too little of it is seen), its cells
        and their neighbourhood registered alone, and its cells placed at every
        translation at those hypotheses' rotations (measure.placement); every other
        partition's cells registered alone, and placed at the half turn; the best
        hypotheses, and the placement whose free space fits best, offered as rivals to
        the settle step (taken on agreement, or on free space that fits)
    recover from every hypothesis (a map measured below, some partition of which its
        free space does not show in place, only): each hypothesis of the call counted as a
        new partition by the recovery's count over the whole map, at the significance of
        all of them at once, its own free space significantly off the reference's walls
        (measure.recovery.pooled_partitions); kept if the map is still measured
    choose again (a map measured below only): every hypothesis of the call that could
        make more cells agree is offered to every partition, taken for any gain of the
        count (measure.pool); undone if a partition is then dropped, or if the map is then
        no longer measured
    measured only if the map's free space does not cross the reference's walls
        (measure.evidence): else not the same place, no degree

Stopping rule ("nothing significant is left")
---------------------------------------------
A candidate set L of ``k`` agreeing cells, out of the ``n`` cells left in T, becomes a
partition only if all of these hold:

1. ``k >= min_partition_cells`` and ``k >= min_partition_fraction * N`` (N = occupied
   cells of the map): too small a part is noise, not a structural error;
2. ``k`` is far above chance: noise alone gives ``k ~ Binomial(n, p)``, and we ask
   ``k >= n p + z sqrt(n p (1 - p))`` with ``z = significance`` (default 6, which also
   covers the maximisation over transforms done by the registration). The chance ``p`` is
   ``min(p0, p_rival)``: ``p0`` is the probability that a cell dropped at random on the
   known reference area agrees (the share of known reference cells within ``threshold`` of
   a wall); ``p_rival`` is the upper quartile of the agreement shares of the cells left
   under the step's *rival* hypotheses, the candidates that put them elsewhere than the
   best does (:func:`~brokenness.measure.hypotheses.rival_chance`, on the scoring sample):
   wrong transforms of this map onto this reference. ``p0`` alone overestimates chance for a map
   of lines whose cells land partly off the reference's known area: with a dense reference
   at 0.1 m (``p0 = 0.3``), wrong transforms of a broken map made 12-15 % of its cells
   agree, its true parts 22-33 %, and the heavily broken maps of the realistic benchmark got
   no partition at all.

Otherwise the recursion stops and the cells left in T are *unassigned* (reported as such,
label :data:`~brokenness.measure.result.UNASSIGNED`). A set that passes but is explained by
the transform of a partition already found -- at least half of its cells that chance would
not put within ``merge_threshold`` of a wall land there -- is not "off" relative to it
(thickened walls, jitter): it is merged into that partition and not counted.

Noise: when the reference's walls are connected lines, isolated occupied cells of the map
(salt-and-pepper) are hidden from the registration, whose spectra they would flatten; they
are still counted by the masking.

Two references
--------------
Each step registers the remainder with the *whole* reference R, as Algorithm 1 of the paper
does (``R' \\subseteq L^R`` in its line 6), and with R', the reference less the walls that
earlier partitions matched. Partitions of a map of a real run usually overlap in the
reference (a robot sees the same corridor before and after a bump; the paper's definition
joins the partitions with a union, not a disjoint one): with R' alone, a later partition
misses the walls it shares with earlier ones, and pieces of it fit better elsewhere in what
is left (a room turned by 90 or 180 degrees, a corridor shifted) -- one true partition then
came back as two or three wrongly placed ones. With R alone, a part of a symmetric building
can fit, equally well, a place an earlier partition already explains (a hexagonal arena
turned by 60 degrees). Each step therefore registers with R, and, when most cells the best
hypothesis ``h_R`` explains land on walls earlier partitions already matched, with R' too
(saving the second registration otherwise). It keeps ``h_R`` unless the best hypothesis of
R' (``h_R'``) explains about as many cells: fewer by no more than ``z sigma`` (the chance
spread of the stopping rule below, with the same ``z``), a difference that coincidence alone
could make. Then the part goes where nothing else is yet.

We register the untransformed remainder of the map in each step, so the transform found is
already the whole transform from the original map to the reference (the composition of the
paper's per-step transforms), without resampling T again and again.

Because the recursion is greedy, a partition found early also takes cells of later ones that
agree with the reference by coincidence (likely in maps of many similar rooms). Once all
transforms are known, each cell is therefore given to the partition that puts it closest to
a reference wall (ties keep the greedy choice); partitions left too small are dropped.

Recovery
--------
Even so, a small partition can lose most of its cells during the recursion, to partitions
under whose transforms its walls happen to lie on reference walls; what is left of it is
then too little to be found, and the degree comes out one short (the usual error of the
higher degrees). After the recursion, :func:`~brokenness.measure.recovery.recover` looks
for such partitions among the cells that no partition explains *coherently* (few cells
around them agree under their partition's transform: coincidences are scattered, a
partition is a contiguous region), with the same stopping rule; and
:func:`~brokenness.measure.partitions.consolidate` joins partitions that are one rigid
piece (a part of a symmetric building first placed at a symmetric twin of its place, and
found again in its true place). See those modules for the details and the measured gain.

Fewest partitions
-----------------
Last, on a measured map, pieces of one part held at different twins of a symmetric
reference are made one partition where one transform (a piece's, followed by a symmetry of
the reference: the reference registered with itself) explains them all as well as their
own transforms do (:mod:`~brokenness.measure.symmetry`; README step 10): the degree is the
least number of partitions, less one.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._memory import small_pages
from .._points import take_rows
from ..errors import MapError, NothingFoundWarning, ParameterError
from ..grid import OccupancyMap
from ..limits import check_threshold
from ..masking import ReferenceIndex, cell_points, unmatched_reference
from ..registration.base import Candidate, Registrar
from ..registration.methods import make_registrar
from ..transform import RigidTransform
from .choice import mostly_on_claimed, prefer_unexplained
from .context import MapContext
from .evidence import (
    MAP_RATIO,
    ClearFree,
    Contradiction,
    contradiction,
    free_space,
    wall_contradiction,
)
from .explained import MAP_SHARE, drop_unexplained, explained_share
from .frames import (
    FRAMES,
    REPLICATED_SHARE,
    REPLICATION_FRAME,
    back_to_own_frame,
    best_of,
    in_frame,
    partitions_in_doubt,
    placed_alike,
    to_replicate,
)
from .hypotheses import best_hypothesis, rival_chance
from .options import BrokennessOptions, Settings
from .partitions import (
    Found,
    assemble,
    consolidate,
    drop_redundant,
    labels_in_original_grid,
    merge_target,
    reassign,
    with_fringe,
)
from .pool import Recorded, offered, recorded_transforms
from .recovery import drop_incoherent, pooled_partitions, recover, relocation_rivals
from .reference import ReferenceWork, WorkingReference
from .refine import refit_transform
from .result import BrokennessResult, Partition
from .settle import settle
from .support import occupied_around
from .symmetry import merges, symmetries
from .views import (
    candidates_of,
    exhausted,
    moving_remainder,
    not_isolated,
    occupied_count,
    prepared_reference,
    walls_connected,
)
from .walls import LARGEST_THICKNESS, wall_thickness

__all__ = ["compute_brokenness"]

MapLike = OccupancyMap | ArrayLike | str | os.PathLike[str]


@dataclass(frozen=True)
class Verdict:
    """:func:`_judge`'s verdict on a set of partitions.

    Attributes
    ----------
    reason : str or None
        Why the map is not measured (``None``: it is).
    ratio, bound : float or None
        The whole map's free-space ratio and its upper bound (``None``: too little free
        space to tell, or to bound it).
    ratios, bounds : list of float or None
        Each partition's ratio and upper bound, largest partition first (as :func:`assemble`
        sorts them).
    """

    reason: str | None
    ratio: float | None
    bound: float | None
    ratios: list[float | None]
    bounds: list[float | None]


#: iFMI options of the recursion, under the user's: a remainder mixes partitions, so more
#: rotation peaks are worth examining than for a single registration.
_IFMI_RECURSION_OPTIONS = {"rotation_peaks": 3, "peak_ratio": 0.3, "translation_peaks": 3}
#: ... and a wider search, tried when a step finds nothing significant with the above.
_IFMI_THOROUGH_OPTIONS = {"rotation_peaks": 6, "peak_ratio": 0.05, "translation_peaks": 3}
#: The wider search is also tried, for R and R' each on its own, when its best hypothesis
#: explains less than this share of the cells left.
_THOROUGH_BELOW = 0.4
#: Regions of the remainder are registered on their own (the tiles of these grids over its
#: box) when no hypothesis of the whole remainder is significant and it still holds at least
#: this share of the map's occupied cells (a heavily broken map, no part dominating it).
REGIONS_FROM = 0.1
REGION_GRIDS = (2, 3)
#: The recovery and the tests after it run again, up to this many times in all, while the
#: recovery finds a new partition among the cells the settled transforms leave unexplained.
RECOVERY_ROUNDS = 3


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


def compute_brokenness(
    map: MapLike,  # noqa: A002 - the paper's name
    reference: MapLike,
    options: BrokennessOptions | None = None,
    **overrides: Any,
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
        the coarser of the two is resampled to the finer one's first (the map keeps the
        detail that tells its partitions apart; ``threshold`` and every other length in
        cells are cells of that grid, ``parameters["working_resolution"]`` of the result;
        a coarser map's ``threshold`` is at least the side of one of its cells there, and
        a map whose walls are drawn thicker than the reference's, how far they reach
        beyond it, ``parameters["working_threshold"]``; the map's wall thickness, in its
        cells, ``parameters["wall_thickness"]``),
        unless the reference upsampled would exceed the cell limit: then the map is
        downsampled to the reference's resolution. Transforms and displacements are always
        reported from the map's cells to the reference's.
    options : BrokennessOptions, optional
        Every option of the measure in one object (defaults: ``BrokennessOptions()``; its
        docstring describes each).
    **overrides
        Options by name (``threshold=3``, ``method="random-walk"``...), applied on top of
        ``options``: any field of :class:`BrokennessOptions`.

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

    Notes
    -----
    The call runs with numpy's transparent huge-page advice turned off, and restores it on
    return (:func:`brokenness._memory.small_pages`): on kernels that compact memory to find
    huge pages, fresh grids of large maps cost seconds of system time otherwise. Results do
    not depend on it. No thread count is set here (a batch's workers run on one thread
    each: see the README, "Evaluate many maps").

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
    opts = _options(options, overrides)
    with small_pages():  # fresh grids without huge-page compaction (see brokenness._memory)
        return _in_frames(map, reference, opts)


def _in_frames(
    map: MapLike,  # noqa: A002 - the paper's name
    reference: MapLike,
    opts: BrokennessOptions,
) -> BrokennessResult:
    """:func:`_compute` in the map's own frame and, where needed, in other grid frames.

    A map measured with a partition in doubt
    (:func:`~brokenness.measure.frames.to_replicate`) is measured again with its grid
    turned by a half turn (:data:`~brokenness.measure.frames.REPLICATION_FRAME`), and is
    measured only if it is there too, on the same partitions: half of its partitioned cells,
    and half of the cells of its partitions in doubt, placed alike (README step 11); the
    result's ``parameters`` then say so (``replication_frame``, ``replication_degree``,
    ``replication_placed_alike``, ``replication_placed_alike_in_doubt``).

    With ``opts.frames`` over 1, a map measured with a partition in doubt
    (:func:`~brokenness.measure.frames.in_doubt`) is computed in the next ``opts.frames - 1``
    grid frames too; of the results measured at the own frame's degree, the best is kept
    (:func:`~brokenness.measure.frames.best_of`), reported in the map's own cells. Whether
    the map is measured is decided in its own frame and by the replication, as without
    frames (the own frame's warnings are issued as they are; the other frames' are not):
    the other frames only offer other partitionings of a map that is measured, so they
    cannot give a degree where the map's own frame would give none. The result's
    ``parameters`` say which frame it came from (``frame``) and the degree of every frame
    tried (``frame_degrees``, ``None`` where not measured), so that a user sees how far
    they agree."""
    started = time.perf_counter()
    original = _as_map(map, "map")
    ref = _as_map(reference, "reference")
    once = replace(opts, frames=1)
    work = ReferenceWork(ref)  # the reference's share, made once for every frame
    own = _compute(original, work, once)
    # a map measured with a partition in doubt: the frames asked for, the replication's
    # (the first of them) at least
    replicate = to_replicate(own)
    tried = FRAMES[1 : max(opts.frames, 2)] if replicate else ()
    results = [own]
    for frame in tried:
        moved, cells = in_frame(original, frame)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the map's own frame has said what there is
            result = _compute(moved, work, once)
        results.append(back_to_own_frame(result, frame, cells, original, ref))
    parameters: dict[str, Any] = {}
    best = 0  # the own frame's result, unless other frames were asked for
    if opts.frames > 1:
        best = best_of(results)
        parameters = {
            "frames": opts.frames,
            "frame": FRAMES[best],
            "frame_degrees": [r.degree for r in results],  # how far the frames agree
        }
    if replicate:
        again = results[1 + tried.index(REPLICATION_FRAME)]
        # c in reference cells: the working grid is the reference's, or upsampled from it
        upsampling = work.at(own.parameters["working_resolution"]).upsampling
        tolerance = own.parameters["working_threshold"] / upsampling
        # the partitions the replication is asked for (none only if asked otherwise)
        doubtful = [p.index for p in partitions_in_doubt(own)]
        alike = placed_alike(own, again, tolerance)
        alike_in_doubt = placed_alike(own, again, tolerance, doubtful) if doubtful else None
        parameters |= {
            "replication_frame": REPLICATION_FRAME,
            "replication_degree": again.degree,
            "replication_placed_alike": alike,
            "replication_placed_alike_in_doubt": alike_in_doubt,
        }
        shares = [alike] if alike_in_doubt is None else [alike, alike_in_doubt]
        if not again.measured or min(shares) < REPLICATED_SHARE:
            parameters["frame"] = FRAMES[0]  # the own frame's result, not measured
            return _not_replicated(own, again, parameters, time.perf_counter() - started)
    if not parameters:
        return own
    chosen = results[best]
    return replace(
        chosen,
        parameters=chosen.parameters | parameters,
        seconds=time.perf_counter() - started,
    )


def _not_replicated(
    own: BrokennessResult, again: BrokennessResult, parameters: dict[str, Any], seconds: float
) -> BrokennessResult:
    """``own``, measured in the map's own frame with a partition in doubt, made not measured
    because the map in :data:`~brokenness.measure.frames.REPLICATION_FRAME` (``again``) is
    not, or is measured on other partitions: the share of ``own``'s partitioned cells that
    ``again`` places as ``own`` does (``parameters["replication_placed_alike"]``), or of the
    cells of its partitions in doubt (``parameters["replication_placed_alike_in_doubt"]``),
    is under :data:`~brokenness.measure.frames.REPLICATED_SHARE`."""
    doubtful = len(partitions_in_doubt(own))
    found = (
        f"found in the map's own grid frame ({len(own.partitions)} partitions, {doubtful} of "
        "them in doubt: their free space does not show their place)"
    )
    if not again.measured:
        reason = f"{found} but not with its grid {REPLICATION_FRAME} degrees ({again.reason})"
    else:  # the share short of half: of all the partitioned cells first, else those in doubt
        share, cells = parameters["replication_placed_alike"], "its partitioned cells"
        if share >= REPLICATED_SHARE:
            share = parameters["replication_placed_alike_in_doubt"]
            cells = "the cells of its partitions in doubt"
        reason = (
            f"{found}, and with its grid {REPLICATION_FRAME} degrees on other partitions: "
            f"{_short_of_half(share)} of {cells} placed alike, not half"
        )
    warnings.warn(f"the degree was not measured: {reason}", NothingFoundWarning, stacklevel=4)
    return replace(
        own,
        degree=None,
        measured=False,
        reason=reason,
        parameters=own.parameters | parameters,
        seconds=seconds,
    )


def _short_of_half(share: float) -> str:
    """``share`` (under a half) as a percentage that does not round up to the half: whole
    percents, rounded down (``0.4954`` is ``49%``)."""
    return f"{math.floor(100 * share)}%"


def _compute(
    original: OccupancyMap,
    work: ReferenceWork,
    opts: BrokennessOptions,
) -> BrokennessResult:
    """:func:`compute_brokenness` of ``original`` in its own frame, against the reference of
    ``work`` (what the call makes of the reference alone, shared by its frames)."""
    started = time.perf_counter()
    ref = work.reference
    original_points = cell_points(original.occupied)  # (N, 2), row-major order
    n_occupied = original_points.shape[0]
    if n_occupied == 0:
        raise MapError("the map has no occupied cell: nothing to measure")
    if not ref.occupied.any():
        raise MapError("the reference map has no occupied cell")
    working, to_working, working_ref = _common_resolution(original, work)
    to_reference = working_ref.to_reference
    asked = opts
    thickness = wall_thickness(original_points)
    opts = _at_working_resolution(
        opts,
        original,
        working,
        thickness,
        lambda: working_ref.upsampling * (work.wall_thickness - 1) / 2,
    )
    # the neighbourhood the threshold implies fits the reference
    check_threshold(opts.threshold, working_ref.reference.shape)
    index = working_ref.index
    method = opts.method
    kwargs: dict[str, Any] = dict(_IFMI_RECURSION_OPTIONS) if method == "ifmi" else {}
    kwargs.update(opts.registration_kwargs)
    registrar = make_registrar(method, seed=opts.seed, **kwargs)
    # The wider search of a step that falls short, of the regions and of the recovery:
    # iFMI with more peaks, the random walk with twice the start poses.
    if method == "ifmi":
        thorough = make_registrar(method, **{**kwargs, **_IFMI_THOROUGH_OPTIONS})
    else:
        thorough = _wider(registrar)

    # every hypothesis of the call, remembered for the last offers (:func:`_rechosen`)
    hypotheses: list[tuple[Candidate, ...]] = []
    registrar = Recorded(registrar, hypotheses)
    if thorough is not None:
        thorough = Recorded(thorough, hypotheses)
    points = original_points if working is original else cell_points(working.occupied)
    uses_free = bool(getattr(registrar, "uses_free_space", True))
    as_cells = bool(getattr(registrar, "accepts_cells", False))
    if thorough is not None:
        as_cells = as_cells and bool(getattr(thorough, "accepts_cells", False))
    settings = Settings.of(
        opts,
        points.shape[0],
        uses_free,
        walls_connected(index.reference, index.occupied_points),
        as_cells,
    )
    whole = prepared_reference(registrar, index.reference, index.occupied, uses_free, as_cells)
    # Algorithm 1, then the tests of what it found, in this order
    found = _recurse(working, points, index, registrar, thorough, whole, settings)
    # of the map alone, once a call: the occupied cells around each, the clear free cells
    # (these made when first needed)
    context = MapContext(
        points,
        working,
        index,
        settings,
        occupied_around(points, working.shape),
        ClearFree(working, settings.threshold),
    )
    found, rivals = recover(found, context, thorough, whole, relocate=True)
    searched = found  # what the recovery's last search ran on
    found = _tested(found, context, rivals)
    for _ in range(1, RECOVERY_ROUNDS):  # settled transforms leave clearer suspects
        if _same_partitions(found, searched):
            break  # the tests changed nothing: a round would repeat the last search
        again, rivals = recover(found, context, thorough, whole)
        if len(again) <= len(found):
            break
        searched = again
        found = _tested(again, context, rivals)
    found, evidence = _relocated(found, context, thorough, whole, hypotheses)
    # the reference's symmetries (step 10), while it is prepared; not recorded as hypotheses
    motions: list[RigidTransform] = []
    if method == "ifmi" and len(found) > 1 and isinstance(thorough, Recorded):
        key = (settings.max_candidates, settings.threshold)  # what symmetries reads
        search = partial(symmetries, thorough.registrar, whole, index, settings)
        motions = working_ref.symmetries(key, search)
    del whole  # the prepared reference (its distance map): no registration now
    found, verdict, evidence = _explained_and_judged(found, context, evidence)
    if verdict.reason is None:  # measured: every hypothesis of the call, offered once more
        found, verdict = _grown(found, verdict, evidence, context, hypotheses)
        found, verdict = _rechosen(found, verdict, context, hypotheses)
        found, verdict = _fewest(found, verdict, context, motions)
    reason = verdict.reason
    found_partitions, labels_working = assemble(
        found, points, working, (to_working, to_reference), original, ref, index
    )
    labels = labels_in_original_grid(labels_working, working, to_working, original)
    # the cells of each partition, counted at the original map's occupied cells
    at = original_points
    lab = labels[at[:, 1].astype(np.intp), at[:, 0].astype(np.intp)]
    sizes = np.bincount(lab[lab >= 0], minlength=len(found_partitions))
    assigned = int(sizes.sum())
    acceptance: list[float | None] = [None] * len(found_partitions)
    if method == "random-walk":  # the random walk's own quality measure, per partition
        from ..registration.random_walk import partition_acceptance

        transforms = [p.transform for p in found_partitions]
        acceptance = partition_acceptance(original.states, ref.states, labels, transforms)
    # Partition sizes and fractions are counted in the original map's cells.
    partitions = tuple(
        Partition(
            index=p.index,
            cells=int(sizes[p.index]),
            fraction=float(sizes[p.index]) / n_occupied,
            transform=p.transform,
            confidence=p.confidence,
            rotation_offset_deg=p.rotation_offset_deg,
            displacement=p.displacement,
            displacement_m=p.displacement_m,
            step_seconds=p.step_seconds,
            contradiction=verdict.ratios[p.index],
            contradiction_bound=verdict.bounds[p.index],
            acceptance=acceptance[p.index],
        )
        for p in found_partitions
    )
    parameters = asked.to_dict() | {
        "working_resolution": working.resolution,
        "working_threshold": opts.threshold,
        "wall_thickness": thickness,
    }
    if reason is not None:
        warnings.warn(f"the degree was not measured: {reason}", NothingFoundWarning, stacklevel=4)
    return BrokennessResult(
        degree=len(partitions) - 1 if reason is None else None,
        partitions=partitions,
        labels=labels,
        occupied_cells=n_occupied,
        unassigned_cells=n_occupied - assigned,
        method=method,
        parameters=parameters,
        seconds=time.perf_counter() - started,
        measured=reason is None,
        reason=reason,
        contradiction=verdict.ratio,
        contradiction_bound=verdict.bound,
    )


def _same_partitions(a: list[Found], b: list[Found]) -> bool:
    """Whether ``a`` and ``b`` hold the same partitions: the same transforms (the same
    objects: the tests keep a transform they do not move) and the same members, in order.

    The recovery's search is a function of the partitions it starts from (it first gives
    every cell to its best partition, which changes nothing in partitions it returned), so
    a round on the partitions its last round returned would search the same suspects again
    and find nothing; a round is run only if the tests in between changed them."""
    return len(a) == len(b) and all(
        f.transform is g.transform and np.array_equal(f.members, g.members)
        for f, g in zip(a, b, strict=True)
    )


def _tested(found: list[Found], context: MapContext, rivals: list[RigidTransform]) -> list[Found]:
    """The tests of what the recursion and the recovery found, in order: join one-piece
    partitions, drop those that are not real, settle the transforms (offering ``rivals``),
    and, if settling changed anything, drop again."""
    joined = consolidate(found, context.points, context.index, context.settings)
    return _settled(_real(joined, context), context, rivals)


def _settled(found: list[Found], context: MapContext, rivals: list[RigidTransform]) -> list[Found]:
    """Settle the transforms (offering ``rivals``) and, if that changed anything, drop the
    partitions that are no longer real (the last tests of :func:`_tested`)."""
    points, index, settings = context.points, context.index, context.settings
    settled = settle(found, points, index, settings, rivals, clear=context.clear)
    if settled is found:
        return found
    # the tests again: settling moves transforms, it adds nothing
    return _real(settled, context)


def _real(found: list[Found], context: MapContext) -> list[Found]:
    """The partitions that are real (step 7 of the README): coherent
    (:func:`~brokenness.measure.recovery.drop_incoherent`), and not a redundant placement
    (:func:`~brokenness.measure.partitions.drop_redundant`); the last test of step 7, that
    a partition explains the region of the map it lies in
    (:func:`~brokenness.measure.explained.drop_unexplained`), runs once, before the judge."""
    found = drop_incoherent(found, context)
    return drop_redundant(found, context.points, context.index, context.settings)


def _relocated(
    found: list[Found],
    context: MapContext,
    registrar: Registrar,
    whole: Any,
    hypotheses: list[tuple[Candidate, ...]],
) -> tuple[list[Found], Contradiction | None]:
    """The settled partitions, each that may be at a wrong place offered the best places that
    its own cells and its neighbourhood give registered alone
    (:func:`~brokenness.measure.recovery.relocation_rivals`, with the wider search
    ``registrar``, ``whole`` its prepared reference): a small part held at a twin of its room
    holds mostly its own cells once the transforms are settled, and registered alone they,
    or the cells around them, give its true place. The rivals are offered alone first (the
    partitions' refits were tried), then with the refits of whatever moved, and the tests of
    :func:`_real` run again if anything did.

    A partition *may be at a wrong place* when its free space, on its own, would not pass the
    map's test (:meth:`~brokenness.measure.evidence.Contradiction.doubtful`): the upper bound
    of its rate of crossing the reference's walls, at the stopping rule's significance, is
    over :data:`MAP_RATIO` of the chance rate (it crosses them too often, or too little of it
    lands on the reference to show that it does not). A placement at a twin of the part's
    room puts its free space on walls about as often as chance (on the failing maps of the
    realistic benchmark traced, 0.7-1.9 times). A twin can nevertheless show its free space
    in place, where the building repeats a room (a drawn atrium of degree 6: 0.46 of the
    chance rate, 144 cells from the part's place), so every other partition's own cells are
    registered alone too, once; their neighbourhood and their pairs are not (those
    registrations are most of the cost of this step).
    The rivals are added to ``hypotheses`` (the placements among them are no registration's:
    :func:`_rechosen` offers them again).

    Returns the partitions and, if they are the ones given, their contradiction (for
    :func:`_judge`; else ``None``).
    """
    if len(found) < 2:
        return found, None  # a lone partition's cells are what the first step registered
    points, index, settings, clear = context.points, context.index, context.settings, context.clear
    owned = free_space(found, points, clear, index)
    evidence = contradiction(found, points, clear, index, owned)
    which = evidence.doubtful(settings.significance)
    rivals = relocation_rivals(found, context, registrar, whole, which, owned)
    # the placements among them too, for :func:`_rechosen` (each alone: no registration's)
    hypotheses.extend((Candidate(t, 1.0),) for t in rivals)
    if not rivals:
        return found, evidence
    moved = settle(found, points, index, settings, rivals, refits=False, clear=clear, owned=owned)
    if moved is found:
        return found, evidence
    moved = settle(moved, points, index, settings, rivals, clear=clear)
    return _real(moved, context), None


def _rechosen(
    found: list[Found],
    verdict: Verdict,
    context: MapContext,
    hypotheses: list[tuple[Candidate, ...]],
) -> tuple[list[Found], Verdict]:
    """The partitions of a measured map (``verdict``, :func:`_judge`'s), each offered every
    hypothesis of the call that could make more cells agree
    (:mod:`~brokenness.measure.pool`), judged by the count alone, then the tests of
    :func:`_real` and of :func:`_explained_and_judged` again. The pass decides neither the
    degree nor whether the map is measured: it is undone (``found`` and ``verdict`` are
    returned) if a partition is dropped or the map is no longer measured.
    """
    points, index, settings = context.points, context.index, context.settings
    walls = points[not_isolated(points)]
    transforms = [f.transform for f in found]
    rivals = offered(recorded_transforms(hypotheses), transforms, walls, index, settings.threshold)
    if not rivals:
        return found, verdict
    moved = settle(
        found, points, index, settings, rivals, refits=False, clear=context.clear, by_count=True
    )
    if moved is found:
        return found, verdict
    again = _measured_again(moved, context)
    if again is None or len(again[0]) != len(found):
        return found, verdict
    return again


def _grown(
    found: list[Found],
    verdict: Verdict,
    evidence: Contradiction | None,
    context: MapContext,
    hypotheses: list[tuple[Candidate, ...]],
) -> tuple[list[Found], Verdict]:
    """The partitions of a measured map (``verdict``, :func:`_judge`'s on ``evidence``, their
    contradiction), grown by those that the call's hypotheses hold
    (:func:`~brokenness.measure.recovery.pooled_partitions`: the recovery's count over the
    whole map, applied to every hypothesis of the call), then the tests of :func:`_real` and
    of :func:`_explained_and_judged` again.

    Only where some partition's free space does not show that it is in place
    (:meth:`~brokenness.measure.evidence.Contradiction.doubtful`, as for the relocation): a
    part held by a partition found before it, at that partition's transform, puts its free
    space on the reference's walls. Kept only if the map is still measured, with more
    partitions than before; else ``found`` and ``verdict`` are returned."""
    if evidence is None or not evidence.doubtful(context.settings.significance):
        return found, verdict
    grown = pooled_partitions(found, context, hypotheses)
    if len(grown) == len(found):
        return found, verdict
    again = _measured_again(grown, context)
    if again is None or len(again[0]) <= len(found):
        return found, verdict
    return again


def _fewest(
    found: list[Found], verdict: Verdict, context: MapContext, motions: list[RigidTransform]
) -> tuple[list[Found], Verdict]:
    """The partitions of a measured map (``verdict``, :func:`_judge`'s), with the partitions
    that one transform explains as well as their own transforms do replaced by one
    partition of it (README step 10, :mod:`~brokenness.measure.symmetry`: pieces of a part
    held at twins that the reference's symmetries ``motions`` relate).

    The merges are tried best first (:func:`~brokenness.measure.symmetry.merges`), each
    set of partitions once: the transform is refitted on their cells
    (:func:`~brokenness.measure.refine.refit_transform`), every cell goes to its best
    partition (:func:`~brokenness.measure.partitions.reassign`), and the tests of
    :func:`_real` and :func:`_explained_and_judged` run again. The first merge after which
    the map is still measured, and those tests drop no partition, is kept, and the merges
    are sought again among the new partitions; else ``found`` and ``verdict`` are returned.
    """
    points, index, settings = context.points, context.index, context.settings
    while len(found) > 1:
        tried: set[tuple[int, ...]] = set()
        for merge in merges(found, points, index, settings, motions):
            if merge.partitions in tried:
                continue
            tried.add(merge.partitions)
            joined = [found[q] for q in merge.partitions]
            members = np.sort(np.concatenate([f.members for f in joined]))
            transform = refit_transform(
                merge.transform,
                take_rows(points, members),
                index,
                settings.threshold,
                settings.loose,
            )
            one = Found(
                transform,
                members,
                max(f.confidence for f in joined),
                sum(f.seconds for f in joined),
            )
            # the merged partition where the first of them was, the others left out
            first, others = merge.partitions[0], merge.partitions[1:]
            fewer = [one if q == first else f for q, f in enumerate(found) if q not in others]
            fewer = reassign(fewer, points, index, settings.threshold, settings.min_cells)
            again = _measured_again(fewer, context)
            if again is not None and len(again[0]) == len(fewer):
                found, verdict = again
                break
        else:
            return found, verdict
    return found, verdict


def _measured_again(found: list[Found], context: MapContext) -> tuple[list[Found], Verdict] | None:
    """``found`` after the tests of :func:`_real` and of :func:`_explained_and_judged`, with
    the verdict, if the map is still measured (``None`` if not): how the last passes check
    what they changed."""
    again, judged, _ = _explained_and_judged(_real(found, context), context, None)
    return None if judged.reason is not None else (again, judged)


def _explained_and_judged(
    found: list[Found], context: MapContext, evidence: Contradiction | None
) -> tuple[list[Found], Verdict, Contradiction | None]:
    """The partitions that explain their region of the map
    (:func:`~brokenness.measure.explained.drop_unexplained`), :func:`_judge`'s verdict on
    them and their contradiction (``evidence``, if made for ``found``; ``None`` if there
    are no partitions)."""
    explaining = drop_unexplained(found, context)
    if explaining is not found:  # partitions dropped: their free space is owned anew
        evidence = None
    if evidence is None and explaining:
        evidence = contradiction(explaining, context.points, context.clear, context.index)
    return explaining, _judge(explaining, context, evidence), evidence


def _wider(registrar: Registrar) -> Registrar:
    """The random walk's wider search (:meth:`RandomWalkRegistrar.wider`: twice the start
    poses; made before any walk, it opens the budget that every walk of the call is counted
    in, and the measure skips it once it is :func:`~brokenness.measure.views.exhausted`), or
    ``registrar`` itself for a method without one."""
    wider = getattr(registrar, "wider", None)
    return wider() if callable(wider) else registrar


def _region_candidates(
    working: OccupancyMap,
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    remaining: NDArray[np.bool_],
    registrar: Registrar,
    whole: Any,
    settings: Settings,
) -> list[Candidate]:
    """Hypotheses from regions of the remainder: the tiles of 2 x 2 and 3 x 3 grids over its
    box, each registered on its own (tiles with fewer than ``min_cells`` cells are skipped, so
    are tiles of isolated cells only, which the registration does not see, and the tiles left
    once ``registrar`` has spent its budget)."""
    r, c = rows[remaining], cols[remaining]
    r0, r1, c0, c1 = int(r.min()), int(r.max()) + 1, int(c.min()), int(c.max()) + 1
    out: list[Candidate] = []
    for g in REGION_GRIDS:
        row_edges = np.linspace(r0, r1, g + 1)
        col_edges = np.linspace(c0, c1, g + 1)
        tile_row = np.searchsorted(row_edges, rows, side="right") - 1
        tile_col = np.searchsorted(col_edges, cols, side="right") - 1
        for i in range(g):
            for j in range(g):
                cells = remaining & (tile_row == i) & (tile_col == j)
                if np.count_nonzero(cells) < settings.min_cells:
                    continue
                if exhausted(registrar):
                    return out
                states = moving_remainder(
                    working,
                    rows,
                    cols,
                    cells,
                    settings.uses_free,
                    settings.drop_isolated,
                    settings.as_cells,
                )
                if occupied_count(states) == 0:
                    continue  # only isolated cells, hidden from the registration: nothing left
                out += candidates_of(registrar, whole, states, settings.max_candidates)
    return out


def _judge(
    found: list[Found], context: MapContext, evidence: Contradiction | None = None
) -> Verdict:
    """Contradiction test of the partitions (:mod:`brokenness.measure.evidence`; their
    :func:`~brokenness.measure.evidence.contradiction` made here unless given).

    Returns why the map is not measured (``None`` if it is), the whole map's ratio (observed
    free-space contradiction over what chance would give), its upper bound (``None`` if it
    cannot be bounded) and each partition's ratio, largest first (as
    :func:`assemble` sorts them). The map is measured when the upper bound of its ratio, at
    the stopping rule's significance, is at most :data:`MAP_RATIO`, and so is the upper bound
    of the converse ratio, the map's walls in the reference's clear free space
    (:func:`~brokenness.measure.evidence.wall_contradiction`); and first, its partitions
    must hold at least :data:`~brokenness.measure.explained.MAP_SHARE` of its occupied cells
    (:func:`~brokenness.measure.explained.explained_share`; the ratios are measured all the
    same).
    """
    if not found:
        return Verdict(
            "no part of the map agrees with the reference under any transform found "
            "(registration failed, or not the same place?)",
            None,
            None,
            [],
            [],
        )
    if evidence is None:
        evidence = contradiction(found, context.points, context.clear, context.index)
    order = sorted(range(len(found)), key=lambda i: (-found[i].members.size, i))
    settings = context.settings
    ratios = [evidence.ratio(i) for i in order]
    bounds = [_finite(evidence.upper_ratio(settings.significance, i)) for i in order]
    ratio = evidence.ratio()
    upper = evidence.upper_ratio(settings.significance)
    reason: str | None = None
    explained = explained_share(found, context)
    if explained < MAP_SHARE:
        reason = (
            f"only {100 * explained:.0f} % of the map's occupied cells agree with the reference "
            f"under its partitions (at least {100 * MAP_SHARE:.0f} % must): most of the map is "
            "not of the reference's place, or lies beyond it"
        )
    elif not math.isfinite(upper):
        reason = (
            "the map shows no free space on the reference under its partitions' transforms: "
            "nothing tells whether it is of the reference's place"
        )
    elif upper > MAP_RATIO:
        seen = "too few free cells to tell" if ratio is None else f"{100 * ratio:.0f} %"
        reason = (
            f"the map's free space crosses the reference's walls at {seen} of the rate of a "
            f"random placement (up to {100 * upper:.0f} % at {settings.significance:g} sigma; "
            f"at most {100 * MAP_RATIO:.0f} % for a map of the reference's place): "
            "not the same place?"
        )
    if reason is None:
        walls = wall_contradiction(found, context.points, context.index, settings.threshold)
        wall_upper = walls.upper_ratio(settings.significance)
        if wall_upper > MAP_RATIO:
            wall_ratio = walls.ratio()
            seen = "too few cells to tell" if wall_ratio is None else f"{100 * wall_ratio:.0f} %"
            reason = (
                f"the map's walls land in the reference's free space at {seen} of the rate of "
                f"a random placement (up to {100 * wall_upper:.0f} % at "
                f"{settings.significance:g} sigma; at most {100 * MAP_RATIO:.0f} % for a map "
                "of the reference's place): most of the map is explained by no partition; "
                "not the same place?"
            )
    return Verdict(reason, ratio, _finite(upper), ratios, bounds)


def _finite(bound: float) -> float | None:
    """An upper bound as reported: ``None`` for one that nothing bounds (``inf``)."""
    return bound if math.isfinite(bound) else None


def _options(options: BrokennessOptions | None, overrides: dict[str, Any]) -> BrokennessOptions:
    """``options`` with ``overrides`` applied (unknown names are a :class:`ParameterError`)."""
    base = BrokennessOptions() if options is None else options
    if not isinstance(base, BrokennessOptions):
        raise ParameterError("options must be a BrokennessOptions (or give options by name)")
    known = {f.name for f in fields(BrokennessOptions)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ParameterError(f"unknown option {unknown[0]!r} (options: {', '.join(sorted(known))})")
    if overrides.get("registration_options", ()) is None:
        overrides = {**overrides, "registration_options": ()}
    return replace(base, **overrides) if overrides else base


def _common_resolution(
    m: OccupancyMap, work: ReferenceWork
) -> tuple[OccupancyMap, RigidTransform, WorkingReference]:
    """Map and reference at the finer of their two resolutions: ``(working map, original
    map cells -> working map cells, working reference)`` (the reference of ``work``, and the
    transform of its cells to the reference's, :class:`~brokenness.measure.reference.
    WorkingReference`).

    The coarser of the two is resampled (:func:`~brokenness.io.resample.resample_to_resolution`):
    a coarser map is upsampled to the reference's cells, a coarser reference to the map's.
    Downsampling the map instead would throw away what tells its partitions apart: parts
    clearly off from each other (half a metre) are a few cells off at the coarser
    resolution, within the merge threshold of each other. On the realistic benchmark's
    simulated maps made at 5 cm against references at 10 cm, all partitions were true in
    33 of 42 cases with the map downsampled, and the exact degree more often with the
    reference upsampled (see the README, "Resolutions and thick walls"). A reference that
    would exceed the cell limit upsampled (:func:`~brokenness.limits.max_cells`) is kept as
    it is, and the map downsampled to it.
    """
    identity = RigidTransform.identity()
    ref = work.reference
    if (
        m.resolution is None
        or ref.resolution is None
        or math.isclose(m.resolution, ref.resolution, rel_tol=1e-9)
    ):
        return m, identity, work.at(None)
    from ..io.resample import cell_scale_offset, resample_to_resolution, resampled_size
    from ..limits import max_cells

    if m.resolution < ref.resolution:  # the map is the finer: upsample the reference, if it fits
        scale = ref.resolution / m.resolution
        rows, cols = (resampled_size(n, scale) for n in ref.shape)
        if rows * cols <= max_cells():
            return m, identity, work.at(m.resolution)
    working = resample_to_resolution(m, ref.resolution)
    s, tx, ty = cell_scale_offset(m, working)
    return working, RigidTransform(0.0, tx, ty, s), work.at(None)


def _at_working_resolution(
    opts: BrokennessOptions,
    original: OccupancyMap,
    working: OccupancyMap,
    thickness: int = 1,
    reference_reach: Callable[[], float] = lambda: 0.0,
) -> BrokennessOptions:
    """``opts`` with the threshold ``c`` (and a merge threshold given below it) raised to
    how far, in working cells, the map draws a wall from where it is, beyond the band in
    which the reference draws it, if that is larger. ``thickness``: the map's walls, in its
    own cells (:func:`~brokenness.measure.walls.wall_thickness`); ``reference_reach()``: how
    far, in working cells, the reference's drawing of a wall surely reaches beyond the cell
    that holds it (asked only when the map's walls are thick).

    A map coarser than the reference is upsampled to the reference's cells
    (:func:`_common_resolution`): each of its cells becomes a square of ``r`` working cells a
    side (``r`` the ratio of the two resolutions), and a wall anywhere in the cell is drawn
    across all ``r`` of them, up to ``r - 1`` cells from where it is, plus a cell of the
    reference's own drawing: ``r``. A smaller ``c`` cannot tell a wall that is in place from
    one that is off, and the map falls apart into pieces of whatever agrees by chance (the
    bundled example map at 0.2 m against its 0.05 m reference: degree 6 at ``c = 2``, its
    true 2 from ``c = 3`` on). At the default ``c = 2`` nothing changes up to twice the
    reference's cell (``r <= 2``: the realistic benchmark's 0.1 m maps against 0.05 m
    references). A coarser reference needs no such floor: its walls, drawn ``r`` cells
    thick, hold the true wall within them, and it is the map's cells that are counted.

    A map that draws its walls ``t`` cells thick draws them about where they are (a hit
    blurred by the sensor model to both sides, a dilation): ``(t - 1) / 2`` of its cells to
    either side of the cell that holds the wall, ``r (t - 1) / 2`` working cells. A reference
    that draws its walls ``t_r`` of its own cells thick, each ``s`` working cells (``s > 1``
    when it was upsampled), holds ``s (t_r - 1) / 2`` of them to either side of its cell
    that holds the wall (the wall anywhere in that one); so ``c`` is at least
    ``r + r (t - 1) / 2 - s (t_r - 1) / 2`` (session 42: the realistic maps
    at 0.1 m against 0.05 m references, their walls thickened to three cells, came out of
    degree 4-9 or not measured at ``c = 2``). For walls of one cell this is the floor above;
    for a map whose walls are :data:`~brokenness.measure.walls.LARGEST_THICKNESS` cells or
    more (solids: objects drawn filled, the outside of a building drawn occupied) there is
    no band to tell, and the floor above stays.
    """
    side = 1.0
    if not (
        working is original
        or original.resolution is None
        or working.resolution is None
        or working.resolution >= original.resolution
    ):
        side = round(original.resolution / working.resolution, 9)
    band = side
    # walls of the largest thickness told apart: solids, no band to tell (the floor above)
    banded = thickness < LARGEST_THICKNESS
    if banded and side * (thickness + 1) / 2 > max(opts.threshold, side):  # else c stays
        band = max(side, side * (thickness + 1) / 2 - reference_reach())
    if band <= opts.threshold:
        return opts
    merge = None if opts.merge_threshold is None else max(opts.merge_threshold, band)
    return replace(opts, threshold=band, merge_threshold=merge)


def _recurse(
    working: OccupancyMap,
    points: NDArray[np.float64],
    index: ReferenceIndex,
    registrar: Registrar,
    thorough: Registrar | None,
    whole: Any,
    settings: Settings,
) -> list[Found]:
    """Algorithm 1: the partitions in the order found (members index ``points``)."""
    threshold, merge_threshold = settings.threshold, settings.loose
    min_cells, significance = settings.min_cells, settings.significance
    max_partitions, max_candidates = settings.max_partitions, settings.max_candidates
    uses_free, drop_isolated = settings.uses_free, settings.drop_isolated
    n_total = points.shape[0]
    remaining = np.ones(n_total, dtype=bool)
    reference_occupied = index.occupied  # never modified: the first step makes a new mask
    p0 = index.chance_agreement(threshold)
    rows, cols = points[:, 1].astype(np.intp), points[:, 0].astype(np.intp)
    found: list[Found] = []
    carried: list[Candidate] = []  # the previous step's hypotheses, from R and R'
    carried_rest: list[Candidate] = []  # ... from R' only
    steps = 0
    while np.count_nonzero(remaining) >= min_cells and len(found) < max_partitions:
        steps += 1
        if steps > 2 * max_partitions:  # merges do not count; bound them too
            break
        t0 = time.perf_counter()
        moving_states = moving_remainder(
            working, rows, cols, remaining, uses_free, drop_isolated, settings.as_cells
        )
        if occupied_count(moving_states) < min_cells:
            break  # what is left is scattered noise: nothing to register
        left = np.flatnonzero(remaining)
        left_points = take_rows(points, left)
        n = left.size
        # the rule with p0 while the hypotheses are gathered (when to widen the search); with
        # the chance of the best hypothesis's rivals once it is known (the stopping rule)
        chance, spread, needed = settings.needed(n, p0)
        best = None
        # A step first asks the registration (with R, and with R' when the best hypothesis of
        # R lies mostly on matched walls: see "Two references") for its usual hypotheses,
        # plus those of the previous step (a part seen there, beside the larger one that won,
        # is often registered better than from what is left alone). If none is significant,
        # or the best (or the best of R') explains less than 40 % of what is left, it asks
        # once more with a wider search (``thorough``: more peaks, same prepared references)
        # for the reference(s) whose best fell short, and keeps the better answer.
        rest = None
        pool: list[Candidate] = list(carried)
        pool_rest: list[Candidate] = list(carried_rest)
        refined: dict[Any, Any] = {}  # refinements of this step's candidates, for reuse
        enough = max(needed, _THOROUGH_BELOW * n)
        best_whole = best_rest = None
        # Each reference gets the wider search only while its own best falls short.
        widen_whole = widen_rest = True
        fresh: list[Candidate] = []
        fresh_rest: list[Candidate] = []
        for attempt in (registrar, thorough):
            if attempt is None or (attempt is thorough and exhausted(attempt)):
                continue  # no wider search, or its budget is spent (the random walk's)
            limit = max_candidates if attempt is registrar else 2 * max_candidates
            if widen_whole:
                fresh = candidates_of(attempt, whole, moving_states, limit)
                pool += fresh
                best_whole = best_hypothesis(pool, left_points, index, threshold, refined)
                widen_whole = best_whole is None or bool(np.count_nonzero(best_whole[1]) < enough)
            best = best_whole
            rest_ok = True
            use_rest = rest is not None
            if not use_rest and best_whole is not None and found:
                use_rest = mostly_on_claimed(
                    best_whole, left_points, index.occupied, reference_occupied, threshold
                )
            if best_whole is not None and use_rest:
                if rest is None:
                    rest = prepared_reference(
                        registrar,
                        index.reference,
                        reference_occupied,
                        uses_free,
                        settings.as_cells,
                    )
                if widen_rest and not (attempt is thorough and exhausted(attempt)):
                    fresh_rest = candidates_of(attempt, rest, moving_states, limit)
                    pool_rest += fresh_rest
                    best_rest = best_hypothesis(pool_rest, left_points, index, threshold, refined)
                    widen_rest = best_rest is None or bool(np.count_nonzero(best_rest[1]) < enough)
                rest_ok = not widen_rest
                best = prefer_unexplained(best_whole, best_rest, significance * spread)
            if best is not None and np.count_nonzero(best[1]) >= enough and rest_ok:
                break
        if (
            thorough is not None
            and not exhausted(thorough)
            and (best is None or np.count_nonzero(best[1]) < needed)
            and n >= max(4 * min_cells, REGIONS_FROM * n_total)
        ):
            # No part dominates what is left (a heavily broken map): its spectra have no
            # peak of their own. Parts of the map do: register regions of it.
            fresh += _region_candidates(working, rows, cols, remaining, thorough, whole, settings)
            pool += fresh
            regional = best_hypothesis(pool, left_points, index, threshold, refined)
            if regional is not None and (
                best is None or np.count_nonzero(regional[1]) > np.count_nonzero(best[1])
            ):
                best = regional
        carried, carried_rest = fresh + fresh_rest, fresh_rest
        if best is not None:  # chance for this map and reference: the rivals of the best
            p_step = rival_chance(
                pool + pool_rest, left_points, index, threshold, best[0], merge_threshold, p0
            )
            chance, spread, needed = settings.needed(n, p_step)
        if best is None or np.count_nonzero(best[1]) < needed:
            break
        transform, agree = best
        k = int(np.count_nonzero(agree))
        members = left[with_fringe(transform, left_points, agree, index, merge_threshold)]
        member_points = take_rows(points, members)
        moved = transform.apply(member_points)
        # Merge into an earlier partition whose transform explains this set as well.
        target = merge_target(found, member_points, index, merge_threshold)
        remaining[members] = False
        # the walls still available to the next step (none: this was the last step)
        last = (
            np.count_nonzero(remaining) < min_cells
            or len(found) + (target is None) >= max_partitions
            or steps >= 2 * max_partitions
        )
        if not last:  # a new mask the first time (the index's is kept), then in place
            reference_occupied = unmatched_reference(
                reference_occupied,
                moved,
                threshold,
                in_place=reference_occupied is not index.occupied,
            )
        elapsed = time.perf_counter() - t0
        excess = (k - chance) / k
        if target is not None:
            f = found[target]
            found[target] = Found(
                f.transform, np.concatenate([f.members, members]), f.confidence, f.seconds + elapsed
            )
        else:
            found.append(Found(transform, members, float(excess), elapsed))
        if last or not reference_occupied.any():
            break
    return found
