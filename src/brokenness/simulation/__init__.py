"""Synthetic broken maps of known degree: buildings, a simulated laser, a mapper, bump noise.

- :mod:`.building`: seeded floor plans (rooms, corridors, doors, clutter, slanted walls);
- :mod:`.mapper`: a vectorised log-odds occupancy-grid mapper for 2D laser scans;
"""

from __future__ import annotations

from .building import Building, generate_building
from .mapper import ScanCounts, counts_to_map, grid_geometry, map_scans, scan_counts

__all__ = [
    "Building",
    "ScanCounts",
    "counts_to_map",
    "generate_building",
    "grid_geometry",
    "map_scans",
    "scan_counts",
]
