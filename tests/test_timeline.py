"""Brokenness over a simulated SLAM run: bags written with rosbags, a bump, a repair."""

from __future__ import annotations

import csv
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

import brokenness
import brokenness.measure
from brokenness.cli.main import main
from brokenness.errors import MapError, ParameterError
from brokenness.io.rosbag import iter_bag_maps, load_bag_map
from brokenness.io.rosbag_write import write_bag_maps
from brokenness.simulation import map_prefixes, map_scans
from brokenness.simulation.slam_run import simulate_slam_run
from brokenness.timeline import (
    EVENT_BREAK,
    EVENT_REPAIR,
    TimelineFrame,
    TimelinePartition,
    find_events,
    timeline,
    timeline_csv,
)

ROTATION_DEG = 20.0


@pytest.fixture(scope="module")
def run():
    """A 15 m building, 262 scans, the map published every 10 scans (27 messages)."""
    return simulate_slam_run(
        seed=0, bump_at=0.5, repair_at=0.8, rotation_deg=ROTATION_DEG, publish_every=10
    )


@pytest.fixture(scope="module")
def bags(run, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bags")
    ros1 = write_bag_maps(folder / "run.bag", run.maps(), ros=1)
    ros2 = write_bag_maps(folder / "run_ros2", run.maps(), ros=2)
    brokenness.save_map(run.reference, folder / "ref.yaml")
    return {"ros1": ros1, "ros2": ros2, "ref": folder / "ref.yaml"}


def check_run(tl, run, kept):
    """Degree 0 (or not measured) before the bump, the break and the repair on time."""
    pos = {f.message_index: i for i, f in enumerate(tl.frames)}
    assert [f.message_index for f in tl.frames] == kept
    b = run.break_message
    before = [f for f in tl.frames if f.message_index < b]
    assert before and all(f.degree in (0, None) for f in before)
    breaks = [e for e in tl.events if e.kind == EVENT_BREAK]
    repairs = [e for e in tl.events if e.kind == EVENT_REPAIR]
    assert len(breaks) == 1 and len(repairs) == 1, [e.describe() for e in tl.events]
    first_kept_after = next(i for i in kept if i >= b)
    # within one (kept) message of the first message that shows scans after the bump
    assert pos[breaks[0].message_index] - pos[first_kept_after] in (0, 1)
    assert breaks[0].degree_before == 0 and breaks[0].degree_after == 1
    new = breaks[0].partitions
    assert len(new) == 1 and 0.0 < new[0].fraction < 0.5
    # as it stands in the last broken frame: turned by the bump's rotation, larger
    (settled,) = breaks[0].settled
    assert abs(abs(settled.rotation_offset_deg) - ROTATION_DEG) < 2.0
    assert settled.fraction >= new[0].fraction
    assert pos[breaks[0].settled_message_index] == pos[repairs[0].message_index] - 1
    assert breaks[0].time == pytest.approx(run.stamps_ns[breaks[0].message_index] / 1e9 - 5.0)
    r = run.repair_message
    first_kept_repaired = next(i for i in kept if i >= r)
    assert pos[repairs[0].message_index] - pos[first_kept_repaired] in (0, 1)
    assert repairs[0].degree_after == 0
    # just before the repair the off partition is turned by the bump's rotation
    last_broken = tl.frames[pos[repairs[0].message_index] - 1]
    assert last_broken.degree == 1
    assert abs(abs(last_broken.partitions[1].rotation_offset_deg) - ROTATION_DEG) < 2.0
    assert tl.final_degree == 0


def test_ros1_bag_break_and_repair(run, bags):
    assert run.simulation.expected_degree == 1
    tl = brokenness.timeline(bags["ros1"], bags["ref"])
    check_run(tl, run, list(range(len(run.ends))))
    assert tl.count("error") == 0 and tl.count("reused") == 0
    assert all(f.measured and f.digest for f in tl.frames)
    json.dumps(tl.to_dict(), allow_nan=False)


def test_ros2_bag_thinned_every(run, bags):
    tl = timeline(bags["ros2"], run.reference, every=3)
    n = len(run.ends)
    kept = list(range(0, n, 3)) + ([n - 1] if (n - 1) % 3 else [])
    check_run(tl, run, kept)


def test_thinned_by_period(run, bags):
    # messages every 5 s: a period of 9.9 s keeps every second one (and the last)
    tl = timeline(bags["ros1"], run.reference, period=9.9)
    n = len(run.ends)
    assert [f.message_index for f in tl.frames][:-1] == list(range(0, n - 1, 2))
    assert tl.frames[-1].message_index == n - 1


def test_early_maps_not_measured(run, bags):
    tl = timeline(bags["ros1"], run.reference, min_occupied_cells=1500)
    early = [f for f in tl.frames if f.occupied_cells < 1500]
    assert early and all(not f.measured and f.degree is None for f in early)
    assert all("too little mapped" in (f.reason or "") for f in early)
    assert all(f.largest_fraction is None for f in early)
    check_run(tl, run, list(range(len(run.ends))))  # not a break, nor a fake 0


def test_unchanged_maps_are_reused(run, tmp_path, monkeypatch):
    maps = [m for _s, m in itertools.islice(run.maps(), 3)]
    seq = [maps[0], maps[0], maps[1], maps[1], maps[1], maps[2], maps[1]]
    bag = write_bag_maps(tmp_path / "dup.bag", [((i + 1) * 10**9, m) for i, m in enumerate(seq)])
    calls = []
    real = brokenness.measure.compute_brokenness

    def counting(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(brokenness.measure, "compute_brokenness", counting)
    tl = timeline(bag, run.reference)
    assert len(calls) == 4  # 0, 2, 5, 6: a map equal to the previous message is not redone
    assert [f.same_as for f in tl.frames] == [None, 0, None, 2, 2, None, None]
    for f in tl.frames:
        if f.same_as is not None:
            root = tl.frames[f.same_as]
            assert f.degree == root.degree and f.partitions == root.partitions
            assert f.seconds == 0.0 and f.digest == root.digest
    assert [f.time for f in tl.frames] == [float(i) for i in range(7)]


def test_save_results_and_resume(run, bags, tmp_path, monkeypatch):
    out = tmp_path / "frames"
    first = timeline(bags["ros1"], run.reference, every=8, save_results=out, dpi=30)
    zips = sorted(p.name for p in out.glob("frame_*.zip"))
    assert zips == sorted(f.result_file for f in first.frames)
    record = brokenness.report.load_results(out / zips[0])
    assert record.info["timeline"]["message_index"] == 0
    (out / zips[1]).unlink()
    calls = []
    real = brokenness.measure.compute_brokenness
    monkeypatch.setattr(
        brokenness.measure,
        "compute_brokenness",
        lambda *a, **k: calls.append(1) or real(*a, **k),
    )
    again = timeline(bags["ros1"], run.reference, every=8, save_results=out, dpi=30)
    assert len(calls) == 1  # only the deleted one
    assert again.count("resumed") == len(first.frames) - 1
    assert [f.degree for f in again.frames] == [f.degree for f in first.frames]
    assert [len(f.partitions) for f in again.frames] == [len(f.partitions) for f in first.frames]
    for a, b in zip(again.frames, first.frames, strict=True):
        for p, q in zip(a.partitions, b.partitions, strict=True):
            assert p.fraction == pytest.approx(q.fraction)
            assert p.rotation_offset_deg == pytest.approx(q.rotation_offset_deg)
            assert p.translation_m == pytest.approx(q.translation_m)
    assert [(e.kind, e.message_index) for e in again.events] == [
        (e.kind, e.message_index) for e in first.events
    ]


def test_process_pool_same_as_inline(run, bags):
    inline = timeline(bags["ros1"], run.reference, every=2)
    pooled = timeline(bags["ros1"], run.reference, every=2, workers=2)
    assert [f.degree for f in pooled.frames] == [f.degree for f in inline.frames]
    assert [e.kind for e in pooled.events] == [e.kind for e in inline.events]


def test_dask_local_cluster(run, bags):
    pytest.importorskip("distributed")
    tl = timeline(bags["ros1"], run.reference, every=8, workers=2, local_cluster=True)
    inline = timeline(bags["ros1"], run.reference, every=8)
    assert [f.degree for f in tl.frames] == [f.degree for f in inline.frames]


def test_dask_scheduler_address(run, bags):
    distributed = pytest.importorskip("distributed")
    # an in-process cluster (threads) starts fast; the client path is the same
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster:
        tl = timeline(bags["ros1"], run.reference, every=13, scheduler=cluster.scheduler_address)
    assert [f.message_index for f in tl.frames] == [0, 13, 26]
    assert all(f.measured for f in tl.frames)


def test_bad_options(run, bags):
    with pytest.raises(ParameterError):
        timeline(bags["ros1"], run.reference, every=2, period=1.0)
    with pytest.raises(ParameterError):
        timeline(bags["ros1"], run.reference, workers=0)
    with pytest.raises(ParameterError):
        timeline(bags["ros1"], run.reference, scheduler="tcp://x:1", local_cluster=True)
    with pytest.raises(MapError, match="no topic"):
        timeline(bags["ros1"], run.reference, topic="/nope")


# -- the reader ------------------------------------------------------------------------------
def test_iter_bag_maps_lazy_and_single_map_api_intact(run, bags, tmp_path):
    for bag in (bags["ros1"], bags["ros2"]):
        it = iter_bag_maps(bag)
        first = next(it)
        assert first.index == 0 and first.stamp_ns == run.stamps_ns[0]
        assert first.header_stamp == pytest.approx(run.stamps_ns[0] / 1e9)
        rest = list(it)
        assert [b.index for b in rest] == list(range(1, len(run.ends)))
        last = load_bag_map(bag)  # the single-map API: still the last message
        np.testing.assert_array_equal(last.states, rest[-1].map.states)
        assert last.origin == pytest.approx(run.simulation.map.origin)
    with pytest.raises(MapError):
        next(iter_bag_maps(bags["ros1"], every=0))
    (db3,) = Path(bags["ros2"]).glob("*.db3")  # a storage file: read through its folder
    assert [b.index for b in iter_bag_maps(db3, every=10)] == [0, 10, 20, len(run.ends) - 1]
    lone = tmp_path / "lone.db3"  # metadata.yaml lost: read with the storage plugin
    lone.write_bytes(db3.read_bytes())
    assert [b.index for b in iter_bag_maps(lone, every=10)] == [0, 10, 20, len(run.ends) - 1]


def test_map_prefixes_equal_map_scans(run):
    sim = run.simulation
    r = sim.run
    geo = dict(
        max_range=r.laser.max_range,
        resolution=sim.map.resolution,
        shape=sim.map.shape,
        origin=sim.map.origin,
    )
    got = list(map_prefixes(r.true_poses, r.ranges, r.angles, [7, 30], **geo))
    for end, m in zip([7, 30], got, strict=True):
        want = map_scans(r.true_poses[:end], r.ranges[:end], r.angles, **geo)
        np.testing.assert_array_equal(m.states, want.states)


# -- events ---------------------------------------------------------------------------------
def part(index, fraction, rot=0.0, tx=0.0):
    return TimelinePartition(
        index, int(1000 * fraction), fraction, rot, (tx, 0.0), None, None, 1.0, rot, tx, None
    )


def frame(i, degree, parts=()):
    return TimelineFrame(
        i,
        i * 10**9,
        float(i),
        None,
        degree is not None,
        degree,
        None,
        tuple(parts),
        1000,
        0,
        0.0,
        str(i),
    )


def test_events_skip_unmeasured_and_name_the_new_partition():
    a = part(0, 1.0)
    frames = [
        frame(0, None),
        frame(1, 0, [a]),
        frame(2, None),  # not measured: neither a break nor a repair
        frame(3, 2, [part(0, 0.6), part(1, 0.3, 30.0, 20.0), part(2, 0.1, -45.0, 9.0)]),
        frame(4, 1, [part(0, 0.7), part(1, 0.3, 30.5, 20.5)]),
        frame(5, 0, [part(0, 1.0)]),
    ]
    events = find_events(frames)
    assert [(e.kind, e.message_index, e.after_message_index) for e in events] == [
        (EVENT_BREAK, 3, 1),
        (EVENT_REPAIR, 4, 3),
        (EVENT_REPAIR, 5, 4),
    ]
    assert [p.index for p in events[0].partitions] == [1, 2]
    assert events[0].settled == events[0].partitions and events[0].settled_message_index == 3
    assert events[1].settled == ()
    assert [p.rotation_offset_deg for p in events[1].partitions] == [-45.0]  # the one gone
    assert find_events([frame(0, 1, [a, part(1, 0.2, 10.0)])])[0].degree_before is None
    assert math.isclose(events[0].partitions[1].rotation_offset_deg, -45.0)


# -- the command line -----------------------------------------------------------------------
def test_cli_timeline(run, bags, tmp_path, capsys):
    csv_path, plot, js = tmp_path / "tl.csv", tmp_path / "tl.png", tmp_path / "tl.json"
    code = main(
        [
            "timeline",
            str(bags["ros1"]),
            str(bags["ref"]),
            "--every",
            "2",
            "--csv",
            str(csv_path),
            "--plot",
            str(plot),
            "--json",
            str(js),
            "--no-progress",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "break, degree 0 -> 1" in out and "repair, degree 1 -> 0" in out
    rows = list(csv.DictReader(csv_path.open()))
    n = len(run.ends)
    assert len(rows) == len(range(0, n, 2)) + (1 if (n - 1) % 2 else 0)
    assert {r["event"] for r in rows} == {"", "break", "repair"}
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    doc = json.loads(js.read_text())
    assert doc["format"] == "brokenness-timeline" and doc["final_degree"] == 0
    assert timeline_csv  # the writer is public


def test_cli_timeline_exit_codes(bags, capsys):
    assert main(["timeline", str(bags["ros1"]), str(bags["ref"]), "--topic", "/x"]) == 2
    assert "no topic '/x'" in capsys.readouterr().err
    code = main(
        [
            "timeline",
            str(bags["ros1"]),
            str(bags["ref"]),
            "--every",
            "9",
            "--min-occupied-cells",
            "100000",
            "--no-progress",
        ]
    )
    assert code == 3  # nothing measured
    assert "0 measured" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:  # argparse: --every and --period exclude each other
        main(["timeline", str(bags["ros1"]), str(bags["ref"]), "--every", "2", "--period", "1"])
    assert exc.value.code == 2


def test_write_bag_rejects_bad_ros(tmp_path, run):
    with pytest.raises(ParameterError):
        write_bag_maps(tmp_path / "x.bag", [], ros=3)
    assert Path(tmp_path).is_dir()
