"""Every hypothesis of a call, offered once more when the partitions are settled.

Each registration of the measure (a step of the recursion, a region, a group of suspect
cells in the recovery, a partition's own cells in the relocation) returns several ranked
hypotheses, and the stage that asked keeps the best one for the cells it registered. A
hypothesis that was second there, or that was registered on cells of several parts, may
still be the best transform of a partition found later: a part held at a twin of its room
(or as a compromise of two parts) is often exactly such a case, its true transform found by
an earlier registration of cells that were not yet its own (of four failing simulated maps
of the realistic benchmark traced, two had every part's true transform among the hypotheses
of the call, within a cell, the other two all but one part's, while a partition held a
part at a twin).

So the measure remembers every hypothesis (:class:`Recorded`, a registrar that records
what it returns, one group a registration; the relocation adds its placements, which no
registration returns), and once a map is measured, counts them as new partitions
(:func:`~brokenness.measure.recovery.pooled_partitions`: a part shifted along its
neighbour's walls, held by that neighbour, whose true transform an earlier registration
returned), then offers those that could make it agree more (:func:`offered`) to every
partition as rivals of the settle step, judged by the count alone
(``settle(..., by_count=True)``). Neither the degree nor the verdict is at stake there: a
rival that would empty a partition must still be significant, and the pass is undone if a
partition is then dropped or the map is no longer measured
(:func:`~brokenness.measure.recursion._rechosen`). So of two placements of a partition
already counted, the one under which more of the map's cells agree wins, as the
registration itself chooses.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..masking import ReferenceIndex
from ..registration.base import Candidate, Registrar
from ..transform import RigidTransform

__all__ = ["Recorded", "counts", "distinct_indices", "offered", "recorded_transforms"]

#: Hypotheses that put the map's centre within the same cell, at rotations within the same
#: half degree, are one: the first is kept (a partition's cells lie within a few hundred
#: cells of the centre, where the two differ by about a cell at most).
_ROTATION_STEP_DEG = 0.5
#: Cells of each partition looked up first, to pass over the hypotheses that cannot gain
#: in its place (an even sample; the others are looked up only for what is left).
_PROBE_CELLS = 256
#: Cells looked up at once (the agreement rows of a batch of hypotheses: bounded
#: temporaries, whatever the pool).
_BATCH_CELLS = 1 << 20


class Recorded:
    """A registrar that remembers every hypothesis it returns, in ``pool``: the hypotheses of
    each call as one group (the rivals of one another: a registration's chance), in order.

    Everything but :meth:`candidates` is the wrapped ``registrar``'s own (its optional
    attributes too), so the measure drives it as it would the registrar.
    """

    def __init__(self, registrar: Registrar, pool: list[tuple[Candidate, ...]]) -> None:
        self.registrar = registrar
        self._pool = pool
        self.name = registrar.name
        self.uses_free_space = registrar.uses_free_space

    def __getattr__(self, name: str) -> Any:
        if name == "registrar":  # not set yet (a copy being made): no recursion
            raise AttributeError(name)
        return getattr(self.registrar, name)

    def prepare_reference(self, reference_states: Any) -> Any:
        """The wrapped registrar's own."""
        return self.registrar.prepare_reference(reference_states)

    def candidates(
        self, prepared_reference: Any, moving_states: Any, max_candidates: int
    ) -> list[Candidate]:
        """The wrapped registrar's hypotheses, recorded (one group a call)."""
        out = self.registrar.candidates(prepared_reference, moving_states, max_candidates)
        if out:
            self._pool.append(tuple(out))
        return out


def recorded_transforms(pool: Sequence[Sequence[Candidate]]) -> list[RigidTransform]:
    """The transforms of every group of ``pool`` (as :class:`Recorded` keeps them), in order."""
    return [c.transform for group in pool for c in group]


