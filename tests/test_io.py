"""Tests of brokenness.io: formats, map_server semantics, round trips and resampling."""

from __future__ import annotations

import os
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from brokenness.errors import MapError
from brokenness.grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from brokenness.io import (
    MapWarning,
    common_resolution,
    load_map,
    resample_to_resolution,
    save_map,
)
from brokenness.io.resample import cell_scale_offset

DATA = Path(__file__).parent / "data"

O, F, U = OCCUPIED, FREE, UNKNOWN  # noqa: E741


def write_yaml(path: Path, image: str, **fields: object) -> Path:
    lines = [f"image: {image}"]
    fields.setdefault("resolution", 0.05)
    fields.setdefault("origin", "[0.0, 0.0, 0.0]")
    lines += [f"{k}: {v}" for k, v in fields.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def p5(pixels: np.ndarray, maxval: int = 255, header_comment: bool = False) -> bytes:
    h, w = pixels.shape
    comment = b"# a comment\n" if header_comment else b""
    head = b"P5\n" + comment + f"{w} ".encode() + comment + f"{h}\n{maxval}\n".encode()
    dtype = ">u2" if maxval > 255 else "u1"
    return head + pixels.astype(dtype).tobytes()


def p2(pixels: np.ndarray, maxval: int = 255) -> bytes:
    h, w = pixels.shape
    rows = "\n".join(" ".join(str(int(v)) for v in row) for row in pixels)
    return f"P2\n# made by hand\n{w} {h}\n# maxval next\n{maxval}\n{rows}\n".encode()


def load_quiet(path: Path, **kw: object) -> OccupancyMap:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning expected
        return load_map(path, **kw)


# --- the bundled real maps -----------------------------------------------------------------

EXPECTED = {
    # name: (shape, resolution, origin, occupied, free, unknown); counts verified from the
    # pixel histograms (0 / 205 / 254 for map_saver files; building_31 has greys 64/128/191)
    "tb3_sandbox": ((384, 384), 0.05, (-10.0, -10.0, 0.0), 870, 7903, 138683),
    "building_31": ((648, 693), 0.05, (-26.0, -11.0, 0.0), 17356 + 197, 431063, 210 + 238),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bundled_maps_counts(name: str) -> None:
    shape, res, origin, occ, free, unk = EXPECTED[name]
    m = load_quiet(DATA / f"{name}.yaml")
    assert m.shape == shape
    assert m.resolution == res
    assert m.origin == origin
    counts = {s: int(np.count_nonzero(m.states == s)) for s in (O, F, U)}
    assert counts == {O: occ, F: free, U: unk}
    assert m.source == str(DATA / f"{name}.yaml")


def test_willow_probabilistic_greys_match_pillow_histogram() -> None:
    m = load_quiet(DATA / "willow-2010-02-18-0.10.yaml")
    pixels = np.asarray(Image.open(DATA / "willow-2010-02-18-0.10.pgm"))
    # p = (255 - v) / 255: occupied iff p > 0.65 iff v <= 89; free iff p < 0.196 iff v >= 206
    assert np.array_equal(m.occupied, pixels <= 89)
    assert np.array_equal(m.free, pixels >= 206)
    assert m.n_occupied == 544
    assert m.resolution == 0.1


def test_depot_nav2_trap_warns_and_follows_yaml() -> None:
    with pytest.warns(MapWarning, match=r"8894 pixels of grey 205.*free_thresh=0\.25"):
        m = load_map(DATA / "depot.yaml")
    pixels = np.asarray(Image.open(DATA / "depot.pgm"))
    assert np.array_equal(m.states[pixels == 205], np.full(8894, F))  # as ROS would
    assert m.n_occupied == 5947
    assert not (m.states == U).any()


def test_plain_images_load_without_yaml() -> None:
    m = load_quiet(DATA / "tb3_sandbox.pgm")
    assert m.resolution is None and m.origin is None
    assert m.n_occupied == 870
    ref = load_quiet(DATA / "tb3_sandbox.yaml")
    assert np.array_equal(m.states, ref.states)
    m2 = load_quiet(DATA / "building_31.png", resolution=0.05, origin=(1.0, 2.0, 0.5))
    assert m2.resolution == 0.05 and m2.origin == (1.0, 2.0, 0.5)


# --- YAML fields ---------------------------------------------------------------------------


def test_relative_and_absolute_image_path(tmp_path: Path) -> None:
    sub = tmp_path / "maps" / "img"
    sub.mkdir(parents=True)
    shutil.copy(DATA / "tb3_sandbox.pgm", sub / "a.pgm")
    rel = write_yaml(tmp_path / "maps" / "rel.yaml", "img/a.pgm", origin="[1.5, -2.25, 0.3]")
    m = load_quiet(rel)
    assert m.n_occupied == 870
    assert m.origin == (1.5, -2.25, 0.3)
    # relative to the YAML's folder, not the working directory
    cwd = os.getcwd()
    try:
        os.chdir(tmp_path)
        assert load_quiet(Path("maps/rel.yaml")).n_occupied == 870
    finally:
        os.chdir(cwd)
    absolute = write_yaml(tmp_path / "abs.yaml", str(sub / "a.pgm"), resolution=0.1)
    assert load_quiet(absolute).resolution == 0.1


def test_keyword_arguments_override_yaml(tmp_path: Path) -> None:
    m = load_quiet(DATA / "tb3_sandbox.yaml", resolution=0.1, origin=(0, 0, 0))
    assert m.resolution == 0.1 and m.origin == (0.0, 0.0, 0.0)


def test_missing_optional_fields_use_defaults(tmp_path: Path) -> None:
    (tmp_path / "a.pgm").write_bytes(p5(np.array([[0, 205, 254]], np.uint8)))
    (tmp_path / "a.yaml").write_text("image: a.pgm\nresolution: 0.05\n")
    m = load_quiet(tmp_path / "a.yaml")
    assert m.origin is None
    assert m.states.tolist() == [[O, U, F]]


def test_string_numbers_as_yaml_cpp_reads_them(tmp_path: Path) -> None:
    (tmp_path / "a.pgm").write_bytes(p5(np.array([[0]], np.uint8)))
    write_yaml(tmp_path / "a.yaml", "a.pgm", resolution="5e-2")  # a string in YAML 1.1
    assert load_quiet(tmp_path / "a.yaml").resolution == 0.05


# --- exact threshold semantics -------------------------------------------------------------


def test_thresholds_are_strict(tmp_path: Path) -> None:
    # p = (255 - v) / 255: v = 102 gives exactly 0.6, v = 204 exactly 0.2
    assert (255 - 102) / 255 == 0.6 and (255 - 204) / 255 == 0.2
    pixels = np.array([[101, 102, 103, 203, 204, 205]], np.uint8)
    (tmp_path / "t.pgm").write_bytes(p5(pixels))
    y = write_yaml(tmp_path / "t.yaml", "t.pgm", occupied_thresh=0.6, free_thresh=0.2)
    with pytest.warns(MapWarning, match="1 pixels of grey 205"):  # 205 is free here: the trap
        m = load_map(y)
    assert m.states.tolist() == [[O, U, U, U, U, F]]


def test_negate(tmp_path: Path) -> None:
    # negate: p = v / 255; v = 153 gives exactly 0.6 and v = 51 exactly 0.2
    assert 153 / 255 == 0.6 and 51 / 255 == 0.2
    pixels = np.array([[0, 50, 51, 153, 154, 255]], np.uint8)
    (tmp_path / "n.pgm").write_bytes(p5(pixels))
    y = write_yaml(tmp_path / "n.yaml", "n.pgm", negate=1, occupied_thresh=0.6, free_thresh=0.2)
    assert load_quiet(y).states.tolist() == [[F, F, U, U, O, O]]
    y2 = write_yaml(
        tmp_path / "n2.yaml", "n.pgm", negate="true", occupied_thresh=0.6, free_thresh=0.2
    )
    assert load_quiet(y2).states.tolist() == [[F, F, U, U, O, O]]


def test_scale_mode_gives_trinary_states(tmp_path: Path) -> None:
    pixels = np.arange(256, dtype=np.uint8).reshape(16, 16)
    (tmp_path / "s.pgm").write_bytes(p5(pixels))
    tri = load_quiet(write_yaml(tmp_path / "t.yaml", "s.pgm", mode="trinary"))
    sca = load_quiet(write_yaml(tmp_path / "s.yaml", "s.pgm", mode="scale"))
    assert np.array_equal(tri.states, sca.states)
    p = (255 - pixels.astype(float)) / 255
    assert np.array_equal(tri.occupied, p > 0.65)
    assert np.array_equal(tri.free, p < 0.196)


def test_raw_mode(tmp_path: Path) -> None:
    pixels = np.array([[0, 19, 20, 65, 66, 100, 101, 200, 255]], np.uint8)
    (tmp_path / "r.pgm").write_bytes(p5(pixels))
    y = write_yaml(tmp_path / "r.yaml", "r.pgm", mode="raw")
    # v / 100 against 0.65 / 0.196 strictly; > 100 (and 255 = -1) unknown
    assert load_quiet(y).states.tolist() == [[F, F, U, U, O, O, U, U, U]]
    # the mode argument overrides; a plain image can be read raw as well
    assert load_quiet(tmp_path / "r.pgm", mode="raw").states.tolist() == [
        [F, F, U, U, O, O, U, U, U]
    ]


# --- PGM variants --------------------------------------------------------------------------


def test_p5_and_p2_8bit_with_comments(tmp_path: Path) -> None:
    pixels = np.array([[0, 205, 254], [254, 0, 89]], np.uint8)
    expected = [[O, U, F], [F, O, O]]
    (tmp_path / "a.pgm").write_bytes(p5(pixels, header_comment=True))
    (tmp_path / "b.pgm").write_bytes(p2(pixels))
    assert load_quiet(tmp_path / "a.pgm").states.tolist() == expected
    assert load_quiet(tmp_path / "b.pgm").states.tolist() == expected


def test_p2_comments_in_body_and_trailing_data(tmp_path: Path) -> None:
    body = b"P2 3 2 255\n0 # wall\n205 254\n# second row\n254 0 205\nP2 next image 7\n"
    (tmp_path / "a.pgm").write_bytes(body)
    assert load_quiet(tmp_path / "a.pgm").states.tolist() == [[O, U, F], [F, O, U]]


@pytest.mark.parametrize("writer", [p5, p2])
@pytest.mark.parametrize("maxval", [65535, 1000])
def test_16bit_pgm(tmp_path: Path, writer, maxval: int) -> None:
    # p = (maxval - v) / maxval; occupied > 0.65, free < 0.196
    values = [0, int(0.34 * maxval), int(0.36 * maxval), int(0.5 * maxval), maxval - 1, maxval]
    pixels = np.array([values], np.uint16)
    (tmp_path / "w.pgm").write_bytes(writer(pixels, maxval))
    assert load_quiet(tmp_path / "w.pgm").states.tolist() == [[O, O, U, U, F, F]]


def test_pgm_with_small_maxval(tmp_path: Path) -> None:
    pixels = np.array([[0, 1, 2, 3]], np.uint8)  # maxval 3: p = 1, 2/3, 1/3, 0
    (tmp_path / "m.pgm").write_bytes(p5(pixels, maxval=3))
    assert load_quiet(tmp_path / "m.pgm").states.tolist() == [[O, O, U, F]]


def test_large_pgm_reads_same_as_pillow(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    pixels = rng.integers(0, 256, size=(301, 257), dtype=np.uint8)
    (tmp_path / "r.pgm").write_bytes(p5(pixels))
    Image.fromarray(pixels).save(tmp_path / "r.png")
    a = load_quiet(tmp_path / "r.pgm")
    b = load_quiet(tmp_path / "r.png")
    assert np.array_equal(a.states, b.states)
    p = (255 - pixels.astype(float)) / 255
    assert np.array_equal(a.occupied, p > 0.65) and np.array_equal(a.free, p < 0.196)


# --- Pillow formats ------------------------------------------------------------------------


def test_rgb_channels_are_averaged(tmp_path: Path) -> None:
    rgb = np.array([[[0, 0, 255], [0, 255, 255], [255, 255, 250], [0, 0, 0]]], np.uint8)
    Image.fromarray(rgb).save(tmp_path / "c.png")
    # averages 85 (p 0.667 occupied), 170 (p 0.333 unknown), 253.3 (free), 0 (occupied)
    assert load_quiet(tmp_path / "c.png").states.tolist() == [[O, U, F, O]]


def test_rgba_not_opaque_is_unknown(tmp_path: Path) -> None:
    rgba = np.array(
        [[[0, 0, 0, 255], [0, 0, 0, 0], [254, 254, 254, 128], [254, 254, 254, 255]]], np.uint8
    )
    Image.fromarray(rgba).save(tmp_path / "a.png")
    assert load_quiet(tmp_path / "a.png").states.tolist() == [[O, U, U, F]]
    la = np.array([[[0, 255], [0, 0], [255, 254], [255, 255]]], np.uint8)
    Image.frombytes("LA", (4, 1), la.tobytes()).save(tmp_path / "la.png")
    assert load_quiet(tmp_path / "la.png").states.tolist() == [[O, U, U, F]]


def test_palette_png_with_transparency(tmp_path: Path) -> None:
    img = Image.new("P", (4, 1))
    img.putpalette([0, 0, 0, 205, 205, 205, 254, 254, 254, 255, 255, 255])
    img.putdata([0, 1, 2, 3])
    img.save(tmp_path / "q.png")  # no transparency
    img.save(tmp_path / "p.png", transparency=3)
    assert load_quiet(tmp_path / "p.png").states.tolist() == [[O, U, F, U]]
    assert load_quiet(tmp_path / "q.png").states.tolist() == [[O, U, F, F]]


def test_16bit_png_and_bilevel(tmp_path: Path) -> None:
    img16 = Image.fromarray(np.array([[0, 40000, 65535]], np.uint16))
    img16.save(tmp_path / "s.png")
    assert load_quiet(tmp_path / "s.png").states.tolist() == [[O, U, F]]
    Image.fromarray(np.array([[True, False]])).save(tmp_path / "b.png")  # white, black
    assert load_quiet(tmp_path / "b.png").states.tolist() == [[F, O]]


def test_bmp_and_tiff(tmp_path: Path) -> None:
    pixels = np.array([[0, 205, 254]], np.uint8)
    for ext in ("bmp", "tif"):
        Image.fromarray(pixels).save(tmp_path / f"x.{ext}")
        assert load_quiet(tmp_path / f"x.{ext}").states.tolist() == [[O, U, F]]


# --- npy ----------------------------------------------------------------------------------


def test_npy_variants(tmp_path: Path) -> None:
    np.save(tmp_path / "b.npy", np.array([[True, False]]))
    assert load_quiet(tmp_path / "b.npy").states.tolist() == [[O, F]]
    np.save(tmp_path / "n.npy", np.array([[-1, 0, 19, 20, 64, 65, 100]], np.int8))
    assert load_quiet(tmp_path / "n.npy").states.tolist() == [[U, F, F, U, U, O, O]]
    np.save(tmp_path / "t.npy", np.array([[-1, 0, 1]], np.int8))  # the 3-state encoding
    assert load_quiet(tmp_path / "t.npy").states.tolist() == [[U, F, O]]
    np.save(tmp_path / "f.npy", np.array([[0.0, 0.5, 1.0]]))
    m = load_quiet(tmp_path / "f.npy", resolution=0.1, origin=(1, 2, 3))
    assert m.states.tolist() == [[F, U, O]] and m.resolution == 0.1 and m.origin == (1, 2, 3)


def test_map_without_occupied_cells_loads(tmp_path: Path) -> None:
    (tmp_path / "e.pgm").write_bytes(p5(np.full((3, 3), 254, np.uint8)))
    assert load_quiet(tmp_path / "e.pgm").n_occupied == 0


# --- save and round trips ------------------------------------------------------------------


def random_map(seed: int, shape=(37, 53), geometry: bool = True) -> OccupancyMap:
    rng = np.random.default_rng(seed)
    states = rng.choice(np.array([O, F, U], np.int8), size=shape)
    if not geometry:
        return OccupancyMap(states)
    return OccupancyMap(states, resolution=0.037, origin=(-12.3456789, 1e-5, -2.5))


@pytest.mark.parametrize("fmt", ["pgm", "png"])
def test_yaml_round_trip(tmp_path: Path, fmt: str) -> None:
    m = random_map(1)
    out = save_map(m, tmp_path / "m.yaml", image_format=fmt)
    assert out == tmp_path / "m.yaml"
    assert (tmp_path / f"m.{fmt}").is_file()
    back = load_quiet(out)
    assert np.array_equal(back.states, m.states)
    assert back.resolution == m.resolution and back.origin == m.origin
    pixels = np.asarray(Image.open(tmp_path / f"m.{fmt}"))
    assert set(np.unique(pixels).tolist()) == {0, 205, 254}
    text = (tmp_path / "m.yaml").read_text()
    assert f"image: m.{fmt}" in text and "mode: trinary" in text


@pytest.mark.parametrize("ext", ["pgm", "png", "npy"])
def test_plain_round_trips(tmp_path: Path, ext: str) -> None:
    m = random_map(2, geometry=False)
    back = load_quiet(save_map(m, tmp_path / f"m.{ext}"))
    assert np.array_equal(back.states, m.states)
    assert back.resolution is None


def test_npy_written_as_nav_values(tmp_path: Path) -> None:
    m = OccupancyMap(np.array([[O, F, U]], np.int8))
    save_map(m, tmp_path / "m.npy")
    arr = np.load(tmp_path / "m.npy")
    assert arr.dtype == np.int8 and arr.tolist() == [[100, 0, -1]]


def test_save_yaml_without_geometry_warns_and_uses_defaults(tmp_path: Path) -> None:
    m = random_map(3, geometry=False)
    with pytest.warns(MapWarning, match="no resolution"):
        save_map(m, tmp_path / "g.yaml")
    back = load_quiet(tmp_path / "g.yaml")
    assert back.resolution == 0.05 and back.origin == (0.0, 0.0, 0.0)
    assert np.array_equal(back.states, m.states)


def test_save_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    m = random_map(4)
    save_map(m, tmp_path / "m.npy")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npy"]  # no temp file left
    before = (tmp_path / "m.npy").read_bytes()

    def fail(src: str, dst: str) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(MapError, match="No space left"):
        save_map(random_map(5), tmp_path / "m.npy")
    assert (tmp_path / "m.npy").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.npy"]


def test_save_overwrites_and_rereads_bundled(tmp_path: Path) -> None:
    for name in ("tb3_sandbox", "building_31", "willow-2010-02-18-0.10"):
        m = load_quiet(DATA / f"{name}.yaml")
        save_map(m, tmp_path / "x.yaml")  # overwrite each time
        back = load_quiet(tmp_path / "x.yaml")
        assert np.array_equal(back.states, m.states)
        assert (back.resolution, back.origin) == (m.resolution, m.origin)


# --- resampling ---------------------------------------------------------------------------


def walled(shape=(40, 60), res=0.05, origin=(1.0, -2.0, 0.3)) -> OccupancyMap:
    states = np.full(shape, F, np.int8)
    states[:5] = U
    states[17, 3:50] = O  # horizontal wall, odd row
    states[10:30, 30] = O  # vertical wall, even column
    states[10:30, 41] = O  # vertical wall, odd column
    states[np.arange(20, 38), np.arange(5, 23)] = O  # diagonal wall
    return OccupancyMap(states, res, origin)


def test_thin_walls_survive_downsampling() -> None:
    m = walled()
    for factor in (2, 3, 4):
        d = resample_to_resolution(m, 0.05 * factor)
        assert d.resolution == pytest.approx(0.05 * factor)
        assert d.origin == m.origin
        rows, cols = m.shape
        assert d.shape == (-(-rows // factor), -(-cols // factor))
        # every occupied fine cell lies in an occupied coarse cell (integer factor: max-pool)
        flipped = m.occupied[::-1]
        yb, x = np.nonzero(flipped)
        coarse = d.occupied[::-1]
        assert coarse[yb // factor, x // factor].all()
        # and no coarse cell is occupied without an occupied fine cell in it
        assert d.n_occupied == len(
            set(zip((yb // factor).tolist(), (x // factor).tolist(), strict=True))
        )


def test_downsampling_free_and_unknown_rule() -> None:
    states = np.array([[F, F, F, F, U, U], [F, U, U, U, U, U]], np.int8)
    d = resample_to_resolution(OccupancyMap(states, 0.1, (0, 0, 0)), 0.2)
    # blocks: 3 free of 4 -> free; 2 of 4 -> unknown (not "mostly"); 0 -> unknown
    assert d.states.tolist() == [[F, U, U]]


def test_non_integer_downsampling_keeps_every_obstacle() -> None:
    rng = np.random.default_rng(7)
    states = np.where(rng.random((45, 61)) < 0.02, O, F).astype(np.int8)
    m = OccupancyMap(states, 0.05, (0.5, 0.25, 0.0))
    d = resample_to_resolution(m, 0.07)
    assert d.shape == (int(np.ceil(45 * 5 / 7)), int(np.ceil(61 * 5 / 7)))
    # the world position of each occupied fine cell centre, in coarse cell coordinates
    yx = np.argwhere(m.occupied)
    pts = np.c_[yx[:, 1], yx[:, 0], np.ones(len(yx))].T.astype(float)
    world = m.cell_to_world_matrix() @ pts
    cell = np.linalg.inv(d.cell_to_world_matrix()) @ world
    cx, cy = np.floor(cell[0] + 0.5).astype(int), np.floor(cell[1] + 0.5).astype(int)
    occ = np.pad(d.occupied, 1)
    near = np.zeros(len(cx), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= occ[cy + 1 + dy, cx + 1 + dx]
    assert near.all()


def test_cell_centres_keep_world_position() -> None:
    m = walled(shape=(41, 59))
    for res in (0.1, 0.025, 0.07):
        r = resample_to_resolution(m, res)
        s = 0.05 / res
        assert r.shape == (int(np.ceil(41 * s - 1e-9)), int(np.ceil(59 * s - 1e-9)))
        # old cell centre (x, y) -> new (x + 0.5) s - 0.5, y counted from the bottom row
        x, y = 7.0, 11.0
        xb = (x + 0.5) * s - 0.5
        yb_new = ((41 - 1 - y) + 0.5) * s - 0.5
        y_new = r.shape[0] - 1 - yb_new
        w_old = m.cell_to_world_matrix() @ [x, y, 1]
        w_new = r.cell_to_world_matrix() @ [xb, y_new, 1]
        assert np.allclose(w_old, w_new)
        scale, tx, ty = cell_scale_offset(m, r)
        assert scale == pytest.approx(s)
        assert (scale * x + tx, scale * y + ty) == pytest.approx((xb, y_new))


@pytest.mark.parametrize("factor", [2, 3])
def test_upsample_then_downsample_is_identity(factor: int) -> None:
    m = random_map(6, shape=(23, 31))
    up = resample_to_resolution(m, m.resolution / factor)
    assert up.shape == (23 * factor, 31 * factor)
    assert np.array_equal(up.states[::factor, ::factor], m.states)
    back = resample_to_resolution(up, m.resolution)
    assert np.array_equal(back.states, m.states)
    assert back.origin == m.origin and back.resolution == m.resolution


def test_resample_bundled_map_and_identity() -> None:
    m = load_quiet(DATA / "tb3_sandbox.yaml")
    assert resample_to_resolution(m, 0.05) is m
    d = resample_to_resolution(m, 0.1)
    assert d.shape == (192, 192) and d.origin == m.origin and d.n_occupied > 0


def test_resample_errors() -> None:
    with pytest.raises(MapError, match="no resolution"):
        resample_to_resolution(OccupancyMap(np.zeros((2, 2), np.int8)), 0.1)
    m = random_map(8)
    for bad in (0, -0.1, float("nan"), float("inf"), "x"):
        with pytest.raises(ValueError):
            resample_to_resolution(m, bad)  # type: ignore[arg-type]


def test_common_resolution() -> None:
    a = random_map(9)
    b = OccupancyMap(a.states, resolution=0.1)
    assert common_resolution(a, b) == 0.1
    assert common_resolution(b, a) == 0.1
    assert common_resolution(a, OccupancyMap(a.states)) is None
