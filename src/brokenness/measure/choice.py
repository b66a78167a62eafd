"""Which hypothesis a step of the recursion keeps.

A step has hypotheses registered with the whole reference R and, at times, with R' (the
reference less the walls earlier partitions matched); :func:`choose` picks the best of a pool
(:func:`~brokenness.measure.hypotheses.best_hypothesis`), asking the remainder's
:class:`Neighbourhood` for more when that best is not significant, and
:func:`prefer_unexplained` decides between the best of R and of R'. The reasons are in the
docstring of :mod:`brokenness.measure.recursion` ("Two references", "Neighbourhood").
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..grid import OccupancyMap
from ..masking import ReferenceIndex, sample_at
from ..registration.base import Candidate, Registrar
from ..transform import RigidTransform
from .hypotheses import best_hypothesis
from .views import neighbourhood, remainder_states

__all__ = [
    "NEIGHBOURHOOD_CELLS",
    "Neighbourhood",
    "choose",
    "mostly_claimed",
    "prefer_unexplained",
]

#: Radius (cells) of the map around the cells left that a registration includes when the
#: cells left alone give no significant hypothesis.
NEIGHBOURHOOD_CELLS = 8


class Neighbourhood:
    """Hypotheses for a step's remainder registered with the map around it (on demand, once).

    See "Neighbourhood" in :mod:`brokenness.measure.recursion`. Without a registrar (the
    random walk), or when the neighbourhood adds no cell, there are none.
    """

    def __init__(
        self,
        registrar: Registrar | None,
        reference: Any,
        working: OccupancyMap,
        rows: NDArray[np.intp],
        cols: NDArray[np.intp],
        remaining: NDArray[np.bool_],
        uses_free: bool,
        limit: int,
    ) -> None:
        self.registrar = registrar
        self.limit = limit
        self.reference = reference
        self.working = working
        self.rows, self.cols = rows, cols
        self.remaining = remaining.copy()
        self.uses_free = uses_free
        self._found: list[Candidate] | None = None

    def hypotheses(self) -> list[Candidate]:
        if self._found is None:
            self._found = []
            near = neighbourhood(
                self.working.shape, self.rows, self.cols, self.remaining, NEIGHBOURHOOD_CELLS
            )
            if self.registrar is not None and np.count_nonzero(near) > np.count_nonzero(
                self.remaining
            ):
                states = remainder_states(
                    self.working, self.rows, self.cols, near, self.uses_free, drop_isolated=False
                )
                self._found = self.registrar.candidates(self.reference, states, self.limit)
        return self._found


def choose(
    candidates: list[Candidate],
    points: NDArray[np.float64],
    index: ReferenceIndex,
    threshold: float,
    needed: float,
    refined: dict[Any, Any],
    context: Neighbourhood,
) -> tuple[RigidTransform, NDArray[np.bool_]] | None:
    """The best hypothesis of ``candidates`` for the remainder ``points``; if it is not
    significant (fewer than ``needed`` agreeing cells), with the neighbourhood's ones too."""
    chosen = best_hypothesis(candidates, points, index, threshold, refined)
    if chosen is not None and np.count_nonzero(chosen[1]) >= needed:
        return chosen
    extra = context.hypotheses()
    if not extra:
        return chosen
    wider = best_hypothesis(candidates + extra, points, index, threshold, refined)
    if wider is not None and (
        chosen is None or np.count_nonzero(wider[1]) > np.count_nonzero(chosen[1])
    ):
        return wider
    return chosen


def prefer_unexplained(
    best: tuple[RigidTransform, NDArray[np.bool_]],
    best_rest: tuple[RigidTransform, NDArray[np.bool_]] | None,
    margin: float,
) -> tuple[RigidTransform, NDArray[np.bool_]]:
    """The hypothesis a step keeps: the best of all, or the best registered with R'.

    Parameters
    ----------
    best : (RigidTransform, ndarray of bool)
        The best hypothesis among those registered with the whole reference R and with R'
        (the reference less the walls earlier partitions matched), with the cells of the
        remainder that agree under it.
    best_rest : (RigidTransform, ndarray of bool) or None
        The best among those registered with R' only.
    margin : float
        Agreeing cells that chance alone could account for (``z sigma`` of the stopping rule).

    Returns
    -------
    (RigidTransform, ndarray of bool)
        ``best_rest`` if it explains at least as many cells as ``best`` less ``margin`` (the
        two explain the remainder equally well, and ``best_rest`` puts it where no partition
        is yet), else ``best``.
    """
    if best_rest is None:
        return best
    if np.count_nonzero(best_rest[1]) >= np.count_nonzero(best[1]) - margin:
        return best_rest
    return best


def mostly_claimed(
    best: tuple[RigidTransform, NDArray[np.bool_]],
    points: NDArray[np.float64],
    near_claimed: NDArray[np.bool_],
    threshold: float,
) -> bool:
    """Whether most agreeing cells of ``best`` land on walls earlier partitions matched.

    ``near_claimed`` marks the reference cells within ``threshold`` of such walls
    (:func:`~brokenness.masking.within_manhattan`); the moved cells are rounded to the
    nearest cell, cells off the grid are not on them.
    """
    transform, agree = best
    if not agree.any():
        return False
    flags = near_claimed.view(np.uint8).astype(np.float32)
    on_claimed = sample_at(flags, transform.apply(points[agree]), 0.0, nearest=True) > 0.5
    return bool(np.count_nonzero(on_claimed) * 2 >= np.count_nonzero(agree))
