"""Hostile-input corpus: every row of issue 11's table, built in tmp_path.

Each case runs the command line in this process (``brokenness.cli.main.main``) under an alarm,
so that a regression that hangs fails the test instead of hanging the suite, and checks the
contract: exit 2, exactly one line on stderr, no traceback, within a few seconds. The batch
rows (kills, Ctrl-C, two batches on one folder) run the real command in a subprocess.
"""

from __future__ import annotations

import csv
import io
import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from _alarm import alarm
from PIL import Image

import brokenness
from brokenness.batch import read_manifest
from brokenness.batch.runner import LOCK_NAME, lock_folder
from brokenness.cli.main import main
from brokenness.report import load_results

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
MAP = EXAMPLES / "broken_building_31.yaml"
REFERENCE = EXAMPLES / "building_31.yaml"
SECONDS = 5.0  # the target for every row
POSIX = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")


def run_cli(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, float]:
    """Exit code, stderr and seconds of ``brokenness *argv`` run in this process."""
    start = time.perf_counter()
    with alarm():
        code = main([str(a) for a in argv])
    seconds = time.perf_counter() - start
    return code, capsys.readouterr().err, seconds


def refused(capsys: pytest.CaptureFixture[str], *argv: object, match: str) -> str:
    """``brokenness *argv`` exits 2 with one line naming ``match``, fast, no traceback."""
    code, err, seconds = run_cli(capsys, *argv)
    assert code == 2, err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    assert match.lower() in err.lower(), err
    assert seconds < SECONDS, f"{seconds:.1f} s"
    return err


def yaml_map(folder: Path, image: str | Path, extra: str = "resolution: 0.05\n") -> Path:
    path = folder / "m.yaml"
    path.write_text(f"image: {image}\n{extra}")
    return path


def small_png(path: Path, size: int = 40) -> Path:
    img = np.full((size, size), 254, np.uint8)
    img[5, 5:35] = img[5:35, 5] = img[34, 5:35] = img[5:35, 34] = img[5:20, 20] = 0
    Image.fromarray(img).save(path)
    return path


# -- inputs that are not regular files ---------------------------------------------------------
@POSIX
def test_fifo_as_map_yaml_image_and_bag(tmp_path, capsys):
    for name in ("map.pgm", "map.png", "map.yaml", "map.npy", "map.bag", "img.pgm"):
        os.mkfifo(tmp_path / name)
    for name in ("map.pgm", "map.png", "map.yaml", "map.npy", "map.bag"):
        refused(capsys, "compute", tmp_path / name, REFERENCE, match="FIFO")
    refused(capsys, "compute", yaml_map(tmp_path, "img.pgm"), REFERENCE, match="FIFO")
    with pytest.raises(brokenness.MapError, match="FIFO"), alarm():
        brokenness.load_map(tmp_path / "map.pgm")


@POSIX
def test_fifo_in_a_rosbag2_folder(tmp_path, capsys):
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    os.mkfifo(bag / "bag_0.db3")
    refused(capsys, "compute", bag, REFERENCE, match="FIFO")


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_devices_as_yaml_image_or_through_a_symlink(tmp_path, capsys, device):
    refused(capsys, "compute", yaml_map(tmp_path, device), REFERENCE, match="character device")
    link = tmp_path / "link.png"
    link.symlink_to(device)
    refused(capsys, "compute", link, REFERENCE, match="character device")
    refused(capsys, "compute", yaml_map(tmp_path, link.name), REFERENCE, match="device")


def test_symlink_loop_and_dangling_link(tmp_path, capsys):
    (tmp_path / "a.pgm").symlink_to(tmp_path / "b.pgm")
    (tmp_path / "b.pgm").symlink_to(tmp_path / "a.pgm")
    refused(capsys, "compute", tmp_path / "a.pgm", REFERENCE, match="symbolic link loop")
    (tmp_path / "gone.pgm").symlink_to(tmp_path / "nothing.pgm")
    refused(capsys, "compute", tmp_path / "gone.pgm", REFERENCE, match="broken symbolic link")


@POSIX
def test_fifo_manifest_and_fifo_result(tmp_path, capsys):
    os.mkfifo(tmp_path / "runs.csv")
    refused(capsys, "batch", tmp_path / "runs.csv", "--out", tmp_path / "o", match="FIFO")
    os.mkfifo(tmp_path / "r.zip")
    refused(capsys, "compare", tmp_path / "r.zip", match="FIFO")


