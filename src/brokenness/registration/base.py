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

__all__ = ["Candidate", "Registrar", "Registration"]


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
        All hypotheses that were scored, best first (the best is ``candidates[0]``).
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

    def prepare_reference(self, reference_states: NDArray[np.int8]) -> Any:
        """Precompute what depends on the reference only."""
        ...

    def candidates(
        self, prepared_reference: Any, moving_states: NDArray[np.int8], max_candidates: int
    ) -> list[Candidate]:
        """Ranked hypotheses (best first, at least one) for moving -> reference."""
        ...
