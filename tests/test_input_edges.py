"""Edge inputs of timeline, simulate, batch and the file helpers: typed errors, one line, fast.

Each case that could block (a FIFO, ``/dev/zero``) runs under an alarm, so that a regression
fails the test instead of hanging the suite.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np
import pytest
from _alarm import alarm

import brokenness
from brokenness._atomic import AtomicWriteError, atomic_write_text
from brokenness.batch import ManifestError, read_manifest, run_batch
from brokenness.cli.main import main
from brokenness.errors import MapError, MapSizeError, ParameterError
from brokenness.io._files import read_file_bytes
from brokenness.io.rosbag import MAX_PERIOD, count_bag_maps, iter_bag_maps, thinning
from brokenness.limits import MAX_CELLS_CEILING, MAX_CELLS_ENV, max_cells
from brokenness.simulation import BumpOptions, grid_geometry, route_poses, simulate_broken_map
from brokenness.simulation.building import MAX_BUILDING_SIDE

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
MAP = EXAMPLES / "broken_building_31.yaml"
REFERENCE = EXAMPLES / "building_31.yaml"
POSIX = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
DEV_ZERO = pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")


def refused(capsys: pytest.CaptureFixture[str], *argv: object, match: str) -> str:
    """``brokenness *argv`` exits 2 with one line containing ``match``, fast, no traceback."""
    start = time.perf_counter()
    with alarm():
        code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    assert match.lower() in err.lower(), err
    assert time.perf_counter() - start < 5.0
    return err


# -- 1. timeline: bags that are not regular files --------------------------------------------
@DEV_ZERO
def test_timeline_refuses_dev_zero_bag(tmp_path, capsys):
    link = tmp_path / "zl.bag"
    link.symlink_to("/dev/zero")
    with pytest.raises(MapError, match="character device"), alarm():
        brokenness.timeline(link, REFERENCE)
    refused(capsys, "timeline", link, REFERENCE, match="character device")


@POSIX
@pytest.mark.parametrize("name", ["f.db3", "f.mcap", "f.bag"])
def test_timeline_refuses_fifo_bag(tmp_path, capsys, name):
    fifo = tmp_path / name
    os.mkfifo(fifo)
    with pytest.raises(MapError, match="FIFO"), alarm():
        brokenness.timeline(fifo, REFERENCE)
    with pytest.raises(MapError, match="FIFO"), alarm():
        next(iter_bag_maps(fifo))
    with alarm():
        assert count_bag_maps(fifo) is None  # refused, not opened
    refused(capsys, "timeline", fifo, REFERENCE, match="FIFO")


@POSIX
def test_fifo_listed_in_rosbag2_metadata_is_refused(tmp_path, capsys):
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  version: 5\n  relative_file_paths: [part_0]\n"
    )
    os.mkfifo(bag / "part_0")  # no .db3 suffix: found through the metadata
    with pytest.raises(MapError, match="part_0: is a FIFO"), alarm():
        brokenness.timeline(bag, REFERENCE)
    refused(capsys, "timeline", bag, REFERENCE, match="FIFO")
    refused(capsys, "compute", bag, REFERENCE, match="FIFO")


# -- 2. timeline: thinning options ------------------------------------------------------------
@pytest.mark.parametrize("period", [1e308, math.inf, math.nan, -1.0, MAX_PERIOD * 1.01])
def test_timeline_period_out_of_range(tmp_path, period):
    with pytest.raises(ParameterError, match="period must be a number of seconds"):
        brokenness.timeline(tmp_path / "missing.bag", REFERENCE, period=period)
    with pytest.raises(MapError, match="period"):  # the reader's own contract: MapError
        next(iter_bag_maps(MAP, period=period))


def test_thinning_bounds():
    assert thinning(1, None) is None
    assert thinning(1, 0.5) == 500_000_000
    assert thinning(1, MAX_PERIOD) == 2**63 - 1  # the longest period still fits an int64
    with pytest.raises(ParameterError, match="every must be a positive integer"):
        thinning(0, None)
    with pytest.raises(ParameterError, match="every"):
        brokenness.timeline(MAP, REFERENCE, every=-3)


def test_cli_timeline_period_overflow(capsys):
    refused(capsys, "timeline", MAP, REFERENCE, "--period", "1e308", match="period must be")


# -- 3. simulate: sizes that would overflow ---------------------------------------------------
def test_bump_radius_beyond_the_world():
    with pytest.raises(ParameterError, match=r"bump radius must be in \[0, 21.21\] m"):
        simulate_broken_map(degree=1, bump_radius=1e308)
    with pytest.raises(ParameterError, match="bump radius"):
        BumpOptions(bump_probability=0.1, bump_radius=math.nan).check_radius((0, 0, 10, 10))
    BumpOptions(bump_radius=1e308).check_radius((0, 0, 10, 10))  # no bumps drawn: unused
    BumpOptions(degree=1, bump_radius=14.1).check_radius((0, 0, 10, 10))


def test_cli_simulate_bump_radius_overflow(tmp_path, capsys):
    out = tmp_path / "s"
    refused(
        capsys,
        "simulate",
        "--out",
        out,
        "--degree",
        "1",
        "--bump-radius",
        "1e308",
        match="bump radius",
    )
    assert not out.exists() or not any(out.iterdir())


def test_simulate_building_size_and_route_bounds(tmp_path, capsys):
    with pytest.raises(ParameterError, match="at most 500 m x 500 m"):
        simulate_broken_map(size=MAX_BUILDING_SIDE + 1)
    refused(
        capsys,
        "simulate",
        "--out",
        tmp_path / "s",
        "--size",
        "1e6",
        "--resolution",
        "1e4",
        match="at most 500 m",
    )
    for spacing in (1e-308, math.nan, -1.0):
        with pytest.raises(ParameterError, match="spacing|scans"):
            route_poses([[0.0, 0.0], [10.0, 0.0]], spacing=spacing)
    with pytest.raises(MapSizeError, match="larger than the limit"):
        grid_geometry([[0.0, 0.0], [1e308, 1e308]], 0.05)


# -- 4. BROKENNESS_MAX_CELLS beyond any integer a float holds ---------------------------------
def test_max_cells_ceiling(capsys, monkeypatch, tmp_path):
    huge = "99999999999999999999999"
    with pytest.raises(ParameterError, match=f"{MAX_CELLS_ENV} must be at most 2\\*\\*53"):
        max_cells({MAX_CELLS_ENV: huge})
    assert max_cells({MAX_CELLS_ENV: str(MAX_CELLS_CEILING)}) == MAX_CELLS_CEILING
    monkeypatch.setenv(MAX_CELLS_ENV, huge)
    refused(capsys, "compute", MAP, REFERENCE, match=MAX_CELLS_ENV)
    small = tmp_path / "small.bin"
    small.write_bytes(b"abc")
    assert read_file_bytes(small, limit=2**62) == b"abc"  # the limit is never allocated


# -- 5. simulate: no partition counts ---------------------------------------------------------
@pytest.mark.parametrize(
    "options", [{"resolution": 100.0}, {"bump_probability": 1.0, "resolution": 0.1, "size": 10.0}]
)
def test_no_partition_counts_is_an_error(options):
    with pytest.raises(ParameterError, match="no partition of the broken map counts"):
        simulate_broken_map(**options)


def test_cli_simulate_no_partition_counts(tmp_path, capsys):
    refused(
        capsys,
        "simulate",
        "--out",
        tmp_path / "s",
        "--resolution",
        "100",
        match="no partition of the broken map counts",
    )


# -- 6, 7. batch options checked before any work ----------------------------------------------
def test_batch_worker_memory_checked_with_one_worker(tmp_path, monkeypatch):
    monkeypatch.setenv("BROKENNESS_WORKER_MEMORY", "abc")
    with pytest.raises(ParameterError, match="BROKENNESS_WORKER_MEMORY must be a size"):
        run_batch(EXAMPLES / "manifest.csv", tmp_path / "out", workers=1, progress=False)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("fraction", ["3", "-0.5", "nan"])
def test_batch_min_partition_fraction_checked_up_front(tmp_path, capsys, fraction):
    out = tmp_path / "out"
    refused(
        capsys,
        "batch",
        EXAMPLES / "manifest.csv",
        "--out",
        out,
        "--workers",
        "1",
        "--min-partition-fraction",
        fraction,
        match="min_partition_fraction must be in [0, 1)",
    )
    assert not out.exists()


# -- 8. write errors name the file asked for --------------------------------------------------
def test_write_errors_name_the_target(tmp_path, capsys):
    target = tmp_path / "nope" / "x.json"
    with pytest.raises(AtomicWriteError) as info:
        atomic_write_text(target, "{}")
    assert str(info.value) == f"cannot write {target}: No such file or directory"
    folder = tmp_path / "r.json"
    folder.mkdir()  # replacing a folder fails at the rename
    with pytest.raises(OSError, match=f"^cannot write {folder}: Is a directory$"):
        atomic_write_text(folder, "{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]  # no temp file left
    if os.path.isdir("/proc"):  # no file can be made there, whatever os.access says (root)
        err = refused(capsys, "compute", MAP, REFERENCE, "--json", "/proc/x.json", match="")
        assert "cannot write /proc/x.json" in err and ".tmp" not in err


# -- 9. load_map(None) ------------------------------------------------------------------------
@pytest.mark.parametrize("path", [None, 3, 2.5])
def test_load_map_of_no_path(path):
    with pytest.raises(ParameterError, match="must be a file path"):
        brokenness.load_map(path)


# -- 10. CSV rows with fewer values than the header -------------------------------------------
def test_short_csv_row_refused_with_its_line(tmp_path):
    manifest = tmp_path / "runs.csv"
    manifest.write_text(
        f"map,reference,system,noise\n# a comment\n\n{MAP},{REFERENCE},ex,0\n{MAP},{REFERENCE}\n"
    )
    with pytest.raises(ManifestError, match=r"row 2 \(line 5\): fewer values than columns"):
        read_manifest(manifest)
    manifest.write_text(f"map,reference,system\n{MAP},{REFERENCE},\n")  # empty, not missing
    assert read_manifest(manifest).pairs[0].labels == {}


def test_grid_geometry_of_an_ordinary_grid_unchanged():
    # grid_geometry still sizes an ordinary grid (the new cell check is not in the way)
    shape, origin = grid_geometry(np.array([[0.0, 0.0], [1.0, 2.0]]), 0.1, margin=0.5)
    assert shape == (30, 20) and origin == (-0.5, -0.5, 0.0)


def test_timeline_workers_are_bounded_as_a_batchs() -> None:
    """A timeline starts at most MAX_WORKERS processes, as a batch does: more is refused before
    anything is read."""
    from brokenness.limits import MAX_WORKERS
    from brokenness.timeline.run import timeline

    with pytest.raises(ParameterError, match=f"at most {MAX_WORKERS}"):
        timeline("no-such.bag", "no-such.yaml", workers=MAX_WORKERS + 1)