def offered(
    pool: Sequence[RigidTransform],
    transforms: Sequence[RigidTransform],
    walls: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
) -> list[RigidTransform]:
    """The hypotheses of ``pool`` that could make more of ``walls`` agree in place of one of
    ``transforms``, most promising first.

    Replacing partition ``j``'s transform by a hypothesis gains at most the cells the
    hypothesis makes agree that no partition explains, less the cells only ``j`` explained
    and the hypothesis does not; a hypothesis is offered if that bound is positive for some
    partition (the settle step computes the gain itself). Distinct hypotheses only (see
    :data:`_ROTATION_STEP_DEG`); ordered by the bound, then as recorded.

    Parameters
    ----------
    pool : sequence of RigidTransform
        The hypotheses, as :class:`Recorded` kept them.
    transforms : sequence of RigidTransform
        The partitions' transforms.
    walls : ndarray, shape (N, 2)
        The map's occupied cells that count (isolated cells left out), ``(x, y)``.
    index : ReferenceIndex
        The reference.
    threshold : float
        Agreement threshold (cells).
    """
    if not pool or not transforms or walls.shape[0] == 0:
        return []
    agree = np.stack([index.occupied_agreement(t.apply(walls), threshold) for t in transforms])
    covered = np.count_nonzero(agree, axis=0)
    unexplained = walls[covered == 0]
    if unexplained.shape[0] == 0:
        return []  # nothing to gain: no hypothesis can make more cells agree
    distinct = [pool[k] for k in distinct_indices(pool, walls.mean(axis=0))]
    # the gain is at most the cells a hypothesis explains that no partition does: those
    # that explain none are passed over after a lookup of the unexplained cells alone
    new = counts(distinct, unexplained, index, threshold)
    alone = agree & (covered == 1)  # (P, N): the cells only each partition explains
    hopeful = _possible(distinct, new, walls, alone, index, threshold)
    candidates = [distinct[k] for k in hopeful]
    bounds = np.empty(len(candidates))
    only = alone.astype(np.float32)
    lost = only.sum(axis=1)  # what each partition loses if replaced by nothing
    for at, rows in _rows(candidates, walls, index, threshold):
        kept = rows.astype(np.float32) @ only.T  # (k, P): counts, exact in float32
        bounds[at] = (new[hopeful[at], None] + kept - lost[None, :]).max(axis=1)
    order = sorted(np.flatnonzero(bounds > 0).tolist(), key=lambda k: (-bounds[k], k))
    return [candidates[k] for k in order]


def _possible(
    transforms: Sequence[RigidTransform],
    new: NDArray[np.intp],
    walls: NDArray[np.float64],
    alone: NDArray[np.bool_],
    index: ReferenceIndex,
    threshold: float,
) -> NDArray[np.intp]:
    """Indices of the ``transforms`` that may gain in place of some partition: in place of
    partition ``j`` the gain is ``new`` less the cells only ``j`` explains (``alone[j]``) that
    the hypothesis does not; an even sample of those cells that already misses ``new`` of
    them rules ``j`` out (exactly: the sample's misses are some of the misses)."""
    hopeful = np.flatnonzero(new > 0)
    them = [transforms[k] for k in hopeful.tolist()]
    possible = np.zeros(hopeful.size, dtype=bool)
    for only_j in alone:
        cells = walls[only_j]
        probe = cells[:: max(1, -(-cells.shape[0] // _PROBE_CELLS))]
        possible |= probe.shape[0] - counts(them, probe, index, threshold) < new[hopeful]
    return hopeful[possible]


def counts(
    transforms: Sequence[RigidTransform],
    cells: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
) -> NDArray[np.intp]:
    """How many of ``cells`` agree under each of ``transforms``."""
    out = np.zeros(len(transforms), dtype=np.intp)
    for at, rows in _rows(transforms, cells, index, threshold):
        out[at] = np.count_nonzero(rows, axis=1)
    return out


def _rows(
    transforms: Sequence[RigidTransform],
    cells: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
) -> Iterator[tuple[slice, NDArray[np.bool_]]]:
    """Which of ``cells`` agree under each of ``transforms``, in batches of about
    :data:`_BATCH_CELLS` lookups: ``(the batch's slice of transforms, its rows)``."""
    n = cells.shape[0]
    if n == 0:
        return
    per_batch = max(1, _BATCH_CELLS // n)
    for start in range(0, len(transforms), per_batch):
        batch = transforms[start : start + per_batch]
        moved = np.empty((len(batch) * n, 2))
        for k, t in enumerate(batch):
            moved[k * n : (k + 1) * n] = t.apply(cells)
        rows = index.occupied_agreement(moved, threshold).reshape(len(batch), n)
        yield slice(start, start + len(batch)), rows


def distinct_indices(pool: Sequence[RigidTransform], centre: NDArray[np.float64]) -> list[int]:
    """The index of the first of each group of hypotheses of ``pool`` that put ``centre`` in
    the same cell at the same half degree of rotation, in order."""
    if not pool:
        return []
    angle = np.array([t.rotation for t in pool])
    shift = np.array([(t.tx, t.ty) for t in pool])
    scale = np.array([t.scale for t in pool])
    cos, sin = scale * np.cos(angle), scale * np.sin(angle)
    x = np.rint(cos * centre[0] - sin * centre[1] + shift[:, 0]).astype(np.int64)
    y = np.rint(sin * centre[0] + cos * centre[1] + shift[:, 1]).astype(np.int64)
    turn = np.rint(np.degrees(angle) / _ROTATION_STEP_DEG).astype(np.int64)
    turn %= round(360.0 / _ROTATION_STEP_DEG)
    seen: dict[tuple[int, int, int], int] = {}
    for k, key in enumerate(zip(x.tolist(), y.tolist(), turn.tolist(), strict=True)):
        seen.setdefault(key, k)
    return list(seen.values())
