"""brokenness: how structurally broken is an occupancy-grid map?

Implements A. Birk, "Using Recursive Spectral Registrations to Determine Brokenness as
Measure of Structural Map Errors", ICRA 2010: a map is broken with degree n when it splits
into n + 1 partitions, each consistent with the reference on its own but rigidly "off"
relative to each other.

The pipeline, one subpackage each: :mod:`~brokenness.io` (maps in) ->
:mod:`~brokenness.registration` (iFMI, random walk) -> :mod:`~brokenness.masking`
(Psi, Psi_2) -> :mod:`~brokenness.measure` (Algorithm 1) -> :mod:`~brokenness.report`
and :mod:`~brokenness.cli`; :mod:`~brokenness.simulation` makes broken maps of known
degree; :func:`timeline` (in :mod:`brokenness.timeline`) follows the brokenness over the
map messages of a bag.
"""

from __future__ import annotations

__version__ = "0.1.0"

from .errors import (
    BrokennessError,
    MapError,
    MapFormatError,
    MapSizeError,
    NothingFoundWarning,
    ParameterError,
)
from .grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from .io import MapWarning, load_map, resample_to_resolution, save_map
from .masking import picture_distance
from .measure import (
    NOT_OCCUPIED,
    UNASSIGNED,
    BrokennessOptions,
    BrokennessResult,
    Partition,
    compute_brokenness,
)
from .registration import Registration, register
from .simulation import SimulatedMap, save_simulation, simulate_broken_map
from .timeline import timeline  # the function (the subpackage: brokenness.timeline.*)
from .transform import RigidTransform

__all__ = [
    "FREE",
    "NOT_OCCUPIED",
    "OCCUPIED",
    "UNASSIGNED",
    "UNKNOWN",
    "BrokennessError",
    "BrokennessOptions",
    "BrokennessResult",
    "MapError",
    "MapFormatError",
    "MapSizeError",
    "MapWarning",
    "NothingFoundWarning",
    "OccupancyMap",
    "ParameterError",
    "Partition",
    "Registration",
    "RigidTransform",
    "SimulatedMap",
    "__version__",
    "compute_brokenness",
    "load_map",
    "picture_distance",
    "register",
    "resample_to_resolution",
    "save_map",
    "save_simulation",
    "simulate_broken_map",
    "timeline",
]
