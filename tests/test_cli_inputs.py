"""Inputs as researchers give them: .npy row order, mirrored maps, bare images' geometry."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from brokenness import load_map
from brokenness.cli._common import geometry_warning
from brokenness.cli.main import main
from brokenness.errors import ParameterError
from brokenness.grid import OccupancyMap
from brokenness.io import save_map
from brokenness.io.resample import resample_to_resolution
from brokenness.measure.mirror import mirror_check, mirrored

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "examples" / "building_31.yaml"


def _nav_values(m: OccupancyMap) -> np.ndarray:
    """``nav_msgs/OccupancyGrid.data`` of a map, reshaped (row 0 = the bottom row)."""
    nav = np.where(m.states == 1, 100, np.where(m.states == 0, 0, -1)).astype(np.int8)
    return nav[::-1]


@pytest.fixture(scope="module")
def ref() -> OccupancyMap:
    return load_map(REFERENCE)


def test_occupancy_grid_npy_is_read_in_ros_row_order(tmp_path, ref):
    np.save(tmp_path / "grid.npy", _nav_values(ref))
    m = load_map(tmp_path / "grid.npy")
    assert np.array_equal(m.states, ref.states)  # as the rosbag reader reads it
    image = load_map(tmp_path / "grid.npy", row_order="image")
    assert np.array_equal(image.states, ref.states[::-1])
    # three-state and bool arrays stay in image order unless told
    np.save(tmp_path / "s.npy", ref.states)
    assert np.array_equal(load_map(tmp_path / "s.npy").states, ref.states)
    assert np.array_equal(load_map(tmp_path / "s.npy", row_order="ros").states, ref.states[::-1])


def test_npy_written_by_save_map_round_trips_in_ros_order(tmp_path, ref):
    save_map(OccupancyMap(ref.states), tmp_path / "m.npy")
    assert np.array_equal(np.load(tmp_path / "m.npy"), _nav_values(ref))
    assert np.array_equal(load_map(tmp_path / "m.npy").states, ref.states)


def test_row_order_checked(tmp_path):
    with pytest.raises(ParameterError, match="row_order"):
        load_map(REFERENCE, row_order="ros")
    np.save(tmp_path / "a.npy", np.zeros((3, 3), np.int8))
    with pytest.raises(ParameterError, match="row_order"):
        load_map(tmp_path / "a.npy", row_order="bottom-up")


def test_mirror_check(ref):
    assert not mirror_check(ref, ref).far_better_mirrored
    check = mirror_check(mirrored(ref), ref)
    assert check.far_better_mirrored and check.mirrored_share > 0.95
    assert "rows in the wrong order" in check.message()


def test_compute_npy_in_both_row_orders(tmp_path, capsys, ref):
    np.save(tmp_path / "grid.npy", _nav_values(ref))
    assert main(["compute", str(tmp_path / "grid.npy"), str(REFERENCE), "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["degree"] == 0
    args = ["compute", str(tmp_path / "grid.npy"), str(REFERENCE), "--row-order", "image"]
    main(args)
    captured = capsys.readouterr()
    assert "far better mirrored: rows in the wrong order?" in captured.err
    assert len(captured.err.strip().splitlines()) == 2  # the resolution warning and this one
    assert main(["compute", str(REFERENCE), str(REFERENCE), "--row-order", "ros"]) == 2
    assert ".npy maps only" in capsys.readouterr().err


def test_a_topic_without_a_bag_is_refused(capsys):
    """--topic names the map topic of a ROS bag: given with no bag, it is a mistake (as
    --row-order without a .npy), not silently ignored."""
    assert main(["compute", str(REFERENCE), str(REFERENCE), "--topic", "/map"]) == 2
    err = capsys.readouterr().err
    assert "--topic applies to ROS bags only" in err and len(err.strip().splitlines()) == 1


def test_bare_image_warns_and_takes_its_resolution(tmp_path, capsys, ref):
    half = resample_to_resolution(ref, 0.1)
    save_map(OccupancyMap(half.states), tmp_path / "half.png")
    message = geometry_warning(load_map(tmp_path / "half.png"), ref)
    assert message is not None and "--map-resolution" in message
    assert geometry_warning(ref, ref) is None
    main(["compute", str(tmp_path / "half.png"), str(REFERENCE), "-q"])
    err = capsys.readouterr().err
    assert "the map has none" in err and "--map-resolution" in err
    args = ["compute", str(tmp_path / "half.png"), str(REFERENCE), "--json", "-"]
    assert main([*args, "--map-resolution", "0.1", "--map-origin", "0,0"]) == 0
    captured = capsys.readouterr()
    record = json.loads(captured.out)
    assert record["degree"] == 0 and "has none" not in captured.err
    assert record["partitions"][0]["transform"]["scale"] == pytest.approx(2.0)
    with pytest.raises(SystemExit) as exc:
        main([*args, "--map-resolution", "-1"])
    assert exc.value.code == 2


def test_same_file_warns_once(tmp_path, capsys):
    depot = ROOT / "tests" / "data" / "depot.yaml"
    main(["compute", str(depot), str(depot), "-q"])
    assert capsys.readouterr().err.count("205") == 1


def test_npy_of_message_data_reads_as_the_bag_reader_reads_the_message(tmp_path):
    pytest.importorskip("rosbags")
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from test_rosbag import GRID, TS1, grid_msg, top_first, write_ros1

    msg = grid_msg(TS1, top_first(3))
    bag = write_ros1(tmp_path / "m.bag", [("/map", GRID, msg, 1_000_000_000)])
    np.save(tmp_path / "m.npy", np.asarray(msg.data).reshape(msg.info.height, msg.info.width))
    assert np.array_equal(load_map(tmp_path / "m.npy").states, load_map(bag).states)
