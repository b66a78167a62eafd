"""CARMEN log reader and log mapper (brokenness.simulation.carmen) on the repo's small log."""

from __future__ import annotations

import dataclasses
import gzip
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from brokenness import (
    MapError,
    MapFormatError,
    MapWarning,
    ParameterError,
    compute_brokenness,
    picture_distance,
)
from brokenness.simulation.carmen import (
    CarmenLog,
    broken_log_map,
    flaser_angles,
    log_geometry,
    map_log,
    read_carmen,
    wall_check,
)

DATA = Path(__file__).parent / "data"
LOG = DATA / "carmen" / "orebro-corrected.log.gz"


@pytest.fixture(scope="module")
def log() -> CarmenLog:
    return read_carmen(LOG)


@pytest.fixture(scope="module")
def lines() -> list[str]:
    return gzip.decompress(LOG.read_bytes()).decode().splitlines()


def _write(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


# -- reading ----------------------------------------------------------------------------------
def test_small_log_scans_beams_angles(log: CarmenLog) -> None:
    assert (log.n_scans, log.n_beams) == (237, 181)
    assert log.message == "FLASER"
    assert (log.skipped_lines, log.skipped_scans) == (0, 0)
    deg = np.degrees(log.angles)
    assert deg[0] == pytest.approx(-90.0) and deg[-1] == pytest.approx(90.0)
    np.testing.assert_allclose(np.diff(deg), 1.0)
    # the first scan's ranges and the last scan's pose, as printed in the file
    assert log.ranges[0, :3].tolist() == [3.46, 3.382, 3.319]
    np.testing.assert_array_equal(log.poses[-1], [-2.13299, 0.233541, -0.0666724])
    assert log.max_range == pytest.approx(32.767)
    # the SICK no-return codes 32.759..32.767 are not hits; 32.63 is below the 0.2 % margin
    assert not log.hits[log.ranges >= 32.759].any()
    assert log.hits[log.ranges == 32.63].all()


def test_flaser_angle_rules() -> None:
    for n, first, step, last in (
        (180, -90, 1.0, 89),
        (181, -90, 1.0, 90),
        (360, -90, 0.5, 89.5),
        (361, -90, 0.5, 90),
    ):
        deg = np.degrees(flaser_angles(n))
        assert len(deg) == n
        assert deg[0] == pytest.approx(first) and deg[-1] == pytest.approx(last)
        np.testing.assert_allclose(np.diff(deg), step)
    np.testing.assert_allclose(np.degrees(flaser_angles(91))[[0, -1]], [-90, 90])
    assert flaser_angles(1).tolist() == [0.0]
    with pytest.raises(ParameterError):
        flaser_angles(0)


def test_gzip_and_plain_agree_whatever_the_name(log: CarmenLog, tmp_path: Path) -> None:
    plain = tmp_path / "orebro.log.gz"  # plain text under a .gz name
    plain.write_bytes(gzip.decompress(LOG.read_bytes()))
    zipped = tmp_path / "orebro.txt"  # gzip under a .txt name
    zipped.write_bytes(LOG.read_bytes())
    for other in (read_carmen(plain), read_carmen(str(zipped))):
        np.testing.assert_array_equal(other.poses, log.poses)
        np.testing.assert_array_equal(other.ranges, log.ranges)
        np.testing.assert_array_equal(other.angles, log.angles)
        assert other.max_range == log.max_range


def test_malformed_and_truncated_lines_are_skipped_and_counted(
    lines: list[str], tmp_path: Path
) -> None:
    flaser = [ln for ln in lines if ln.startswith("FLASER")]
    good = flaser[:10]
    tok = flaser[10].split()
    bad = [
        " ".join(tok[:100]),  # truncated inside the ranges
        " ".join(tok[:2] + ["oops"] + tok[3:]),  # a range that is not a number
        " ".join(tok[:183] + ["nan"] + tok[184:]),  # a non-finite pose
        " ".join(tok + ["extra"] * 3),  # too many fields
        "FLASER",  # no beam count
        "FLASER -3 1 2 3",  # negative beam count
    ]
    other_layout = " ".join(["FLASER", "180"] + tok[2:182] + tok[183:])  # valid, 180 beams
    body = good[:5] + bad + ["ODOM 0 0 0 0 0 0 0 host 0", other_layout] + good[5:]
    cut = " ".join(flaser[11].split()[:150])  # the file ends in the middle of a line
    path = _write(tmp_path / "broken.log", body + [cut])
    with pytest.warns(MapWarning) as record:
        got = read_carmen(path)
    messages = " ".join(str(w.message) for w in record)
    assert "skipped 7 malformed or truncated FLASER line(s)" in messages
    assert "skipped 1 FLASER scan(s) whose beam layout differs" in messages
    assert (got.n_scans, got.n_beams) == (10, 181)
    assert (got.skipped_lines, got.skipped_scans) == (7, 1)
    ref = read_carmen(_write(tmp_path / "good.log", good))
    np.testing.assert_array_equal(got.ranges, ref.ranges)
    np.testing.assert_array_equal(got.poses, ref.poses)


def test_truncated_gzip_reads_what_is_there(tmp_path: Path) -> None:
    data = LOG.read_bytes()
    path = tmp_path / "cut.log.gz"
    path.write_bytes(data[: len(data) // 2])
    with pytest.warns(MapWarning) as record:
        got = read_carmen(path)
    assert any("gzip data ends early" in str(w.message) for w in record)
    assert 50 < got.n_scans < 237
    assert got.skipped_lines <= 1  # at most the line the cut went through
    full = read_carmen(LOG)
    np.testing.assert_array_equal(got.poses, full.poses[: got.n_scans])


def test_clean_log_does_not_warn(tmp_path: Path, lines: list[str]) -> None:
    path = _write(tmp_path / "clean.log", lines[:40])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_carmen(path).skipped_lines == 0


def test_robotlaser1_lines_match_flaser(log: CarmenLog, lines: list[str], tmp_path: Path) -> None:
    out = []
    for ln in [ln for ln in lines if ln.startswith("FLASER")][:30]:
        tok = ln.split()
        n = int(tok[1])
        ranges, pose = tok[2 : 2 + n], tok[2 + n : 5 + n]
        out.append(
            " ".join(
                [
                    "ROBOTLASER1",
                    "0",
                    repr(-math.pi / 2),
                    repr(math.pi),
                    repr(math.pi / 180),
                    "32.767",
                    "0.01",
                    "0",
                    str(n),
                    *ranges,
                    "2",
                    "7",
                    "8",
                    *pose,
                    *pose,
                    "0 0 0.5 0.2 1",
                    "1.5",
                    "host",
                    "1.5",
                ]
            )
        )
        out.append(ln)  # FLASER lines are ignored when ROBOTLASER1 lines are present
    got = read_carmen(_write(tmp_path / "robot.log", out))
    assert got.message == "ROBOTLASER1"
    assert got.n_scans == 30
    np.testing.assert_allclose(got.angles, log.angles, atol=1e-12)
    np.testing.assert_array_equal(got.ranges, log.ranges[:30])
    np.testing.assert_array_equal(got.poses, log.poses[:30])
    assert got.max_range == 32.767


def test_not_a_log_is_a_format_error(tmp_path: Path) -> None:
    with pytest.raises(MapFormatError, match="not a CARMEN laser log"):
        read_carmen(DATA / "depot.yaml")
    with pytest.raises(MapFormatError, match="not a CARMEN laser log"):
        read_carmen(DATA / "building_31.png")
    with pytest.raises(MapFormatError, match="not a CARMEN laser log"):
        read_carmen(_write(tmp_path / "empty.log", [""]))
    with pytest.raises(MapFormatError, match=r"no valid laser line \(2 malformed\)"):
        read_carmen(_write(tmp_path / "junk.log", ["FLASER 3 1 2", "FLASER x"]))
    bad_gzip = tmp_path / "bad.gz"
    bad_gzip.write_bytes(b"\x1f\x8b" + b"\x00" * 40)
    with pytest.raises(MapFormatError, match="gzip"):
        read_carmen(bad_gzip)


def test_missing_file_is_a_map_error(tmp_path: Path) -> None:
    with pytest.raises(MapError, match="no such CARMEN log"):
        read_carmen(tmp_path / "nowhere.log")
    with pytest.raises(MapError, match="directory"):
        read_carmen(tmp_path)


def test_select_and_end_points(log: CarmenLog) -> None:
    half = log.select(np.arange(10))
    assert half.n_scans == 10 and half.n_beams == log.n_beams
    ends = half.end_points()
    assert ends.shape == (int(half.hits.sum()), 2)
    # beam 90 points straight ahead: the end point is pose + r * (cos, sin)(theta)
    i = int(np.flatnonzero(half.hits[:, 90])[0])
    x, y, t = half.poses[i]
    r = half.ranges[i, 90]
    k = int(half.hits[:i].sum() + half.hits[i, :90].sum())
    np.testing.assert_allclose(ends[k], [x + r * math.cos(t), y + r * math.sin(t)])


# -- mapping ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ore_map(log: CarmenLog):  # noqa: ANN201
    return map_log(log, resolution=0.1, max_range=10.0)


def test_map_of_the_log(log: CarmenLog, ore_map) -> None:  # noqa: ANN001
    m = ore_map
    assert m.resolution == 0.1 and m.has_geometry
    assert m.source == str(LOG)
    # the corridors of Orebro are some 60 m long: a few thousand wall cells, mostly free inside
    assert 3000 < m.n_occupied < 20000
    assert m.free.sum() > 10 * m.n_occupied
    # every pose lies in free space (the robot drove there)
    inv = np.linalg.inv(m.cell_to_world_matrix())
    cells = np.rint(np.c_[log.poses[:, :2], np.ones(log.n_scans)] @ inv.T)[:, :2].astype(int)
    assert (m.states[cells[:, 1], cells[:, 0]] == 0).mean() > 0.95
    # same inputs, same map, bit for bit
    np.testing.assert_array_equal(map_log(log, resolution=0.1, max_range=10.0).states, m.states)


def test_map_is_not_broken_against_itself(ore_map) -> None:  # noqa: ANN001
    assert picture_distance(ore_map, ore_map) == 0.0
    assert compute_brokenness(ore_map, ore_map, seed=0).degree == 0


def test_walls_are_single(log: CarmenLog) -> None:
    check = wall_check(log)  # 0.1 m cells, 2 cells tolerance, 10 m mapping range
    # measured 0.948 (second half vs first half) and 0.990 (first half vs full log)
    assert check.cross_half >= 0.9
    assert check.half_in_full >= 0.95
    assert check.compared_cells > 500
    assert check.psi_half_full < 0.5


def test_wall_check_sees_doubled_walls(log: CarmenLog) -> None:
    # a 3 degree turn of the pose estimate a quarter into the run doubles the walls
    k = log.n_scans // 4
    p = log.poses.copy()
    t = math.radians(3.0)
    c, s = math.cos(t), math.sin(t)
    dx, dy = p[k:, 0] - p[k, 0], p[k:, 1] - p[k, 1]
    p[k:, 0], p[k:, 1] = p[k, 0] + c * dx - s * dy, p[k, 1] + s * dx + c * dy
    p[k:, 2] += t
    check = wall_check(log, poses=p)
    assert check.cross_half < 0.8


def test_map_options(log: CarmenLog) -> None:
    shape, origin = log_geometry(log, resolution=0.2, max_range=10.0)
    m = map_log(log, resolution=0.2, max_range=10.0, shape=shape, origin=origin)
    assert m.shape == shape and m.origin == origin
    cleared = map_log(
        log, resolution=0.2, max_range=10.0, shape=shape, origin=origin, clear_no_returns=True
    )
    assert cleared.free.sum() > m.free.sum()  # no returns now clear space up to 10 m
    with pytest.raises(ParameterError):
        map_log(log, resolution=0.2, shape=shape)
    with pytest.raises(ParameterError):
        map_log(log, resolution=0.2, max_range=-1.0)
    with pytest.raises(ParameterError):
        map_log(log, resolution=0.2, poses=log.poses[:5])


# -- broken maps of the real building -----------------------------------------------------------
def _agreement(sim, j: int) -> float:  # noqa: ANN001
    """Share of partition j's cells within 2 cells of an occupied reference cell (own check)."""
    from brokenness.masking import cell_points
    from brokenness.masking.distance import manhattan_distance_map

    dist = manhattan_distance_map(sim.reference.occupied)
    pts = np.rint(sim.partitions[j].transform.apply(cell_points(sim.labels == j))).astype(int)
    rows, cols = dist.shape
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < cols) & (pts[:, 1] >= 0) & (pts[:, 1] < rows)
    d = np.full(len(pts), np.inf)
    d[inside] = dist[pts[inside, 1], pts[inside, 0]]
    return float((d <= 2).mean())


@pytest.fixture(scope="module")
def broken2(log: CarmenLog):  # noqa: ANN201
    return broken_log_map(log, degree=2, seed=1, resolution=0.1, max_range=10.0)


def test_broken_log_map_ground_truth(log: CarmenLog, broken2) -> None:  # noqa: ANN001
    sim = broken2
    assert sim.expected_degree == 2 and len(sim.partitions) == 3 and len(sim.bumps) == 2
    assert sim.map.resolution == sim.reference.resolution == 0.1
    assert sim.map.shape != sim.reference.shape  # the bumped map needs a larger canvas
    for j, part in enumerate(sim.partitions):
        assert part.counted and part.share > 0.1
        # measured 0.986, 0.981, 0.986
        assert _agreement(sim, j) >= 0.9
        # the world part takes the bumped pose estimate back onto the corrected poses
        scans = np.arange(part.first_scan, part.end_scan)
        assert part.transform.world is not None
        back = part.transform.world.apply(sim.estimated_poses[scans, :2])
        np.testing.assert_allclose(back, log.poses[scans, :2], atol=1e-9)
    # the check can fail: partition 2's cells under partition 1's transform
    swapped = dataclasses.replace(sim.partitions[2], transform=sim.partitions[1].transform)
    wrong = dataclasses.replace(sim, partitions=(*sim.partitions[:2], swapped))
    assert _agreement(wrong, 2) < 0.5


def test_broken_log_map_is_measured_right(broken2) -> None:  # noqa: ANN001
    result = compute_brokenness(broken2.map, broken2.reference, seed=0)
    assert result.degree == 2


def test_broken_log_map_degree_zero_and_determinism(log: CarmenLog, broken2) -> None:  # noqa: ANN001
    sim = broken_log_map(log, degree=0, seed=5, resolution=0.1, max_range=10.0)
    assert sim.expected_degree == 0 and sim.bumps == ()
    assert sim.map.shape == sim.reference.shape and sim.map.origin == sim.reference.origin
    np.testing.assert_array_equal(sim.map.states, sim.reference.states)
    again = broken_log_map(log, degree=2, seed=1, resolution=0.1, max_range=10.0)
    np.testing.assert_array_equal(again.map.states, broken2.map.states)
    np.testing.assert_array_equal(again.labels, broken2.labels)
    assert again.bumps == broken2.bumps
    with pytest.raises(ParameterError):
        broken_log_map(log, degree=1, bumps=1)
    with pytest.raises(ParameterError):
        broken_log_map(log, seed=-1)
