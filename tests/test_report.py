"""Overlay picture, repaired map and result files, on a hand-made broken map."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from PIL import Image
from test_report_fixtures import SHIFT, broken_rooms, rooms

from brokenness import OccupancyMap, RigidTransform, picture_distance
from brokenness.errors import MapError
from brokenness.measure.result import BrokennessResult, Partition
from brokenness.report import (
    ResultFileError,
    load_results,
    render_overlay,
    repair,
    repair_map,
    save_results,
)
from brokenness.report.overlay import (
    overlay_figure,
    overlay_image,
    palette_rgb,
    reference_in_map_frame,
)
from brokenness.report.repair import align_map, partition_owners


@pytest.fixture(scope="module")
def case():
    return broken_rooms()


# -- overlay ----------------------------------------------------------------------------------
def test_overlay_image_colours_partitions_in_map_frame(case):
    ref, m, result = case
    rgb = overlay_image(result, m, ref)
    assert rgb.shape == (*m.shape, 3)
    blue, orange = palette_rgb(2)
    labels = result.labels
    np.testing.assert_allclose(rgb[labels == 0], np.broadcast_to(blue, ((labels == 0).sum(), 3)))
    np.testing.assert_allclose(rgb[labels == 1], np.broadcast_to(orange, ((labels == 1).sum(), 3)))
    assert (rgb[labels == -2] == 0).all()  # unassigned in black


def test_reference_warp_uses_inverse_of_transform():
    ref = rooms()
    # the map is the reference shifted by (+5, +3): map->ref transform is (-5, -3)
    t = RigidTransform(0.0, -5, -3)
    warped = reference_in_map_frame(ref, t, ref.shape)
    expected = np.zeros(ref.shape, bool)
    expected[3:, 5:] = ref.occupied[:-3, :-5]
    np.testing.assert_array_equal(warped, expected)


def test_render_overlay_writes_decodable_png(case, tmp_path):
    ref, m, result = case
    out = tmp_path / "overlay.png"
    render_overlay(result, m, ref, out, dpi=80)
    with Image.open(out) as im:
        im.load()
        assert im.format == "PNG"
        w, h = im.size
        pixels = np.asarray(im.convert("RGB"))
    assert 0.85 * 8 * 80 < w < 1.1 * 8 * 80 and 150 < h < 800
    # both partition colours are present in the picture
    for colour in palette_rgb(2):
        target = np.round(np.asarray(colour) * 255)
        close = np.abs(pixels.astype(int) - target).sum(axis=2) <= 6
        assert close.sum() > 20


@pytest.mark.parametrize("shape", [(40, 200), (200, 40)])
def test_overlay_nothing_clipped(tmp_path, shape):
    """Title, axis labels and legend lie inside the picture, for wide and tall maps."""
    rows, cols = shape
    states = np.zeros(shape, np.int8)
    states[[0, -1], :] = 1
    states[:, [0, -1]] = 1
    m = OccupancyMap(states, 0.05, (0.0, 0.0, 0.0), source="a_map_with_a_long_file_name.pgm")
    labels = np.where(m.occupied, 0, -1).astype(np.int16)
    labels[: rows // 2][m.occupied[: rows // 2]] = 1
    n0, n1 = int((labels == 0).sum()), int((labels == 1).sum())
    n = n0 + n1
    t = RigidTransform(0.1, 2.0, 3.0)
    parts = tuple(
        Partition(i, c, c / n, t, 0.9, 0.0, 123.45, 6.17, 0.0) for i, c in enumerate((n0, n1))
    )
    result = BrokennessResult(1, parts, labels, n, 0, "ifmi", {}, 0.0)
    fig = overlay_figure(result, m, m)
    handles = fig.legends[0].legend_handles
    assert len(handles) == 3
    out = tmp_path / "o.png"
    render_overlay(result, m, m, out, dpi=60)
    with Image.open(out) as im:
        px = np.asarray(im.convert("L")).astype(int)
    # a clipped artist would touch the border; the trimmed picture keeps a white margin
    edges = (px[:3], px[-3:], px[:, :3], px[:, -3:])
    border = np.concatenate([e.ravel() for e in edges])
    assert (border == 255).all()
    assert (px < 128).sum() > 100  # text and walls were drawn


def test_overlay_rejects_result_of_another_map(case, tmp_path):
    ref, _, result = case
    small = OccupancyMap(np.zeros((10, 10), np.int8))
    with pytest.raises(MapError, match="shape"):
        render_overlay(result, small, ref, tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


# -- repair -----------------------------------------------------------------------------------
def test_partition_owners_nearest_partition():
    labels = np.full((5, 9), -1, np.int16)
    labels[2, 0] = 0
    labels[2, 8] = 1
    owners = partition_owners(labels)
    assert (owners[:, :4] == 0).all() and (owners[:, 5:] == 1).all()
    assert (partition_owners(np.full((3, 3), -2)) == -1).all()


def test_repaired_map_is_closer_to_reference(case):
    ref, m, result = case
    rep = repair(result, m, ref)
    assert rep.repaired.shape == ref.shape
    assert rep.repaired.resolution == ref.resolution and rep.repaired.origin == ref.origin
    assert rep.psi_map == pytest.approx(picture_distance(align_map(m, RigidTransform(), ref), ref))
    assert rep.psi_repaired < 0.5 * rep.psi_map
    # every wall of the reference away from the cut is back in place
    dx, _ = SHIFT
    interior = np.zeros(ref.shape, bool)
    interior[:, 50:] = True
    assert (rep.repaired.occupied[ref.occupied & interior]).mean() > 0.97
    assert repair_map(result, m, ref).n_occupied == rep.repaired.n_occupied


def test_repair_without_partitions_is_identity(case):
    ref, m, result = case
    from dataclasses import replace

    empty = replace(result, partitions=(), degree=0)
    rep = repair(empty, m, ref)
    np.testing.assert_array_equal(rep.repaired.states, m.states)


# -- result files ------------------------------------------------------------------------------
def test_results_zip_round_trip(case, tmp_path):
    ref, m, result = case
    path = tmp_path / "run.zip"
    written = save_results(path, result, m, ref, info={"labels": {"system": "s1"}}, dpi=60)
    with zipfile.ZipFile(path) as zf:
        assert sorted(zf.namelist()) == ["info.json", "labels.npy", "overlay.png", "stats.json"]
    rec = load_results(path)
    assert rec.degree == 1 and rec.run_labels == {"system": "s1"}
    np.testing.assert_array_equal(rec.labels, result.labels)
    assert rec.labels.dtype == np.int16
    assert rec.stats == written.stats
    assert rec.info["version"] and rec.info["method"] == "ifmi"
    assert rec.info["parameters"]["threshold"] == 2.0
    assert rec.info["timings"]["compute_seconds"] == pytest.approx(0.05)
    s = rec.stats
    assert s["n_partitions"] == 2 and s["unassigned_cells"] == 2
    p1 = s["partitions"][1]
    assert p1["transform"]["translation_cells"] == [-5.0, -3.0]
    assert p1["transform"]["translation_norm_cells"] == pytest.approx(np.hypot(5, 3))
    assert p1["transform"]["translation_norm_m"] == pytest.approx(np.hypot(5, 3) * 0.05)
    # world frame: +x cells is +x metres, +y cells (down) is -y metres
    assert p1["transform"]["world"]["translation_m"] == pytest.approx([-0.25, 0.15])
    assert p1["relative_to_largest"]["translation_cells"] == [-5.0, -3.0]
    assert 0 <= s["psi_repaired"] < s["psi_map"]
    assert "seconds" not in s  # timings are not part of the deterministic stats
    with Image.open(__import__("io").BytesIO(rec.overlay_png)) as im:
        assert im.format == "PNG"


def test_stats_are_deterministic(case, tmp_path):
    ref, m, result = case
    a = save_results(tmp_path / "a.zip", result, m, ref, dpi=40)
    b = save_results(tmp_path / "b.zip", result, m, ref, dpi=40)
    assert json.dumps(a.stats, sort_keys=True) == json.dumps(b.stats, sort_keys=True)
    with zipfile.ZipFile(tmp_path / "a.zip") as za, zipfile.ZipFile(tmp_path / "b.zip") as zb:
        for name in ("stats.json", "labels.npy", "overlay.png"):
            assert za.read(name) == zb.read(name)


def test_input_checksums_recorded(case, tmp_path):
    ref, m, result = case
    src = tmp_path / "broken.pgm"
    src.write_bytes(b"P5 not really")
    m2 = OccupancyMap(m.states, m.resolution, m.origin, source=str(src))
    rec = save_results(tmp_path / "r.zip", result, m2, ref, dpi=40)
    import hashlib

    assert rec.info["inputs"]["map"] == {
        "path": str(src),
        "sha256": hashlib.sha256(b"P5 not really").hexdigest(),
    }
    assert rec.info["inputs"]["reference"]["sha256"] is None  # "rooms.pgm" does not exist


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_atomic_write_leaves_nothing_on_failure(case, tmp_path, monkeypatch, exc):
    ref, m, result = case
    dest = tmp_path / "run.zip"
    calls = []
    original = zipfile.ZipFile.writestr

    def failing(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise exc("boom")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(zipfile.ZipFile, "writestr", failing)
    with pytest.raises(exc):
        save_results(dest, result, m, ref, dpi=40)
    assert list(tmp_path.iterdir()) == []

    # an existing good file survives a failed overwrite
    monkeypatch.undo()
    save_results(dest, result, m, ref, dpi=40)
    before = dest.read_bytes()
    import os as _os

    def bad_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(_os, "replace", bad_replace)
    with pytest.raises(OSError, match="disk full"):
        save_results(dest, result, m, ref, dpi=40)
    assert dest.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["run.zip"]


def test_load_results_errors(tmp_path):
    with pytest.raises(ResultFileError, match="no such"):
        load_results(tmp_path / "missing.zip")
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ResultFileError, match="not a valid zip"):
        load_results(bad)
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(other, "w") as zf:
        zf.writestr("hello.txt", "hi")
    with pytest.raises(ResultFileError, match="not a brokenness result"):
        load_results(other)
