"""What every registration method returns, and the interface the recursion uses.

A registration finds the rigid transform that maps cells of a *moving* map onto a
*reference* (see :mod:`brokenness.transform` for the convention). Methods offer several
ranked *candidates*, because the recursion of :func:`brokenness.compute_brokenness` picks
among them the one under which the largest part of the map agrees with the reference.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ..transform import RigidTransform

__all__ = ["Candidate", "CellsRegistrar", "OccupiedCells", "Registrar", "Registration"]


@dataclass(frozen=True)
class Candidate:
    """One hypothesis of a registration method.

    Attributes
    ----------
    transform : RigidTransform
        Moving cells -> reference cells.
    confidence : float
        Method-specific quality of the hypothesis in [0, 1] (1 = unambiguous).
    acceptance : float, optional
        Birk & Carpin's acceptance indicator ``agree / (agree + disagree)`` of the
        hypothesis (cells known in both maps with the same / a different state), when the
        method computes it (the random walk does; iFMI leaves it ``None``).
    """

    transform: RigidTransform
    confidence: float
    acceptance: float | None = None


@dataclass(frozen=True, eq=False)
class OccupiedCells:
    """The occupied cells of a moving map, as a crop of its grid (the rest is unknown).

    What a registration that looks at occupied cells only needs of a moving map, without a
    grid of the map's size: the recursion builds it from the cells left in each step, at a
    cost that follows those cells, not the canvas.

    Attributes
    ----------
    crop : ndarray of bool, 2D
        The occupied cells inside the box ``rows row0 .. row0 + crop.shape[0] - 1``,
        ``columns col0 .. col0 + crop.shape[1] - 1`` of the grid; no cell outside the box is
        occupied.
    offset : (int, int)
        ``(col0, row0)``.
    shape : (int, int)
        ``(rows, cols)`` of the whole grid.
    points : ndarray of int32, shape (N, 2), optional
        ``(x, y)`` of the occupied cells in the crop, row by row (the order of
        ``cv2.findNonZero``), when the maker has them at hand: then they are not looked for
        in the crop again.
    """

    crop: NDArray[np.bool_]
    offset: tuple[int, int]
    shape: tuple[int, int]
    points: NDArray[np.int32] | None = None

    @property
    def count(self) -> int:
        """Number of occupied cells."""
        if self.points is not None:
            return int(self.points.shape[0])
        return int(np.count_nonzero(self.crop))

    def flat_indices(self) -> NDArray[np.intp]:
        """Indices of the occupied cells in the flattened crop, ascending."""
        if self.points is None:
            return np.flatnonzero(self.crop)
        width = self.crop.shape[1]
        return self.points[:, 1].astype(np.intp) * width + self.points[:, 0]

    def states(self) -> NDArray[np.int8]:
        """The whole grid as cell states: occupied (1) on the cells, unknown (-1) elsewhere."""
        out = np.full(self.shape, -1, dtype=np.int8)
        c0, r0 = self.offset
        h, w = self.crop.shape
        out[r0 : r0 + h, c0 : c0 + w][self.crop] = 1
        return out

    def same(self, other: OccupiedCells) -> bool:
        """Whether ``other`` holds the same cells of a grid of the same shape."""
        return (
            self.shape == other.shape
            and self.offset == other.offset
            and self.crop.shape == other.crop.shape
            and bool(np.array_equal(self.crop, other.crop))
        )


@dataclass(frozen=True)
class Registration:
    """Result of :func:`brokenness.register`.

    Attributes
    ----------
    transform : RigidTransform
        Best transform, moving cells -> reference cells (with its world part when both maps
        have a resolution and origin).
    confidence : float
        Quality of the best hypothesis in [0, 1].
    candidates : tuple of Candidate
        The first ``max_candidates`` of the ranking of the hypotheses examined, best first
        (the best is ``candidates[0]``).
    method : str
        ``"ifmi"`` or ``"random-walk"``.
    seconds : float
        Wall-clock time of the registration.
    """

    transform: RigidTransform
    confidence: float
    candidates: tuple[Candidate, ...]
    method: str
    seconds: float

    @property
    def rotation_deg(self) -> float:
        """Rotation of the best transform, degrees."""
        return self.transform.rotation_deg

    @property
    def translation(self) -> tuple[float, float]:
        """Translation of the best transform, reference cells."""
        return self.transform.translation

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "method": self.method,
            "transform": self.transform.to_dict(),
            "confidence": self.confidence,
            "seconds": self.seconds,
            "candidates": [
                {
                    "transform": c.transform.to_dict(),
                    "confidence": c.confidence,
                    "acceptance": c.acceptance,
                }
                for c in self.candidates
            ],
        }


class Registrar(Protocol):
    """A registration method as the recursion of Algorithm 1 drives it.

    ``prepare_reference`` does the work that depends on the reference only (spectra,
    distance maps) so that it can be reused; ``candidates`` registers one moving map
    against a prepared reference. Both take cell-state arrays (int8: 1 occupied, 0 free,
    -1 unknown); the reference and the moving map may differ in shape.
    """

    name: str
    #: Whether the method looks at free cells. If not, the recursion skips withdrawing the
    #: free space around masked cells (a distance transform per step).
    uses_free_space: bool
    # Optional attribute ``accepts_cells`` (absent: False): the method is also a
    # :class:`CellsRegistrar`.

    def prepare_reference(self, reference_states: NDArray[np.int8]) -> Any:
        """Precompute what depends on the reference only."""
        ...

    def candidates(
        self, prepared_reference: Any, moving_states: NDArray[np.int8], max_candidates: int
    ) -> list[Candidate]:
        """Ranked hypotheses (best first, at least one) for moving -> reference."""
        ...


class CellsRegistrar(Registrar, Protocol):
    """A registration whose ``prepare_reference`` and ``candidates`` also take the maps as
    :class:`OccupiedCells` (a method that looks at occupied cells only; its
    ``accepts_cells`` is True): the recursion then builds no grid of the map's size per
    step."""

    accepts_cells: bool

    def prepare_reference(self, reference_states: NDArray[np.int8] | OccupiedCells) -> Any:
        """Precompute what depends on the reference only."""
        ...

    def candidates(
        self,
        prepared_reference: Any,
        moving_states: NDArray[np.int8] | OccupiedCells,
        max_candidates: int,
    ) -> list[Candidate]:
        """Ranked hypotheses (best first, at least one) for moving -> reference."""
        ...