def test_huge_yaml_is_refused_by_size(tmp_path, capsys):
    path = tmp_path / "m.yaml"
    path.write_bytes(b"image: m.pgm\nresolution: 0.05\n#" + b"x" * (2 << 20) + b"\n")
    refused(capsys, "compute", path, REFERENCE, match="limit")


# -- YAML ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ("resolution: !!int\n", "invalid YAML"),
        ("resolution: !!float nen\n", "invalid YAML"),
        ("resolution: !!timestamp 2020-99-99\n", "invalid YAML"),
        ("resolution: 1.0e-300\n", "outside the supported range"),
        ("resolution: 1.0e+300\n", "outside the supported range"),
        ("resolution: 1e999999\n", "must be finite"),
        ("resolution: 0.05\nresolution: 0.1\n", "duplicate key 'resolution'"),
        ("resolution: 0.05\norigin: [1e300, 0, 0]\n", "out of range"),
        ("resolution: 0.05\norigin: " + "[" * 1000 + "]" * 1000 + "\n", "YAML"),
        ("resolution: 0.05\nnegate: !!int\n", "invalid YAML"),
    ],
)
def test_hostile_yaml_fields(tmp_path, capsys, fields, match):
    small_png(tmp_path / "m.png")
    refused(capsys, "compute", yaml_map(tmp_path, "m.png", fields), REFERENCE, match=match)


def test_tagged_values_and_duplicate_keys_in_a_manifest(tmp_path, capsys):
    out = tmp_path / "o"
    for text, match in [
        ("pairs:\n  - {map: a.yaml, reference: b.yaml, seed: !!int }\n", "not valid YAML"),
        ("pairs:\n  - {map: a.yaml, reference: !!float nen}\n", "not valid YAML"),
        ("pairs:\n  - {map: a.yaml, map: c.yaml, reference: b.yaml}\n", "duplicate key"),
    ]:
        (tmp_path / "runs.yaml").write_text(text)
        refused(capsys, "batch", tmp_path / "runs.yaml", "--out", out, match=match)
    (tmp_path / "runs.csv").write_text('map,reference\n"' + "a" * 200_000 + '",b\n')
    refused(capsys, "batch", tmp_path / "runs.csv", "--out", out, match="invalid CSV")


def test_resampling_to_a_much_finer_reference_is_refused_before_allocation(tmp_path, capsys):
    small_png(tmp_path / "r.png")
    fine = tmp_path / "fine.yaml"
    fine.write_text("image: r.png\nresolution: 0.0005\n")
    coarse = tmp_path / "coarse.yaml"
    coarse.write_text(f"image: {MAP.with_suffix('.png')}\nresolution: 0.05\n")
    refused(capsys, "compute", coarse, fine, match="larger than the limit")


