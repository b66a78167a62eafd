"""What a result file costs on a large map, with the same results as before.

Psi computed only where the maps differ, the aligned map warped from the states' bytes, the
overlay's raster built with OpenCV's scans, the overlay drawn in a second thread, Pillow's
decompression-bomb warning under this package's own cell limit: each checked against the
plain computation it replaces.
"""

from __future__ import annotations

import importlib
import io
import math
import warnings
import zipfile

import cv2
import numpy as np
import pytest
from PIL import Image
from test_report_fixtures import broken_rooms

from brokenness import OccupancyMap, RigidTransform, load_map, picture_distance
from brokenness.errors import MapError, MapSizeError
from brokenness.grid import FREE, OCCUPIED, UNKNOWN, count_state
from brokenness.io.pixels import _lookup, _lut, read_pixels
from brokenness.measure.result import NOT_OCCUPIED, BrokennessResult, Partition
from brokenness.report import load_results, save_results
from brokenness.report.raster import _background, _cells, _View, overlay_raster, palette_rgb
from brokenness.report.repair import align_map

similarity = importlib.import_module("brokenness.masking.similarity")
results_module = importlib.import_module("brokenness.report.results")
repair_module = importlib.import_module("brokenness.report.repair")

STATES = np.array([UNKNOWN, FREE, OCCUPIED], np.int8)


# -- Psi: the plain definition, summed as picture_distance sums ------------------------------
def _plain_mean(of: np.ndarray, to: np.ndarray, kind: int, cap: float) -> float:
    """Mean Manhattan distance by brute force over all pairs (small maps only)."""
    src, dst = np.argwhere(of == kind), np.argwhere(to == kind)
    if len(src) == 0:
        return 0.0
    if len(dst) == 0:
        return float(np.float64(cap) * len(src)) / len(src)
    total = int(np.abs(src[:, None, :] - dst[None, :, :]).sum(-1).min(1).sum())
    return float(total) / len(src)


def _plain_psi(a: OccupancyMap, b: OccupancyMap) -> float:
    cap = float(sum(a.shape))
    total = 0.0
    for kind in (OCCUPIED, FREE):
        total += _plain_mean(a.states, b.states, kind, cap) + _plain_mean(
            b.states, a.states, kind, cap
        )
    return total


