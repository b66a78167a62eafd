"""Choosing, in each step, the registration hypothesis that aligns most of the remainder best."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._points import point_norms
from ..masking import ReferenceIndex
from ..registration.base import Candidate
from ..transform import RigidTransform
from .refine import refit_stages, soft_agreements

__all__ = ["RIVAL_QUANTILE", "best_hypothesis", "rival_chance"]

#: Candidates (by smooth agreement) that get the full refinement in each step.
REFINED_CANDIDATES = 2
#: At most this many cells (an even stride of them) score the hypotheses of a step.
SAMPLE_CELLS = 3000
#: Largest number of trimmed-ICP iterations of a refinement.
ICP_ITERATIONS = 8
#: The quantile of the rival hypotheses' agreement shares taken as chance
#: (:func:`rival_chance`): the upper quartile, not the median, errs on the side of chance
#: (the hypotheses of a registration are already biased towards agreement). The median
#: measured the same on the realistic benchmark, but let more maps of other places past
#: the stopping rule (to the contradiction test: 375 of 392 against 342).
RIVAL_QUANTILE = 0.75


def best_hypothesis(
    candidates: list[Any],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    refined: dict[tuple[float, float, float], list[tuple[RigidTransform, float]]] | None = None,
) -> tuple[RigidTransform, NDArray[np.bool_]] | None:
    """Refine the most promising candidates; keep the one that aligns the most cells best.

    Candidates are ranked by the smooth agreement score (:func:`soft_agreement`), which
    rewards exact alignment over loose agreement: a transform that gains a few cells of
    another partition by tilting the main one a little must not win.

    ``refined``, if given, remembers the refinements of each candidate transform; pass the
    same dictionary to calls on the same ``points`` (and only those) to skip repeated work.
    """
    memo: dict[tuple[float, float, float], list[tuple[RigidTransform, float]]] = (
        {} if refined is None else refined
    )

    def hard(moved: NDArray[np.float64]) -> NDArray[np.bool_]:
        return index.occupied_agreement(moved, threshold)

    sample = _sample(points)
    rigid = _rigid(candidates)
    values = soft_agreements(
        index.occupied_distance, [c.transform for c in rigid], sample, threshold
    )
    raw = [(float(v), i, c) for i, (v, c) in enumerate(zip(values, rigid, strict=True))]
    raw.sort(key=lambda item: (-item[0], item[1]))
    best: RigidTransform | None = None
    best_score = -1.0
    # Refine the best hypothesis, and the runner-up only when it scored comparably.
    contenders = [c for value, _, c in raw[:REFINED_CANDIDATES] if value >= 0.5 * raw[0][0]]
    for cand in contenders:
        t = cand.transform
        key = (t.rotation, t.tx, t.ty)
        if key not in memo:
            memo[key] = _refinements(t, sample, index, threshold)
        for option, value in memo[key]:
            if value > best_score:
                best_score = value
                best = option
    if best is None:
        return None
    return best, hard(best.apply(points))


def _sample(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """The evenly strided sample (at most :data:`SAMPLE_CELLS`) hypotheses are scored on."""
    return points[:: max(1, -(-points.shape[0] // SAMPLE_CELLS))]


def _rigid(candidates: list[Any]) -> list[Candidate]:
    """The rigid hypotheses, as exact rigid transforms (a registration's matrix algebra may
    leave the scale at 1 +- 1e-15)."""
    return [
        Candidate(
            RigidTransform(c.transform.rotation, c.transform.tx, c.transform.ty), c.confidence
        )
        for c in candidates
        if abs(c.transform.scale - 1.0) < 1e-6
    ]


def _refinements(
    transform: RigidTransform, sample: NDArray[np.float64], index: ReferenceIndex, threshold: float
) -> list[tuple[RigidTransform, float]]:
    """The stages of the refinement of one candidate (:func:`~brokenness.measure.refine.
    refit_stages`, ICP gated at ``threshold + 1`` cells, :data:`ICP_ITERATIONS` iterations),
    each with its score (best stage last)."""
    stages = refit_stages(transform, sample, index, threshold, threshold + 1.0, ICP_ITERATIONS)
    if stages is None:
        return []
    swept, fitted, polished = stages
    options = [polished, fitted, swept, transform]
    scores = soft_agreements(index.occupied_distance, options, sample, threshold)
    return [(option, float(v)) for option, v in zip(options, scores, strict=True)]


#: Candidates compared with the best one per pass in :func:`rivals`.
_RIVAL_CHUNK = 8


def rivals(
    candidates: Sequence[Candidate], sample: NDArray[np.float64], best: RigidTransform, apart: float
) -> list[tuple[Candidate, NDArray[np.float64]]]:
    """The candidates that put ``sample`` (on average) more than ``apart`` cells from where
    ``best`` does (not the best hypothesis itself, nor a copy of it), each with ``sample``
    moved by it."""
    if not candidates:
        return []
    at_best = best.apply(sample)
    moved = [c.transform.apply(sample) for c in candidates]
    # the candidates' mean distances, _RIVAL_CHUNK candidates a pass (bounded temporaries
    # however many hypotheses a step pools): each point's norm over its last axis and each
    # candidate's mean a reduction of its own row (the same sums, in the same order, as one
    # candidate at a time)
    mean: list[float] = []
    for start in range(0, len(moved), _RIVAL_CHUNK):
        chunk = np.stack(moved[start : start + _RIVAL_CHUNK])
        mean += point_norms(chunk - at_best).mean(axis=1).tolist()
    return [(c, m) for c, m, d in zip(candidates, moved, mean, strict=True) if d > apart]


def rival_chance(
    candidates: list[Any],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    best: RigidTransform,
    apart: float,
    p0: float,
) -> float:
    """The chance agreement of the stopping rule for ``points`` and the hypothesis ``best``.

    ``p0`` (a cell dropped at random on the known reference area agrees) overestimates
    chance when much of the map lands off the reference's known area and its cells are
    lines, not scattered dots: at 0.1 m cells with ``c = 2`` a dense reference has
    ``p0 = 0.3``, while wrong transforms of a broken map make 8-13 % of its cells agree
    (median; 12-15 % at the upper quartile). The step's *rival* hypotheses -- the
    candidates that put the cells, on average, more than ``apart`` cells from where ``best``
    does -- are such wrong transforms of this very map onto this very reference (a few of
    them may be other true parts): the upper quartile of their agreement shares
    (:data:`RIVAL_QUANTILE`, on the same strided sample of at most :data:`SAMPLE_CELLS`
    cells as the scores) is chance for them. Returns ``min(p0, that quartile)``; ``p0``
    when there is no rival.
    """
    sample = _sample(points)
    if sample.shape[0] == 0:
        return p0
    shares = [
        np.count_nonzero(index.occupied_agreement(moved, threshold))
        for _, moved in rivals(_rigid(candidates), sample, best, apart)
    ]
    if not shares:
        return p0
    rival = float(np.quantile(np.asarray(shares, dtype=np.float64), RIVAL_QUANTILE))
    return min(p0, rival / sample.shape[0])
