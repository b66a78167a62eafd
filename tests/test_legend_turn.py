"""The legend of the partition pictures says how each part is turned in the map, on screen."""

from __future__ import annotations

import numpy as np
import pytest
from _breaking import break_map, move_about

from brokenness import OccupancyMap, compute_brokenness
from brokenness.report.raster import legend_entries


@pytest.mark.parametrize(("degrees", "way"), [(12.0, "clockwise"), (-12.0, "counter-clockwise")])
def test_the_legend_gives_the_turn_of_the_part_in_the_map(
    corner: OccupancyMap, degrees: float, way: str
) -> None:
    """The right third of building 31's corner turned by ``degrees`` in the map (rows point
    down: a positive angle turns it clockwise on screen): the legend of P1 says the part is
    turned that way, not the way that undoes it (the sign of its transform's offset)."""
    right = np.zeros(corner.shape, bool)
    right[:, 340:] = True  # the smaller part: P1
    centre = (430.0, 260.0)
    motions = [move_about(centre, 0.0, (0, 0)), move_about(centre, degrees, (0, 0))]
    broken, _ = break_map(corner, [~right, right], motions, pad=30)
    result = compute_brokenness(broken, corner)
    assert result.degree == 1
    part = next(p for p in result.partitions if p.index == 1)
    assert part.rotation_offset_deg == pytest.approx(-degrees, abs=0.5)  # the transform's
    label = legend_entries(result, broken)[1].label
    assert f"turned {abs(degrees):.0f}." in label
    assert f"\N{DEGREE SIGN} {way}," in label