def _random_states(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    kind = rng.integers(0, 4)
    if kind == 0:  # an empty image: nothing known
        return np.full(shape, UNKNOWN, np.int8)
    p = rng.dirichlet(np.ones(3))
    states = rng.choice(STATES, size=shape, p=p)
    if kind == 1:  # content in a box somewhere, possibly touching the border
        out = np.full(shape, UNKNOWN, np.int8)
        r0, r1 = sorted(rng.integers(0, shape[0] + 1, 2))
        c0, c1 = sorted(rng.integers(0, shape[1] + 1, 2))
        out[r0:r1, c0:c1] = states[r0:r1, c0:c1]
        return out
    return states


def _pairs(seed: int, n: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        shape = (int(rng.integers(1, 24)), int(rng.integers(1, 24)))
        a = _random_states(rng, shape)
        choice = rng.integers(0, 3)
        if choice == 0:
            b = _random_states(rng, shape)
        else:  # the same map, or the same with a few cells changed
            b = a.copy()
            if choice == 2:
                idx = rng.integers(0, a.size, int(rng.integers(1, 4)))
                b.flat[idx] = rng.choice(STATES, len(idx))
        yield OccupancyMap(a), OccupancyMap(b)


@pytest.mark.parametrize("seed", range(4))
def test_psi_equals_the_plain_definition_bit_for_bit(seed):
    for a, b in _pairs(seed, 150):
        assert picture_distance(a, b).hex() == _plain_psi(a, b).hex()
        assert picture_distance(b, a).hex() == _plain_psi(b, a).hex()


def test_psi_of_content_touching_every_border():
    rng = np.random.default_rng(11)
    a = rng.choice(STATES, size=(30, 41))
    a[0, :] = OCCUPIED
    a[:, -1] = FREE
    b = np.roll(a, (2, -3), axis=(0, 1))
    ma, mb = OccupancyMap(a), OccupancyMap(b)
    assert picture_distance(ma, mb).hex() == _plain_psi(ma, mb).hex()


def test_psi_of_empty_images():
    empty = OccupancyMap(np.full((7, 9), UNKNOWN, np.int8))
    walls = np.full((7, 9), UNKNOWN, np.int8)
    walls[3, 2:6] = OCCUPIED
    walls[4, 2:6] = FREE
    m = OccupancyMap(walls)
    assert picture_distance(empty, empty) == 0.0
    # each kind of m is absent from the empty map: the largest distance, rows + cols, a cell
    assert picture_distance(m, empty) == 2 * 16.0
    assert picture_distance(empty, m) == picture_distance(m, empty)


def test_psi_distance_maps_cover_only_what_differs(monkeypatch):
    """The distances are taken over the box of the differing cells and of their targets:
    none for identical maps, a small box for a small room on a large canvas."""
    shapes: list[tuple[int, int]] = []
    plain = similarity._distance_sum

    def spy(of_states, of_kind, to_states, to_kind):
        shapes.append(of_states.shape)
        return plain(of_states, of_kind, to_states, to_kind)

    monkeypatch.setattr(similarity, "_distance_sum", spy)
    canvas = np.full((600, 700), UNKNOWN, np.int8)
    canvas[100:140, 200:260] = FREE
    canvas[100, 200:260] = canvas[139, 200:260] = OCCUPIED
    room = OccupancyMap(canvas)
    assert picture_distance(room, OccupancyMap(canvas.copy())) == 0.0
    assert shapes == []  # identical maps: no distance map at all
    moved = OccupancyMap(np.roll(canvas, 3, axis=1))
    value = picture_distance(room, moved)
    assert shapes and all(r <= 40 and c <= 63 for r, c in shapes)
    monkeypatch.setattr(similarity, "_distance_sum", plain)
    # the same value as over the whole grid
    whole = 0.0
    for kind in (OCCUPIED, FREE):
        for of, to in ((room, moved), (moved, room)):
            total = plain(of.states, kind, to.states, kind)
            whole += float(total) / count_state(of.states, kind)
    assert value == whole


def test_psi_far_targets_in_the_box_need_several_passes():
    """A box larger than one saturated pass (255 cells): the later passes run on the box."""
    a = np.full((300, 700), UNKNOWN, np.int8)
    a[10:20, 5:650] = FREE
    b = np.full((300, 700), UNKNOWN, np.int8)
    b[280, 690] = FREE
    b[10:20, 5:8] = FREE
    ma, mb = OccupancyMap(a), OccupancyMap(b)
    assert picture_distance(ma, mb).hex() == _plain_psi(ma, mb).hex()
    assert picture_distance(mb, ma).hex() == _plain_psi(mb, ma).hex()


# -- the grid ------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [2, -2, 127, -128])
def test_occupancy_map_still_refuses_other_values(bad):
    states = np.zeros((5, 6), np.int8)
    states[4, 5] = bad
    with pytest.raises(MapError):
        OccupancyMap(states)


def test_count_state_counts_every_band():
    rng = np.random.default_rng(2)
    states = rng.choice(STATES, size=(1500, 7))  # several bands of rows
    for state in (UNKNOWN, FREE, OCCUPIED):
        assert count_state(states, state) == int(np.count_nonzero(states == state))
    assert OccupancyMap(states).n_occupied == int(np.count_nonzero(states == OCCUPIED))


# -- the aligned map -----------------------------------------------------------------------
def test_align_map_equals_warping_the_encoded_states():
    rng = np.random.default_rng(5)
    for i in range(60):
        m = OccupancyMap(rng.choice(STATES, size=(int(rng.integers(1, 40)), 33)))
        ref = OccupancyMap(np.zeros((int(rng.integers(1, 40)), int(rng.integers(1, 40))), np.int8))
        turn = float(rng.uniform(-math.pi, math.pi)) if i % 3 else 0.0
        t = RigidTransform(turn, float(rng.uniform(-15, 15)), float(rng.uniform(-15, 15)))
        encoded = repair_module._warp(repair_module._encode(m.states), t, ref.shape)
        aligned = align_map(m, t, ref)
        np.testing.assert_array_equal(aligned.states, repair_module._decode(encoded))
        assert not aligned.states.flags.writeable


# -- the overlay's raster ------------------------------------------------------------------
def test_cells_are_numpys_nonzero():
    rng = np.random.default_rng(8)
    for shape in ((1, 1), (3, 500), (64, 9)):
        mask = rng.random(shape) < 0.05
        rr, cc = _cells(mask)
        er, ec = np.nonzero(mask)
        np.testing.assert_array_equal(rr, er)
        np.testing.assert_array_equal(cc, ec)
    rr, cc = _cells(np.zeros((4, 4), bool))
    assert len(rr) == len(cc) == 0


def _plain_background(states: np.ndarray, view: _View) -> np.ndarray:
    """A block of the view is free when any of its cells inside the grid is known."""
    k = view.k
    out = np.zeros((view.h, view.w), np.uint16)
    rows, cols = states.shape
    for v in range(view.h):
        for u in range(view.w):
            y0, x0 = view.y0 + v * k, view.x0 + u * k
            block = states[
                max(y0, 0) : max(min(y0 + k, rows), 0), max(x0, 0) : max(min(x0 + k, cols), 0)
            ]
            out[v, u] = int(bool((block != UNKNOWN).any()))
    return out


@pytest.mark.parametrize(
    "view",
    [_View(0, 0, 3, 1, 14, 10), _View(-4, -7, 5, 1, 12, 9), _View(2, 1, 7, 1, 4, 4)],
)
def test_background_pools_every_block(view):
    rng = np.random.default_rng(view.k)
    states = rng.choice(STATES, size=(31, 37), p=[0.97, 0.02, 0.01])
    np.testing.assert_array_equal(
        _background(OccupancyMap(states), view), _plain_background(states, view)
    )


def test_pooled_picture_keeps_a_one_cell_wall():
    """A 3000 x 3000 map drawn on a raster of about 300 pixels (10 cells a pixel): its one
    cell thick wall is still an unbroken line of pixels in its partition's colour, and the
    free space beside it white."""
    states = np.full((3000, 3000), FREE, np.int8)
    states[1501, 200:2800] = OCCUPIED  # one cell thick, not on a block boundary
    m = OccupancyMap(states)
    labels = np.where(states == OCCUPIED, 0, NOT_OCCUPIED).astype(np.int16)
    n = m.n_occupied
    part = Partition(0, n, 1.0, RigidTransform.identity(), 1.0, 0.0, 0.0, None, 0.0)
    result = BrokennessResult(0, (part,), labels, n, 0, "ifmi", {}, 0.0)
    rgb, view = overlay_raster(result, m, m, target=300, dpi=150)
    assert view.k >= 10
    row = (1501 - view.y0) // view.k
    blue = np.array(palette_rgb(1)[0], np.float32)
    on_wall = np.all(np.isclose(rgb[row], blue, atol=1e-6), axis=-1)
    col0, col1 = (200 - view.x0) // view.k, (2799 - view.x0) // view.k
    assert on_wall[col0 : col1 + 1].all()
    white = np.all(rgb == 1.0, axis=-1)
    assert white[row - 5, col0 : col1 + 1].all()  # free space off the wall


# -- the result file -----------------------------------------------------------------------
def test_overlay_in_a_second_thread_writes_the_same_file(tmp_path, monkeypatch):
    ref, m, result = broken_rooms()
    monkeypatch.setattr(results_module, "_threads_allowed", lambda: True)
    one = save_results(tmp_path / "a.zip", result, m, ref)
    monkeypatch.setattr(results_module, "_threads_allowed", lambda: False)
    two = save_results(tmp_path / "b.zip", result, m, ref)
    for name in ("stats.json", "labels.npy", "overlay.png"):
        with zipfile.ZipFile(tmp_path / "a.zip") as za, zipfile.ZipFile(tmp_path / "b.zip") as zb:
            assert za.read(name) == zb.read(name)
            assert (
                za.namelist()
                == zb.namelist()
                == [
                    "info.json",
                    "stats.json",
                    "labels.npy",
                    "overlay.png",
                ]
            )
    assert one.overlay_png == two.overlay_png == load_results(tmp_path / "a.zip").overlay_png
    Image.open(io.BytesIO(one.overlay_png)).verify()


def test_a_failing_overlay_thread_leaves_no_file(tmp_path, monkeypatch):
    ref, m, result = broken_rooms()

    def broken(*args, **kwargs):
        raise RuntimeError("no picture")

    monkeypatch.setattr(results_module, "_threads_allowed", lambda: True)
    monkeypatch.setattr(results_module, "_overlay_png", broken)
    with pytest.raises(RuntimeError, match="no picture"):
        save_results(tmp_path / "x.zip", result, m, ref)
    assert list(tmp_path.iterdir()) == []


def test_threads_follow_opencvs_thread_count(monkeypatch):
    before = cv2.getNumThreads()
    try:
        cv2.setNumThreads(1)
        assert not results_module._threads_allowed()
    finally:
        cv2.setNumThreads(before)


# -- Pillow's decompression-bomb warning ---------------------------------------------------
def _png(path, shape=(40, 50)):
    Image.fromarray(np.full(shape, 254, np.uint8)).save(path)
    return path


def test_no_pillow_bomb_warning_within_our_cell_limit(tmp_path, monkeypatch):
    # Pillow's own count lowered below the image (restored by monkeypatch): Pillow would
    # warn, this package's limit (100 million cells) governs
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1500)
    path = _png(tmp_path / "m.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pixels = read_pixels(path)
    assert pixels.sums.shape == (40, 50)


def test_images_over_our_cell_limit_are_still_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("BROKENNESS_MAX_CELLS", "1000")
    with pytest.raises(MapSizeError):
        read_pixels(_png(tmp_path / "m.png"))
    monkeypatch.delenv("BROKENNESS_MAX_CELLS")
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 500)  # Pillow's error: twice its count
    with pytest.raises(MapSizeError):
        read_pixels(_png(tmp_path / "n.png"))


# -- loading -------------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (40, 57)])
def test_lookup_is_numpys_indexing(shape):
    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    for mode, negate in (("trinary", False), ("raw", False), ("scale", True)):
        lut = _lut(1, 255, mode, negate, 0.65, 0.196)
        sums = rng.integers(0, 256, shape).astype(np.uint8)
        got = _lookup(lut, sums)
        assert got.dtype == np.int8 and got.flags.writeable
        np.testing.assert_array_equal(got, lut[sums])
    small = _lut(1, 100, "trinary", False, 0.65, 0.196)  # a PGM of maxval 100: numpy's way
    sums = rng.integers(0, 101, shape).astype(np.uint8)
    np.testing.assert_array_equal(_lookup(small, sums), small[sums])


def test_loaded_map_is_taken_without_a_copy(tmp_path):
    states = np.array([[0, 254], [205, 0]], np.uint8)
    Image.fromarray(states).save(tmp_path / "m.png")
    m = load_map(tmp_path / "m.png")
    np.testing.assert_array_equal(m.states, [[OCCUPIED, FREE], [UNKNOWN, OCCUPIED]])
    assert not m.states.flags.writeable
