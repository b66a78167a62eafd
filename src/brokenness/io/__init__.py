"""Map input/output: ROS ``map_server`` YAML, PGM, PNG and other images, ``.npy``, rosbags.

Public names: :func:`load_map`, :func:`save_map`, :func:`resample_to_resolution`,
:func:`common_resolution` and :class:`MapWarning`.
"""

from __future__ import annotations

from ._files import MapWarning
from .load import load_map

__all__ = ["MapWarning", "load_map"]
