"""Input hardening of the readers (adversarial review 1): one strict YAML reader without
aliases, bounded echoes of values and paths, every file of a bag folder checked, bounded
metadata and CARMEN logs, no silent misreading of 32-bit integer images, and a folder that
cannot be entered reported as a typed error.

Each test fails without its fix and runs in well under a second: the "bombs" are small (a
few levels of aliases, a few MiB of zeros) and the limits are lowered where needed.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from _alarm import alarm
from PIL import Image

import brokenness
from brokenness.batch import read_manifest
from brokenness.batch.manifest import ManifestError
from brokenness.cli.main import main
from brokenness.errors import BrokennessError, MapError, MapFormatError, MapSizeError
from brokenness.io import load_map
from brokenness.io._files import PATH_CHARS, SHOWN_CHARS, path_text, shown
from brokenness.io._yaml import parse_yaml
from brokenness.io.pixels import _from_pillow
from brokenness.io.rosbag import check_bag, load_bag_map
from brokenness.limits import MAX_TEXT_BYTES
from brokenness.simulation import carmen
from brokenness.simulation.carmen import read_carmen

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
REFERENCE = EXAMPLES / "building_31.yaml"
POSIX = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
SHORT = 400  # a message that echoes a value or a path stays below this many characters


def alias_bomb(levels: int, key: str = "x") -> str:
    """YAML lines defining nested aliases: ``*{key}{levels - 1}`` stands for 9**levels items."""
    lines = [f'{key}0: &{key}0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, levels):
        refs = ", ".join([f"*{key}{i - 1}"] * 9)
        lines.append(f"{key}{i}: &{key}{i} [{refs}]")
    return "\n".join(lines) + "\n"


def small_png(path: Path) -> Path:
    img = np.full((40, 40), 254, np.uint8)
    img[5, 5:35] = img[5:35, 5] = img[34, 5:35] = img[5:35, 34] = 0
    Image.fromarray(img).save(path)
    return path


def one_short_line(exc: BaseException) -> str:
    msg = str(exc)
    assert isinstance(exc, BrokennessError)
    assert "\n" not in msg and len(msg) < SHORT, msg[:500]
    return msg


# -- the message helpers ----------------------------------------------------------------------
def test_shown_is_short_and_one_line_whatever_the_value():
    assert shown("resolution") == "'resolution'"
    assert shown("a\nb") == "'a\\nb'"
    for value in ("9" * 500_000, [["x"] * 1000] * 1000, {str(i): i for i in range(10_000)}):
        text = shown(value)
        assert len(text) <= SHOWN_CHARS and "\n" not in text
    assert "digits" in shown(10**5000)  # repr itself refuses an int of more than 4300 digits
    nested: list[object] = []
    for _ in range(50):
        nested = [nested] * 9  # 9**50 items once expanded: only the top is walked
    assert len(shown(nested)) <= SHOWN_CHARS


def test_path_text_escapes_and_bounds_paths():
    assert path_text("maps/a.yaml") == "maps/a.yaml"
    assert path_text(Path("maps") / "a.yaml") == os.path.join("maps", "a.yaml")
    assert path_text("a\nb.png") == "'a\\nb.png'"
    long = path_text("d/" * 100_000 + "map.png")
    assert len(long) <= PATH_CHARS and long.endswith("map.png")


# -- 2. YAML aliases ----------------------------------------------------------------------------
def test_the_yaml_reader_refuses_aliases():
    assert parse_yaml(b"a: &x 1\nb: 2\n", "m.yaml") == {"a": 1, "b": 2}  # an anchor alone
    with pytest.raises(MapFormatError, match=r"m.yaml: invalid YAML \(alias \*x \(line 2"):
        parse_yaml(b"a: &x 1\nb: *x\n", "m.yaml")
    with pytest.raises(MapFormatError, match="alias"):
        parse_yaml(b"base: &b {resolution: 0.05}\nmap:\n  <<: *b\n", "m.yaml")


@pytest.mark.parametrize("key", ["resolution", "image", "origin", "mode", "negate"])
def test_a_map_yaml_alias_bomb_is_refused_at_once(tmp_path, key, capsys):
    small_png(tmp_path / "m.png")
    fields = {"image": "m.png", "resolution": "0.05"} | {key: "*x5"}
    path = tmp_path / "bomb.yaml"
    path.write_text(alias_bomb(6) + "".join(f"{k}: {v}\n" for k, v in fields.items()))
    start = time.perf_counter()
    with pytest.raises(MapFormatError, match="alias") as info:
        load_map(path)
    assert time.perf_counter() - start < 2.0
    one_short_line(info.value)
    assert main(["compute", str(path), str(REFERENCE)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and len(err) < SHORT and "alias" in err


def test_a_manifest_alias_bomb_is_refused(tmp_path):
    path = tmp_path / "runs.yaml"
    text = "defaults:\n  reference: ref.yaml\n" + "".join(
        "  " + line + "\n" for line in alias_bomb(6, "zz").splitlines()
    )
    path.write_text(text + "pairs:\n  - {map: a.yaml, system: *zz5}\n")
    with pytest.raises(ManifestError, match="alias") as info:
        read_manifest(path)
    one_short_line(info.value)


def test_manifest_messages_echo_values_shortened(tmp_path):
    path = tmp_path / "runs.yaml"
    path.write_text(f"pairs:\n  - {{map: a.yaml, reference: b.yaml, seed: '{'7x' * 50_000}'}}\n")
    with pytest.raises(ManifestError, match="seed must be an integer") as info:
        read_manifest(path)
    one_short_line(info.value)
    path.write_text(f"pairs:\n  - '{'p' * 100_000}'\n")
    with pytest.raises(ManifestError, match="a pair must be a mapping") as info:
        read_manifest(path)
    one_short_line(info.value)


# -- 7. values and paths in messages ----------------------------------------------------------
def test_a_path_with_a_newline_is_echoed_on_one_line(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text('image: "no\\nsuch.png"\nresolution: 0.05\n')
    with pytest.raises(MapError, match="does not exist") as info:
        load_map(path)
    assert "no\\nsuch.png" in one_short_line(info.value)


BIG = "9" * 200_000
MANY = "[" + "1, " * 100_000 + "1]"


@pytest.mark.parametrize(
    "field",
    [
        f"resolution: '{BIG}'",
        f"resolution: {MANY}",
        f"resolution: 0.05\norigin: '{BIG}'",
        f"resolution: 0.05\norigin: {MANY}",
        f"resolution: 0.05\nmode: '{BIG}'",
        f"resolution: 0.05\nnegate: {MANY}",
    ],
    ids=["resolution", "resolution-list", "origin", "origin-list", "mode", "negate-list"],
)
def test_a_huge_value_is_echoed_shortened(tmp_path, field):
    small_png(tmp_path / "m.png")
    path = tmp_path / "m.yaml"
    path.write_text(f"image: m.png\n{field}\n")
    with pytest.raises(MapFormatError) as info:
        load_map(path)
    one_short_line(info.value)


def test_a_huge_image_name_is_echoed_shortened(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text(f"image: {'d/' * 200_000}map.png\nresolution: 0.05\n")
    with pytest.raises(MapError, match="does not exist") as info:
        load_map(path)
    assert len(str(info.value)) < 2 * PATH_CHARS


# -- 1. every file of a bag folder, metadata bounded ------------------------------------------
def bag_folder(tmp_path: Path, metadata: str, pad: int = 0) -> Path:
    folder = tmp_path / "bag"
    folder.mkdir()
    text = metadata + ("#" + "x" * 1000 + "\n") * (pad // 1002 + 1 if pad else 0)
    (folder / "metadata.yaml").write_text(text)
    return folder


LISTING = (
    "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: sqlite3\n"
    "  relative_file_paths: [{files}]\n"
)


@POSIX
def test_a_fifo_in_a_bag_folder_is_refused_even_with_huge_metadata(tmp_path):
    folder = bag_folder(tmp_path, LISTING.format(files="pipe"), pad=MAX_TEXT_BYTES + 10)
    os.mkfifo(folder / "pipe")
    with alarm(), pytest.raises(MapError, match="pipe: is a FIFO") as info:
        check_bag(folder)
    one_short_line(info.value)
    with alarm(), pytest.raises(MapError, match="FIFO"):
        load_bag_map(folder)


@POSIX
def test_an_unlisted_fifo_in_a_bag_folder_is_refused(tmp_path):
    folder = bag_folder(tmp_path, LISTING.format(files="bag_0.db3"))
    (folder / "bag_0.db3").write_bytes(b"x")
    os.mkfifo(folder / "notes")
    with alarm(), pytest.raises(MapError, match="notes: is a FIFO"):
        check_bag(folder)
    # the storage file is read through its folder: the folder's files are checked too
    with alarm(), pytest.raises(MapError, match="notes: is a FIFO"):
        check_bag(folder / "bag_0.db3")
    (folder / "sub").mkdir()  # a sub-folder is never read: it does not matter
    (folder / "notes").unlink()
    assert check_bag(folder) == folder


def test_a_huge_bag_metadata_is_refused_before_the_bag_reader(tmp_path):
    folder = bag_folder(tmp_path, LISTING.format(files="bag_0.db3"), pad=MAX_TEXT_BYTES + 10)
    (folder / "bag_0.db3").write_bytes(b"x")
    start = time.perf_counter()
    with pytest.raises(MapSizeError, match="metadata.yaml: the rosbag2 metadata file has"):
        check_bag(folder)
    with pytest.raises(MapSizeError, match="limit"):
        load_map(folder)
    with pytest.raises(MapSizeError, match="limit"):
        check_bag(folder / "bag_0.db3")  # a storage file beside it: the metadata is its bag's
    assert time.perf_counter() - start < 2.0


def test_a_bag_metadata_alias_bomb_is_refused(tmp_path):
    meta = alias_bomb(6) + LISTING.format(files="*x5")
    folder = bag_folder(tmp_path, meta)
    start = time.perf_counter()
    with pytest.raises(MapFormatError, match="alias") as info:
        check_bag(folder)
    one_short_line(info.value)
    with pytest.raises(MapFormatError, match="alias"):
        load_map(folder / "metadata.yaml")
    assert time.perf_counter() - start < 2.0


# -- 3. CARMEN logs: bounded file and gunzipped text -------------------------------------------
FLASER = "FLASER 3 1.0 2.0 3.0 0 0 0 0 0 0 1.0 host 1.0\n"


def gzip_bytes(chunks: int, chunk: bytes = b"\0" * (1 << 20), head: bytes = b"") -> bytes:
    """A gzip member of ``head`` + ``chunks`` times ``chunk``, built without holding it."""
    packer = zlib.compressobj(9, zlib.DEFLATED, 31)
    out = [packer.compress(head)]
    out += [packer.compress(chunk) for _ in range(chunks)]
    return b"".join([*out, packer.flush()])


def test_a_gzip_bomb_carmen_log_is_refused_past_the_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(carmen, "MAX_LOG_BYTES", 1 << 20)
    ok = tmp_path / "ok.log.gz"
    ok.write_bytes(gzip_bytes(0, head=(FLASER * 100).encode()))
    assert read_carmen(ok).n_scans == 100
    bomb = tmp_path / "bomb.log.gz"
    bomb.write_bytes(gzip_bytes(64, head=FLASER.encode()))  # 64 MiB of zeros in ~64 kB
    assert bomb.stat().st_size < 100_000
    start = time.perf_counter()
    with pytest.raises(MapSizeError, match="gunzipped CARMEN log is larger than the limit") as info:
        read_carmen(bomb)
    assert time.perf_counter() - start < 2.0
    one_short_line(info.value)
    # several members add up
    twice = tmp_path / "twice.log.gz"
    twice.write_bytes(gzip_bytes(0, head=FLASER.encode() + b"\0" * 700_000) * 2)
    with pytest.raises(MapSizeError, match="limit"):
        read_carmen(twice)
    plain = tmp_path / "big.log"
    plain.write_bytes(FLASER.encode() * ((2 << 20) // len(FLASER)))
    with pytest.raises(MapSizeError, match="CARMEN log has"):
        read_carmen(plain)


def test_only_laser_lines_are_split_and_file_order_is_kept(tmp_path):
    lines = ["PARAM x 1", "ODOM 0 0 0", "FLASERX 3 1 2", " FLASER 3 1 2 3 0 0 0 0 0 0"]
    log = tmp_path / "a.log"
    pose = "{0} 0 0 0 0 0 1.0 host 1.0"
    flasers = [f"FLASER 3 1.0 2.0 3.0 {pose.format(i)}" for i in range(5)]
    log.write_text("\n".join(lines[:2] + flasers[:2] + lines[2:] + flasers[2:]) + "\n")
    got = read_carmen(log)
    assert got.n_scans == 5 and got.poses[:, 0].tolist() == [0, 1, 2, 3, 4]


@POSIX
def test_a_fifo_carmen_log_is_refused_not_read(tmp_path):
    os.mkfifo(tmp_path / "run.log")
    with alarm(), pytest.raises(MapError, match="FIFO"):
        read_carmen(tmp_path / "run.log")


# -- 5. 32-bit integer images --------------------------------------------------------------------
def test_a_32_bit_integer_tiff_is_refused_not_misread(tmp_path):
    values = np.full((40, 40), 254, np.int32)
    values[5, 5:35] = 0  # 8-bit values in a 32-bit image: read as 16-bit, all "occupied"
    Image.fromarray(values).save(tmp_path / "m.tif")
    with pytest.raises(MapFormatError, match="8-bit or 16-bit grey") as info:
        load_map(tmp_path / "m.tif")
    one_short_line(info.value)


def test_a_16_bit_png_that_pillow_opens_as_mode_i_is_16_bit():
    """Pillow before 10.3 opens a 16-bit grey PNG in mode 'I': that is 16-bit, unambiguous."""
    img = Image.fromarray(np.array([[0, 65535]], np.int32))
    img.format = "PNG"
    pixels = _from_pillow(img, "m.png")
    assert pixels.maxval == 65535 and pixels.sums.tolist() == [[0, 65535]]
    img.format = "TIFF"
    with pytest.raises(MapFormatError, match="white level is ambiguous"):
        _from_pillow(img, "m.tif")


# -- 6. a folder that cannot be entered ---------------------------------------------------------
def test_a_folder_that_cannot_be_entered_is_a_map_error(tmp_path, monkeypatch):
    shutil.copy(EXAMPLES / "building_31.yaml", tmp_path / "m.yaml")
    locked = str(tmp_path)
    real_stat = os.stat

    def stat(path, *args, **kwargs):  # as for a user without search permission on tmp_path
        if os.fspath(path).startswith(locked + os.sep):
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real_stat(path, *args, **kwargs)

    monkeypatch.setattr(os, "stat", stat)
    for path in (tmp_path / "m.yaml", tmp_path / "bag"):
        with pytest.raises(MapError, match="permission denied") as info:
            load_map(path)
        one_short_line(info.value)
    with pytest.raises(MapError, match="permission denied"):
        brokenness.compute_brokenness(tmp_path / "m.yaml", REFERENCE)


@pytest.mark.skipif(not hasattr(os, "geteuid"), reason="POSIX users")
def test_a_folder_that_cannot_be_entered_for_real(tmp_path):
    folder = tmp_path / "nox"
    folder.mkdir()
    shutil.copy(EXAMPLES / "building_31.yaml", folder / "m.yaml")
    code = (
        "import brokenness, sys\n"
        "try:\n"
        f"    brokenness.load_map({str(folder / 'm.yaml')!r})\n"
        "except brokenness.MapError as exc:\n"
        "    print(type(exc).__name__, exc)\n"
    )
    if os.geteuid() != 0:
        folder.chmod(0)
        try:
            with pytest.raises(MapError, match="permission denied"):
                load_map(folder / "m.yaml")
        finally:
            folder.chmod(0o755)
        return
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv to drop privileges")
    folder.chmod(0)
    drop = [setpriv, "--reuid=65534", "--regid=65534", "--clear-groups"]
    env = {**os.environ, "PYTHONPATH": str(Path(brokenness.__file__).parents[1])}
    probe = subprocess.run(
        [*drop, sys.executable, "-c", "import brokenness"], capture_output=True, env=env
    )
    if probe.returncode != 0:
        pytest.skip("the package cannot be imported as an unprivileged user here")
    run = subprocess.run(
        [*drop, sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60
    )
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    assert run.stdout.startswith("MapError ") and "permission denied" in run.stdout
    assert run.stdout.count("\n") == 1


# -- the library's writers and the timeline's options: typed errors (review item 17) -----------
def test_writers_and_timeline_options_raise_typed_errors(tmp_path):
    """save_map without a path, save_simulation into a path that is a file, and a timeline's
    min_occupied_cells that is no integer: a BrokennessError each (a TypeError, a
    FileExistsError and a ValueError before), raised before any work."""
    from brokenness.simulation import save_simulation, simulate_broken_map

    m = brokenness.OccupancyMap.from_array(np.eye(8, dtype=bool), resolution=0.05)
    with pytest.raises(brokenness.ParameterError, match="save_map's path"):
        brokenness.save_map(m, None)  # type: ignore[arg-type]
    a_file = tmp_path / "taken"
    a_file.write_text("x")
    sim = simulate_broken_map(seed=1)
    with pytest.raises(MapError, match="cannot make the folder"):
        save_simulation(sim, a_file, "run")
    for bad in ("x", 2.5):
        with pytest.raises(brokenness.ParameterError, match="min_occupied_cells must be an int"):
            brokenness.timeline(tmp_path / "none.bag", m, min_occupied_cells=bad)
