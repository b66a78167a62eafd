"""Where else a partition's cells fit: every translation at each rotation, the free space judging.

A small part placed at a *twin* of its place (a room of the same shape elsewhere in the
building, or its own room turned by 90 or 180 degrees) keeps, once every cell has gone to
the partition that explains it best, the cells that fit the twin. Registered alone
(:func:`~brokenness.measure.recovery.relocation_rivals`), those cells give the twin back:
the registration's translation peaks are few and pooled, and the twin is among the highest.
The true placement is nevertheless there to be found. On the maps of the realistic benchmark
whose degree was right but one partition stood at a twin, it made nearly as many of the
partition's cells agree as the twin did (160 of 161, 214 of 219), at a rotation among the
registration's hypotheses of those cells; only its translation was not among the peaks.
Counted over *every* translation, it is one of the few placements that explain the cells
about as well, and of those it is the one whose free space crosses the reference's walls
least often (a rate of 0.2 against 1.8 times that of a random placement, 0.3 against 0.5).

:func:`free_placement`, for one partition:

1. takes the rotations it is given (the partition's own and those of the hypotheses of its
   cells registered alone, or the opposite of its own), of those that turn no cell by half
   a coarse cell against an earlier one the first only (the refinement corrects the rest);
2. at each rotation counts, for every translation, the partition's cells that agree, on a
   coarse grid (:class:`CoarseAgreement`, ``2 threshold`` cells a side or coarser): the
   reference's agreement mask (cells within ``threshold`` of a wall), max-pooled and dilated
   by one coarse cell, correlated with the cells' counts per coarse cell. The coarse count
   is never below the count at full resolution of any translation it stands for, so a
   placement that explains enough cells is not lost to the coarse grid (only to the limit
   of :data:`PEAKS` below). A rotation at which no box the size of the grid's agreeing
   cells (:attr:`CoarseAgreement.extent`) holds the floor of step 3 is not counted: no
   translation there could reach it;
3. keeps the coarse placements that are local maxima and count at least the *floor*: the
   cells the partition's own transform makes agree, less ``z`` standard deviations of
   chance (``z sqrt(n p0 (1 - p0))`` for ``n`` cells and chance agreement ``p0``, the
   margin within which the recursion already treats two hypotheses as explaining about as
   many cells); of the :data:`PEAKS` highest over all rotations, those that do not stand
   for the partition's own placement (within a coarse cell's diagonal plus the loose
   threshold of it, on average: the refinement would bring them back to it) are placed to
   the cell (the translation, among those within a coarse cell, that makes the most of a
   sample of the cells agree) and refined at full resolution by the trimmed ICP that
   refines the registration's hypotheses;
4. of the refined placements that still reach the floor and put the cells elsewhere (more
   than the loose threshold from where the partition's transform puts them, on average),
   returns the one whose free space (the partition's clear free cells) has the lowest upper
   bound of its rate of crossing the reference's walls
   (:meth:`~brokenness.measure.evidence.Contradiction.upper_ratio`, same ``z``), if that is
   below the partition's own transform's rate.

The partitions placed this way are those whose free space does not show that they are in
place (at their own rotation and those of their hypotheses) and, after the last settling,
every other one, at the opposite of its own rotation only
(:func:`~brokenness.measure.recovery.relocation_rivals`). The placement is offered to
:func:`~brokenness.measure.settle.settle` as a rival, which
judges it as every rival: it must make more cells of the map agree than the partition's
transform does, by more than chance could, or by less but with the partition's free space
crossing walls significantly less often. This module only proposes.

Steps 2-3, :func:`placements`, are also the recovery's last search for a lost partition
(:meth:`~brokenness.measure.recovery._Search.placed`): the regions of suspect cells placed at
the rotations of their walls (:mod:`~brokenness.registration.orientation`), every
translation counted, the placements judged there by the recovery's own tests.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.fft
from numpy.typing import NDArray

from .._points import point_norms, squared_norms
from ..masking import ReferenceIndex
from ..transform import RigidTransform
from .evidence import Contradiction, chance_rate, landing
from .options import Settings
from .refine import refine_transform

__all__ = ["PEAKS", "CoarseAgreement", "coarse_counts", "free_placement", "placements"]


def _pool(threshold: float) -> int:
    """Side of a coarse cell, in cells of the working grid, at least: the largest at which
    the middle of a coarse cell is less than the agreement ``threshold`` from each
    translation it stands for along each axis (``(pool - 1) / 2 < threshold``; 4 cells at
    the default 2), so that a count does not stand for placements a wall's agreement band
    tells apart. A pool of 6 (from the refinement's gate, the loose threshold, instead) lost
    three of the seven maps of the realistic benchmark this search first made all true:
    coarser counts let more placements reach the floor, and the refinement started farther
    off."""
    return max(1, math.ceil(2.0 * threshold))


#: The coarse grid is at most this many cells a side (the pool grows for larger
#: references, so the correlations' cost stays bounded): at the smallest pool (4 cells at
#: the default threshold), references of up to 1536 cells a side (every reference of the
#: realistic benchmark and of the controls) are counted at it.
COARSE_SIDE = 384

#: Coarse placements refined at full resolution, at most (over all rotations): the refinement
#: and the free-space count are the cost of this step.
PEAKS = 16

#: Cells of a partition whose agreement places a coarse placement to the cell before it is
#: refined: every ``n // FINE_SAMPLE``-th of its ``n`` cells (256 to 511 of them, or all of
#: fewer).
FINE_SAMPLE = 256


@dataclass(frozen=True, eq=False)
class CoarseAgreement:
    """The reference's agreement mask on a coarse grid, for exhaustive translation counts.

    Attributes
    ----------
    grid : ndarray of float32, shape (H' + 1, W' + 1)
        1 where some cell of the coarse cell, or of the next coarse cell along either axis
        or both, is within ``threshold`` of an occupied reference cell (max-pooled, then
        dilated toward higher indices by one coarse cell: a translation that is not a
        multiple of the pool moves a cell into the next coarse cell at most). Coarse cell
        ``[i, j]`` holds the working grid's rows ``pool (i - 1)`` to ``pool i - 1`` and its
        columns ``pool (j - 1)`` to ``pool j - 1``: the first row and column lie before the
        reference.
    pool : int
        Cells of the working grid per coarse cell, along each axis.
    extent : tuple of int
        Rows and columns of the smallest box of coarse cells that holds every 1 of ``grid``
        (no translation can count more of a partition's cells than lie in a box of this
        size: :func:`_coarse_peaks` skips the rotations whose cells cannot reach the floor).
    """

    grid: NDArray[np.float32]
    pool: int
    extent: tuple[int, int]

    @classmethod
    def of(cls, index: ReferenceIndex, threshold: float) -> CoarseAgreement:
        """The coarse agreement grid of a reference at the agreement ``threshold``, from its
        occupied cells (a cell within ``threshold`` of one, Manhattan, is one of the
        cells around it; the cost follows the occupied cells, not the grid)."""
        h, w = index.reference.shape
        pool = max(_pool(threshold), math.ceil(max(h, w) / COARSE_SIDE))
        gh, gw = -(-h // pool), -(-w // pool)
        grid = np.zeros((gh, gw), dtype=np.uint8)
        x = index.occupied_points[:, 0].astype(np.intp)
        y = index.occupied_points[:, 1].astype(np.intp)
        reach = math.floor(threshold)
        for dy in range(-reach, reach + 1):
            for dx in range(-(reach - abs(dy)), reach - abs(dy) + 1):
                cx, cy = x + dx, y + dy
                on = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
                grid[cy[on] // pool, cx[on] // pool] = 1
        # one coarse row and column before the reference (a cell moved to just before its
        # first coarse cell may land in it), then each coarse cell or the next along
        # either axis
        padded = np.zeros((gh + 1, gw + 1), dtype=np.uint8)
        padded[1:, 1:] = grid
        dilated = padded.copy()
        dilated[:-1] |= padded[1:]
        dilated[:, :-1] |= dilated[:, 1:].copy()
        rows, cols = np.flatnonzero(dilated.any(axis=1)), np.flatnonzero(dilated.any(axis=0))
        extent = (int(rows[-1] - rows[0]) + 1, int(cols[-1] - cols[0]) + 1) if rows.size else (0, 0)
        return cls(dilated.astype(np.float32), pool, extent)


def free_placement(
    members: NDArray[np.float64],
    transform: RigidTransform,
    angles: Sequence[float],
    free: NDArray[np.float64],
    index: ReferenceIndex,
    coarse: CoarseAgreement,
    settings: Settings,
) -> RigidTransform | None:
    """The placement of a partition's cells that explains them about as well as its transform
    and whose free space crosses the reference's walls least (see the module docstring).

    Parameters
    ----------
    members : ndarray, shape (n, 2)
        The partition's cells ``(x, y)`` in the working grid.
    transform : RigidTransform
        The partition's transform.
    angles : sequence of float
        Rotations (radians) to try: the transform's own and those of the hypotheses of the
        cells registered alone, or only the opposite of its own (a half-turn twin).
    free : ndarray, shape (m, 2)
        The partition's clear free cells ``(x, y)`` (those
        :func:`~brokenness.measure.evidence.free_space` gives it).
    index : ReferenceIndex
        The reference, at the working resolution.
    coarse : CoarseAgreement
        ``index``'s coarse agreement grid at ``settings.threshold``.
    settings : Settings
        The per-map settings (``threshold``, ``loose``, ``significance``).

    Returns
    -------
    RigidTransform or None
        The placement, or ``None`` if no placement elsewhere reaches the floor with a lower
        rate of crossing walls than ``transform``'s.
    """
    if members.shape[0] < settings.min_cells:
        return None
    threshold, z = settings.threshold, settings.significance
    here = transform.apply(members)  # the partition's own placement
    own = int(np.count_nonzero(index.occupied_agreement(here, threshold)))
    p0 = index.chance_agreement(threshold)
    floor = own - z * math.sqrt(members.shape[0] * p0 * (1.0 - p0))
    # rotations that move no cell by half a coarse cell against each other are one
    radius = float(np.sqrt(squared_norms(members - members.mean(axis=0)).max()))
    same = coarse.pool / (2.0 * max(radius, 1.0))
    turns = _distinct(angles, same)
    chance = chance_rate(index)
    own_rate = _upper_rate(free, transform, index, chance, z)
    best, best_rate = None, own_rate
    for refined in placements(members, turns, index, coarse, settings, floor, besides=here):
        moved = refined.apply(members)
        if np.count_nonzero(index.occupied_agreement(moved, threshold)) < floor:
            continue
        if float(np.mean(point_norms(moved - here))) <= settings.loose:
            continue  # the partition's own placement
        rate = _upper_rate(free, refined, index, chance, z)
        if rate < best_rate:
            best, best_rate = refined, rate
    return best


def placements(
    members: NDArray[np.float64],
    angles: Sequence[float],
    index: ReferenceIndex,
    coarse: CoarseAgreement,
    settings: Settings,
    floor: float,
    peaks: int = PEAKS,
    besides: NDArray[np.float64] | None = None,
) -> Iterator[RigidTransform]:
    """The placements of ``members`` at ``angles`` (radians) whose coarse count reaches
    ``floor`` (steps 2-3 of the module docstring): the ``peaks`` highest local maxima over
    all angles, highest first, each placed to the cell and refined at full resolution by
    the trimmed ICP (gate: the loose threshold). A generator: each is refined when it is
    asked for.

    Parameters
    ----------
    members : ndarray, shape (n, 2)
        Cells ``(x, y)`` of the working grid.
    angles : sequence of float
        The rotations tried.
    index : ReferenceIndex
        The reference, at the working resolution.
    coarse : CoarseAgreement
        ``index``'s coarse agreement grid at ``settings.threshold``.
    settings : Settings
        The per-map settings (``threshold``, ``loose``).
    floor : float
        Coarse counts below this are not placed.
    peaks : int, optional
        Placements refined, at most.
    besides : ndarray, shape (n, 2), optional
        ``members`` where a placement already puts them: the coarse placements that put
        them within a coarse cell's diagonal plus the loose threshold of there, on average,
        are that placement and are not refined (the refinement, gated at the loose
        threshold, would bring them back to it).

    Yields
    ------
    RigidTransform
    """
    highest = _coarse_peaks(members, list(angles), coarse, floor)[:peaks]
    if besides is not None:
        near = settings.loose + coarse.pool * math.sqrt(2.0)
        highest = [
            p for p in highest if float(np.mean(point_norms(p.apply(members) - besides))) > near
        ]
    sample = members[:: max(1, members.shape[0] // FINE_SAMPLE)]
    for placement in highest:
        start = _fine(placement, sample, index, settings.threshold, coarse.pool)
        yield refine_transform(start, members, index.correspondences, gate=settings.loose)


def _fine(
    placement: RigidTransform,
    sample: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    pool: int,
) -> RigidTransform:
    """Where the refinement of a coarse placement starts: of the whole-cell translations
    within a coarse cell of those the placement stands for (``-pool`` to ``2 pool`` cells
    added along each axis), the middle of those that make the most of ``sample`` agree (a
    wall agrees over a band ``2 threshold + 1`` cells wide, so several translations do).

    A pool wider than that band (a reference so large that the coarse grid would be over
    :data:`COARSE_SIDE` cells a side; at the default threshold, over 1920 cells) is searched
    in steps of the band first, then cell by cell around the best step: a wall's band is
    not stepped over, and the lookups grow with ``(pool / band) ** 2`` only."""
    band = 2 * math.floor(threshold) + 1
    if pool <= band:
        return _best_shift(placement, sample, index, threshold, np.arange(-pool, 2 * pool + 1))
    stepped = _best_shift(placement, sample, index, threshold, np.arange(-pool, 2 * pool + 1, band))
    return _best_shift(stepped, sample, index, threshold, np.arange(1 - band, band))


def _best_shift(
    placement: RigidTransform,
    sample: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    steps: NDArray[np.int64],
) -> RigidTransform:
    """``placement`` shifted by the middle (the medoid, Manhattan) of the shifts (``steps``
    along each axis) that make the most of ``sample`` agree."""
    offsets = steps.astype(np.float64)
    shifts = np.stack(np.meshgrid(offsets, offsets), axis=-1).reshape(-1, 2)  # (x, y) rows
    moved = placement.apply(sample)
    agree = index.occupied_agreement((moved[None] + shifts[:, None]).reshape(-1, 2), threshold)
    counts = agree.reshape(shifts.shape[0], -1).sum(axis=1)
    tied = shifts[counts == counts.max()]
    # the middle of the tied shifts: the one nearest the others (the mean of two separate
    # groups, two walls' bands, could lie where nothing agrees)
    spread = np.abs(tied[:, None] - tied[None]).sum(axis=(1, 2))
    dx, dy = tied[int(np.argmin(spread))]
    return RigidTransform(placement.rotation, placement.tx + dx, placement.ty + dy)


def _distinct(angles: Sequence[float], same: float) -> list[float]:
    """``angles`` (radians) without those within ``same`` of an earlier one."""
    kept: list[float] = []
    for a in angles:
        if all(abs(math.remainder(a - b, math.tau)) >= same for b in kept):
            kept.append(float(a))
    return kept


def _coarse_peaks(
    members: NDArray[np.float64],
    angles: list[float],
    coarse: CoarseAgreement,
    floor: float,
) -> list[RigidTransform]:
    """The coarse placements (local maxima of the count, at least ``floor``) over all
    ``angles``, highest count first (ties: first angle, then row-major order).

    A rotation at which no box of the grid's :attr:`~CoarseAgreement.extent` holds
    ``floor`` of the cells is not correlated: no translation could count that many (a
    partition turned so that its cells spread wider than the reference's walls)."""
    least = max(1, math.ceil(floor))  # whole counts; at least one cell
    templates = _templates(members, angles, coarse.pool)
    reachable = [k for k, t in enumerate(templates) if _most_in_box(t[2], coarse.extent) >= least]
    correlated = _correlated([templates[k] for k in reachable], coarse)
    found: list[tuple[float, int, int, RigidTransform]] = []
    for k, (counts, placement) in zip(reachable, correlated, strict=True):
        # local maxima (3 x 3 coarse cells) that reach the floor, highest first; none within
        # 2 coarse cells of one kept before it (a plateau of equal counts is one placement),
        # and at most PEAKS an angle (no more are refined)
        top = cv2.dilate(counts, np.ones((3, 3), np.uint8))
        rows, cols = np.nonzero((counts >= top) & (counts >= least))
        order = np.argsort(-counts[rows, cols], kind="stable")  # highest first, row-major
        kept: list[tuple[int, int]] = []
        for r, q in zip(rows[order].tolist(), cols[order].tolist(), strict=True):
            if len(kept) == PEAKS:
                break
            if any(abs(r - a) <= 2 and abs(q - b) <= 2 for a, b in kept):
                continue
            kept.append((r, q))
            found.append((float(counts[r, q]), k, r * counts.shape[1] + q, placement(r, q)))
    found.sort(key=lambda f: (-f[0], f[1], f[2]))
    return [f[3] for f in found]


def coarse_counts(
    members: NDArray[np.float64], angles: Sequence[float], coarse: CoarseAgreement
) -> list[tuple[NDArray[np.float32], Callable[[int, int], RigidTransform]]]:
    """For every coarse translation of ``members`` turned by each of ``angles``, a count of
    its cells that agree, never below the count at full resolution of the translations it
    stands for.

    Per angle, the counts (a correlation of the cells' coarse counts with the grid, by FFT,
    the grid's spectrum computed once for all angles; whole numbers) and the placement of
    count ``[r, q]``: the lowest of the translations it stands for, those that add 0 to
    ``pool`` cells to it along each axis.
    """
    return _correlated(_templates(members, angles, coarse.pool), coarse)


#: A rotation's cells binned on the coarse grid: the angle, the lowest corner of the turned
#: cells and their count per coarse cell.
_Template = tuple[float, NDArray[np.float64], NDArray[np.floating]]


def _templates(members: NDArray[np.float64], angles: Sequence[float], pool: int) -> list[_Template]:
    """``members`` turned by each of ``angles`` and counted per coarse cell of ``pool``
    cells."""
    # single precision sums whole counts to well within a half below 2**16 cells (the
    # correlation runs in the templates' precision); beyond, double
    dtype = np.float32 if members.shape[0] < 2**16 else np.float64
    templates = []
    for angle in angles:
        c, s = math.cos(angle), math.sin(angle)
        turned = members @ np.array([[c, s], [-s, c]])
        low = np.floor(turned.min(axis=0))
        # a cell's lookup rounds it: binned after the same half-cell offset, each lands in
        # the coarse cell of its translation or the next one (which the grid's dilation
        # covers)
        cells = np.floor((turned - low + 0.5) / pool).astype(np.intp)
        shape = (int(cells[:, 1].max()) + 1, int(cells[:, 0].max()) + 1)
        template = np.zeros(shape, dtype=dtype)
        np.add.at(template, (cells[:, 1], cells[:, 0]), 1.0)
        templates.append((float(angle), low, template))
    return templates


def _most_in_box(template: NDArray[np.floating], box: tuple[int, int]) -> float:
    """The most of ``template``'s cells that one box of ``box`` coarse cells holds (every
    position of the box over the template, by an integral image)."""
    bh, bw = min(box[0], template.shape[0]), min(box[1], template.shape[1])
    if bh <= 0 or bw <= 0:
        return 0.0
    sums = cv2.integral(template, sdepth=cv2.CV_64F)
    held = sums[bh:, bw:] - sums[:-bh, bw:] - sums[bh:, :-bw] + sums[:-bh, :-bw]
    return float(held.max())


def _correlated(
    templates: list[_Template], coarse: CoarseAgreement
) -> list[tuple[NDArray[np.float32], Callable[[int, int], RigidTransform]]]:
    """:func:`coarse_counts` of the ``templates`` (the grid in their precision)."""
    if not templates:
        return []
    pool, grid = coarse.pool, coarse.grid
    grid = grid.astype(templates[0][2].dtype, copy=False)
    # linear (not circular) correlation: the transform is as large as grid and template
    th = max(t.shape[0] for _, _, t in templates)
    tw = max(t.shape[1] for _, _, t in templates)
    size = (
        scipy.fft.next_fast_len(grid.shape[0] + th - 1, real=True),
        scipy.fft.next_fast_len(grid.shape[1] + tw - 1, real=True),
    )
    spectrum = scipy.fft.rfft2(grid, size)
    out = []
    for angle, low, template in templates:
        h, w = template.shape
        full = scipy.fft.irfft2(spectrum * scipy.fft.rfft2(template[::-1, ::-1], size), size)
        # [r, q]: the template's coarse cell (0, 0) on the grid's (q - w + 1, r - h + 1)
        counts = np.rint(full[: grid.shape[0] + h - 1, : grid.shape[1] + w - 1])
        out.append((counts.astype(np.float32), _placement(angle, low, h, w, pool)))
    return out


def _placement(
    angle: float, low: NDArray[np.float64], h: int, w: int, pool: int
) -> Callable[[int, int], RigidTransform]:
    """The placement of count ``[r, q]`` of :func:`coarse_counts` (a template of ``h`` x
    ``w`` coarse cells, its cells' lowest corner ``low``): the lowest translation it stands
    for."""

    def placement(r: int, q: int) -> RigidTransform:
        # the template's coarse cell (0, 0) on the grid's coarse cell (q - w + 1, r - h + 1),
        # whose first working cell is pool (q - w) (the grid's first column lies before the
        # reference)
        tx = (q - w) * pool - low[0]
        ty = (r - h) * pool - low[1]
        return RigidTransform(angle, tx, ty)

    return placement


def _upper_rate(
    free: NDArray[np.float64],
    transform: RigidTransform,
    index: ReferenceIndex,
    chance: float,
    z: float,
) -> float:
    """:meth:`~brokenness.measure.evidence.Contradiction.upper_ratio` of the free cells
    ``free`` moved by ``transform`` (``chance``: the reference's
    :func:`~brokenness.measure.evidence.chance_rate`)."""
    n, x = landing(free, transform, index)
    return Contradiction(np.array([n]), np.array([x]), chance, 1).upper_ratio(z, 0)
