"""Every Radish log in ../shared/data/radish-corrected-carmen-logs/ reads and maps to single walls.

Skipped where the shared data folder is absent (a plain clone of the repository). Scan and beam
counts are those listed in that folder's README.txt.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from brokenness.simulation.carmen import read_carmen, wall_check

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
LOGS = SHARED / "radish-corrected-carmen-logs"

#: name -> (scans, beams), from LOGS / README.txt
EXPECTED = {
    "aces": (440, 180),
    "csail": (406, 361),
    "fhw": (488, 180),
    "freiburg-079": (4791, 360),
    "freiburg-101": (292, 360),
    "intel": (910, 180),
    "orebro": (237, 181),
    "seattle": (241, 361),
}

pytestmark = pytest.mark.skipif(not LOGS.is_dir(), reason=f"{LOGS} is absent")


def test_the_folder_holds_exactly_these_logs() -> None:
    names = sorted(p.name.removesuffix("-corrected.log.gz") for p in LOGS.glob("*.log.gz"))
    assert names == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_shared_log_reads_and_has_single_walls(name: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # these logs are clean: nothing may be skipped
        log = read_carmen(LOGS / f"{name}-corrected.log.gz")
    scans, beams = EXPECTED[name]
    assert (log.n_scans, log.n_beams) == (scans, beams)
    assert (log.skipped_lines, log.skipped_scans) == (0, 0)
    assert math.degrees(log.angles[0]) == pytest.approx(-90.0)
    assert np.isfinite(log.poses).all()
    # most readings are returns (fr-101 has the most no returns: 12 %)
    assert log.hits.mean() > 0.85
    check = wall_check(log)  # 0.1 m cells, 2 cells, 10 m range; measured 0.930 .. 0.998
    assert check.cross_half >= 0.9, check
    assert check.half_in_full >= 0.95, check
