"""Local refinement of a registration on the measure itself.

The registration's hypotheses are already refined on the reference's distance map; what is
left is a residual of a fraction of a cell or degree, which far from the rotation centre can
still push cells over the masking threshold, and the angle of a small or elongated part can
be off by a degree or two. :func:`sweep_rotation` tries a fan of rotations about the agreeing
cells, :func:`refine_transform` (trimmed ICP) pulls the cells onto their nearest reference
walls, and :func:`polish_transform` climbs a smoothed
count of agreeing cells (:func:`soft_agreement`) by a compass search: each evaluation is one
vectorised bilinear lookup of the Manhattan distance map (no Python loop over cells).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from .._points import take_rows
from ..masking import ReferenceIndex
from ..masking.distance import DistanceMap, sample_at, sample_xy
from ..transform import RigidTransform

__all__ = [
    "fit_rigid",
    "polish_transform",
    "refine_transform",
    "refit_stages",
    "refit_transform",
    "soft_agreement",
    "soft_agreements",
    "sweep_rotation",
]


def _turn_about(
    pivot: NDArray[np.float64], angle: float, dx: float = 0.0, dy: float = 0.0
) -> RigidTransform:
    """Rotation by ``angle`` about ``pivot``, followed by a shift ``(dx, dy)``."""
    c, s = math.cos(angle), math.sin(angle)
    return RigidTransform(
        angle,
        pivot[0] - (c * pivot[0] - s * pivot[1]) + dx,
        pivot[1] - (s * pivot[0] + c * pivot[1]) + dy,
    )


def fit_rigid(source: NDArray[np.float64], target: NDArray[np.float64]) -> RigidTransform:
    """Least-squares rigid transform taking ``source`` points onto ``target`` (2D Kabsch).

    Parameters
    ----------
    source, target : ndarray, shape (N, 2)
        Corresponding points, ``N >= 2``.

    Returns
    -------
    RigidTransform
        ``t`` minimising ``sum |t(source) - target|^2``.
    """
    # sums and cross-products as BLAS products: numpy's axis-0 reductions of (N, 2) arrays
    # are several times slower, and ICP calls this on every iteration; the 2x2 algebra on
    # Python floats (the same IEEE operations as numpy's, without its per-call overhead)
    ones = np.ones(source.shape[0])
    n = float(source.shape[0])
    sx, sy = (ones @ source).tolist()
    tx, ty = (ones @ target).tolist()
    csx, csy, ctx, cty = sx / n, sy / n, tx / n, ty / n
    (h00, h01), (h10, h11) = (source.T @ target).tolist()  # cross-covariance (times N) ...
    h00 -= n * (csx * ctx)  # ... less the centroids' part
    h01 -= n * (csx * cty)
    h10 -= n * (csy * ctx)
    h11 -= n * (csy * cty)
    angle = math.atan2(h01 - h10, h00 + h11)
    c, si = math.cos(angle), math.sin(angle)
    return RigidTransform(angle, ctx - (c * csx - si * csy), cty - (si * csx + c * csy))


def refine_transform(
    transform: RigidTransform,
    points: NDArray[np.float64],
    nearest: Callable[[NDArray[np.float64], float], tuple[NDArray[np.intp], NDArray[np.float64]]],
    *,
    gate: float,
    iterations: int = 20,
    max_points: int = 2000,
) -> RigidTransform:
    """Trimmed ICP: move ``points`` closer to their nearest occupied reference cells.

    Parameters
    ----------
    transform : RigidTransform
        Starting estimate, map cells -> reference cells (scale 1).
    points : ndarray, shape (N, 2)
        Occupied map cells to align (others' cells may be among them: the gate rejects them).
    nearest : callable
        ``nearest(moved, gate)`` -> ``(rows, cells)``: the indices (ascending) of the moved
        points within ``gate`` of an occupied reference cell, and the nearest such cell of
        each, shape ``(len(rows), 2)``
        (:meth:`brokenness.masking.ReferenceIndex.correspondences`).
    gate : float
        Correspondences farther than this (cells) are ignored.
    iterations : int
        Largest number of iterations (it stops earlier once the steps vanish).
    max_points : int
        At most this many points take part, picked by a fixed stride (deterministic).

    Returns
    -------
    RigidTransform
        The refined transform, or ``transform`` itself if too few correspondences were found.
    """
    if points.shape[0] > max_points:
        points = points[:: int(math.ceil(points.shape[0] / max_points))]
    current = transform
    for _ in range(iterations):
        moved = current.apply(points)
        inliers, matched = nearest(moved, gate)
        if inliers.size < 3:
            break
        step = fit_rigid(moved.take(inliers, axis=0), matched)
        current = step.compose(current)
        if abs(step.rotation) < 1e-4 and math.hypot(step.tx, step.ty) < 1e-2:
            break
    return current


def sweep_rotation(
    transform: RigidTransform,
    points: NDArray[np.float64],
    distance_map: DistanceMap,
    threshold: float,
    pivot: NDArray[np.float64],
    *,
    half_range_deg: float = 3.0,
    step_deg: float = 0.25,
) -> RigidTransform:
    """Best rotation near ``transform``, turning the moved points about ``pivot``.

    The spectral rotation estimate of a small or elongated part (a corridor, say) can be off
    by a degree or two, and far from the centre that is more than the masking threshold and
    more than a local search recovers. Trying a fan of small rotations about the cells that
    already agree, and keeping the one with the best :func:`soft_agreement`, puts the polish
    into the right basin. The whole fan is scored in one lookup.

    Parameters
    ----------
    transform : RigidTransform
        Starting estimate.
    points : ndarray, shape (N, 2)
        Map cells.
    distance_map : ndarray of float32 or uint16
        The reference's Manhattan distance map.
    threshold : float
        Threshold of :func:`soft_agreement`.
    pivot : ndarray, shape (2,)
        Centre of the rotations, in reference cells.
    half_range_deg, step_deg : float
        The fan of rotations tried, in degrees.
    """
    n = int(round(half_range_deg / step_deg))
    deltas = [float(d) for d in np.radians(step_deg * np.arange(-n, n + 1)) if d != 0.0]
    moved = transform.apply(points)
    # the fan in the float32 of the lookup, each point rounded once from float64 as the
    # lookup would round it (no float64 copy of the fan), its columns and rows as two planes
    fan = _planes(len(deltas) + 1, moved.shape[0])
    fan[0][0], fan[1][0] = moved[:, 0], moved[:, 1]
    # the turns ascend from -half_range to half_range: turn k from the end is the negative
    # of turn k from the start
    half = len(deltas) // 2
    pairs = (slice(half, None), slice(half - 1, None, -1))
    _turned(moved, pivot, _trig(deltas), (fan[0][1:], fan[1][1:]), pairs)
    k = int(np.argmax(_soft_scores_xy(distance_map, fan, threshold)))
    # the first of equal scores: no turn wins ties
    return transform if k == 0 else _turn_about(pivot, deltas[k - 1]).compose(transform)


#: Points as two planes of one shape: their columns ``x`` and their rows ``y`` (float32, as
#: :func:`~brokenness.masking.distance.sample_xy` looks them up).
_Planes = tuple[NDArray[np.float32], NDArray[np.float32]]


def _planes(count: int, n: int) -> _Planes:
    """Two empty ``(count, n)`` float32 planes: ``count`` sets of ``n`` points."""
    return np.empty((count, n), dtype=np.float32), np.empty((count, n), dtype=np.float32)


#: Two sets of rows of a fan of turns, ``(a, b)``: the angle of row ``b[i]`` is the
#: negative of that of row ``a[i]``.
_Pairs = tuple[slice, slice]


def _trig(angles: list[float]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The cosines and sines of ``angles``, each of shape ``(len(angles), 1)``."""
    a = np.asarray(angles, dtype=np.float64)[:, None]
    return np.cos(a), np.sin(a)


def _turned(
    moved: NDArray[np.float64],
    pivot: NDArray[np.float64],
    trig: tuple[NDArray[np.float64], NDArray[np.float64]],
    out: _Planes,
    pairs: _Pairs | None = None,
) -> None:
    """Write ``moved`` turned about ``pivot`` by each of the angles whose :func:`_trig` is
    given to the planes ``out`` (each ``(len(angles), N)``: computed in float64, then
    rounded to float32); ``pairs`` as for :func:`_turn_offsets`."""
    _turn_offsets(_offsets(moved, pivot), pivot, trig, out, pairs)


def _columns(
    points: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The columns ``x`` and ``y`` of ``points`` (shape (N, 2)), each contiguous."""
    return np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1])


def _offsets(
    moved: NDArray[np.float64], pivot: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The points ``moved`` less ``pivot``, as the columns ``(dx, dy)`` that :func:`_turned`
    turns."""
    return moved[:, 0] - pivot[0], moved[:, 1] - pivot[1]


def _turn_offsets(
    offsets: tuple[NDArray[np.float64], NDArray[np.float64]],
    pivot: NDArray[np.float64],
    trig: tuple[NDArray[np.float64], NDArray[np.float64]],
    out: _Planes,
    pairs: _Pairs | None = None,
) -> None:
    """:func:`_turned` of the points whose :func:`_offsets` from ``pivot`` are given.

    Each point is ``(c dx - s dy + x0, s dx + c dy + y0)``, in float64, then rounded. With
    ``pairs``, the rows of the rest of the fan whose angles are negatives of each other,
    whose cosines are the same and whose sines are negated, bit for bit: the turn by ``-a``
    is then the sum and the difference of the same products as the turn by ``a``, exactly
    (``c dx - (-s) dy = c dx + s dy`` and ``(-s) dx + c dy = c dy - s dx``), half the
    products. Every row of ``out`` must be in one of the two sets.
    """
    c, s = trig
    if pairs is not None:
        pos, neg = pairs
        if c[neg].tobytes() == c[pos].tobytes() and s[neg].tobytes() == (-s[pos]).tobytes():
            _turn_pairs(offsets, pivot, (c[pos], s[pos]), (out[0][pos], out[1][pos]), out, neg)
            return
    dx, dy = offsets
    # c dx - s dy + x0 and s dx + c dy + y0 in float64 (one temporary each), then rounded
    # (an add into the float32 planes would buffer, and copy the pivot into its buffers)
    x = c * dx
    x -= s * dy
    x += pivot[0]
    out[0][...] = x
    y = s * dx
    y += c * dy
    y += pivot[1]
    out[1][...] = y


def _turn_pairs(
    offsets: tuple[NDArray[np.float64], NDArray[np.float64]],
    pivot: NDArray[np.float64],
    trig: tuple[NDArray[np.float64], NDArray[np.float64]],
    first: _Planes,
    out: _Planes,
    neg: slice,
) -> None:
    """:func:`_turn_offsets` of the turns by the angles ``a`` of ``trig`` (their cosines and
    sines) into the planes ``first`` and by the ``-a`` into the rows ``neg`` of ``out``."""
    dx, dy = offsets
    c, s = trig
    x0, y0 = pivot[0], pivot[1]
    cdx, sdy = c * dx, s * dy
    first[0][...] = _plus(cdx - sdy, x0)
    out[0][neg] = _plus(cdx + sdy, x0)
    sdx, cdy = s * dx, c * dy
    first[1][...] = _plus(sdx + cdy, y0)
    out[1][neg] = _plus(cdy - sdx, y0)


def _plus(values: NDArray[np.float64], shift: np.float64) -> NDArray[np.float64]:
    """``values + shift``, in place (``values`` is a temporary of the caller)."""
    values += shift
    return values


def _soft_scores(
    distance_map: DistanceMap, moved: NDArray[np.floating], threshold: float
) -> NDArray[np.float64]:
    """:func:`soft_agreement` of each set of moved points, ``moved`` of shape (K, N, 2)."""
    return _scores(sample_at(distance_map, moved, threshold + 1.0), threshold)


def _soft_scores_xy(
    distance_map: DistanceMap, moved: _Planes, threshold: float
) -> NDArray[np.float64]:
    """:func:`_soft_scores` of the points given as two ``(K, N)`` planes."""
    return _scores(sample_xy(distance_map, moved[0], moved[1], threshold + 1.0), threshold)


def _scores(d: NDArray[np.float32], threshold: float) -> NDArray[np.float64]:
    """:func:`soft_agreement` of each row of the samples ``d`` (shape (K, N))."""
    return np.asarray(np.maximum(threshold + 1.0 - d, 0.0).sum(axis=1, dtype=np.float64))


def soft_agreement(
    distance_map: DistanceMap, moved: NDArray[np.float64], threshold: float
) -> float:
    """Smooth version of the agreement count: ``sum(max(0, threshold + 1 - d))``.

    ``d`` is the reference's Manhattan distance map sampled bilinearly at the moved points
    (far away outside the grid), so that sub-cell moves change the score.
    """
    return float(_soft_scores(distance_map, moved[None], threshold)[0])


def soft_agreements(
    distance_map: DistanceMap,
    transforms: list[RigidTransform],
    points: NDArray[np.float64],
    threshold: float,
) -> NDArray[np.float64]:
    """:func:`soft_agreement` of ``points`` under each of ``transforms``, in one lookup."""
    n = points.shape[0]
    moved = np.empty((len(transforms), n, 2), dtype=np.float32)
    for i, t in enumerate(transforms):
        moved[i] = t.apply(points)
    return _soft_scores(distance_map, moved, threshold)


def polish_transform(
    transform: RigidTransform,
    points: NDArray[np.float64],
    distance_map: DistanceMap,
    threshold: float,
    *,
    max_points: int = 8000,
    max_evaluations: int = 200,
) -> RigidTransform:
    """Compass search on :func:`soft_agreement` around ``transform``.

    ICP minimises squared distances to the nearest reference cells, which clutter and thick
    walls bias by a cell or a fraction of a degree; the measure itself counts cells within
    the threshold. This search climbs the (smoothed) count directly: it tries steps in
    rotation (about the centroid of the points) and in x and y, keeps any improvement, and
    halves the steps when none helps, down to 0.02 degrees and 0.05 cells. The moves of a
    round are scored together, in one lookup, and the best improving one is taken.
    """
    if points.shape[0] > max_points:
        points = points[:: int(math.ceil(points.shape[0] / max_points))]
    moved = transform.apply(points)
    if moved.shape[0] == 0:
        return transform
    pivot = moved.mean(axis=0)
    best = transform
    best_score = soft_agreement(distance_map, moved, threshold)
    rot_step, shift_step = math.radians(0.4), 1.0
    evaluations = 0
    # the moves in the float32 of the lookup: each coordinate computed in float64 and
    # rounded once, as the lookup rounds a float64 one (the same samples, no float64 copy),
    # their columns and rows as two planes
    moves = _planes(6, moved.shape[0])
    mx, my = moves
    # moved's columns (contiguous), and their offsets from the pivot
    xs, ys = _columns(moved)
    offsets = (xs - pivot[0], ys - pivot[1])
    fresh = True  # moved changed since the last round
    while evaluations < max_evaluations and (rot_step > math.radians(0.02) or shift_step > 0.05):
        # the six compass moves around the current best (turns about the pivot, shifts in x
        # and y), scored together; the best one is taken if it improves, else the steps
        # are halved
        steps = (
            (rot_step, 0.0, 0.0),
            (-rot_step, 0.0, 0.0),
            (0.0, shift_step, 0.0),
            (0.0, -shift_step, 0.0),
            (0.0, 0.0, shift_step),
            (0.0, 0.0, -shift_step),
        )
        _turn_offsets(offsets, pivot, _trig([rot_step, -rot_step]), (mx[:2], my[:2]))
        # the four shifts, each along its own axis (float64 sums, rounded into the moves);
        # the other axis is moved's, written again only when moved has changed
        if fresh:
            my[2:4] = ys
            mx[4:6] = xs
            fresh = False
        mx[2], mx[3] = xs + shift_step, xs - shift_step
        my[4], my[5] = ys + shift_step, ys - shift_step
        scores = _soft_scores_xy(distance_map, moves, threshold)
        evaluations += len(steps)
        k = int(np.argmax(scores))
        if scores[k] > best_score:
            best = _turn_about(pivot, *steps[k]).compose(best)
            best_score = float(scores[k])
            xs, ys = _columns(best.apply(points))
            offsets = (xs - pivot[0], ys - pivot[1])
            fresh = True
        else:
            rot_step *= 0.5
            shift_step *= 0.5
    return best


def refit_transform(
    transform: RigidTransform,
    cells: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    gate: float,
) -> RigidTransform:
    """``transform`` refitted on ``cells``: the rotation fan about the cells that agree
    (:func:`sweep_rotation`), trimmed ICP within ``gate`` (:func:`refine_transform`), then
    the compass search on the cells that agree after it (:func:`polish_transform`).

    The refinement of the recursion's hypotheses, applied to a transform found elsewhere
    (a tile's partition in the settle step, a rival of a partition). ``transform`` itself
    if no cell agrees under it.
    """
    stages = refit_stages(transform, cells, index, threshold, gate)
    return transform if stages is None else stages[-1]


def refit_stages(
    transform: RigidTransform,
    cells: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    gate: float,
    iterations: int = 20,
) -> tuple[RigidTransform, RigidTransform, RigidTransform] | None:
    """The stages of :func:`refit_transform` (``iterations`` of the trimmed ICP): the
    transform swept, fitted and polished, in that order; ``None`` if no cell of ``cells``
    agrees under ``transform``."""
    moved = transform.apply(cells)
    agree = index.occupied_agreement(moved, threshold)
    if not agree.any():
        return None
    pivot = take_rows(moved, agree).mean(axis=0)
    swept = sweep_rotation(transform, cells, index.occupied_distance, threshold, pivot)
    fitted = refine_transform(swept, cells, index.correspondences, gate=gate, iterations=iterations)
    polished = polish_transform(
        fitted,
        take_rows(cells, index.occupied_agreement(fitted.apply(cells), threshold)),
        index.occupied_distance,
        threshold,
    )
    return swept, fitted, polished
