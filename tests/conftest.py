"""Fixtures shared by the tests: building 31's corner for the measure's stages, and a
package hidden as if it were not installed."""

from __future__ import annotations

import sys
from collections.abc import Callable

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


@pytest.fixture
def hide_package(monkeypatch: pytest.MonkeyPatch) -> Callable[[str], None]:
    """``hide_package(name)``: until the test ends, importing ``name`` (or a submodule of it)
    raises ImportError, as when the optional package is not installed."""

    def hide(name: str) -> None:
        for module in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            monkeypatch.delitem(sys.modules, module)
        monkeypatch.setitem(sys.modules, name, None)

    return hide
