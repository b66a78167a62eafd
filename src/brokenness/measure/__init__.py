"""Brokenness: Algorithm 1 of Birk (2010) and its result types.

:class:`BrokennessOptions` is loaded with the package (a batch checks its options before
any work); the other names (numpy, OpenCV, SciPy) on first use (:mod:`brokenness._lazy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports
from .options import BrokennessOptions

if TYPE_CHECKING:
    from .recursion import compute_brokenness
    from .result import NOT_OCCUPIED, UNASSIGNED, BrokennessResult, Partition

__all__ = [
    "NOT_OCCUPIED",
    "UNASSIGNED",
    "BrokennessOptions",
    "BrokennessResult",
    "Partition",
    "compute_brokenness",
]

__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "compute_brokenness": ".recursion",
        **dict.fromkeys(("NOT_OCCUPIED", "UNASSIGNED", "BrokennessResult", "Partition"), ".result"),
    },
)
