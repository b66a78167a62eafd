"""Bad input to brokenness.io: a typed error with a one-line message naming the file."""

from __future__ import annotations

import io
import os
import struct
import sys
import types
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from brokenness.errors import (
    BrokennessError,
    MapError,
    MapFormatError,
    MapSizeError,
    ParameterError,
)
from brokenness.grid import MAX_CELLS, OccupancyMap
from brokenness.io import load_map, save_map

DATA = Path(__file__).parent / "data"


def expect(exc_type: type[Exception], path: Path, match: str, **kw: object) -> str:
    """load_map(path) raises exactly ``exc_type``; the message is one line naming ``path``."""
    with pytest.raises(exc_type, match=match) as info:
        load_map(path, **kw)
    msg = str(info.value)
    assert str(path) in msg
    assert "\n" not in msg
    assert isinstance(info.value, BrokennessError)
    return msg


def good_pgm(path: Path) -> Path:
    path.write_bytes(b"P5\n2 1\n255\n\x00\xfe")
    return path


def png_bytes(width: int, height: int) -> bytes:
    """A valid 1x1 grey PNG whose header claims ``width`` x ``height``."""
    buf = io.BytesIO()
    Image.fromarray(np.zeros((1, 1), np.uint8)).save(buf, format="PNG")
    data = bytearray(buf.getvalue())
    ihdr = 8  # after the signature: length(4) 'IHDR'(4) data(13) crc(4)
    data[ihdr + 8 : ihdr + 16] = struct.pack(">II", width, height)
    crc = zlib.crc32(bytes(data[ihdr + 4 : ihdr + 21]))
    data[ihdr + 21 : ihdr + 25] = struct.pack(">I", crc)
    return bytes(data)


# --- files ---------------------------------------------------------------------------------


def test_missing_file(tmp_path: Path) -> None:
    expect(MapError, tmp_path / "nope.yaml", "no such file")
    expect(MapError, tmp_path / "nope.pgm", "no such file")


def test_directory(tmp_path: Path) -> None:
    expect(MapError, tmp_path, "is a directory")


@pytest.mark.skipif(os.geteuid() == 0, reason="root can read any file")
def test_unreadable(tmp_path: Path) -> None:
    p = good_pgm(tmp_path / "a.pgm")
    p.chmod(0)
    expect(MapError, p, "permission denied")


@pytest.mark.parametrize("name", ["e.pgm", "e.png", "e.yaml", "e.npy"])
def test_empty_file(tmp_path: Path, name: str) -> None:
    p = tmp_path / name
    p.write_bytes(b"")
    expect(MapFormatError, p, "empty file")


@pytest.mark.parametrize("name", ["m.txt", "m.jsonx", "m"])
def test_unsupported_extension(tmp_path: Path, name: str) -> None:
    p = tmp_path / name
    p.write_bytes(b"whatever")
    expect(MapFormatError, p, "unsupported map file extension")


# --- images --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"P5\n10 10\n255\n" + b"\x00" * 99, r"truncated PGM data \(99 of 100 bytes"),
        (b"P5\n10 10\n65535\n" + b"\x00" * 150, r"truncated PGM data \(150 of 200 bytes"),
        (b"P2\n3 2\n255\n0 1 2 3 4\n", r"truncated PGM data \(5 of 6 samples"),
        (b"P5\n10 10", "truncated PGM header"),
        (b"P5\n10 10\n# comment without end", "truncated PGM header"),
        (b"P5\nab 10\n255\n", "bad width"),
        (b"P5\n2 1\n0\n\x00\x00", "maxval 0"),
        (b"P5\n2 1\n70000\n\x00\x00\x00\x00", "maxval 70000"),
        (b"P5\n2 1\n100\n\x00\xc8", "sample 200 is larger than maxval 100"),
        (b"P2\n2 1\n255\n0 x\n", "invalid sample"),
        (b"P2\n2 1\n255\n0 300\n", "sample 300 is larger than maxval 255"),
        (b"P5\n2 1\n255\x00\x00\x00", "no whitespace after maxval"),
        (b"GARBAGE, not an image at all", "not an image file"),
    ],
)
def test_corrupt_pgm(tmp_path: Path, content: bytes, match: str) -> None:
    p = tmp_path / "bad.pgm"
    p.write_bytes(content)
    expect(MapFormatError, p, match)


@pytest.mark.parametrize(
    ("header", "match"),
    [
        (f"P5\n{20001} {20000}\n255\n".encode(), "larger than the limit"),
        (b"P5\n0 10\n255\n", "zero side"),
        (f"P2\n{MAX_CELLS} 2\n255\n".encode(), "larger than the limit"),
    ],
)
def test_absurd_pgm_size_checked_before_decoding(tmp_path: Path, header: bytes, match: str) -> None:
    p = tmp_path / "huge.pgm"
    p.write_bytes(header + b"\x00" * 16)
    expect(MapSizeError, p, match)


