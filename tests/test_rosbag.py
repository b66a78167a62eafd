"""Maps read from real ROS 1 and ROS 2 bags written with rosbags' own writers."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

import brokenness
from brokenness.cli.main import main
from brokenness.errors import MapError, MapFormatError
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.io.rosbag import load_bag_map, quaternion_yaw

GRID = "nav_msgs/msg/OccupancyGrid"
STRING = "std_msgs/msg/String"
TS1 = get_typestore(Stores.ROS1_NOETIC)
TS2 = get_typestore(Stores.ROS2_HUMBLE)


def top_first(seed: int = 0, rows: int = 7, cols: int = 11) -> np.ndarray:
    """An asymmetric grid of OccupancyGrid values, row 0 = TOP (our convention)."""
    g = np.full((rows, cols), 0, np.int8)
    g[0, :] = 100  # top wall only
    g[:, 0] = 100  # left wall only
    g[rows - 2, cols - 3] = 100  # one pillar near the bottom right
    g[1:3, cols - 2 :] = -1  # unknown block at the top right
    g[rows - 1, 1:4] = 50  # 50 %: unknown by the thresholds
    g[2, 2 + seed % 5] = 100  # differs per message
    return g


def expected_states(values: np.ndarray) -> np.ndarray:
    s = np.full(values.shape, UNKNOWN, np.int8)
    s[(values >= 0) & (values <= 19)] = FREE
    s[values >= 65] = OCCUPIED
    return s


def grid_msg(ts, values_top_first, *, res=0.05, origin=(1.5, -2.25, 0.7), stamp=1):
    rows, cols = values_top_first.shape
    types = ts.types
    Time = types["builtin_interfaces/msg/Time"]
    Header = types["std_msgs/msg/Header"]
    Pose = types["geometry_msgs/msg/Pose"]
    Point = types["geometry_msgs/msg/Point"]
    Quaternion = types["geometry_msgs/msg/Quaternion"]
    MapMetaData = types["nav_msgs/msg/MapMetaData"]
    yaw = origin[2]
    pose = Pose(
        position=Point(x=origin[0], y=origin[1], z=0.0),
        orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
    )
    t = Time(sec=stamp, nanosec=0)
    header = (
        Header(seq=stamp, stamp=t, frame_id="map") if ts is TS1 else Header(stamp=t, frame_id="map")
    )
    info = MapMetaData(map_load_time=t, resolution=res, width=cols, height=rows, origin=pose)
    # ROS: row-major from the bottom-left cell -> our bottom row first
    data = np.ascontiguousarray(values_top_first[::-1]).ravel().astype(np.int8)
    return types[GRID](header=header, info=info, data=data)


def string_msg(ts, text="hello"):
    return ts.types[STRING](data=text)


def write_ros1(path: Path, messages) -> Path:
    """messages: list of (topic, msgtype, msg, stamp_ns)."""
    with Writer1(path) as writer:
        conns = {}
        for topic, msgtype, msg, stamp in messages:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=TS1)
            writer.write(conns[topic], stamp, TS1.serialize_ros1(msg, msgtype))
    return path


def write_ros2(path: Path, messages, storage=StoragePlugin.SQLITE3) -> Path:
    with Writer2(path, version=9, storage_plugin=storage) as writer:
        conns = {}
        for topic, msgtype, msg, stamp in messages:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=TS2)
            writer.write(conns[topic], stamp, TS2.serialize_cdr(msg, msgtype))
    return path


def three_maps(ts):
    """Three map messages (different content) plus chatter on another topic."""
    return [
        ("/map", GRID, grid_msg(ts, top_first(0), stamp=1), 1_000_000_000),
        ("/chatter", STRING, string_msg(ts), 1_500_000_000),
        ("/map", GRID, grid_msg(ts, top_first(1), stamp=2), 2_000_000_000),
        (
            "/map",
            GRID,
            grid_msg(ts, top_first(2), origin=(-3.0, 4.0, -2.5), res=0.1, stamp=3),
            3_000_000_000,
        ),
    ]


def check_last(m, source):
    np.testing.assert_array_equal(m.states, expected_states(top_first(2)))
    assert m.resolution == pytest.approx(0.1)
    assert m.origin == pytest.approx((-3.0, 4.0, -2.5))
    assert m.source == source


def test_quaternion_yaw():
    for t in (0.0, 0.7, -2.5, math.pi / 2, 3.0):
        assert quaternion_yaw(0, 0, math.sin(t / 2), math.cos(t / 2)) == pytest.approx(t)
    # unnormalised quaternion, same rotation
    assert quaternion_yaw(0, 0, 2 * math.sin(0.4), 2 * math.cos(0.4)) == pytest.approx(0.8)


def test_ros1_bag_exact_and_last_message_wins(tmp_path):
    bag = write_ros1(tmp_path / "run.bag", three_maps(TS1))
    check_last(load_bag_map(bag), str(bag))


def test_ros1_single_message_keeps_orientation(tmp_path):
    values = top_first(0)
    bag = write_ros1(tmp_path / "one.bag", [("/slam/map", GRID, grid_msg(TS1, values), 5)])
    m = load_bag_map(bag, topic="/slam/map")
    # the flip: the top row is the full wall, the bottom row is not
    assert m.states[0].tolist() == [OCCUPIED] * 11
    assert m.states[-1, 0] == OCCUPIED and m.states[-1, 5] == FREE
    np.testing.assert_array_equal(m.states, expected_states(values))
    assert m.resolution == pytest.approx(0.05)
    assert m.origin == pytest.approx((1.5, -2.25, 0.7))


@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_ros2_bag_folder_and_storage_file(tmp_path, storage):
    folder = write_ros2(tmp_path / "bag2", three_maps(TS2), storage)
    check_last(load_bag_map(folder), str(folder))
    # the storage file itself, inside its folder
    (store,) = [p for p in folder.iterdir() if p.suffix in (".db3", ".mcap")]
    check_last(load_bag_map(store), str(store))
    # a lone storage file whose metadata.yaml was lost
    lone = tmp_path / f"lone{store.suffix}"
    shutil.copy(store, lone)
    check_last(load_bag_map(lone), str(lone))


def test_through_load_map_and_topic(tmp_path):
    bag = write_ros1(tmp_path / "a.bag", [("/other_map", GRID, grid_msg(TS1, top_first(3)), 7)])
    m = brokenness.load_map(bag, topic="/other_map")
    np.testing.assert_array_equal(m.states, expected_states(top_first(3)))
    folder = write_ros2(tmp_path / "b", three_maps(TS2))
    check_last(brokenness.load_map(folder), str(folder))
    # the metadata.yaml of a rosbag2 folder is read as the folder
    assert brokenness.load_map(folder / "metadata.yaml").states.tolist() == (
        expected_states(top_first(2)).tolist()
    )


def test_errors_are_one_line(tmp_path):
    bag = write_ros1(
        tmp_path / "x.bag",
        [("/map", GRID, grid_msg(TS1, top_first(0)), 1), ("/chatter", STRING, string_msg(TS1), 2)],
    )
    with pytest.raises(MapError, match=r"no topic '/nope'.*OccupancyGrid topics: /map"):
        load_bag_map(bag, topic="/nope")
    with pytest.raises(MapFormatError, match=r"std_msgs/msg/String, not nav_msgs/OccupancyGrid"):
        load_bag_map(bag, topic="/chatter")
    # a connection without any message
    empty = tmp_path / "empty.bag"
    with Writer1(empty) as writer:
        writer.add_connection("/map", GRID, typestore=TS1)
    with pytest.raises(MapError, match="no message on topic '/map'"):
        load_bag_map(empty)
    # damaged files
    cut = tmp_path / "cut.bag"
    cut.write_bytes(bag.read_bytes()[:300])
    garbage = tmp_path / "garbage.bag"
    garbage.write_bytes(b"#ROSBAG V2.0\n" + b"\x00\xff" * 64)
    text = tmp_path / "text.db3"
    text.write_text("not a database\n")
    for bad in (cut, garbage, text):
        with pytest.raises(MapFormatError) as info:
            load_bag_map(bad)
        assert "\n" not in str(info.value) and str(bad) in str(info.value)
    folder = tmp_path / "nometa"
    folder.mkdir()
    with pytest.raises(MapFormatError, match="metadata.yaml"):
        load_bag_map(folder)
    with pytest.raises(MapError, match="no such file"):
        load_bag_map(tmp_path / "missing.bag")


def test_inconsistent_grid_is_rejected(tmp_path):
    msg = grid_msg(TS1, top_first(0))
    msg.info.width = 12  # 7x12 cells announced, 7x11 values sent
    bag = write_ros1(tmp_path / "bad.bag", [("/map", GRID, msg, 1)])
    with pytest.raises(MapFormatError, match="77 values for 12x7 cells"):
        load_bag_map(bag)


def test_cli_compute_with_topic(tmp_path, capsys):
    # a real map through a bag: the building has walls enough to register
    ref = brokenness.load_map(Path(__file__).parent / "data" / "tb3_sandbox.yaml")
    values = np.where(ref.states == OCCUPIED, 100, np.where(ref.states == FREE, 0, -1))
    msg = grid_msg(TS1, values.astype(np.int8), res=ref.resolution, origin=ref.origin)
    bag = write_ros1(tmp_path / "slam.bag", [("/robot/map", GRID, msg, 1)])
    m = brokenness.load_map(bag, topic="/robot/map")
    np.testing.assert_array_equal(m.states, ref.states)
    assert m.origin == pytest.approx(ref.origin)
    out = tmp_path / "r.json"
    code = main(["compute", str(bag), str(bag), "--topic", "/robot/map", "--json", str(out)])
    assert code == 0
    assert '"degree": 0' in out.read_text()
    code = main(["compute", str(bag), str(bag), "--topic", "/nope"])
    err = capsys.readouterr().err
    assert code == 2 and "no topic '/nope'" in err and err.count("\n") == 1


def test_without_rosbags_a_bag_is_refused_with_the_extra_to_install(tmp_path, hide_package, capsys):
    """Without the optional package, reading and writing a bag say which extra to install
    (a typed error; one line and status 2 on the command line), not a traceback."""
    from brokenness.errors import MissingDependencyError
    from brokenness.io.rosbag import iter_bag_maps
    from brokenness.io.rosbag_write import write_bag_maps

    bag = write_ros1(tmp_path / "x.bag", [("/map", GRID, grid_msg(TS1, top_first(0)), 1)])
    hide_package("rosbags")
    hint = r"needs the optional package rosbags: pip install 'brokenness\[rosbags\]'"
    with pytest.raises(MissingDependencyError, match="reading ROS bags " + hint):
        load_bag_map(bag)
    with pytest.raises(MissingDependencyError, match="reading ROS bags " + hint):
        next(iter_bag_maps(bag))
    m = brokenness.OccupancyMap(expected_states(top_first(0)), 0.05, (0.0, 0.0, 0.0))
    with pytest.raises(MissingDependencyError, match="writing ROS bags " + hint):
        write_bag_maps(tmp_path / "y.bag", [(1, m)])
    assert not (tmp_path / "y.bag").exists()
    reference = tmp_path / "ref.yaml"
    brokenness.save_map(m, reference)
    capsys.readouterr()
    assert main(["timeline", str(bag), str(reference)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'brokenness[rosbags]'" in err


@pytest.mark.parametrize("x", [1e300, -2e9, math.nan, math.inf])
def test_an_origin_out_of_range_is_refused_as_in_a_map_yaml(tmp_path, x):
    """The origin of a bag's grid has the range of a YAML origin (|value| <= 1e9, finite)."""
    msg = grid_msg(TS1, top_first(0), origin=(x, -11.0, 0.0))
    bag = write_ros1(tmp_path / "far.bag", [("/map", GRID, msg, 1)])
    with pytest.raises(MapFormatError, match=r"origin .* is out of range") as info:
        load_bag_map(bag)
    assert "\n" not in str(info.value) and len(str(info.value)) < 300
    near = write_ros1(tmp_path / "near.bag", [("/map", GRID, grid_msg(TS1, top_first(0)), 1)])
    assert load_bag_map(near).origin == pytest.approx((1.5, -2.25, 0.7))


def test_a_grid_of_only_minus_one_zero_and_one_is_read_as_percent(tmp_path):
    """A bag's grid is always OccupancyGrid percent values: a grid that happens to hold only
    -1, 0 and 1 must read 1 as 1 % (free), not as the occupied cell state (an array's rule
    for such values, OccupancyMap.from_array)."""
    values = np.zeros((5, 6), np.int8)
    values[0, :] = 1
    values[4, :] = -1
    bag = write_ros1(tmp_path / "run.bag", [("/map", GRID, grid_msg(TS1, values), 1)])
    np.testing.assert_array_equal(load_bag_map(bag).states, expected_states(values))
