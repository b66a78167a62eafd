"""Map input/output: ROS ``map_server`` YAML, PGM, PNG and other images, ``.npy``, rosbags.

Public names: :func:`load_map`, :func:`save_map`, :func:`resample_to_resolution`,
:func:`common_resolution`, :func:`cell_scale_offset` and :class:`MapWarning`. The exact
pixel semantics are documented in :mod:`brokenness.io.pixels`, the YAML fields in
:mod:`brokenness.io.ros_yaml` and the resampling geometry in :mod:`brokenness.io.resample`.
The names but :class:`MapWarning` are imported on first use (:mod:`brokenness._lazy`), so
that reading a file (a batch's manifest) does not load numpy, Pillow and SciPy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports
from ._files import MapWarning

if TYPE_CHECKING:
    from .load import load_map
    from .resample import cell_scale_offset, common_resolution, resample_to_resolution
    from .save import save_map

__all__ = [
    "MapWarning",
    "cell_scale_offset",
    "common_resolution",
    "load_map",
    "resample_to_resolution",
    "save_map",
]

__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "load_map": ".load",
        **dict.fromkeys(
            ("cell_scale_offset", "common_resolution", "resample_to_resolution"), ".resample"
        ),
        "save_map": ".save",
    },
)
