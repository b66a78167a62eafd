"""Masking: Birk's similarity functions on occupancy grids.

- :func:`picture_distance` -- the global picture distance Psi between two maps;
- :class:`ReferenceIndex` -- the local agreement Psi_2 used to mask the cells of the map
  that a transform aligns with the reference;
- :func:`manhattan_distance_map` -- the linear-time distance maps both are built on.
"""

from .agreement import ReferenceIndex, cell_points, unmatched_reference, within_manhattan
from .distance import lookup_distance, manhattan_distance_map, sample_at
from .similarity import picture_distance

__all__ = [
    "ReferenceIndex",
    "cell_points",
    "lookup_distance",
    "sample_at",
    "manhattan_distance_map",
    "picture_distance",
    "unmatched_reference",
    "within_manhattan",
]
