"""Command-line plumbing under an adversarial review: result files with fields of odd types,
scheduler addresses, the error line, environment settings, and output paths (checked before
any work; never an input, never a special file replaced).

Each case runs the command line in this process (``brokenness.cli.main.main``) under an
alarm, as ``test_hostile.py`` does, and checks the contract: exit status, one line on stderr,
no traceback.
"""

from __future__ import annotations

import gc
import json
import os
import shutil
import stat
import time
import zipfile
from pathlib import Path
from typing import Any

import pytest
from _alarm import alarm
from test_report_fixtures import broken_rooms

import brokenness
import brokenness.cli.compute as cli_compute
import brokenness.report.html as report_html
from brokenness._atomic import AtomicWriteError, atomic_write_bytes
from brokenness.batch.cluster import check_scheduler
from brokenness.cli.main import MAX_ERROR_CHARS, main
from brokenness.errors import ParameterError
from brokenness.report import ResultFileError, load_results, save_results

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run_cli(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str]:
    """Exit status and stderr of ``brokenness *argv`` run in this process."""
    with alarm(30):
        code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


def refused(capsys: pytest.CaptureFixture[str], *argv: object, match: str) -> str:
    """``brokenness *argv`` exits 2 with one line holding ``match``, no traceback."""
    code, err = run_cli(capsys, *argv)
    assert code == 2, err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    assert match in err, err
    return err


def _never(*args: Any, **kwargs: Any) -> Any:
    raise AssertionError("the work started before the outputs were checked")


# -- result files with fields of odd types (review item 9) -----------------------------------
@pytest.fixture(scope="module")
def good_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    ref, m, result = broken_rooms()
    path = tmp_path_factory.mktemp("results") / "good.zip"
    save_results(path, result, m, ref, info={"labels": {"system": "a"}}, overlay="none")
    return path


