"""Issue 11's last row: a PNG of 10000 x 10000 cells that compresses to about 120 KB.

A grid of walls: the middle 8000 x 8000 cells are free (the rest unknown), with walls three
cells thick every 800 cells (11 a direction, so 10 x 10 rooms) and one occupied cell in the
middle of each room: 527,200 occupied cells. Written as a ROS ``map_server`` YAML with a
trinary PNG beside it (0.05 m a cell), the map the README's issue 11 measurements use:

    python benchmarks/make_huge_png.py /tmp/huge.yaml
    /usr/bin/time -v brokenness compute /tmp/huge.yaml /tmp/huge.yaml --save-results out.zip

(the PNG alone, ``/tmp/huge.png``, loads to the same cells).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from brokenness import OccupancyMap, save_map

#: map side, cells; the known square [LOW, HIGH) and the wall period
SIDE, LOW, HIGH, STEP, THICK = 10000, 1000, 9000, 800, 3


def grid_of_walls(
    side: int = SIDE, low: int = LOW, high: int = HIGH, step: int = STEP, thick: int = THICK
) -> np.ndarray:
    """Trinary states (-1 unknown, 0 free, 1 occupied) of the grid of walls.

    Parameters
    ----------
    side : int
        Rows and columns of the map.
    low, high : int
        The free square is ``[low, high)`` in both directions.
    step : int
        Walls start every ``step`` cells from ``low`` up to ``high`` included.
    thick : int
        Wall thickness, cells.

    Returns
    -------
    numpy.ndarray
        ``int8`` states of shape ``(side, side)``.
    """
    states = np.full((side, side), -1, np.int8)
    states[low:high, low:high] = 0
    for s in range(low, high + 1, step):
        states[s : s + thick, low:high] = 1
        states[low:high, s : s + thick] = 1
    centres = np.arange(low + step // 2, high, step)
    states[np.ix_(centres, centres)] = 1
    return states


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the YAML to write (its PNG beside it)")
    args = parser.parse_args()
    walls = OccupancyMap(grid_of_walls(), 0.05, (0.0, 0.0, 0.0))
    path = save_map(walls, args.out, image_format="png")
    png = path.with_suffix(".png")
    print(f"{path} and {png} ({png.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
