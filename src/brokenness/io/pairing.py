"""Checks of a map/reference pair that loading each map alone cannot make."""

from __future__ import annotations

from ..grid import OccupancyMap

__all__ = ["geometry_warning"]


def geometry_warning(
    a: OccupancyMap, b: OccupancyMap, first: str = "map", second: str = "reference"
) -> str | None:
    """The warning for a pair where one map knows its resolution and the other does not.

    The one without is then taken at the other's cell size, which is wrong for a bare image
    at another resolution (a large degree from a scale mismatch).
    """
    if (a.resolution is None) == (b.resolution is None):
        return None
    known, unknown = (first, second) if a.resolution is not None else (second, first)
    res = a.resolution if a.resolution is not None else b.resolution
    return (
        f"the {known} has a resolution ({res:g} m/cell) and the {unknown} has none "
        f"(a bare image or array?): its cells are taken as {res:g} m; if that is wrong, "
        f"give --{unknown}-resolution"
    )
