"""Brokenness: Algorithm 1 of Birk (2010) and its result types."""

from .options import BrokennessOptions
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
