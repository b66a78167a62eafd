"""Typed exceptions raised by :mod:`brokenness`.

Every error that bad input can cause is a subclass of :class:`BrokennessError`, so that a
caller (and the command-line interface) can catch one type and show a one-line message.
"""

from __future__ import annotations

__all__ = [
    "BrokennessError",
    "MapError",
    "MapFormatError",
    "MapSizeError",
    "MissingDependencyError",
    "NothingFoundWarning",
    "ParameterError",
]


class BrokennessError(Exception):
    """Base class of every error raised on purpose by this package."""


class MapError(BrokennessError, ValueError):
    """A map (or reference) cannot be used: missing, unreadable, empty or inconsistent."""


class MapFormatError(MapError):
    """A map file exists but its content is not a valid map (corrupt image, bad YAML...)."""


class MapSizeError(MapError):
    """A map is larger than :data:`brokenness.grid.MAX_CELLS` cells (or has a zero side)."""


class ParameterError(BrokennessError, ValueError):
    """An option passed to an algorithm is out of its valid range."""


class MissingDependencyError(BrokennessError, ImportError):
    """A feature needs an optional package that is not installed (the message says which
    extra to install, e.g. ``pip install 'brokenness[rosbags]'``)."""


class NothingFoundWarning(UserWarning):
    """No part of the map agrees with the reference under any transform that was found.

    :func:`brokenness.compute_brokenness` then returns degree 0 with no partition and every
    occupied cell unassigned: the degree was not measured (the registration failed, or the
    map does not show the reference's place).
    """