def test_truncated_and_corrupt_png(tmp_path: Path) -> None:
    buf = io.BytesIO()
    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 256, (200, 200), dtype=np.uint8)).save(buf, format="PNG")
    data = buf.getvalue()
    (tmp_path / "t.png").write_bytes(data[: len(data) // 2])
    expect(MapFormatError, tmp_path / "t.png", "corrupt or truncated")
    (tmp_path / "g.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 10)
    expect(MapFormatError, tmp_path / "g.png", "not an image file|corrupt")


@pytest.mark.parametrize("side", [15000, 20001])
def test_png_bomb(tmp_path: Path, side: int) -> None:
    # 15000^2 is under MAX_CELLS but over Pillow's bomb limit; 20001^2 over both
    p = tmp_path / "bomb.png"
    p.write_bytes(png_bytes(side, side))
    expect(MapSizeError, p, "too large|larger than the limit")


def test_float_image_refused(tmp_path: Path) -> None:
    p = tmp_path / "f.tif"
    Image.fromarray(np.zeros((2, 2), np.float32)).save(p)
    expect(MapFormatError, p, "unsupported image mode 'F'")


# --- YAML ----------------------------------------------------------------------------------


def yaml_case(tmp_path: Path, text: str) -> Path:
    good_pgm(tmp_path / "a.pgm")
    p = tmp_path / "m.yaml"
    p.write_text(text)
    return p


BASE = "image: a.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("- 1\n- 2\n", "expected a mapping, got list"),
        ("just a string\n", "expected a mapping, got str"),
        ("# only a comment\n", "expected a mapping, got empty"),
        ("image: [unclosed\n", "invalid YAML"),
        ("resolution: 0.05\n", "no 'image' field"),
        ("image: a.pgm\n", "no 'resolution' field"),
        ("image: 12\nresolution: 0.05\n", "'image' must be a file name"),
        ("image: a.pgm\nresolution: -0.05\n", "'resolution' must be > 0"),
        ("image: a.pgm\nresolution: 0\n", "'resolution' must be > 0"),
        ("image: a.pgm\nresolution: .nan\n", "'resolution' must be finite"),
        ("image: a.pgm\nresolution: abc\n", "'resolution' must be a number"),
        ("image: a.pgm\nresolution: true\n", "'resolution' must be a number"),
        ("image: a.pgm\nresolution: 0.05\norigin: [0, 0]\n", "'origin' must be"),
        ("image: a.pgm\nresolution: 0.05\norigin: 5\n", "'origin' must be"),
        ("image: a.pgm\nresolution: 0.05\norigin: [0, x, 0]\n", "'origin' must be a number"),
        ("image: a.pgm\nresolution: 0.05\norigin: [0, .nan, 0]\n", "'origin' must be finite"),
        (BASE + "occupied_thresh: 1.5\n", "'occupied_thresh' must be in"),
        (BASE + "free_thresh: -0.1\n", "'free_thresh' must be in"),
        (BASE + "occupied_thresh: 0.3\nfree_thresh: 0.3\n", "must be smaller than"),
        (BASE + "occupied_thresh: 0.2\nfree_thresh: 0.5\n", "must be smaller than"),
        (BASE + "mode: bogus\n", "unknown mode 'bogus'"),
        (BASE + "negate: 2\n", "'negate' must be 0 or 1"),
        ("image: m.yaml\nresolution: 0.05\n", "must be a raster image"),
    ],
)
def test_bad_yaml(tmp_path: Path, text: str, match: str) -> None:
    expect(MapFormatError, yaml_case(tmp_path, text), match)


def test_yaml_image_missing(tmp_path: Path) -> None:
    p = tmp_path / "m.yaml"
    p.write_text("image: gone.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    msg = expect(MapError, p, "does not exist")
    assert "gone.pgm" in msg


def test_yaml_image_corrupt(tmp_path: Path) -> None:
    (tmp_path / "a.pgm").write_bytes(b"P5\n4 4\n255\n\x00")
    p = tmp_path / "m.yaml"
    p.write_text("image: a.pgm\nresolution: 0.05\n")
    with pytest.raises(MapFormatError, match="truncated PGM data") as info:
        load_map(p)
    assert "a.pgm" in str(info.value)


# --- npy ----------------------------------------------------------------------------------


def test_npy_errors(tmp_path: Path) -> None:
    cases = {
        "nan.npy": (np.array([[0.0, np.nan]]), MapError, "NaN"),
        "3d.npy": (np.zeros((2, 2, 2), np.int8), MapError, "2D"),
        "range.npy": (np.array([[0, 101]], np.int16), MapError, "0..100"),
        "neg.npy": (np.array([[-2, 0]], np.int8), MapError, "0..100"),
        "big.npy": (np.array([[0.0, 1.5]]), MapError, r"\[0, 1\]"),
    }
    for name, (arr, exc, match) in cases.items():
        np.save(tmp_path / name, arr)
        expect(exc, tmp_path / name, match)
    np.save(tmp_path / "obj.npy", np.array([[{"a": 1}]], dtype=object), allow_pickle=True)
    expect(MapFormatError, tmp_path / "obj.npy", "unreadable .npy")
    (tmp_path / "junk.npy").write_bytes(b"not numpy at all")
    expect(MapFormatError, tmp_path / "junk.npy", "not a valid .npy")
    buf = io.BytesIO()
    np.save(buf, np.zeros((100, 100), np.int8))
    (tmp_path / "cut.npy").write_bytes(buf.getvalue()[:-500])
    expect(MapFormatError, tmp_path / "cut.npy", "npy")


def test_npy_absurd_shape_checked_from_header(tmp_path: Path) -> None:
    header = {"descr": "|i1", "fortran_order": False, "shape": (30000, 30000)}
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    (tmp_path / "huge.npy").write_bytes(buf.getvalue() + b"\0" * 64)
    expect(MapSizeError, tmp_path / "huge.npy", "larger than the limit")


# --- rosbags -------------------------------------------------------------------------------


def test_bag_dispatch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple[Path, str]] = []
    fake = types.ModuleType("brokenness.io.rosbag")

    def load_bag_map(path: Path, *, topic: str) -> OccupancyMap:
        calls.append((Path(path), topic))
        return OccupancyMap(np.zeros((2, 2), np.int8), 0.05, (0, 0, 0))

    fake.load_bag_map = load_bag_map  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "brokenness.io.rosbag", fake)
    for name in ("a.bag", "b.db3", "c.mcap"):
        (tmp_path / name).write_bytes(b"x")
        load_map(tmp_path / name)
    bag2 = tmp_path / "bag2"
    bag2.mkdir()
    (bag2 / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 5\n")
    load_map(bag2, topic="/other")
    m = load_map(bag2 / "metadata.yaml", resolution=0.1)
    assert m.resolution == 0.1
    assert calls == [
        (tmp_path / "a.bag", "/map"),
        (tmp_path / "b.db3", "/map"),
        (tmp_path / "c.mcap", "/map"),
        (bag2, "/other"),
        (bag2, "/map"),
    ]


def test_bag_support_missing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "brokenness.io.rosbag", None)  # import fails
    (tmp_path / "a.bag").write_bytes(b"x")
    expect(MapError, tmp_path / "a.bag", "rosbag support is unavailable")