def _with(src: Path, dst: Path, member: str, change: dict[str, Any]) -> Path:
    """``src`` with fields of one of its JSON members replaced."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == member:
                doc = json.loads(data)
                doc.update(change)
                data = json.dumps(doc).encode()
            zout.writestr(info.filename, data)
    return dst


ODD_FIELDS = [
    ("info.json", {"parameters": "x"}, "parameters must be an object, got text 'x'"),
    ("info.json", {"parameters": [1, 2]}, "parameters must be an object, got a list"),
    ("info.json", {"timings": "x"}, "timings must be an object"),
    ("info.json", {"timings": {"total_seconds": "x"}}, "timings.total_seconds must be a number"),
    ("info.json", {"labels": [1, 2]}, "labels must be an object"),
    ("info.json", {"labels": {"system": {"a": 1}}}, "labels.system must be text, a number"),
    ("info.json", {"method": 5}, "method must be text, got a number 5"),
    ("stats.json", {"measured": "no"}, "measured must be true or false"),
    ("stats.json", {"psi_map": "x"}, "psi_map must be a number"),
    ("stats.json", {"largest_fraction": 1e308}, "largest_fraction must be a share in [0, 1]"),
    (
        "stats.json",
        {"degree": 0, "partitions": [{"index": 0, "cells": 9, "fraction": 0.5, "transform": "x"}]},
        "partitions[0].transform must be an object, got text 'x'",
    ),
    ("stats.json", {"degree": 0, "partitions": [{"fraction": 0.5}]}, "partitions[0].index is"),
    ("stats.json", {"degree": 7}, "degree must be the partitions less one, got degree 7"),
    ("stats.json", {"degree": None}, "got degree null with 2 partitions"),
]


@pytest.mark.parametrize(("member", "change", "match"), ODD_FIELDS)
def test_odd_field_types_are_refused_naming_file_and_field(
    tmp_path, capsys, good_zip, member, change, match
):
    odd = _with(good_zip, tmp_path / "odd.zip", member, change)
    with pytest.raises(ResultFileError, match=f"odd.zip: {member}: ") as info:
        load_results(odd)
    assert match in str(info.value)
    for command in (["compare"], ["report", "--html", tmp_path / "r.html"]):
        err = refused(capsys, command[0], good_zip, odd, *command[1:], match=match)
        assert str(odd) in err
    assert not (tmp_path / "r.html").exists()


def test_good_result_file_still_reads_and_reports(tmp_path, capsys, good_zip):
    nulls = _with(good_zip, tmp_path / "nulls.zip", "info.json", {"parameters": None})
    code, err = run_cli(capsys, "report", good_zip, nulls, "--html", tmp_path / "r.html")
    assert code == 0, err
    assert "<html" in (tmp_path / "r.html").read_text()


# -- scheduler addresses (item 11) ------------------------------------------------------------
@pytest.mark.parametrize(
    ("address", "ok"),
    [
        ("tcp://127.0.0.1:8786", True),
        ("127.0.0.1:8786", True),
        ("tls://[::1]:8786", True),
        ("garbage", False),
        ("tcp://host", False),
        ("http://host:80", False),
        ("inproc://192.0.2.2/8834/1", True),
        ("host:99999", False),
        ("a\nb:8786", False),
    ],
)
def test_scheduler_address_checked_without_a_client(address, ok):
    if ok:
        check_scheduler(address)
    else:
        with pytest.raises(ParameterError, match="not a Dask scheduler address"):
            check_scheduler(address)


@pytest.mark.parametrize("command", ["batch", "timeline"])
def test_garbage_scheduler_is_one_line_before_any_client(tmp_path, capsys, monkeypatch, command):
    distributed = pytest.importorskip("distributed")
    monkeypatch.setattr(distributed, "Client", _never)  # no half-made client to close
    if command == "batch":
        manifest = tmp_path / "m.csv"
        manifest.write_text(f"map,reference\n{EXAMPLES / 'building_31.yaml'},x.yaml\n")
        argv: list[object] = ["batch", manifest, "--out", tmp_path / "out", "--workers", "1"]
    else:
        argv = ["timeline", tmp_path / "run.bag", EXAMPLES / "building_31.yaml"]
    refused(capsys, *argv, "--scheduler", "garbage", match="not a Dask scheduler address")
    assert not (tmp_path / "out").exists()


def test_a_client_that_fails_to_start_is_closed_at_once(tmp_path, capsys):
    pytest.importorskip("distributed")
    start = time.perf_counter()
    argv = ["batch", _one_pair(tmp_path), "--out", tmp_path / "out", "--workers", "1"]
    # TLS without its certificates: the client fails after its event loop has started
    refused(capsys, *argv, "--scheduler", "tls://127.0.0.1:1", match="cannot connect to the")
    gc.collect()  # a half-made client left behind would wait 20 s here, with a traceback
    assert time.perf_counter() - start < 5
    assert "Exception ignored" not in capsys.readouterr().err


# -- one error line (item 19) -----------------------------------------------------------------
def test_error_with_a_newline_is_one_line_escaped(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    err = refused(
        capsys,
        "compute",
        "m.yaml",
        "r.yaml",
        "--json",
        "no\ndir/x.json",
        match="--json no\\ndir/x.json: folder no\\ndir does not exist",
    )
    assert err.startswith("brokenness compute: error: ")


def test_long_error_is_cut(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    long = "d" * 3000
    err = refused(capsys, "compute", "m.yaml", "r.yaml", "--json", f"{long}/x.json", match="...")
    assert len(err) <= len("brokenness compute: error: ") + MAX_ERROR_CHARS + 1
    assert err.endswith("...\n")


# -- environment settings checked first (item 20) and the memory limit (item 23) ---------------
def _one_pair(folder: Path) -> Path:
    manifest = folder / "m.csv"
    ex = EXAMPLES
    manifest.write_text(f"map,reference\n{ex / 'building_31.yaml'},{ex / 'building_31.yaml'}\n")
    return manifest


def test_bad_max_cells_stops_a_batch_before_any_work(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("BROKENNESS_MAX_CELLS", "abc")
    out = tmp_path / "out"
    argv = ["batch", _one_pair(tmp_path), "--out", out, "--workers", "1", "--no-progress"]
    refused(capsys, *argv, match="BROKENNESS_MAX_CELLS must be a positive integer")
    assert not out.exists()  # no folder, no error rows


def test_bad_max_cells_stops_a_timeline_before_the_bag_is_read(tmp_path, monkeypatch):
    monkeypatch.setenv("BROKENNESS_MAX_CELLS", "abc")
    with pytest.raises(ParameterError, match="BROKENNESS_MAX_CELLS"):
        brokenness.timeline(tmp_path / "no.bag", tmp_path / "no.yaml")


def test_worker_memory_with_one_worker_says_it_is_not_applied(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("BROKENNESS_WORKER_MEMORY", "4G")
    manifest = tmp_path / "m.csv"
    manifest.write_text("map,reference\nmissing.yaml,missing.yaml\n")  # fails at once
    argv = ["batch", manifest, "--out", tmp_path / "out", "--workers", "1", "--no-progress"]
    code, err = run_cli(capsys, *argv)
    assert code == 1, err  # the pair failed; the run went on
    warning = [line for line in err.splitlines() if "BROKENNESS_WORKER_MEMORY" in line]
    assert warning == [
        "brokenness: warning: BROKENNESS_WORKER_MEMORY=4G is not applied: it limits the worker "
        "processes of workers > 1 only; with one worker the pairs are evaluated in this process"
    ]


# -- output paths: checked before the work (item 21), never an input (item 22) ---------------
@pytest.fixture
def pair(tmp_path: Path) -> tuple[Path, Path]:
    """Copies of the bundled map and reference (YAML + PNG) in ``tmp_path``."""
    for name in ("broken_building_31", "building_31"):
        for suffix in (".yaml", ".png"):
            shutil.copy(EXAMPLES / f"{name}{suffix}", tmp_path / f"{name}{suffix}")
    return tmp_path / "broken_building_31.yaml", tmp_path / "building_31.yaml"


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc")
def test_unwritable_folder_is_refused_before_the_maps_load(capsys, monkeypatch, pair):
    monkeypatch.setattr(cli_compute, "load_pair", _never)
    m, ref = pair
    refused(capsys, "compute", m, ref, "--json", "/proc/x.json", match="/proc is not writable")
    refused(capsys, "compare", m, "--table", "/proc/x.md", match="--table: cannot write /proc/x.md")


def test_report_into_a_folder_is_refused_before_reading(tmp_path, capsys, monkeypatch, good_zip):
    monkeypatch.setattr(report_html, "collect_results", _never)
    refused(capsys, "report", good_zip, "--html", tmp_path, match="is a folder, not a file")


@pytest.mark.parametrize(
    ("option", "target", "match"),
    [
        ("--repaired", "building_31.yaml", "is an input of this command"),
        ("--json", "broken_building_31.png", "is the image of the input map"),
        ("--json", "building_31.png", "is the image of the input map"),
        ("--repaired", "sub/../building_31.yaml", "is an input of this command"),
        ("--overlay", "building_31.png", "is the image of the input map"),
    ],
)
def test_an_output_never_overwrites_an_input(capsys, monkeypatch, pair, option, target, match):
    monkeypatch.setattr(cli_compute, "load_pair", _never)
    m, ref = pair
    (m.parent / "sub").mkdir()
    before = {p.name: p.read_bytes() for p in m.parent.iterdir() if p.is_file()}
    refused(capsys, "compute", m, ref, option, m.parent / target, match=match)
    assert {p.name: p.read_bytes() for p in m.parent.iterdir() if p.is_file()} == before


def test_an_input_named_through_a_link_or_a_repaired_image(capsys, monkeypatch, pair):
    monkeypatch.setattr(cli_compute, "load_pair", _never)
    m, ref = pair
    link = m.parent / "link.yaml"
    link.symlink_to(ref)
    refused(capsys, "compute", m, link, "--repaired", ref, match="is an input of this command")
    # a YAML map is written with its image next to it: that image may be an input too
    pgm_map = m.parent / "map.pgm"
    pgm_map.write_bytes(b"P5 1 1 255\n\x00")
    refused(
        capsys,
        "compute",
        pgm_map,
        ref,
        "--repaired",
        m.parent / "map.yaml",
        match="(writes " + str(pgm_map) + "): is an input of this command",
    )
    (m.parent / "sub").mkdir()
    dotted = m.parent / "sub" / ".." / m.name
    refused(capsys, "register", ref, m, "--json", dotted, match="is an input of this command")


def test_a_batch_summary_never_overwrites_its_manifest(tmp_path, capsys):
    out = tmp_path / "runs"
    out.mkdir()
    manifest = _one_pair(out)
    manifest = manifest.rename(out / "summary.csv")
    text = manifest.read_text()
    refused(capsys, "batch", manifest, "--out", out, match="summary.csv): is an input")
    assert manifest.read_text() == text


def test_two_outputs_to_one_file_are_refused(tmp_path, capsys, monkeypatch, pair):
    monkeypatch.setattr(cli_compute, "load_pair", _never)
    m, ref = pair
    out = tmp_path / "o.png"
    refused(capsys, "compute", m, ref, "--json", out, "--overlay", out, match="written by --json")


# -- special files are never replaced ----------------------------------------------------------
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_a_fifo_output_is_refused_not_replaced(tmp_path, capsys, monkeypatch, pair):
    monkeypatch.setattr(cli_compute, "load_pair", _never)
    fifo = tmp_path / "out.json"
    os.mkfifo(fifo)
    with pytest.raises(AtomicWriteError, match="not a regular file"):
        atomic_write_bytes(fifo, b"{}")
    m, ref = pair
    refused(capsys, "compute", m, ref, "--json", fifo, match="exists and is not a regular file")
    assert stat.S_ISFIFO(fifo.stat().st_mode)


def test_a_character_device_is_written_in_place(tmp_path):
    null = tmp_path / "null"
    try:
        os.mknod(null, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # a /dev/null of our own
    except (OSError, AttributeError):
        pytest.skip("cannot make a device node here (not root)")
    atomic_write_bytes(null, b"{}")
    assert stat.S_ISCHR(null.stat().st_mode)  # still the device, not a file in its place
    assert [p.name for p in tmp_path.iterdir()] == ["null"]  # no temporary file left


def test_register_names_its_flag_when_candidates_are_out_of_range(capsys):
    """--candidates over MAX_CANDIDATES (2048) is refused before any work, naming the flag."""
    for n in (0, 5000):
        line = refused(
            capsys,
            "register",
            EXAMPLES / "building_31.yaml",
            EXAMPLES / "building_31.yaml",
            "--candidates",
            n,
            match="--candidates must be an integer in",
        )
        assert "max_candidates" not in line