def test_cell_limit_is_overridable(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("BROKENNESS_MAX_CELLS", "1000")
    refused(capsys, "compute", MAP, REFERENCE, match="BROKENNESS_MAX_CELLS")
    monkeypatch.setenv("BROKENNESS_MAX_CELLS", "lots")
    refused(capsys, "compute", MAP, REFERENCE, match="positive integer")


# -- options ---------------------------------------------------------------------------------
@pytest.mark.parametrize("value", ["1e9", "nan", "inf", "-1", "0", "5000"])
def test_absurd_threshold(capsys, value):
    refused(capsys, "compute", MAP, REFERENCE, "--threshold", value, match="threshold")


def test_absurd_batch_options(tmp_path, capsys):
    manifest = tmp_path / "runs.csv"
    manifest.write_text(f"map,reference\n{MAP},{REFERENCE}\n")
    out = tmp_path / "o"
    refused(capsys, "batch", manifest, "--out", out, "--threshold", "1e9", match="threshold")
    refused(capsys, "batch", manifest, "--out", out, "--workers", "100000", match="workers")
    (tmp_path / "runs.yaml").write_text(
        f"options: {{no_such_option: 1}}\npairs:\n  - {{map: {MAP}, reference: {REFERENCE}}}\n"
    )
    refused(capsys, "batch", tmp_path / "runs.yaml", "--out", out, match="unknown option")


def test_absurd_seed_and_dpi(tmp_path, capsys):
    refused(capsys, "compute", MAP, REFERENCE, "--seed", "-5", match="--seed")
    refused(capsys, "compare", tmp_path, "--dpi", "10000000", match="--dpi")
    # one range for every picture: compare and compute alike
    for command in (["compare", tmp_path], ["compute", MAP, REFERENCE]):
        refused(capsys, *command, "--dpi", "5", match="--dpi must be between 10 and 1200")


# -- numpy -----------------------------------------------------------------------------------
def npy_with_header(path: Path, header: dict[str, object]) -> Path:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    path.write_bytes(buf.getvalue() + b"\x00" * 64)
    return path


@pytest.mark.parametrize(
    ("shape", "match"),
    [
        ((10**12,), "larger than the limit"),
        ((10**5, 10**5, 100), "larger than the limit"),
        ((100,), "2D"),
        ((10, 10, 10), "2D"),
        ((10**6, 10**6), "larger than the limit"),
        ((1000, 1000), "truncated"),
    ],
)
def test_npy_headers(tmp_path, capsys, shape, match):
    header = {"descr": "<f8", "fortran_order": False, "shape": shape}
    path = npy_with_header(tmp_path / "m.npy", header)
    refused(capsys, "compute", path, REFERENCE, match=match)


def test_npy_of_strings_is_refused_before_allocation(tmp_path, capsys):
    header = {"descr": "<U100000", "fortran_order": False, "shape": (1000, 1000)}
    path = npy_with_header(tmp_path / "m.npy", header)
    refused(capsys, "compute", path, REFERENCE, match="truncated")


# -- result files ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def result_zip(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("result")
    path = folder / "good.zip"
    assert main(["compute", str(MAP), str(REFERENCE), "--save-results", str(path)]) == 0
    return path


def rewrite(src: Path, dst: Path, **members: bytes) -> Path:
    """``src`` with some members replaced (same names, deflated)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            zout.writestr(info.filename, members.get(info.filename, zin.read(info)))
    return dst


def corrupt_deflate(src: Path, dst: Path) -> Path:
    """``src`` with bytes of stats.json's compressed data flipped (headers intact)."""
    data = bytearray(src.read_bytes())
    with zipfile.ZipFile(src) as zf:
        info = zf.getinfo("stats.json")
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    for k in range(start + 2, start + min(info.compress_size, 40)):
        data[k] ^= 0x5A
    dst.write_bytes(bytes(data))
    return dst


def test_compare_on_corrupt_zips(tmp_path, capsys, result_zip):
    refused(capsys, "compare", corrupt_deflate(result_zip, tmp_path / "z.zip"), match="damaged")
    stats = json.loads(zipfile.ZipFile(result_zip).read("stats.json"))
    text = json.dumps(stats).replace(f'"degree": {stats["degree"]}', '"degree": Infinity')
    inf = rewrite(result_zip, tmp_path / "inf.zip", **{"stats.json": text.encode()})
    refused(capsys, "compare", inf, match="non-finite")
    big = rewrite(result_zip, tmp_path / "e.zip", **{"stats.json": b'{"degree": 1e400}'})
    refused(capsys, "compare", big, match="non-finite")
    neg = rewrite(result_zip, tmp_path / "n.zip", **{"stats.json": b'{"degree": -3}'})
    refused(capsys, "compare", neg, match="invalid degree")
    (tmp_path / "junk.zip").write_bytes(b"PK\x03\x04" + b"\x00" * 100)
    refused(capsys, "compare", tmp_path / "junk.zip", match="zip")


def test_zip_bomb_member_is_refused_from_its_declared_size(tmp_path, capsys, result_zip):
    bomb = b'{"degree": 0, "pad": "' + b" " * (20 << 20) + b'"}'
    path = rewrite(result_zip, tmp_path / "bomb.zip", **{"stats.json": bomb})
    assert path.stat().st_size < 1 << 20  # a small file that would inflate to 20 MB
    refused(capsys, "compare", path, match="declares")
    labels = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        labels, {"descr": "<i2", "fortran_order": False, "shape": (10**5, 10**5)}
    )
    path = rewrite(result_zip, tmp_path / "labels.zip", **{"labels.npy": labels.getvalue()})
    with pytest.raises(brokenness.BrokennessError, match="larger than the limit"):
        load_results(path)


