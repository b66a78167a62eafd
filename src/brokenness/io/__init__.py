"""Map input/output: ROS ``map_server`` YAML, PGM, PNG and other images, ``.npy``, rosbags.

Public names: :func:`load_map`, :func:`save_map`, :func:`resample_to_resolution`,
:func:`common_resolution`, :func:`cell_scale_offset` and :class:`MapWarning`. The exact
pixel semantics are documented in :mod:`brokenness.io.pixels`, the YAML fields in
:mod:`brokenness.io.ros_yaml` and the resampling geometry in :mod:`brokenness.io.resample`.
"""

from __future__ import annotations

from ._files import MapWarning
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
