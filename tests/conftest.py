"""Fixtures shared by the tests of the measure's stages on building 31's corner."""

from __future__ import annotations

import pytest
from _breaking import building_31_corner

from brokenness import OccupancyMap
from brokenness.masking import ReferenceIndex


@pytest.fixture(scope="session")
def corner() -> OccupancyMap:
    """The bundled building 31 map's top-left 520 x 520 cells, as a reference."""
    return building_31_corner(520)


@pytest.fixture(scope="session")
def corner_index(corner: OccupancyMap) -> ReferenceIndex:
    """The :class:`ReferenceIndex` of :func:`corner`."""
    return ReferenceIndex.build(corner)