# -- outputs ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("option", "value", "match"),
    [
        ("--overlay", "out.jpgx", "unsupported file type"),
        ("--overlay", "nodir/o.png", "does not exist"),
        ("--save-results", "run.tar", "unsupported file type"),
        ("--save-results", "nodir/run.zip", "does not exist"),
        ("--repaired", "fixed.txt", "unsupported file type"),
        ("--json", "nodir/r.json", "does not exist"),
    ],
)
def test_output_paths_checked_before_computing(tmp_path, capsys, monkeypatch, option, value, match):
    monkeypatch.chdir(tmp_path)
    err = refused(capsys, "compute", MAP, REFERENCE, option, value, match=match)
    assert option in err


def test_output_folder_is_a_file_or_read_only(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    refused(capsys, "compute", MAP, REFERENCE, "--overlay", tmp_path / "file" / "o.png",
            match="not a folder")  # fmt: skip
    manifest = tmp_path / "runs.csv"
    manifest.write_text(f"map,reference\n{MAP},{REFERENCE}\n")
    refused(capsys, "batch", manifest, "--out", tmp_path / "file", match="not a folder")
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir(mode=0o500)
        refused(capsys, "compute", MAP, REFERENCE, "--json", ro / "r.json", match="not writable")


# -- maps that cannot be measured ------------------------------------------------------------
def test_single_occupied_cell_is_not_degree_0(tmp_path, capsys):
    one = np.zeros((50, 50), np.int8)
    one[25, 25] = 1
    np.save(tmp_path / "one.npy", one)
    refused(
        capsys,
        "compute",
        tmp_path / "one.npy",
        REFERENCE,
        "--map-resolution",
        "0.05",
        match="too few occupied cells",
    )


def test_overlay_of_a_huge_map_is_reduced_and_keeps_thin_walls():
    from brokenness.report.overlay import overlay_image

    states = np.zeros((3000, 2000), np.int8)
    states[1500, :] = 1  # a wall one cell thin
    m = brokenness.OccupancyMap(states)
    result = brokenness.compute_brokenness(m, m)
    rgb = overlay_image(result, m, m, max_side=500)
    assert rgb.shape == (500, 334, 3)
    wall = rgb[250]
    assert np.all(np.abs(wall - wall[0]) < 1e-6) and not np.allclose(wall[0], 1.0)


# -- batch -----------------------------------------------------------------------------------
def test_second_batch_on_the_same_folder_is_refused(tmp_path, capsys):
    manifest = tmp_path / "runs.csv"
    manifest.write_text(f"map,reference\n{MAP},{REFERENCE}\n")
    out = tmp_path / "o"
    out.mkdir()
    with lock_folder(out):
        refused(capsys, "batch", manifest, "--out", out, "--workers", "1", match="another batch")
    assert (out / LOCK_NAME).exists()
    assert not list(out.glob("*.zip"))


def test_damaged_zip_on_resume_is_recomputed(tmp_path, capsys):
    manifest = tmp_path / "runs.csv"
    manifest.write_text(f"map,reference\n{MAP},{REFERENCE}\n")
    out = tmp_path / "o"
    code, err, _ = run_cli(capsys, "batch", manifest, "--out", out, "--workers", "1",
                           "--no-progress")  # fmt: skip
    assert code == 0, err
    (zipped,) = out.glob("*.zip")
    corrupt_deflate(zipped, zipped)
    code, err, _ = run_cli(capsys, "batch", manifest, "--out", out, "--workers", "1",
                           "--no-progress")  # fmt: skip
    assert code == 0, err
    assert load_results(zipped).degree == 2
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [r["status"] for r in rows] == ["done"]


# the batch's workers are separate processes: these tests run the real command
def _procs() -> dict[int, tuple[str, int]]:
    """pid -> (comm, parent pid) of every process."""
    out = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                comm = Path(f"/proc/{entry}/comm").read_text().strip()
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            out[int(entry)] = (comm, int(stat.rsplit(")", 1)[1].split()[1]))
    return out


def _wait_for(predicate, seconds: float = 60.0):  # type: ignore[no-untyped-def]
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.01)
    raise AssertionError("timed out")


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _batch(manifest: Path, out: Path, **kw: object) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "brokenness.cli.main", "batch", str(manifest), "--out", str(out)]
    return subprocess.Popen(
        [*cmd, "--workers", "2", "--no-progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,  # type: ignore[call-overload]
    )


@pytest.fixture
def slow_manifest(tmp_path) -> tuple[Path, str]:
    """A manifest whose first pair (a 4x larger map) takes a while, then three quick pairs."""
    m, ref = brokenness.load_map(MAP), brokenness.load_map(REFERENCE)
    np.save(tmp_path / "big.npy", np.tile(m.states, (2, 2)))
    np.save(tmp_path / "bigref.npy", np.tile(ref.states, (2, 2)))
    quick = "".join(f"{MAP},{REFERENCE},{k}\n" for k in range(3))
    path = tmp_path / "runs.csv"
    # a label unique to this test: its pair id (and worker name) is not another test's
    path.write_text(f"map,reference,k\nbig.npy,bigref.npy,slow-{tmp_path.name}\n" + quick)
    slow = read_manifest(path).pairs[0]
    return path, slow.id


@pytest.mark.skipif(not Path("/proc/self/comm").exists(), reason="needs Linux /proc")
def test_killed_worker_costs_only_its_pair(tmp_path, slow_manifest):
    manifest, slow_id = slow_manifest
    proc = _batch(manifest, tmp_path / "o")
    try:
        worker = _wait_for(lambda: [p for p, (c, _) in _procs().items() if c == f"bk-{slow_id}"])
        os.kill(worker[0], signal.SIGKILL)  # as the OOM killer would
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 1, err
    assert "Traceback" not in err
    rows = {r["id"]: r for r in csv.DictReader((tmp_path / "o" / "summary.csv").open())}
    assert rows[slow_id]["status"] == "error"
    assert "worker killed by SIGKILL" in rows[slow_id]["error"]
    assert "out of memory?" in rows[slow_id]["error"]
    others = [r for i, r in rows.items() if i != slow_id]
    assert [r["status"] for r in others] == ["done"] * 3
    assert "worker killed" in out


@pytest.mark.skipif(not Path("/proc/self/comm").exists(), reason="needs Linux /proc")
def test_killed_batch_leaves_no_process_behind(tmp_path, slow_manifest):
    manifest, slow_id = slow_manifest
    proc = _batch(manifest, tmp_path / "o")
    try:
        _wait_for(lambda: [p for p, (c, _) in _procs().items() if c == f"bk-{slow_id}"])
        ps = _procs()
        children = [p for p, (_, parent) in ps.items() if parent == proc.pid]  # fork server...
        workers = [p for p, (_, parent) in ps.items() if parent in children]
        assert workers
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        proc.kill()
        proc.communicate()

    def gone() -> bool:
        return not [p for p in children + workers if _running(p)]

    _wait_for(gone, seconds=10)


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def test_ctrl_c_drains_the_workers_before_the_summary(tmp_path):
    manifest = tmp_path / "runs.csv"
    # enough pairs that the batch cannot finish between its first result and the signal
    pairs = 40
    manifest.write_text(
        "map,reference,k\n" + "".join(f"{MAP},{REFERENCE},{k}\n" for k in range(pairs))
    )
    out = tmp_path / "o"
    # Ctrl-C as a terminal delivers it: the batch must not inherit SIGINT ignored (as it
    # does when the suite runs as a background job of a shell without job control)
    proc = _batch(manifest, out, start_new_session=True, preexec_fn=_default_sigint)
    try:
        _wait_for(lambda: out.is_dir() and list(out.glob("*.zip")), seconds=30)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C reaches the whole process group
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    time.sleep(1.0)  # a worker left running would write more zips now
    finished = {p.stem.rsplit("-", 1)[1] for p in out.glob("*.zip")}
    rows = {r["id"]: r["status"] for r in csv.DictReader((out / "summary.csv").open())}
    assert len(rows) == pairs
    assert {i for i, s in rows.items() if s == "done"} == finished
    assert set(rows.values()) <= {"done", "not run"}


def test_plain_pgm_with_a_tiny_header_and_a_huge_body(tmp_path):
    # numpy would parse (and allocate 8 bytes for) every token; only 4 are samples
    path = tmp_path / "m.pgm"
    path.write_bytes(b"P2\n2 2\n255\n" + b"0 " * 10_000_000)
    start = time.perf_counter()
    with alarm():
        m = brokenness.load_map(path)
    assert m.shape == (2, 2)
    assert time.perf_counter() - start < SECONDS