# --- arguments and saving ------------------------------------------------------------------


def test_bad_arguments(tmp_path: Path) -> None:
    p = good_pgm(tmp_path / "a.pgm")
    with pytest.raises(ParameterError, match="mode"):
        load_map(p, mode="bogus")
    for res in (0, -1, float("nan"), float("inf"), "x"):
        with pytest.raises(ParameterError, match="resolution"):
            load_map(p, resolution=res)  # type: ignore[arg-type]
    for origin in ((0, 0), (0, float("nan"), 0), "abc"):
        with pytest.raises(ParameterError, match="origin"):
            load_map(p, origin=origin)  # type: ignore[arg-type]


def test_save_errors(tmp_path: Path) -> None:
    m = OccupancyMap(np.zeros((2, 2), np.int8), 0.05, (0, 0, 0))
    with pytest.raises(MapError, match="unsupported extension"):
        save_map(m, tmp_path / "m.txt")
    with pytest.raises(MapError, match="does not exist"):
        save_map(m, tmp_path / "no" / "such" / "m.pgm")
    with pytest.raises(ParameterError, match="image_format"):
        save_map(m, tmp_path / "m.yaml", image_format="jpg")
    with pytest.raises(MapError, match="OccupancyMap"):
        save_map(np.zeros((2, 2)), tmp_path / "m.npy")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


def test_permission_error_is_converted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # runs as root too (where chmod 0 does not stop reading): simulate the OS refusing
    p = good_pgm(tmp_path / "a.pgm")

    def refuse(path: Path) -> int:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr("brokenness.io._files.open_nonblocking", refuse)
    expect(MapError, p, "permission denied")
    expect(MapError, Path(str(p)), "permission denied")
