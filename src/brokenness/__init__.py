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

The public names are imported on first use (:mod:`brokenness._lazy`): ``import brokenness``
itself loads neither numpy nor OpenCV nor SciPy, so that the command line, and a batch
process that only hands pairs to its workers, start in a few tens of milliseconds.
"""

from __future__ import annotations

__version__ = "0.1.0"

import sys
import types
from typing import TYPE_CHECKING, Any

from ._lazy import lazy_exports
from .errors import (
    BrokennessError,
    MapError,
    MapFormatError,
    MapSizeError,
    MissingDependencyError,
    NothingFoundWarning,
    ParameterError,
)

if TYPE_CHECKING:
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
    "MissingDependencyError",
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

#: Where each public name is defined (imported on first use).
_EXPORTS = {
    **dict.fromkeys(("FREE", "OCCUPIED", "UNKNOWN", "OccupancyMap"), ".grid"),
    **dict.fromkeys(("MapWarning", "load_map", "resample_to_resolution", "save_map"), ".io"),
    "picture_distance": ".masking",
    **dict.fromkeys(
        (
            "NOT_OCCUPIED",
            "UNASSIGNED",
            "BrokennessOptions",
            "BrokennessResult",
            "Partition",
            "compute_brokenness",
        ),
        ".measure",
    ),
    **dict.fromkeys(("Registration", "register"), ".registration"),
    **dict.fromkeys(("SimulatedMap", "save_simulation", "simulate_broken_map"), ".simulation"),
    "timeline": ".timeline",
    "RigidTransform": ".transform",
}
#: Submodules that ``import brokenness`` used to load, still attributes of the package.
_SUBMODULES = (
    "errors",
    "grid",
    "io",
    "limits",
    "masking",
    "measure",
    "registration",
    "simulation",
    "transform",
)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, _SUBMODULES)


class _Package(types.ModuleType):
    """The ``brokenness`` module: its attribute ``timeline`` stays the function.

    Importing a subpackage makes it an attribute of its parent: ``from brokenness.timeline
    import TimelineResult`` would replace the function :func:`timeline` by the subpackage
    of the same name; here the subpackage's function is kept instead.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "timeline" and isinstance(value, types.ModuleType):
            value = value.timeline
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
